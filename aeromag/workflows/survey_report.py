"""The levelling QC page: figures and one self-contained ``report.html`` for a levelled survey.

``aeromag level SURVEY -o OUT.csv --plot DIR`` ends here (and ``am.workflows.
write_survey_report(res, DIR)`` from Python): the anomaly map (the levelled column gridded
by minimum curvature, in colour with shaded relief, the flight lines on top and a colour bar
in nT), the mistie histograms before and after levelling, stacked line profiles, and an HTML
page with the steps' figures (lag, diurnal, IGRF, crossings, levelling passes, degrees of
freedom, micro-levelling), the warnings, and one row per line. The figures are embedded
as base64 ``data:`` URIs, so the page is one file that opens anywhere. Every file is written
atomically.
"""

from __future__ import annotations

import html
import logging
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from ..errors import InputError
from ..io import atomic_path
from ..survey.chain import LevelResult
from ._report_html import figure_html, fmt, html_table, html_time, page_head

__all__ = ["SURVEY_FIGURES", "render_survey_html", "write_survey_report"]

log = logging.getLogger(__name__)

#: Figure files :func:`write_survey_report` writes (when the data allow), with captions.
SURVEY_FIGURES: dict[str, str] = {
    "map.png": "Levelled anomaly gridded by minimum curvature (tension 0.25), shaded relief "
               "lit from the north-west, flight lines in black; blank cells are farther than "
               "1.5 line spacings from every sample",
    "misties.png": "Misties at the line-tie crossings before and after tie-line levelling",
    "profiles.png": "Stacked profiles of the levelled anomaly along the lines",
}

#: Most cells of the report's map: a QC picture, not the deliverable (``aeromag grid``).
MAP_MAX_CELLS = 1_000_000


def _map_grid(res: LevelResult, column: str) -> Any:
    """The map's grid: the default cell, coarsened to at most MAP_MAX_CELLS cells."""
    from ..survey.grids import grid

    d = res.data
    x, y = d["x_m"].to_numpy(float), d["y_m"].to_numpy(float)
    ok = np.isfinite(x) & np.isfinite(y)
    area = float(np.ptp(x[ok]) * np.ptp(y[ok])) if ok.any() else 0.0
    cell = None
    spacing = res.geometry.line_spacing_m
    if spacing is not None and np.isfinite(spacing) and area > 0:
        cell = max(spacing / 5.0, float(np.sqrt(area / MAP_MAX_CELLS)))
    return grid(d, value=column, cell_m=cell, crs=res.geometry.crs)


def _figures(res: LevelResult, column: str) -> dict[str, Callable[[Any], Any]]:
    """Figure name -> callable drawing it to a path."""
    from ..plot.grid_map import plot_grid_map
    from ..plot.levelling import plot_mistie_histogram, plot_stacked_profiles

    def draw_map(path: Any) -> Any:
        g = _map_grid(res, column)
        d = res.data
        return plot_grid_map(g, lines=(d["x_m"].to_numpy(float), d["y_m"].to_numpy(float)),
                             line_id=d["line"].to_numpy(), path=path,
                             title=f"{column} (nT), cell {g.summary.cell_m:.3g} m")

    jobs: dict[str, Callable[[Any], Any]] = {"map.png": draw_map}
    if res.crossings is not None and res.crossings.n:
        jobs["misties.png"] = lambda p: plot_mistie_histogram(res, path=p)
    jobs["profiles.png"] = lambda p: plot_stacked_profiles(res, column=column, path=p)
    return jobs


def _summary_rows(rep: dict[str, Any], res: LevelResult) -> list[list[Any]]:
    d = res.data
    types = d.groupby("line")["line_type"].first() if len(d) else None
    n_ties = int((types == "tie").sum()) if types is not None else 0
    rows: list[list[Any]] = [
        ["samples", len(d)],
        ["lines / ties", f"{0 if types is None else len(types) - n_ties} / {n_ties}"
                         f" (ties: {(rep.get('ties') or {}).get('source')})"],
        ["levelled column", str(rep.get("value"))],
        ["CRS", f"EPSG:{rep.get('crs')}"],
        ["line spacing (m)", rep.get("line_spacing_m")],
    ]
    lag = rep.get("lag_estimate")
    rows.append(["lag (s)", f"{fmt(rep.get('lag_s'))} ± {fmt(lag['std_s'])} from "
                            f"{lag['n_pairs']} line pairs" if lag else fmt(rep.get("lag_s"))])
    ig = rep.get("igrf")
    rows.append(["IGRF", f"{ig['model']} ({str(ig['date'])}), mean "
                         f"{fmt(ig['mean_nT'], 7)} nT" if ig else "not removed"])
    di = rep.get("diurnal")
    if di:
        cov = di.get("coverage_s") or [None, None]
        rows.append(["diurnal", f"{str(di.get('source'))}: datum "
                                f"{fmt(di.get('datum_nT'), 7)} nT ({str(di.get('datum'))})"
                                f", range {fmt(di.get('range_nT'))} nT, {di.get('n_spikes', 0)} "
                                f"spike(s) removed, {di.get('n_uncovered', 0)} sample(s) not "
                                f"covered; base {html_time(cov[0])} – {html_time(cov[1])}"])
    else:
        rows.append(["diurnal", "not removed (no base station)"])
    ms, mr = rep.get("mistie_std_nT") or {}, rep.get("mistie_robust_std_nT") or {}
    rows += [["crossings", rep.get("n_crossovers")],
             ["mistie std before → after (nT)",
              f"{fmt(ms.get('before'))} → {fmt(ms.get('after'))}"],
             ["robust mistie std before → after (nT, 1.4826 MAD)",
              f"{fmt(mr.get('before'))} → {fmt(mr.get('after'))}"]]
    lev = rep.get("levelling") or {}
    if lev.get("method") not in (None, "none"):
        rows += [["levelling", f"{str(lev['method'])}, {len(lev.get('passes', []))}"
                               f" passes, {lev.get('n_rejected', 0)} crossing(s) rejected, "
                               f"{lev.get('n_networks')} network(s)"],
                 ["effective parameters / degrees of freedom",
                  f"{fmt(lev.get('n_parameters_effective'))} / {fmt(lev.get('dof'))}"]]
    else:
        rows.append(["levelling", "none"])
    dec = rep.get("decorrugation")
    if dec:
        rows.append(["micro-levelling", f"bound {fmt(dec.get('limit_nT'))} nT, std removed per "
                                        f"line median {fmt(dec.get('std_removed_median_nT'))}, "
                                        f"max {fmt(dec.get('std_removed_max_nT'))} nT"])
    return rows


def _line_rows(rep: dict[str, Any]) -> tuple[list[list[Any]], list[str]]:
    lines = rep.get("lines") or []
    mlev = any("mlev_std_removed_nT" in ln for ln in lines)
    header = ["line", "type", "samples", "pieces", "correction mean (nT)",
              "correction std (nT)"] + (["micro-levelling std removed (nT)"] if mlev else [])
    rows = [[ln.get("line"), ln.get("type"), ln.get("n"), ln.get("n_pieces"),
             ln.get("correction_mean_nT"), ln.get("correction_std_nT")]
            + ([ln.get("mlev_std_removed_nT")] if mlev else []) for ln in lines]
    return rows, header


def render_survey_html(rep: dict[str, Any], res: LevelResult, figures: dict[str, bytes],
                       *, title: str | None = None) -> str:
    """The self-contained HTML page of a levelling.

    Parameters
    ----------
    rep : dict
        The levelling report (:meth:`LevelResult.to_report`, as OUT.json holds it).
    res : LevelResult
        The levelling.
    figures : dict
        Figure file name -> PNG bytes.
    title : str, optional
        Page title.

    Returns
    -------
    str
        HTML5 document.
    """
    src = str(rep.get("input") or res.data.attrs.get("source", ""))
    title = title or f"aeromag levelling report: {src}"
    parts = [page_head(title, f"aeromag {__version__}"), "<h2>Summary</h2>"]
    for w in res.warnings:
        parts.append(f"<p class='warn'>Warning: {html.escape(w)}</p>")
    parts.append(html_table(_summary_rows(rep, res), ["step", "value"]))
    parts.append("<p class='small'>Misties are line minus tie at each crossing, in the "
                 "anomaly before levelling and after it; the effective parameters are the "
                 "trace of the levelling's hat matrix (datum and trend prior included), and "
                 "few degrees of freedom mean the levelled misties show the fit rather than "
                 "the level error left.</p>")
    for name, png in figures.items():
        parts.append(figure_html(name, png, SURVEY_FIGURES.get(name, name)))
    passes = (rep.get("levelling") or {}).get("passes") or []
    if passes:
        parts.append("<h2>Levelling passes</h2>")
        parts.append(html_table([[i + 1, p["kind"], p["mistie_std_nT"],
                                  p["mistie_robust_std_nT"], p["n_rejected"]]
                                 for i, p in enumerate(passes)],
                                ["pass", "weights", "mistie std (nT)",
                                 "robust mistie std (nT)", "crossings rejected"]))
    rows, header = _line_rows(rep)
    if rows:
        parts.append("<h2>Lines</h2>")
        parts.append(html_table(rows, header))
    parts.append("</body></html>")
    return "\n".join(parts)


def write_survey_report(res: LevelResult, out_dir: str | Path, *,
                        report: dict[str, Any] | None = None) -> list[Path]:
    """Write the levelling's figures and ``report.html`` into a folder.

    Parameters
    ----------
    res : LevelResult
        The levelling (:func:`aeromag.level`).
    out_dir : path-like
        Folder (created when missing).
    report : dict, optional
        The report as OUT.json holds it (default ``res.to_report()``).

    Returns
    -------
    list of Path
        The files written: the PNG figures the data allow, then ``report.html``.

    Raises
    ------
    InputError
        The folder cannot be created.
    """
    from ..plot.grid_map import figure_png

    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"{out}: cannot create the report folder ({exc.strerror}); give "
                         "another --plot folder") from None
    rep = report if report is not None else res.to_report()
    column = "tmi_mlev" if "tmi_mlev" in res.data.columns else "tmi_lev"
    pngs: dict[str, bytes] = {}
    written: list[Path] = []
    for name, draw in _figures(res, column).items():
        try:
            fig = draw(None)
        except InputError as exc:  # e.g. too few lines to grid: the page says so
            log.warning("%s: %s not drawn: %s", out, name, exc)
            continue
        pngs[name] = figure_png(fig)
        with atomic_path(out / name) as tmp:
            tmp.write_bytes(pngs[name])
        written.append(out / name)
    page = out / "report.html"
    with atomic_path(page) as tmp:
        tmp.write_text(render_survey_html(rep, res, pngs), encoding="utf-8")
    written.append(page)
    return written

