"""``aeromag batch``: compensation (and track check) over many logs, locally or on Dask."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .app import EXIT_USER_ERROR, app, column_options, setup_logging, user_errors
from .compensate import (
    Band,
    Col,
    Fmt,
    MapFile,
    MaxCond,
    MaxInterf,
    NoScreen,
    Ridge,
    SegSec,
    Terms,
    Units,
    Verbose,
)

# Same as aeromag.workflows.batch.LOG_EXTENSIONS (a test checks it); literal here so that
# 'aeromag --help' does not import pandas.
LOG_EXTENSIONS = (".csv", ".txt", ".parquet", ".pq", ".xyz", ".h5", ".hdf5")


@app.command()
def batch(
    inputs: Annotated[list[str], typer.Argument(
        metavar="INPUTS", help="Logs: files, globs or folders (a folder's "
        f"{', '.join('*' + e for e in LOG_EXTENSIONS)} files).", show_default=False)],
    output: Annotated[Path, typer.Option("-o", metavar="OUTDIR", help="Output folder "
                                         "(NAME_comp.csv/.json per log, "
                                         "batch_summary.csv/.json).")],
    model: Annotated[Path | None, typer.Option("--model", metavar="MODEL.json",
                     help="Apply this saved model to every log (default: self-calibrate each "
                     "log like 'compensate').")] = None,
    plan: Annotated[Path | None, typer.Option("--plan", metavar="PLAN.csv", help="Mission "
                    "plan: also run the track check per log (NAME_track.csv/.json).")] = None,
    workers: Annotated[int | None, typer.Option("--workers", metavar="N", help="Local worker "
                       "processes (default: all cores).")] = None,
    scheduler: Annotated[str | None, typer.Option("--scheduler", metavar="ADDRESS",
                         help="Run on a Dask cluster, e.g. tcp://host:8786 "
                         "(pip install 'aeromag[dask]').")] = None,
    force: Annotated[bool, typer.Option("--force", help="Re-process every log (by default a "
                                        "log is skipped when its outputs are newer than it and "
                                        "were made with the same options, model, plan and "
                                        "aeromag version).")] = False,
    chunk_rows: Annotated[int | None, typer.Option("--chunk-rows", metavar="N",
                          help="With --model: apply it in chunks of N rows (bounded memory "
                          "for very large logs).")] = None,
    threshold: Annotated[float, typer.Option("--threshold", metavar="M", help="Track alarm "
                                             "threshold, metres (with --plan).")] = 1.0,
    band: Band = (0.1, 0.9),
    terms: Terms = "16",
    segment_seconds: SegSec = 60.0,
    no_screen: NoScreen = False,
    no_filter: Annotated[bool, typer.Option("--no-filter", help="Leave mag_comp unfiltered.")]
    = False,
    ridge: Ridge = 0.0,
    max_condition: MaxCond = 1e5,
    max_interference: MaxInterf = 0.25,
    col: Col = None,
    map_file: MapFile = None,
    units: Units = None,
    fmt: Fmt = None,
    no_progress: Annotated[bool, typer.Option("--no-progress", help="No progress bar.")] = False,
    verbose: Verbose = False,
) -> None:
    """Compensate (and track-check) many logs in parallel.

    Each log is compensated exactly as 'aeromag compensate' does it (and with --plan checked
    as 'aeromag track' does); a bad log is reported in the summary without stopping the
    others, and the exit status is 1 when any failed.  Logs whose outputs are up to date are
    skipped (see --force).
    """
    setup_logging(verbose, quiet=not verbose)
    from ..compensation.config import CompensationConfig
    from ..workflows.batch import run_batch

    with user_errors():
        columns, unit_map = column_options(col, map_file, units)
        cfg = CompensationConfig(band_hz=band, terms=terms, segment_seconds=segment_seconds,
                                 screen=not no_screen, filter_output=not no_filter, ridge=ridge,
                                 max_condition=max_condition,
                                 max_interference=max_interference)
        summary = run_batch(inputs, output, model=model, plan=plan, cfg=cfg, workers=workers,
                            scheduler=scheduler, force=force, columns=columns, units=unit_map,
                            fmt=fmt, progress=not no_progress, chunk_rows=chunk_rows,
                            track_options={"threshold_m": threshold})
    _print_summary(summary)
    if summary.failed:
        raise typer.Exit(EXIT_USER_ERROR)


def _print_summary(summary) -> None:  # noqa: ANN001 - BatchSummary
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"aeromag batch -> {summary.out_dir}")
    for name in ("input", "status", "s", "rows", "improvement", "residual nT", "flagged legs"):
        table.add_column(name)

    def fmt(x: float | None, spec: str) -> str:
        return "" if x is None else format(x, spec)

    for r in summary.results:
        style = {"ok": "green", "skipped": "dim", "failed": "red"}[r.status]
        table.add_row(Path(r.input).name, f"[{style}]{r.status}[/{style}]",
                      fmt(r.seconds, ".1f"), "" if r.n_rows is None else str(r.n_rows),
                      fmt(r.improvement_ratio, ".2f"), fmt(r.residual_std_nT, ".4f"),
                      "" if r.flagged_legs is None else str(r.flagged_legs))
    console = Console()
    console.print(table)
    n_ok = sum(r.status == "ok" for r in summary.results)
    n_skip = sum(r.status == "skipped" for r in summary.results)
    console.print(f"{n_ok} ok, {n_skip} up to date, {len(summary.failed)} failed in "
                  f"{summary.seconds:.1f} s; summary: {summary.summary_csv}", highlight=False)
    err = Console(stderr=True, highlight=False)
    for r in summary.failed:
        err.print(f"error: {r.error}", markup=False, soft_wrap=True)
