"""What to tell the user about a log against its plan: altitude datums, reversed or far plans.

* **Altitude datum.**  A log whose altitude is relative to home, or above mean sea level
  against a plan on the ellipsoid, sits a constant height above or below every leg.  The
  offset is the median height above the leg's line of the airborne samples that follow a leg
  horizontally (:func:`~aeromag.track.legs.samples_along_legs`); it is taken as a datum
  difference and removed when it exceeds :data:`DATUM_MIN_OFFSET_M` and three times its robust
  spread, airborne passes along the legs are flown at it and the plan's own altitude explains
  (almost) none, and the report names those passes.
* **Plans that do not match the flight.**  The log is always decoded against the plan
  reversed (waypoint order) and against the plan with a widened tolerance (a plan moved
  sideways: a neighbouring field); when (almost) no sample follows a leg, also horizontally
  only (altitude reference) and for distance (site): the warning says which.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .assign import covered_m
from .geometry import cross_track
from .legs import LegModel, decode_legs, leg_evidence, samples_along_legs

__all__ = ["DATUM_MIN_OFFSET_M", "NO_OFFSET_SHARE", "PASS_BAND_M", "PASS_MAX_GAP_S",
           "PASS_MIN_ALONG_M", "altitude_offset", "passes_at_height", "plan_distance_m",
           "plan_warnings"]

#: Smallest constant vertical offset taken as a datum difference, m.  Datum differences are
#: tens of metres (geoid undulation -106 to +85 m; a take-off height of 20-500 m for altitudes
#: relative to home); a smaller constant offset is more likely the vehicle flying too high or
#: too low, which the check must report as deviation.
DATUM_MIN_OFFSET_M = 3.0

#: Fraction of the positioned samples on legs below which the plan is diagnosed.
MIN_ON_LEG_FRACTION = 0.01


#: A sample is at a hypothesised height when within this of it, m (the datum threshold: a
#: pass within it of the plan is at the plan's own altitude).
PASS_BAND_M = DATUM_MIN_OFFSET_M

#: A pass supports a height when it covers this much of its leg, m (or half a shorter leg).
PASS_MIN_ALONG_M = 20.0

#: Longest gap inside one pass, s.
PASS_MAX_GAP_S = 2.0

#: A datum offset is not taken when the passes at the plan's own altitude cover at least this
#: share of the distance covered by the passes at the offset (prefer no offset).
NO_OFFSET_SHARE = 0.1

#: Supporting passes named in the warning (the rest counted).
PASSES_NAMED = 6


def passes_at_height(time_s: np.ndarray, idx: np.ndarray, leg: np.ndarray, up: np.ndarray,
                     along: np.ndarray, waypoints: np.ndarray, height_m: float
                     ) -> list[tuple[int, float, float, float]]:
    """The passes flown along legs at a given height above the plan.

    Among the samples flown along a leg (:func:`~aeromag.track.legs.samples_along_legs`), those
    within :data:`PASS_BAND_M` of ``height_m`` above the leg's line, in runs on one leg with no
    gap over :data:`PASS_MAX_GAP_S`, are a pass when the run covers at least
    ``min(PASS_MIN_ALONG_M, half the leg)`` along it.

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Sample times of the log, s.
    idx, leg, up, along : ndarray
        Rows flown along a leg, their leg, height above its line [m] and distance along it [m].
    waypoints : ndarray, shape (m, 3)
        The waypoints the legs are numbered along, NED, m.
    height_m : float
        The height above the plan to test, m.

    Returns
    -------
    list of (leg, t_start, t_end, covered_m)
    """
    sel = np.abs(up - height_m) < PASS_BAND_M
    i, k, a = idx[sel], leg[sel], along[sel]
    if i.size == 0:
        return []
    t = np.asarray(time_s, dtype=np.float64)[i]
    brk = np.flatnonzero((np.diff(t) > PASS_MAX_GAP_S) | (np.diff(k) != 0)) + 1
    lengths = np.linalg.norm(np.diff(waypoints, axis=0), axis=1)
    out = []
    for s0, s1 in zip(np.r_[0, brk], np.r_[brk, i.size], strict=True):
        kk = int(k[s0])
        cover = float(a[s0:s1].max() - a[s0:s1].min())
        if cover >= min(PASS_MIN_ALONG_M, 0.5 * float(lengths[kk])):
            out.append((kk, float(t[s0]), float(t[s1 - 1]), cover))
    return out


def altitude_offset(ned: np.ndarray, vel: np.ndarray, waypoints: np.ndarray, model: LegModel,
                    spec: str | float, *, time_s: np.ndarray | None = None,
                    ground: np.ndarray | None = None) -> tuple[float, dict, list[str]]:
    """Resolve the vertical offset to remove from the log's altitude.

    ``auto``: the offset is the median height above the legs of the airborne samples flown
    along them (plan or plan reversed, whichever covers more of its legs in passes at its
    median); it is taken as a datum difference only when it exceeds
    :data:`DATUM_MIN_OFFSET_M` and three times its robust spread, airborne passes along the
    legs support it (:func:`passes_at_height`), and the passes at the plan's own altitude (no
    offset, either direction) cover less than :data:`NO_OFFSET_SHARE` of what the offset's
    passes cover.  Ground rows (``ground``) are never evidence: carried back along a line
    20 m below the plan they are no pass.

    Parameters
    ----------
    ned, vel : ndarray, shape (n, 3)
        Positions [m] and velocities [m/s], NED.
    waypoints : ndarray, shape (m, 3)
        Plan waypoints, NED, m.
    model : LegModel
        Leg model.
    spec : "auto", "none" or float
        ``auto``: estimate and remove a datum offset; ``none`` (or 0): never; a number: the
        log's height above the plan to remove, m.
    time_s : ndarray, shape (n,), optional
        Sample times, s (default 10 Hz from 0), to name the passes.
    ground : ndarray of bool, shape (n,), optional
        Rows on the ground (:func:`aeromag.track.ground.ground_rows`).

    Returns
    -------
    applied_m : float
        Height of the log above the plan removed from every sample, m (0 when none).
    info : dict
        ``mode``, ``estimated_m``, ``spread_m``, ``n_samples``, ``applied_m``, ``n_passes``
        (airborne passes at the estimate), ``passes`` (``[leg, t_start, t_end]`` each, plan
        numbering), ``n_passes_at_plan_altitude`` for the report.
    warnings : list of str
    """
    text = str(spec).strip().lower()
    n_rows = len(ned)
    t = np.arange(n_rows) / 10.0 if time_s is None else np.asarray(time_s, dtype=np.float64)
    air = None if ground is None else ~np.asarray(ground, dtype=bool)
    n_legs = len(waypoints) - 1
    best = None
    at_plan = 0.0
    n_at_plan = 0
    # a mission flown against the plan reversed follows the reversed legs
    for rev, w in ((False, waypoints), (True, waypoints[::-1].copy())):
        idx, leg, up, along = samples_along_legs(ned, vel, w, model, air)
        zero = passes_at_height(t, idx, leg, up, along, w, 0.0)
        if sum(p[3] for p in zero) > at_plan:
            at_plan, n_at_plan = sum(p[3] for p in zero), len(zero)
        if up.size < 3:
            continue
        est = float(np.median(up))
        spread = 1.4826 * float(np.median(np.abs(up - est)))
        found = passes_at_height(t, idx, leg, up, along, w, est)
        cover = sum(p[3] for p in found)
        if best is None or cover > best[3]:
            numbered = [(n_legs - 1 - k if rev else k, t0, t1) for k, t0, t1, _ in found]
            best = (est, spread, int(up.size), cover, numbered)
    est, spread, n, cover, found = best or (float("nan"), float("nan"), 0, 0.0, [])
    info = {"mode": text if text in ("auto", "none") else "given",
            "estimated_m": None if not np.isfinite(est) else est,
            "spread_m": None if not np.isfinite(spread) else spread,
            "n_samples": n, "applied_m": 0.0, "n_passes": len(found),
            "passes": [[k, t0, t1] for k, t0, t1 in found],
            "n_passes_at_plan_altitude": n_at_plan}
    warns: list[str] = []
    if text == "none":
        return 0.0, info, warns
    if text != "auto":
        val = float(spec)
        info["applied_m"] = val
        return val, info, warns
    if not (np.isfinite(est) and n >= 10 and abs(est) > DATUM_MIN_OFFSET_M
            and abs(est) > 3.0 * spread):
        return 0.0, info, warns
    where = "above" if est > 0 else "below"
    if not found or at_plan >= NO_OFFSET_SHARE * cover:
        # the plan's own altitude explains passes (or nothing airborne supports the offset):
        # the heights off the plan are deviations (or ground), not a datum
        if found:
            warns.append(
                f"the log's samples along the legs are a median {abs(est):.1f} m {where} the"
                f" plan, but {n_at_plan} pass(es) are flown at the plan's own altitude: no"
                " altitude datum difference removed")
        return 0.0, info, warns
    info["applied_m"] = est
    named = ", ".join(f"leg {k} {t0:.1f}-{t1:.1f} s" for k, t0, t1 in found[:PASSES_NAMED])
    more = f" and {len(found) - PASSES_NAMED} more" if len(found) > PASSES_NAMED else ""
    warns.append(
        f"the log's altitude is a constant {abs(est):.1f} m {where} the plan on the legs"
        f" (spread {spread:.2f} m over {n} samples; {len(found)} airborne pass(es) at it:"
        f" {named}{more}): a different altitude reference (altitude relative to home, or"
        " above mean sea level against an ellipsoidal plan?); removed before the check. Give"
        " altitude_offset='none' to keep it, or horizontal=True")
    return est, info, warns


def plan_distance_m(ned: np.ndarray, waypoints: np.ndarray) -> float:
    """Smallest horizontal distance from any sample to any leg segment of the plan, m."""
    p = ned[np.isfinite(ned).all(axis=1)][:, :2]
    if p.size == 0:
        return float("nan")
    step = max(1, len(p) // 20000)
    p = p[::step]
    best = np.inf
    for k in range(len(waypoints) - 1):
        a, b = waypoints[k, :2], waypoints[k + 1, :2]
        ab = b - a
        ll = float(ab @ ab)
        f = np.clip(((p - a) @ ab) / ll, 0.0, 1.0) if ll > 0 else np.zeros(len(p))
        d = np.linalg.norm(p - (a + f[:, None] * ab), axis=1)
        best = min(best, float(d.min()))
    return best


#: How many times more samples the reversed plan (or the plan moved sideways) must explain than
#: the plan as given before the warning says so ("clearly more").
MISMATCH_RATIO = 1.25

#: Tolerance factor of the widened check for a plan moved sideways (a neighbouring field).
OFFSET_TOLERANCE_FACTOR = 5.0

#: Largest robust spread of the distances beside the legs, as a fraction of their median, of a
#: plan diagnosed as offset (a parallel track; the tests' offsets give under 0.1).
OFFSET_MAX_SPREAD = 0.3


def _decoded(ned: np.ndarray, vel: np.ndarray, time_s: np.ndarray, waypoints: np.ndarray,
             model: LegModel, ground: np.ndarray | None = None,
             horizontal_only: bool | None = None) -> np.ndarray:
    ev = leg_evidence(ned, vel, waypoints, model, horizontal_only=horizontal_only)
    if ground is not None:
        ev[ground] = model.floor   # ground rows are no evidence for any plan
    lab = decode_legs(ev, time_s, model)
    if ground is not None:
        lab[ground] = -1
    return lab


def _far_warning(model: LegModel, plan_name: str, dist: float) -> str:
    """The warning for a log that comes within ``model.tolerance_m`` of no leg (``dist`` m)."""
    return (f"no sample of the log comes within {model.tolerance_m:g} m of any leg of"
            f" {plan_name} (closest {dist:.0f} m): check that the plan is this flight's"
            " (site, lat/lon order) and its altitude reference")


def plan_warnings(ned: np.ndarray, vel: np.ndarray, time_s: np.ndarray, waypoints: np.ndarray,
                  labels: np.ndarray, model: LegModel, plan_name: str = "the plan",
                  info: dict | None = None, leg_numbers: np.ndarray | None = None,
                  ground: np.ndarray | None = None) -> list[str]:
    """Say what to check when the log does not follow the plan.

    The log is always decoded against the plan reversed (waypoint order) and against the plan
    with a tolerance :data:`OFFSET_TOLERANCE_FACTOR` times wider.  When the reversed plan
    explains clearly more samples (:data:`MISMATCH_RATIO`) than the plan, the plan is diagnosed
    as reversed, unless the widened plan explains clearly more still with most of its samples
    beside the legs: then (and whenever most of the flight along the legs is beside them) the
    plan is diagnosed as offset (another field).  When
    (almost) no sample follows a leg, the distance to the plan and the altitude reference are
    checked too.

    Parameters
    ----------
    ned, vel : ndarray, shape (n, 3)
        Positions [m] (datum offset removed) and velocities [m/s], NED.
    time_s : ndarray, shape (n,)
        Sample times, s.
    waypoints : ndarray, shape (m, 3)
        Plan waypoints, NED, m.
    labels : ndarray of int
        Assigned legs, numbered along ``waypoints`` (-1: none).
    model : LegModel
        Leg model.
    plan_name : str
        How to name the plan in the messages.
    info : dict, optional
        Filled with ``mismatch`` (``None``, ``"reversed"``, ``"offset"``, ``"far"``,
        ``"altitude"`` or ``"few"``), ``n_on_leg``, ``n_reversed``, ``n_widened`` and, for an
        offset, ``offset_m`` (median horizontal distance of the widened samples to their leg).
    leg_numbers : ndarray of int, shape (m - 1,), optional
        The number the user knows each leg of ``waypoints`` by (default ``0 .. m - 2``); the
        legs without a sample are named by it.  A flight diagnosed against the plan reversed
        gives ``waypoints[::-1]`` and ``leg_numbers = arange(m - 1)[::-1]`` so that the
        warning names the legs of the plan as given, as the per-leg report does.
    ground : ndarray of bool, shape (n,), optional
        Rows on the ground (:func:`aeromag.track.ground.ground_rows`): no evidence for the
        plan reversed or moved, not counted among the positioned samples.

    Returns
    -------
    list of str
        Warnings (empty when the log follows the plan).
    """
    info = {} if info is None else info
    info.update(mismatch=None)
    ok = np.isfinite(ned).all(axis=1)
    if ground is not None:
        ground = np.asarray(ground, dtype=bool)
        ok &= ~ground
    n_ok = int(ok.sum())
    n_on = int((labels >= 0).sum())
    info["n_on_leg"] = n_on
    warns: list[str] = []
    if n_ok == 0 or len(waypoints) < 2:
        return warns
    few = n_on <= MIN_ON_LEG_FRACTION * n_ok
    if few:
        dist = plan_distance_m(ned, waypoints)
        if dist > model.tolerance_m * OFFSET_TOLERANCE_FACTOR:
            info["mismatch"] = "far"
            return [_far_warning(model, plan_name, dist)]
    margin = max(10, int(0.01 * n_ok))
    rev_lab = _decoded(ned, vel, time_s, waypoints[::-1], model, ground)
    n_rev = int((rev_lab >= 0).sum())
    wide_model = dataclasses.replace(
        model, tolerance_m=model.tolerance_m * OFFSET_TOLERANCE_FACTOR)
    wide = _decoded(ned, vel, time_s, waypoints, wide_model, ground)
    n_wide = int((wide >= 0).sum())
    info.update(n_reversed=n_rev, n_widened=n_wide)
    # offset: most of the flight along the legs' directions is beside them, not on them, at a
    # steady distance (a ferry between legs flown out of order converges to or diverges from
    # a leg's line: its distances spread from 0 to the widened tolerance)
    sel = (wide >= 0) & (labels < 0)
    side = np.full(int(sel.sum()), np.nan)
    for k in np.unique(wide[sel]):
        m = wide[sel] == k
        _, h, _, _ = cross_track(ned[sel][m], waypoints[k], waypoints[k + 1])
        side[m] = np.abs(h)
    off = float(np.median(side)) if side.size else float("nan")
    steady = side.size > 0 and (
        1.4826 * float(np.median(np.abs(side - off))) < OFFSET_MAX_SPREAD * off)
    offset_like = n_on < 0.5 * n_wide and n_wide - n_on > margin and steady
    # and by the distance covered: slow rows (a vehicle walked back along a line) are many
    reversed_like = (n_rev > MISMATCH_RATIO * n_on and n_rev - n_on > margin
                     and covered_m(rev_lab, ned, waypoints[::-1])
                     > MISMATCH_RATIO * covered_m(labels, ned, waypoints))
    if reversed_like and not (offset_like and n_wide > MISMATCH_RATIO * n_rev):
        info["mismatch"] = "reversed"
        warns.append(
            f"{n_on} sample(s) follow a leg of {plan_name} but {n_rev} follow its legs"
            " backwards: the plan looks reversed (check the waypoint order); the alarms are of"
            " the flight against the plan as given")
        return warns
    if offset_like:
        info.update(mismatch="offset", offset_m=off)
        warns.append(
            f"most straight flight follows no leg of {plan_name}: {n_wide - n_on} sample(s) fly"
            f" along its legs a median {off:.1f} m beside them ({n_on} on a leg): the plan may be"
            " offset or for another field (check the site and the plan's coordinates)")
        return warns
    if few:
        if dist > model.tolerance_m:
            info["mismatch"] = "far"
            return [_far_warning(model, plan_name, dist)]
        if not model.horizontal_only:
            hor = _decoded(ned, vel, time_s, waypoints, model, ground, horizontal_only=True)
            n_hor = int((hor >= 0).sum())
            if n_hor > max(10, 5 * n_on):
                info["mismatch"] = "altitude"
                warns.append(
                    f"{n_hor} sample(s) follow the legs of {plan_name} horizontally but not at"
                    " the planned altitude: check the altitude reference (relative to home,"
                    " mean sea level or ellipsoid), or use horizontal=True")
                return warns
        info["mismatch"] = "few"
        warns.append(
            f"only {n_on} of {n_ok} positioned samples follow a leg of {plan_name}: check the"
            " plan (waypoint order, site, altitude reference)")
        return warns
    names = (np.arange(len(waypoints) - 1) if leg_numbers is None
             else np.asarray(leg_numbers, dtype=np.int64))
    if names.shape != (len(waypoints) - 1,):
        raise ValueError(f"leg_numbers has {names.size} values for {len(waypoints) - 1} legs")
    flown = np.zeros(len(names), dtype=bool)
    flown[np.unique(labels[labels >= 0])] = True
    missing = sorted(int(k) for k in names[~flown])
    if missing:
        warns.append(f"leg(s) {', '.join(map(str, missing))} of {plan_name} have no sample:"
                     " not flown, or not along the plan")
    return warns
