"""``aeromag compass``: online hard/soft-iron calibration of the vector magnetometer."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ._app import app, column_options, setup_logging, user_errors


@app.command()
def compass(
    log_file: Annotated[Path, typer.Argument(metavar="LOG", help="Log with time, flux_x/y/z, "
                                             "heading, pitch, roll (and lat, lon, alt for "
                                             "IGRF).", show_default=False)],
    output: Annotated[Path, typer.Option("-o", metavar="OUT.csv", help="Output CSV (the "
                                         "report goes to OUT.json).", show_default=False)],
    forgetting: Annotated[float, typer.Option("--forgetting", metavar="L",
                          help="Forgetting factor lambda, 0 < L <= 1 (1: plain recursive "
                          "least squares; 0.96-0.975 follow a change of interference within "
                          "seconds at 50 Hz).")] = 0.975,
    date: Annotated[str | None, typer.Option("--date", metavar="YYYY-MM-DD",
                    help="Date of the flight, for the IGRF-14 reference field at the log's "
                    "lat, lon, alt.", show_default=False)] = None,
    earth_field: Annotated[tuple[float, float, float] | None, typer.Option(
        "--earth-field", metavar="F I D", help="Explicit reference field instead of IGRF: "
        "intensity nT, inclination and declination degrees.", show_default=False)] = None,
    window: Annotated[float, typer.Option("--window", metavar="S", help="Window of the "
                      "excitation indicator, s.")] = 5.0,
    col: Annotated[list[str] | None, typer.Option("--col", metavar="NAME=SOURCE",
                   help="Column map, repeatable (e.g. flux_x=mag_x).")] = None,
    map_file: Annotated[Path | None, typer.Option("--map", metavar="FILE",
                        help="TOML column map: [columns] NAME = \"SOURCE\", optional "
                        "[units] NAME = \"UNIT\".")] = None,
    units: Annotated[list[str] | None, typer.Option("--units", metavar="NAME=UNIT",
                     help="Convert a field column or group (flux) to nT.")] = None,
    verbose: Annotated[bool, typer.Option("-v", "--verbose", help="Log progress details.")]
    = False,
) -> None:
    """Calibrate the compass online (soft and hard iron).

    Estimates flux_cal = D @ flux + e sample by sample (recursive least squares with a
    forgetting factor) against the Earth field rotated into body axes by heading, pitch and
    roll. Writes OUT.csv (the log plus flux_cal_x/y/z, mag_heading_cal, heading_err_deg)
    and OUT.json (matrix, offset_nT, forgetting, reference, metrics, excitation per window).
    """
    setup_logging(verbose)
    from ..io import json_path_for
    from ..workflows.compass import compass_file

    with user_errors():
        columns, unit_map = column_options(col, map_file, units)
        rep = compass_file(log_file, output, forgetting=forgetting, date=date,
                           earth_field=earth_field, columns=columns, units=unit_map,
                           window_s=window)
    m = rep.metrics
    line = f"wrote {output} and {json_path_for(output)}"
    if m.rms_deg is not None:
        line += f": heading error RMS {m.rms_deg:.2f} deg, mean {m.mean_deg:.2f} deg"
    exc = rep.excitation
    if exc.n_insufficient:
        line += f"; {exc.n_insufficient}/{exc.n_windows} windows under-excited"
    typer.echo(line)
