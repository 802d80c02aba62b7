"""Read a survey log in any format into validated canonical columns."""

from __future__ import annotations

import logging
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..errors import InputError
from .columns import (
    NUMERIC_COLUMNS,
    apply_column_map,
    check_unique_names,
    convert_units,
    plain_number,
    to_numeric,
)
from .formats import read_table_rows
from .rows import ROWS_ATTR, row_location

log = logging.getLogger(__name__)

def read_log(
    path: str | os.PathLike[str],
    *,
    columns: Mapping[str, str] | None = None,
    units: Mapping[str, str] | None = None,
    required: Sequence[str] = ("time",),
    fmt: str | None = None,
    min_rows: int = 2,
) -> pd.DataFrame:
    """Read a survey log into canonical columns and validate it.

    Steps: read the table (CSV by default; a column name used twice is an error), rename
    through ``columns``, check that the ``required`` columns exist, convert canonical columns
    to numbers (an unparseable cell is an error naming its column and its line in the file, or
    its row / sample for Parquet / HDF5; a ``time`` of ISO 8601 or datetime values becomes
    seconds since 1970-01-01 UTC), convert units when asked, drop exact duplicate rows and
    check that ``time`` is strictly increasing.  All other rows and columns are kept.

    Parameters
    ----------
    path : path-like
        The log file.
    columns : mapping, optional
        Column map ``{canonical_name: source_name}``.
    units : mapping, optional
        Unit conversions ``{column_or_group: unit}`` (``flux`` or ``mag`` groups, or a column).
    required : sequence of str
        Canonical columns that must be present.
    fmt : str, optional
        Format name; inferred from the extension when omitted.
    min_rows : int
        Fewest data rows accepted.

    Returns
    -------
    DataFrame
        The log; ``df.attrs["source"]`` holds the path.
    """
    p = Path(path)
    source = str(p)
    if not p.exists():
        raise InputError(f"{source}: file not found")
    df = read_table_rows(p, fmt)
    rows = df.attrs.pop(ROWS_ATTR, None)
    check_unique_names([str(c) for c in df.columns], source, what="table")
    df = apply_column_map(df, columns, source=source)
    missing = [c for c in required if c not in df.columns]
    if missing:
        avail = ", ".join(map(str, df.columns[:20]))
        raise InputError(
            f"{source}: missing column(s) {', '.join(missing)}; columns are: {avail};"
            " map them with --col NAME=SOURCE"
        )
    if len(df) < min_rows:
        raise InputError(f"{source}: only {len(df)} data row(s); need at least {min_rows}")
    present = [c for c in NUMERIC_COLUMNS if c in df.columns]
    df = to_numeric(df, present, source, rows)
    df = convert_units(df, units, source=source)
    n_read = len(df)
    plain = df.attrs.pop("_plain_csv_columns", None)
    if df.attrs.pop("_time_converted", False):
        plain = None  # the time column is no longer the file's text
    if "time" in df.columns:
        df = _clean_time(df, source, rows)
    if len(df) < min_rows:
        raise InputError(f"{source}: only {len(df)} usable row(s); need at least {min_rows}")
    df.attrs.pop("_plain_csv_columns", None)
    df.attrs["source"] = source
    if plain is not None and not columns and not units and len(df) == n_read:
        # Every row and column is exactly as in the file: outputs may copy its lines.
        df.attrs["passthrough_csv"] = {"path": source, "columns": plain}
    return df


def _clean_time(df: pd.DataFrame, source: str,
                rows: Mapping[str, Any] | None = None) -> pd.DataFrame:
    """Drop exact duplicate rows; require a finite, strictly increasing ``time``."""
    t = df["time"].to_numpy(dtype=np.float64)
    bad = ~np.isfinite(t)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"{source}: column 'time', {row_location(rows, i)}: empty or"
                         " non-finite time; fix or remove the row")
    dup = np.zeros(len(df), dtype=bool)
    same_t = np.r_[False, t[1:] == t[:-1]]
    if same_t.any():
        # Only rows identical to their predecessor in every column are dropped.
        prev = df.shift(1)
        eq = (df.eq(prev) | (df.isna() & prev.isna())).all(axis=1).to_numpy()
        dup = same_t & eq
        if dup.any():
            log.warning("%s: dropped %d exact duplicate row(s)", source, int(dup.sum()))
            df = df.loc[~dup].reset_index(drop=True)
            t = t[~dup]
    dt = np.diff(t)
    if (dt <= 0).any():
        i = int(np.flatnonzero(dt <= 0)[0]) + 1
        # Report the line in the original file.
        orig = int(np.flatnonzero(~dup)[i]) if dup.any() else i
        raise InputError(
            f"{source}: column 'time', {row_location(rows, orig)}: time {plain_number(t[i])} is"
            f" not after {plain_number(t[i - 1])}; time must be strictly increasing (sort the log"
            " or fix the row)"
        )
    return df
