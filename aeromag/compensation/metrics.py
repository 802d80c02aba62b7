"""Compensation metrics on band-passed fields (interface.md ``metrics``)."""

from __future__ import annotations

import logging
from typing import Any

import numpy as np

from .._core.filters import (
    butter_sos,
    filter_stretches,
    filter_stretches_each,
    sampling_rate,
    trim_mask,
)
from .._core.moments import masked_std
from .._core.stretches import find_stretches
from .config import CompensationConfig

log = logging.getLogger(__name__)


def compensation_metrics(
    mag: np.ndarray, mag_comp: np.ndarray, time_s: np.ndarray, stretch: np.ndarray,
    cfg: CompensationConfig, kept: np.ndarray | None = None,
) -> dict[str, Any]:
    """Improvement ratio and residual std on band-passed fields (interface.md metrics).

    Parameters
    ----------
    mag, mag_comp : ndarray, shape (n,)
        Uncompensated and compensated total field as written [nT].
    time_s : ndarray, shape (n,)
        Times [s].
    stretch : ndarray of int, shape (n,)
        Stretch labels.
    cfg : CompensationConfig
        Band and order.
    kept : ndarray of bool, optional
        Samples of kept segments (extra metrics over them).

    Returns
    -------
    dict
        ``improvement_ratio`` (std band-passed ``mag`` / std band-passed ``mag_comp``),
        ``residual_std_nT`` (std band-passed ``mag_comp``), ``std_before_nT``, ``n_samples``,
        and the same over kept segments.
    """
    return _band_metrics(mag, mag_comp, time_s, stretch, cfg, kept=kept)[0]


def _band_metrics(
    mag: np.ndarray, mag_comp: np.ndarray, time_s: np.ndarray, stretch: np.ndarray,
    cfg: CompensationConfig, kept: np.ndarray | None = None, fs_hz: float | None = None,
    stretch_bp: np.ndarray | None = None, mag_bp: np.ndarray | None = None,
) -> tuple[dict[str, Any], np.ndarray]:
    """:func:`compensation_metrics` and the band-passed ``mag_comp`` it used (NaN outside).

    ``stretch_bp`` and ``mag_bp``, when given, are the stretches of finite ``mag_comp`` and
    ``mag`` already band-passed over them (computed here otherwise).
    """
    fs = sampling_rate(time_s) if fs_hz is None else fs_hz
    sos = butter_sos("bandpass", cfg.band_hz, fs, cfg.order)
    if stretch_bp is not None:
        st = stretch_bp
    else:
        fin = np.isfinite(mag_comp)
        # Re-label so a NaN inside a stretch splits it (filters never run over NaN).
        st = stretch if fin[stretch >= 0].all() else find_stretches(
            time_s, fin & (stretch >= 0), cfg.max_gap_s)
    if mag_bp is not None:
        comp_bp = filter_stretches(np.asarray(mag_comp, dtype=np.float64)[None, :], st, sos,
                                   axis=1)[0]
    elif len(mag) > 2_000_000:  # one at a time: each filter's temporaries are 3 x the series
        mag_bp = filter_stretches(np.asarray(mag, dtype=np.float64)[None, :], st, sos,
                                  axis=1)[0]
        comp_bp = filter_stretches(np.asarray(mag_comp, dtype=np.float64)[None, :], st, sos,
                                   axis=1)[0]
    else:
        mag_bp, comp_bp = filter_stretches_each([mag, mag_comp], st, sos)
    trim = (0.5 / cfg.band_hz[0]) if cfg.trim_s is None else cfg.trim_s
    fin = np.isfinite(mag_bp) & np.isfinite(comp_bp)
    use = trim_mask(st, time_s, trim) & fin
    if use.sum() < 10:
        use = fin
    before = masked_std(mag_bp, use)
    after = masked_std(comp_bp, use)
    kept_std = None
    if kept is not None:
        uk = use if kept.all() else use & kept
        if uk.any():
            kept_std = ((before, after) if uk is use
                        else (masked_std(mag_bp, uk), masked_std(comp_bp, uk)))
    out = metrics_dict(int(use.sum()), before, after, kept_std, cfg.band_hz)
    comp_bp[~use] = np.nan
    return out, comp_bp



def metrics_dict(n_samples: int, before: float, after: float,
                 kept: tuple[float, float] | None, band_hz: tuple[float, float]
                 ) -> dict[str, Any]:
    """The ``metrics`` block from band-passed standard deviations (in memory and chunked).

    Parameters
    ----------
    n_samples : int
        Samples the standard deviations were taken over.
    before, after : float
        Std of band-passed ``mag`` and of band-passed ``mag_comp`` [nT].
    kept : (float, float) or None
        The same over the kept segments.
    band_hz : (float, float)
        The fitting band [Hz].

    Returns
    -------
    dict
        ``n_samples``, ``std_before_nT``, ``residual_std_nT``, ``improvement_ratio``
        (before / after), the ``kept_`` versions, ``band_hz``.
    """
    out: dict[str, Any] = {"n_samples": int(n_samples)}
    out["std_before_nT"] = before
    out["residual_std_nT"] = after
    out["improvement_ratio"] = before / after if after > 0 else float("nan")
    if kept is not None:
        b2, a2 = kept
        out["kept_std_before_nT"] = b2
        out["kept_residual_std_nT"] = a2
        out["kept_improvement_ratio"] = b2 / a2 if a2 > 0 else float("nan")
    out["band_hz"] = list(band_hz)
    return out
