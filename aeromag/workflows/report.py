"""The compensation QC report: PNG figures, ``qc.json`` and one self-contained ``report.html``.

``aeromag report OUT.csv -o DIR`` (and ``--plot DIR`` on compensate/calibrate) end here:

* :func:`load_compensated` reads ``OUT.csv`` and the ``OUT.json`` beside it into a
  :class:`~aeromag.compensation.result.CompensationResult` and its configuration;
* :func:`write_report` computes the QC metrics (:func:`aeromag.qc.compute_qc`), draws every
  figure the data allow (:mod:`aeromag.plot.compensation`, decimated for display), and writes
  the PNGs, ``qc.json`` and ``report.html`` (figures embedded as base64 ``data:`` URIs, so the
  page is one file that opens anywhere).  Every file is written atomically.

Progress is reported through an optional callback ``progress(done, total, step)`` (the command
line draws it as a progress bar); nothing here prints.
"""

from __future__ import annotations

import html
import json
import logging
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .. import __version__
from ..compensation.config import CompensationConfig
from ..compensation.model import TLModel
from ..compensation.report_types import (
    CompensationReport,
    ScreeningSummary,
    SegmentRow,
)
from ..compensation.result import CompensationResult
from ..errors import AeromagError, InputError
from ..io import atomic_path, json_path_for, read_log, write_json
from ..plot import compensation as pc
from ..qc import QCResult, compute_qc, kept_mask, segment_labels
from ..qc.quality import QCMetrics, config_of
from ..qc.summaries import QCSegmentRow
from ._report_html import (
    extended_html,
    figure_html,
    fmt,
    fom_rows,
    headline_words,
    html_table,
    html_time,
    page_head,
)
from .report_check import headline_from_data, headline_record

__all__ = ["FIGURES", "report_file", "load_compensated", "render_html", "write_report"]

log = logging.getLogger(__name__)

#: ``progress(done, total, step)``: called as the report advances.
Progress = Callable[[int, int, str], None]

#: Columns of a compensated log the report uses (others in the log are not read).
REPORT_COLUMNS = ("time", "mag", "mag_tl", "mag_comp", "segment", "segment_kept", "line",
                  "flux_x", "flux_y", "flux_z", "heading", "pitch", "roll", "lat", "lon", "alt",
                  "truth_mag_tl", "maneuver")

#: Columns only drawn or used for manoeuvre detection, read in single precision: 7 digits
#: (0.005 nT of a 50000 nT fluxgate, 0.3 m of latitude) are ample and halve their memory.
REPORT_DTYPES = {c: np.float32 for c in ("flux_x", "flux_y", "flux_z", "heading", "pitch",
                                         "roll", "lat", "lon", "alt")}

#: Figure files written by :func:`write_report`, with their captions.
FIGURES: dict[str, str] = {
    "residuals.png": "Band-passed field before (mag) and after (mag - mag_tl) compensation, in"
                     " the fitting band, each segment filtered on its own; dropped segments red",
    "timeseries.png": "Uncompensated vs compensated total field",
    "map.png": "Flight in metres (east, north of the first fix) coloured by the compensated"
               " field; dropped segments marked",
    "pca_scores.png": "PCA score plot of the segment coefficient vectors (PC1 vs PC2) with the"
                      " screening decision boundary",
    "explained_variance.png": "Explained variance of the principal components",
    "psd.png": "Power spectral density before and after compensation",
    "term_contributions.png": "Permanent, induced and eddy contributions to the interference",
    "fom.png": "Figure of Merit: peak-to-peak per heading and manoeuvre",
}

def _figures(result: CompensationResult, qc: QCResult, band: tuple[float, float]
             ) -> dict[str, Callable[[], Any]]:
    """Callables drawing each figure (some raise InputError when data are missing)."""
    data, report = result.data, result.report

    def residuals() -> Any:
        if qc.residuals is None:
            raise InputError("no band-passed residuals")
        return pc.plot_residuals(data["time"].to_numpy(), qc.residuals.before_bp,
                                 qc.residuals.after_bp, kept=kept_mask(data), band_hz=band)

    def fom() -> Any:
        fb = qc.metrics.fom
        if fb is None or not fb.applicable:
            raise InputError((fb.reason if fb is not None else None) or "no FOM")
        return pc.plot_fom(qc.fom)

    return {
        "residuals.png": residuals,
        "timeseries.png": lambda: pc.plot_timeseries(data),
        "map.png": lambda: pc.plot_map(data),
        "pca_scores.png": lambda: pc.plot_pca_scores(report),
        "explained_variance.png": lambda: pc.plot_explained_variance(report),
        "psd.png": lambda: pc.plot_psd(data, band_hz=band),
        "term_contributions.png": lambda: pc.plot_term_contributions(data, report),
        "fom.png": fom,
    }


def write_report(
    result: CompensationResult, out_dir: Any, *, config: CompensationConfig | None = None,
    title: str | None = None, progress: Progress | None = None, **qc_kw: Any,
) -> Path:
    """Compute QC, write the figures, ``qc.json`` and ``report.html`` into ``out_dir``.

    Parameters
    ----------
    result : CompensationResult
        A compensation (:func:`aeromag.compensate`, or :func:`load_compensated` on ``OUT.csv``).
    out_dir : path-like
        Output folder (created when missing).
    config : CompensationConfig, optional
        The configuration it was compensated with (default: the result's).
    title : str, optional
        Page title (default: the report's source).
    progress : callable, optional
        ``progress(done, total, step)``, called after each step.
    **qc_kw
        Passed to :func:`aeromag.qc.compute_qc` (e.g. ``maneuver_column``).

    Returns
    -------
    Path
        The HTML page.
    """
    if result.data is None:
        raise InputError("this result holds no compensated data (use compensate())")
    result = headline_from_data(result, config)  # the headline of the data shown (issue 15)
    report = result.report
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    draws = _figures(result, None, (0.0, 0.0))  # names only, for the step count
    total = 2 + len(draws)
    step = 0

    def advance(what: str) -> None:
        nonlocal step
        step += 1
        if progress is not None:
            progress(step, total, what)

    qc = compute_qc(result, config=config, **qc_kw)
    record = headline_record(report)
    if record.headline_check is not None:
        qc.metrics.headline_check = record.headline_check
    if record.compensation_metrics is not None:
        qc.metrics.compensation_metrics = record.compensation_metrics
    # Only the metrics, the FOM table and the band-passed fields are shown: the per-sample
    # manoeuvre labels go before the figures.
    qc.maneuvers = None
    advance("quality metrics")
    band = tuple(qc.metrics.band_hz)
    pngs: dict[str, bytes] = {}
    skipped: dict[str, str] = {}
    for name, draw in _figures(result, qc, band).items():
        try:
            pngs[name] = pc.figure_png(draw())
        except (AeromagError, KeyError) as exc:
            skipped[name] = str(exc)
            log.info("report: %s skipped: %s", name, exc)
        if name == "residuals.png":
            qc.residuals = None  # the band-passed fields (32 MB at 2e6 rows): drawn
        advance(name)
    for name, data in pngs.items():
        with atomic_path(out / name) as tmp:
            Path(tmp).write_bytes(data)
    qc.metrics.figures = sorted(pngs)
    qc.metrics.figures_skipped = skipped
    qc.metrics.segments = segment_rows(result, qc)
    doc = qc.metrics.to_dict()
    doc.setdefault("warnings", [])  # a report: write_json fills the list, [] if none
    write_json(doc, out / "qc.json")
    qc.metrics.warnings = doc["warnings"]
    page = render_html(qc.metrics, report, pngs, title=title)
    html_path = out / "report.html"
    with atomic_path(html_path) as tmp:
        Path(tmp).write_text(page, encoding="utf-8")
    advance("report.html")
    log.info("wrote %s (%d figures)", html_path, len(pngs))
    return html_path


def segment_rows(result: CompensationResult, qc: QCResult) -> list[QCSegmentRow]:
    """One row per segment: line, time span, samples, kept, why dropped, residuals.

    Parameters
    ----------
    result : CompensationResult
        The compensation (its data and report).
    qc : QCResult
        Its quality control.

    Returns
    -------
    list of QCSegmentRow
        ``segment``, ``line``, ``t_start``/``t_end`` [s], ``n``, ``kept``, ``reason``,
        ``residual_std_nT`` (qc: band-passed ``mag - mag_tl`` of the segment) and
        ``model_residual_std_nT`` (the model file's).
    """
    data = result.data
    seg = segment_labels(data)
    t = data["time"].to_numpy(dtype=np.float64)
    rep = {int(s.id): s for s in result.report.segments}
    by_seg = qc.metrics.residual_std_by_segment_nT or {}
    kept = kept_mask(data)
    line_col = data["line"].to_numpy() if "line" in data.columns else None
    rows = []
    # Runs of equal labels (a few per segment), then grouped per id: no whole-length sort,
    # mask or copy (np.unique of the labels rose 95 MB at 2e6 rows for 8004 segments).
    if not len(seg):
        return rows
    start = np.r_[0, np.flatnonzero(seg[1:] != seg[:-1]) + 1]
    end = np.r_[start[1:], len(seg)] - 1
    rid = seg[start]
    keep = rid >= 0
    start, end, rid = start[keep], end[keep], rid[keep]
    del seg
    if len(rid):
        ids, inv = np.unique(rid, return_inverse=True)
        first_at = np.full(len(ids), len(t), dtype=np.int64)
        np.minimum.at(first_at, inv, start)
        last_at = np.full(len(ids), -1, dtype=np.int64)
        np.maximum.at(last_at, inv, end)
        counts = np.bincount(inv, weights=end - start + 1, minlength=len(ids)).astype(np.int64)
        for j, sid in enumerate(ids.tolist()):
            e = rep.get(sid)
            line = e.line if e is not None else None
            if line is None and line_col is not None:
                line = line_col[first_at[j]]
            reason = None
            if e is not None:  # another tool's report may name the reason otherwise
                reason = e.reason or e.extra.get("drop_reason") or e.extra.get("why")
            if isinstance(reason, dict):
                reason = reason.get("text") or json.dumps(reason)
            if not reason and e is not None:
                reason = _why_dropped(e, result.report.screening)
            k = bool(e.kept) if e is not None else bool(kept[first_at[j]])
            rows.append(QCSegmentRow(
                segment=sid, line=None if line is None or pd.isna(line) else
                (int(line) if float(line).is_integer() else float(line)),
                t_start=float(t[first_at[j]]), t_end=float(t[last_at[j]]),
                n=int(counts[j]), kept=k,
                reason=None if k else (reason or "dropped by the PCA screening"),
                residual_std_nT=by_seg.get(str(sid)),
                model_residual_std_nT=e.residual_std if e is not None else None))
    return rows


def _why_dropped(seg: SegmentRow, screening: ScreeningSummary) -> str | None:
    """Why the screening dropped a segment, in words and its own numbers (None: unknown)."""
    d, cut = seg.robust_distance, screening.cutoff
    res, exc = seg.residual_std, seg.residual_excess
    tail = (f"; residual {res:.3g} nT = {exc:.3g}x the median of kept segments"
            if res is not None and exc is not None else "")
    if seg.pca_outlier and d is not None and cut is not None:
        return f"PCA outlier: robust distance\u00b2 {d:.4g} > {cut:.3g}{tail}"
    if tail:
        return f"residual far above the other segments'{tail}"
    return None


def report_file(
    out_csv: str | os.PathLike[str], out_dir: str | os.PathLike[str],
    report_json: str | os.PathLike[str] | None = None, *, progress: Progress | None = None,
    **qc_kw: Any,
) -> Path:
    """Build the QC report of a compensated log written by ``aeromag compensate``.

    Parameters
    ----------
    out_csv : path-like
        The compensated log (``OUT.csv``).
    out_dir : path-like
        Output folder for the PNGs, ``qc.json`` and ``report.html``.
    report_json : path-like, optional
        The report (default ``OUT.json`` beside ``OUT.csv``; without it the default
        configuration is assumed and the PCA figures are skipped).
    progress : callable, optional
        ``progress(done, total, step)``.
    **qc_kw
        Passed to :func:`aeromag.qc.compute_qc`.

    Returns
    -------
    Path
        The HTML page.
    """
    result, config = load_compensated(out_csv, report_json)
    return write_report(result, out_dir, config=config, progress=progress, **qc_kw)


def load_compensated(
    out_csv: str | os.PathLike[str], report_json: str | os.PathLike[str] | None = None,
) -> tuple[CompensationResult, CompensationConfig]:
    """Read a compensated log and its report back into a result and its configuration.

    Parameters
    ----------
    out_csv : path-like
        The compensated log (``OUT.csv``).
    report_json : path-like, optional
        The report (default ``OUT.json`` beside ``OUT.csv``).

    Returns
    -------
    result : CompensationResult
    config : CompensationConfig
        The configuration recorded in the report (defaults for what it lacks).

    Raises
    ------
    InputError
        When the log is not compensated (no ``mag_comp``): run ``aeromag compensate`` first.
    """
    src = Path(out_csv)
    rj = Path(report_json) if report_json is not None else json_path_for(src)
    doc: dict[str, Any] = {}
    if rj.exists():
        try:
            doc = json.loads(rj.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise InputError(f"{rj}: not a readable JSON report ({exc}); rerun"
                             " `aeromag compensate`") from None
    elif report_json is not None:
        raise InputError(f"{rj}: file not found")
    else:
        log.warning("%s: no report beside the log; default configuration assumed", rj)
    if not isinstance(doc, dict):
        raise InputError(f"{rj}: not a JSON report (an object of keys expected); rerun"
                         " `aeromag compensate`")
    if "crossovers" in doc and "mistie_std_nT" in doc:  # before reading the log itself
        raise InputError(f"{src}: a levelled survey ({rj.name} is a levelling report), not a "
                         "compensated log; its QC page (map, misties, profiles, report.html) "
                         f"comes from aeromag level SURVEY -o {src.name} --plot DIR")
    data = read_log(src, usecols=REPORT_COLUMNS, dtypes=REPORT_DTYPES, required=())
    if "mag_comp" not in data.columns:
        raise InputError(f"{src}: no mag_comp column: this log is not compensated; run"
                         f" `aeromag compensate {src} -o OUT.csv` first, then"
                         " `aeromag report OUT.csv -o DIR`")
    if "time" not in data.columns:
        raise InputError(f"{src}: missing column 'time'")
    doc.setdefault("source", str(src))
    data.attrs["report_json"] = str(rj)  # named by the headline check (report_check)
    report = CompensationReport.from_dict(doc)
    config = config_of(report)
    model = None
    if doc.get("coef"):
        try:
            model = TLModel.from_dict(doc, source=str(rj))
        except AeromagError:
            model = None
    return CompensationResult(data, model, report, config=config), config


# --------------------------------------------------------------------------- HTML
def render_html(metrics: QCMetrics | dict[str, Any], report: CompensationReport | dict[str, Any],
                figures: dict[str, Any], *, title: str | None = None) -> str:
    """The self-contained HTML page: metrics tables and base64-embedded PNG figures.

    Parameters
    ----------
    metrics : QCMetrics or dict
        QC metrics (:func:`aeromag.qc.compute_qc`), with ``segments`` rows (a dict: as
        ``qc.json`` holds them, :meth:`QCMetrics.from_dict`).
    report : CompensationReport or dict
        The compensation report (source, model, screening; a dict: as ``OUT.json`` holds it).
    figures : dict
        Figure file name -> PNG bytes (or the path of a PNG) to embed.
    title : str, optional
        Page title.

    Returns
    -------
    str
        HTML5 document.
    """
    if not isinstance(metrics, QCMetrics):
        metrics = QCMetrics.from_dict(metrics)
    if not isinstance(report, CompensationReport):
        report = CompensationReport.from_dict(report)
    title = title or f"aeromag compensation report: {report.source}"
    band = metrics.band_hz
    parts = [page_head(title, f"aeromag {__version__}; fitting band "
                              f"{band[0]:g}–{band[1]:g} Hz")]
    fom, fit, noise = metrics.fom, metrics.fit, metrics.noise
    check = metrics.headline_check
    rec = metrics.compensation_metrics
    names = [("improvement ratio (band-passed mag / mag - mag_tl)", "improvement_ratio"),
             ("residual (nT, band-passed mag - mag_tl)", "residual_std_nT"),
             ("before (nT, band-passed mag)", "std_before_nT"),
             ("samples", "n_samples")]
    header = ["metric", "kept segments", "all data"]
    rows: list[list[Any]] = [[label, getattr(metrics, k), getattr(metrics.all_data, k, None)]
                             for label, k in names]
    if check is not None and check.compared:
        header.append(f"recorded in {Path(check.recorded_in or 'OUT.json').name}"
                      " (kept / all)")
        for r, (_, k) in zip(rows, names, strict=True):
            r.append(f"{fmt(getattr(rec, k, None))} / {fmt(getattr(rec, 'all_' + k, None))}")
    parts.append("<h2>Summary</h2>")
    if check is not None and check.warning:
        parts.append(f"<p class='warn' id='headline-warning'>Warning: "
                     f"{html.escape(check.warning)}</p>")
    comp_warning = (check.mag_comp.warning if check is not None and check.mag_comp is not None
                    else None)
    if comp_warning:
        parts.append(f"<p class='warn' id='mag-comp-warning'>Warning: "
                     f"{html.escape(comp_warning)}</p>")
    parts.append(html_table(rows, header))
    words = headline_words(check)
    if metrics.definition:
        words = f"{metrics.definition}. {words}"
    parts.append(f"<p class='small'>{html.escape(words)}</p>")
    more = [
        ["4th-difference noise before / after (nT)",
         f"{fmt(getattr(noise, 'fourth_difference_before_nT', None))} / "
         f"{fmt(getattr(noise, 'fourth_difference_after_nT', None))}"],
        ["condition number (unit-norm columns)", getattr(fit, "condition_number_scaled", None)],
        ["largest VIF", getattr(fit, "max_vif", None)],
        ["leave-one-segment-out CV residual (nT)", getattr(fit, "cv_residual_std_nT", None)],
        ["in-sample fit residual (nT)", getattr(fit, "fit_residual_std_nT", None)],
    ]
    scr = report.screening
    if scr.n_segments is not None:
        more.append(["segments kept / fitted", f"{'–' if scr.n_kept is None else scr.n_kept} / "
                     f"{scr.n_segments}"])
    parts.append(html_table(more, ["diagnostic", "value"]))
    # FOM: numbers only for complete calibration boxes.
    parts.append("<h2>Figure of Merit</h2>")
    if fom is not None and fom.applicable:
        parts.append(html_table(fom_rows(fom), ["metric", "manoeuvres in kept segments",
                                             "all manoeuvres"]))
        boxes = fom.complete_boxes
        parts.append(f"<p class='small'>Complete boxes: {len(boxes)} (box "
                     f"{html.escape(', '.join(map(str, boxes)))}); manoeuvres in kept segments:"
                     f" {fmt(fom.n_maneuvers_kept)} of {fmt(fom.n_maneuvers)}."
                     f" {html.escape(fom.kept_reason or '')}"
                     f" {html.escape(fom.kept_definition or '')}</p>")
        pm = fom.per_maneuver
        if pm:
            keys = [k for k in ("ptp_before_nT", "ptp_after_nT", "ptp_truth_nT")
                    if pm[0].written(k)]
            parts.append(html_table([[r.heading, r.maneuver, *(getattr(r, k) for k in keys)]
                                 for r in pm],
                                ["heading", "manoeuvre", *[f"{k[4:-3]} (nT p-p)" for k in keys]]))
    else:
        reason = fom.reason if fom is not None else None
        parts.append(f"<p class='na'>{html.escape(reason or 'FOM not applicable')}</p>")
    # The model that was applied.
    parts.append("<h2>Model applied</h2>")
    src = report.model_source
    origin = ("fitted on this log" if src in (None, "fitted") else f"saved model: {src}")
    fitb = report.fit
    mrows = [["model", origin], ["terms", len(report.terms)],
             ["band (Hz)", f"{band[0]:g}–{band[1]:g}"]]
    if fitb is not None:
        mrows += [["fit samples", fitb.n_samples],
                  ["segments fitted", fitb.n_segments_fitted],
                  ["fit residual (nT)", fitb.residual_std_nT]]
    parts.append(html_table(mrows, ["", "value"]))
    if report.terms and report.coef:
        parts.append(html_table(
            [[t, c] for t, c in zip(report.terms, report.coef, strict=True)],
            ["term", "coefficient (nT; eddy nT·s)"]))
    parts.append(extended_html(report.extended))
    # Per line.
    segs = metrics.segments or []
    if segs:
        parts.append("<h2>Lines and segments</h2>")
        parts.append(html_table(
            [[s.segment, s.line, html_time(s.t_start), html_time(s.t_end), s.n,
              s.kept, s.residual_std_nT, s.model_residual_std_nT, s.reason or ""]
             for s in segs],
            ["segment", "line", "start", "end", "samples", "kept", "residual (nT)",
             "model file residual (nT)", "why dropped"],
            ["dropped" if not s.kept else "" for s in segs]))
    by_h = metrics.residual_std_by_heading_nT or {}
    if by_h:
        parts.append("<h2>Residual per heading (nT)</h2>"
                     + html_table([[k, v] for k, v in by_h.items()], ["heading", "residual"]))
    if fit is not None and fit.vif:
        parts.append("<h2>Variance inflation factors</h2>"
                     + html_table([[k, v] for k, v in fit.vif.items()], ["term", "VIF"]))
    notes = list(metrics.notes or [])
    notes += [f"{k} not drawn: {v}" for k, v in (metrics.figures_skipped or {}).items()]
    if notes:
        parts.append("<h2>Notes</h2><ul>" + "".join(
            f"<li class='note'>{html.escape(n)}</li>" for n in notes) + "</ul>")
    parts.append("<h2>Figures</h2>")
    for name, png in figures.items():
        parts.append(figure_html(name, png, FIGURES.get(name, name)))
    parts.append("</body></html>")
    return "\n".join(parts)
