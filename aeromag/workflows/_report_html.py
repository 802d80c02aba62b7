"""Pieces of the report's HTML page (:func:`aeromag.workflows.report.render_html`).

Style sheet, cell formatting, tables, table times, the FOM rows (manoeuvres in kept segments
first) and the sentence saying where the headline comes from.
"""

from __future__ import annotations

import datetime as dt
import html
from pathlib import Path
from typing import Any

import numpy as np

from ..compensation.report import is_epoch
from ..compensation.report_types import ExtendedSummary, HeadlineCheck, HeldOut
from ..qc.fom_types import FomSummary

CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:2em auto;
max-width:1100px;color:#222;padding:0 1em}
h1{font-size:1.5em}h2{font-size:1.2em;margin-top:1.6em;border-bottom:1px solid #ccc}
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:.25em .6em;
text-align:right}th{background:#f3f3f3}td:first-child,th:first-child{text-align:left}
tr.dropped td{background:#fdecea}
figure{margin:1em 0}figure img{max-width:100%;border:1px solid #eee}
figcaption{font-size:.9em;color:#555}.note{color:#a60}.na{color:#a60;font-weight:600}
.small{font-size:.9em;color:#555}
.warn{color:#b00;font-weight:600;border-left:4px solid #b00;padding-left:.5em}
"""


def fmt(v: Any, digits: int = 4) -> str:
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


def html_table(rows: list[list[Any]], header: list[str], classes: list[str] | None = None) -> str:
    h = "".join(f"<th>{html.escape(c)}</th>" for c in header)
    cls = classes or [""] * len(rows)
    body = "".join((f"<tr class='{c}'>" if c else "<tr>")
                   + "".join(f"<td>{fmt(v)}</td>" for v in r) + "</tr>"
                   for r, c in zip(rows, cls, strict=True))
    return f"<table><thead><tr>{h}</tr></thead><tbody>{body}</tbody></table>"


def html_time(t: float | None) -> str:
    """A time for the tables: UTC when epoch seconds, else seconds."""
    if t is None or not np.isfinite(t):
        return "–"
    if is_epoch(t):
        return dt.datetime.fromtimestamp(t, dt.UTC).strftime("%H:%M:%S")
    return f"{t:.1f}"


def fom_rows(fom: FomSummary) -> list[list[Any]]:
    """FOM table rows: the manoeuvres in kept segments first, all manoeuvres beside them."""
    def reduction(before: Any, after: Any) -> float | None:
        return float(before / after) if before is not None and after else None

    kb, ka = fom.fom_kept_before_nT, fom.fom_kept_after_nT
    rows: list[list[Any]] = [
        ["FOM before (nT, sum of 12 p-p of band-passed mag)", kb, fom.fom_before_nT],
        ["FOM after (nT, sum of 12 p-p of band-passed mag - mag_tl)", ka, fom.fom_after_nT],
        ["FOM reduction (before / after)", reduction(kb, ka), fom.fom_reduction]]
    if fom.fom_truth_nT is not None:
        rows.insert(2, ["FOM of the true interference (nT)", fom.fom_kept_truth_nT,
                        fom.fom_truth_nT])
    return rows


def headline_words(check: HeadlineCheck | None) -> str:
    """Where the headline comes from and how it was checked, in one sentence."""
    if check is None:
        return "Headline as the compensation recorded it."
    src = Path(check.recorded_in or "OUT.json").name
    if not check.compared:
        return (f"Headline computed from this log's columns; {src} holds no metrics to"
                " compare it with.")
    verdict = ("agrees" if check.agree else "DISAGREES")
    return (f"Headline computed from this log's columns (mag, mag_tl, segment_kept); it"
            f" {verdict} with {src} (largest relative difference"
            f" {check.max_relative_difference or 0.0:.2g}, tolerance"
            f" {check.relative_tolerance or 0.0:g}; sample counts compared exactly).")


def extended_html(ext: ExtendedSummary | None) -> str:
    """The section of an extended fit (``--reference``, ``--extra``): held-out errors, extras.

    Parameters
    ----------
    ext : ExtendedSummary or None
        The report's ``extended`` block (:mod:`aeromag.compensation.extended`).

    Returns
    -------
    str
        HTML ("" without an extended fit).
    """
    if ext is None:
        return ""
    held = ext.held_out or HeldOut()
    rows = [["target", f"mag − {ext.reference} (full band, intercept)"
             if ext.reference else "band-passed mag (self-fit)"],
            ["estimator", ext.estimator], ["regularisation", ext.param],
            ["held-out residual std, with the extras (nT)", held.residual_std_nT],
            ["held-out residual std, TL terms only (nT)", held.tl_only_residual_std_nT],
            ["rows left out (no value in an extra or the reference)", ext.rows_left_out]]
    if ext.dropped_extras:
        rows.append(["extras dropped (constant or empty)", ", ".join(ext.dropped_extras)])
    mlp = ext.mlp_training
    if mlp:
        rows.append(["network kept", mlp.get("kept")])
        rows.append(["network / linear held-out std, last 20 % (nT)",
                     f"{fmt(mlp.get('mlp_std_nT'))} / {fmt(mlp.get('linear_std_nT'))}"])
    parts = ["<h2>Beyond the 16 terms</h2>", html_table(rows, ["", "value"]),
             f"<p class='small'>{html.escape(str(held.method or ''))}</p>"]
    contrib = {c["name"]: c for c in held.contributions}
    extras = ext.extras
    if extras:
        parts.append(html_table(
            [[e["name"], e["coef_nT_per_unit"], e["center"], e["scale"],
              contrib.get(e["name"], {}).get("increase_nT"),
              contrib.get(e["name"], {}).get("increase_pct")] for e in extras],
            ["extra", "coefficient (nT per unit)", "mean", "std",
             "held-out increase without it (nT)", "increase (%)"]))
    return "".join(parts)


def page_head(title: str, subtitle: str) -> str:
    """The start of a self-contained page: doctype, title, the style sheet, the heading."""
    return (f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
            f"<title>{html.escape(title)}</title><style>{CSS}</style></head><body>"
            f"<h1>{html.escape(title)}</h1><p class='small'>{html.escape(subtitle)}</p>")


def figure_html(name: str, png: bytes | str | Path, caption: str) -> str:
    """A PNG embedded as a base64 ``data:`` URI, with its caption (the page stays one file)."""
    import base64

    data = png if isinstance(png, bytes | bytearray) else Path(png).read_bytes()
    b64 = base64.b64encode(data).decode("ascii")
    cap = html.escape(caption)
    return (f"<figure id='{html.escape(Path(name).stem)}'><img alt='{cap}' "
            f"src='data:image/png;base64,{b64}'><figcaption>{cap}</figcaption></figure>")
