"""Geometrics MagArrow native CSV."""

from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np
import pandas as pd

from ...errors import InputError
from ..csv import read_csv
from ..rows import ROWS_ATTR
from ._native import check_made_names, interp_sparse, native_values, parse_datetime_seconds

log = logging.getLogger(__name__)

def read_magarrow(path: str | os.PathLike[str], *, allow_truncated: bool = False
                  ) -> pd.DataFrame:
    """Read the native CSV of a Geometrics MagArrow.

    Canonical columns: ``time`` = ``Date`` + ``Time`` (UTC) in seconds since 1970-01-01;
    ``mag`` = ``Mag`` [nT] (NaN where ``MagValid`` is 0); ``lat``/``lon`` = ``Latitude`` /
    ``Longitude`` [deg] (the instrument interpolates them to every row); ``alt`` = height above
    the WGS84 ellipsoid [m] = ``Altitude`` (above mean sea level, from the GGA sentence) +
    ``HeightOverEllipsoid`` (which holds the GGA geoid separation), interpolated in time between
    the GNSS rows.  A value of ``Mag``, ``MagValid``, the position or height columns that is
    not a number (or a ``Date``/``Time`` that is not a date and time) is an error naming its
    line; the empty fields the rows end with are dropped.  The IMU channels (``CompassX/Y/Z``
    raw counts, gyroscope, accelerometer) are logged on sparse rows only and stay NaN
    elsewhere; the compass is not a calibrated fluxgate in nT, so no ``flux_*`` columns are
    made (map them with ``--col`` and ``--units`` if yours is calibrated).

    Parameters
    ----------
    path : path-like
        The MagArrow CSV.

    Returns
    -------
    DataFrame
    """
    p = Path(path)
    src = str(p)
    # The rows end with one or two delimiters more than the header has (GNSS rows two): the
    # CSV reader drops these empty fields (and refuses a row where one holds a value) instead
    # of shifting the columns.
    df = read_csv(p, spare_fields=_MAGARROW_SPARE_FIELDS, allow_truncated=allow_truncated)
    rows = df.attrs.get(ROWS_ATTR)
    missing = [c for c in ("Date", "Time", "Mag") if c not in df.columns]
    if missing:
        raise InputError(f"{p}: not a MagArrow log: missing column(s) {', '.join(missing)}")
    made = {"time": "Date and Time", "mag": "Mag"}
    made.update({k: v for k, v in (("lat", "Latitude"), ("lon", "Longitude"),
                                    ("alt", "Altitude + HeightOverEllipsoid"))
                 if v.split()[0] in df.columns})
    check_made_names(list(df.columns), made, src, "MagArrow")
    t = parse_datetime_seconds(df["Date"], df["Time"], src, rows)
    out = df.drop(columns=["Date", "Time"])
    out.attrs.clear()
    out.insert(0, "time", t)
    mag = native_values(out.pop("Mag"), src, "Mag", rows)
    if "MagValid" in out.columns:
        valid = native_values(out["MagValid"], src, "MagValid", rows)
        invalid = valid == 0
        if invalid.any():
            log.info("%s: %d sample(s) with MagValid=0 set to NaN", p, int(invalid.sum()))
            mag = np.where(invalid, np.nan, mag)
    out.insert(1, "mag", mag)
    rename = {"Latitude": "lat", "Longitude": "lon"}
    out = out.rename(columns={k: v for k, v in rename.items() if k in out.columns})
    for c in ("lat", "lon"):
        if c in out.columns:
            out[c] = native_values(out[c], src, {"lat": "Latitude", "lon": "Longitude"}[c],
                                    rows)
    if "Altitude" in out.columns:
        msl = native_values(out["Altitude"], src, "Altitude", rows)
        sep = (native_values(out["HeightOverEllipsoid"], src, "HeightOverEllipsoid", rows)
               if "HeightOverEllipsoid" in out.columns else np.zeros(len(out)))
        alt = interp_sparse(t, msl + sep)
        if np.isfinite(alt).any():
            out["alt"] = alt
    out.attrs["units"] = {"time": "s", "mag": "nT", "lat": "deg", "lon": "deg", "alt": "m"}
    out.attrs[ROWS_ATTR] = rows
    return out


#: Empty fields a MagArrow row may have after the header's last column (1 to 2 seen).
_MAGARROW_SPARE_FIELDS = 4
