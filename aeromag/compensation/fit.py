"""Fit the TL model on a log: per-segment fits, PCA screening, one refit on the kept segments."""

from __future__ import annotations

import datetime as _dt
import logging
from typing import Any

import numpy as np
import pandas as pd

from .. import __version__
from .._core.fit_diagnostics import diagnostics_from_stats
from .._core.lstsq import solve_normal
from ..errors import FitError, InputError
from .config import CompensationConfig, _config_dict
from .model import TLModel
from .normal import _residual_std, _scaled_cond, segment_normal_equations
from .prepare import Prepared, prepare
from .result import CompensationResult
from .screening import (
    RULE,
    ScreenResult,
    _material,
    _readmit,
    masked_outlier,
    own_fit_excess,
    pca_screen,
    shrunk_segment_fits,
)
from .segments import segment_counts
from .terms import design_matrix, parse_terms

log = logging.getLogger(__name__)


# --------------------------------------------------------------------------- fitting
def fit_model(
    df: pd.DataFrame, cfg: CompensationConfig | None = None, *, source: str | None = None,
    prep: Prepared | None = None,
) -> CompensationResult:
    """Fit the TL model on a log: per-segment fits, PCA screening, refit on kept segments.

    Parameters
    ----------
    df : DataFrame
        Calibration or survey log with canonical columns.
    cfg : CompensationConfig, optional
        Options (defaults as on the command line).
    source : str, optional
        File name quoted in errors and the report.
    prep : Prepared, optional
        Arrays already prepared from ``df``.

    Returns
    -------
    CompensationResult
        ``data`` is None; ``model`` carries the report as its metadata.
    """
    cfg = cfg or CompensationConfig()
    prep = prep or prepare(df, cfg, source=source)
    terms = parse_terms(cfg.terms)
    fit_terms = tuple(t for t in terms if t != "bias")
    if not fit_terms:
        raise InputError("--terms: the bias alone cannot be fitted in a band; add terms")
    stats = segment_normal_equations(prep, fit_terms, cfg)
    m = len(stats.ids)
    if m == 0:
        raise FitError(
            f"{prep.source}: every segment is too short to fit ({len(stats.too_short)} segment(s));"
            " use a longer --segment-seconds or check the line column"
        )
    for sid, cnt in stats.too_short.items():
        log.warning("%s: segment %d too short to fit (%d usable samples): left out",
                    prep.source, sid, cnt)
    kept = np.ones(m, dtype=bool)
    screen: ScreenResult | None = None
    notes: list[str] = []
    iterations = 0
    seg_coef = np.full((m, len(fit_terms)), np.nan)
    readmitted = np.zeros(m, dtype=bool)
    screened = cfg.screen and m >= cfg.min_segments
    if cfg.screen and not screened:
        notes.append(
            f"only {m} segment(s) could be fitted (screening needs {cfg.min_segments}):"
            " fitted without screening"
        )
    if screened:
        for iterations in range(1, cfg.max_iter + 1):  # noqa: B007 - reported below
            G = stats.gram[kept].sum(axis=0)
            b = stats.rhs[kept].sum(axis=0)
            pooled, _, _ = solve_normal(G, b, max(cfg.ridge, 1e-9))
            col_ms = np.diag(G) / stats.n[kept].sum()
            seg_coef = shrunk_segment_fits(stats.gram, stats.rhs, stats.n.astype(float), pooled,
                                           col_ms, cfg.shrink)
            screen = pca_screen(seg_coef, variance=cfg.pca_variance,
                                quantile=cfg.screen_quantile)
            r_pool = _residual_std(stats, pooled)
            own = own_fit_excess(r_pool, _residual_std(stats, seg_coef))
            excess = r_pool / np.median(r_pool[kept])
            own_ratio = own / max(float(np.median(own[kept])), 1e-300)
            out = ~screen.kept & _material(r_pool, own, kept, cfg)
            masked = masked_outlier(r_pool, own, screen.kept, kept,
                                    residual_ratio=cfg.inlier_excess,
                                    own_ratio=cfg.inlier_own_excess,
                                    min_excess_nT=cfg.min_excess_nT)
            if masked is not None:
                out[masked] = True
            new = ~out
            if new.sum() < max(3, (m + 1) // 2):
                # Never let the "main cluster" be a minority: keep the closest half.
                order = np.argsort(screen.distance)
                new = np.zeros(m, dtype=bool)
                new[order[: max(3, (m + 1) // 2)]] = True
                notes.append("screening would drop most segments: kept the closest half")
            if np.array_equal(new, kept):
                break
            kept = new
        else:
            notes.append(f"screening did not settle within {cfg.max_iter} rounds")
        kept, readmitted = _readmit(stats, kept, cfg)
    else:
        # Not screened: each segment's own (shrunk) fit is still recorded for the report.
        G0 = stats.gram.sum(axis=0)
        pooled0, _, _ = solve_normal(G0, stats.rhs.sum(axis=0), max(cfg.ridge, 1e-9))
        seg_coef = shrunk_segment_fits(stats.gram, stats.rhs, stats.n.astype(float), pooled0,
                                       np.diag(G0) / stats.n.sum(), cfg.shrink)
    G = stats.gram[kept].sum(axis=0)
    b = stats.rhs[kept].sum(axis=0)
    try:
        coef_fit, cond, cond_s = solve_normal(G, b, cfg.ridge)
    except FitError as exc:
        raise FitError(f"{prep.source}: {exc}") from None
    if cfg.ridge <= 0 and not cond_s <= cfg.max_condition:
        raise FitError(
            f"{prep.source}: the fit is ill-conditioned (scaled condition number {cond_s:.3g}"
            f" > {cfg.max_condition:.3g}): the attitude varies too little to separate the TL"
            " terms (no manoeuvres?); calibrate on a flight with pitch/roll/yaw manoeuvres and"
            " apply it with --model, or regularise with --ridge 1e-3, or fit fewer --terms"
        )
    coef = np.zeros(len(terms))
    idx = [terms.index(t) for t in fit_terms]
    coef[idx] = coef_fit
    if "bias" in terms:
        # The bias is invisible in the band: fix it on the unfiltered kept samples.
        inkeep = np.isin(prep.segment, stats.ids[kept]) & prep.valid
        A = design_matrix(prep.flux[inkeep], prep.time[inkeep], fit_terms,
                          stretch=prep.stretch[inkeep])
        coef[terms.index("bias")] = float(np.mean(prep.mag[inkeep] - A @ coef_fit))
    resid = _residual_std(stats, coef_fit)
    seg_cond = _scaled_cond(stats.gram)

    diag, cv_segs = diagnostics_from_stats(stats, kept, fit_terms, cfg.ridge)
    cv_resid = cv_segs["cv_residual_std_nT"].to_numpy()
    n_fit = int(stats.n[kept].sum())
    sse = float(stats.yy[kept].sum() - 2 * coef_fit @ b + coef_fit @ G @ coef_fit)
    # "n" counts the segment's samples in the log (as when a saved model is applied);
    # "n_fit" those its fit used (valid, filterable, filter edges trimmed).
    all_ids, all_n = segment_counts(prep.segment)
    n_of = dict(zip(all_ids.tolist(), all_n.tolist(), strict=True))
    segments = []
    for j, sid in enumerate(stats.ids):
        entry: dict[str, Any] = {
            "id": int(sid),
            "n": int(n_of.get(int(sid), 0)),
            "n_fit": int(stats.n[j]),
            "kept": bool(kept[j]),
            "scores": screen.scores[j].tolist() if screen is not None else None,
            "residual_std": float(resid[j]),
            "cv_residual_std": float(cv_resid[j]),
            "condition_number": float(seg_cond[j]),
            "coef": [float(c) for c in seg_coef[j]],
        }
        if screen is not None:
            entry["robust_distance"] = float(screen.distance[j])
            entry["pca_outlier"] = bool(not screen.kept[j])
            entry["residual_excess"] = float(excess[j])
            entry["own_fit_excess"] = float(own_ratio[j])
            entry["readmitted"] = bool(readmitted[j])
        segments.append(entry)
    for sid, cnt in sorted(stats.too_short.items()):
        segments.append({"id": sid, "n": int(n_of.get(int(sid), 0)), "n_fit": cnt,
                         "kept": False, "scores": None,
                         "residual_std": None, "condition_number": None,
                         "reason": "too short to fit"})
    segments.sort(key=lambda e: e["id"])
    if prep.line_of_segment:
        for e in segments:
            e["line"] = prep.line_of_segment.get(e["id"])
    screening: dict[str, Any] = {
        "enabled": bool(screened),
        "requested": bool(cfg.screen),
        "method": "pca+mcd",
        "rule": RULE,
        "pca_variance_threshold": cfg.pca_variance,
        "quantile": cfg.screen_quantile,
        "shrink": cfg.shrink,
        "min_excess": cfg.min_excess,
        "min_excess_nT": cfg.min_excess_nT,
        "iterations": iterations,
        "n_segments": m,
        "n_kept": int(kept.sum()),
        "dropped": [int(s) for s in stats.ids[~kept]],
        "readmitted": [int(s) for s in stats.ids[readmitted]],
        "notes": notes + (screen.notes if screen is not None else []),
    }
    if screen is not None:
        screening.update(screen.to_dict())
        screening["notes"] = notes + screen.notes
    report: dict[str, Any] = {
        "aeromag_version": __version__,
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "source": prep.source,
        "terms": list(terms),
        "coef": [float(c) for c in coef],
        "scale_nT": 50000.0,
        "band_hz": list(cfg.band_hz),
        "filter_order": cfg.order,
        "sampling_rate_hz": prep.fs,
        "mag_from_fluxgate": prep.mag_from_flux,
        "fit": {
            "n_samples": n_fit,
            "n_segments_fitted": int(kept.sum()),
            "condition_number": cond,
            "condition_number_scaled": cond_s,
            "ridge": cfg.ridge,
            "residual_std_nT": float(np.sqrt(max(sse, 0.0) / max(n_fit, 1))),
            "vif": diag["vif"],
            "max_vif": diag["max_vif"],
            "cv_residual_std_nT": diag["cv_residual_std_nT"],
            "cv_ratio": diag["cv_ratio"],
        },
        "segments": segments,
        "screening": screening,
        "config": _config_dict(cfg),
    }
    model = TLModel(terms, coef, meta={k: v for k, v in report.items()
                                       if k not in ("terms", "coef", "scale_nT")})
    table = pd.DataFrame(segments)
    return CompensationResult(None, model, report, screen, table)

