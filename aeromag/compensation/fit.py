"""The one TL fit: per-segment normal equations, screening, one refit on the kept segments.

:func:`fit_model` is what ``aeromag calibrate`` / ``compensate`` run and what the scikit-learn
:class:`~aeromag.compensation.estimator.TollesLawsonRegressor` calls, so both refuse the same data:
:func:`solve_fit` refuses an unregularised fit whose scaled condition number exceeds
``max_condition`` and :func:`check_interference` a model whose interference no aircraft makes.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
import pandas as pd

from .._core.fit_diagnostics import diagnostics_from_stats
from .._core.lstsq import scaled_condition, solve_normal
from ..errors import FitError, InputError
from .config import CompensationConfig
from .decimation import fit_arrays
from .model import ModelMeta, TLModel
from .normal import SegmentStats, segment_normal_equations, segment_residual_std
from .prepare import Prepared, prepare
from .report import fit_report
from .result import CompensationResult, FitOutcome
from .screening import ScreeningOutcome, screen_segments
from .terms import design_matrix, parse_terms

log = logging.getLogger(__name__)

__all__ = ["FitOutcome", "check_interference", "fit_model", "fit_outcome", "fit_result",
           "screen_stats", "solve_fit"]


def solve_fit(gram: np.ndarray, rhs: np.ndarray, *, ridge: float, max_condition: float,
              source: str) -> tuple[np.ndarray, float, float]:
    """Solve the final normal equations with the refusals every fit shares.

    Parameters
    ----------
    gram, rhs : ndarray, shape (k, k) and (k,)
        Summed band-passed normal equations of the kept segments.
    ridge : float
        Relative ridge parameter (0: plain least squares).
    max_condition : float
        Largest scaled condition number of an unregularised fit.
    source : str
        File name quoted in errors.

    Returns
    -------
    coef : ndarray, shape (k,)
        Coefficients [nT; eddy nT*s].
    cond, cond_scaled : float
        Condition numbers (see :func:`aeromag._core.lstsq.solve_normal`).

    Raises
    ------
    FitError
        Singular, non-finite or ill-conditioned normal equations.
    """
    try:
        coef, cond, cond_s = solve_normal(gram, rhs, ridge)
    except FitError as exc:
        raise FitError(f"{source}: {exc}") from None
    if ridge <= 0 and not cond_s <= max_condition:
        raise FitError(
            f"{source}: the fit is ill-conditioned (scaled condition number {cond_s:.3g}"
            f" > {max_condition:.3g}): the attitude varies too little to separate the TL"
            " terms (no maneuvers?); calibrate on a flight with pitch/roll/yaw maneuvers and"
            " apply it with model=MODEL, or regularise with ridge=1e-3, or fit fewer terms"
            " (terms=9)"
        )
    return coef, cond, cond_s


def check_interference(mag_tl_nT: np.ndarray, field_nT: float, max_interference: float, *,
                       source: str, fitted: bool) -> None:
    """Refuse (fitted) or warn about (saved model) an interference no aircraft makes.

    Parameters
    ----------
    mag_tl_nT : ndarray, shape (n,)
        Modelled interference on the log [nT].
    field_nT : float
        The Earth field's magnitude on the log [nT].
    max_interference : float
        Largest plausible interference as a fraction of ``field_nT``.
    source : str
        File name quoted in the message.
    fitted : bool
        The model was fitted on this log (refuse) rather than loaded (warn).

    Raises
    ------
    FitError
        When ``fitted`` and the 99th percentile of ``|mag_tl|`` exceeds the limit.
    """
    tl = np.asarray(mag_tl_nT)
    sub = np.abs(tl[:: max(1, len(tl) // 100_000)])
    sub = sub[np.isfinite(sub)]
    peak = float(np.percentile(sub, 99)) if sub.size else float("nan")
    limit = max_interference * field_nT
    if not (np.isfinite(peak) and np.isfinite(limit) and peak > limit):
        return
    msg = (f"{source}: the model gives an aircraft interference of {peak:.4g} nT"
           f" ({peak / field_nT:.0%} of the {field_nT:.0f} nT field), which no aircraft makes")
    if fitted:
        raise FitError(
            msg + ": this flight does not determine the TL terms at low frequency (too few"
            " headings or maneuvers); calibrate on a box flight with maneuvers and apply"
            " it with model=MODEL, or regularise with ridge=1e-3 (limit: max_interference)"
        )
    log.warning("%s; check that the model belongs to this aircraft and sensor", msg)


def screen_stats(stats: SegmentStats, cfg: CompensationConfig, source: str,
                 ) -> tuple[ScreeningOutcome, np.ndarray, np.ndarray]:
    """Refuse no fittable segment, warn about short ones, screen; the kept segments' sums.

    Parameters
    ----------
    stats : SegmentStats
        Per-segment band-passed normal equations of the TL terms.
    cfg : CompensationConfig
        Options (the screening's).
    source : str
        File name quoted in messages.

    Returns
    -------
    screening : ScreeningOutcome
    gram, rhs : ndarray
        Normal equations summed over the kept segments.
    """
    if len(stats.ids) == 0:
        raise FitError(
            f"{source}: every segment is too short to fit ({len(stats.too_short)} segment(s));"
            " use a longer segment_seconds=... or check the line column"
        )
    for sid, cnt in stats.too_short.items():
        log.warning("%s: segment %d too short to fit (%d usable samples): left out",
                    source, sid, cnt)
    out = screen_segments(stats, cfg)
    return out, stats.gram[out.kept].sum(axis=0), stats.rhs[out.kept].sum(axis=0)


def fit_outcome(prep: Prepared, cfg: CompensationConfig) -> FitOutcome:
    """Fit on prepared arrays: normal equations, screening, refusals, bias, diagnostics.

    Parameters
    ----------
    prep : Prepared
        Arrays of the log (:func:`aeromag.compensation.prepare.prepare`).
    cfg : CompensationConfig
        Options.

    Returns
    -------
    FitOutcome
    """
    terms = parse_terms(cfg.terms)
    fit_terms = tuple(t for t in terms if t != "bias")
    if not fit_terms:
        raise InputError("terms=bias: the bias alone cannot be fitted in a band; add terms")
    # A high-rate log is fitted on its decimated copy (the band kept exact); the
    # coefficients are applied to every original sample (docs/compensation.md).
    fit_prep, q, design = fit_arrays(prep, cfg, fit_terms)
    stats = segment_normal_equations(fit_prep, fit_terms, cfg, design)
    out, G, b = screen_stats(stats, cfg, prep.source)
    kept = out.kept
    coef_fit, cond, cond_s = solve_fit(G, b, ridge=cfg.ridge, max_condition=cfg.max_condition,
                                       source=prep.source)
    coef = np.zeros(len(terms))
    coef[[terms.index(t) for t in fit_terms]] = coef_fit
    if "bias" in terms:
        # The bias is invisible in the band: fix it on the unfiltered kept samples.
        inkeep = np.isin(prep.segment, stats.ids[kept]) & prep.valid
        A = design_matrix(prep.flux[inkeep], prep.time[inkeep], fit_terms,
                          stretch=prep.stretch[inkeep])
        coef[terms.index("bias")] = float(np.mean(prep.mag[inkeep] - A @ coef_fit))
    diag, cv_segs = diagnostics_from_stats(stats, kept, fit_terms, cfg.ridge)
    sse = float(stats.yy[kept].sum() - 2 * coef_fit @ b + coef_fit @ G @ coef_fit)
    return FitOutcome(prep, cfg, terms, fit_terms, coef, stats, out, cond, cond_s, diag,
                      cv_segs["cv_residual_std_nT"].to_numpy(),
                      segment_residual_std(stats, coef_fit), scaled_condition(stats.gram), sse,
                      q)


def fit_model(
    df: pd.DataFrame, cfg: CompensationConfig | None = None, *, source: str | None = None,
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

    Returns
    -------
    CompensationResult
        ``data`` is None; ``model`` carries the report as its metadata.
    """
    cfg = cfg or CompensationConfig()
    return fit_result(prepare(df, cfg, source=source), cfg)


def fit_result(prep: Prepared, cfg: CompensationConfig, *, fit: FitOutcome | None = None,
               extended: Any = None) -> CompensationResult:
    """:func:`fit_model` on arrays already prepared (what the pipeline calls).

    Parameters
    ----------
    prep : Prepared
        Arrays of the log.
    cfg : CompensationConfig
        Options.
    fit : FitOutcome, optional
        An outcome already fitted (the extended fit's:
        :func:`aeromag.compensation.extended_fit.extended_result`); default :func:`fit_outcome`.
    extended : ExtendedModel, optional
        Its extras, reference and network: the model's ``extended`` and the report's block.

    Returns
    -------
    CompensationResult
        ``data`` is None; ``model`` carries the report as its metadata.
    """
    fit = fit if fit is not None else fit_outcome(prep, cfg)
    report = fit_report(fit)
    if extended is not None:
        report.extended = extended.summary()
    model = TLModel(fit.terms, fit.coef, meta=ModelMeta(report=report), extended=extended)
    return CompensationResult(None, model, report, fit.screening.screen,
                              pd.DataFrame([s.to_dict() for s in report.segments]), fit=fit)
