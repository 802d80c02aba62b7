"""``aeromag report``: QC figures, qc.json and a self-contained HTML page."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ._app import app, setup_logging, user_errors
from ._progress import progress_bar


@app.command()
def report(
    out_csv: Annotated[Path, typer.Argument(metavar="OUT.csv", help="Compensated log written "
                                            "by 'aeromag compensate' (OUT.csv; OUT.json is "
                                            "read too).",
                                            show_default=False)],
    output: Annotated[Path, typer.Option("-o", metavar="DIR", help="Output folder for the PNG "
                                         "figures, qc.json and report.html.")],
    report_json: Annotated[Path | None, typer.Option("--report", metavar="JSON",
                           help="Report to use instead of OUT.json beside OUT.csv.")] = None,
    maneuver_column: Annotated[str | None, typer.Option(
        "--maneuver-column", metavar="COL",
        help="Column naming each sample's manoeuvre (pitch/roll/yaw) instead of detection.")]
    = None,
    verbose: Annotated[bool, typer.Option("-v", "--verbose", help="Log progress details.")]
    = False,
) -> None:
    """QC figures and an HTML page for a compensated log.

    Quality control of a compensation: FOM (before/after), improvement ratio, residuals per
    segment and heading, noise, VIF, cross-validation; PNG figures, qc.json and report.html
    in -o DIR.
    """
    setup_logging(verbose)
    with user_errors(), progress_bar("aeromag report") as progress:
        from ..workflows.report import report_file

        page = report_file(out_csv, output, report_json, maneuver_column=maneuver_column,
                            progress=progress)
    typer.echo(str(page))
