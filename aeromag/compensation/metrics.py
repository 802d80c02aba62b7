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
from ..errors import InputError
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
        See :func:`metrics_dict`: ``improvement_ratio`` (std band-passed ``mag`` / std
        band-passed ``mag_comp``), ``residual_std_nT``, ``std_before_nT``, ``n_samples``, over
        the kept segments, and ``all_*`` over all samples.  Pass ``mag - mag_tl`` (unfiltered)
        as ``mag_comp`` for the figures the pipeline reports.
    """
    return _band_metrics(mag, mag_comp, time_s, stretch, cfg, kept=kept)[0]


def _band_metrics(
    mag: np.ndarray, mag_comp: np.ndarray, time_s: np.ndarray, stretch: np.ndarray,
    cfg: CompensationConfig, kept: np.ndarray | None = None, fs_hz: float | None = None,
    stretch_bp: np.ndarray | None = None, mag_bp: np.ndarray | None = None,
    source: str = "<log>",
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
    require_samples(int(use.sum()), fs, cfg.band_hz, source)
    before = masked_std(mag_bp, use)
    after = masked_std(comp_bp, use)
    kept_std = None
    if kept is not None:
        uk = use if kept.all() else use & kept
        if uk.any():
            kept_std = ((before, after) if uk is use
                        else (masked_std(mag_bp, uk), masked_std(comp_bp, uk)))
    n_kept = int(use.sum()) if kept is None or kept.all() else int((use & kept).sum())
    out = metrics_dict(int(use.sum()), before, after, kept_std, cfg.band_hz, n_kept=n_kept)
    comp_bp[~use] = np.nan
    return out, comp_bp



#: What the metrics are, in the report's words.
DEFINITION = ("std of mag and of mag - mag_tl (unfiltered), each band-passed once in band_hz"
              " (zero-phase Butterworth, per stretch, each dropped segment on its own), filter"
              " edges trimmed; headline figures over the kept segments, all_* over all"
              " segments; improvement_ratio = std_before_nT / residual_std_nT")


def require_samples(n_used: int, fs_hz: float, band_hz: tuple[float, float], source: str) -> None:
    """Refuse metrics on too few band-passed samples (a log too short for the band).

    Parameters
    ----------
    n_used : int
        Band-passed samples left after trimming the filter edges.
    fs_hz : float
        Sampling rate [Hz].
    band_hz : (float, float)
        The fitting band [Hz].
    source : str
        File name for the message.

    Raises
    ------
    InputError
        With fewer samples than one period of the band's lower edge (and fewer than 10).
    """
    need = max(10, int(np.ceil(fs_hz / band_hz[0])))
    if n_used < need:
        raise InputError(
            f"{source}: too short to measure the compensation: {n_used} sample(s) remain in"
            f" continuous stretches band-passed {band_hz[0]:g}-{band_hz[1]:g} Hz with the filter"
            f" edges trimmed, and the metrics need at least {need} ({need / fs_hz:.3g} s); give"
            " a longer log (or a higher low edge of band_hz)")


def metrics_dict(n_samples: int, before: float, after: float,
                 kept: tuple[float, float] | None, band_hz: tuple[float, float], *,
                 n_kept: int | None = None) -> dict[str, Any]:
    """The ``metrics`` block from band-passed standard deviations (in memory and chunked).

    Parameters
    ----------
    n_samples : int
        Samples the all-segment standard deviations were taken over.
    before, after : float
        Over all segments: std of band-passed ``mag`` and of band-passed ``mag - mag_tl`` [nT].
    kept : (float, float) or None
        The same over the kept segments (None: all segments are kept).
    band_hz : (float, float)
        The fitting band [Hz].
    n_kept : int, optional
        Samples of the kept segments (default ``n_samples``).

    Returns
    -------
    dict
        ``definition``; the headline over the kept segments: ``n_samples``,
        ``std_before_nT``, ``residual_std_nT``, ``improvement_ratio`` (before / after), also
        as ``kept_*``; beside them the same over all segments (``all_*``); ``band_hz``.
    """
    def ratio(b: float, a: float) -> float:
        return b / a if a > 0 else float("nan")

    kb, ka = kept if kept is not None else (before, after)
    return {
        "definition": DEFINITION,
        "n_samples": int(n_samples if n_kept is None else n_kept),
        "std_before_nT": kb,
        "residual_std_nT": ka,
        "improvement_ratio": ratio(kb, ka),
        "kept_std_before_nT": kb,
        "kept_residual_std_nT": ka,
        "kept_improvement_ratio": ratio(kb, ka),
        "all_n_samples": int(n_samples),
        "all_std_before_nT": before,
        "all_residual_std_nT": after,
        "all_improvement_ratio": ratio(before, after),
        "band_hz": list(band_hz),
    }
