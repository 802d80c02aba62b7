"""Plan geometry in the local north-east-down frame: waypoints and the distance to a leg's line.

``d = |(X - A) x (B - A)| / |B - A|`` for a leg from ``A`` to ``B`` and an antenna position
``X``, with its signed horizontal and vertical parts and the position along the leg (methods M2).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .._core.geodesy import geodetic_to_ned

__all__ = ["cross_track", "plan_ned"]


def cross_track(
    x: np.ndarray, a: np.ndarray, b: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Distance from points to the line through ``a`` and ``b`` and its parts (NED frame).

    ``d = |(x - a) x (b - a)| / |b - a|``.  The perpendicular offset is split into a horizontal
    part along ``down x u`` (``u`` the unit leg direction; positive to the right of travel) and a
    vertical part along ``u x (down x u)`` reversed (positive above the line).  For a vertical
    leg the horizontal axis is east.

    Parameters
    ----------
    x : ndarray, shape (n, 3) or (3,)
        Points, NED, m.
    a, b : ndarray, shape (3,)
        Line start and end, NED, m (distinct).

    Returns
    -------
    d, h, v, along : ndarray, shape (n,)
        3-D distance to the line [m], signed horizontal part [m], signed vertical part [m]
        (``hypot(h, v) == d``), and position along the line from ``a`` [m].
    """
    x = np.atleast_2d(np.asarray(x, dtype=np.float64))
    a = np.asarray(a, dtype=np.float64)
    ab = np.asarray(b, dtype=np.float64) - a
    length = float(np.linalg.norm(ab))
    if not length > 0:
        raise ValueError("cross_track: a and b must be distinct")
    u = ab / length
    rel = x - a
    d = np.linalg.norm(np.cross(rel, ab), axis=1) / length
    along = rel @ u
    down = np.array([0.0, 0.0, 1.0])
    hdir = np.cross(down, u)
    hn = float(np.linalg.norm(hdir))
    hdir = hdir / hn if hn > 1e-12 else np.array([0.0, 1.0, 0.0])
    vdir = np.cross(hdir, u)  # up for a horizontal leg
    h = rel @ hdir
    v = rel @ vdir
    return d, h, v, along


def plan_ned(plan: pd.DataFrame) -> np.ndarray:
    """Waypoints of a plan in the NED frame at its first waypoint.

    Parameters
    ----------
    plan : DataFrame
        ``lat``, ``lon`` [deg], ``alt`` [m].

    Returns
    -------
    ndarray, shape (n_waypoints, 3)
        North, east, down, m.
    """
    lat, lon, alt = (plan[c].to_numpy(dtype=np.float64) for c in ("lat", "lon", "alt"))
    return geodetic_to_ned(lat, lon, alt, (lat[0], lon[0], alt[0]))
