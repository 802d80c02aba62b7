"""The flight's constant horizontal offset from its plan, found by motion, not distance.

A flight a constant few metres beside its plan (a plan drawn on a shifted basemap, an RTK base
surveyed in the wrong place) must still be checked and flagged: :func:`estimate_plan_offset`
matches each sample to the leg it flies along and solves for the offset in the least absolute
deviations sense; :func:`plan_offsets` decides, for the plan and for the plan reversed, whether
the moved legs explain the samples clearly better.  :mod:`aeromag.track.assign` decodes each
direction about its own offset.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .geometry import cross_track
from .legs import LegModel, leg_evidence

__all__ = ["OFFSET_DECODE_MIN_M", "OFFSET_MAX_SAMPLES", "OFFSET_MIN_CONSTRAINT",
           "OFFSET_MIN_LEG_FRACTION", "OFFSET_MIN_SAMPLES", "OFFSET_SEARCH_FACTOR",
           "OFFSET_SUPPORT_GAIN", "estimate_plan_offset", "plan_offsets", "shifted"]

#: The plan is searched for the flight's constant offset with this many times the tolerance.
OFFSET_SEARCH_FACTOR = 5.0

#: Samples flown along a leg needed to estimate the offset.
OFFSET_MIN_SAMPLES = 50

#: Share of the samples' normal "energy" a direction needs for the offset along it to be
#: estimated (legs within about 13 degrees of each other constrain only across them).
OFFSET_MIN_CONSTRAINT = 0.05

#: Share of the plan's legs (and at least 2) flown at the offset for it to be taken.
OFFSET_MIN_LEG_FRACTION = 1.0 / 3.0

#: A plan offset larger than this is decoded about the moved lines, m (below it the distance
#: term and the gate centred on the offset keep the legs).
OFFSET_DECODE_MIN_M = 2.0

#: The moved legs must explain the samples this many times better (summed evidence) than the
#: plan as given for the offset to be taken.
OFFSET_SUPPORT_GAIN = 1.1

#: Samples used for the offset (a longer log is thinned evenly).
OFFSET_MAX_SAMPLES = 10000

def estimate_plan_offset(ned: np.ndarray, vel: np.ndarray, waypoints: np.ndarray,
                         model: LegModel) -> tuple[np.ndarray, int, int]:
    """Constant horizontal offset of the flight from a plan, found by motion, not distance.

    Each sample is matched to the leg it flies along (speed and direction along the leg,
    between its ends) with a tolerance :data:`OFFSET_SEARCH_FACTOR` times wider than the given
    one, horizontally only; the samples whose evidence for their best leg is strong (above half
    the bonus) give one equation each, ``n_k . offset = h`` (``n_k`` the leg's horizontal
    normal, ``h`` the signed distance to its line), solved in the least absolute deviations
    sense (iteratively reweighted; a direction the legs hardly constrain, e.g. along parallel
    lines, stays at 0: :data:`OFFSET_MIN_CONSTRAINT`).  A flight several metres beside its
    plan (beyond the tolerance, where the distance term alone loses it) is then decoded about
    its own lines.

    Parameters
    ----------
    ned : ndarray, shape (n, 3)
        Positions, NED, m.
    vel : ndarray, shape (n, 3)
        Velocities, m/s.
    waypoints : ndarray, shape (m, 3)
        Plan waypoints, NED, m (in the direction to test).
    model : LegModel
        Parameters as given.

    Returns
    -------
    offset_ne : ndarray, shape (2,)
        North and east offset of the flight from the plan, m (zeros when fewer than
        :data:`OFFSET_MIN_SAMPLES` samples qualify).
    n : int
        Samples used.
    n_legs : int
        Legs with at least ``OFFSET_MIN_SAMPLES // 5`` samples flown at that offset (within
        ``max(OFFSET_DECODE_MIN_M, 0.25 |offset|)`` of it).
    """
    wide = dataclasses.replace(model, tolerance_m=OFFSET_SEARCH_FACTOR * model.tolerance_m,
                               horizontal_only=True)
    ev = leg_evidence(ned, vel, waypoints, wide, horizontal_only=True)
    if ev.shape[1] == 0:
        return np.zeros(2), 0, 0
    k = np.argmax(ev, axis=1)
    idx = np.flatnonzero(ev[np.arange(len(ev)), k] > 0.5 * model.bonus)
    if idx.size < OFFSET_MIN_SAMPLES:
        return np.zeros(2), int(idx.size), 0
    h = np.empty(idx.size)
    nrm = np.empty((idx.size, 2))
    for leg in np.unique(k[idx]):
        sel = k[idx] == leg
        _, h[sel], _, _ = cross_track(ned[idx[sel]], waypoints[leg], waypoints[leg + 1])
        d = waypoints[leg + 1, :2] - waypoints[leg, :2]
        ln = float(np.linalg.norm(d))
        nrm[sel] = (-d[1] / ln, d[0] / ln) if ln > 0 else (0.0, 0.0)
    # a direction the legs hardly constrain (near-parallel legs) stays at 0
    evals, evecs = np.linalg.eigh(nrm.T @ nrm)
    basis = evecs[:, evals > OFFSET_MIN_CONSTRAINT * float(evals.max())]
    q = nrm @ basis
    w = np.ones(idx.size)   # least squares first, then least absolute deviations
    c = np.zeros(basis.shape[1])
    for _ in range(20):
        new = np.linalg.solve((q * w[:, None]).T @ q, (q * w[:, None]).T @ h)
        done = float(np.max(np.abs(new - c))) < 1e-3
        c = new
        if done:
            break
        w = 1.0 / np.maximum(np.abs(q @ c - h), 0.05)
    off = basis @ c
    # the legs flown at that offset (a pattern that meets one or two legs by chance, e.g. a
    # calibration flight over a survey plan, is no plan offset)
    inl = np.abs(nrm @ off - h) < max(OFFSET_DECODE_MIN_M, 0.25 * float(np.hypot(*off)))
    _, counts = np.unique(k[idx][inl], return_counts=True)
    return off, int(idx.size), int((counts >= OFFSET_MIN_SAMPLES // 5).sum())


def shifted(wps: np.ndarray, off_ne: np.ndarray) -> np.ndarray:
    """The waypoints moved by a horizontal offset (north, east), m."""
    return wps + np.r_[off_ne, 0.0]


def _support(ned: np.ndarray, vel: np.ndarray, wps: np.ndarray, model: LegModel) -> float:
    """How well the legs explain the samples: the sum of each sample's best positive evidence."""
    ev = leg_evidence(ned, vel, wps, model)
    return float(np.maximum(ev.max(axis=1), 0.0).sum()) if ev.shape[1] else 0.0


def plan_offsets(ned: np.ndarray, vel: np.ndarray, wps: np.ndarray, model: LegModel
             ) -> tuple[np.ndarray, np.ndarray]:
    """The decoding offset of the plan and of the plan reversed (zeros when not taken).

    An offset is taken when it exceeds :data:`OFFSET_DECODE_MIN_M` and the moved legs explain
    the samples clearly better (:data:`OFFSET_SUPPORT_GAIN` times the summed evidence): a
    transit that runs beside a leg's direction (from a take-off point away from the plan) can
    pull the estimate along a direction few legs constrain; it then explains nothing more.
    """
    step = max(1, len(ned) // OFFSET_MAX_SAMPLES)   # a long or fast log: every step-th sample
    p, v = ned[::step], vel[::step]
    out = []
    for w in (wps, wps[::-1].copy()):
        off, _, n_legs = estimate_plan_offset(p, v, w, model)
        best, score = np.zeros(2), OFFSET_SUPPORT_GAIN * _support(p, v, w, model)
        enough = n_legs >= max(2, OFFSET_MIN_LEG_FRACTION * (len(w) - 1))
        if enough and float(np.hypot(*off)) > OFFSET_DECODE_MIN_M:
            # the offset, and its parts along north and east alone (a part pulled by a
            # transit along a direction few legs constrain explains nothing)
            cands = [off] + [c for c in (np.array([off[0], 0.0]), np.array([0.0, off[1]]))
                             if float(np.hypot(*(c - off))) > 0.5]
            for cand in cands:
                if float(np.hypot(*cand)) > OFFSET_DECODE_MIN_M:
                    sc = _support(p, v, shifted(w, cand), model)
                    if sc > score:
                        best, score = cand, sc
        out.append(best)
    return out[0], out[1]
