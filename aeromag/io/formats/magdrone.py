"""SENSYS MagDrone R3 native CSV."""

from __future__ import annotations

import logging
import os
import re
from pathlib import Path

import numpy as np
import pandas as pd

from ...errors import InputError
from ..columns import FIELD_UNITS_TO_NT, check_unique_names, datetime_seconds, filled_cells
from ..csv import (
    check_text_file,
    not_utf8_message,
    open_quote_line,
    short_row,
    stray_quote_message,
    truncated_row_message,
)
from ..rows import ROWS_ATTR, row_location, rows_after_header
from ._native import check_made_names, interp_sparse, native_values

log = logging.getLogger(__name__)

_MAGDRONE_UNIT = re.compile(r"^\s*(.*?)\s*\[(.*)\]\s*$")

#: Time units of a MagDrone ``Timestamp [unit]`` header: seconds = value * num / den (a
#: division where exact, so that 65 ms is exactly the float nearest 0.065 s).
_TIME_UNITS: dict[str, tuple[float, float]] = {
    "ns": (1.0, 1e9), "us": (1.0, 1e6), "\u00b5s": (1.0, 1e6), "\u03bcs": (1.0, 1e6),
    "ms": (1.0, 1e3), "s": (1.0, 1.0), "sec": (1.0, 1.0), "min": (60.0, 1.0),
    "h": (3600.0, 1.0),
}


#: Empty fields a MagDrone row may have after the header's last column (rows end with ';').
_MAGDRONE_SPARE_FIELDS = 2
_SPARE = "\x00spare"


def _magdrone_header(p: Path) -> tuple[list[str], int, list[str]]:
    """Metadata lines, 0-based index of the header line and its column names.

    The file must be UTF-8 text; the header is the line whose first field is ``Timestamp``
    (quotes and a BOM allowed); trailing empty fields (rows ending with ``;``) are not
    columns.
    """
    import csv

    check_text_file(p, "MagDrone log")
    meta: list[str] = []
    try:
        with open(p, "rb") as fh:
            for i, raw in enumerate(fh):
                if i > 500:
                    break
                try:
                    line = raw.decode("utf-8").removeprefix("\ufeff")
                except UnicodeDecodeError:
                    raise InputError(not_utf8_message(p)) from None
                if line.lstrip().lstrip('"').startswith("Timestamp"):
                    fields = next(csv.reader([line.rstrip("\r\n")], delimiter=";"))
                    fields = [f.strip() for f in fields]
                    while fields and not fields[-1]:
                        fields.pop()
                    if any(not f for f in fields):
                        j = fields.index("")
                        raise InputError(f"{p}: line {i + 1}: column {j + 1} of the MagDrone"
                                         " header has no name; fix the header line")
                    return meta, i, fields
                if line.strip():
                    meta.append(line.strip())
    except OSError as exc:
        raise InputError(f"{p}: cannot read ({exc.strerror or exc})") from None
    raise InputError(f"{p}: no 'Timestamp [ms];...' header line in the first 500 lines: not a"
                     " MagDrone R3 log (give fmt=FORMAT if it is another format)")


#: Largest spread [s] of (GPS UTC - logger clock) over the fixes for the clock to be trusted.
GPS_CLOCK_SPREAD_S = 1.0


def _gps_utc(df: pd.DataFrame, t: np.ndarray, fix: np.ndarray, src: str,
             rows: dict | None) -> np.ndarray | None:
    """UTC seconds since 1970 of every row from the GPS date and time of the fixes.

    The logger clock (``Timestamp``) runs through; the GPS rows (``Quality`` > 0, a date) tie
    it to UTC: ``time = Timestamp + median(UTC - Timestamp)`` over the fixes.  None (the
    logger clock is kept, with a warning when GPS times exist) when there is no GPS date and
    time, or when the offsets spread more than :data:`GPS_CLOCK_SPREAD_S`.
    """
    if "GPSDate" not in df.columns:
        return None
    clock_col = next((c for c in df.columns if str(c).startswith("GPSTime_")), None)
    if clock_col is None and "GPSTime" not in df.columns:
        return None
    date = df["GPSDate"].astype(str).str.strip()
    ok = fix & ~date.isin(["0", "", "nan", "None"]).to_numpy() & np.isfinite(t)
    if not ok.any():
        return None
    if clock_col is not None:
        clock = df[clock_col].astype(str).str.strip()[ok]
    else:  # hhmmss.sss as a number
        v = native_values(df["GPSTime"], src, "GPSTime", rows)[ok]
        if not np.all(np.isfinite(v)) or np.any((v < 0) | (v >= 240000)):
            return None
        h, rest = np.divmod(v, 10000.0)
        m, sec = np.divmod(rest, 100.0)
        clock = pd.Series([f"{int(a):02d}:{int(b):02d}:{c:06.3f}" for a, b, c in
                           zip(h, m, sec, strict=True)], index=date.index[ok])
    stamp = date[ok] + " " + clock
    with np.errstate(all="ignore"):
        dt = pd.to_datetime(stamp, format="mixed", errors="coerce", utc=True)
    bad = dt.isna().to_numpy()
    if bad.any():
        i = int(np.flatnonzero(ok)[np.flatnonzero(bad)[0]])
        raise InputError(f"{src}: columns GPSDate/GPSTime, {row_location(rows, i)}: cannot read"
                         f" {stamp.iloc[int(np.flatnonzero(bad)[0])]!r} as a UTC date and time;"
                         " fix the row, or set its Quality to 0")
    with np.errstate(all="ignore"):
        off = datetime_seconds(dt, src, rows) - t[ok]
    spread = float(np.max(off) - np.min(off)) if np.all(np.isfinite(off)) else float("inf")
    if not spread <= GPS_CLOCK_SPREAD_S:
        log.warning("%s: the GPS UTC times disagree with the logger clock (Timestamp) by up"
                    " to %.3g s; time stays the logger clock (s since it started): check the"
                    " GPS columns", src, spread)
        return None
    return t + float(np.median(off))


def read_magdrone(path: str | os.PathLike[str], *, sensor: int = 1,
                  allow_truncated: bool = False) -> pd.DataFrame:
    """Read the native CSV of a SENSYS MagDrone R3 (metadata header, then a ``;`` table).

    The metadata lines before the ``Timestamp [ms];...`` header are kept in
    ``df.attrs["metadata"]``.  Canonical columns: ``time`` = ``Timestamp [ms]`` / 1000 [s since
    the logger started; another time unit in the header (ns, us, s, min, h) is converted, a
    missing or unknown one is an error]; ``flux_x/y/z`` = fluxgate ``B1x/B1y/B1z``
    (``sensor=2``: ``B2``), converted to nT from the unit in the header (the R3 writes nT; pT,
    uT/µT/μT, mT, G are converted, a missing or unknown unit is an error); the other fluxgate
    stays as ``B2x``... (or ``B1x``...).  A value of these columns, or of the GPS columns, that
    is not a number is an error naming its line (never silently NaN).  There is no scalar
    ``mag``: the pipeline then uses the fluxgate magnitude.  When GPS rows (``Quality`` > 0)
    give a UTC date and time (``GPSDate``, ``GPSTime [hh:mm:ss.sss]`` or ``GPSTime``
    hhmmss.sss), ``time`` becomes UTC seconds since 1970-01-01 (the logger clock tied to the
    GPS clock, see :func:`_gps_utc`) and the logger clock is kept as ``time_logger`` [s].
    GPS columns hold 0 on rows without a fix; there ``lat``/``lon`` [deg] are interpolated in
    time between fixes (Quality > 0), and ``Altitude`` (above mean sea level: the file holds
    no geoid separation) becomes ``alt_msl`` [m], not ``alt``.

    Parameters
    ----------
    path : path-like
        The MagDrone CSV.
    sensor : {1, 2}
        Fluxgate mapped to ``flux_x/y/z``.

    Returns
    -------
    DataFrame
    """
    p = Path(path)
    if sensor not in (1, 2):
        raise InputError(f"{p}: MagDrone fluxgate {sensor} does not exist; use 1 or 2")
    meta, header_at, fields = _magdrone_header(p)
    n = len(fields)
    cols = fields + [f"{_SPARE}{k}" for k in range(_MAGDRONE_SPARE_FIELDS)]
    short = short_row(p, header_at + 1, n, delimiter=";")
    if short is not None and not (short[2] and allow_truncated):
        raise InputError(truncated_row_message(p, short[0], short[1], n, short[2]))
    try:
        raw = pd.read_csv(p, sep=";", header=None, names=cols, skiprows=header_at + 1,
                          skipinitialspace=True, low_memory=False, index_col=False,
                          encoding="utf-8")
    except UnicodeDecodeError:
        raise InputError(not_utf8_message(p)) from None
    except pd.errors.EmptyDataError:
        raw = pd.DataFrame({c: pd.Series(dtype=np.float64) for c in cols})
    except (pd.errors.ParserError, ValueError, OverflowError) as exc:
        msg = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
        stray = open_quote_line(p, header_at + 1) if "inside string" in msg else None
        if stray is not None:
            raise InputError(stray_quote_message(p, stray)) from None
        raise InputError(f"{p}: cannot parse the MagDrone table ({msg}); every row needs"
                         f" {n} values separated by ';'") from None
    if short is not None:  # the last row, cut short: allowed
        raw = raw.iloc[:-1].reset_index(drop=True)
        log.warning("%s: line %d: the last row is cut short (%d of %d fields: the log ended"
                    " in the middle of a row); dropped it", p, short[0], short[1], n)
    spare_rows = rows_after_header(p, header_at + 1)
    for c in cols[n:]:
        filled = filled_cells(raw[c])
        if filled.any():
            i = int(np.flatnonzero(filled)[0])
            raise InputError(
                f"{p}: {row_location(spare_rows, i)}: more fields than the {n} columns of the"
                f" header (value {str(raw[c].iloc[i]).strip()!r} has no column); remove the"
                " extra value or add its name to the header")
    raw = raw.drop(columns=cols[n:])
    names: dict[str, str] = {}
    units: dict[str, str] = {}
    for c in raw.columns:
        m = _MAGDRONE_UNIT.match(str(c))
        base, unit = (m.group(1), m.group(2)) if m else (str(c).strip(), "")
        if base in names.values():  # e.g. 'GPSTime' and 'GPSTime [hh:mm:ss.sss]'
            base = f"{base}_{unit}".replace(":", "").replace(".", "")
        names[c] = base
        units[base] = unit
    df = raw.rename(columns=names)
    src = str(p)
    rows = rows_after_header(p, header_at + 1)
    check_unique_names([str(c) for c in df.columns], src, what="MagDrone header")
    if "Timestamp" not in df.columns:
        raise InputError(f"{p}: no 'Timestamp' column in the MagDrone table")
    made = {"time": "Timestamp (and the GPS clock)", "time_logger": "Timestamp",
            **{f"flux_{a}": f"B{sensor}{a}" for a in "xyz"}}
    if "Latitude" in df.columns and "Longitude" in df.columns:
        made.update(lat="Latitude", lon="Longitude", alt_msl="Altitude")
    check_made_names(list(raw.columns), made, src, "MagDrone", header_at + 1)
    tu = units.get("Timestamp", "").strip()
    scale = _TIME_UNITS.get(tu.lower())
    if scale is None:
        raise InputError(
            f"{p}: column 'Timestamp' has {'unknown unit ' + repr(tu) if tu else 'no unit'} in"
            f" the header; expected one of {', '.join(_TIME_UNITS)} as in 'Timestamp [ms]'")
    t = native_values(df.pop("Timestamp"), src, f"Timestamp [{tu}]", rows)
    t = t * scale[0] / scale[1]
    df.insert(0, "time", t)
    out_units = {"time": "s"}
    for axis in "xyz":
        col = f"B{sensor}{axis}"
        if col not in df.columns:
            raise InputError(f"{p}: MagDrone column {col!r} not found; columns: "
                             + ", ".join(map(str, df.columns)))
        unit = units.get(col, "").strip()
        factor = FIELD_UNITS_TO_NT.get(unit.lower())
        if factor is None:
            raise InputError(
                f"{p}: column {col!r} has {'unknown unit ' + repr(unit) if unit else 'no unit'}"
                f" in the header; expected a field unit such as nT, as in '{col} [nT]'")
        df[f"flux_{axis}"] = native_values(df.pop(col), src, f"{col} [{unit}]", rows) * factor
        out_units[f"flux_{axis}"] = "nT"
    if "Latitude" in df.columns and "Longitude" in df.columns:
        lat = native_values(df.pop("Latitude"), src, "Latitude", rows)
        lon = native_values(df.pop("Longitude"), src, "Longitude", rows)
        q = (native_values(df["Quality"], src, "Quality", rows)
             if "Quality" in df.columns else np.where((lat != 0) | (lon != 0), 1.0, 0.0))
        fix = q > 0
        df["lat"] = interp_sparse(t, np.where(fix, lat, np.nan))
        df["lon"] = interp_sparse(t, np.where(fix, lon, np.nan))
        if "Altitude" in df.columns:
            alt = native_values(df.pop("Altitude"), src, "Altitude", rows)
            df["alt_msl"] = interp_sparse(t, np.where(fix, alt, np.nan))
        out_units.update(lat="deg", lon="deg", alt_msl="m")
        utc = _gps_utc(df, t, fix, src, rows)
        if utc is not None:
            df.insert(1, "time_logger", t)
            df["time"] = utc
            out_units.update(time="s since 1970-01-01 UTC", time_logger="s")
    df.attrs["metadata"] = meta
    df.attrs["units"] = {**units, **out_units}
    df.attrs[ROWS_ATTR] = rows
    return df
