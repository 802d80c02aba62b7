"""Read a survey log in any format into validated canonical columns."""

from __future__ import annotations

import contextlib
import logging
import os
import threading
from collections.abc import Iterator, Mapping, Sequence
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
from .messages import check_input_file
from .outputs import register_input
from .rows import ROWS_ATTR, row_location

log = logging.getLogger(__name__)

_options = threading.local()

#: Largest ``|time|`` accepted [s]: about the year 5100 in seconds since 1970.
MAX_TIME_S = 1e11


@contextlib.contextmanager
def reading_options(*, allow_truncated: bool = False) -> Iterator[None]:
    """Defaults of :func:`read_log` (and the chunked reader) inside the block.

    The command line sets ``--allow-truncated`` this way for whatever the command reads.

    Parameters
    ----------
    allow_truncated : bool
        Drop a last row cut short (a log that ended in the middle of a row) with a warning,
        instead of refusing the file.
    """
    old = getattr(_options, "allow_truncated", False)
    _options.allow_truncated = allow_truncated
    try:
        yield
    finally:
        _options.allow_truncated = old


def allow_truncated_default(value: bool | None = None) -> bool:
    """``value``, or the default set by :func:`reading_options` when None."""
    return bool(getattr(_options, "allow_truncated", False)) if value is None else value


def read_log(
    path: str | os.PathLike[str],
    *,
    columns: Mapping[str, str] | None = None,
    units: Mapping[str, str] | None = None,
    required: Sequence[str] = ("time",),
    fmt: str | None = None,
    min_rows: int = 2,
    allow_truncated: bool | None = None,
    usecols: Sequence[str] | None = None,
    dtypes: Mapping[str, Any] | None = None,
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
    allow_truncated : bool, optional
        Drop a last row that is cut short (a log that ended in the middle of a row), with a
        warning (recorded in the report of a command), instead of refusing the file; default
        False (see :func:`reading_options`).  A shorter row anywhere else is always an error.
    usecols : sequence of str, optional
        Read only these columns (canonical names, or names of the file that are not mapped;
        those the log lacks are left out): a CSV parses no other column (pyarrow's
        ``include_columns``), so the memory and time are those of the columns kept.  Default:
        every column.
    dtypes : mapping, optional
        ``{column: numpy dtype}`` of columns to hold in another type than float64 once
        validated (e.g. ``np.float32`` for columns only drawn); columns the log lacks are
        ignored.

    Returns
    -------
    DataFrame
        The log; ``df.attrs["source"]`` holds the path.
    """
    p = Path(path)
    source = str(p)
    check_input_file(p)
    register_input(p, "input log")
    source_cols = None
    if usecols is not None:
        source_cols = [(columns or {}).get(c, c) for c in usecols]
    source_types = {(columns or {}).get(c, c): dt for c, dt in (dtypes or {}).items()}
    df = read_table_rows(p, fmt, allow_truncated=allow_truncated_default(allow_truncated),
                         usecols=source_cols, dtypes=source_types)
    rows = df.attrs.pop(ROWS_ATTR, None)
    check_unique_names([str(c) for c in df.columns], source, what="table")
    df = apply_column_map(df, columns, source=source)
    missing = [c for c in required if c not in df.columns]
    if missing:
        avail = ", ".join(map(str, df.columns[:20]))
        raise InputError(
            f"{source}: missing column(s) {', '.join(missing)}; columns are: {avail};"
            " map them with columns={'NAME': 'SOURCE'}"
        )
    if len(df) < min_rows:
        raise InputError(f"{source}: only {len(df)} data row(s); need at least {min_rows}:"
                         " give a longer log")
    present = [c for c in NUMERIC_COLUMNS if c in df.columns]
    df = to_numeric(df, present, source, rows, keep=tuple(dtypes or ()))
    df = convert_units(df, units, source=source, rows=rows)
    n_read = len(df)
    plain = df.attrs.pop("_plain_csv_columns", None)
    if df.attrs.pop("_time_converted", False):
        plain = None  # the time column is no longer the file's text
    if "time" in df.columns:
        df = clean_time(df, source, rows)
    if len(df) < min_rows:
        raise InputError(f"{source}: only {len(df)} usable row(s); need at least {min_rows}:"
                         " give a longer log")
    df.attrs.pop("_plain_csv_columns", None)
    for c, dt in (dtypes or {}).items():
        if c in df.columns:
            df[c] = df[c].to_numpy().astype(dt, copy=False)
    df.attrs["source"] = source
    if plain is not None and not columns and not units and len(df) == n_read:
        # Every row and column is exactly as in the file: outputs may copy its lines.
        df.attrs["passthrough_csv"] = {"path": source, "columns": plain}
    return df


def check_time_values(t: np.ndarray, source: str, rows: Mapping[str, Any] | None) -> None:
    """Refuse an empty or non-finite time, or one beyond :data:`MAX_TIME_S` (naming the row).

    Parameters
    ----------
    t : ndarray
        Times [s].
    source : str
        File name quoted in errors.
    rows : mapping or None
        Where the rows are in the file.
    """
    bad = ~np.isfinite(t)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"{source}: column 'time', {row_location(rows, i)}: empty or"
                         " non-finite time; fix or remove the row")
    huge = np.abs(t) > MAX_TIME_S
    if huge.any():
        i = int(np.flatnonzero(huge)[0])
        raise InputError(
            f"{source}: column 'time', {row_location(rows, i)}: time {plain_number(t[i])} s is"
            f" beyond {MAX_TIME_S:.0e} s (the year 5000): fix the value, or if time is in ms, us"
            " or ns convert it to seconds")


def duplicates_warning(source: str, n: int, where: str) -> str:
    """The warning for exact duplicate rows dropped (the same in memory and chunked)."""
    return (f"{source}: dropped {n} exact duplicate row(s) (the first at {where}: a copy of the"
            " row before it); check the logger if you did not expect copies")


def clean_time(df: pd.DataFrame, source: str,
                rows: Mapping[str, Any] | None = None) -> pd.DataFrame:
    """Drop exact duplicate rows; require a finite, strictly increasing ``time``.

    The readers' check (:func:`read_log`), also run by ``aeromag report`` on the log it reads,
    so that both refuse a log in the same words.

    Parameters
    ----------
    df : DataFrame
        The log, with ``time`` [s].
    source : str
        The file, for messages.
    rows : mapping, optional
        How to name a row of the file in messages (:mod:`aeromag.io.rows`).

    Returns
    -------
    DataFrame
        ``df`` without its exact duplicate rows (a warning says how many).

    Raises
    ------
    InputError
        Naming the file, column ``time`` and the row where time does not increase.
    """
    t = df["time"].to_numpy(dtype=np.float64)
    check_time_values(t, source, rows)
    dup = np.zeros(len(df), dtype=bool)
    same_t = np.r_[False, t[1:] == t[:-1]]
    if same_t.any():
        # Only rows identical to their predecessor in every column are dropped.
        prev = df.shift(1)
        eq = (df.eq(prev) | (df.isna() & prev.isna())).all(axis=1).to_numpy()
        dup = same_t & eq
        if dup.any():
            first = int(np.flatnonzero(dup)[0])
            log.warning("%s", duplicates_warning(source, int(dup.sum()),
                                                 row_location(rows, first)))
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
