"""DGPS track-deviation check per mission leg, combined with the heading detector.

Method (methods M2): a multirotor on RTK DGPS follows its planned lines to within tens of
centimetres.  When a magnetic disturbance bends the compass, the estimated heading drifts, the
commanded acceleration is rotated by the heading error and the track leaves the line.  For a
leg from waypoint ``A`` to ``B`` and an antenna position ``X``, all in a local north-east-down
(NED) frame with its origin at the first waypoint of the plan (the take-off point),

    d = |(X - A) x (B - A)| / |B - A|                                   (``xtrack_m``)

and the sample alarms when ``d`` is strictly above a threshold (1 m by default).

Geometry is exact: geodetic (WGS84 latitude, longitude, ellipsoidal height) -> ECEF with pyproj
(one Transformer, built once) -> NED by the rotation at the origin.  No degrees are ever used as
metres, so the result holds anywhere on Earth, across UTM zone boundaries and at high latitude.
The deviation is split into a horizontal part ``xtrack_h_m`` (signed, positive to the right of
the direction of travel) and a vertical part ``xtrack_v_m`` (signed, positive above the line),
with ``hypot(xtrack_h_m, xtrack_v_m) == xtrack_m``; ``along_m`` is the position along the leg
from ``A``.

Leg assignment
--------------
When the log has a ``leg`` column (the autopilot's own leg index) it is used as is (empty or
negative values mean "no leg").  Otherwise legs are assigned by this rule, with a waypoint
radius ``R`` (default 5 m, enlarged to 1.5 times the 95th percentile of the distance between
successive samples when the log is sparse):

1. *Leg start.*  Leg ``k`` (``A = W_k`` to ``B = W_k+1``) starts at the first sample at which
   the vehicle leaves the sphere of radius ``R`` around ``A`` towards ``B``: the previous sample
   was inside the sphere, this one is outside, and it lies within 45 degrees of the leg's
   direction (cross-track distance <= along-track distance).  A vehicle that has not reached
   ``A`` yet, is climbing to it, or is turning around inside it is therefore not on the leg.
2. *Leg end.*  The leg ends (exclusive) at the first later sample inside the sphere around
   ``B`` or past the plane through ``B`` perpendicular to the leg, or when the vehicle leaves
   ``A`` towards ``B`` again (the leg is being re-flown).
3. *Sequence.*  Starting from the beginning of the log, the next leg is the one whose start
   event comes first after the current leg's end; on a tie the next leg in the plan is
   preferred, then the same leg again (re-flown), then the nearest leg number.
4. Samples on no leg -- take-off, climb to the first waypoint, turns and hovering inside the
   waypoint spheres, transit back to re-fly a leg, landing -- get an empty ``leg``, no
   ``xtrack_*`` values and never alarm.

Turns therefore never count as deviations; the price is that the first and last ``R`` metres
of each leg are not checked.

Per-leg summary: ``leg``, ``n_samples``, ``t_start``/``t_end`` [s], ``max_xtrack_m``,
``max_abs_xtrack_h_m``, ``max_abs_xtrack_v_m``, ``first_alarm_time`` (combined verdict; null
when none), ``first_track_alarm_time``, ``first_heading_alarm_time``, ``time_above_threshold_s``,
``flagged`` and ``first_detector`` (``"track"``, ``"heading"``, ``"both"`` or null).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from .._core.geodesy import geodetic_to_ned
from ..detection.combine import combine_alarms
from ..detection.heading import CalmWindow, heading_columns_available, heading_detector
from ..errors import InputError
from .deviation import leg_summary, track_alarm
from .geometry import cross_track
from .legs import DEFAULT_WAYPOINT_RADIUS_M, assign_legs, labels_from_column
from .plan import validate_plan

__all__ = ["ADDED_COLUMNS", "TrackResult", "check_track"]

log = logging.getLogger(__name__)

#: Columns that ``track`` adds, in output order.
ADDED_COLUMNS = ("leg", "xtrack_m", "xtrack_h_m", "xtrack_v_m", "along_m", "track_alarm",
                 "heading_diff_deg", "heading_alarm", "alarm")


@dataclass
class TrackResult:
    """Result of :func:`check_track`.

    Attributes
    ----------
    data : DataFrame
        The input log with the added columns (``leg``, ``xtrack_m``, ``xtrack_h_m``,
        ``xtrack_v_m``, ``along_m``, ``track_alarm``, and when possible ``heading_diff_deg``,
        ``heading_alarm``; always ``alarm``).
    legs : list of dict
        Per-leg summary (see :func:`leg_summary`).
    report : dict
        The JSON report: ``{"legs": legs, ...settings and heading statistics}``.
    """

    data: pd.DataFrame
    legs: list[dict[str, Any]] = field(default_factory=list)
    report: dict[str, Any] = field(default_factory=dict)


def check_track(
    log_df: pd.DataFrame,
    plan: pd.DataFrame,
    *,
    threshold_m: float = 1.0,
    min_duration_s: float = 0.0,
    calm_window: CalmWindow = None,
    heading_sigmas: float = 5.0,
    declination_deg: float = 0.0,
    combine: str = "or",
    waypoint_radius_m: float = DEFAULT_WAYPOINT_RADIUS_M,
    source: str | None = None,
) -> TrackResult:
    """Flag DGPS track deviations per leg, run the heading detector and combine them.

    Parameters
    ----------
    log_df : DataFrame
        Survey log with ``time`` [s], ``lat``/``lon`` [deg], ``alt`` [m]; optionally ``leg``,
        ``heading`` [deg] with ``mag_heading`` [deg] or ``flux_x/y/z`` [nT] + ``pitch``/``roll``
        [deg] for the heading detector.
    plan : DataFrame
        Waypoints with ``lat``, ``lon`` [deg], ``alt`` [m] (validated here).
    threshold_m : float
        Track alarm threshold, m (alarm when ``xtrack_m`` is strictly above it).
    min_duration_s : float
        Minimum duration of an exceedance before the track alarm fires, s.
    calm_window : float, (float, float), str or None
        Calm reference window of the heading detector: seconds from the start (default 30) or
        an absolute time range (``"t0:t1"``), s.
    heading_sigmas : float
        Heading alarm factor ``k`` (alarm above ``k`` sigma of the calm window).
    declination_deg : float
        Declination for a fluxgate-derived magnetometer heading, degrees east.
    combine : {"or", "and"}
        How the two detectors make the verdict ``alarm`` (see
        :func:`aeromag.detection.combine.combine_alarms`).
    waypoint_radius_m : float
        Waypoint radius of the leg-assignment rule, m (unused when the log has ``leg``).
    source : str, optional
        Name of the log quoted in errors (default ``log_df.attrs["source"]``).

    Returns
    -------
    TrackResult
    """
    src = source or str(log_df.attrs.get("source", "<log>"))
    if not np.isfinite(threshold_m) or threshold_m <= 0:
        raise InputError(f"--threshold {threshold_m!r}: must be a positive number of metres")
    if not np.isfinite(min_duration_s) or min_duration_s < 0:
        raise InputError(f"--min-duration {min_duration_s!r}: must be >= 0 seconds")
    if not np.isfinite(waypoint_radius_m) or waypoint_radius_m <= 0:
        raise InputError(f"--waypoint-radius {waypoint_radius_m!r}: must be positive metres")
    if str(combine).lower() not in ("or", "and"):
        raise InputError(f"--combine {combine!r}: use 'or' or 'and'")
    missing = [c for c in ("time", "lat", "lon", "alt") if c not in log_df.columns]
    if missing:
        raise InputError(
            f"{src}: missing column(s) {', '.join(missing)}; the track check needs time, lat, lon"
            " and alt (DGPS position); map them with --col NAME=SOURCE"
        )
    plan = validate_plan(plan, str(plan.attrs.get("source", "<plan>")))
    wp_geo = plan[["lat", "lon", "alt"]].to_numpy(dtype=np.float64)
    origin = (float(wp_geo[0, 0]), float(wp_geo[0, 1]), float(wp_geo[0, 2]))
    wps = geodetic_to_ned(wp_geo[:, 0], wp_geo[:, 1], wp_geo[:, 2], origin)
    n_legs = len(wps) - 1

    data = log_df.copy()
    pos = data[["lat", "lon", "alt"]].apply(pd.to_numeric, errors="coerce")
    lat, lon, alt = (pos[c].to_numpy(dtype=np.float64) for c in ("lat", "lon", "alt"))
    ok = np.isfinite(lat) & np.isfinite(lon) & np.isfinite(alt)
    if not ok.any():
        raise InputError(f"{src}: no row has a finite lat, lon and alt; the track check needs"
                         " DGPS positions")
    ned = np.full((len(data), 3), np.nan)
    ned[ok] = geodetic_to_ned(lat[ok], lon[ok], alt[ok], origin)

    if "leg" in data.columns:
        labels = labels_from_column(data, n_legs, src)
        how = "log column"
    else:
        labels = assign_legs(ned, wps, waypoint_radius_m=waypoint_radius_m)
        how = "assigned"
    labels[~ok] = -1

    n = len(data)
    xt, xh, xv, al = (np.full(n, np.nan) for _ in range(4))
    for k in np.unique(labels[labels >= 0]):
        m = labels == k
        d, h, v, a = cross_track(ned[m], wps[k], wps[k + 1])
        xt[m], xh[m], xv[m], al[m] = d, h, v, a
    t = data["time"].to_numpy(dtype=np.float64)
    tr = track_alarm(xt, labels, t, threshold_m=threshold_m, min_duration_s=min_duration_s)

    data["leg"] = pd.array(np.where(labels >= 0, labels, 0), dtype="Int64")
    data.loc[labels < 0, "leg"] = pd.NA
    data["xtrack_m"] = xt
    data["xtrack_h_m"] = xh
    data["xtrack_v_m"] = xv
    data["along_m"] = al
    data["track_alarm"] = tr

    heading_info: dict[str, Any] = {"available": False}
    hd_alarm = None
    if heading_columns_available(data) is not None:
        hres = heading_detector(data, calm_window=calm_window, sigmas=heading_sigmas,
                                declination_deg=declination_deg, source=src)
        hd_alarm = hres.alarm & (labels >= 0)
        data["heading_diff_deg"] = hres.diff_deg
        data["heading_alarm"] = hd_alarm
        heading_info = {"available": True, "source": hres.source, "mean_deg": hres.mean_deg,
                        "sigma_deg": hres.sigma_deg, "n_calm": hres.n_calm,
                        "sigmas": heading_sigmas, "declination_deg": declination_deg}
    else:
        log.info("%s: no heading columns; heading detector skipped", src)
    data["alarm"] = combine_alarms([tr, hd_alarm], labels, combine)

    legs = leg_summary(data, n_legs, threshold_m, {"track": tr, "heading": hd_alarm})
    report = {
        "legs": legs,
        "n_legs": n_legs,
        "n_flagged": sum(1 for row in legs if row["flagged"]),
        "flagged_legs": [row["leg"] for row in legs if row["flagged"]],
        "threshold_m": threshold_m,
        "min_duration_s": min_duration_s,
        "combine": str(combine).lower(),
        "leg_source": how,
        "waypoint_radius_m": waypoint_radius_m,
        "origin": {"lat": origin[0], "lon": origin[1], "alt": origin[2]},
        "heading_detector": heading_info,
        "n_samples": n,
        "n_on_leg": int((labels >= 0).sum()),
    }
    log.info("%s: %d/%d legs flagged", src, report["n_flagged"], n_legs)
    return TrackResult(data=data, legs=legs, report=report)
