"""The extended fit's steps: screening as the TL fit screens, then the fit with extras / reference.

:func:`extended_outcome` is what :func:`aeromag.compensation.fit.fit_outcome` runs when the
configuration has ``reference`` or ``extras`` (:mod:`aeromag.compensation.extended` for the
method).  The PCA screening is the TL fit's, on the band-passed TL terms of each segment (with
a self-fit, the same pass builds the extras' normal equations: the TL block of them is exactly
the TL fit's); the kept segments are then fitted with the extras, and against the reference
over the full band when one is given.
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np
import pandas as pd

from .._core.fit_diagnostics import diagnostics_from_stats
from .._core.lstsq import scaled_condition
from .._core.stretches import find_stretches
from ..errors import InputError
from .config import CompensationConfig
from .decimation import fit_arrays
from .extended import (
    ExtendedFit,
    ExtendedInputs,
    ExtendedModel,
    cv_linear,
    extended_inputs,
    reference_normal_equations,
    sub_stats,
    train_mlp,
)
from .fit import FitOutcome, fit_result, screen_stats, solve_fit
from .normal import SegmentStats, segment_normal_equations, segment_residual_std
from .prepare import Prepared
from .result import CompensationResult
from .terms import design_matrix, parse_terms

log = logging.getLogger(__name__)

__all__ = ["extended_inputs_for", "extended_outcome", "extended_result"]


def extended_inputs_for(df: pd.DataFrame, cfg: CompensationConfig,
                        source: str) -> ExtendedInputs | None:
    """The extras and reference of ``cfg`` read from ``df`` (None when it asks for neither).

    Parameters
    ----------
    df : DataFrame
        The log.
    cfg : CompensationConfig
        ``extras`` and ``reference``.
    source : str
        File name for messages.

    Returns
    -------
    ExtendedInputs or None
        None also when every extra was dropped and there is no reference (the TL fit runs).
    """
    if not cfg.extras and cfg.reference is None:
        return None
    inputs = extended_inputs(df, cfg.extras, cfg.reference, source)
    if not inputs.names and inputs.reference is None:
        log.warning("%s: no usable --extra: the 16-term fit runs alone", source)
        return None
    return inputs


def extended_result(prep: Prepared, cfg: CompensationConfig,
                    inputs: ExtendedInputs) -> CompensationResult:
    """:func:`aeromag.compensation.fit.fit_result` with the extended fit.

    Parameters
    ----------
    prep, cfg : Prepared, CompensationConfig
        The log's arrays and the run's options.
    inputs : ExtendedInputs
        From :func:`extended_inputs_for`.

    Returns
    -------
    CompensationResult
        ``data`` is None; ``model`` carries the report as its metadata and the extended part
        as ``model.extended``; the report has an ``extended`` block.
    """
    fit, ext = extended_outcome(prep, cfg, inputs)
    return fit_result(prep, cfg, fit=fit, extended=ext.model)


def _select(stats: SegmentStats, mask: np.ndarray) -> SegmentStats:
    return SegmentStats(stats.ids[mask], stats.n[mask], stats.gram[mask], stats.rhs[mask],
                        stats.yy[mask], stats.too_short, stats.min_samples)


def _held_out(stats: SegmentStats, k_tl: int, names: tuple[str, ...], intercept: bool,
              estimator: str) -> tuple:
    """The fit with every column, the TL-only one, and each extra left out in turn."""
    off = 1 if intercept else 0
    full = cv_linear(stats, intercept=intercept, estimator=estimator)
    base = list(range(off + k_tl))
    tl = cv_linear(sub_stats(stats, base), intercept=intercept, estimator=estimator) \
        if names else full
    contrib = []
    for j, name in enumerate(names):
        cols = [c for c in range(stats.gram.shape[1]) if c != off + k_tl + j]
        r = cv_linear(sub_stats(stats, cols), intercept=intercept, estimator=estimator,
                      param=full.param)  # at the full fit's regularisation
        inc = r.cv_std_nT - full.cv_std_nT
        contrib.append({"name": name, "held_out_std_without_nT": r.cv_std_nT,
                        "increase_nT": inc,
                        "increase_pct": 100.0 * inc / full.cv_std_nT if full.cv_std_nT > 0
                        else float("nan")})
    return full, tl, contrib


def extended_outcome(prep: Prepared, cfg: CompensationConfig, inputs: ExtendedInputs):
    """Screen, then fit with extras and/or against a reference (see the module docstring).

    Parameters
    ----------
    prep : Prepared
        Arrays of the log.
    cfg : CompensationConfig
        Options (``reference``, ``extras``, ``estimator``).
    inputs : ExtendedInputs
        The extras and reference read from the log
        (:func:`aeromag.compensation.extended.extended_inputs`).

    Returns
    -------
    outcome : FitOutcome
        As the TL fit's (screening and diagnostics of the TL terms), with the extended fit's TL
        coefficients.
    extended : ExtendedFit
    """
    terms = parse_terms(cfg.terms)
    fit_terms = tuple(t for t in terms if t != "bias")
    if not fit_terms:
        raise InputError("terms=bias: the bias alone cannot be fitted; add terms")
    k = len(fit_terms)
    names = inputs.names
    e = len(names)
    ref_mode = inputs.reference is not None
    valid = prep.valid & inputs.usable
    if valid.all() or valid.sum() == prep.valid.sum():
        fprep = prep
    else:  # rows without an extra or the reference split the stretches (never differentiated
        # or filtered across)
        fprep = dataclasses.replace(prep, valid=valid,
                                    stretch=find_stretches(prep.time, valid, cfg.max_gap_s))
    estimator = "ridge" if cfg.estimator == "mlp" else cfg.estimator
    if not ref_mode:
        # One band-passed pass for the terms and the extras (no decimation: the extras
        # would need it too); its TL block is the TL fit's normal equations.
        fit_prep, q, design = fit_arrays(fprep, dataclasses.replace(cfg, decimate=False)
                                         if e else cfg, fit_terms)
        stats_all = segment_normal_equations(fit_prep, fit_terms, cfg, design,
                                             extra=inputs.values if e else None)
        stats = sub_stats(stats_all, np.arange(k))
    else:
        fit_prep, q, design = fit_arrays(prep, cfg, fit_terms)
        stats = segment_normal_equations(fit_prep, fit_terms, cfg, design)
    out, G, b = screen_stats(stats, cfg, prep.source)
    kept = out.kept
    if not ref_mode:
        # The self-fit's refusal of an ill-conditioned TL fit stands (a reference, which
        # holds the low frequencies, lifts it).
        solve_fit(G, b, ridge=cfg.ridge, max_condition=cfg.max_condition, source=prep.source)
    cond = float(np.linalg.cond(G)) if np.all(np.isfinite(G)) else float("inf")
    cond_s = float(scaled_condition(G[None])[0])
    kept_ids = stats.ids[kept]
    record: dict = {"reference": cfg.reference, "rows_left_out": int(prep.valid.sum()
                                                                     - valid.sum()),
                    "dropped_extras": list(inputs.dropped)}
    if not ref_mode:
        fstats = _select(stats_all, kept)
        full, tl, contrib = _held_out(fstats, k, names, False, estimator)
        coef_all = full.coef
        coef_tl, coef_ex, c0 = coef_all[:k], coef_all[k:], 0.0
        center = np.array([np.nanmean(inputs.values[j][valid]) for j in range(e)])
        residual = segment_residual_std(stats_all, coef_all)
        sse = float(fstats.yy.sum() - 2 * coef_all @ fstats.rhs.sum(0)
                    + coef_all @ fstats.gram.sum(0) @ coef_all)
        band = "band-passed (the fitting band), as the TL self-fit"
    else:
        rows = valid & np.isin(prep.segment, kept_ids)
        A = design_matrix(prep.flux[valid], prep.time[valid], fit_terms,
                          stretch=fprep.stretch[valid])
        sel = rows[valid]
        X = np.empty((int(sel.sum()), 1 + k + e))
        X[:, 0] = 1.0
        X[:, 1:1 + k] = A[sel]
        del A
        if e:
            X[:, 1 + k:] = inputs.values[:, rows].T
        y = prep.mag[rows] - inputs.reference[rows]
        rstats = reference_normal_equations(X, y, prep.segment[rows], kept_ids)
        full, tl, contrib = _held_out(rstats, k, names, True, estimator)
        c0, coef_tl, coef_ex = full.coef[0], full.coef[1:1 + k], full.coef[1 + k:]
        center = X[:, 1 + k:].mean(axis=0) if e else np.zeros(0)
        residual = segment_residual_std(stats, coef_tl)
        sse = float(stats.yy[kept].sum() - 2 * coef_tl @ b + coef_tl @ G @ coef_tl)
        band = "full band against the reference, mean removed by the intercept"
        if cfg.estimator == "mlp":
            res = y - X @ full.coef
            mlp, mrec = train_mlp(X[:, 1:], res, seed=0)
            record["mlp_training"] = mrec
            if mlp is None:
                log.warning("%s: --estimator mlp: the network does not lower the held-out "
                            "error (%.4g nT against %.4g nT linear on the last 20 %% of the "
                            "time): the linear model is used", prep.source,
                            mrec.get("mlp_std_nT", float("nan")),
                            mrec.get("linear_std_nT", float("nan")))
        del X
    scale = np.array([np.nanstd(inputs.values[j][valid]) for j in range(e)])
    record.update({
        "held_out": {
            "method": f"cross-validation over {max(2, min(10, len(kept_ids)))} contiguous blocks"
                      " of kept segments (blocks of time): each block predicted by the fit made"
                      " without it; std of the residual pooled over the blocks, " + band,
            "residual_std_nT": full.cv_std_nT,
            "tl_only_residual_std_nT": tl.cv_std_nT,
            "tl_only_param": tl.param,
            "contributions": contrib,
        },
        "n_fit_samples": int(full.coef.size and (stats.n[kept].sum() if not ref_mode
                                                  else rows.sum())),
    })
    coef = np.zeros(len(terms))
    coef[[terms.index(t) for t in fit_terms]] = coef_tl
    mlp_model = None
    if ref_mode and cfg.estimator == "mlp" and record["mlp_training"].get("kept"):
        mlp_model = mlp
    ext = ExtendedModel(cfg.reference, names, np.asarray(coef_ex, dtype=np.float64), center,
                        scale, float(c0 + center @ coef_ex) if e else float(c0),
                        cfg.estimator, full.param, mlp_model, record)
    diag, cv_segs = diagnostics_from_stats(stats, kept, fit_terms, cfg.ridge)
    outcome = FitOutcome(prep, cfg, terms, fit_terms, coef, stats, out, cond, cond_s, diag,
                         cv_segs["cv_residual_std_nT"].to_numpy(), residual,
                         scaled_condition(stats.gram), sse, q)
    return outcome, ExtendedFit(ext, coef_tl)
