"""Canonical columns, column maps, map files, units and numeric conversion of a raw table.

A survey log is a :class:`pandas.DataFrame` with the canonical columns of
``shared/interface.md``.  Logs named otherwise are read through a column map
(``{"mag": "mag_1_uc"}``); units other than nT are converted only when asked
(``{"flux": "uT"}``), never guessed.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd

from ..conventions import CANONICAL_COLUMNS, FLUX_COLUMNS  # noqa: F401 - FLUX_COLUMNS re-exported
from ..errors import InputError
from .messages import clean
from .rows import row_location
from .units import (  # noqa: F401 - FIELD_UNITS_TO_NT re-exported
    FIELD_UNITS_TO_NT,
    UNIT_GROUPS,
    time_ticks,
    unit_factor,
)

log = logging.getLogger(__name__)

#: Columns whose values must be numeric when present: the canonical columns of the contract
#: (:mod:`aeromag.conventions`, the one list).
NUMERIC_COLUMNS: tuple[str, ...] = tuple(CANONICAL_COLUMNS)

#: Canonical columns that hold whole numbers (ids, counts): validated, not cast to float.
INTEGER_COLUMNS: frozenset[str] = frozenset(
    c for c, unit in CANONICAL_COLUMNS.items() if unit in ("integer", "0-255"))


class ColumnNames(list):
    """A list of column names that :func:`copy.deepcopy` copies shallowly (names are str).

    pandas deep-copies ``DataFrame.attrs`` on every column access (``df[c]``): a plain list of
    the 5,000 names of a wide log in ``attrs`` made writing it 5,000 x 5,000 copies.
    """

    def __deepcopy__(self, memo: dict[int, Any]) -> ColumnNames:
        return ColumnNames(self)


#: ``df.attrs`` key of the names of the scalar datasets a reader skipped (HDF5 metadata).
SCALARS_ATTR = "_hdf5_scalars"


# --------------------------------------------------------------------------- column maps
def parse_column_map(items: Iterable[str], *, option: str = "--col") -> dict[str, str]:
    """Parse ``NAME=SOURCE`` strings into a column map.

    Parameters
    ----------
    items : iterable of str
        Strings such as ``"mag=mag_1_uc"``; ``NAME`` is the canonical column, ``SOURCE`` the
        column name in the file.
    option : str
        Option name quoted in error messages.

    Returns
    -------
    dict
        ``{canonical_name: source_name}``.
    """
    out: dict[str, str] = {}
    for item in items:
        if "=" not in item:
            raise InputError(f"{option} {item!r}: expected NAME=VALUE, e.g. {option} mag=mag_1_uc")
        name, _, source = item.partition("=")
        name, source = name.strip(), source.strip()
        if not name or not source:
            raise InputError(f"{option} {item!r}: expected NAME=VALUE with both parts non-empty")
        out[name] = source
    return out


def plain_number(x: Any) -> str:
    """A number as plain text for messages: ``0.1``, ``1601300273.001`` (not ``np.float64(..)``)."""
    try:
        v = float(x)
    except (TypeError, ValueError):
        return repr(x)
    return str(int(v)) if v.is_integer() and abs(v) < 1e15 else repr(v)


_BOOL_WORDS = frozenset({"true", "false"})


def _boolean_cells(s: pd.Series) -> np.ndarray | None:
    """Cells that are booleans (bool dtype, or the words true/false), or None when none is."""
    if pd.api.types.is_bool_dtype(s.dtype):
        mask = s.notna().to_numpy()
        return mask if mask.any() else None
    if s.dtype.kind != "O" and not pd.api.types.is_string_dtype(s.dtype):
        return None
    vals = s.to_numpy()
    mask = np.fromiter((isinstance(v, bool | np.bool_) or (isinstance(v, str) and v.strip()
                        .lower() in _BOOL_WORDS) for v in vals), dtype=bool, count=len(vals))
    return mask if mask.any() else None


#: What :func:`numeric_values` tells a caller to do by default.
_REMAP = "fix the value or map another column with columns={'NAME': 'SOURCE'}"


def numeric_values(s: pd.Series, source: str, column: str, rows: Mapping[str, Any] | None,
                   remedy: str = _REMAP) -> np.ndarray:
    """float64 values of a column; empty cells are NaN, any other unparseable cell an error.

    Parameters
    ----------
    s : Series
        The column as read.
    source : str
        File name quoted in the error.
    column : str
        Column name quoted in the error (as the file spells it).
    rows : mapping or None
        Where the rows are in the file (see :func:`row_location`).
    remedy : str
        What to do, ending the message.

    Returns
    -------
    ndarray of float64
    """
    if pd.api.types.is_numeric_dtype(s.dtype) and not pd.api.types.is_bool_dtype(s.dtype):
        return s.to_numpy(dtype=np.float64, na_value=np.nan)
    flags = _boolean_cells(s)
    if flags is not None:
        i = int(np.flatnonzero(flags)[0])
        raise InputError(
            f"{clean(source)}: column {clean(column)!r}, {row_location(rows, i)}: value"
            f" {clean(s.iloc[i])!r} is true/false, not a number; {remedy}")
    if s.dtype.kind in "SO" and len(s) and isinstance(s.iloc[int(s.notna().argmax())], bytes):
        raise InputError(f"{clean(source)}: column {clean(column)!r} holds binary data, not"
                         f" numbers; {remedy}")
    conv = pd.to_numeric(s, errors="coerce")
    bad = (conv.isna() & s.notna()).to_numpy()
    if bad.any():
        bad = bad & (s.astype(str).str.strip() != "").to_numpy()
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(
            f"{clean(source)}: column {clean(column)!r}, {row_location(rows, i)}: value"
            f" {clean(s.iloc[i])!r} is not a number; {remedy}"
        )
    return conv.to_numpy(dtype=np.float64, na_value=np.nan)


def check_unique_names(names: Sequence[str], source: str, *, what: str = "header") -> None:
    """Raise :class:`InputError` naming the first column name that appears twice.

    Parameters
    ----------
    names : sequence of str
        Column names in file order (empty names are not checked).
    source : str
        File name quoted in the error.
    what : str
        Where the names come from, for the message.
    """
    seen: dict[str, int] = {}
    for j, name in enumerate(names):
        if not name:
            continue
        if name in seen:
            raise InputError(
                f"{source}: column {name!r} appears twice in the {what} (columns {seen[name] + 1}"
                f" and {j + 1}); rename one of them (e.g. {name}_2) so that each column has its"
                " own name, then pick one with columns={'NAME': 'SOURCE'} if needed")
        seen[name] = j


def filled_cells(s: pd.Series) -> np.ndarray:
    """Cells that hold something (not missing, not only blanks)."""
    filled = s.notna().to_numpy()
    if filled.any() and not pd.api.types.is_numeric_dtype(s.dtype):
        filled = filled & (s.astype(str).str.strip() != "").to_numpy()
    return filled


def apply_column_map(
    df: pd.DataFrame, columns: Mapping[str, str] | None, *, source: str = "<log>"
) -> pd.DataFrame:
    """Rename source columns to canonical names.

    Parameters
    ----------
    df : DataFrame
        Raw table.
    columns : mapping or None
        ``{canonical_name: source_name}``.
    source : str
        File name quoted in errors.

    Returns
    -------
    DataFrame
        The table with mapped columns renamed (unmapped columns kept as they are).
    """
    if not columns:
        return df
    rename: dict[str, str] = {}
    for name, src in columns.items():
        if src not in df.columns and src in (df.attrs.get(SCALARS_ATTR) or ()):
            raise InputError(
                f"{clean(source)}: dataset {clean(src)!r} (mapped to {name!r}) is a scalar (one"
                " value, shape ()), not one value per sample; map a 1-D channel instead")
        if src not in df.columns:
            avail = ", ".join(map(str, df.columns[:20]))
            raise InputError(
                f"{clean(source)}: column {clean(src)!r} (mapped to {name!r}) not found; fix the"
                f" map (columns={{'{name}': 'SOURCE'}}); columns are: {clean(avail)}"
            )
        rename[src] = name
    # A canonical name that is also an existing, unmapped column would collide: drop the old one.
    clash = [name for src, name in rename.items() if name in df.columns and name != src]
    out = df.drop(columns=[c for c in clash if c not in rename])
    return out.rename(columns=rename)


def to_numeric(df: pd.DataFrame, cols: Sequence[str], source: str,
                rows: Mapping[str, Any] | None = None, keep: Sequence[str] = ()
                ) -> pd.DataFrame:
    """Convert ``cols`` to float, naming the first unparseable cell (and its line) in the error.

    Numeric columns named in ``keep`` stay in the type they were read in (e.g. float32).

    A ``time`` column of date-times (ISO 8601 text, or datetime / duration values from Parquet)
    becomes float seconds since 1970-01-01 UTC (see :func:`datetime_seconds`).
    """
    for c in cols:
        s = df[c]
        if isinstance(s, pd.DataFrame):  # a name used twice
            raise InputError(f"{source}: column {c!r} appears more than once; rename the copies"
                             " so that each column has its own name")
        if c == "time" and _is_datetime_like(s):
            df[c] = datetime_seconds(s, source, rows)
            df.attrs["_time_converted"] = True
            continue
        if pd.api.types.is_numeric_dtype(s.dtype) and not pd.api.types.is_bool_dtype(s.dtype):
            if s.dtype != np.float64 and c not in INTEGER_COLUMNS and c not in keep:
                df[c] = s.astype(np.float64)
        else:
            df[c] = numeric_values(s, source, c, rows)
        _check_magnitudes(df[c], source, c, rows)
    return df


#: Largest line / leg id accepted (integers exact in float64).
MAX_ID = 10**15


def _check_magnitudes(s: pd.Series, source: str, column: str,
                      rows: Mapping[str, Any] | None) -> None:
    """Infinite values (a number beyond float range) and absurd line / leg ids are errors."""
    if s.dtype.kind not in "fiu":
        return
    v = s.to_numpy()
    if v.dtype.kind == "f":
        bad = np.isinf(v)
        if column in ("line", "leg"):
            fin = np.isfinite(v)
            bad |= fin & (np.abs(v) > MAX_ID)
    elif column in ("line", "leg"):
        bad = np.abs(v.astype(np.float64)) > MAX_ID
    else:
        return
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        what = ("is infinite (beyond the range of numbers)" if np.isinf(v[i]) else
                f"is beyond {MAX_ID:.0e}: not a {column} id")
        raise InputError(f"{clean(source)}: column {clean(column)!r}, {row_location(rows, i)}:"
                         f" value {plain_number(v[i])} {what}; fix the value")


#: ISO 8601 date and time at the start of a text value (``2024-01-01T00:00:00``, with a space too).
ISO_DATETIME = re.compile(r"^\s*[+-]?\d{4}-\d{2}-\d{2}[T ]\d{2}:\d{2}")


def _is_datetime_like(s: pd.Series) -> bool:
    """A datetime / duration column, or text whose first value is an ISO 8601 date-time."""
    if pd.api.types.is_datetime64_any_dtype(s.dtype) or pd.api.types.is_timedelta64_dtype(
            s.dtype):
        return True
    if pd.api.types.is_numeric_dtype(s.dtype) or pd.api.types.is_bool_dtype(s.dtype):
        return False
    first = s.first_valid_index()
    return first is not None and isinstance(s.loc[first], str) and bool(
        ISO_DATETIME.match(s.loc[first]))


#: Ticks per second of the datetime64 / timedelta64 units.
_TICKS_PER_S = {"s": 1, "ms": 10**3, "us": 10**6, "ns": 10**9}


def datetime_seconds(s: pd.Series, source: str = "<log>",
                     rows: Mapping[str, Any] | None = None) -> np.ndarray:
    """Date-times as float seconds since 1970-01-01 UTC; durations as float seconds.

    Accepts datetime64 of any resolution (s, ms, us, ns), time-zone aware (converted to UTC)
    or naive (taken as UTC), timedelta64, and ISO 8601 text (``2024-01-01T00:00:00.1``, with
    an optional ``Z`` or ``+02:00`` offset; naive text is taken as UTC).  The whole seconds and
    the fraction are converted separately, so nothing below the stored resolution is lost
    before the float cast (float64 keeps about 0.2 us at today's epoch seconds).  Missing
    values become NaN; a text value that is not a date-time is an error naming its line.

    Parameters
    ----------
    s : Series
        The column.
    source : str
        File name quoted in errors.
    rows : mapping, optional
        Where the rows are in the file (see :func:`row_location`).

    Returns
    -------
    ndarray of float64
        Seconds.
    """
    if pd.api.types.is_timedelta64_dtype(s.dtype):
        arr = s.to_numpy()
    else:
        if not pd.api.types.is_datetime64_any_dtype(s.dtype):
            parsed = pd.to_datetime(s, format="ISO8601", utc=True, errors="coerce")
            bad = parsed.isna().to_numpy() & filled_cells(s)
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                raise InputError(
                    f"{source}: column 'time', {row_location(rows, i)}: value"
                    f" {str(s.iloc[i])!r} is not an ISO 8601 date-time like the rows before it;"
                    " fix the value")
            s = parsed
        if isinstance(s.dtype, pd.DatetimeTZDtype):
            s = s.dt.tz_convert("UTC").dt.tz_localize(None)
        arr = s.to_numpy()
    unit, count = np.datetime_data(arr.dtype)
    if unit not in _TICKS_PER_S or count != 1:
        kind = "m8" if arr.dtype.kind == "m" else "M8"
        arr, unit = arr.astype(f"{kind}[ns]"), "ns"
    per = _TICKS_PER_S[unit]
    ticks = arr.view(np.int64)
    out = (ticks // per).astype(np.float64) + (ticks % per) / per
    out[np.isnat(arr)] = np.nan
    log.info("%s: column 'time' holds %s: converted to seconds%s", source,
             "durations" if arr.dtype.kind == "m" else "date-times",
             "" if arr.dtype.kind == "m" else " since 1970-01-01 UTC")
    return out


def convert_units(
    df: pd.DataFrame, units: Mapping[str, str] | None, *, source: str = "<log>",
    rows: Mapping[str, Any] | None = None,
) -> pd.DataFrame:
    """Convert field columns to nT and ``time`` to s as requested (never guessed), then check.

    Without a time unit, a ``time`` that looks like epoch milliseconds, microseconds or
    nanoseconds (median above 1e11 s, the year 5100) is an error naming the file, the column,
    the first such row and the likely unit (see :func:`check_time_scale`).

    Parameters
    ----------
    df : DataFrame
        Log with canonical names.
    units : mapping or None
        ``{column_or_group: unit}``; groups are ``flux`` (the three fluxgate axes) and ``mag``;
        ``time`` takes ``s``, ``ms``, ``us`` or ``ns``.
    source : str
        File name quoted in errors.
    rows : mapping, optional
        Where the rows are in the file (see :func:`row_location`).

    Returns
    -------
    DataFrame
        The same frame, converted in place.
    """
    units = dict(units or {})
    for key, unit in units.items():
        # The parameter as a caller spells it (units={'flux': 'uT'}; the CLI: --units flux=uT).
        given = f"units={{{key!r}: {unit!r}}}"
        if key == "time":
            ticks = time_ticks(unit, what=f"{source}: {given}")
            if "time" not in df.columns:
                raise InputError(f"{source}: {given}: no column 'time' in the log")
            if df.attrs.get("_time_converted"):
                raise InputError(f"{source}: {given}: column 'time' holds date-times,"
                                 " already converted to seconds; drop the time unit")
            df["time"] = df["time"].astype(np.float64) / ticks
            continue
        factor = unit_factor(unit, what=f"{source}: {given}")
        cols = UNIT_GROUPS.get(key, (key,))
        present = [c for c in cols if c in df.columns]
        if not present:
            raise InputError(f"{source}: {given}: no column {key!r} in the log")
        for c in present:
            if CANONICAL_COLUMNS.get(c, "nT") != "nT":
                raise InputError(f"{source}: {given}: column {c!r} is not a field in nT")
            df[c] = df[c].astype(np.float64) * factor
    if "time" in df.columns and "time" not in units:
        check_time_scale(df["time"], source, rows)
    return df


#: Median ``|time|`` [s] above which a time is taken for epoch ms / us / ns (the year 5100).
EPOCH_TIME_LIMIT_S = 1e11


def check_time_scale(t: pd.Series, source: str, rows: Mapping[str, Any] | None = None) -> None:
    """Refuse a ``time`` column whose values look like epoch ms, us or ns instead of seconds.

    Seconds since 1970 are about 1.8e9 today; milliseconds 1.8e12, microseconds 1.8e15,
    nanoseconds 1.8e18.  A median ``|time|`` above :data:`EPOCH_TIME_LIMIT_S` names the likely
    unit and ``units={'time': UNIT}``.  Isolated huge values are left to the time checks of
    :func:`aeromag.io.read_log` (which name their row).

    Parameters
    ----------
    t : Series
        The time column (numbers).
    source : str
        File name quoted in the error.
    rows : mapping, optional
        Where the rows are in the file.
    """
    if t.dtype.kind not in "fiu":
        return
    v = np.abs(t.to_numpy(dtype=np.float64))
    fin = np.isfinite(v)
    if not fin.any():
        return
    med = float(np.median(v[fin]))
    if med <= EPOCH_TIME_LIMIT_S:
        return
    unit = "ms" if med < 1e14 else "us" if med < 1e17 else "ns"
    i = int(np.flatnonzero(fin & (v > EPOCH_TIME_LIMIT_S))[0])
    raise InputError(
        f"{clean(source)}: column 'time', {row_location(rows, i)}: time"
        f" {plain_number(t.iloc[i])} is not seconds (median {med:.3g}, beyond the year 5000);"
        f" it looks like {unit} since 1970: pass units={{'time': '{unit}'}}")
