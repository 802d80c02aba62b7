"""``aeromag compensate`` and ``aeromag calibrate``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ..errors import InputError
from ._app import app, column_options, setup_logging, user_errors

Band = Annotated[
    tuple[float, float],
    typer.Option("--band", metavar="LOW HIGH",
                 help="Band-pass applied before fitting, Hz (zero-phase Butterworth)."),
]
Terms = Annotated[str, typer.Option("--terms", metavar="SET", help="Term set: 16 (default), "
                                    "18, 9, or groups like permanent,induced_5,eddy_8[,bias].")]
SegSec = Annotated[float, typer.Option("--segment-seconds", metavar="S",
                                       help="Segment length when the log has no 'line' column, s.")]
NoScreen = Annotated[bool, typer.Option("--no-screen",
                                        help="Skip PCA screening (fit all segments).")]
Col = Annotated[list[str] | None, typer.Option("--col", metavar="NAME=SOURCE",
                                               help="Column map, repeatable (e.g. mag=mag_1_uc).")]
MapFile = Annotated[Path | None, typer.Option("--map", metavar="FILE",
                                              help="TOML column map: [columns] NAME = "
                                              "\"SOURCE\", optional [units] NAME = \"UNIT\".")]
Units = Annotated[list[str] | None, typer.Option("--units", metavar="NAME=UNIT",
                  help="Convert a field column or group (flux, mag) from nT/uT/mT/G to nT.")]
Ridge = Annotated[float, typer.Option("--ridge", help="Relative ridge parameter (0 = plain LS).")]
MaxCond = Annotated[float, typer.Option("--max-condition", metavar="K", help="Refuse an "
                    "unregularised fit whose scaled condition number exceeds K (a box "
                    "calibration gives ~1e2; straight-and-level flight ~1e5-1e6).")]
MaxInterf = Annotated[float, typer.Option("--max-interference", metavar="FRACTION", help="Refuse "
                      "a fitted model whose |mag_tl| (99th percentile) exceeds this fraction "
                      "of the Earth field (non-physical: the flight did not determine it).")]
Shrink = Annotated[float, typer.Option("--shrink", help="Shrinkage of per-segment fits toward "
                                       "the pooled fit during screening (0 = none).")]
Variance = Annotated[float, typer.Option("--pca-variance", help="Cumulative explained variance "
                                         "of the PCA components used for screening.")]
Quantile = Annotated[float, typer.Option("--screen-quantile", help="Chi-square quantile of the "
                                         "screening cut-off on the robust distance.")]
MinExcess = Annotated[float, typer.Option("--min-excess", help="A PCA outlier is dropped only "
                                          "when the pooled fit leaves it a residual above this "
                                          "times the median segment's.")]
MinExcessNT = Annotated[float, typer.Option("--min-excess-nt", help="... and by at least this "
                                            "much in nT (harmless differences are kept).")]
MaxGap = Annotated[float | None, typer.Option("--max-gap", metavar="S", help="A time step longer "
                                              "than this starts a new stretch, s (default 5 dt).")]
MaxInterp = Annotated[float, typer.Option("--max-interp", metavar="S", help="NaN gaps up to this "
                                          "long are interpolated, s; longer ones split stretches.")]
Fmt = Annotated[str | None, typer.Option("--format", metavar="FORMAT", help="Input format "
                                         "(default: from the extension and contents; see "
                                         "docs/formats.md).")]
Verbose = Annotated[bool, typer.Option("-v", "--verbose", help="Log progress details.")]
Plot = Annotated[Path | None, typer.Option("--plot", metavar="DIR", help="Also write the QC "
                                           "figures (PNG) and report.html into DIR.")]


def _warm(screen: bool, log: Path | None = None, fmt: str | None = None) -> None:
    """Start parsing ``log`` (a CSV) on a thread, then import what the run needs (scipy.signal,
    and scikit-learn when screening) on this thread while it parses (see aeromag.io.warm)."""
    import importlib

    from ..io.warm import prefetch_csv

    if log is not None and fmt in (None, "csv"):
        prefetch_csv(log)
    mods = ["aeromag.compensation", "scipy.signal", "aeromag.qc"]
    if screen:
        mods += ["sklearn.decomposition", "sklearn.covariance", "scipy.stats"]
    for name in mods:
        importlib.import_module(name)


@app.command()
def compensate(
    survey: Annotated[Path, typer.Argument(metavar="SURVEY.csv", help="Survey log (CSV, or "
                                           "another --format).", show_default=False)],
    output: Annotated[Path, typer.Option("-o", metavar="OUT.csv",
                                         help="Output CSV (the report goes to OUT.json).")],
    model: Annotated[Path | None, typer.Option("--model", metavar="MODEL.json",
                                               help="Apply a saved model "
                                               "(from 'aeromag calibrate') instead of fitting.")]
    = None,
    band: Band = (0.1, 0.9),
    terms: Terms = "16",
    segment_seconds: SegSec = 60.0,
    no_screen: NoScreen = False,
    no_filter: Annotated[bool, typer.Option("--no-filter", help="Leave mag_comp unfiltered.")]
    = False,
    lowpass: Annotated[float | None, typer.Option("--lowpass", metavar="HZ", help="Cut-off of "
                       "the final low-pass on mag_comp, Hz (default: the band's upper edge).")]
    = None,
    col: Col = None,
    map_file: MapFile = None,
    units: Units = None,
    ridge: Ridge = 0.0,
    max_condition: MaxCond = 1e5,
    max_interference: MaxInterf = 0.25,
    shrink: Shrink = 1.0,
    pca_variance: Variance = 0.8,
    screen_quantile: Quantile = 0.975,
    min_excess: MinExcess = 1.5,
    min_excess_nt: MinExcessNT = 0.01,
    max_gap: MaxGap = None,
    max_interp: MaxInterp = 1.0,
    fmt: Fmt = None,
    fom: Annotated[bool, typer.Option("--fom", help="Detect manoeuvres and report the Figure of "
                                      "Merit (for a calibration-style flight).")] = False,
    plot: Plot = None,
    chunk_rows: Annotated[int | None, typer.Option("--chunk-rows", metavar="N", help="With "
                          "--model: apply it in chunks of N rows, memory bounded by the chunk "
                          "size (identical output; for very large logs).")] = None,
    verbose: Verbose = False,
) -> None:
    """Compensate a log: fit on the log itself, or apply --model.

    Fits the Tolles-Lawson model on the survey itself (per segment, PCA screening of the
    segments, refit on the kept ones) or applies a saved --model, then writes OUT.csv (the log
    plus mag_tl, mag_comp, segment, segment_kept) and OUT.json (coefficients, per-segment PCA
    scores, screening, metrics).
    """
    setup_logging(verbose)
    _warm(screen=model is None and not no_screen, log=None if chunk_rows else survey, fmt=fmt)
    # Library imports here, not at module level: 'aeromag --help' stays instant.
    from ..compensation.config import CompensationConfig
    from ..compensation.model import TLModel
    from ..io import json_path_for
    from ..workflows.compensate import compensate_file

    with user_errors():
        if json_path_for(output) == output:
            raise InputError(f"-o {output}: the report goes to OUT.json, so OUT must not end in"
                             " .json; give the output CSV another name, e.g. -o survey_comp.csv")
        columns, unit_map = column_options(col, map_file, units)
        cfg = CompensationConfig(
            band_hz=band, terms=terms, segment_seconds=segment_seconds, screen=not no_screen,
            filter_output=not no_filter, lowpass_hz=lowpass, ridge=ridge, shrink=shrink,
            pca_variance=pca_variance, screen_quantile=screen_quantile, max_gap_s=max_gap,
            min_excess=min_excess, min_excess_nT=min_excess_nt, max_interp_s=max_interp,
            fom=fom or None, max_condition=max_condition,
            max_interference=max_interference,
        )
        if chunk_rows is not None:
            if model is None:
                raise InputError("--chunk-rows applies a saved model: add --model MODEL.json")
            if plot is not None:
                raise InputError("--plot needs the whole log in memory: drop --chunk-rows, or "
                                 "run 'aeromag report' on the output")
            if chunk_rows < 1:
                raise InputError(f"--chunk-rows {chunk_rows}: must be a positive row count")
            from ..workflows.chunked import apply_model_chunked

            report = apply_model_chunked(survey, output, TLModel.load(model), cfg,
                                         chunk_rows=chunk_rows, columns=columns,
                                         units=unit_map, fmt=fmt)
            _summary(report, output, json_path_for(output))
            return
        res = compensate_file(survey, output, cfg, model=model, columns=columns, units=unit_map,
                              fmt=fmt)
        if plot is not None:
            from ..workflows.report import (
                write_report,  # matplotlib only when figures are asked for
            )

            page = write_report(res.data, res.report, plot, cfg=cfg)
    _summary(res.report, output, json_path_for(output))
    if plot is not None:
        typer.echo(f"wrote {page}")


@app.command()
def calibrate(
    cal: Annotated[Path, typer.Argument(metavar="CAL.csv", help="Calibration flight log (CSV, "
                                        "or another --format).", show_default=False)],
    output: Annotated[Path, typer.Option("-o", metavar="MODEL.json",
                                         help="Output model file (JSON).")],
    band: Band = (0.1, 0.9),
    terms: Terms = "16",
    segment_seconds: SegSec = 60.0,
    no_screen: NoScreen = False,
    col: Col = None,
    map_file: MapFile = None,
    units: Units = None,
    ridge: Ridge = 0.0,
    max_condition: MaxCond = 1e5,
    max_interference: MaxInterf = 0.25,
    shrink: Shrink = 1.0,
    pca_variance: Variance = 0.8,
    screen_quantile: Quantile = 0.975,
    min_excess: MinExcess = 1.5,
    min_excess_nt: MinExcessNT = 0.01,
    max_gap: MaxGap = None,
    max_interp: MaxInterp = 1.0,
    fmt: Fmt = None,
    plot: Plot = None,
    verbose: Verbose = False,
) -> None:
    """Fit and screen the model on a calibration flight.

    Fits the Tolles-Lawson model per segment, screens the segments by PCA, refits on the kept
    ones and writes the model JSON (coefficients, per-segment PCA scores, screening, metrics
    and the FOM) for 'aeromag compensate --model'.
    """
    setup_logging(verbose)
    _warm(screen=not no_screen, log=cal, fmt=fmt)
    from ..compensation.config import CompensationConfig
    from ..workflows.compensate import calibrate_file

    with user_errors():
        columns, unit_map = column_options(col, map_file, units)
        cfg = CompensationConfig(
            band_hz=band, terms=terms, segment_seconds=segment_seconds, screen=not no_screen,
            ridge=ridge, shrink=shrink, pca_variance=pca_variance,
            screen_quantile=screen_quantile, max_gap_s=max_gap, max_interp_s=max_interp,
            min_excess=min_excess, min_excess_nT=min_excess_nt, max_condition=max_condition,
            max_interference=max_interference,
        )
        res = calibrate_file(cal, output, cfg, columns=columns, units=unit_map, fmt=fmt)
        if plot is not None:
            from ..workflows.report import (
                write_report,  # matplotlib only when figures are asked for
            )

            page = write_report(res.data, res.report, plot, cfg=cfg)
    _summary(res.report, output, None)
    if plot is not None:
        typer.echo(f"wrote {page}")


def _summary(report: dict, out: Path, out_json: Path | None) -> None:
    m = report.get("metrics", {})
    scr = report.get("screening", {})
    segs = report.get("segments", [])
    kept = sum(1 for s in segs if s.get("kept"))
    line = (f"wrote {out}" + (f" and {out_json}" if out_json else "")
            + f": {kept}/{len(segs)} segments kept")
    if scr.get("dropped"):
        line += f" (dropped {', '.join(map(str, scr['dropped']))})"
    ir = m.get("improvement_ratio")
    rs = m.get("residual_std_nT")
    if ir is not None and rs is not None:
        line += f"; improvement ratio {ir:.2f}, residual std {rs:.4f} nT"
        kir = m.get("kept_improvement_ratio")
        if scr.get("dropped") and kir is not None:
            line += f" ({kir:.2f} and {m['kept_residual_std_nT']:.4f} nT on kept segments)"
    typer.echo(line)
