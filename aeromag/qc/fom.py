"""Figure of Merit: peak-to-peak band-passed interference in the 12 manoeuvres of a box.

For every manoeuvre found by :func:`aeromag.qc.maneuvers.detect_maneuvers`, the peak-to-peak
amplitude of the field band-passed in the fitting band within the manoeuvre interval; a box's
FOM is the sum over its 12 (heading, manoeuvre) pairs.  "After" is ``mag - mag_tl`` (the
residual without the pipeline's final low-pass, as MagNav.jl and deinterf users compute it).
See ``docs/qc.md``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from .._core.runs import run_bounds
from ..errors import InputError
from .maneuvers import CARDINALS, MANEUVERS, ManeuverResult, detect_maneuvers
from .noise import band_passed

__all__ = ["fom_not_applicable", "fom_summary", "fom_table", "not_applicable"]


def fom_table(
    data: pd.DataFrame,
    maneuvers: ManeuverResult | None = None,
    *,
    band_hz: tuple[float, float] = (0.1, 0.9),
    order: int = 4,
    before: str = "mag",
    after: str | None = None,
    truth: str | None = "truth_mag_tl",
    max_gap_s: float | None = None,
    **detect_kw: Any,
) -> pd.DataFrame:
    """Peak-to-peak amplitude of the band-passed field in every manoeuvre, before and after.

    Parameters
    ----------
    data : DataFrame
        Compensated log (``time`` [s], ``before`` and ``after`` columns [nT]).
    maneuvers : ManeuverResult, optional
        Detected manoeuvres; detected here (:func:`aeromag.maneuvers.detect_maneuvers`, with
        ``detect_kw``) when omitted.
    band_hz : (float, float)
        Pass band applied before taking peak-to-peak values [Hz].
    order : int
        Butterworth order.
    before : str
        Column of the uncompensated field [nT].  When absent the fluxgate magnitude is used
        (as the pipeline does).
    after : str, optional
        Column of the compensated field [nT].  Default: ``before - mag_tl`` (the residual
        without the pipeline's final low-pass, as MagNav.jl and deinterf compute the FOM),
        ``mag_comp`` only when the log has no ``mag_tl``.
    truth : str or None
        Column of the true interference [nT] (simulations); ignored when absent.
    max_gap_s : float, optional
        Longest time step inside a stretch [s].

    Returns
    -------
    DataFrame
        One row per manoeuvre: ``id``, ``box``, ``heading_leg``, ``heading``, ``maneuver``,
        ``t_start``, ``t_end`` [s], ``ptp_before_nT``, ``ptp_after_nT`` (and ``ptp_truth_nT``):
        peak-to-peak [nT] within the manoeuvre of the field band-passed once (zero-phase,
        per continuous stretch).  ``attrs["fields"]`` names the field of each.
    """
    if maneuvers is None:
        maneuvers = detect_maneuvers(data, max_gap_s=max_gap_s, **detect_kw)
    t = data["time"].to_numpy(dtype=np.float64)
    if before in data.columns:
        b = data[before].to_numpy(dtype=np.float64)
    elif {"flux_x", "flux_y", "flux_z"} <= set(data.columns):
        b = np.linalg.norm(data[["flux_x", "flux_y", "flux_z"]].to_numpy(dtype=np.float64),
                           axis=1)
    else:
        raise InputError(f"FOM needs a {before!r} column (or the fluxgate)")
    b_name = before if before in data.columns else "|flux|"
    if after is None and "mag_tl" in data.columns:
        after_x = b - data["mag_tl"].to_numpy(dtype=np.float64)
        a_name = f"{b_name} - mag_tl"
    else:
        a_name = "mag_comp" if after is None else after
        if a_name not in data.columns:
            raise InputError(f"FOM needs a {a_name!r} column; run 'aeromag compensate' first")
        after_x = data[a_name].to_numpy(dtype=np.float64)
    cols = {"before": b, "after": after_x}
    fields = {"before": b_name, "after": a_name}
    if truth and truth in data.columns:
        cols["truth"] = data[truth].to_numpy(dtype=np.float64)
        fields["truth"] = truth
    mid = maneuvers.labels["maneuver_id"].to_numpy()
    tab = maneuvers.table[["id", "box", "heading_leg", "heading", "maneuver", "t_start",
                           "t_end"]].copy()
    a, b, ids = run_bounds(mid)  # each manoeuvre is one run of samples
    pos = np.searchsorted(ids, tab["id"].to_numpy())
    found = (pos < len(ids)) & (ids[np.minimum(pos, max(len(ids) - 1, 0))] ==
                                tab["id"].to_numpy()) if len(ids) else np.zeros(len(tab), bool)
    for name, x in cols.items():
        xf = band_passed(x, t, band_hz, order, max_gap_s)
        ptp = np.full(len(tab), np.nan)
        if len(ids):
            with np.errstate(invalid="ignore"):
                hi = np.fmax.reduceat(xf, a)  # NaN (filter edges) ignored, as pandas does
                lo = np.fmin.reduceat(xf, a)
            ptp[found] = (hi - lo)[pos[found]]
        tab[f"ptp_{name}_nT"] = ptp
    tab = tab.reset_index(drop=True)
    tab.attrs["fields"] = fields
    return tab


def fom_summary(table: pd.DataFrame) -> dict[str, Any]:
    """Box FOM (sum of the 12 peak-to-peak values) before/after (and truth), complete boxes only.

    A FOM is the sum over the 12 manoeuvres of a calibration box (pitch, roll and yaw on each
    of the four headings); a box missing any of them has no FOM (a survey flight has none),
    and then the summary says why instead of giving a number.

    Parameters
    ----------
    table : DataFrame
        Output of :func:`fom_table`.

    Returns
    -------
    dict
        ``applicable`` (a complete box exists), ``reason`` (why not, else None), ``boxes``
        (per box: ``box``, ``n_maneuvers``, ``complete``, ``missing`` (``"W pitch"``...),
        ``fom_before_nT``, ``fom_after_nT``... for complete boxes), ``complete_boxes``,
        ``fom_before_nT``/``fom_after_nT`` (mean over complete boxes, None when none),
        ``fom_reduction`` (before / after), ``n_maneuvers`` and ``per_maneuver`` (heading,
        manoeuvre -> mean peak-to-peak over the complete boxes), ``fields`` (the field each
        ``ptp_*_nT`` is of) and ``definition`` (the words for it).
    """
    cols = [c for c in ("before", "after", "truth") if f"ptp_{c}_nT" in table.columns]
    boxes = []
    for b, g in table.groupby("box"):
        pairs = set(zip(g["heading_leg"], g["maneuver"], strict=True))
        missing = [f"{CARDINALS[h]} {m}" for h in range(4) for m in MANEUVERS
                   if (h, m) not in pairs]
        e: dict[str, Any] = {"box": int(b), "n_maneuvers": len(g), "complete": not missing,
                             "missing": missing}
        for c in cols:
            e[f"fom_{c}_nT"] = float(np.nansum(g[f"ptp_{c}_nT"])) if not missing else None
        boxes.append(e)
    complete = [e["box"] for e in boxes if e["complete"]]
    out: dict[str, Any] = {"applicable": bool(complete), "reason": None, "boxes": boxes,
                           "complete_boxes": complete, "n_maneuvers": len(table)}
    fields = table.attrs.get("fields") or {}
    if fields:
        out["fields"] = {f"ptp_{k}_nT": v for k, v in fields.items()}
        out["definition"] = (
            "ptp_X_nT: peak-to-peak [nT] within one manoeuvre of field X band-passed once in"
            " band_hz (zero-phase Butterworth per continuous stretch), X as in 'fields'"
            " (after = mag - mag_tl: the residual without the final low-pass); fom_X_nT: their"
            " sum over the 12 manoeuvres of a complete box, averaged over complete boxes")
    for c in cols:
        vals = [e[f"fom_{c}_nT"] for e in boxes if e["complete"]]
        out[f"fom_{c}_nT"] = float(np.mean(vals)) if vals else None
    fa = out.get("fom_after_nT")
    fb = out.get("fom_before_nT")
    out["fom_reduction"] = float(fb / fa) if fa and fb is not None else None
    sub = table[table["box"].isin(complete)]
    out["per_maneuver"] = []
    if len(sub):
        agg = sub.groupby(["heading_leg", "maneuver"])[[f"ptp_{c}_nT" for c in cols]].mean()
        out["per_maneuver"] = [
            {"heading": CARDINALS[int(h)], "maneuver": m,
             **{k: float(v) for k, v in row.items()}}
            for (h, m), row in agg.iterrows()
        ]
    if not complete:
        worst = min(boxes, key=lambda e: len(e["missing"])) if boxes else None
        out["reason"] = not_applicable(
            f"no complete calibration box: {len(boxes)} box(es) found, the most complete"
            f" (box {worst['box']}) lacks {', '.join(worst['missing'])}" if worst else
            "no manoeuvre found")
    return out


def not_applicable(why: str) -> str:
    """The sentence the report and JSON give when there is no FOM.

    Parameters
    ----------
    why : str
        What is missing.

    Returns
    -------
    str
    """
    return (f"FOM not applicable: {why}. A FOM needs a complete calibration box (pitch, roll"
            " and yaw manoeuvres on each of the four headings); survey flights have none.")


def fom_not_applicable(why: str) -> dict[str, Any]:
    """The ``fom`` block of a flight without a complete box: no numbers, the reason.

    Parameters
    ----------
    why : str
        What is missing (e.g. "no pitch/roll/yaw manoeuvre found").

    Returns
    -------
    dict
        ``applicable`` False, ``reason``, ``fom_before_nT``/``fom_after_nT`` None.
    """
    return {"applicable": False, "reason": not_applicable(why), "fom_before_nT": None,
            "fom_after_nT": None, "fom_reduction": None, "boxes": [], "complete_boxes": [],
            "n_maneuvers": 0, "per_maneuver": []}
