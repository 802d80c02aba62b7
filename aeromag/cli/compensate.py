"""``aeromag compensate`` and ``aeromag calibrate`` (options: :mod:`aeromag.cli._options`)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import typer

from ..errors import InputError
from ._app import column_options, setup_logging, strict_warnings, user_errors
from ._options import Options, command, config_errors
from ._progress import progress_bar

if TYPE_CHECKING:
    from ..compensation.report_types import CompensationReport
from .online import dispatch as _online_dispatch  # registers --online and --forgetting


@command("compensate")
def compensate(opts: Options) -> None:
    """Compensate a log: fit on the log itself, or apply --model.

    Fits the Tolles-Lawson model on the survey itself (per segment, PCA screening of the
    segments, refit on the kept ones) or applies a saved --model, then writes OUT.csv (the log
    plus mag_tl, mag_comp, segment, segment_kept) and OUT.json (coefficients, per-segment PCA
    scores, screening, metrics).
    """
    if _online_dispatch(opts):  # --online: aeromag.workflows.online_compensate
        return
    setup_logging(opts.verbose)
    output, model, chunk_rows = opts.output, opts.model, opts.chunk_rows
    # Library imports here, not at module level: 'aeromag --help' stays instant.
    from ..compensation.model import TLModel
    from ..io import json_path_for
    from ..workflows.compensate import compensate_file

    with (user_errors(), strict_warnings(opts.strict), config_errors(),
          progress_bar("aeromag compensate")):  # a bar on a terminal only
        if json_path_for(output) == output:
            raise InputError(f"-o {output}: the report goes to OUT.json, so OUT must not end in"
                             " .json; give the output CSV another name, e.g. -o survey_comp.csv")
        opts.refuse_unused_options()  # --model / --no-screen with an option they ignore
        columns, unit_map = column_options(opts.col, opts.map_file, opts.units)
        cfg = opts.config()
        if chunk_rows is not None:
            if model is None:
                raise InputError("--chunk-rows applies a saved model: add --model MODEL.json")
            if opts.plot is not None:
                raise InputError("--plot needs the whole log in memory: drop --chunk-rows, or "
                                 "run 'aeromag report' on the output")
            if chunk_rows < 1:
                raise InputError(f"--chunk-rows {chunk_rows}: must be a positive row count")
            from ..workflows.chunked import apply_model_chunked

            report = apply_model_chunked(opts.survey, output, TLModel.load(model), cfg,
                                         chunk_rows=chunk_rows, columns=columns,
                                         units=unit_map, fmt=opts.fmt)
            _summary(report, output, json_path_for(output))
            return
        res = compensate_file(opts.survey, output, cfg, model=model, columns=columns,
                              units=unit_map, fmt=opts.fmt, self_check=True)
        page = _plot(res, opts.plot, cfg)
    _summary(res.report, output, json_path_for(output))
    if page is not None:
        typer.echo(f"wrote {page}")


@command("calibrate")
def calibrate(opts: Options) -> None:
    """Fit and screen the model on a calibration flight.

    Fits the Tolles-Lawson model per segment, screens the segments by PCA, refits on the kept
    ones and writes the model JSON (coefficients, per-segment PCA scores, screening, metrics
    and the FOM) for 'aeromag compensate --model'.
    """
    setup_logging(opts.verbose)
    from ..workflows.compensate import calibrate_file

    with (user_errors(), strict_warnings(opts.strict), config_errors(),
          progress_bar("aeromag calibrate")):  # a bar on a terminal only
        opts.refuse_unused_options()  # --no-screen with a screening threshold
        columns, unit_map = column_options(opts.col, opts.map_file, opts.units)
        cfg = opts.config()
        res = calibrate_file(opts.cal, opts.output, cfg, columns=columns, units=unit_map,
                             fmt=opts.fmt)
        page = _plot(res, opts.plot, cfg)
    _summary(res.report, opts.output, None)
    if page is not None:
        typer.echo(f"wrote {page}")


def _plot(res: object, plot: Path | None, cfg: object) -> Path | None:
    """Write the QC figures and report.html into ``plot`` when asked (matplotlib only then)."""
    if plot is None:
        return None
    from ..workflows.report import write_report

    return write_report(res, plot, config=cfg)


def _summary(report: CompensationReport, out: Path, out_json: Path | None) -> None:
    from ..compensation.report import dropped_summary
    from ..compensation.report_types import CompensationMetrics

    m = report.metrics or CompensationMetrics()
    segs = report.segments
    kept = sum(1 for s in segs if s.kept)
    line = (f"wrote {out}" + (f" and {out_json}" if out_json else "")
            + f": {kept}/{len(segs)} segments kept")
    if dropped_summary(report):
        line += f" ({dropped_summary(report)})"
    ir = m.improvement_ratio
    rs = m.residual_std_nT
    if ir is not None and rs is not None:
        line += f"; improvement ratio {ir:.2f}, residual std {rs:.4f} nT"
        air = m.all_improvement_ratio
        if dropped_summary(report) and air is not None:
            line += (f" on kept segments ({air:.2f} and {m.all_residual_std_nT:.4f} nT over"
                     " all)")
        if report.self_calibration:
            line += "; in-sample (fitted on this log)"
    no_mag = m.n_rows_without_mag
    if no_mag:
        line += f"; {no_mag} row{'s' if no_mag != 1 else ''} without mag: mag_comp left empty"
    typer.echo(line)
