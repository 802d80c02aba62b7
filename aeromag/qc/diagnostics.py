"""Fit diagnostics from per-segment normal equations: condition numbers, VIF, LOSO-CV.

The kernels are pure numerics (:mod:`aeromag._core.fit_diagnostics`, which the compensation fit
uses too); :func:`fit_diagnostics` rebuilds the band-passed per-segment normal equations of a
compensated log (:func:`aeromag.compensate.segment_normal_equations`) and runs them.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .._core.fit_diagnostics import (
    FitDiagnostics,
    diagnostics_from_stats,
    loso_cv,
    variance_inflation,
)
from ..compensation.config import CompensationConfig
from ..compensation.normal import segment_normal_equations
from ..compensation.prepare import prepare
from ..compensation.terms import TERMS_16
from .labels import kept_mask, segment_labels

__all__ = ["FitDiagnostics", "diagnostics_from_stats", "fit_diagnostics", "loso_cv",
           "variance_inflation"]


def fit_diagnostics(
    data: pd.DataFrame, cfg: CompensationConfig, terms: tuple[str, ...] = TERMS_16,
    *, seg: np.ndarray | None = None,
) -> tuple[FitDiagnostics, pd.DataFrame]:
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
    diagnostics : FitDiagnostics
        ``terms``, ``condition_number``, ``condition_number_scaled``, ``vif`` (term -> VIF),
        ``max_vif``, ``n_segments_kept``, ``cv_residual_std_nT``, ``fit_residual_std_nT``
        [nT], ``cv_ratio`` (CV / in-sample).
    segments : DataFrame
        Output of :func:`loso_cv`.
    """
    fit_terms = tuple(x for x in terms if x != "bias")
    # The heading only goes into the fit report's per-segment headings, not into the
    # normal equations: without it prepare keeps no float64 copy of it (16 MB at 2e6 rows)
    # while they are built.  (drop copies no column data: the frame's blocks are shared.)
    base = data.drop(columns=[c for c in ("mag_tl", "mag_comp", "heading")
                              if c in data.columns])
    if seg is None:
        seg = segment_labels(data)
    has_seg = bool((seg >= 0).any())
    # The fluxgate stays the log's float32 columns (cast to float64 batch by batch as the
    # design rows are built) and the log's segments are used as they are: no (n, 3) float64
    # copy, no segments assigned only to be replaced (64 + 16 MB fewer at 2e6 rows).
    prep = prepare(base, cfg, flux_columns=True, segment=seg if has_seg else None)
    # The normal equations only compare stretch labels: int32 holds them in half the memory
    # (8 MB fewer at 2e6 rows while they are built), the same values (prepare's
    # flux_columns=True already gives int32).
    prep.stretch = prep.stretch.astype(np.int32, copy=False)
    # Small filtering batches: ~4 MB per filter-pool thread instead of 33 MB.
    stats = segment_normal_equations(prep, fit_terms, cfg, batch_samples=8_192)
    del prep  # its full-length arrays: the diagnostics need only the per-segment sums
    kept_samples = kept_mask(data)
    kept_ids = _kept_segment_ids(seg, kept_samples) if has_seg else stats.ids
    kept = np.isin(stats.ids, kept_ids)
    if not kept.any():
        kept = np.ones(len(stats.ids), dtype=bool)
    return diagnostics_from_stats(stats, kept, fit_terms, cfg.ridge)


def _kept_segment_ids(seg: np.ndarray, kept: np.ndarray, block: int = 1 << 18) -> np.ndarray:
    """Ids of the segments with a kept sample: ``np.unique(seg[kept & (seg >= 0)])``.

    Block by block, so that no full-length selection and its sorted copy exist (32 MB at
    2e6 samples).
    """
    found = []
    for a in range(0, len(seg), block):
        s = seg[a:a + block]
        found.append(np.unique(s[kept[a:a + block] & (s >= 0)]))
    return np.unique(np.concatenate(found)) if found else np.zeros(0, dtype=seg.dtype)
