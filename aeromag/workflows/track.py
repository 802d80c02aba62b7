"""``aeromag track``, file in, files out: read a log and a plan, check the track, write OUT.csv
and OUT.json."""

from __future__ import annotations

import os
from pathlib import Path

from ..detection.heading import CalmWindow
from ..io import atomic_path, json_path_for, read_log, write_csv, write_json
from ..io.plans import read_plan
from ..plot.track import plot_track
from ..track.check import TrackResult, check_track
from ..track.legs import DEFAULT_WAYPOINT_RADIUS_M
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
    declination_deg: float = 0.0,
    combine: str = "or",
    waypoint_radius_m: float = DEFAULT_WAYPOINT_RADIUS_M,
    columns: dict[str, str] | None = None,
    units: dict[str, str] | None = None,
    plot_dir: str | os.PathLike[str] | None = None,
    fmt: str | None = None,
) -> TrackResult:
    """Read a log and a plan, check the track, write OUT.csv and OUT.json atomically.

    Outputs that would overwrite the log or the plan are refused before anything is read.

    Parameters
    ----------
    log_path : path-like
        Survey log (needs ``time``, ``lat``, ``lon``, ``alt``).
    plan_path : path-like
        Mission plan CSV (``lat``, ``lon``, ``alt`` per waypoint).
    out_path : path-like
        Output CSV; the report goes to the same path with suffix ``.json``.
    threshold_m, min_duration_s, calm_window, heading_sigmas, declination_deg, combine,
    waypoint_radius_m
        See :func:`check_track` (m, s, s, -, degrees, -, m).
    columns : dict, optional
        Column map ``{canonical: source}``.
    units : dict, optional
        Unit conversions for field columns.
    plot_dir : path-like, optional
        Folder for the track plots (PNG); none when omitted.
    fmt : str, optional
        Log format (default from the extension).

    Returns
    -------
    TrackResult
    """
    out = Path(out_path)
    out_json = json_path_for(out)
    check_outputs(log_path, out, out_json)  # not OUT.json, never over the log or the plan
    check_outputs(plan_path, out, out_json, kind="plan")
    plan = read_plan(plan_path)
    plan.attrs["source"] = str(plan_path)
    df = read_log(log_path, columns=columns, units=units,
                  required=("time", "lat", "lon", "alt"), fmt=fmt)
    res = check_track(df, plan, threshold_m=threshold_m, min_duration_s=min_duration_s,
                      calm_window=calm_window, heading_sigmas=heading_sigmas,
                      declination_deg=declination_deg, combine=combine,
                      waypoint_radius_m=waypoint_radius_m, source=str(log_path))
    res.report["input"] = str(log_path)
    res.report["plan"] = str(plan_path)
    if plot_dir is not None:
        res.report["plots"] = [str(p) for p in plot_track(res, plan, plot_dir,
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
        write_json(res.report, tmp_json)
