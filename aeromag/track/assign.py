"""Leg assignment of a whole log: direction of the mission, GNSS error, transits kept off legs.

:mod:`aeromag.track.legs` decodes one plan in one direction with one tolerance.  A real log
asks three more questions, answered here in :func:`assign_track_legs`:

* **Which way was the mission flown?**  Crews fly a plan backwards (last waypoint first) as
  often as not.  The log is decoded against the plan and against the plan reversed (waypoint
  order: every leg B to A, last leg first); when the reversed plan explains
  :data:`REVERSED_RATIO` times more samples, its labels are used (leg ``j`` of the reversed plan
  is leg ``K - 1 - j`` of the plan).  A leg flown backwards is on its line: it is checked.  The
  transits stay off plan as they do for a mission flown as planned (the mission order, motion
  and progress terms of the HMM apply to the reversed plan).
* **Is the flight beside its plan?**  A flight a constant few metres beside its plan must be
  checked and flagged, not lost, and distance cannot tell its direction (a lawn-mower flown
  backwards 5 m east of its plan is also the plan flown 15 m west, line by line against the
  neighbouring line).  Each direction is decoded about its own offset, found by motion
  (:mod:`aeromag.track.offset`) and taken when above ``OFFSET_DECODE_MIN_M`` and the
  moved legs explain the samples better; the direction that needed the smaller offset is the
  default and the other must explain :data:`REVERSED_RATIO` times more samples (equal
  offsets: the larger count).  The labels are then checked against the plan as given.
* **How good is the position?**  Plain GNSS wanders by metres with correlation times of minutes
  (a random walk or Gauss-Markov error); with the default 10 m tolerance whole stretches of a
  leg then fall off it, unchecked.  The robust scatter of the assigned samples about their
  line (:func:`line_error_sigma_m`: horizontal and vertical apart, a constant offset such as
  a plan moved sideways removed) estimates the error; when
  :data:`GATE_SIGMAS` times it exceeds a tolerance, the log is decoded again with that
  tolerance (at most :data:`MAX_TOLERANCE_FACTOR` times the given one) and an end margin of
  one sigma (the error along a leg moves samples before its start or past its end).
* **Is a run a pass or a transit?**  A ferry between legs flown out of order (the next leg's
  start is not the last leg's end) can run along a leg's direction a few degrees off its line,
  converging to or diverging from it: the HMM takes it for the leg and every sample of it
  alarms.  A pass is flown on its line: a run is kept only when at least
  ``min(MIN_ON_LINE_S, ON_LINE_FRACTION * duration)`` of it is within the on-line gate
  (``max(ON_LINE_GATE_M, GATE_SIGMAS * sigma)``, horizontally, about the flight's constant
  offset from the plan) of the line, *and* it has a stretch that long within the gate that is
  parallel to the line (:data:`PARALLEL_MAX_SLOPE`: the least-squares slope of the lateral
  distance against the distance flown, over windows that grow with the position error so
  that the error cannot tilt them, :data:`PARALLEL_NOISE_FACTOR`).  On RTK
  the 2 m gate alone does it (a ferry 8 deg off crosses it in 3 s); on plain GNSS the gate is
  widened to 4 sigma, as wide as the widened tolerance, so every decoded run of a converging
  ferry lies within it, and only its steady slope (0.14 m per m at 8 deg, a pass wanders
  without a trend) tells it from a pass.  A disturbed pass starts on its line and stays a pass
  however far it then veers; a ferry that meets the line only at a waypoint is dropped.
"""

from __future__ import annotations

import dataclasses
import logging
from typing import Any

import numpy as np

from .._core.runs import run_bounds, true_runs
from .continuation import continue_legs
from .geometry import cross_track
from .legs import LegModel, decode_legs, leg_evidence, velocity_for_legs
from .offset import OFFSET_DECODE_MIN_M, plan_offsets, shifted

__all__ = ["GATE_SIGMAS", "MAX_TOLERANCE_FACTOR", "MIN_ON_LINE_S", "ON_LINE_FRACTION",
           "ON_LINE_GATE_M", "PARALLEL_MAX_SLOPE", "PARALLEL_MIN_ALONG_M",
           "PARALLEL_NOISE_FACTOR", "REVERSED_RATIO", "assign_legs", "assign_track_legs",
           "covered_m", "drop_transit_runs", "has_parallel_stretch", "line_error_sigma_m"]

log = logging.getLogger(__name__)

#: How many times more samples the reversed plan must explain to be taken as flown.
REVERSED_RATIO = 1.25

#: Gate in robust sigmas of the position error (tolerance widening and on-line gate).
GATE_SIGMAS = 4.0

#: Largest widening of the tolerances by the position error.
MAX_TOLERANCE_FACTOR = 5.0

#: Smallest on-line gate, m: an autopilot holds its line to well within this on RTK.
ON_LINE_GATE_M = 2.0

#: A run must be within the on-line gate this long, s (or for ``ON_LINE_FRACTION`` of a
#: shorter run) to be a pass.
MIN_ON_LINE_S = 5.0

#: Fraction of a short run that must be within the on-line gate.
ON_LINE_FRACTION = 0.5

#: Largest steady slope of the lateral distance against the distance flown (m per m) of the
#: stretch that makes a run a pass: 0.05 is 2.9 deg.  A ferry 8 deg off a line converges at
#: 0.14; plain GNSS (1.5 m Gauss-Markov, tau 120 s, 0.3 m white) tilts a pass by about
#: 0.015 (one sigma) over the 45 m windows it is tested on, far less over a whole line.
PARALLEL_MAX_SLOPE = 0.05

#: The parallel stretch spans at least this distance along the leg, m (or the whole
#: in-gate stretch when shorter): over a few metres the noise, not the track, sets the slope.
PARALLEL_MIN_ALONG_M = 20.0

#: A stretch of length ``L`` along the leg is parallel up to a slope of
#: ``max(PARALLEL_MAX_SLOPE, PARALLEL_NOISE_FACTOR * sigma / L)`` (``sigma`` the position error,
#: the gate over :data:`GATE_SIGMAS`), and the windows are long enough for the first term to
#: rule: a correlated GNSS error of sigma wanders by about sigma over a stretch, so a short or
#: noisy stretch cannot show a slope and is kept (5 m Gauss-Markov, tau 60 s: windows of 150 m).
PARALLEL_NOISE_FACTOR = 1.5


def line_error_sigma_m(ned: np.ndarray, labels: np.ndarray, waypoints: np.ndarray
                       ) -> tuple[float, float, int, np.ndarray]:
    """Robust scatter of the assigned samples about their leg's line, a constant offset aside.

    The horizontal residual of a sample is its signed distance to the line times the line's
    horizontal normal (a north-east vector); the median vector over the samples (a plan moved
    sideways, which :mod:`aeromag.track.diagnose` reports, or the mean of the GNSS error) is
    removed before the scatter is taken, and likewise the median vertical distance.

    Parameters
    ----------
    ned : ndarray, shape (n, 3)
        Positions, NED, m.
    labels : ndarray of int, shape (n,)
        Leg per sample, -1 for none.
    waypoints : ndarray, shape (m, 3)
        Plan waypoints, NED, m.

    Returns
    -------
    sigma_h_m, sigma_v_m : float
        ``1.4826 median |d - offset|`` of the horizontal and vertical distances, m (NaN when
        fewer than 10 samples are assigned).
    n : int
        Samples used.
    offset_ne : ndarray, shape (2,)
        The median horizontal residual (north, east), m (zeros when too few samples).
    """
    on = np.flatnonzero((labels >= 0) & np.isfinite(ned).all(axis=1))
    if on.size < 10:
        return float("nan"), float("nan"), int(on.size), np.zeros(2)
    h = np.empty(on.size)
    v = np.empty(on.size)
    nrm = np.empty((on.size, 2))
    for k in np.unique(labels[on]):
        m = labels[on] == k
        _, hk, vk, _ = cross_track(ned[on[m]], waypoints[k], waypoints[k + 1])
        h[m], v[m] = hk, vk
        d = waypoints[k + 1, :2] - waypoints[k, :2]
        ln = float(np.linalg.norm(d))
        nrm[m] = (-d[1] / ln, d[0] / ln) if ln > 0 else (0.0, 0.0)
    off = np.median(h[:, None] * nrm, axis=0)
    hr = h - nrm @ off
    vr = v - float(np.median(v))
    return (1.4826 * float(np.median(np.abs(hr))), 1.4826 * float(np.median(np.abs(vr))),
            int(on.size), off)


def has_parallel_stretch(time_s: np.ndarray, along_m: np.ndarray, h_m: np.ndarray,
                         need_s: float, dt_s: float, max_slope: float = PARALLEL_MAX_SLOPE,
                         sigma_m: float = 0.0, min_along_m: float = PARALLEL_MIN_ALONG_M
                         ) -> bool:
    """Whether a stretch of a run is flown parallel to its line (no steady lateral trend).

    A window of consecutive samples lasting at least ``need_s`` and spanning at least
    ``max(min_along_m, PARALLEL_NOISE_FACTOR * sigma_m / max_slope)`` along the leg is parallel
    when the least-squares slope of the lateral distance against the distance along the leg is
    at most ``max_slope`` in magnitude.  When no window is that long, the whole stretch (if it
    lasts ``need_s``) is tested, against ``max(max_slope, PARALLEL_NOISE_FACTOR * sigma_m /
    L)`` for its span ``L`` along the leg: the position error alone tilts a short stretch.
    A stretch of two fixes, or without progress along the leg, cannot show a trend and is
    taken as parallel (the gate alone decides, as before this test).

    Parameters
    ----------
    time_s : ndarray, shape (m,)
        Times of the stretch's samples (consecutive positioned samples within the gate), s.
    along_m : ndarray, shape (m,)
        Distance along the leg, m.
    h_m : ndarray, shape (m,)
        Signed horizontal distance to the line, m.
    need_s : float
        Shortest window, s.
    dt_s : float
        Sample interval, s (a window of ``k`` samples lasts ``t_last - t_first + dt_s``).
    max_slope : float
        Largest slope of a parallel window, m per m.
    sigma_m : float
        Horizontal position error (one sigma), m.
    min_along_m : float
        Shortest window along the leg, m.

    Returns
    -------
    bool
    """
    t = np.asarray(time_s, dtype=np.float64)
    m = t.size
    if m == 0 or t[-1] - t[0] + dt_s < need_s - 1e-9:
        return False
    if m < 3:
        return True   # two fixes (a log with gaps) cannot show a trend: the gate decides
    x = np.asarray(along_m, dtype=np.float64) - float(along_m[0])
    y = np.asarray(h_m, dtype=np.float64) - float(h_m[0])
    # window from sample i to the first j that is long enough in time and along the leg
    j_t = np.searchsorted(t, t + need_s - dt_s - 1e-9, side="left")
    xm = np.maximum.accumulate(x)
    span = max(min_along_m, PARALLEL_NOISE_FACTOR * sigma_m / max_slope)
    j_x = np.searchsorted(xm, x + span, side="left")
    j = np.maximum(np.maximum(j_t, j_x), np.arange(m) + 2)
    i = np.flatnonzero(j < m)
    if i.size:
        j = j[i]
    else:
        # no window long enough: the whole stretch, with the slope its noise allows
        i, j = np.array([0]), np.array([m - 1])
        length = float(np.max(x) - np.min(x))
        if length > 0:
            max_slope = max(max_slope, PARALLEL_NOISE_FACTOR * sigma_m / length)
    c0 = np.r_[0.0, np.cumsum(np.ones(m))]
    cx, cy = np.r_[0.0, np.cumsum(x)], np.r_[0.0, np.cumsum(y)]
    cxx, cxy = np.r_[0.0, np.cumsum(x * x)], np.r_[0.0, np.cumsum(x * y)]
    n = c0[j + 1] - c0[i]
    sx, sy = cx[j + 1] - cx[i], cy[j + 1] - cy[i]
    vxx = cxx[j + 1] - cxx[i] - sx * sx / n
    vxy = cxy[j + 1] - cxy[i] - sx * sy / n
    ok = vxx > 1e-12 * np.maximum(1.0, n)
    if not ok.any():
        return True   # no progress along the leg to measure a slope on: the gate decides
    return bool(np.any(np.abs(vxy[ok]) <= max_slope * vxx[ok]))


def drop_transit_runs(labels: np.ndarray, ned: np.ndarray, time_s: np.ndarray,
                      waypoints: np.ndarray, gate_h_m: float,
                      offset_ne: np.ndarray | None = None,
                      max_slope: float | None = PARALLEL_MAX_SLOPE) -> tuple[np.ndarray, int]:
    """Unassign the runs that are not flown on their line (transits taken for a leg).

    A run is a pass when it is within the gate for ``min(MIN_ON_LINE_S, ON_LINE_FRACTION *
    duration)`` and has a stretch that long, within the gate, parallel to the line
    (:func:`has_parallel_stretch`): a ferry a few degrees off a line converges on it (or
    diverges from it) steadily, which a gate as wide as the tolerance (plain GNSS) cannot see.
    Horizontal only: a ferry between legs is a horizontal transit (climbs and descents have no
    motion along a leg), and a pass flown at a constant wrong height is a deviation to report.

    Parameters
    ----------
    labels : ndarray of int, shape (n,)
        Leg per sample, -1 for none.
    ned : ndarray, shape (n, 3)
        Positions, NED, m.
    time_s : ndarray, shape (n,)
        Sample times, s.
    waypoints : ndarray, shape (m, 3)
        Plan waypoints, NED, m.
    gate_h_m : float
        On-line gate, horizontal, m.
    offset_ne : ndarray, shape (2,), optional
        Constant horizontal offset of the flight from the plan (north, east), m: the gate is
        centred on it (:func:`line_error_sigma_m`), so that a plan moved sideways by a few
        metres is checked (and alarms), not dropped.
    max_slope : float or None
        Largest lateral slope of the parallel stretch, m per m (:data:`PARALLEL_MAX_SLOPE`);
        None: the gate alone decides (the rule before the parallel stretch).

    Returns
    -------
    labels : ndarray of int
        A new array without the dropped runs.
    n_dropped : int
        Runs dropped.
    """
    lab = np.array(labels, dtype=np.int64, copy=True)
    t = np.asarray(time_s, dtype=np.float64)
    dts = np.diff(t)
    dt = float(np.median(dts)) if dts.size else 0.1
    starts, stops, vals = run_bounds(lab)
    dropped = 0
    for s0, s1, k in zip(starts, stops, vals, strict=True):
        p = ned[s0:s1]
        fin = np.isfinite(p).all(axis=1)
        if not fin.any():
            continue
        _, h, _, along = cross_track(np.where(fin[:, None], p, 0.0), waypoints[k],
                                     waypoints[k + 1])
        centre = 0.0
        if offset_ne is not None:
            d = waypoints[k + 1, :2] - waypoints[k, :2]
            ln = float(np.linalg.norm(d))
            centre = float((-d[1] * offset_ne[0] + d[0] * offset_ne[1]) / ln) if ln > 0 else 0.0
        near = fin & (np.abs(h - centre) <= gate_h_m)
        duration = float(t[s1 - 1] - t[s0]) + dt
        need = min(MIN_ON_LINE_S, ON_LINE_FRACTION * duration)
        # time on the line: its share of the positioned samples (sparse fixes) of the run
        if near.sum() / fin.sum() * duration < need - 1e-9:
            lab[s0:s1] = -1
            dropped += 1
            continue
        if max_slope is None or gate_h_m <= ON_LINE_GATE_M + 1e-9:
            # the 2 m gate (RTK, or a navigated position as good) is narrower than a ferry's
            # convergence: the gate alone decides, as before the parallel rule (a pass that
            # flies on through a GNSS outage on navigated rows, which drift without noise)
            continue
        # a stretch of consecutive positioned samples within the gate, parallel to the line;
        # its time counts positioned samples at the run's mean positioned rate (sparse fixes)
        idx = np.flatnonzero(fin)
        tt = t[s0:s1][idx]
        dt_fix = duration / idx.size
        parallel = False
        for a, b in zip(*true_runs(near[idx]), strict=True):
            if has_parallel_stretch(tt[a:b], along[idx[a:b]], h[idx[a:b]], need, dt_fix,
                                    max_slope, gate_h_m / GATE_SIGMAS):
                parallel = True
                break
        if not parallel:
            lab[s0:s1] = -1
            dropped += 1
    return lab, dropped


def covered_m(labels: np.ndarray, ned: np.ndarray, waypoints: np.ndarray) -> float:
    """Distance along their legs covered by the runs of a labelling, m.

    Each run of leg ``k`` counts the extent of its positions along the leg (``max - min`` of
    the distance from waypoint ``k``): a pass counts its length however fast or slowly, and
    however often it was sampled.

    Parameters
    ----------
    labels : ndarray of int, shape (n,)
        Leg per sample (numbered along ``waypoints``), -1 for none.
    ned : ndarray, shape (n, 3)
        Positions, NED, m.
    waypoints : ndarray, shape (m, 3)
        Waypoints, NED, m.

    Returns
    -------
    float
    """
    total = 0.0
    for s0, s1, k in zip(*run_bounds(labels), strict=True):
        p = ned[s0:s1]
        p = p[np.isfinite(p).all(axis=1)]
        if len(p):
            _, _, _, along = cross_track(p, waypoints[k], waypoints[k + 1])
            total += float(along.max() - along.min())
    return total


def _raw(ned: np.ndarray, vel: np.ndarray, t: np.ndarray, wps: np.ndarray, model: LegModel,
         offs: tuple[np.ndarray, np.ndarray], ground: np.ndarray | None = None
         ) -> tuple[np.ndarray, np.ndarray]:
    """Labels against the plan and against it reversed (reversed plan numbering).

    Each direction is decoded about its own lines (the waypoints moved by its offset).
    Ground rows have the lowest evidence for every leg and no leg.
    """
    out = []
    for w, off in zip((wps, wps[::-1].copy()), offs, strict=True):
        w = shifted(w, off)
        ev = leg_evidence(ned, vel, w, model)
        if ground is not None:
            ev[ground] = model.floor
        lab = continue_legs(decode_legs(ev, t, model), ned, vel, w, model)
        if ground is not None:
            lab[ground] = -1
        out.append(lab)
    return out[0], out[1]


def _gate(sig_h: float) -> float:
    return max(ON_LINE_GATE_M, GATE_SIGMAS * sig_h) if np.isfinite(sig_h) else ON_LINE_GATE_M


def _choose(ned: np.ndarray, t: np.ndarray, wps: np.ndarray, fwd: np.ndarray, rev: np.ndarray,
            offs: tuple[np.ndarray, np.ndarray], gate: float | None
            ) -> tuple[np.ndarray, bool, dict[str, int]]:
    """The labelling (plan numbering) that explains the flight best, transit runs dropped.

    The direction whose decoding needed the smaller offset is the default (both below
    :data:`OFFSET_DECODE_MIN_M`: the plan as given); the other is taken only when it explains
    :data:`REVERSED_RATIO` times more samples.  With equal offsets (a flight half-way between
    lines, as far from the plan as from the plan reversed) the larger count wins.
    """
    d_f = d_r = 0
    w_f, w_r = shifted(wps, offs[0]), shifted(wps[::-1].copy(), offs[1])
    if gate is not None:
        # each centred on the flight's residual offset from its (moved) lines
        fwd, d_f = drop_transit_runs(fwd, ned, t, w_f, gate, line_error_sigma_m(ned, fwd, w_f)[3])
        rev, d_r = drop_transit_runs(rev, ned, t, w_r, gate, line_error_sigma_m(ned, rev, w_r)[3])
    n_f, n_r = int((fwd >= 0).sum()), int((rev >= 0).sum())
    margin = max(10, int(0.01 * np.isfinite(ned).all(axis=1).sum()))
    counts = {"n_forward": n_f, "n_reversed": n_r}
    # a direction must also cover more of its legs: rows carried slowly along a line (a
    # vehicle walked back on the ground) are many per metre, passes flown fast are few
    c_f, c_r = covered_m(fwd, ned, w_f), covered_m(rev, ned, w_r)
    a_f, a_r = float(np.hypot(*offs[0])), float(np.hypot(*offs[1]))
    if abs(a_f - a_r) < OFFSET_DECODE_MIN_M and max(a_f, a_r) > 0:
        take_rev = n_r > n_f + margin and c_r > c_f
    elif a_r < a_f:
        take_rev = not (n_f > REVERSED_RATIO * n_r and n_f - n_r > margin
                        and c_f > REVERSED_RATIO * c_r)
    else:
        take_rev = (n_r > REVERSED_RATIO * n_f and n_r - n_f > margin
                    and c_r > REVERSED_RATIO * c_f)
    if take_rev:
        counts["n_dropped_runs"] = d_r
        return np.where(rev >= 0, len(wps) - 2 - rev, -1), True, counts
    counts["n_dropped_runs"] = d_f
    return fwd, False, counts


def assign_track_legs(ned: np.ndarray, vel: np.ndarray, time_s: np.ndarray,
                      waypoints: np.ndarray, model: LegModel,
                      ground: np.ndarray | None = None
                      ) -> tuple[np.ndarray, LegModel, dict[str, Any], list[str]]:
    """Assign legs to a whole log (see the module docstring).

    Parameters
    ----------
    ned : ndarray, shape (n, 3)
        Antenna positions, NED, m (datum offset removed).
    vel : ndarray, shape (n, 3)
        Velocities, m/s.
    time_s : ndarray, shape (n,)
        Sample times, s.
    waypoints : ndarray, shape (m, 3)
        Plan waypoints, NED, m.
    model : LegModel
        Parameters as given.
    ground : ndarray of bool, shape (n,), optional
        Rows on the ground (:func:`aeromag.track.ground.ground_rows`): never on a leg and no
        evidence for an offset or a direction.

    Returns
    -------
    labels : ndarray of int, shape (n,)
        Leg per sample (plan numbering), -1 for none.
    model : LegModel
        The parameters used (tolerances widened for the position error).
    info : dict
        ``direction`` (``"as planned"`` or ``"reversed"``), ``sigma_h_m``, ``sigma_v_m``,
        ``gate_h_m``, ``offset_ne_m``, ``tolerance_m``, ``vertical_tolerance_m``,
        ``n_forward``, ``n_reversed``, ``n_dropped_runs``.
    warnings : list of str
    """
    t = np.asarray(time_s, dtype=np.float64)
    wps = np.asarray(waypoints, dtype=np.float64)
    used = model
    gr = None if ground is None or not np.any(ground) else np.asarray(ground, dtype=bool)
    # the offsets from the airborne rows only (a NaN row is no evidence)
    air_ned = ned if gr is None else np.where(gr[:, None], np.nan, ned)
    # the position error from a first decoding (no run dropped: the gate depends on it)
    offs = plan_offsets(air_ned, vel, wps, used)
    raw = _raw(ned, vel, t, wps, used, offs, gr)
    lab, _, _ = _choose(ned, t, wps, *raw, offs, None)
    sig_h, sig_v, _, off_ne = line_error_sigma_m(ned, lab, wps)
    for _ in range(2):
        if not np.isfinite(sig_h):
            break
        tol_h = min(max(model.tolerance_m, GATE_SIGMAS * sig_h),
                    MAX_TOLERANCE_FACTOR * model.tolerance_m)
        tol_v = model.vertical_tolerance_m if model.horizontal_only else min(
            max(model.vertical_tolerance_m, GATE_SIGMAS * sig_v),
            MAX_TOLERANCE_FACTOR * model.vertical_tolerance_m)
        if tol_h <= used.tolerance_m and tol_v <= used.vertical_tolerance_m:
            break
        # the error along the leg moves samples before its start or past its end
        used = dataclasses.replace(used, tolerance_m=max(tol_h, used.tolerance_m),
                                   vertical_tolerance_m=max(tol_v, used.vertical_tolerance_m),
                                   end_margin_m=max(model.end_margin_m, sig_h))
        raw = _raw(ned, vel, t, wps, used, offs, gr)
        lab, _, _ = _choose(ned, t, wps, *raw, offs, None)
        sig_h, sig_v, _, off_ne = line_error_sigma_m(ned, lab, wps)
    gate_h = _gate(sig_h)
    lab, rev, counts = _choose(ned, t, wps, *raw, offs, gate_h)
    decode_off = offs[1] if rev else offs[0]
    off_ne = line_error_sigma_m(ned, lab, wps)[3]   # of the labels kept
    warns: list[str] = []
    if used is not model:
        warns.append(
            f"the positions scatter {sig_h:.1f} m about the legs' lines horizontally and"
            f" {sig_v:.1f} m vertically (not RTK?): legs assigned with a tolerance of"
            f" {used.tolerance_m:.0f} m horizontally and {used.vertical_tolerance_m:.0f} m"
            " vertically; deviations below a few times that scatter are noise")
    if rev:
        warns.append(
            "the plan looks reversed: the flight follows its legs backwards (last waypoint"
            " first); the legs are assigned and checked in that direction")
    info: dict[str, Any] = {
        "direction": "reversed" if rev else "as planned",
        "sigma_h_m": None if not np.isfinite(sig_h) else sig_h,
        "sigma_v_m": None if not np.isfinite(sig_v) else sig_v,
        "gate_h_m": gate_h, "offset_ne_m": [float(x) for x in off_ne],
        "decode_offset_ne_m": [float(x) for x in decode_off],
        "tolerance_m": used.tolerance_m, "vertical_tolerance_m": used.vertical_tolerance_m,
        **counts,
    }
    log.debug("leg assignment: %s", info)
    return lab, used, info, warns


def assign_legs(
    ned: np.ndarray,
    waypoints: np.ndarray,
    *,
    time_s: np.ndarray | None = None,
    model: LegModel | None = None,
) -> np.ndarray:
    """Assign each sample to a mission leg (see :func:`assign_track_legs`).

    Parameters
    ----------
    ned : ndarray, shape (n, 3)
        Antenna positions, NED, m (NaN rows: no leg).
    waypoints : ndarray, shape (m, 3)
        Plan waypoints, NED, m.
    time_s : ndarray, shape (n,), optional
        Sample times, s (default: 10 Hz from 0).
    model : LegModel, optional
        Parameters (default :class:`LegModel`).

    Returns
    -------
    ndarray of int, shape (n,)
        Leg index per sample, -1 for none.
    """
    model = model or LegModel()
    p = np.asarray(ned, dtype=np.float64)
    t = np.arange(len(p)) / 10.0 if time_s is None else np.asarray(time_s, dtype=np.float64)
    vel, _ = velocity_for_legs(t, p, model)
    lab, _, _, _ = assign_track_legs(p, vel, t, np.asarray(waypoints, dtype=np.float64), model)
    lab[~np.isfinite(p).all(axis=1)] = -1
    return lab
