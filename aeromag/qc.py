"""Compensation quality control: Figure of Merit, improvement ratio, residuals, noise, VIF, CV.

Every number here is computed from a compensated log (the output of ``aeromag compensate``:
``mag``, ``mag_tl``, ``mag_comp``, ``segment``, ``segment_kept``) and, when available, its JSON
report.  See ``docs/qc.md`` for the definitions.

* **FOM** (Figure of Merit): the sum over the 12 manoeuvres of a calibration box (pitch, roll
  and yaw on each of the four headings) of the peak-to-peak amplitude of the band-passed
  signal within the manoeuvre; *before* on ``mag``, *after* on ``mag_comp``, and *truth* on a
  ``truth_mag_tl`` column when the log has one (simulations).  The box FOM is reported per box,
  and the headline value is the mean over complete boxes.
* **Improvement ratio**: std of band-passed ``mag`` over std of band-passed ``mag_comp``.
* **Residual std** per segment and per heading: std of band-passed ``mag_comp`` [nT].
* **Noise**: band-limited std before/after and the fourth-difference noise estimate.
* **Fit diagnostics**: condition number (raw and with unit-norm columns) and variance
  inflation factors of the band-passed design matrix over the kept segments.
* **Leave-one-segment-out CV**: each kept segment's residual under the model fitted on all the
  other kept segments, computed from the per-segment normal equations (no refiltering).
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from .compensate import (
    CompensationConfig,
    SegmentStats,
    compensation_metrics,
    prepare,
    segment_normal_equations,
)
from .errors import AeromagError, InputError
from .filters import butter_sos, filter_stretches, sampling_rate, trim_mask
from .maneuvers import CARDINALS, ManeuverResult, detect_maneuvers
from .segments import find_stretches
from .tolles_lawson import TERMS_16

log = logging.getLogger(__name__)

#: Divisor turning the std of a fourth difference into the std of white noise: sqrt(70).
FOURTH_DIFF_NORM = float(np.sqrt(70.0))


@dataclass
class QCResult:
    """Quality-control results of one compensated log.

    Attributes
    ----------
    metrics : dict
        JSON-ready metrics (see :func:`quality_metrics`).
    fom : DataFrame or None
        Per-manoeuvre peak-to-peak table (:func:`fom_table`), None when no manoeuvre was found.
    maneuvers : ManeuverResult or None
        Detected legs and manoeuvres.
    segments : DataFrame
        Per-segment residual std, kept flag and cross-validated residual.
    notes : list of str
        Why something could not be computed.
    """

    metrics: dict[str, Any]
    fom: pd.DataFrame | None
    maneuvers: ManeuverResult | None
    segments: pd.DataFrame
    notes: list[str] = field(default_factory=list)


# --------------------------------------------------------------------------- helpers
def config_from_report(report: dict[str, Any] | None) -> CompensationConfig:
    """The :class:`CompensationConfig` recorded in a report (defaults for what is missing).

    Parameters
    ----------
    report : dict or None
        A compensation report (``OUT.json``) or model file.

    Returns
    -------
    CompensationConfig
    """
    if not report:
        return CompensationConfig()
    names = {f.name for f in dataclasses.fields(CompensationConfig)}
    kw = {k: v for k, v in (report.get("config") or {}).items() if k in names}
    if "band_hz" not in kw and report.get("band_hz"):
        kw["band_hz"] = report["band_hz"]
    return CompensationConfig(**kw)


def band_passed(
    x: np.ndarray, time_s: np.ndarray, band_hz: tuple[float, float], order: int = 4,
    max_gap_s: float | None = None, trim_s: float = 0.0, fs_hz: float | None = None,
) -> np.ndarray:
    """Zero-phase band-pass of a series, per continuous finite stretch.

    Parameters
    ----------
    x : ndarray, shape (n,)
        Samples [nT].
    time_s : ndarray, shape (n,)
        Times [s].
    band_hz : (float, float)
        Pass band [Hz].
    order : int
        Butterworth order.
    max_gap_s : float, optional
        A longer time step starts a new stretch [s].
    trim_s : float
        Samples closer than this to a stretch end become NaN [s].
    fs_hz : float, optional
        Sampling rate [Hz] when known (default: from ``time_s``).

    Returns
    -------
    ndarray, shape (n,)
        Band-passed samples [nT], NaN where not filterable.
    """
    xv = np.asarray(x, dtype=np.float64)
    t = np.asarray(time_s, dtype=np.float64)
    st = find_stretches(t, np.isfinite(xv), max_gap_s)
    fs = sampling_rate(t) if fs_hz is None else fs_hz
    sos = butter_sos("bandpass", band_hz, fs, order)
    out = filter_stretches(xv[None, :], st, sos, axis=1)[0]
    if trim_s > 0:
        out[~trim_mask(st, t, trim_s)] = np.nan
    return out


def fourth_difference_noise(x: np.ndarray, time_s: np.ndarray,
                            max_gap_s: float | None = None) -> float:
    """White-noise level from the fourth difference: ``std(d4 x) / sqrt(70)`` [nT].

    Differences spanning a time gap or a NaN are ignored.

    Parameters
    ----------
    x : ndarray, shape (n,)
        Samples [nT].
    time_s : ndarray, shape (n,)
        Times [s].
    max_gap_s : float, optional
        Longest time step inside a stretch [s].

    Returns
    -------
    float
        Noise std [nT] (NaN when fewer than 5 contiguous samples).
    """
    xv = np.asarray(x, dtype=np.float64)
    st = find_stretches(np.asarray(time_s, dtype=np.float64), np.isfinite(xv), max_gap_s)
    if len(xv) < 5:
        return float("nan")
    # Moments of the fourth difference block by block, in one pass (no n-sized temporaries):
    # sums of (d - K) and (d - K)^2 about K, the first block's mean, so the variance has no
    # cancellation (the fourth difference of a log is centred near 0 anyway).
    n = len(xv) - 4
    step = 1 << 16
    cnt = 0
    s1 = 0.0
    s2 = 0.0
    shift = None
    for a in range(0, n, step):
        b = min(n, a + step)
        seg = xv[a:b + 4]
        d4 = np.diff(np.where(np.isfinite(seg), seg, 0.0), n=4)
        same = (st[a + 4:b + 4] == st[a:b]) & (st[a + 4:b + 4] >= 0)
        d = d4 if same.all() else d4[same]
        if d.size == 0:
            continue
        if shift is None:
            shift = float(d.mean())
        d -= shift
        cnt += d.size
        s1 += float(d.sum())
        s2 += float(d @ d)
    if cnt == 0:
        return float("nan")
    var = max(s2 / cnt - (s1 / cnt) ** 2, 0.0)
    return float(np.sqrt(var) / FOURTH_DIFF_NORM)


# --------------------------------------------------------------------------- FOM
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


# --------------------------------------------------------------------------- residuals
def grouped_std(x: np.ndarray, groups: np.ndarray) -> dict[int, float]:
    """Std of ``x`` per non-negative group label, ignoring NaN (vectorised bincount).

    Parameters
    ----------
    x : ndarray, shape (n,)
        Samples.
    groups : ndarray of int, shape (n,)
        Group labels (negative = none).

    Returns
    -------
    dict
        ``{group: std}``.
    """
    g = np.asarray(groups)
    ok = np.isfinite(x) & (g >= 0)
    if not ok.any():
        return {}
    if ok.all():  # no copies of the whole log
        gk, xk = g.astype(np.int64, copy=False), np.asarray(x)
    else:
        gk = g[ok].astype(np.int64, copy=False)
        xk = x[ok]
    top = int(gk.max())
    if top <= 4 * gk.size + 1024:  # small labels: histograms, no sort
        n = np.bincount(gk, minlength=top + 1)
        ids = np.flatnonzero(n)
        s1 = np.bincount(gk, xk, minlength=top + 1)[ids]
        s2 = np.bincount(gk, xk * xk, minlength=top + 1)[ids]
        n = n[ids]
    else:
        ids, inv = np.unique(gk, return_inverse=True)
        n = np.bincount(inv)
        s1 = np.bincount(inv, xk)
        s2 = np.bincount(inv, xk * xk)
    mean = s1 / n
    std = np.sqrt(np.maximum(s2 / n - mean * mean, 0.0))
    return {int(i): float(s) for i, s in zip(ids, std, strict=True)}


def _segment_labels(data: pd.DataFrame) -> np.ndarray:
    if "segment" not in data.columns:
        return np.full(len(data), -1, dtype=np.int64)
    s = pd.to_numeric(data["segment"], errors="coerce").to_numpy(dtype=np.float64)
    return np.where(np.isfinite(s), s, -1).astype(np.int64)


def _kept(data: pd.DataFrame) -> np.ndarray:
    if "segment_kept" not in data.columns:
        return np.ones(len(data), dtype=bool)
    k = data["segment_kept"]
    if k.dtype == object or pd.api.types.is_string_dtype(k):
        return k.astype(str).str.strip().str.lower().isin(["true", "1", "yes"]).to_numpy()
    return k.fillna(False).to_numpy(dtype=bool)


# --------------------------------------------------------------------------- fit diagnostics
def variance_inflation(gram: np.ndarray) -> np.ndarray:
    """Variance inflation factors of the columns of a (zero-mean) design matrix.

    ``VIF_j = [R^-1]_jj`` with ``R`` the correlation matrix, here the Gram matrix scaled to
    unit diagonal (band-passed columns have zero mean).

    Parameters
    ----------
    gram : ndarray, shape (k, k)
        ``A.T @ A``.

    Returns
    -------
    ndarray, shape (k,)
        VIF per column (1 = orthogonal to the others; above 10 = strongly collinear).
    """
    d = np.sqrt(np.maximum(np.diag(gram), 1e-300))
    r = gram / d[:, None] / d[None, :]
    try:
        return np.diag(np.linalg.inv(r)).copy()
    except np.linalg.LinAlgError:
        return np.full(len(d), np.inf)


def loso_cv(stats: SegmentStats, kept: np.ndarray, ridge: float = 0.0) -> pd.DataFrame:
    """Leave-one-segment-out residuals from per-segment normal equations.

    For each kept segment ``j`` the model is refitted on the other kept segments,
    ``c_j = (G - G_j)^-1 (b - b_j)``, and its band-passed residual is
    ``sqrt((yy_j - 2 c_j.b_j + c_j.G_j.c_j) / n_j)``.  Dropped segments get the residual under
    the model fitted on all kept segments (they were left out anyway).

    Parameters
    ----------
    stats : SegmentStats
        Per-segment Gram matrices, right-hand sides, ``yy`` and sizes.
    kept : ndarray of bool, shape (m,)
        Segments used in the fit.
    ridge : float
        Relative ridge parameter of the fit.

    Returns
    -------
    DataFrame
        ``segment``, ``n``, ``kept``, ``fit_residual_std_nT`` (in-sample) and
        ``cv_residual_std_nT`` (out of sample).
    """
    G = stats.gram[kept].sum(axis=0)
    b = stats.rhs[kept].sum(axis=0)
    Gi = np.where(kept[:, None, None], G - stats.gram, G)
    bi = np.where(kept[:, None], b - stats.rhs, b)
    k = G.shape[0]

    def solve(g: np.ndarray, r: np.ndarray) -> np.ndarray:
        d = np.sqrt(np.maximum(np.diagonal(g, axis1=-2, axis2=-1), 1e-300))
        gs = g / d[..., :, None] / d[..., None, :] + ridge * np.eye(k)
        rhs = (r / d)[..., None]
        try:
            z = np.linalg.solve(gs, rhs)[..., 0]
        except np.linalg.LinAlgError:
            z = (np.linalg.pinv(gs) @ rhs)[..., 0]
        return z / d

    c_all = solve(G, b)
    c_cv = solve(Gi, bi)

    def resid(c: np.ndarray) -> np.ndarray:
        c = np.broadcast_to(c, stats.rhs.shape)
        sse = stats.yy - 2 * np.einsum("mk,mk->m", c, stats.rhs) + np.einsum(
            "mk,mkj,mj->m", c, stats.gram, c)
        return np.sqrt(np.maximum(sse, 0.0) / stats.n)

    return pd.DataFrame({"segment": stats.ids.astype(int), "n": stats.n.astype(int),
                         "kept": kept, "fit_residual_std_nT": resid(c_all),
                         "cv_residual_std_nT": resid(c_cv)})


def fit_diagnostics(
    data: pd.DataFrame, report: dict[str, Any] | None = None,
    cfg: CompensationConfig | None = None,
) -> tuple[dict[str, Any], pd.DataFrame]:
    """Condition number, VIF and leave-one-segment-out CV of the fit on a compensated log.

    The band-passed per-segment normal equations are rebuilt from the log with the
    configuration of the report (:func:`aeromag.compensate.segment_normal_equations`) using the
    log's ``segment`` labels and ``segment_kept`` flags.

    Parameters
    ----------
    data : DataFrame
        Compensated log with the fluxgate, ``mag``, ``segment`` and ``segment_kept``.
    report : dict, optional
        Its JSON report (terms, config).
    cfg : CompensationConfig, optional
        Overrides the report's configuration.

    Returns
    -------
    diagnostics : dict
        ``condition_number``, ``condition_number_scaled``, ``vif`` (term -> VIF), ``max_vif``,
        ``cv_residual_std_nT``, ``fit_residual_std_nT``, ``cv_ratio`` (CV / in-sample).
    segments : DataFrame
        Output of :func:`loso_cv`.
    """
    cfg = cfg or config_from_report(report)
    terms = tuple((report or {}).get("terms") or TERMS_16)
    fit_terms = tuple(x for x in terms if x != "bias")
    base = data.drop(columns=[c for c in ("mag_tl", "mag_comp") if c in data.columns])
    prep = prepare(base, cfg)
    seg = _segment_labels(data)
    if (seg >= 0).any():
        prep.segment = seg
    stats = segment_normal_equations(prep, fit_terms, cfg)
    kept_samples = _kept(data)
    kept_ids = np.unique(seg[kept_samples & (seg >= 0)]) if (seg >= 0).any() else stats.ids
    kept = np.isin(stats.ids, kept_ids)
    if not kept.any():
        kept = np.ones(len(stats.ids), dtype=bool)
    return diagnostics_from_stats(stats, kept, fit_terms, cfg.ridge)


def diagnostics_from_stats(
    stats: SegmentStats, kept: np.ndarray, fit_terms: tuple[str, ...], ridge: float = 0.0,
) -> tuple[dict[str, Any], pd.DataFrame]:
    """Condition numbers, VIF and leave-one-segment-out CV from per-segment normal equations.

    Parameters
    ----------
    stats : SegmentStats
        Per-segment band-passed normal equations.
    kept : ndarray of bool, shape (m,)
        Segments used in the fit.
    fit_terms : tuple of str
        Names of the fitted terms.
    ridge : float
        Relative ridge parameter of the fit.

    Returns
    -------
    diagnostics : dict
        See :func:`fit_diagnostics`.
    segments : DataFrame
        Output of :func:`loso_cv`.
    """
    G = stats.gram[kept].sum(axis=0)
    ev = np.linalg.eigvalsh(G)
    d = np.sqrt(np.maximum(np.diag(G), 1e-300))
    evs = np.linalg.eigvalsh(G / d[:, None] / d[None, :])
    vif = variance_inflation(G)
    segs = loso_cv(stats, kept, ridge)
    nk = segs.loc[segs["kept"], "n"].to_numpy()

    def pooled(col: str) -> float:
        v = segs.loc[segs["kept"], col].to_numpy()
        return float(np.sqrt(np.sum(v**2 * nk) / max(nk.sum(), 1)))

    cv = pooled("cv_residual_std_nT")
    fit = pooled("fit_residual_std_nT")
    diag = {
        "terms": list(fit_terms),
        "condition_number": float(np.sqrt(ev[-1] / ev[0])) if ev[0] > 0 else float("inf"),
        "condition_number_scaled": float(np.sqrt(evs[-1] / evs[0])) if evs[0] > 0
        else float("inf"),
        "vif": {t: float(v) for t, v in zip(fit_terms, vif, strict=True)},
        "max_vif": float(np.max(vif)),
        "n_segments_kept": int(kept.sum()),
        "fit_residual_std_nT": fit,
        "cv_residual_std_nT": cv,
        "cv_ratio": cv / fit if fit > 0 else None,
    }
    return diag, segs


# --------------------------------------------------------------------------- everything
def compute_qc(
    data: pd.DataFrame,
    report: dict[str, Any] | None = None,
    cfg: CompensationConfig | None = None,
    *,
    maneuvers: ManeuverResult | None = None,
    maneuver_column: str | None = None,
    fit: bool = True,
    detect: bool = True,
    base_metrics: dict[str, Any] | None = None,
    comp_bp: np.ndarray | None = None,
    segment: np.ndarray | None = None,
    fs_hz: float | None = None,
) -> QCResult:
    """All quality-control metrics of a compensated log.

    Parameters
    ----------
    data : DataFrame
        Compensated log (``time``, ``mag`` or fluxgate, ``mag_comp``, ``mag_tl``, ``segment``,
        ``segment_kept``; attitude when available).
    report : dict, optional
        Its JSON report (``OUT.json``): configuration, terms, fit.
    cfg : CompensationConfig, optional
        Overrides the report's configuration (band, order, gaps).
    maneuvers : ManeuverResult, optional
        Already detected manoeuvres.
    maneuver_column : str, optional
        Column naming the manoeuvre of each sample (instead of detection).
    fit : bool
        Compute the fit diagnostics (VIF, condition number, CV); needs the fluxgate.
    base_metrics : dict, optional
        :func:`aeromag.compensate.compensation_metrics` already computed for this log (the
        report's ``metrics``), so they are not computed twice.
    detect : bool
        Detect manoeuvres and compute the FOM (a calibration flight); False skips it unless
        ``maneuvers`` or ``maneuver_column`` is given (surveys have no manoeuvres, and the
        detection costs more than the compensation on long logs).
    comp_bp : ndarray, shape (n,), optional
        ``mag_comp`` already band-passed in ``band_hz`` with stretch edges NaN (the pipeline
        passes the array its metrics used); filtered here when not given.
    segment : ndarray of int, shape (n,), optional
        Segment id per sample (default: the ``segment`` column).
    fs_hz : float, optional
        Sampling rate [Hz] when known.

    Returns
    -------
    QCResult
    """
    cfg = cfg or config_from_report(report)
    notes: list[str] = []
    t = data["time"].to_numpy(dtype=np.float64)
    if "mag_comp" not in data.columns:
        raise InputError("the log has no 'mag_comp' column; run 'aeromag compensate' first")
    if "mag" in data.columns:
        mag = data["mag"].to_numpy(dtype=np.float64)
    else:
        mag = np.linalg.norm(data[["flux_x", "flux_y", "flux_z"]].to_numpy(dtype=np.float64),
                             axis=1)
    comp = data["mag_comp"].to_numpy(dtype=np.float64)
    band = cfg.band_hz
    if base_metrics is None:
        st = find_stretches(t, np.isfinite(mag) & np.isfinite(comp), cfg.max_gap_s)
        base = compensation_metrics(mag, comp, t, st, cfg)
    else:
        base = base_metrics
    metrics: dict[str, Any] = {
        "band_hz": list(band),
        "improvement_ratio": base["improvement_ratio"],
        "residual_std_nT": base["residual_std_nT"],
        "std_before_nT": base["std_before_nT"],
    }
    if comp_bp is None:
        trim = (0.5 / band[0]) if cfg.trim_s is None else cfg.trim_s
        comp_bp = band_passed(comp, t, band, cfg.order, cfg.max_gap_s, trim_s=trim,
                              fs_hz=fs_hz)
    seg = _segment_labels(data) if segment is None else np.asarray(segment)
    seg_std = grouped_std(comp_bp, seg)
    metrics["residual_std_by_segment_nT"] = {str(k): v for k, v in seg_std.items()}
    # Noise levels.
    raw_after = mag - data["mag_tl"].to_numpy(dtype=np.float64) if "mag_tl" in data.columns \
        else comp
    metrics["noise"] = {
        "band_hz": list(band),
        "band_std_before_nT": base["std_before_nT"],
        "band_std_after_nT": base["residual_std_nT"],
        "fourth_difference_before_nT": fourth_difference_noise(mag, t, cfg.max_gap_s),
        "fourth_difference_after_nT": fourth_difference_noise(raw_after, t, cfg.max_gap_s),
    }
    # Manoeuvres, heading legs, FOM.
    fom = None
    if maneuvers is None and not detect and maneuver_column is None:
        notes.append("manoeuvre detection skipped (no FOM): run 'aeromag report' or --fom")
    elif maneuvers is None:
        try:
            maneuvers = detect_maneuvers(data, maneuver_column=maneuver_column,
                                         max_gap_s=cfg.max_gap_s)
        except AeromagError as exc:
            notes.append(f"manoeuvre detection failed: {exc}")
    if maneuvers is not None:
        hl = maneuvers.labels["heading_leg"].to_numpy()
        metrics["residual_std_by_heading_nT"] = {
            CARDINALS[k]: v for k, v in grouped_std(comp_bp, hl).items()}
        metrics["maneuvers"] = {
            "method": maneuvers.method, "n_legs": len(maneuvers.legs),
            "n_maneuvers": len(maneuvers.table), "complete_boxes": maneuvers.complete_boxes,
            "heading_offset_deg": maneuvers.heading_offset_deg, "notes": maneuvers.notes}
        if len(maneuvers.table):
            fom = fom_table(data, maneuvers, band_hz=band, order=cfg.order,
                            max_gap_s=cfg.max_gap_s)
            summary = fom_summary(fom)
            summary["table"] = _records(fom)
            metrics["fom"] = summary
        else:
            notes.append("no pitch/roll/yaw manoeuvre found: no FOM (not a calibration flight?)")
            metrics["fom"] = None
    else:
        metrics["fom"] = None
    segs = pd.DataFrame({"segment": list(seg_std), "residual_std_nT": list(seg_std.values())})
    if fit and {"flux_x", "flux_y", "flux_z"} <= set(data.columns):
        try:
            diag, cv = fit_diagnostics(data, report, cfg)
            metrics["fit"] = diag
            segs = cv.merge(segs, on="segment", how="outer")
        except AeromagError as exc:
            notes.append(f"fit diagnostics failed: {exc}")
    metrics["notes"] = notes
    for n in notes:
        log.info("qc: %s", n)
    return QCResult(metrics, fom, maneuvers, segs, notes)


def quality_metrics(
    data: pd.DataFrame, report: dict[str, Any] | None = None,
    cfg: CompensationConfig | None = None, **kw: Any,
) -> dict[str, Any]:
    """JSON-ready QC metrics of a compensated log (the ``qc`` block of a report).

    Parameters
    ----------
    data : DataFrame
        Compensated log.
    report : dict, optional
        Its report.
    cfg : CompensationConfig, optional
        Configuration (default: the report's).
    **kw
        Passed to :func:`compute_qc`.

    Returns
    -------
    dict
        ``improvement_ratio``, ``residual_std_nT``, ``std_before_nT``, ``fom`` (box FOM
        before/after [nT], per-box and per-manoeuvre tables, or None),
        ``residual_std_by_segment_nT``, ``residual_std_by_heading_nT``, ``noise``, ``fit``
        (condition numbers, VIF, leave-one-segment-out CV), ``maneuvers``, ``notes``.
    """
    return compute_qc(data, report, cfg, **kw).metrics


def _records(df: pd.DataFrame) -> list[dict[str, Any]]:
    out = []
    for rec in df.to_dict(orient="records"):
        out.append({k: (v.item() if hasattr(v, "item") else v) for k, v in rec.items()})
    return out
