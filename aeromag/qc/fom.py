"""Figure of Merit: peak-to-peak band-passed interference in the 12 manoeuvres of a box.

For every manoeuvre found by :func:`aeromag.qc.maneuvers.detect_maneuvers`, the peak-to-peak
amplitude of the field band-passed in the fitting band within the manoeuvre interval; a box's
FOM is the sum over its 12 (heading, manoeuvre) pairs.  "After" is ``mag - mag_tl`` (the
residual without the pipeline's final low-pass, as MagNav.jl and deinterf users compute it).
See ``docs/qc.md``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd

from .._core.filters import sampling_rate
from .._core.runs import run_bounds
from ..errors import InputError
from .fom_types import FomBox, FomManeuver, FomSummary, FomTableRow
from .labels import kept_mask, segment_labels
from .maneuvers import CARDINALS, MANEUVERS, ManeuverResult, detect_maneuvers
from .noise import band_passed_blocks

__all__ = ["fom_not_applicable", "fom_rows", "fom_summary", "fom_table", "not_applicable"]


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
    fs_hz: float | None = None,
    total_field: np.ndarray | None = None,
    total_field_name: str = "|flux|",
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
    fs_hz : float, optional
        Sampling rate [Hz] when the caller knows it (default: from ``time``).
    total_field : ndarray, shape (n,), optional
        The uncompensated field per row [nT] instead of the ``before`` column: the total
        field the compensation used (e.g. the fluxgate magnitude,
        :func:`aeromag.qc.total_field.prepared_total_field`).
    total_field_name : str
        Its name in ``attrs["fields"]``.

    Returns
    -------
    DataFrame
        One row per manoeuvre: ``id``, ``box``, ``heading_leg``, ``heading``, ``maneuver``,
        ``t_start``, ``t_end`` [s], ``ptp_before_nT``, ``ptp_after_nT`` (and ``ptp_truth_nT``):
        peak-to-peak [nT] within the manoeuvre of the field band-passed once (zero-phase,
        per continuous stretch, each dropped segment on its own); ``kept`` (every sample of
        the manoeuvre lies in a kept segment; True when the log has no ``segment_kept``).
        ``attrs["fields"]`` names the field of each.
    """
    if maneuvers is None:
        maneuvers = detect_maneuvers(data, max_gap_s=max_gap_s, **detect_kw)
    t = data["time"].to_numpy(dtype=np.float64)
    fs = sampling_rate(t) if fs_hz is None else fs_hz  # once for the two or three fields
    if total_field is not None:
        b = np.asarray(total_field, dtype=np.float64)
        if b.shape != t.shape:
            raise InputError(f"total_field has {b.size} values for {len(t)} rows")
    elif before in data.columns:
        b = data[before].to_numpy(dtype=np.float64)
    elif {"flux_x", "flux_y", "flux_z"} <= set(data.columns):
        b = np.linalg.norm(data[["flux_x", "flux_y", "flux_z"]].to_numpy(dtype=np.float64),
                           axis=1)
    else:
        raise InputError(f"FOM needs a {before!r} column (or the fluxgate)")
    b_name = (total_field_name if total_field is not None
              else before if before in data.columns else "|flux|")
    # Each field read a block of rows at a time when it is filtered (band_passed_blocks): no
    # full-length copy of a field or of mag - mag_tl (16 MB each at 2e6 rows).
    cols: dict[str, Callable[[int, int], np.ndarray]] = {"before": lambda s, e: b_field[s:e]}
    b_field = b
    if after is None and "mag_tl" in data.columns:
        tl = data["mag_tl"].to_numpy(dtype=np.float64)
        cols["after"] = lambda s, e: b_field[s:e] - tl[s:e]
        a_name = f"{b_name} - mag_tl"
    else:
        a_name = "mag_comp" if after is None else after
        if a_name not in data.columns:
            raise InputError(f"FOM needs a {a_name!r} column; run 'aeromag compensate' first")
        a_col = data[a_name].to_numpy(dtype=np.float64)
        cols["after"] = lambda s, e: a_col[s:e]
    fields = {"before": b_name, "after": a_name}
    if truth and truth in data.columns:
        tr_col = data[truth].to_numpy(dtype=np.float64)
        cols["truth"] = lambda s, e: tr_col[s:e]
        fields["truth"] = truth
    del b
    mid = maneuvers.labels["maneuver_id"].to_numpy()
    tab = maneuvers.table[["id", "box", "heading_leg", "heading", "maneuver", "t_start",
                           "t_end"]].copy()
    a, b, ids = run_bounds(mid)  # each manoeuvre is one run of samples
    pos = np.searchsorted(ids, tab["id"].to_numpy())
    found = (pos < len(ids)) & (ids[np.minimum(pos, max(len(ids) - 1, 0))] ==
                                tab["id"].to_numpy()) if len(ids) else np.zeros(len(tab), bool)
    ab = np.column_stack([a, b]).ravel()  # [a, b) of each run: reduceat, even entries
    ab_in = ab[:-1] if len(ab) and ab[-1] == len(t) else ab
    keep = kept_mask(data)
    seg = segment_labels(data, copy=False)

    def dropped(s: int, e: int) -> np.ndarray:
        """Each dropped segment filtered alone (band_passed only looks for changes)."""
        g = seg[s:e]
        return np.where((g < 0) | keep[s:e], -1, g)

    for name, make in cols.items():
        xf = band_passed_blocks(make, len(t), t, band_hz, order, max_gap_s, split=dropped,
                                fs_hz=fs)
        ptp = np.full(len(tab), np.nan)
        if len(ids):
            # [a, b) of each run only (reduceat over a alone ran on to the next start); a
            # last run ending at the log's end needs no stop index (reduceat runs to the end):
            # no NaN-padded copy of the field (16 MB at 2e6 rows).
            with np.errstate(invalid="ignore"):
                hi = np.fmax.reduceat(xf, ab_in)[::2]  # NaN (filter edges) ignored, as pandas
                lo = np.fmin.reduceat(xf, ab_in)[::2]
            ptp[found] = (hi - lo)[pos[found]]
        tab[f"ptp_{name}_nT"] = ptp
        del xf
    allk = np.ones(len(tab), dtype=bool)
    if len(ids):
        allk[found] = np.logical_and.reduceat(np.r_[keep, True], ab)[::2][pos[found]]
    tab["kept"] = allk  # every sample of the manoeuvre in a kept segment
    tab = tab.reset_index(drop=True)
    tab.attrs["fields"] = fields
    return tab


def fom_summary(table: pd.DataFrame) -> FomSummary:
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
    FomSummary
        ``applicable`` (a complete box exists), ``reason`` (why not, else None), ``boxes``
        (per box, :class:`~aeromag.qc.fom_types.FomBox`: ``box``, ``n_maneuvers``,
        ``complete``, ``missing`` (``"W pitch"``...), ``fom_before_nT``, ``fom_after_nT``...
        for complete boxes), ``complete_boxes``, ``fom_before_nT``/``fom_after_nT`` (mean
        over complete boxes [nT], None when none), ``fom_reduction`` (before / after),
        ``fom_kept_before_nT``/``fom_kept_after_nT`` (the same over only the complete boxes
        whose 12 manoeuvres all lie in kept segments, ``kept_boxes``; None when there is none,
        ``kept_applicable`` False; ``kept_reason`` names each box left out, e.g. "box 1: 3 of
        its 12 manoeuvres in dropped segments"; ``kept_definition``; ``n_maneuvers_kept``),
        ``n_maneuvers`` and ``per_maneuver`` (heading, manoeuvre -> mean peak-to-peak over the
        complete boxes, :class:`~aeromag.qc.fom_types.FomManeuver`), ``fields`` (the field
        each ``ptp_*_nT`` is of) and ``definition`` (the words for it).
    """
    cols = [c for c in ("before", "after", "truth") if f"ptp_{c}_nT" in table.columns]
    boxes = _box_entries(table, cols)
    complete = [e.box for e in boxes if e.complete]
    out = FomSummary(applicable=bool(complete), reason=None, boxes=boxes,
                     complete_boxes=complete, n_maneuvers=len(table))
    fields = table.attrs.get("fields") or {}
    if fields:
        out.fields = {f"ptp_{k}_nT": v for k, v in fields.items()}
        out.definition = (
            "ptp_X_nT: peak-to-peak [nT] within one manoeuvre of field X band-passed once in"
            " band_hz (zero-phase Butterworth per continuous stretch, each dropped segment on"
            " its own; windows clipped at line boundaries), X as in 'fields'"
            " (after = mag - mag_tl: the residual without the final low-pass); fom_X_nT: their"
            " sum over the 12 manoeuvres of a complete box, averaged over complete boxes")
    for c in cols:
        vals = [getattr(e, f"fom_{c}_nT") for e in boxes if e.complete]
        out.set(f"fom_{c}_nT", float(np.mean(vals)) if vals else None)
    if "kept" in table.columns:
        _kept_fom(out, cols)
        out.n_maneuvers_kept = int(table["kept"].sum())
    fa, fb = out.fom_after_nT, out.fom_before_nT
    out.fom_reduction = float(fb / fa) if fa and fb is not None else None
    sub = table[table["box"].isin(complete)]
    if len(sub):
        agg = sub.groupby(["heading_leg", "maneuver"])[[f"ptp_{c}_nT" for c in cols]].mean()
        out.per_maneuver = [
            FomManeuver.from_dict({"heading": CARDINALS[int(h)], "maneuver": m,
                                   **{k: float(v) for k, v in row.items()}})
            for (h, m), row in agg.iterrows()
        ]
    if not complete:
        worst = min(boxes, key=lambda e: len(e.missing)) if boxes else None
        out.reason = not_applicable(
            f"no complete calibration box: {len(boxes)} box(es) found, the most complete"
            f" (box {worst.box}) lacks {', '.join(worst.missing)}" if worst else
            "no manoeuvre found")
    return out


def fom_rows(table: pd.DataFrame) -> list[FomTableRow]:
    """The rows of a FOM table as typed rows (the QC block's ``table``).

    Parameters
    ----------
    table : DataFrame
        Output of :func:`fom_table`.

    Returns
    -------
    list of FomTableRow
        One per manoeuvre, numpy scalars as Python numbers.
    """
    return [FomTableRow.from_dict({k: (v.item() if hasattr(v, "item") else v)
                                   for k, v in rec.items()})
            for rec in table.to_dict(orient="records")]


def _kept_fom(out: FomSummary, cols: list[str]) -> None:
    """The kept FOM: the mean over the complete boxes whose manoeuvres are all kept.

    A box with some of its 12 manoeuvres in dropped segments has no kept FOM (the sum of the
    rest is not a sum of 12 peak-to-peak values): its ``fom_kept_X_nT`` become None and its
    ``kept_reason`` says how many manoeuvres were dropped.  Edits ``out`` and its boxes in
    place.

    Parameters
    ----------
    out : FomSummary
        The summary; its boxes are those of :func:`_box_entries` (with ``n_maneuvers_kept``).
    cols : list of str
        The fields (``"before"``, ``"after"``, ``"truth"``).

    Sets ``fom_kept_X_nT`` [nT] (None when no box is wholly kept), ``kept_applicable``,
    ``kept_boxes``, ``kept_reason`` (None when every complete box is wholly kept) and
    ``kept_definition``.
    """
    kept, excluded = [], []
    for e in out.boxes:
        e.set("kept_reason", None)
        if not e.complete:
            continue
        n_dropped = e.n_maneuvers - (e.n_maneuvers_kept or 0)
        if n_dropped == 0:
            kept.append(e)
            continue
        e.kept_reason = (f"box {e.box}: {n_dropped} of its {e.n_maneuvers} manoeuvres"
                         " in dropped segments")
        excluded.append(e.kept_reason)
        for c in cols:
            e.set(f"fom_kept_{c}_nT", None)
    kept_boxes = [e.box for e in kept]
    out.kept_applicable = bool(kept)
    out.kept_boxes = kept_boxes
    for c in cols:
        vals = [getattr(e, f"fom_kept_{c}_nT") for e in kept]
        out.set(f"fom_kept_{c}_nT", float(np.mean(vals)) if vals else None)
    reason = None
    if excluded and kept_boxes:
        reason = (f"FOM of the kept segments over box{'es' if len(kept_boxes) > 1 else ''}"
                  f" {', '.join(map(str, kept_boxes))} only, not applicable to"
                  f" {'; '.join(excluded)}.")
    elif excluded:
        reason = ("FOM of the kept segments not applicable: no complete box has all its"
                  f" manoeuvres in kept segments ({'; '.join(excluded)}).")
    out.set("kept_reason", reason)
    out.kept_definition = (
        "fom_kept_X_nT: the same FOM averaged over only the complete boxes whose 12"
        " manoeuvres all lie wholly in kept segments (kept_boxes); a box with any manoeuvre"
        " in a dropped segment has no kept FOM (boxes[].kept_reason, boxes[].dropped names"
        " them): the FOM without the dropped faults")


def _box_entries(table: pd.DataFrame, cols: list[str]) -> list[FomBox]:
    """Per-box entries of :func:`fom_summary`, boxes ascending, rows in table order.

    Plain arrays sliced per box: a pandas group per box (each copying the table's ``attrs``)
    cost 0.17 s for the 417 boxes of a 1e6-row log.  The sums are ``np.nansum`` over the same
    values in the same order, so the numbers are bitwise those of a groupby.
    """
    if table.empty:
        return []
    box = table["box"].to_numpy()
    order = np.argsort(box, kind="stable")  # groups of one box, table order inside
    ub, first = np.unique(box[order], return_index=True)
    bounds = np.r_[first, len(order)]
    heads = table["heading_leg"].to_numpy()[order].tolist()
    mans = np.asarray(table["maneuver"], dtype=object)[order].tolist()
    ptp = {c: table[f"ptp_{c}_nT"].to_numpy(dtype=np.float64)[order] for c in cols}
    kept = (table["kept"].to_numpy(dtype=bool)[order] if "kept" in table.columns else None)
    boxes = []
    for j, b in enumerate(ub.tolist()):
        a, z = int(bounds[j]), int(bounds[j + 1])
        pairs = set(zip(heads[a:z], mans[a:z], strict=True))
        missing = [f"{CARDINALS[h]} {m}" for h in range(4) for m in MANEUVERS
                   if (h, m) not in pairs]
        e = FomBox(box=int(b), n_maneuvers=z - a, complete=not missing, missing=missing)
        for c in cols:
            e.set(f"fom_{c}_nT", float(np.nansum(ptp[c][a:z])) if not missing else None)
        if kept is not None:
            k = kept[a:z]
            e.n_maneuvers_kept = int(k.sum())
            e.dropped = [f"{CARDINALS[int(heads[i])]} {mans[i]}"
                         for i in range(a, z) if not kept[i]]
            for c in cols:
                e.set(f"fom_kept_{c}_nT", float(np.nansum(ptp[c][a:z][k]))
                      if not missing else None)
        boxes.append(e)
    return boxes


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


def fom_not_applicable(why: str) -> FomSummary:
    """The ``fom`` block of a flight without a complete box: no numbers, the reason.

    Parameters
    ----------
    why : str
        What is missing (e.g. "no pitch/roll/yaw manoeuvre found").

    Returns
    -------
    FomSummary
        ``applicable`` False, ``reason``, ``fom_before_nT``/``fom_after_nT`` None (the
        not-applicable kind, ``from_table`` False).
    """
    return FomSummary(applicable=False, reason=not_applicable(why), from_table=False)
