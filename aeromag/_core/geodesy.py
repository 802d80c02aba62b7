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
           "ned_to_geodetic"]

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
