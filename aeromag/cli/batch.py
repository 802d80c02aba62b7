"""``aeromag batch``: compensation (and track check) over many logs, locally or on Dask."""

from __future__ import annotations

from pathlib import Path

import typer

from ._app import EXIT_USER_ERROR, column_options, setup_logging, strict_warnings, user_errors
from ._options import LOG_EXTENSIONS, Options, command, flag_batch_summary

__all__ = ["LOG_EXTENSIONS", "batch"]


@command("batch")
def batch(opts: Options) -> None:
    """Compensate (and track-check) many logs in parallel.

    Each log is compensated exactly as 'aeromag compensate' does it (and with --plan checked
    as 'aeromag track' does); a bad log is reported in the summary without stopping the
    others, and the exit status is 1 when any failed.  Logs whose outputs are up to date are
    skipped (see --force).  A log fitted on itself is checked for a calibration box as
    'aeromag compensate' does; with --strict a log's warning is its error.
    """
    setup_logging(opts.verbose, quiet=not opts.verbose)
    from ..workflows.batch import run_batch

    with user_errors():
        opts.refuse_unused_options()  # --model / --no-screen with an option they ignore
        with strict_warnings(opts.strict):  # a warning about the options fails them all
            columns, unit_map = column_options(opts.col, opts.map_file, opts.units)
            cfg = opts.config()
        # Per log: run_batch's strict makes each log's warning that log's error.
        summary = run_batch(opts.inputs, opts.output, model=opts.model, plan=opts.plan,
                            cfg=cfg, workers=opts.workers, scheduler=opts.scheduler,
                            force=opts.force, columns=columns, units=unit_map, fmt=opts.fmt,
                            progress=not opts.no_progress, chunk_rows=opts.chunk_rows,
                            track_options={"threshold_m": opts.threshold},
                            strict=opts.strict)
    with user_errors():  # reasons and warnings in the flags' words, as 'compensate' says them
        flag_batch_summary(summary)
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
        style = {"ok": "green", "warn": "yellow", "skipped": "dim", "failed": "red"}[r.status]
        table.add_row(Path(r.input).name, f"[{style}]{r.status}[/{style}]",
                      fmt(r.seconds, ".1f"), "" if r.n_rows is None else str(r.n_rows),
                      fmt(r.improvement_ratio, ".2f"), fmt(r.residual_std_nT, ".4f"),
                      "" if r.flagged_legs is None else str(r.flagged_legs))
    console = Console()
    console.print(table)
    n_ok = sum(r.status == "ok" for r in summary.results)
    n_skip = sum(r.status == "skipped" for r in summary.results)
    # One line whatever the terminal's width (a path is never broken after "summary: ").
    console.print(f"{n_ok} ok, {len(summary.warned)} with warnings, {n_skip} up to date,"
                  f" {len(summary.failed)} failed in {summary.seconds:.1f} s; summary:"
                  f" {summary.summary_csv}", highlight=False, markup=False, soft_wrap=True)
    err = Console(stderr=True, highlight=False)
    for r in summary.warned:
        for w in r.warnings:
            err.print(f"warning: {_naming(r.input, w)}", markup=False, soft_wrap=True)
    for r in summary.failed:
        err.print(f"error: {r.error}", markup=False, soft_wrap=True)


def _naming(inp: str, message: str) -> str:
    """``message`` led by the input's name, unless it names the input already."""
    name = Path(inp).name
    if f"{inp}:" in message or f"{name}:" in message:
        return message
    return f"{name}: {message}"
