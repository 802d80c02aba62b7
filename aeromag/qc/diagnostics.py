"""Fit diagnostics from per-segment normal equations: condition numbers, VIF, LOSO-CV.

The kernels are pure numerics (:mod:`aeromag._core.fit_diagnostics`, which the compensation fit
uses too); :func:`fit_diagnostics` rebuilds the band-passed per-segment normal equations of a
compensated log (:func:`aeromag.compensate.segment_normal_equations`) and runs them.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from .._core.fit_diagnostics import diagnostics_from_stats, loso_cv, variance_inflation
from ..compensation.config import CompensationConfig
from ..compensation.normal import segment_normal_equations
from ..compensation.prepare import prepare
from ..compensation.terms import TERMS_16
from .labels import kept_mask, segment_labels

__all__ = ["diagnostics_from_stats", "fit_diagnostics", "loso_cv", "variance_inflation"]


def fit_diagnostics(
    data: pd.DataFrame, cfg: CompensationConfig, terms: tuple[str, ...] = TERMS_16,
    *, seg: np.ndarray | None = None,
) -> tuple[dict[str, Any], pd.DataFrame]:
    """Condition number, VIF and leave-one-segment-out CV of the fit on a compensated log.

    The band-passed per-segment normal equations are rebuilt from the log with the
    configuration of the compensation
    (:func:`aeromag.compensation.normal.segment_normal_equations`) using the
    log's ``segment`` labels and ``segment_kept`` flags.

    Parameters
    ----------
    data : DataFrame
        Compensated log with the fluxgate, ``mag``, ``segment`` and ``segment_kept``.
    cfg : CompensationConfig
        The configuration the log was compensated with (band, order, gaps, ridge).
    terms : tuple of str
        Terms of the model that was applied.
    seg : ndarray of int, shape (n,), optional
        :func:`aeromag.qc.segment_labels` of ``data`` when the caller already has them
        (not computed again).

    Returns
    -------
    diagnostics : dict
        ``condition_number``, ``condition_number_scaled``, ``vif`` (term -> VIF), ``max_vif``,
        ``cv_residual_std_nT``, ``fit_residual_std_nT``, ``cv_ratio`` (CV / in-sample).
    segments : DataFrame
        Output of :func:`loso_cv`.
    """
    fit_terms = tuple(x for x in terms if x != "bias")
    # The heading only goes into the fit report's per-segment headings, not into the
    # normal equations: without it prepare keeps no float64 copy of it (16 MB at 2e6 rows)
    # while they are built.  (drop copies no column data: the frame's blocks are shared.)
    base = data.drop(columns=[c for c in ("mag_tl", "mag_comp", "heading")
                              if c in data.columns])
    prep = prepare(base, cfg)
    if seg is None:
        seg = segment_labels(data)
    if (seg >= 0).any():
        prep.segment = seg
    # The normal equations only compare stretch labels: int32 holds them in half the memory
    # (8 MB fewer at 2e6 rows while they are built), the same values.
    prep.stretch = prep.stretch.astype(np.int32)
    stats = segment_normal_equations(prep, fit_terms, cfg)
    del prep  # its full-length arrays: the diagnostics need only the per-segment sums
    kept_samples = kept_mask(data)
    kept_ids = np.unique(seg[kept_samples & (seg >= 0)]) if (seg >= 0).any() else stats.ids
    kept = np.isin(stats.ids, kept_ids)
    if not kept.any():
        kept = np.ones(len(stats.ids), dtype=bool)
    return diagnostics_from_stats(stats, kept, fit_terms, cfg.ridge)
