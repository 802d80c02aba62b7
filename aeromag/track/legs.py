"""Which mission leg each sample belongs to."""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd

from ..errors import InputError
from .geometry import cross_track

__all__ = ["DEFAULT_WAYPOINT_RADIUS_M", "assign_legs", "labels_from_column"]

log = logging.getLogger(__name__)

#: Default waypoint radius, m (see the leg-assignment rule).
DEFAULT_WAYPOINT_RADIUS_M = 5.0


def _effective_radius(ned: np.ndarray, radius: float) -> float:
    """Waypoint radius, enlarged when successive samples are far apart."""
    if len(ned) < 2:
        return radius
    steps = np.linalg.norm(np.diff(ned, axis=0), axis=1)
    steps = steps[np.isfinite(steps)]
    if steps.size == 0:
        return radius
    eff = max(radius, 1.5 * float(np.percentile(steps, 95)))
    if eff > radius:
        log.info("waypoint radius enlarged from %.2f m to %.2f m (sparse samples)", radius, eff)
    return eff


def assign_legs(
    ned: np.ndarray, waypoints: np.ndarray, *, waypoint_radius_m: float = DEFAULT_WAYPOINT_RADIUS_M
) -> np.ndarray:
    """Assign each sample to a mission leg (see the module docstring for the rule).

    Parameters
    ----------
    ned : ndarray, shape (n, 3)
        Antenna positions, NED, m.
    waypoints : ndarray, shape (m, 3)
        Plan waypoints, NED, m.
    waypoint_radius_m : float
        Radius of the sphere around each waypoint inside which the vehicle is turning, m.

    Returns
    -------
    ndarray of int, shape (n,)
        Leg index per sample, -1 for none.
    """
    n = len(ned)
    n_legs = len(waypoints) - 1
    labels = np.full(n, -1, dtype=np.int64)
    if n < 2 or n_legs < 1:
        return labels
    r = _effective_radius(ned, waypoint_radius_m)
    finite = np.isfinite(ned).all(axis=1)
    starts: list[np.ndarray] = []
    ends: list[np.ndarray] = []
    for k in range(n_legs):
        a, b = waypoints[k], waypoints[k + 1]
        d, _, _, along = cross_track(ned, a, b)
        length = float(np.linalg.norm(b - a))
        in_a = (np.linalg.norm(ned - a, axis=1) <= r) & finite
        in_b = (np.linalg.norm(ned - b, axis=1) <= r) & finite
        leave = np.r_[False, in_a[:-1] & ~in_a[1:]] & finite & (d <= along)
        starts.append(np.flatnonzero(leave))
        ends.append(np.flatnonzero(in_b | (along >= length)))
    pos, cur = 0, -1
    while True:
        best: tuple[int, int, int] | None = None
        for k in range(n_legs):
            j = int(np.searchsorted(starts[k], pos))
            if j == len(starts[k]):
                continue
            prio = 0 if k == cur + 1 else (1 if k == cur else 2 + abs(k - cur))
            cand = (int(starts[k][j]), prio, k)
            if best is None or cand < best:
                best = cand
        if best is None:
            break
        s, _, k = best
        j = int(np.searchsorted(ends[k], s + 1))
        e = int(ends[k][j]) if j < len(ends[k]) else n
        j = int(np.searchsorted(starts[k], s + 1))
        if j < len(starts[k]):
            e = min(e, int(starts[k][j]))
        labels[s:e] = k
        pos, cur = e, k
    return labels


def labels_from_column(log_df: pd.DataFrame, n_legs: int, source: str) -> np.ndarray:
    """Leg labels from the log's own ``leg`` column (empty or negative: no leg)."""
    vals = pd.to_numeric(log_df["leg"], errors="coerce").to_numpy(dtype=np.float64)
    ok = np.isfinite(vals) & (vals >= 0)
    frac = ok & (vals != np.round(vals))
    if frac.any():
        i = int(np.flatnonzero(frac)[0])
        raise InputError(f"{source}: column 'leg', line {i + 2}: {vals[i]!r} is not an integer"
                         " leg index")
    over = ok & (vals >= n_legs)
    if over.any():
        i = int(np.flatnonzero(over)[0])
        raise InputError(
            f"{source}: column 'leg', line {i + 2}: leg {int(vals[i])} but the plan has only"
            f" {n_legs} leg(s) (0-{n_legs - 1}); use the matching plan or drop the leg column"
        )
    return np.where(ok, vals, -1).astype(np.int64)
