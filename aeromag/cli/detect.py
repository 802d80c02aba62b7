"""``aeromag detect``: particle-filter fault detection on the magnetometer against the gyro."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ._app import app, column_options, setup_logging, user_errors
from ._progress import progress_bar

# Literal copies of aeromag.detection.particle's defaults (a test checks them), so that
# 'aeromag --help' does not import the filter stack.
DEFAULT_PARTICLES = 500
DEFAULT_WINDOW = 20


@app.command()
def detect(
    log_file: Annotated[Path, typer.Argument(metavar="LOG", help="Log with time, a gyro "
                                             "(gyro_z, or gyro_x/y/z with pitch and roll) and "
                                             "a compass (mag_heading, or flux_x/y/z with "
                                             "pitch and roll).", show_default=False)],
    output: Annotated[Path, typer.Option("-o", metavar="OUT.csv", help="Output CSV (the "
                                         "report goes to OUT.json).", show_default=False)],
    particles: Annotated[int, typer.Option("--particles", metavar="N",
                         help="Number of particles.")] = DEFAULT_PARTICLES,
    window: Annotated[int, typer.Option("--window", metavar="M",
                      help="Compass samples in the log-likelihood window.")] = DEFAULT_WINDOW,
    threshold: Annotated[float | None, typer.Option("--threshold", metavar="X",
                         help="Alarm threshold on pf_stat (default: from the calm window).",
                         show_default=False)] = None,
    calm_window: Annotated[str, typer.Option("--calm-window", metavar="S|T0:T1",
                           help="Calm reference window: seconds from the start, or a time "
                           "range T0:T1.")] = "30",
    declination: Annotated[float, typer.Option("--declination", metavar="DEG",
                           help="Declination for a fluxgate-derived heading, degrees east.")]
    = 0.0,
    seed: Annotated[int, typer.Option("--seed", metavar="N", help="Random seed.")] = 0,
    col: Annotated[list[str] | None, typer.Option("--col", metavar="NAME=SOURCE",
                   help="Column map, repeatable (e.g. gyro_z=IMU_GyrZ).")] = None,
    map_file: Annotated[Path | None, typer.Option("--map", metavar="FILE",
                        help="TOML column map: [columns] NAME = \"SOURCE\", optional "
                        "[units] NAME = \"UNIT\".")] = None,
    units: Annotated[list[str] | None, typer.Option("--units", metavar="NAME=UNIT",
                     help="Convert a field column or group (flux) to nT; gyro=deg/s "
                     "for a gyro logged in deg/s.")] = None,
    verbose: Annotated[bool, typer.Option("-v", "--verbose", help="Log progress details.")]
    = False,
) -> None:
    """Detect magnetic interference with a particle filter.

    The heading is propagated by the gyro and the compass heading is the measurement; pf_stat
    is S_k, the sum over the last --window compass samples of -ln of the mean particle
    likelihood, and pf_alarm is S_k above the threshold (from the calm window unless
    --threshold is given). Writes OUT.csv (the log plus pf_stat, pf_alarm) and OUT.json
    (threshold, window, particles, events).
    """
    setup_logging(verbose)
    from ..io import json_path_for
    from ..workflows.detect import detect_file

    with user_errors(), progress_bar("aeromag detect"):  # a bar on a terminal only
        columns, unit_map = column_options(col, map_file, units)
        rep = detect_file(log_file, output, n_particles=particles, window=window,
                          threshold=threshold, calm_window=calm_window,
                          declination_deg=declination, seed=seed, columns=columns,
                          units=unit_map)
    typer.echo(f"wrote {output} and {json_path_for(output)}: {len(rep.events)} alarm"
               f" event(s), threshold {rep.threshold:.2f} ({rep.threshold_source})")
