"""WGS84 geodesy: the one geodetic <-> ECEF <-> local north-east-down module of the package.

Geodetic coordinates are WGS84 latitude and longitude (degrees) and height above the ellipsoid
(m).  The geodetic <-> ECEF conversion goes through one pyproj Transformer (EPSG:4979 ->
EPSG:4978, built once and cached); ECEF -> NED is the rotation at the origin.  Nothing treats
degrees as metres, so everything holds anywhere on Earth (UTM zone boundaries, high latitude).
"""

from __future__ import annotations

import functools

import numpy as np
from pyproj import Transformer

__all__ = ["geodetic_to_ecef", "ecef_to_geodetic", "ecef_to_ned_matrix", "geodetic_to_ned",
           "ned_to_geodetic", "utm_epsg", "project", "unproject"]

Origin = tuple[float, float, float]


@functools.lru_cache(maxsize=1)
def _ecef_transformer() -> Transformer:
    """WGS84 geographic 3-D (EPSG:4979) -> WGS84 ECEF (EPSG:4978), built once."""
    return Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)


def geodetic_to_ecef(lat: np.ndarray, lon: np.ndarray, alt: np.ndarray) -> np.ndarray:
    """Convert WGS84 geodetic coordinates to ECEF.

    Parameters
    ----------
    lat, lon : array_like
        Latitude and longitude, degrees (WGS84).
    alt : array_like
        Height above the WGS84 ellipsoid, m.

    Returns
    -------
    ndarray, shape (n, 3)
        ECEF X, Y, Z, m.
    """
    lat_a, lon_a, alt_a = np.broadcast_arrays(
        *(np.atleast_1d(np.asarray(v, dtype=np.float64)) for v in (lat, lon, alt)))
    x, y, z = _ecef_transformer().transform(lon_a, lat_a, alt_a)
    return np.column_stack([np.asarray(x), np.asarray(y), np.asarray(z)])


def ecef_to_geodetic(ecef: np.ndarray) -> np.ndarray:
    """Convert ECEF coordinates to WGS84 geodetic.

    Parameters
    ----------
    ecef : ndarray, shape (n, 3)
        ECEF X, Y, Z, m.

    Returns
    -------
    ndarray, shape (n, 3)
        Latitude [deg], longitude [deg], ellipsoidal height [m].
    """
    e = np.atleast_2d(np.asarray(ecef, dtype=np.float64))
    lon, lat, h = _ecef_transformer().transform(e[:, 0], e[:, 1], e[:, 2], direction="INVERSE")
    return np.column_stack([np.asarray(lat), np.asarray(lon), np.asarray(h)])


def ecef_to_ned_matrix(lat0: float, lon0: float) -> np.ndarray:
    """Rotation from ECEF to local north-east-down axes at a geodetic origin.

    Parameters
    ----------
    lat0, lon0 : float
        Geodetic latitude and longitude of the origin, degrees.

    Returns
    -------
    ndarray, shape (3, 3)
        Rows are the north, east and down unit vectors in ECEF (``ned = R @ (ecef - o)``).
    """
    ph, la = np.deg2rad(lat0), np.deg2rad(lon0)
    sp, cp, sl, cl = np.sin(ph), np.cos(ph), np.sin(la), np.cos(la)
    return np.array([
        [-sp * cl, -sp * sl, cp],
        [-sl, cl, 0.0],
        [-cp * cl, -cp * sl, -sp],
    ])


def geodetic_to_ned(lat: np.ndarray, lon: np.ndarray, alt: np.ndarray, origin: Origin
                    ) -> np.ndarray:
    """Convert geodetic coordinates to a local NED frame (exact, via ECEF).

    Parameters
    ----------
    lat, lon : array_like
        Latitude and longitude, degrees (WGS84).
    alt : array_like
        Ellipsoidal height, m.
    origin : (float, float, float)
        Origin latitude [deg], longitude [deg] and height [m].

    Returns
    -------
    ndarray, shape (n, 3)
        North, east, down, m.
    """
    ecef = geodetic_to_ecef(lat, lon, alt)
    o = geodetic_to_ecef(*origin)[0]
    return (ecef - o) @ ecef_to_ned_matrix(origin[0], origin[1]).T


def ned_to_geodetic(ned: np.ndarray, origin: Origin) -> np.ndarray:
    """Convert local NED coordinates back to WGS84 geodetic (exact, via ECEF).

    Parameters
    ----------
    ned : ndarray, shape (n, 3)
        North, east, down, m.
    origin : (float, float, float)
        Latitude [deg], longitude [deg], ellipsoidal height [m] of the NED origin.

    Returns
    -------
    ndarray, shape (n, 3)
        Latitude [deg], longitude [deg], height [m].
    """
    o = geodetic_to_ecef(*origin)[0]
    ecef = np.atleast_2d(np.asarray(ned, dtype=np.float64)) @ ecef_to_ned_matrix(
        origin[0], origin[1]) + o
    return ecef_to_geodetic(ecef)


def utm_epsg(lat: np.ndarray, lon: np.ndarray) -> int:
    """EPSG code of the WGS84 UTM zone that holds the centre of the given positions.

    Parameters
    ----------
    lat, lon : array_like
        Latitude and longitude, degrees (WGS84).

    Returns
    -------
    int
        326ZZ (northern hemisphere) or 327ZZ (southern), ZZ the UTM zone of the centre
        (median position; Norway and Svalbard exceptions not applied).
    """
    la = np.asarray(lat, dtype=np.float64)
    lo = np.asarray(lon, dtype=np.float64)
    ok = np.isfinite(la) & np.isfinite(lo)
    if not ok.any():
        raise ValueError("no finite position to choose a UTM zone from")
    lat_c = float(np.median(la[ok]))
    lon_c = float(np.median(((lo[ok] + 180.0) % 360.0) - 180.0))
    zone = min(int((lon_c + 180.0) // 6.0) + 1, 60)
    return (32600 if lat_c >= 0 else 32700) + zone


@functools.lru_cache(maxsize=8)
def _projector(epsg: int) -> Transformer:
    """WGS84 geographic 2-D (EPSG:4326) -> the projected CRS ``epsg``, built once."""
    return Transformer.from_crs("EPSG:4326", f"EPSG:{int(epsg)}", always_xy=True)


def project(lat: np.ndarray, lon: np.ndarray, epsg: int) -> tuple[np.ndarray, np.ndarray]:
    """Project WGS84 positions into a projected CRS (exact, through pyproj).

    Parameters
    ----------
    lat, lon : array_like
        Latitude and longitude, degrees (WGS84).
    epsg : int
        EPSG code of the projected CRS (e.g. from :func:`utm_epsg`).

    Returns
    -------
    x_m, y_m : ndarray
        Easting and northing, m (NaN where the position is NaN).
    """
    x, y = _projector(int(epsg)).transform(np.asarray(lon, dtype=np.float64),
                                           np.asarray(lat, dtype=np.float64))
    return np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)


def unproject(x_m: np.ndarray, y_m: np.ndarray, epsg: int) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`project`: projected metres back to WGS84 latitude and longitude.

    Parameters
    ----------
    x_m, y_m : array_like
        Easting and northing, m, in ``epsg``.
    epsg : int
        EPSG code of the projected CRS.

    Returns
    -------
    lat, lon : ndarray
        Latitude and longitude, degrees (WGS84).
    """
    lon, lat = _projector(int(epsg)).transform(np.asarray(x_m, dtype=np.float64),
                                               np.asarray(y_m, dtype=np.float64),
                                               direction="INVERSE")
    return np.asarray(lat, dtype=np.float64), np.asarray(lon, dtype=np.float64)
