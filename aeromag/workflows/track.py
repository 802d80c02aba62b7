"""``aeromag track``, file in, files out.

Read a log and a plan, check the track, write OUT.csv and OUT.json.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path

import pandas as pd

from ..detection.alarms import Alarms
from ..detection.heading import DEFAULT_SIGMA_FLOOR_DEG, CalmWindow
from ..io import atomic_path, json_path_for, read_log, write_csv, write_json
from ..io.plans import read_plan
from ..track.check import TrackResult, check_track
from .compensate import check_outputs

__all__ = ["track_file", "write_outputs"]


def track_file(
    log_path: str | os.PathLike[str],
    plan_path: str | os.PathLike[str],
    out_path: str | os.PathLike[str],
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
    extra_detectors: Sequence[Callable[[pd.DataFrame], Alarms]] = (),
    columns: dict[str, str] | None = None,
    units: dict[str, str] | None = None,
    plot_dir: str | os.PathLike[str] | None = None,
    fmt: str | None = None,
    navigated: bool = False,
) -> TrackResult:
    """Read a log and a plan, check the track, write OUT.csv and OUT.json as a set.

    Outputs that would overwrite the log or the plan are refused before anything is read.

    Parameters
    ----------
    log_path : path-like
        Survey log (needs ``time``, ``lat``, ``lon``, ``alt``).
    plan_path : path-like
        Mission plan: CSV (``lat``, ``lon``, ``alt`` per waypoint), QGroundControl ``.plan`` or
        Mission Planner ``.waypoints`` (see :func:`aeromag.io.plans.read_plan`).
    out_path : path-like
        Output CSV; the report goes to the same path with suffix ``.json``.
    threshold_m, min_duration_s, calm_window, heading_sigmas, heading_sigma_floor_deg,
    declination_deg, combine, horizontal, altitude_offset
        See :func:`aeromag.track.check_track` (m, s, s, -, degrees, degrees, -, -, m).
    extra_detectors : sequence of callables
        Each takes the log (canonical columns) and returns an
        :class:`~aeromag.detection.Alarms` on its rows (e.g. the particle filter): passed to
        :func:`~aeromag.track.check_track` as ``detectors``.
    columns : dict, optional
        Column map ``{canonical: source}``.
    units : dict, optional
        Unit conversions for field columns.
    plot_dir : path-like, optional
        Folder for the track plots (PNG); none when omitted.  Their paths are in OUT.json.
    fmt : str, optional
        Log format (default from the extension).
    navigated : bool
        Run the navigation filter (:func:`aeromag.nav.pipeline.track_inputs`) and check the
        navigated position where the log has no GNSS fix, and the heading detector on its
        attitude (without the magnetometer) when the log has no INS heading; its pitch and
        roll are added to OUT.csv when the log has none (``--navigate``; the log needs the
        IMU columns).

    Returns
    -------
    TrackResult
    """
    out = Path(out_path)
    out_json = json_path_for(out)
    check_outputs(log_path, out, out_json)  # not OUT.json, never over the log or the plan
    check_outputs(plan_path, out, out_json, kind="plan")
    plan = read_plan(plan_path)
    # alt is checked by check_track, which knows what a log without it holds (alt_msl)
    df = read_log(log_path, columns=columns, units=units, required=("time", "lat", "lon"),
                  fmt=fmt)
    detectors = [make(df) for make in extra_detectors]
    nav = None
    if navigated:
        from ..nav.pipeline import track_inputs

        nav = track_inputs(df, source=str(log_path))
        df = df.assign(**nav.columns)   # pitch, roll from the filter when the log has none
    res = check_track(df, plan, threshold_m=threshold_m, min_duration_s=min_duration_s,
                      calm_window=calm_window, heading_sigmas=heading_sigmas,
                      heading_sigma_floor_deg=heading_sigma_floor_deg,
                      declination_deg=declination_deg, combine=combine,
                      horizontal=horizontal, altitude_offset=altitude_offset,
                      position=None if nav is None else nav.position,
                      heading_deg=None if nav is None else nav.heading_deg,
                      detectors=detectors, source=str(log_path))
    if nav is not None:
        res.report.navigation = nav.info
    res.report.input = str(log_path)
    res.report.plan = str(plan_path)
    res.report.plan_format = plan.attrs.get("format", "csv")
    if plot_dir is not None:
        from ..plot.track import plot_track  # matplotlib only when figures are asked for

        res.report.plots = [str(p) for p in plot_track(res, plan, plot_dir,
                                                          threshold_m=threshold_m)]
    write_outputs(res, out, out_json)
    return res


def write_outputs(res: TrackResult, out: Path, out_json: Path) -> None:
    """Write OUT.csv and OUT.json as a set: both to temporary names, then both renamed.

    A failure while writing either leaves neither behind (and the old files, if any, intact).

    Parameters
    ----------
    res : TrackResult
        The checked log and its report.
    out, out_json : Path
        The CSV and the report.
    """
    with atomic_path(out) as tmp_csv, atomic_path(out_json) as tmp_json:
        write_csv(res.data, tmp_csv)
        doc = res.report.to_dict()
        write_json(doc, tmp_json)
    res.report.warnings = doc["warnings"]   # with those the command logged, as in the file
