"""Keep a decoded leg while the vehicle still makes progress along it.

A second pass over the Viterbi labels of :mod:`aeromag.track.legs` (see :func:`continue_legs`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .._core.runs import run_bounds
from .geometry import cross_track

if TYPE_CHECKING:
    from .leg_model import LegModel

__all__ = ["CONTINUATION_WAYPOINT_MARGIN_M", "continue_legs"]

#: :func:`continue_legs` keeps no sample within this distance along the leg of either
#: waypoint, m: the approach to a waypoint (an autopilot's waypoint radius, ArduCopter's
#: WPNAV_RADIUS is 2 m) is the turn or hover there, not the pass.
CONTINUATION_WAYPOINT_MARGIN_M = 2.5


def continue_legs(labels: np.ndarray, ned: np.ndarray, vel: np.ndarray, waypoints: np.ndarray,
                  model: LegModel, *, horizontal_only: bool | None = None
                  ) -> np.ndarray:
    """Keep a leg while the vehicle still makes progress along it, even off its direction.

    The direction term of :func:`aeromag.track.legs.leg_evidence` drops a vehicle that veers
    more than about ``atan(1 / direction_ratio)`` off the leg (a disturbed pass), just when
    the track alarm matters.  Once on a leg, the evidence of the next sample should depend on
    that (a continuation), which a first-order Viterbi cannot express; this second pass does the
    equivalent: each decoded run of leg ``k`` is extended forward and backward over the
    contiguous unassigned samples that

    * move along the leg at more than ``min_speed_m_s`` (hover has no progress; the transit
      back along the line has negative progress),
    * lie between the leg's waypoints, at least ``CONTINUATION_WAYPOINT_MARGIN_M`` from either
      along the leg (a transit that leaves the leg at a waypoint, the approach and hover at a
      waypoint are not kept),
    * are within ``tolerance_m`` of the leg's line horizontally (and ``vertical_tolerance_m``
      vertically unless horizontal-only): take-off, landing and ground time are not kept.

    Parameters
    ----------
    labels : ndarray of int, shape (n,)
        Decoded legs (see :func:`decode_legs`), -1 for off plan.
    ned : ndarray, shape (n, 3)
        Antenna positions, NED, m.
    vel : ndarray, shape (n, 3)
        Velocities, m/s.
    waypoints : ndarray, shape (m, 3)
        Plan waypoints, NED, m.
    model : LegModel
        Parameters.
    horizontal_only : bool, optional
        Override ``model.horizontal_only``.

    Returns
    -------
    ndarray of int, shape (n,)
        Labels with the runs extended (a new array).
    """
    horiz = model.horizontal_only if horizontal_only is None else horizontal_only
    lab = np.array(labels, dtype=np.int64, copy=True)
    n = len(lab)
    starts, stops, vals = run_bounds(lab)
    if starts.size == 0:
        return lab
    assigned = np.flatnonzero(lab >= 0)
    r = CONTINUATION_WAYPOINT_MARGIN_M

    def ok_mask(sl: slice, k: int) -> np.ndarray:
        a, bb = waypoints[k], waypoints[k + 1]
        length = float(np.linalg.norm(bb - a))
        p, v = ned[sl], vel[sl]
        fin = np.isfinite(p).all(axis=1) & np.isfinite(v).all(axis=1)
        p = np.where(fin[:, None], p, 0.0)
        v = np.where(fin[:, None], v, 0.0)
        _, h, vv, along = cross_track(p, a, bb)
        u = (bb - a) / length
        if horiz:
            uh = np.r_[u[:2], 0.0]
            nh = float(np.linalg.norm(uh))
            u = uh / nh if nh > 0 else u
            v = np.c_[v[:, :2], np.zeros(len(v))]
        m = (fin & (v @ u > model.min_speed_m_s) & (along >= r) & (along <= length - r)
             & (np.abs(h) < model.tolerance_m))
        if not horiz:
            m &= np.abs(vv) < model.vertical_tolerance_m
        return m

    for s0, s1, k in zip(starts, stops, vals, strict=True):
        # forward: up to the next assigned sample
        j = np.searchsorted(assigned, s1)
        end = int(assigned[j]) if j < assigned.size else n
        if end > s1:
            m = ok_mask(slice(s1, end), int(k))
            stop = int(np.argmin(m)) if not m.all() else m.size
            lab[s1:s1 + stop] = k
        # backward: down to the previous assigned sample
        j = np.searchsorted(assigned, s0) - 1
        beg = int(assigned[j]) + 1 if j >= 0 else 0
        if s0 > beg:
            m = ok_mask(slice(beg, s0), int(k))[::-1]
            stop = int(np.argmin(m)) if not m.all() else m.size
            lab[s0 - stop:s0] = np.where(lab[s0 - stop:s0] < 0, k, lab[s0 - stop:s0])
    return lab
