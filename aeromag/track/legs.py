"""Which mission leg each sample belongs to: a hidden Markov model decoded with Viterbi.

The vehicle is, at every sample, either *on leg k* (flying from waypoint ``W_k`` towards
``W_k+1``) or *off plan* (on the ground, taking off, climbing, hovering or turning at a
waypoint, in transit, landing).  Each sample's evidence for leg ``k`` against "off plan" is a
log-likelihood ratio built from what the vehicle does (all vectorised over samples and legs):

``e_k = bonus (2 g - 1)``               moving along the leg: ``g = sigmoid((v_a - min_speed_m_s)
                                        / speed_softness_m_s) sigmoid((v_a - r v_p) /
                                        direction_softness_m_s)``
    ``- 0.5 (d_h / s_h)^2``               horizontal distance to the leg's line
    ``- 0.5 (d_v / s_v)^2``               vertical distance (altitude near the planned one)
    ``- 0.5 (out / end_margin_m)^2``      progress: how far before ``W_k`` or past ``W_k+1``

clipped to ``[floor, bonus]`` so that one bad fix cannot cut a pass.  ``s_h`` and ``s_v`` are
chosen so that ``e_k = 0`` (no better than off plan) at ``tolerance_m`` horizontally and at
``vertical_tolerance_m`` vertically: ``s = tolerance / sqrt(2 bonus)``.  ``v_a`` is the velocity
along the leg and ``v_p`` across it (3-D), from the positions over ``velocity_window_s``;
hovering (no speed), climbing or descending, crossing a leg and flying the line backwards (the
transit back to re-fly a leg) are off plan.  "Off plan" has evidence 0.

Transitions cost ``switch_cost`` (log-probability) to enter or leave a leg or to go from leg
``k`` straight to leg ``k+1`` (a waypoint passed without stopping); staying costs nothing.  The
off-plan state remembers the last leg flown, so that a leg out of mission order costs
``order_cost`` more (:func:`viterbi`): legs of the same geometry (a line flown back and forth)
are told apart by their order, and a re-flown leg is cheap.  The Viterbi path is the most
likely labelling.  A leg
flown twice is two runs of its label (two *passes*).

With ``horizontal_only`` the vertical term is left out (logs whose altitude cannot be trusted);
take-off, landing and ground time are then off plan by their lack of motion along the leg.

:func:`aeromag.track.assign.assign_track_legs` runs this model over a whole log: the plan as
given and reversed, tolerances widened for a noisy position, transits taken for a leg dropped.
"""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd

from ..errors import InputError
from .continuation import continue_legs
from .geometry import cross_track
from .leg_model import LegModel

__all__ = ["LegModel", "decode_legs",
           "position_jitter_m", "samples_along_legs",
           "velocity_for_legs",
           "leg_evidence", "labels_from_column", "leg_passes", "motion_velocity", "viterbi",
           "continue_legs"]

log = logging.getLogger(__name__)


def motion_velocity(time_s: np.ndarray, ned: np.ndarray, window_s: float = 1.0) -> np.ndarray:
    """Velocity from positions: the mean over a centred time window.

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Sample times, s (increasing).
    ned : ndarray, shape (n, 3)
        Positions, m (NaN rows are skipped; their velocity is NaN).  Times must not decrease;
        repeated times are stepped over.
    window_s : float
        Window length, s; at least the two neighbours of each sample are used.

    Returns
    -------
    ndarray, shape (n, 3)
        Velocity, m/s.
    """
    t = np.asarray(time_s, dtype=np.float64)
    p = np.asarray(ned, dtype=np.float64)
    out = np.full(p.shape, np.nan)
    ok = np.flatnonzero(np.isfinite(p).all(axis=1) & np.isfinite(t))
    if ok.size < 2:
        return out
    tt, pp = t[ok], p[ok]
    # at least the nearest samples of another time on either side (repeated time stamps)
    before = np.maximum(np.searchsorted(tt, tt, side="left") - 1, 0)
    after = np.minimum(np.searchsorted(tt, tt, side="right"), ok.size - 1)
    lo = np.minimum(np.searchsorted(tt, tt - 0.5 * window_s, side="left"), before)
    hi = np.maximum(np.searchsorted(tt, tt + 0.5 * window_s, side="right") - 1, after)
    dt = tt[hi] - tt[lo]
    with np.errstate(invalid="ignore", divide="ignore"):
        v = (pp[hi] - pp[lo]) / dt[:, None]
    v[~(dt > 0)] = np.nan
    out[ok] = v
    return out


def position_jitter_m(ned: np.ndarray) -> float:
    """Sample-to-sample noise of horizontal positions, m (robust, from second differences).

    For white noise of standard deviation ``s`` per axis the second difference has standard
    deviation ``sqrt(6) s``; smooth motion contributes little at the sample rate.

    Parameters
    ----------
    ned : ndarray, shape (n, 3)
        Positions, m (NaN rows skipped).

    Returns
    -------
    float
        Noise per horizontal axis, m (0 with fewer than 3 positions).
    """
    p = ned[np.isfinite(ned).all(axis=1)][:, :2]
    if len(p) < 3:
        return 0.0
    d2 = p[2:] - 2.0 * p[1:-1] + p[:-2]
    return float(1.4826 * np.median(np.abs(d2)) / np.sqrt(6.0))


def velocity_for_legs(time_s: np.ndarray, ned: np.ndarray, model: LegModel,
                      gnss_velocity: np.ndarray | None = None
                      ) -> tuple[np.ndarray, dict[str, float | str]]:
    """The velocity the leg model uses, and how it was obtained.

    The GNSS (Doppler) velocity where the log has it; elsewhere the velocity from positions
    over ``model.velocity_window_s``, widened for noisy positions so that position noise
    ``s`` gives at most about 0.1 m/s of velocity noise (window ``>= 14 s``, at most 5 s).

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Sample times, s.
    ned : ndarray, shape (n, 3)
        Positions, NED, m.
    model : LegModel
        Parameters.
    gnss_velocity : ndarray, shape (n, 3), optional
        ``vel_n``, ``vel_e``, ``vel_d`` of the log, m/s (NaN where absent).

    Returns
    -------
    vel : ndarray, shape (n, 3)
        Velocity, m/s.
    info : dict
        ``source`` (``gnss``, ``positions`` or ``gnss+positions``), ``window_s``,
        ``position_jitter_m`` for the report.
    """
    jitter = position_jitter_m(ned)
    window = float(min(max(model.velocity_window_s, 7.0 * jitter), 5.0))
    vel = motion_velocity(time_s, ned, window)
    source = "positions"
    if gnss_velocity is not None:
        g = np.asarray(gnss_velocity, dtype=np.float64)
        has = np.isfinite(g).all(axis=1)
        if has.any():
            vel = np.where(has[:, None], g, vel)
            source = "gnss" if has.all() else "gnss+positions"
    return vel, {"source": source, "window_s": window, "position_jitter_m": jitter}


def _sigmoid(x: np.ndarray) -> np.ndarray:
    return 0.5 * (1.0 + np.tanh(0.5 * x))


def leg_evidence(ned: np.ndarray, vel: np.ndarray, waypoints: np.ndarray,
                 model: LegModel = LegModel(), *, horizontal_only: bool | None = None  # noqa: B008
                 ) -> np.ndarray:
    """Per-sample evidence for each leg against "off plan" (log-likelihood ratios).

    Parameters
    ----------
    ned : ndarray, shape (n, 3)
        Antenna positions, NED, m.
    vel : ndarray, shape (n, 3)
        Velocities, m/s (see :func:`motion_velocity`).
    waypoints : ndarray, shape (m, 3)
        Plan waypoints, NED, m.
    model : LegModel
        Parameters.
    horizontal_only : bool, optional
        Override ``model.horizontal_only``.

    Returns
    -------
    ndarray, shape (n, m - 1), float32
        Evidence per sample and leg, nats; 0 (no evidence either way: the state carries on)
        where a position or velocity is missing.
    """
    horiz = model.horizontal_only if horizontal_only is None else horizontal_only
    n, n_legs = len(ned), len(waypoints) - 1
    ev = np.zeros((n, n_legs), dtype=np.float32)
    ok = np.isfinite(ned).all(axis=1) & np.isfinite(vel).all(axis=1)
    if not ok.any():
        return ev
    p, v = ned[ok], vel[ok]
    b = model.bonus
    kh = 0.5 * 2.0 * b / model.tolerance_m ** 2   # 0.5 / s_h^2 with s_h = tol / sqrt(2 b)
    kv = 0.5 * 2.0 * b / model.vertical_tolerance_m ** 2
    ks = 0.5 / model.end_margin_m ** 2
    for k in range(n_legs):
        a, bb = waypoints[k], waypoints[k + 1]
        length = float(np.linalg.norm(bb - a))
        u = (bb - a) / length
        _, h, vv, along = cross_track(p, a, bb)
        out = np.maximum(-along, 0.0) + np.maximum(along - length, 0.0)
        if horiz:
            # horizontal motion only: a noisy or drifting altitude must not decide the leg
            uh = np.r_[u[:2], 0.0]
            nh = float(np.linalg.norm(uh))
            uh = uh / nh if nh > 0 else u
            vh = np.c_[v[:, :2], np.zeros(len(v))]
            va = vh @ uh
            vp = np.linalg.norm(vh - va[:, None] * uh, axis=1)
        else:
            va = v @ u
            vp = np.linalg.norm(v - va[:, None] * u, axis=1)
        m = (_sigmoid((va - model.min_speed_m_s) / model.speed_softness_m_s)
             * _sigmoid((va - model.direction_ratio * vp) / model.direction_softness_m_s))
        e = b * (2.0 * m - 1.0) - kh * h * h - ks * out * out
        if not horiz:
            e -= kv * vv * vv
        ev[ok, k] = np.clip(e, model.floor, b)
    return ev


def viterbi(evidence: np.ndarray, switch_cost: float = 8.0, order_cost: float | None = None
            ) -> np.ndarray:
    """Most likely state sequence of the "off plan / on leg k" model, in mission order.

    States are "on leg k" (evidence ``e_k``) and "off plan, last leg flown j" (evidence 0;
    ``j = -1`` before the first leg), so that the model knows the mission order: entering or
    leaving a leg costs ``switch_cost``; entering leg ``k`` from off plan after leg ``j`` costs
    ``order_cost`` more unless ``k`` is ``j + 1`` (the next leg) or ``j`` (the same leg again:
    a re-flight or a resumed leg); going from leg ``k`` straight to leg ``k + 1`` (a waypoint
    passed without stopping) costs ``switch_cost``, to any other leg ``2 switch_cost +
    order_cost``.  Legs with the same geometry (a line flown back and forth) are then told
    apart by their order.  The path starts off plan before the first leg.

    Parameters
    ----------
    evidence : ndarray, shape (n, K)
        Per-sample evidence for each leg, nats (see :func:`leg_evidence`).
    switch_cost : float
        Cost of a change of state, nats.
    order_cost : float, optional
        Extra cost of a leg out of mission order, nats (default ``2 switch_cost``).

    Returns
    -------
    ndarray of int, shape (n,)
        Leg per sample, -1 for off plan.
    """
    e = np.asarray(evidence, dtype=np.float64)
    n, n_legs = e.shape
    if n == 0 or n_legs == 0:
        return np.full(n, -1, dtype=np.int64)
    c = float(switch_cost)
    lam = 2.0 * c if order_cost is None else float(order_cost)
    K = n_legs
    # State index: 0..K are "off plan, last leg j = index - 1"; K + 1 + k is "leg k".
    itype = np.int16 if 2 * K + 1 < 32000 else np.int32
    back = np.empty((n, 2 * K + 1), dtype=itype)
    idx_off = np.arange(K + 1)
    idx_leg = K + 1 + np.arange(K)
    cols = np.arange(K)
    # Candidate predecessors of leg k: itself, leg k-1, off after leg k-1, off after leg k.
    src_table = np.vstack([idx_leg, np.r_[idx_leg[0], idx_leg[:-1]], idx_off[:-1], idx_off[1:]])
    cand = np.full((4, K), -np.inf)
    off = np.full(K + 1, -np.inf)
    off[0] = 0.0
    leg = np.full(K, -np.inf)
    leg[0] = -c
    leg += e[0]
    back[0] = np.r_[idx_off, idx_leg]
    b_off = idx_off.copy()
    for i in range(1, n):
        cand[0] = leg
        np.subtract(leg[:-1], c, out=cand[1, 1:])
        np.subtract(off[:-1], c, out=cand[2])
        np.subtract(off[1:], c, out=cand[3])
        a = cand.argmax(axis=0)
        best = cand[a, cols]
        src = src_table[a, cols]
        jo = int(off.argmax())
        jl = int(leg.argmax())
        any_off, any_leg = off[jo] - c - lam, leg[jl] - 2.0 * c - lam
        any_c, any_src = (any_off, jo) if any_off >= any_leg else (any_leg, K + 1 + jl)
        m = any_c > best
        if m.any():
            best[m] = any_c
            src[m] = any_src
        # off plan after leg j: stay, or leave leg j
        leave = leg - c
        m = leave > off[1:]
        b_off[1:] = np.where(m, idx_leg, idx_off[1:])
        off[1:] = np.where(m, leave, off[1:])
        leg = best + e[i]
        back[i, : K + 1] = b_off
        back[i, K + 1:] = src
    state = np.empty(n, dtype=np.int64)
    s_ = int(np.argmax(np.r_[off, leg]))
    for i in range(n - 1, -1, -1):
        state[i] = s_
        s_ = int(back[i, s_])
    return np.where(state > K, state - K - 1, -1)


def decode_legs(evidence: np.ndarray, time_s: np.ndarray, model: LegModel = LegModel()  # noqa: B008
                ) -> np.ndarray:
    """Viterbi over the evidence at no more than ``1 / model.step_s`` Hz.

    Logs sampled faster than ``step_s`` are decoded in blocks of ``round(step_s / dt)``
    samples (the mean evidence of a block, one state per block), so that the evidence of a
    second of flight weighs the same at 10 Hz and at 1 kHz and the decoding stays fast; the
    labels are then spread back to every sample.

    Parameters
    ----------
    evidence : ndarray, shape (n, K)
        See :func:`leg_evidence`.
    time_s : ndarray, shape (n,)
        Sample times, s.
    model : LegModel
        Parameters (``step_s``, ``switch_cost``, ``order_cost``).

    Returns
    -------
    ndarray of int, shape (n,)
        Leg per sample, -1 for off plan.
    """
    n = len(evidence)
    t = np.asarray(time_s, dtype=np.float64)
    dts = np.diff(t[np.isfinite(t)])
    dt = float(np.median(dts)) if dts.size else model.step_s
    b = max(1, int(round(model.step_s / dt))) if dt > 0 else 1
    if b == 1:
        return viterbi(evidence, model.switch_cost, model.order_cost)
    nb = -(-n // b)
    pad = np.full((nb * b - n, evidence.shape[1]), np.nan, dtype=np.float64)
    blocks = np.nanmean(np.vstack([evidence, pad]).reshape(nb, b, -1), axis=1)
    return np.repeat(viterbi(blocks, model.switch_cost, model.order_cost), b)[:n]


def samples_along_legs(ned: np.ndarray, vel: np.ndarray, waypoints: np.ndarray,
                       model: LegModel = LegModel(), mask: np.ndarray | None = None  # noqa: B008
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The samples flown along a leg horizontally, whatever their height.

    A sample is flown along its best leg when its horizontal evidence (motion along the leg,
    close to its line, within its ends) is above half the bonus.

    Parameters
    ----------
    ned : ndarray, shape (n, 3)
        Positions, NED, m.
    vel : ndarray, shape (n, 3)
        Velocities, m/s.
    waypoints : ndarray, shape (m, 3)
        Plan waypoints, NED, m.
    model : LegModel
        Parameters.
    mask : ndarray of bool, shape (n,), optional
        Rows that may count (e.g. the airborne ones); default all.

    Returns
    -------
    idx : ndarray of int
        Rows flown along a leg (increasing).
    leg : ndarray of int
        Their leg (numbered along ``waypoints``).
    up : ndarray
        Their height above the leg's line, m.
    along : ndarray
        Their distance along the leg from its first waypoint, m.
    """
    ev = leg_evidence(ned, vel, waypoints, model, horizontal_only=True)
    empty = np.zeros(0, dtype=np.int64)
    if ev.shape[1] == 0:
        return empty, empty, np.zeros(0), np.zeros(0)
    k = np.argmax(ev, axis=1)
    strong = ev[np.arange(len(ev)), k] > 0.5 * model.bonus
    if mask is not None:
        strong &= np.asarray(mask, dtype=bool)
    idx = np.flatnonzero(strong)
    up = np.empty(idx.size)
    along = np.empty(idx.size)
    for leg in np.unique(k[idx]):
        sel = k[idx] == leg
        _, _, up[sel], along[sel] = cross_track(ned[idx[sel]], waypoints[leg],
                                                waypoints[leg + 1])
    return idx, k[idx].astype(np.int64), up, along


def leg_passes(labels: np.ndarray, time_s: np.ndarray, along_m: np.ndarray | None = None,
               merge_gap_s: float = 5.0) -> tuple[np.ndarray, pd.DataFrame]:
    """Passes over legs: runs of one leg label, joined across short interruptions.

    Two runs of the same leg separated by less than ``merge_gap_s`` with no other leg between
    them, and (when ``along_m`` is given) with the second starting no further back along the
    leg than where the first ended (minus 5 m), are one pass; otherwise every run is a pass.

    Parameters
    ----------
    labels : ndarray of int, shape (n,)
        Leg per sample, -1 for none.
    time_s : ndarray, shape (n,)
        Sample times, s.
    along_m : ndarray, shape (n,), optional
        Position along the sample's leg, m.
    merge_gap_s : float
        Longest interruption inside one pass, s.

    Returns
    -------
    pass_id : ndarray of int, shape (n,)
        Pass of each sample (numbered from 0 in time order), -1 for none.
    passes : DataFrame
        One row per pass: ``pass``, ``leg``, ``start``, ``stop`` (sample range, half-open).
    """
    lab = np.asarray(labels)
    t = np.asarray(time_s, dtype=np.float64)
    on = np.flatnonzero(lab >= 0)
    pid = np.full(len(lab), -1, dtype=np.int64)
    if on.size == 0:
        return pid, pd.DataFrame(columns=["pass", "leg", "start", "stop"], dtype=np.int64)
    brk = np.r_[True, (np.diff(on) > 1) | (lab[on[1:]] != lab[on[:-1]])]
    starts = on[brk]
    stops = np.r_[on[np.flatnonzero(brk)[1:] - 1], on[-1]] + 1
    rows: list[list[int]] = []
    for s, e in zip(starts, stops, strict=True):
        leg = int(lab[s])
        if rows and rows[-1][1] == leg and t[s] - t[rows[-1][3] - 1] < merge_gap_s:
            prev_end = rows[-1][3] - 1
            if along_m is None or along_m[s] >= along_m[prev_end] - 5.0:
                rows[-1][3] = int(e)
                continue
        rows.append([len(rows), leg, int(s), int(e)])
    for r in rows:
        seg = slice(r[2], r[3])
        pid[seg] = np.where(lab[seg] == r[1], r[0], -1)
    return pid, pd.DataFrame(rows, columns=["pass", "leg", "start", "stop"])


def labels_from_column(log_df: pd.DataFrame, n_legs: int, source: str) -> np.ndarray:
    """Leg labels from the log's own ``leg`` column (empty or negative: no leg).

    Parameters
    ----------
    log_df : DataFrame
        Log with a ``leg`` column.
    n_legs : int
        Legs in the plan.
    source : str
        File name quoted in errors.

    Returns
    -------
    ndarray of int
        Leg per sample, -1 for none.
    """
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
