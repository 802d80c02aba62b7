"""Helpers shared by the native instrument formats (MagArrow, MagDrone)."""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

from ...errors import InputError
from ..columns import (
    datetime_seconds,
    numeric_values,
)
from ..rows import row_location

log = logging.getLogger(__name__)

def parse_datetime_seconds(date: pd.Series, clock: pd.Series, source: str,
                            rows: Mapping[str, object] | None = None) -> np.ndarray:
    """``Date`` + ``Time`` columns -> seconds since 1970-01-01 UTC (float64)."""
    stamp = date.astype(str).str.strip() + " " + clock.astype(str).str.strip()
    dt = pd.to_datetime(stamp, format="mixed", errors="coerce", utc=True)
    bad = dt.isna().to_numpy()
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"{source}: columns 'Date'/'Time', {row_location(rows, i)}: cannot"
                         f" read {stamp.iloc[i]!r} as a date and time; fix or remove the row")
    return datetime_seconds(dt, source, rows)


def check_made_names(columns: Sequence[object], made: Mapping[str, str], source: str,
                     what: str, header_line: int = 1) -> None:
    """Refuse a source column named like a canonical column the native reader makes.

    A vendor header holding e.g. a second ``time`` (or ``time `` with a blank) beside
    ``Date``/``Time`` would collide with the ``time`` the reader computes.

    Parameters
    ----------
    columns : sequence
        Column names of the table, in file order (blanks stripped).
    made : mapping
        ``{canonical name: what it is made from}`` for the columns the reader adds.
    source : str
        File name quoted in the error.
    what : str
        The format, for the message (e.g. ``"MagArrow"``).
    header_line : int
        1-based line of the header in the file.
    """
    names = [str(c).strip() for c in columns]
    for name, origin in made.items():
        if name in names:
            j = names.index(name)
            raise InputError(
                f"{source}: line {header_line}, column {j + 1} ({str(columns[j])!r}): the"
                f" {what} header has a column {name!r}, but the reader makes {name!r} from"
                f" {origin}; rename that column in the header (e.g. {name}_2) or remove it")


def native_values(s: pd.Series, source: str, column: str,
                   rows: Mapping[str, object] | None) -> np.ndarray:
    """float64 values of an instrument channel; an unparseable cell is an error (never NaN)."""
    return numeric_values(s, source, column, rows,
                          remedy="fix or remove that row of the instrument log")


def interp_sparse(t: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Linear interpolation in time over the finite samples (NaN outside their span)."""
    ok = np.isfinite(values)
    if ok.sum() < 2:
        return values
    out = np.interp(t, t[ok], values[ok])
    out[(t < t[ok][0]) | (t > t[ok][-1])] = np.nan
    return out
