"""``aeromag track``: DGPS track-deviation flags per leg, heading detector, combined verdict."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ._app import app, column_options, setup_logging, user_errors
from ._progress import progress_bar

# Same as aeromag.detection.heading.DEFAULT_SIGMA_FLOOR_DEG (a test checks it); literal here
# so that 'aeromag --help' does not import the numerics.
DEFAULT_SIGMA_FLOOR_DEG = 0.5


@app.command()
def track(
    survey: Annotated[Path, typer.Argument(metavar="SURVEY.csv", help="Survey log (CSV) with "
                                           "time, lat, lon, alt.", show_default=False)],
    plan: Annotated[Path, typer.Option("--plan", metavar="PLAN.csv",
                                       help="Mission plan: a CSV of waypoints lat, lon, alt in "
                                       "order, a QGroundControl .plan or a Mission Planner "
                                       ".waypoints file.")],
    output: Annotated[Path, typer.Option("-o", metavar="OUT.csv", help="Output CSV (the "
                                         "per-leg report goes to OUT.json).")],
    threshold: Annotated[float, typer.Option("--threshold", metavar="M",
                         help="Track alarm threshold, metres.")] = 1.0,
    min_duration: Annotated[float, typer.Option("--min-duration", metavar="S",
                            help="Exceedance must last this long before the track alarm, s.")]
    = 0.0,
    calm_window: Annotated[str, typer.Option("--calm-window", metavar="S|T0:T1",
                           help="Calm reference window of the heading detector: seconds from "
                           "the start, or a time range T0:T1.")] = "30",
    heading_sigmas: Annotated[float, typer.Option("--heading-sigmas", metavar="K",
                              help="Heading alarm above K sigma of the calm window.")] = 5.0,
    heading_sigma_floor: Annotated[float, typer.Option(
        "--heading-sigma-floor", metavar="DEG",
        help="Smallest heading sigma used, degrees (compass noise; a calm window can be "
        "quieter than the flight).")] = DEFAULT_SIGMA_FLOOR_DEG,
    declination: Annotated[float, typer.Option("--declination", metavar="DEG",
                           help="Declination for a fluxgate-derived heading, degrees east.")]
    = 0.0,
    combine: Annotated[str, typer.Option("--combine", metavar="or|and",
                       help="Combined verdict: either detector (or) or confirmed by both (and).")]
    = "or",
    horizontal: Annotated[bool, typer.Option(
        "--horizontal", help="Horizontal distance only (xtrack_m = |xtrack_h_m|); altitude "
        "left out of the leg assignment (logs whose altitude cannot be trusted).")] = False,
    altitude_offset: Annotated[str, typer.Option(
        "--altitude-offset", metavar="auto|none|M",
        help="Constant height of the log above the plan to remove: detected (auto: a different "
        "altitude reference, reported), never (none) or given in metres.")] = "auto",
    navigate: Annotated[bool, typer.Option(
        "--navigate", help="Run aeromag navigate's filter on the log (needs the IMU columns): "
        "check the navigated position where the log has no GNSS fix, and give the heading "
        "detector its attitude (without the magnetometer) when the log has no heading.")]
    = False,
    pf: Annotated[bool, typer.Option(
        "--pf", help="Also run the particle-filter detector of aeromag detect (needs a gyro "
        "and a compass) and include pf_alarm in alarm.")] = False,
    plot: Annotated[Path | None, typer.Option("--plot", metavar="DIR",
                    help="Write track and time-series plots (PNG) to DIR.")] = None,
    col: Annotated[list[str] | None, typer.Option("--col", metavar="NAME=SOURCE",
                   help="Column map, repeatable (e.g. lat=gps_lat).")] = None,
    map_file: Annotated[Path | None, typer.Option("--map", metavar="FILE",
                        help="TOML column map: [columns] NAME = \"SOURCE\", optional "
                        "[units] NAME = \"UNIT\".")] = None,
    units: Annotated[list[str] | None, typer.Option("--units", metavar="NAME=UNIT",
                     help="Convert a field column or group (flux, mag) to nT.")] = None,
    verbose: Annotated[bool, typer.Option("-v", "--verbose", help="Log progress details.")]
    = False,
) -> None:
    """Flag DGPS track deviations per mission leg.

    A sample alarms when its 3-D distance to the planned line of its leg (xtrack_m) is above
    --threshold; the heading detector runs too when the columns allow, and the two are
    combined (--combine).  Writes OUT.csv (the log plus leg, xtrack_m, track_alarm, ...,
    alarm) and OUT.json ({"legs": [...]}, one object per leg).
    """
    setup_logging(verbose)

    from ..io import json_path_for
    from ..workflows.track import track_file

    with user_errors(), progress_bar("aeromag track"):  # a bar on a terminal only
        columns, unit_map = column_options(col, map_file, units)
        res = track_file(
            survey, plan, output, threshold_m=threshold, min_duration_s=min_duration,
            calm_window=calm_window, heading_sigmas=heading_sigmas,
            heading_sigma_floor_deg=heading_sigma_floor, declination_deg=declination,
            combine=combine, horizontal=horizontal, altitude_offset=altitude_offset,
            columns=columns, units=unit_map, plot_dir=plot, navigated=navigate,
            extra_detectors=_pf_detectors(pf, calm_window, declination, survey),
        )
    rep = res.report
    flagged = rep.flagged_legs
    n_legs, checked = rep.n_legs, rep.n_legs_checked
    which = f" ({', '.join(map(str, flagged))})" if flagged else ""
    if checked < n_legs:  # "0/19 flagged" must not read as 19 clean
        line = (f"wrote {output} and {json_path_for(output)}: {len(flagged)} of {checked}"
                f" checked leg{'s' if checked != 1 else ''} flagged{which}"
                f" ({n_legs - checked} of {n_legs} not flown: no flown rows on them, see"
                f" {json_path_for(output).name}, legs[].checked)")
    else:
        line = (f"wrote {output} and {json_path_for(output)}: {len(flagged)}/{n_legs}"
                f" legs flagged{which}")
    if not rep.heading_detector.get("available"):
        line += "; heading detector skipped (no heading columns)"
    mismatch = rep.plan_check.get("mismatch")
    if mismatch in _MISMATCH_SUMMARY:
        line += f"; {_MISMATCH_SUMMARY[mismatch]}"
    if rep.warnings:
        line += f"; {len(rep.warnings)} warning(s) in {json_path_for(output).name}"
    typer.echo(line)


#: What the summary line says when the plan does not match the flight (see track.diagnose).
_MISMATCH_SUMMARY = {
    "reversed": "THE PLAN LOOKS REVERSED (the flight follows its legs backwards)",
    "offset": "THE PLAN MAY BE OFFSET OR FOR ANOTHER FIELD (the flight runs beside its legs)",
    "far": "the plan is not this flight's (no sample near its legs)",
    "altitude": "the plan's altitude reference differs from the log's",
}


def _pf_detectors(pf: bool, calm_window: str, declination: float, survey: Path) -> tuple:
    """``--pf``: the particle-filter detector of ``aeromag detect`` as an extra detector."""
    if not pf:
        return ()
    from ..workflows.detect import pf_track_detector

    return (pf_track_detector(calm_window=calm_window, declination_deg=declination,
                              source=str(survey)),)
