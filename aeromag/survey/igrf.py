"""IGRF total intensity at each survey sample (IGRF-14 through ``ppigrf``), vectorised.

The main field is smooth over a survey (a few nT/km, a curvature of about 1e-3 nT/km^2), so
it is evaluated exactly (``ppigrf``: geodetic longitude, latitude, height in km, a date) on a
small lattice of latitude, longitude and height nodes (at most 0.05 degrees and 500 m apart)
at each UTC day of the survey, and interpolated (trilinear in space, linear in time) to the
samples: the interpolation error is below 0.01 nT, and a 1e6-sample survey costs a few
thousand model evaluations.  Dates outside IGRF-14's coefficients (1900-2030) are refused.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import RegularGridInterpolator

from ..errors import InputError

__all__ = ["BLOCK_SAMPLES", "IGRFResult", "igrf_total_intensity", "parse_date", "IGRF_YEARS"]

#: Years the IGRF-14 coefficients shipped with ppigrf cover.
IGRF_YEARS = (1900.0, 2030.0)
_DAY = 86400.0
#: Samples interpolated at a time.
BLOCK_SAMPLES = 500_000


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


def _nodes(v: np.ndarray, step: float) -> np.ndarray:
    lo, hi = float(np.min(v)), float(np.max(v))
    n = max(2, int(np.ceil((hi - lo) / step)) + 1)
    if hi - lo < 1e-9:
        return np.array([lo - step / 2, lo + step / 2])
    return np.linspace(lo, hi, n)


def _lattice_field(lat_n: np.ndarray, lon_n: np.ndarray, h_n: np.ndarray, when: _dt.datetime
                   ) -> np.ndarray:
    import ppigrf

    la, lo, hh = np.meshgrid(lat_n, lon_n, h_n, indexing="ij")
    e, n, u = ppigrf.igrf(lo.ravel(), la.ravel(), hh.ravel() / 1000.0, when)
    f = np.sqrt(np.asarray(e) ** 2 + np.asarray(n) ** 2 + np.asarray(u) ** 2).reshape(la.shape)
    return f


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
    lat = np.asarray(lat, dtype=np.float64)
    lon = np.asarray(lon, dtype=np.float64)
    h = np.broadcast_to(np.asarray(height_m, dtype=np.float64), lat.shape)
    t = np.broadcast_to(np.asarray(time_s, dtype=np.float64), lat.shape)
    ok = np.isfinite(lat) & np.isfinite(lon) & np.isfinite(h) & np.isfinite(t)
    if not ok.any():
        raise InputError("lat/lon/alt/time: no complete sample for the IGRF")
    lon_w = ((lon + 180.0) % 360.0) - 180.0
    tmin, tmax = float(t[ok].min()), float(t[ok].max())
    d0 = _dt.datetime.fromtimestamp(tmin, _dt.UTC).date()
    d1 = _dt.datetime.fromtimestamp(tmax, _dt.UTC).date()
    for d in (d0, d1):
        if not (IGRF_YEARS[0] <= d.year < IGRF_YEARS[1]):
            raise InputError(f"time: {d} is outside IGRF-14 ({IGRF_YEARS[0]:.0f}-"
                             f"{IGRF_YEARS[1]:.0f})")
    days = [d0 + _dt.timedelta(days=k) for k in range((d1 - d0).days + 2)]
    lat_n = _nodes(lat[ok], 0.05)
    lon_n = _nodes(lon_w[ok], 0.05)
    h_n = _nodes(h[ok], 500.0)
    epoch = _dt.datetime(1970, 1, 1)
    t_nodes = np.array([(_dt.datetime(d.year, d.month, d.day) - epoch).total_seconds()
                        for d in days])
    grids = [_lattice_field(lat_n, lon_n, h_n, _dt.datetime(d.year, d.month, d.day))
             for d in days]
    interps = [RegularGridInterpolator((lat_n, lon_n, h_n), g, bounds_error=False,
                                       fill_value=None) for g in grids]
    idx = np.flatnonzero(ok)
    f = np.empty(idx.size)
    # Only the two days around each sample, a block of samples at a time: the memory is the
    # block's, not (days x samples) (13 days x 1e7 samples were 1 GB, and 4 GB of the
    # interpolator's temporaries); each sample's value is the same as evaluated all at once.
    for a in range(0, idx.size, BLOCK_SAMPLES):
        k = idx[a:a + BLOCK_SAMPLES]
        tt = t[k]
        j = np.clip(np.searchsorted(t_nodes, tt, side="right") - 1, 0, len(days) - 2)
        w = (tt - t_nodes[j]) / _DAY
        pts = np.column_stack([lat[k], lon_w[k], h[k]])
        fb = np.empty(k.size)
        for d in np.unique(j):
            m = j == d
            p = pts[m]
            fb[m] = (1 - w[m]) * interps[d](p) + w[m] * interps[d + 1](p)
        f[a:a + BLOCK_SAMPLES] = fb
    out = np.full(lat.shape, np.nan)
    out[ok] = f
    return IGRFResult(out, "IGRF-14", [d.isoformat() for d in days[:-1]])
