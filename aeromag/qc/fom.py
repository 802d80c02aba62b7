"""Figure of Merit: peak-to-peak band-passed interference in the 12 manoeuvres of a box.

For every manoeuvre found by :func:`aeromag.qc.maneuvers.detect_maneuvers`, the peak-to-peak
amplitude of the field band-passed in the fitting band within the manoeuvre interval; a box's
FOM is the sum over its 12 (heading, manoeuvre) pairs.  See ``docs/qc.md``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from ..errors import InputError
from .maneuvers import CARDINALS, ManeuverResult, detect_maneuvers
from .noise import band_passed

__all__ = ["fom_summary", "fom_table"]


def fom_table(
    data: pd.DataFrame,
    maneuvers: ManeuverResult | None = None,
    *,
    band_hz: tuple[float, float] = (0.1, 0.9),
    order: int = 4,
    before: str = "mag",
    after: str = "mag_comp",
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
    before, after : str
        Columns of the uncompensated and compensated fields [nT].  When ``before`` is absent
        the fluxgate magnitude is used (as the pipeline does).
    truth : str or None
        Column of the true interference [nT] (simulations); ignored when absent.
    max_gap_s : float, optional
        Longest time step inside a stretch [s].

    Returns
    -------
    DataFrame
        One row per manoeuvre: ``id``, ``box``, ``heading_leg``, ``heading``, ``maneuver``,
        ``t_start``, ``t_end`` [s], ``ptp_before_nT``, ``ptp_after_nT`` (and ``ptp_truth_nT``).
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
    if after not in data.columns:
        raise InputError(f"FOM needs a {after!r} column; run 'aeromag compensate' first")
    cols = {"before": b, "after": data[after].to_numpy(dtype=np.float64)}
    if truth and truth in data.columns:
        cols["truth"] = data[truth].to_numpy(dtype=np.float64)
    mid = maneuvers.labels["maneuver_id"].to_numpy()
    tab = maneuvers.table[["id", "box", "heading_leg", "heading", "maneuver", "t_start",
                           "t_end"]].copy()
    inm = mid >= 0
    for name, x in cols.items():
        xf = band_passed(x, t, band_hz, order, max_gap_s)
        s = pd.Series(xf[inm]).groupby(mid[inm])
        ptp = (s.max() - s.min()).reindex(tab["id"]).to_numpy()
        tab[f"ptp_{name}_nT"] = ptp
    return tab.reset_index(drop=True)


def fom_summary(table: pd.DataFrame) -> dict[str, Any]:
    """Box FOM (sum of the 12 peak-to-peak values) before/after (and truth).

    Parameters
    ----------
    table : DataFrame
        Output of :func:`fom_table`.

    Returns
    -------
    dict
        ``boxes`` (per box: ``box``, ``n_maneuvers``, ``complete``, ``fom_before_nT``,
        ``fom_after_nT``...), ``fom_before_nT``/``fom_after_nT`` (mean over complete boxes, or
        over all boxes when none is complete), ``fom_reduction`` (before / after),
        ``complete_boxes`` and ``per_maneuver`` (12-entry table ``heading``/``maneuver`` ->
        mean peak-to-peak over the boxes used).
    """
    cols = [c for c in ("before", "after", "truth") if f"ptp_{c}_nT" in table.columns]
    boxes = []
    for b, g in table.groupby("box"):
        pairs = set(zip(g["heading_leg"], g["maneuver"], strict=True))
        e: dict[str, Any] = {"box": int(b), "n_maneuvers": len(g), "complete": len(pairs) == 12}
        for c in cols:
            e[f"fom_{c}_nT"] = float(np.nansum(g[f"ptp_{c}_nT"]))
        boxes.append(e)
    complete = [e["box"] for e in boxes if e["complete"]]
    use = complete or [e["box"] for e in boxes]
    out: dict[str, Any] = {"boxes": boxes, "complete_boxes": complete,
                           "n_maneuvers": len(table)}
    for c in cols:
        vals = [e[f"fom_{c}_nT"] for e in boxes if e["box"] in use]
        out[f"fom_{c}_nT"] = float(np.mean(vals)) if vals else None
    fa = out.get("fom_after_nT")
    fb = out.get("fom_before_nT")
    out["fom_reduction"] = float(fb / fa) if fa and fb is not None else None
    sub = table[table["box"].isin(use)]
    if len(sub):
        agg = sub.groupby(["heading_leg", "maneuver"])[[f"ptp_{c}_nT" for c in cols]].mean()
        out["per_maneuver"] = [
            {"heading": CARDINALS[int(h)], "maneuver": m,
             **{k: float(v) for k, v in row.items()}}
            for (h, m), row in agg.iterrows()
        ]
    else:
        out["per_maneuver"] = []
    if not complete:
        out["note"] = "no complete box of 12 manoeuvres: the FOM is over the manoeuvres found"
    return out
