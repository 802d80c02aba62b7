"""``aeromag simulate``: synthetic calibration flight, survey, plan and ground truth."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Annotated

import typer

from ._app import app, setup_logging, user_errors

log = logging.getLogger(__name__)


def _mission_files(out_dir: Path, seed: int, small: bool) -> dict[str, Path]:
    """Write the multirotor mission-simulator files (DGPS track check)."""
    from ..workflows.mission import write_mission_files

    written = write_mission_files(out_dir, seed=seed, small=small)
    # Its keys ("plan", "truth") would clash with ours: keep them apart.
    return {k if k.startswith("mission") else f"mission_{k}": Path(v) for k, v in written.items()}


_HELP = (
    "Write synthetic flights, plans and their ground truth.\n\n"
    "Files written to the output folder: calibration.csv (boxes on the four cardinal headings "
    "with pitch/roll/yaw maneuvers, one line per maneuver, turns cut out), survey.csv "
    "(parallel lines over buried dipoles, gusty attitude), plan.csv (survey waypoints: start "
    "and end of each line) and truth.json (TL coefficients, Earth field, noise levels, faults)."
    "\n\n"
    "Every log carries ground-truth columns: truth_mag_tl (aircraft interference, nT), "
    "truth_mag_clean, truth_anomaly, truth_diurnal, truth_fault (kind), truth_fault_nT."
    "\n\n"
    "For 'aeromag track', a multirotor mission on RTK DGPS with magnetic heading disturbances "
    "on some legs: mission.csv (the flight log: time, lat, lon, alt, heading, pitch, roll, "
    "flux_x/y/z), mission_plan.csv (its waypoints) and mission_truth.json (per leg: "
    "disturbance kind, onset time and rate); mission.csv carries truth_xtrack_m, truth_leg, "
    "truth_heading, truth_dpsi_deg, truth_disturbance_nT and truth_mag_heading."
)


@app.command(help=_HELP)
def simulate(
    output: Annotated[Path, typer.Option("-o", "--output", metavar="DIR", help="Output folder "
                                         "(created when missing).", show_default=False)],
    seed: Annotated[int, typer.Option("--seed", help="Random seed; the same seed gives the "
                                      "same files.")] = 0,
    faults: Annotated[float, typer.Option(
        "--faults", min=0.0, max=1.0, metavar="FRACTION",
        help="Fraction of the segments (lines) of each flight carrying a fault, 0-1; kinds cycle "
        "over noise_burst, onboard_source, flux_bias, scalar_drift (listed in truth.json).",
    )] = 0.0,
    rate: Annotated[float, typer.Option("--rate", metavar="HZ",
                                        help="Sample rate, Hz.")] = 10.0,
    small: Annotated[bool, typer.Option("--small", help="Small files (one calibration box of 12 "
                                        "segments, ten short survey lines, a short mission): "
                                        "the shipped samples.")]
    = False,
    quadrotor: Annotated[bool, typer.Option(
        "--quadrotor", help="Also write the navigation study's quadrotor flights for 'aeromag "
        "navigate': quadrotor_hover.csv (60 s at 2 m), quadrotor_rectangle.csv (60 s at 1.5 "
        "m/s), their *_truth.csv and quadrotor_truth.json (site, date, field, biases).")]
    = False,
    online: Annotated[bool, typer.Option(
        "--online", help="Also write the logs of the online estimators: compass.csv (the "
        "compass-calibration study's manoeuvre at Taiyuan, interference switched at 15 s) and "
        "online_tl.csv (a survey whose TL coefficients jump), with *_truth.json.")] = False,
    currents: Annotated[int, typer.Option(
        "--currents", min=0, metavar="N", help="N aircraft current loops: their field in mag, "
        "the currents logged as cur_1..cur_N and volt_bus, the loops in truth.json (for "
        "--extra).")] = 0,
    survey: Annotated[bool, typer.Option(
        "--survey", help="Also write a levelling survey for 'aeromag level': level_survey.csv "
        "(east-west lines and north-south ties, lagged magnetometer, diurnal, IGRF, line "
        "errors; truth_anomaly, truth_diurnal, truth_igrf, truth_line_error), level_base.csv "
        "(its base station, time,mag) and level_truth.json.")] = False,
    verbose: Annotated[bool, typer.Option("-v", "--verbose", help="Log progress details.")]
    = False,
) -> None:
    """Write synthetic flights, plans and their ground truth (help: ``_HELP``)."""
    setup_logging(verbose)
    from ..workflows.simulate import write_simulation

    with user_errors():
        paths = write_simulation(output, seed=seed, faults=faults, rate_hz=rate, small=small,
                                 currents=currents)
        paths.update(_mission_files(output, seed, small))
        if quadrotor:
            from ..workflows.quadrotor import write_quadrotor_files

            paths.update(write_quadrotor_files(output, seed=seed))
        if online:
            from ..workflows.simulate_online import write_online_simulation

            paths.update(write_online_simulation(output, seed=seed, small=small))
        if survey:
            from ..workflows.simulate_level import write_level_simulation

            paths.update(write_level_simulation(output, seed=seed, small=small))
    for path in paths.values():
        typer.echo(str(path))
