"""The one IGRF evaluation of aeromag: IGRF-14 (through ``ppigrf``) at many samples, vectorised.

The compass reference (:func:`aeromag.compass.igrf_field`: the field vector at a date) and the
survey chain (:func:`aeromag.survey.igrf.igrf_total_intensity`: the total intensity at each
sample's time) both call :func:`igrf_ned`.

The main field is smooth over a survey (a few nT/km, a curvature of about 1e-3 nT/km^2), so a
log of many samples is evaluated exactly on a small lattice of latitude, longitude and height
nodes (at most 0.05 degrees and 500 m apart) at each UTC midnight it spans, and interpolated
(trilinear in space, linear in time) to the samples: the interpolation error is below 0.01 nT
and a 1e6-sample survey costs a few thousand model evaluations. When the samples are fewer
than the lattice's nodes (a few positions, or a log spread over a continent) the model is
evaluated at the samples themselves.
"""

from __future__ import annotations

import datetime as _dt

import numpy as np

from ..errors import InputError

__all__ = ["BLOCK_SAMPLES", "IGRF_YEARS", "decimal_year", "igrf_ned", "igrf_total"]

#: Years the IGRF-14 coefficients shipped with ppigrf cover, [first, last).
IGRF_YEARS = (1900.0, 2030.0)
_DAY = 86400.0
_EPOCH = _dt.datetime(1970, 1, 1)
_STEP_DEG = 0.05
_STEP_M = 500.0
#: Samples interpolated at a time (memory is the block's, whatever the log's length).
BLOCK_SAMPLES = 500_000


def decimal_year(when: _dt.datetime) -> float:
    """The decimal year of a (naive UTC) datetime, as IGRF-14's range is stated.

    Parameters
    ----------
    when : datetime.datetime
        The epoch (UTC).

    Returns
    -------
    float
        Year plus the fraction of the year elapsed [yr].
    """
    return when.year + (when.timetuple().tm_yday - 1) / 365.25


def _ppigrf():
    try:
        import ppigrf
    except ImportError:
        raise InputError("the IGRF needs the ppigrf package, a dependency of aeromag that is "
                         "missing here: pip install ppigrf (or reinstall aeromag)") from None
    return ppigrf


def _nodes(v: np.ndarray, step: float) -> np.ndarray:
    lo, hi = float(np.min(v)), float(np.max(v))
    if hi - lo < 1e-9:
        return np.array([lo - step / 2, lo + step / 2])
    return np.linspace(lo, hi, max(2, int(np.ceil((hi - lo) / step)) + 1))


def _field(ppigrf, lat: np.ndarray, lon: np.ndarray, h_m: np.ndarray, when: _dt.datetime
           ) -> np.ndarray:
    """IGRF (north, east, down) [nT] at points, shape (n, 3)."""
    e, n, u = ppigrf.igrf(lon, lat, h_m / 1000.0, when)
    e, n, u = (np.asarray(x, dtype=np.float64).reshape(-1) for x in (e, n, u))
    return np.column_stack([n, e, -u])


def _evaluator(ppigrf, lat: np.ndarray, lon: np.ndarray, h: np.ndarray, when: _dt.datetime,
               total: bool):
    """``f(idx)``: the field (``(len(idx), 3)``, or its intensity) at samples ``idx``.

    On a lattice (an interpolator built once) when the samples outnumber its nodes, else
    evaluated exactly at all samples once.
    """
    lat_n, lon_n, h_n = _nodes(lat, _STEP_DEG), _nodes(lon, _STEP_DEG), _nodes(h, _STEP_M)
    if lat.size <= lat_n.size * lon_n.size * h_n.size:
        exact = _field(ppigrf, lat, lon, h, when)
        if total:
            exact = np.linalg.norm(exact, axis=1)
        return lambda idx: exact[idx]
    from scipy.interpolate import RegularGridInterpolator

    la, lo, hh = np.meshgrid(lat_n, lon_n, h_n, indexing="ij")
    g = _field(ppigrf, la.ravel(), lo.ravel(), hh.ravel(), when).reshape(*la.shape, 3)
    if total:  # the intensity is as smooth as the components: interpolate one value, not 3
        g = np.linalg.norm(g, axis=-1)
    interp = RegularGridInterpolator((lat_n, lon_n, h_n), g, bounds_error=False,
                                     fill_value=None)
    return lambda idx: interp(np.column_stack([lat[idx], lon[idx], h[idx]]))


def igrf_ned(lat_deg: np.ndarray, lon_deg: np.ndarray, height_m: np.ndarray | float,
             when: _dt.datetime | np.ndarray | float) -> np.ndarray:
    """IGRF-14 main field (north, east, down) at positions, heights and times.

    Parameters
    ----------
    lat_deg, lon_deg : array_like, shape (n,)
        Geodetic latitude and longitude [deg, WGS84].
    height_m : array_like, shape (n,) or float
        Height above the WGS84 ellipsoid [m].
    when : datetime.datetime, or array_like of shape (n,) or float
        One epoch (naive UTC datetime) for every sample, or each sample's UTC time [s since
        1970]: the field is then interpolated linearly in time between UTC midnights.

    Returns
    -------
    ndarray, shape (n, 3)
        Field [nT]; NaN rows where a position, height or time is not finite.

    Raises
    ------
    InputError
        No complete sample, a latitude outside [-90, 90], an epoch outside IGRF-14
        (1900-2030), or ``ppigrf`` is not installed.

    Notes
    -----
    Samples are interpolated ``BLOCK_SAMPLES`` at a time and each only between the two UTC
    midnights around it, so memory is the block's, not (days x samples): a 13-day survey of
    1e7 samples held 3 GB of temporaries when every day was evaluated at every sample.
    """
    return _igrf(lat_deg, lon_deg, height_m, when, total=False)


def igrf_total(lat_deg: np.ndarray, lon_deg: np.ndarray, height_m: np.ndarray | float,
               when: _dt.datetime | np.ndarray | float) -> np.ndarray:
    """IGRF-14 total intensity at positions, heights and times (as :func:`igrf_ned`).

    Parameters
    ----------
    lat_deg, lon_deg : array_like, shape (n,)
        Geodetic latitude and longitude [deg, WGS84].
    height_m : array_like, shape (n,) or float
        Height above the WGS84 ellipsoid [m].
    when : datetime.datetime, or array_like of shape (n,) or float
        One epoch for every sample, or each sample's UTC time [s since 1970].

    Returns
    -------
    ndarray, shape (n,)
        Total intensity [nT]; NaN where a position, height or time is not finite.

    Raises
    ------
    InputError
        As :func:`igrf_ned`.
    """
    return _igrf(lat_deg, lon_deg, height_m, when, total=True)


def _igrf(lat_deg: np.ndarray, lon_deg: np.ndarray, height_m: np.ndarray | float,
          when: _dt.datetime | np.ndarray | float, *, total: bool) -> np.ndarray:
    lat = np.atleast_1d(np.asarray(lat_deg, dtype=np.float64))
    lon = np.atleast_1d(np.asarray(lon_deg, dtype=np.float64))
    h = np.broadcast_to(np.asarray(height_m, dtype=np.float64), lat.shape)
    one_epoch = isinstance(when, _dt.datetime)
    t = (np.zeros(lat.shape) if one_epoch
         else np.broadcast_to(np.asarray(when, dtype=np.float64), lat.shape))
    ok = np.isfinite(lat) & np.isfinite(lon) & np.isfinite(h) & np.isfinite(t)
    if not ok.any():
        raise InputError("lat/lon/alt/time: no complete sample for the IGRF")
    if np.abs(lat[ok]).max() > 90:
        raise InputError("lat: latitudes must be in [-90, 90] degrees")
    la, lo, hh = lat[ok], ((lon[ok] + 180.0) % 360.0) - 180.0, h[ok]
    if one_epoch:
        epochs = [when]
    else:
        tt = t[ok]
        d0 = _dt.datetime.fromtimestamp(float(tt.min()), _dt.UTC).date()
        d1 = _dt.datetime.fromtimestamp(float(tt.max()), _dt.UTC).date()
        epochs = [_dt.datetime(d.year, d.month, d.day)
                  for d in (d0 + _dt.timedelta(days=k) for k in range((d1 - d0).days + 2))]
    for e in (epochs[0], epochs[-1] - _dt.timedelta(days=0 if one_epoch else 1)):
        if not (IGRF_YEARS[0] <= decimal_year(e) < IGRF_YEARS[1]):
            raise InputError(f"time: {e.date()} is outside IGRF-14 ({IGRF_YEARS[0]:.0f}-"
                             f"{IGRF_YEARS[1]:.0f})")
    ppigrf = _ppigrf()
    fields = [_evaluator(ppigrf, la, lo, hh, e, total) for e in epochs]
    f = np.empty((la.size,) if total else (la.size, 3))
    t_nodes = np.array([(e - _EPOCH).total_seconds() for e in epochs])
    for a in range(0, la.size, BLOCK_SAMPLES):
        idx = np.arange(a, min(a + BLOCK_SAMPLES, la.size))
        if one_epoch:
            f[idx] = fields[0](idx)
            continue
        tb = tt[idx]
        j = np.clip(np.searchsorted(t_nodes, tb, side="right") - 1, 0, len(epochs) - 2)
        w = (tb - t_nodes[j]) / _DAY
        if not total:
            w = w[:, None]
        for d in np.unique(j):
            m = j == d
            f[idx[m]] = (1 - w[m]) * fields[d](idx[m]) + w[m] * fields[d + 1](idx[m])
    if ok.all():
        return f
    out = np.full((lat.size, *f.shape[1:]), np.nan)
    out[ok] = f
    return out
