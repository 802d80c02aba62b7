"""IGRF total intensity at each survey sample (IGRF-14 through ``ppigrf``), vectorised.

The evaluation is :func:`aeromag._core.igrf.igrf_ned` (exact on a small lattice of nodes at
each UTC midnight, interpolated to the samples to better than 0.01 nT), the one the compass
reference uses too. Dates outside IGRF-14's coefficients (1900-2030) are refused.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass

import numpy as np

from .._core.igrf import IGRF_YEARS, igrf_total
from ..errors import InputError

__all__ = ["IGRFResult", "igrf_total_intensity", "parse_date", "IGRF_YEARS"]


@dataclass
class IGRFResult:
    """IGRF total intensity at the samples.

    Attributes
    ----------
    igrf_nT : ndarray
        Total intensity [nT].
    model : str
        ``"IGRF-14"``.
    dates : list of str
        UTC dates evaluated (ISO).
    """

    igrf_nT: np.ndarray
    model: str
    dates: list[str]

    def to_dict(self) -> dict:
        """JSON-ready form (OUT.json ``igrf``)."""
        return {"model": self.model, "package": "ppigrf",
                "date": self.dates[0] if len(self.dates) == 1 else self.dates,
                "mean_nT": float(np.nanmean(self.igrf_nT))}


def parse_date(date: str) -> _dt.date:
    """A ``YYYY-MM-DD`` date inside IGRF-14's range.

    Parameters
    ----------
    date : str
        The date.

    Returns
    -------
    datetime.date

    Raises
    ------
    InputError
        Not a date, or outside 1900-2030.
    """
    try:
        d = _dt.datetime.strptime(str(date).strip(), "%Y-%m-%d").date()
    except ValueError:
        raise InputError(f"--date {date}: not a date; write YYYY-MM-DD, e.g. --date "
                         "2014-11-02") from None
    if not (IGRF_YEARS[0] <= d.year < IGRF_YEARS[1]):
        raise InputError(f"--date {date}: outside IGRF-14 ({IGRF_YEARS[0]:.0f}-"
                         f"{IGRF_YEARS[1]:.0f})")
    return d


def igrf_total_intensity(lat: np.ndarray, lon: np.ndarray, height_m: np.ndarray,
                         time_s: np.ndarray | float) -> IGRFResult:
    """IGRF-14 total intensity at positions, heights and times.

    Parameters
    ----------
    lat, lon : ndarray, shape (n,)
        Geodetic latitude and longitude [deg, WGS84].
    height_m : ndarray, shape (n,) or float
        Height above the WGS84 ellipsoid [m].
    time_s : ndarray, shape (n,) or float
        UTC seconds since 1970 (one value: the same time for every sample).

    Returns
    -------
    IGRFResult
        NaN where the position is not finite.

    Raises
    ------
    InputError
        A time outside IGRF-14 or no finite position.
    """
    t = np.broadcast_to(np.asarray(time_s, dtype=np.float64), np.shape(lat))
    f = igrf_total(lat, lon, height_m, t)
    tt = t[np.isfinite(f)]
    d0 = _dt.datetime.fromtimestamp(float(tt.min()), _dt.UTC).date()
    d1 = _dt.datetime.fromtimestamp(float(tt.max()), _dt.UTC).date()
    dates = [(d0 + _dt.timedelta(days=k)).isoformat() for k in range((d1 - d0).days + 1)]
    return IGRFResult(f, "IGRF-14", dates)
