"""The reference Earth field for the compass calibration: IGRF (via ``ppigrf``) or explicit.

IGRF-14 ships with the ``ppigrf`` package (a base dependency of aeromag); no download
is needed.  Its coefficients run from 1900.0 to 2030.0 (the last five years are the predicted
secular variation); a date outside is refused, not extrapolated.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._core.igrf import IGRF_YEARS, decimal_year, igrf_ned
from ..errors import InputError

__all__ = ["ReferenceField", "explicit_field", "igrf_field", "IGRF_RANGE"]

#: Years covered by the IGRF-14 coefficients that ppigrf ships.
IGRF_RANGE = IGRF_YEARS


@dataclass
class ReferenceField:
    """The expected Earth field at each sample, in north-east-down.

    Attributes
    ----------
    ned_nT : ndarray, shape (n, 3) or (3,)
        Field ``(north, east, down)`` [nT].
    info : dict
        How it was obtained, JSON-ready: ``{"source": "IGRF", "model": "IGRF-14", "date":
        ...}`` or ``{"source": "explicit", "intensity_nT":, "inclination_deg":,
        "declination_deg":}``, plus the mean intensity, inclination and declination.
    """

    ned_nT: np.ndarray
    info: dict[str, Any]

    @property
    def declination_deg(self) -> np.ndarray:
        """Declination at each sample [deg, east of true north]."""
        v = np.atleast_2d(self.ned_nT)
        return np.rad2deg(np.arctan2(v[:, 1], v[:, 0]))


def _summary(ned: np.ndarray) -> dict[str, float]:
    v = np.atleast_2d(ned).mean(axis=0)
    h = float(np.hypot(v[0], v[1]))
    return {"intensity_nT": float(np.linalg.norm(v)),
            "inclination_deg": float(np.rad2deg(np.arctan2(v[2], h))),
            "declination_deg": float(np.rad2deg(np.arctan2(v[1], v[0])))}


def explicit_field(intensity_nT: float, inclination_deg: float, declination_deg: float
                   ) -> ReferenceField:
    """A constant reference field from intensity, inclination and declination.

    Parameters
    ----------
    intensity_nT : float
        Total intensity F [nT], > 0.
    inclination_deg : float
        Inclination I [deg], positive down, in [-90, 90].
    declination_deg : float
        Declination D [deg], positive east of true north.

    Returns
    -------
    ReferenceField
        ``ned_nT`` of shape (3,).

    Raises
    ------
    InputError
        Intensity not positive or inclination outside [-90, 90].
    """
    try:
        f, i, d = (float(x) for x in (intensity_nT, inclination_deg, declination_deg))
    except (TypeError, ValueError):
        raise InputError("earth_field=(F, I, D): the intensity (nT), inclination and "
                         "declination (degrees) must be numbers, got "
                         f"({intensity_nT!r}, {inclination_deg!r}, {declination_deg!r})"
                         ) from None
    if not (np.isfinite(f) and f > 0):
        raise InputError(f"earth_field: intensity must be a positive number of nT, got {f}")
    if not (np.isfinite(i) and -90 <= i <= 90):
        raise InputError(f"earth_field: inclination must be in [-90, 90] degrees, got {i}")
    if not np.isfinite(d):
        raise InputError(f"earth_field: declination must be a number of degrees, got {d}")
    ir, dr = np.deg2rad(i), np.deg2rad(d)
    ned = f * np.array([np.cos(ir) * np.cos(dr), np.cos(ir) * np.sin(dr), np.sin(ir)])
    return ReferenceField(ned, {"source": "explicit", "intensity_nT": f,
                                "inclination_deg": i, "declination_deg": d})


def _parse_date(date: str | _dt.date | _dt.datetime) -> _dt.datetime:
    if isinstance(date, _dt.datetime):
        return date
    if isinstance(date, _dt.date):
        return _dt.datetime(date.year, date.month, date.day)
    try:
        return _dt.datetime.strptime(str(date).strip(), "%Y-%m-%d")
    except ValueError:
        raise InputError(f"date={str(date)!r}: not a date; write YYYY-MM-DD, e.g."
                         " date='2024-06-15'") from None


def igrf_field(lat_deg: np.ndarray, lon_deg: np.ndarray, alt_m: np.ndarray | float,
               date: str | _dt.date | _dt.datetime) -> ReferenceField:
    """IGRF-14 main field at given positions and date.

    Parameters
    ----------
    lat_deg, lon_deg : array_like, shape (n,)
        Geodetic latitude and longitude [deg, WGS84].
    alt_m : array_like, shape (n,) or float
        Height above the WGS84 ellipsoid [m].
    date : str (YYYY-MM-DD) or date or datetime
        Date of the flight.

    Returns
    -------
    ReferenceField
        ``ned_nT`` of shape (n, 3).

    Raises
    ------
    InputError
        The date is not a date or outside the model's range (1900-2030), a position is not
        finite or out of range, or ``ppigrf`` is not installed.
    """
    when = _parse_date(date)
    if not (IGRF_RANGE[0] <= decimal_year(when) < IGRF_RANGE[1]):
        raise InputError(f"date='{when.date()}' is outside IGRF-14 ({IGRF_RANGE[0]:.0f}-"
                         f"{IGRF_RANGE[1]:.0f}); give the field with earth_field=(F, I, D)")
    lat = np.atleast_1d(np.asarray(lat_deg, dtype=np.float64))
    lon = np.atleast_1d(np.asarray(lon_deg, dtype=np.float64))
    alt = np.broadcast_to(np.asarray(alt_m, dtype=np.float64), lat.shape)
    if not (np.isfinite(lat).all() and np.isfinite(lon).all() and np.isfinite(alt).all()):
        raise InputError("lat/lon/alt: positions must be finite for the IGRF reference")
    if np.abs(lat).max(initial=0) > 90:
        raise InputError("lat: latitudes must be in [-90, 90] degrees")
    try:  # what is left to refuse is a missing ppigrf

        ned = igrf_ned(lat, lon, alt, when)
    except InputError as e:
        raise InputError(f"{e}; or give the field with earth_field=(F, I, D)") from None
    info = {"source": "IGRF", "model": "IGRF-14", "package": "ppigrf",
            "date": when.date().isoformat(), **_summary(ned)}
    return ReferenceField(ned, info)
