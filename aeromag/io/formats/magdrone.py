"""SENSYS MagDrone R3 native CSV."""

from __future__ import annotations

import logging
import os
import re
from pathlib import Path

import numpy as np
import pandas as pd

from ...errors import InputError
from ..columns import (
    FIELD_UNITS_TO_NT,
    check_unique_names,
)
from ..rows import ROWS_ATTR, rows_after_header
from ._native import interp_sparse, native_values

log = logging.getLogger(__name__)

_MAGDRONE_UNIT = re.compile(r"^\s*(.*?)\s*\[(.*)\]\s*$")

#: Time units of a MagDrone ``Timestamp [unit]`` header: seconds = value * num / den (a
#: division where exact, so that 65 ms is exactly the float nearest 0.065 s).
_TIME_UNITS: dict[str, tuple[float, float]] = {
    "ns": (1.0, 1e9), "us": (1.0, 1e6), "\u00b5s": (1.0, 1e6), "\u03bcs": (1.0, 1e6),
    "ms": (1.0, 1e3), "s": (1.0, 1.0), "sec": (1.0, 1.0), "min": (60.0, 1.0),
    "h": (3600.0, 1.0),
}


def read_magdrone(path: str | os.PathLike[str], *, sensor: int = 1) -> pd.DataFrame:
    """Read the native CSV of a SENSYS MagDrone R3 (metadata header, then a ``;`` table).

    The metadata lines before the ``Timestamp [ms];...`` header are kept in
    ``df.attrs["metadata"]``.  Canonical columns: ``time`` = ``Timestamp [ms]`` / 1000 [s since
    the logger started; another time unit in the header (ns, us, s, min, h) is converted, a
    missing or unknown one is an error]; ``flux_x/y/z`` = fluxgate ``B1x/B1y/B1z``
    (``sensor=2``: ``B2``), converted to nT from the unit in the header (the R3 writes nT; pT,
    uT/µT/μT, mT, G are converted, a missing or unknown unit is an error); the other fluxgate
    stays as ``B2x``... (or ``B1x``...).  A value of these columns, or of the GPS columns, that
    is not a number is an error naming its line (never silently NaN).  There is no scalar
    ``mag``: the pipeline then uses the fluxgate magnitude.  GPS columns hold 0 on rows
    without a fix; there ``lat``/``lon`` [deg] are interpolated in time between fixes
    (Quality > 0), and ``Altitude`` (above mean sea level: the file holds no geoid separation)
    becomes ``alt_msl`` [m], not ``alt``.

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
    meta: list[str] = []
    header_at = None
    with open(p, encoding="utf-8", errors="replace") as fh:
        for i, line in enumerate(fh):
            if line.lstrip().startswith("Timestamp"):
                header_at = i
                break
            if line.strip():
                meta.append(line.strip())
            if i > 500:
                break
    if header_at is None:
        raise InputError(f"{p}: no 'Timestamp [ms];...' header line: not a MagDrone R3 log")
    try:
        raw = pd.read_csv(p, sep=";", skiprows=header_at, skipinitialspace=True,
                          low_memory=False)
    except (pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        msg = str(exc).strip().splitlines()[-1]
        raise InputError(f"{p}: cannot parse the MagDrone table ({msg})") from None
    raw = raw.loc[:, [c for c in raw.columns if not str(c).startswith("Unnamed")]]
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
    df.attrs["metadata"] = meta
    df.attrs["units"] = {**units, **out_units}
    df.attrs[ROWS_ATTR] = rows
    return df
