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
negative values mean "no leg").  Otherwise a hidden Markov model over "on leg k / off plan"
decoded with Viterbi follows what the vehicle does (:mod:`aeromag.track.legs`): progress along
the leg, motion along it, distance to its line and altitude near the planned one.  Take-off,
climb, hovering and turning at waypoints, transits not in the plan, landing and ground time
belong to no leg: empty ``leg``, no ``xtrack_*`` values, never an alarm.  A leg flown twice gets
both passes.  Over the whole log (:mod:`aeromag.track.assign`) the plan is also tried reversed
(a mission flown last waypoint first is checked along its legs), the tolerances widen for a
noisy (non-RTK) position, and runs not flown on their line (ferries between legs) are dropped.
A constant vertical offset (a different altitude datum) is detected, reported and removed
(:mod:`aeromag.track.diagnose`); ``horizontal=True`` uses the horizontal distance only.

Per-leg summary: ``leg``, ``n_samples``, ``checked`` (any sample), ``t_start``/``t_end`` [s],
``max_xtrack_m``, ``max_abs_xtrack_h_m``, ``max_abs_xtrack_v_m``, ``first_alarm_time`` (combined
verdict; null when none), ``first_track_alarm_time``, ``first_heading_alarm_time``,
``time_above_threshold_s``, ``flagged``, ``first_detector`` (``"track"``, ``"heading"``,
``"both"`` or null), ``n_passes``
and ``passes`` (the same keys per pass, with its own start and end).
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from .._core.geodesy import geodetic_to_ned
from ..detection.alarms import Alarms
from ..detection.combine import combine_alarms
from ..detection.heading import (
    DEFAULT_SIGMA_FLOOR_DEG,
    CalmWindow,
    heading_columns_available,
    heading_detector,
)
from ..errors import InputError
from . import diagnose
from .assign import assign_track_legs
from .deviation import leg_summary, track_alarm
from .geometry import cross_track
from .ground import ground_rows
from .legs import LegModel, labels_from_column, leg_passes, velocity_for_legs
from .offset import OFFSET_DECODE_MIN_M
from .plan import validate_plan
from .report import LegSummary, TrackReport

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
    legs : list of LegSummary
        Per-leg summary (see :func:`leg_summary`).
    report : TrackReport
        The report (its ``legs`` are these; ``report.to_dict()`` is OUT.json).
    plan : DataFrame or None
        The validated plan the log was checked against.
    """

    data: pd.DataFrame
    legs: list[LegSummary] = field(default_factory=list)
    report: TrackReport = field(default_factory=TrackReport)
    plan: pd.DataFrame | None = None


def check_track(
    log_df: pd.DataFrame,
    plan: pd.DataFrame,
    *,
    threshold_m: float = 1.0,
    min_duration_s: float = 0.0,
    calm_window: CalmWindow = None,
    heading_sigmas: float = 5.0,
    heading_sigma_floor_deg: float = DEFAULT_SIGMA_FLOOR_DEG,
    declination_deg: float = 0.0,
    combine: str = "or",
    horizontal: bool = False,
    altitude_offset: str | float = "auto",
    leg_model: LegModel | None = None,
    position: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    heading_deg: np.ndarray | None = None,
    detectors: Sequence[Alarms] = (),
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
    heading_sigma_floor_deg : float
        Floor of the heading detector's calm sigma, degrees.
    declination_deg : float
        Declination for a fluxgate-derived magnetometer heading, degrees east.
    combine : {"or", "and"}
        How the detectors make the verdict ``alarm`` (see
        :func:`aeromag.detection.combine.combine_alarms`).
    horizontal : bool
        Use the horizontal distance only (``xtrack_m = abs(xtrack_h_m)``) and leave altitude out
        of the leg assignment.
    altitude_offset : "auto", "none" or float
        Constant height of the log above the plan to remove: estimated (``auto``), never
        (``none``) or given, m (see :mod:`aeromag.track.diagnose`).
    leg_model : LegModel, optional
        Parameters of the leg assignment (default :class:`~aeromag.track.legs.LegModel`).
    position : (lat, lon, alt) arrays, optional
        Antenna position per row, degrees, degrees, m (default the log's ``lat``, ``lon``,
        ``alt``), e.g. a navigated position where the GNSS has gaps.
    heading_deg : ndarray, optional
        Attitude heading per row for the heading detector, degrees (default the log's
        ``heading``), e.g. a navigation filter's yaw.
    detectors : sequence of Alarms
        Further detectors' results on the same rows (e.g. the particle filter, name ``pf``):
        each adds ``<name>_alarm`` (on legs only), enters ``alarm`` and the per-leg summary.
    source : str, optional
        Name of the log quoted in errors (default ``log_df.attrs["source"]``).

    Returns
    -------
    TrackResult
    """
    src = source or str(log_df.attrs.get("source", "<log>"))
    if not np.isfinite(threshold_m) or threshold_m <= 0:
        raise InputError(f"threshold_m={threshold_m!r}: must be a positive number of metres")
    if not np.isfinite(min_duration_s) or min_duration_s < 0:
        raise InputError(f"min_duration_s={min_duration_s!r}: must be >= 0 seconds")
    if str(combine).lower() not in ("or", "and"):
        raise InputError(f"combine={combine!r}: use 'or' or 'and'")
    offset_spec = _offset_spec(altitude_offset)
    need = ("time",) if position is not None else ("time", "lat", "lon", "alt")
    missing = [c for c in need if c not in log_df.columns]
    if missing:
        hint = ""
        if "alt" in missing and "alt_msl" in log_df.columns:
            # the reader names a height above mean sea level alt_msl, never alt (ellipsoidal)
            hint = ("; the log's height is alt_msl, above mean sea level, not the ellipsoid:"
                    " map it with columns={'alt': 'alt_msl'} (a constant datum difference over"
                    " 3 m is detected on the legs and removed, see the altitude offset in"
                    " OUT.json), or check horizontally with horizontal=True")
        raise InputError(
            f"{src}: missing column(s) {', '.join(missing)}; the track check needs time, lat, lon"
            f" and alt (DGPS position); columns are: {', '.join(map(str, log_df.columns[:30]))};"
            f" map them with columns={{'NAME': 'SOURCE'}}{hint}"
        )
    plan_src = str(plan.attrs.get("source", "<plan>"))
    plan = validate_plan(plan, plan_src)
    wp_geo = plan[["lat", "lon", "alt"]].to_numpy(dtype=np.float64)
    origin = (float(wp_geo[0, 0]), float(wp_geo[0, 1]), float(wp_geo[0, 2]))
    wps = geodetic_to_ned(wp_geo[:, 0], wp_geo[:, 1], wp_geo[:, 2], origin)
    n_legs = len(wps) - 1
    model = leg_model or LegModel(horizontal_only=horizontal)
    if horizontal and not model.horizontal_only:
        model = dataclasses.replace(model, horizontal_only=True)

    data = log_df.copy()
    n = len(data)
    if position is None:
        pos = data[["lat", "lon", "alt"]].apply(pd.to_numeric, errors="coerce")
        lat, lon, alt = (pos[c].to_numpy(dtype=np.float64) for c in ("lat", "lon", "alt"))
    else:
        lat, lon, alt = (np.asarray(c, dtype=np.float64) for c in position)
        if not (len(lat) == len(lon) == len(alt) == n):
            raise InputError(f"{src}: the position arrays must have one value per row ({n})")
    ok = np.isfinite(lat) & np.isfinite(lon) & np.isfinite(alt)
    if not ok.any():
        raise InputError(f"{src}: no row has a finite lat, lon and alt; the track check needs"
                         " DGPS positions")
    ned = np.full((n, 3), np.nan)
    ned[ok] = geodetic_to_ned(lat[ok], lon[ok], alt[ok], origin)
    t = pd.to_numeric(data["time"], errors="coerce").to_numpy(dtype=np.float64)
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size or not np.isfinite(t).all():
        i = int(back[0] + 1) if back.size else int(np.flatnonzero(~np.isfinite(t))[0])
        raise InputError(f"{src}: column 'time', row {i + 1}: {t[i]:g} is not a time after the"
                         " previous row's; the track check needs increasing times (sort the log"
                         " by time)")
    gv = None
    if all(c in data.columns for c in ("vel_n", "vel_e", "vel_d")):
        gv = data[["vel_n", "vel_e", "vel_d"]].apply(pd.to_numeric, errors="coerce").to_numpy(
            dtype=np.float64)
    vel, vel_info = velocity_for_legs(t, ned, model, gv)
    # rows on the ground (the log's armed/landed columns, or inferred): never on a leg and
    # never evidence for a datum, an offset or a direction
    ground, ground_info = ground_rows(t, ned, vel, data, src)

    warnings: list[str] = []
    applied, alt_info, w = diagnose.altitude_offset(ned, vel, wps, model, offset_spec,
                                                    time_s=t, ground=ground)
    warnings += w
    if applied:
        ned[:, 2] += applied   # the log's height above the plan removed (down is positive)

    plan_check: dict[str, Any] = {"mismatch": None}
    assign_info = None
    if "leg" in data.columns:
        labels = labels_from_column(data, n_legs, src)
        how = "log column"
        if ground_info["source"] != "inferred":
            labels[ground] = -1   # the log says the vehicle is on the ground there
    else:
        labels, model, assign_info, w = assign_track_legs(ned, vel, t, wps, model, ground)
        labels[~ok] = -1   # as reported: the plan diagnosis names the legs with no sample
        how = "assigned"
        warnings += w
        if assign_info["direction"] == "reversed":
            # diagnosed against the plan as flown (reversed); the plan as given is reversed
            # (numbered along it; the legs not flown are named in the plan's numbering)
            n_k = n_legs - 1
            warnings += diagnose.plan_warnings(ned, vel, t, wps[::-1].copy(),
                                               np.where(labels >= 0, n_k - labels, -1), model,
                                               plan_src, info=plan_check,
                                               leg_numbers=np.arange(n_legs)[::-1],
                                               ground=ground)
            if plan_check.get("mismatch") is None:
                plan_check["mismatch"] = "reversed"
            # counted against the plan as given: on its legs, and on them backwards
            plan_check.update(n_on_leg=assign_info["n_forward"],
                              n_reversed=assign_info["n_reversed"])
        else:
            warnings += diagnose.plan_warnings(ned, vel, t, wps, labels, model, plan_src,
                                               info=plan_check, ground=ground)
        plan_check["assignment"] = assign_info
    labels[~ok] = -1

    xt, xh, xv, al = (np.full(n, np.nan) for _ in range(4))
    for k in np.unique(labels[labels >= 0]):
        m = labels == k
        d, h, v, a = cross_track(ned[m], wps[k], wps[k + 1])
        xt[m], xh[m], xv[m], al[m] = (np.abs(h) if horizontal else d), h, v, a
    pass_id, passes = leg_passes(labels, t, al)
    if assign_info is not None:
        warnings += _offset_warning(assign_info, plan_check, plan_src, passes, t)
    tr = track_alarm(xt, pass_id, t, threshold_m=threshold_m, min_duration_s=min_duration_s)

    data["leg"] = pd.array(np.where(labels >= 0, labels, 0), dtype="Int64")
    data.loc[labels < 0, "leg"] = pd.NA
    data["xtrack_m"] = xt
    data["xtrack_h_m"] = xh
    data["xtrack_v_m"] = xv
    data["along_m"] = al
    data["track_alarm"] = tr

    heading_info: dict[str, Any] = {"available": False}
    hd_alarm = None
    if heading_deg is not None or heading_columns_available(data) is not None:
        hdf = data if heading_deg is None else data.assign(
            heading=np.asarray(heading_deg, dtype=np.float64))
        hres = heading_detector(hdf, calm_window=calm_window, sigmas=heading_sigmas,
                                declination_deg=declination_deg,
                                sigma_floor_deg=heading_sigma_floor_deg, source=src)
        hd_alarm = hres.alarm & (labels >= 0)
        data["heading_diff_deg"] = hres.diff_deg
        data["heading_alarm"] = hd_alarm
        heading_info = {"available": True, "source": hres.source, "mean_deg": hres.mean_deg,
                        "sigma_deg": hres.sigma_deg, "sigma_raw_deg": hres.sigma_raw_deg,
                        "sigma_floor_deg": hres.sigma_floor_deg,
                        "floored": hres.sigma_raw_deg < hres.sigma_floor_deg,
                        "n_calm": hres.n_calm, "sigmas": heading_sigmas,
                        "declination_deg": declination_deg,
                        "heading_input": "log" if heading_deg is None else "given"}
    else:
        log.info("%s: no heading columns; heading detector skipped", src)
    dets: dict[str, np.ndarray | None] = {"track": tr, "heading": hd_alarm}
    for extra in detectors:
        if len(extra.alarm) != n:
            raise InputError(f"{src}: detector {extra.name!r} has {len(extra.alarm)} rows,"
                             f" the log {n}")
        dets[extra.name] = extra.alarm & (labels >= 0)
        data[f"{extra.name}_alarm"] = dets[extra.name]
    data["alarm"] = combine_alarms(list(dets.values()), pass_id, combine)

    legs = leg_summary(data, n_legs, threshold_m, dets, pass_id)
    warnings += _unchecked_warning(ned, t, labels, src)
    for msg in warnings:
        log.warning("%s", msg)
    report = TrackReport(
        legs=legs, n_legs=n_legs, threshold_m=threshold_m, min_duration_s=min_duration_s,
        combine=str(combine).lower(), distance="horizontal" if horizontal else "3d",
        leg_source=how, leg_model=model.to_dict() if how == "assigned" else None,
        n_passes=int(len(passes)), altitude_offset=alt_info, ground=ground_info,
        origin={"lat": origin[0], "lon": origin[1], "alt": origin[2]},
        position_input="log" if position is None else "given", velocity=vel_info,
        heading_detector=heading_info,
        detectors=[{"detector": name, "ran": a is not None,
                    "n_alarms": None if a is None else int(np.asarray(a).sum())}
                   for name, a in dets.items()],
        n_samples=n, n_on_leg=int((labels >= 0).sum()), plan_check=plan_check,
        warnings=warnings)
    log.info("%s: %d/%d legs flagged (%d checked)", src, report.n_flagged, n_legs,
             report.n_legs_checked)
    return TrackResult(data=data, legs=legs, report=report, plan=plan)


#: A log whose positions span less than this (horizontally, m) or this long (s) is not a flight.
STATIONARY_SPAN_M = 2.0
STATIONARY_SPAN_S = 1.0


def _unchecked_warning(ned: np.ndarray, t: np.ndarray, labels: np.ndarray, src: str
                       ) -> list[str]:
    """Say plainly that nothing was checked when no row is on a leg.

    Says why when the log is not a flight (a stationary or very short log).
    """
    if (labels >= 0).any():
        return []
    fin = np.isfinite(ned).all(axis=1)
    p = ned[fin, :2]
    span_m = float(np.linalg.norm(p.max(axis=0) - p.min(axis=0))) if p.size else 0.0
    span_s = float(t[fin].max() - t[fin].min()) if fin.any() else 0.0
    why = ""
    if span_m < STATIONARY_SPAN_M or span_s < STATIONARY_SPAN_S:
        why = (f": its {int(fin.sum())} positioned row(s) span {span_s:.3g} s and"
               f" {span_m:.3g} m, which is no flight along a leg (a stationary or too short log)")
    return [f"{src}: no row is on a leg of the plan, so nothing was checked{why}; no leg"
            " flagged means no check here, not a clean flight"]


def _offset_warning(assign_info: dict[str, Any], plan_check: dict[str, Any], plan_src: str,
                    passes: pd.DataFrame, t: np.ndarray) -> list[str]:
    """Say so when the legs were decoded about lines moved sideways (a plan offset).

    Sets ``plan_check["mismatch"]`` to ``"offset"`` (unless the plan was found reversed, which
    stays the mismatch) and ``plan_check["offset_m"]`` (horizontal size of the offset, m); the
    warning names the (airborne) passes flown at the offset (leg and time span).
    """
    dec = np.asarray(assign_info.get("decode_offset_ne_m", (0.0, 0.0)), dtype=np.float64)
    if not float(np.hypot(*dec)) > 0:
        return []
    if plan_check.get("mismatch") == "offset":
        return []   # already said by the plan diagnosis
    total = np.asarray(assign_info.get("offset_ne_m", dec), dtype=np.float64)
    size = float(np.hypot(*total))
    if not size > OFFSET_DECODE_MIN_M:
        return []
    plan_check["offset_m"] = size
    if plan_check.get("mismatch") is None:
        plan_check["mismatch"] = "offset"
    spans = [f"leg {int(r.leg)} {t[int(r.start)]:.1f}-{t[int(r.stop) - 1]:.1f} s"
             for r in passes.itertuples()]
    named = ", ".join(spans[:diagnose.PASSES_NAMED])
    if len(spans) > diagnose.PASSES_NAMED:
        named += f" and {len(spans) - diagnose.PASSES_NAMED} more"
    return [f"the flight runs a constant {size:.1f} m beside {plan_src} (north {total[0]:+.1f} m,"
            f" east {total[1]:+.1f} m) along its legs ({len(spans)} airborne pass(es) at it:"
            f" {named}): the legs are assigned about the moved lines and checked against the"
            " plan as given (they alarm); the plan may be offset or for another field (check"
            " the site and the plan's coordinates)"]


def _offset_spec(spec: str | float) -> str | float:
    """Check an ``altitude_offset`` value: auto, none or a number of metres."""
    text = str(spec).strip().lower()
    if text in ("auto", "none"):
        return text
    try:
        val = float(text)
    except ValueError:
        raise InputError(f"altitude_offset={spec!r}: use auto, none or metres (the log's"
                         " height above the plan)") from None
    if not np.isfinite(val):
        raise InputError(f"altitude_offset={spec!r}: must be a finite number of metres")
    return "none" if val == 0 else val
