"""What to tell the user about a log against its plan: altitude datums, reversed or far plans.

* **Altitude datum.**  A log whose altitude is relative to home, or above mean sea level
  against a plan on the ellipsoid, sits a constant height above or below every leg.  The
  offset is the median height above the leg's line of the samples that follow a leg
  horizontally (:func:`~aeromag.track.legs.estimate_altitude_offset`); it is taken as a datum
  difference and removed when it exceeds :data:`DATUM_MIN_OFFSET_M` and three times its robust
  spread, and the report says so.
* **Plans that do not match the flight.**  When (almost) no sample follows a leg, the log is
  checked against the plan reversed (waypoint order), horizontally only (altitude reference),
  and for distance (site): the warning says which.
"""

from __future__ import annotations

import numpy as np

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
            " before the check. Give --altitude-offset none to keep it, or --horizontal")
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


def plan_warnings(ned: np.ndarray, vel: np.ndarray, time_s: np.ndarray, waypoints: np.ndarray,
                  labels: np.ndarray, model: LegModel, plan_name: str = "the plan"
                  ) -> list[str]:
    """Say what to check when the log does not follow the plan.

    Parameters
    ----------
    ned, vel : ndarray, shape (n, 3)
        Positions [m] (datum offset removed) and velocities [m/s], NED.
    time_s : ndarray, shape (n,)
        Sample times, s.
    waypoints : ndarray, shape (m, 3)
        Plan waypoints, NED, m.
    labels : ndarray of int
        Assigned legs (-1: none).
    model : LegModel
        Leg model.
    plan_name : str
        How to name the plan in the messages.

    Returns
    -------
    list of str
        Warnings (empty when the log follows the plan).
    """
    ok = np.isfinite(ned).all(axis=1)
    n_ok = int(ok.sum())
    n_on = int((labels >= 0).sum())
    warns: list[str] = []
    if n_ok == 0:
        return warns
    if n_on <= MIN_ON_LEG_FRACTION * n_ok:
        dist = plan_distance_m(ned, waypoints)
        if dist > model.tolerance_m:
            warns.append(
                f"no sample of the log comes within {model.tolerance_m:g} m of any leg of"
                f" {plan_name} (closest {dist:.0f} m): check that the plan is this flight's"
                " (site, lat/lon order) and its altitude reference")
            return warns
        rev = decode_legs(leg_evidence(ned, vel, waypoints[::-1], model), time_s, model)
        n_rev = int((rev >= 0).sum())
        if n_rev > max(10, 5 * n_on):
            warns.append(
                f"{n_on} sample(s) follow a leg of {plan_name} but {n_rev} follow its legs"
                " backwards: check the waypoint order (is the plan reversed?)")
            return warns
        if not model.horizontal_only:
            hor = decode_legs(leg_evidence(ned, vel, waypoints, model, horizontal_only=True),
                              time_s, model)
            n_hor = int((hor >= 0).sum())
            if n_hor > max(10, 5 * n_on):
                warns.append(
                    f"{n_hor} sample(s) follow the legs of {plan_name} horizontally but not at"
                    " the planned altitude: check the altitude reference (relative to home,"
                    " mean sea level or ellipsoid), or use --horizontal")
                return warns
        warns.append(
            f"only {n_on} of {n_ok} positioned samples follow a leg of {plan_name}: check the"
            " plan (waypoint order, site, altitude reference)")
        return warns
    flown = set(np.unique(labels[labels >= 0]).tolist())
    missing = [k for k in range(len(waypoints) - 1) if k not in flown]
    if missing:
        warns.append(f"leg(s) {', '.join(map(str, missing))} of {plan_name} have no sample:"
                     " not flown, or not along the plan")
    return warns
