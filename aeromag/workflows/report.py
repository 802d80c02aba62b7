"""The compensation QC report: PNG figures, ``qc.json`` and one self-contained ``report.html``.

``aeromag report OUT.csv -o DIR`` (and ``--plot DIR`` on compensate/calibrate) end here:

* :func:`build_report` reads ``OUT.csv`` and the ``OUT.json`` beside it;
* :func:`write_report` computes the QC metrics (:func:`aeromag.qc.compute_qc`), draws every
  figure that the data allow (:mod:`aeromag.plot.compensation`), and writes the PNGs,
  ``qc.json`` and ``report.html`` (figures embedded as base64 ``data:`` URIs, so the page is a
  single file that opens anywhere).  Every file is written atomically.
"""

from __future__ import annotations

import base64
import dataclasses
import html
import json
import logging
import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .. import __version__
from ..compensation.config import CompensationConfig
from ..compensation.model import TLModel
from ..compensation.result import CompensationResult
from ..errors import AeromagError, InputError
from ..io import atomic_path, json_path_for, read_log, write_json
from ..plot import compensation as pc
from ..qc import QCResult, compute_qc

__all__ = ["FIGURES", "build_report", "load_compensated", "render_html", "write_report"]

log = logging.getLogger(__name__)

#: Figure files written by :func:`write_report`, with their captions.
FIGURES: dict[str, str] = {
    "pca_scores.png": "PCA score plot of the segment coefficient vectors (PC1 vs PC2) with the"
                      " screening decision boundary",
    "explained_variance.png": "Explained variance of the principal components",
    "timeseries.png": "Uncompensated vs compensated total field",
    "psd.png": "Power spectral density before and after compensation",
    "term_contributions.png": "Permanent, induced and eddy contributions to the interference",
    "fom.png": "Figure of Merit: peak-to-peak per heading and manoeuvre",
    "map.png": "Flight coloured by the compensated field",
}


def _figures(data: pd.DataFrame, report: dict[str, Any], qc: QCResult,
             band: tuple[float, float]) -> dict[str, Any]:
    """Callables drawing each figure (some may raise InputError when data are missing)."""
    return {
        "pca_scores.png": lambda p: pc.plot_pca_scores(report, path=p),
        "explained_variance.png": lambda p: pc.plot_explained_variance(report, path=p),
        "timeseries.png": lambda p: pc.plot_timeseries(data, path=p),
        "psd.png": lambda p: pc.plot_psd(data, band_hz=band, path=p),
        "term_contributions.png": lambda p: pc.plot_term_contributions(data, report, path=p),
        "fom.png": lambda p: pc.plot_fom(qc.fom, path=p),
        "map.png": lambda p: pc.plot_map(data, path=p),
    }


def write_report(
    result: CompensationResult, out_dir: Any, *legacy: Any,
    config: CompensationConfig | None = None, title: str | None = None, **qc_kw: Any,
) -> Path:
    """Compute QC, write the figures, ``qc.json`` and ``report.html`` into ``out_dir``.

    Parameters
    ----------
    result : CompensationResult
        A compensation (:func:`aeromag.compensate.compensate`, or :func:`load_compensated` on
        ``OUT.csv``).
    out_dir : path-like
        Output folder (created when missing).
    config : CompensationConfig, optional
        The configuration it was compensated with (default: the result's).
    title : str, optional
        Page title (default: the report's source).
    **qc_kw
        Passed to :func:`aeromag.qc.compute_qc` (e.g. ``maneuver_column``).

    Returns
    -------
    Path
        The HTML page.
    """
    if config is None:
        config = qc_kw.pop("cfg", None)
    if isinstance(result, pd.DataFrame):  # the old write_report(data, report, out_dir) call
        warnings.warn("write_report(data, report, out_dir) is deprecated: pass the"
                      " CompensationResult", DeprecationWarning, stacklevel=2)
        if not legacy:
            raise TypeError("write_report(data, report, out_dir): out_dir missing")
        result, out_dir = CompensationResult(result, None, out_dir), legacy[0]
        if config is None:
            config = _config_from(result.report)
    elif legacy:
        raise TypeError("write_report(result, out_dir): too many positional arguments")
    data, report = result.data, result.report
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    qc = compute_qc(result, config=config, **qc_kw)
    band = tuple(qc.metrics["band_hz"])
    written: dict[str, Path] = {}
    skipped: dict[str, str] = {}
    for name, draw in _figures(data, report, qc, band).items():
        try:
            draw(out / name)
            written[name] = out / name
        except (AeromagError, KeyError) as exc:
            skipped[name] = str(exc)
            log.info("report: %s skipped: %s", name, exc)
    qc.metrics["figures"] = sorted(written)
    qc.metrics["figures_skipped"] = skipped
    write_json(qc.metrics, out / "qc.json")
    page = render_html(qc.metrics, report, written, title=title)
    html_path = out / "report.html"
    with atomic_path(html_path) as tmp:
        tmp.write_text(page, encoding="utf-8")
    log.info("wrote %s (%d figures)", html_path, len(written))
    return html_path


def build_report(
    out_csv: str | os.PathLike[str], out_dir: str | os.PathLike[str],
    report_json: str | os.PathLike[str] | None = None, **qc_kw: Any,
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
    **qc_kw
        Passed to :func:`aeromag.qc.compute_qc`.

    Returns
    -------
    Path
        The HTML page.
    """
    result, config = load_compensated(out_csv, report_json)
    return write_report(result, out_dir, config=config, **qc_kw)


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
    """
    src = Path(out_csv)
    data = read_log(src, required=("time", "mag_comp"))
    rj = Path(report_json) if report_json is not None else json_path_for(src)
    report: dict[str, Any] = {}
    if rj.exists():
        try:
            report = json.loads(rj.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise InputError(f"{rj}: not a readable JSON report ({exc}); rerun"
                             " 'aeromag compensate'") from None
    elif report_json is not None:
        raise InputError(f"{rj}: file not found")
    else:
        log.warning("%s: no report beside the log; default configuration assumed", rj)
    report.setdefault("source", str(src))
    config = _config_from(report)
    model = TLModel.from_dict(report, source=str(rj)) if report.get("coef") else None
    return CompensationResult(data, model, report), config


def _config_from(report: dict[str, Any]) -> CompensationConfig:
    """The configuration recorded in a report file (defaults for what it lacks)."""
    names = {f.name for f in dataclasses.fields(CompensationConfig)}
    kw = {k: v for k, v in (report.get("config") or {}).items() if k in names}
    if "band_hz" not in kw and report.get("band_hz"):
        kw["band_hz"] = report["band_hz"]
    return CompensationConfig(**kw)


# --------------------------------------------------------------------------- HTML
_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:2em auto;
max-width:1100px;color:#222;padding:0 1em}
h1{font-size:1.5em}h2{font-size:1.2em;margin-top:1.6em;border-bottom:1px solid #ccc}
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:.25em .6em;
text-align:right}th{background:#f3f3f3}td:first-child,th:first-child{text-align:left}
figure{margin:1em 0}figure img{max-width:100%;border:1px solid #eee}
figcaption{font-size:.9em;color:#555}.note{color:#a60}
"""


def _fmt(v: Any, digits: int = 4) -> str:
    if v is None:
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int | np.integer):
        return str(int(v))
    if isinstance(v, float | np.floating):
        if not np.isfinite(v):
            return str(v)
        return f"{v:.{digits}g}"
    return html.escape(str(v))


def _table(rows: list[list[Any]], header: list[str]) -> str:
    h = "".join(f"<th>{html.escape(c)}</th>" for c in header)
    body = "".join("<tr>" + "".join(f"<td>{_fmt(c)}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><thead><tr>{h}</tr></thead><tbody>{body}</tbody></table>"


def render_html(metrics: dict[str, Any], report: dict[str, Any], figures: dict[str, Path],
                *, title: str | None = None) -> str:
    """The self-contained HTML page: metrics tables and base64-embedded PNG figures.

    Parameters
    ----------
    metrics : dict
        QC metrics (:func:`aeromag.qc.quality_metrics`).
    report : dict
        The compensation report (source, coefficients, screening).
    figures : dict
        Figure file name -> path of the PNG to embed.
    title : str, optional
        Page title.

    Returns
    -------
    str
        HTML5 document.
    """
    title = title or f"aeromag compensation report: {report.get('source', '')}"
    parts = [f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
             f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>",
             f"<h1>{html.escape(title)}</h1>",
             f"<p>aeromag {html.escape(__version__)}; band {metrics['band_hz'][0]:g}–"
             f"{metrics['band_hz'][1]:g} Hz</p>"]
    fom = metrics.get("fom") or {}
    fit = metrics.get("fit") or {}
    noise = metrics.get("noise") or {}
    rows = [
        ["FOM before (nT)", fom.get("fom_before_nT")],
        ["FOM after (nT)", fom.get("fom_after_nT")],
        ["FOM reduction (before / after)", fom.get("fom_reduction")],
        ["improvement ratio", metrics.get("improvement_ratio")],
        ["residual std (nT, band-passed)", metrics.get("residual_std_nT")],
        ["std before (nT, band-passed)", metrics.get("std_before_nT")],
        ["4th-difference noise before / after (nT)",
         f"{_fmt(noise.get('fourth_difference_before_nT'))} / "
         f"{_fmt(noise.get('fourth_difference_after_nT'))}"],
        ["condition number (unit-norm columns)", fit.get("condition_number_scaled")],
        ["largest VIF", fit.get("max_vif")],
        ["leave-one-segment-out CV residual (nT)", fit.get("cv_residual_std_nT")],
        ["in-sample fit residual (nT)", fit.get("fit_residual_std_nT")],
    ]
    if fom.get("fom_truth_nT") is not None:
        rows.insert(2, ["FOM of the true interference (nT)", fom.get("fom_truth_nT")])
    scr = report.get("screening") or {}
    if scr:
        rows.append(["segments kept / fitted", f"{scr.get('n_kept', '–')} / "
                     f"{scr.get('n_segments', '–')}"])
        rows.append(["dropped segments", ", ".join(map(str, scr.get("dropped", []))) or "none"])
    parts.append("<h2>Summary</h2>" + _table(rows, ["metric", "value"]))
    if fom.get("per_maneuver"):
        pm = fom["per_maneuver"]
        keys = [k for k in ("ptp_before_nT", "ptp_after_nT", "ptp_truth_nT") if k in pm[0]]
        parts.append("<h2>Figure of Merit (peak-to-peak per manoeuvre, nT)</h2>")
        parts.append(_table([[r["heading"], r["maneuver"], *(r[k] for k in keys)] for r in pm],
                            ["heading", "manoeuvre", *[k[4:-3] for k in keys]]))
        boxes = fom.get("boxes", [])
        if boxes:
            bk = [k for k in ("fom_before_nT", "fom_after_nT", "fom_truth_nT") if k in boxes[0]]
            parts.append(_table([[b["box"], b["n_maneuvers"], b["complete"],
                                  *(b[k] for k in bk)] for b in boxes],
                                ["box", "manoeuvres", "complete", *bk]))
    by_h = metrics.get("residual_std_by_heading_nT") or {}
    if by_h:
        parts.append("<h2>Residual std per heading (nT)</h2>"
                     + _table([[k, v] for k, v in by_h.items()], ["heading", "residual std"]))
    if fit.get("vif"):
        parts.append("<h2>Variance inflation factors</h2>"
                     + _table([[k, v] for k, v in fit["vif"].items()], ["term", "VIF"]))
    if report.get("terms") and report.get("coef"):
        parts.append("<h2>Coefficients</h2>" + _table(
            [[t, c] for t, c in zip(report["terms"], report["coef"], strict=True)],
            ["term", "coefficient (nT; eddy nT·s)"]))
    notes = list(metrics.get("notes") or [])
    notes += [f"{k} not drawn: {v}" for k, v in (metrics.get("figures_skipped") or {}).items()]
    if notes:
        parts.append("<h2>Notes</h2><ul>" + "".join(
            f"<li class='note'>{html.escape(n)}</li>" for n in notes) + "</ul>")
    parts.append("<h2>Figures</h2>")
    for name, path in figures.items():
        b64 = base64.b64encode(Path(path).read_bytes()).decode("ascii")
        cap = html.escape(FIGURES.get(name, name))
        parts.append(f"<figure id='{html.escape(Path(name).stem)}'><img alt='{cap}' "
                     f"src='data:image/png;base64,{b64}'><figcaption>{cap}</figcaption>"
                     "</figure>")
    parts.append("</body></html>")
    return "\n".join(parts)
