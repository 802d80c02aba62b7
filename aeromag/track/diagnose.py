"""What to tell the user about a log against its plan: altitude datums, reversed or far plans.

* **Altitude datum.**  A log whose altitude is relative to home, or above mean sea level
  against a plan on the ellipsoid, sits a constant height above or below every leg.  The
  offset is the median height above the leg's line of the samples that follow a leg
  horizontally (:func:`~aeromag.track.legs.estimate_altitude_offset`); it is taken as a datum
  difference and removed when it exceeds :data:`DATUM_MIN_OFFSET_M` and three times its robust
  spread, and the report says so.
* **Plans that do not match the flight.**  The log is always decoded against the plan
  reversed (waypoint order) and against the plan with a widened tolerance (a plan moved
  sideways: a neighbouring field); when (almost) no sample follows a leg, also horizontally
  only (altitude reference) and for distance (site): the warning says which.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .geometry import cross_track
from .legs import LegModel, decode_legs, estimate_altitude_offset, leg_evidence

__all__ = ["DATUM_MIN_OFFSET_M", "altitude_offset", "plan_distance_m", "plan_warnings"]

#: Smallest constant vertical offset taken as a datum difference, m.  Datum differences are
#: tens of metres (geoid undulation -106 to +85 m; a take-off height of 20-500 m for altitudes
#: relative to home); a smaller constant offset is more likely the vehicle flying too high or
#: too low, which the check must report as deviation.
DATUM_MIN_OFFSET_M = 3.0

#: Fraction of the positioned samples on legs below which the plan is diagnosed.
MIN_ON_LEG_FRACTION = 0.01


def altitude_offset(ned: np.ndarray, vel: np.ndarray, waypoints: np.ndarray, model: LegModel,
                    spec: str | float) -> tuple[float, dict, list[str]]:
    """Resolve the vertical offset to remove from the log's altitude.

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

    Returns
    -------
    applied_m : float
        Height of the log above the plan removed from every sample, m (0 when none).
    info : dict
        ``mode``, ``estimated_m``, ``spread_m``, ``n_samples``, ``applied_m`` for the report.
    warnings : list of str
    """
    text = str(spec).strip().lower()
    est, spread, n = estimate_altitude_offset(ned, vel, waypoints, model)
    # a mission flown against the plan reversed follows the reversed legs
    est_r, spread_r, n_r = estimate_altitude_offset(ned, vel, waypoints[::-1].copy(), model)
    if n_r > n:
        est, spread, n = est_r, spread_r, n_r
    info = {"mode": text if text in ("auto", "none") else "given",
            "estimated_m": None if not np.isfinite(est) else est,
            "spread_m": None if not np.isfinite(spread) else spread,
            "n_samples": n, "applied_m": 0.0}
    warns: list[str] = []
    if text == "none":
        return 0.0, info, warns
    if text != "auto":
        val = float(spec)
        info["applied_m"] = val
        return val, info, warns
    if (np.isfinite(est) and n >= 10 and abs(est) > DATUM_MIN_OFFSET_M
            and abs(est) > 3.0 * spread):
        info["applied_m"] = est
        where = "above" if est > 0 else "below"
        warns.append(
            f"the log's altitude is a constant {abs(est):.1f} m {where} the plan on the legs"
            f" (spread {spread:.2f} m over {n} samples): a different altitude reference (altitude"
            " relative to home, or above mean sea level against an ellipsoidal plan?); removed"
            " before the check. Give altitude_offset='none' to keep it, or horizontal=True")
    return info["applied_m"], info, warns


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
             model: LegModel) -> np.ndarray:
    return decode_legs(leg_evidence(ned, vel, waypoints, model), time_s, model)


def plan_warnings(ned: np.ndarray, vel: np.ndarray, time_s: np.ndarray, waypoints: np.ndarray,
                  labels: np.ndarray, model: LegModel, plan_name: str = "the plan",
                  info: dict | None = None, leg_numbers: np.ndarray | None = None
                  ) -> list[str]:
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

    Returns
    -------
    list of str
        Warnings (empty when the log follows the plan).
    """
    info = {} if info is None else info
    info.update(mismatch=None)
    ok = np.isfinite(ned).all(axis=1)
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
            warns.append(
                f"no sample of the log comes within {model.tolerance_m:g} m of any leg of"
                f" {plan_name} (closest {dist:.0f} m): check that the plan is this flight's"
                " (site, lat/lon order) and its altitude reference")
            return warns
    margin = max(10, int(0.01 * n_ok))
    n_rev = int((_decoded(ned, vel, time_s, waypoints[::-1], model) >= 0).sum())
    wide_model = dataclasses.replace(
        model, tolerance_m=model.tolerance_m * OFFSET_TOLERANCE_FACTOR)
    wide = _decoded(ned, vel, time_s, waypoints, wide_model)
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
    reversed_like = n_rev > MISMATCH_RATIO * n_on and n_rev - n_on > margin
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
            warns.append(
                f"no sample of the log comes within {model.tolerance_m:g} m of any leg of"
                f" {plan_name} (closest {dist:.0f} m): check that the plan is this flight's"
                " (site, lat/lon order) and its altitude reference")
            return warns
        if not model.horizontal_only:
            hor = decode_legs(leg_evidence(ned, vel, waypoints, model, horizontal_only=True),
                              time_s, model)
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
