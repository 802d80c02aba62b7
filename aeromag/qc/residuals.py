"""Band-passed residuals per segment piece: the numbers the fit reports, for any compensation.

The residual of a compensation is ``mag - mag_tl`` (unfiltered by the pipeline's final
low-pass), band-passed in the fitting band.  As in the fit (:mod:`aeromag.compensation.normal`)
every *piece* (a maximal run of one segment within one continuous stretch) is filtered on its
own, and ``trim_s`` (default ``0.25 / band_hz[0]``) is dropped at each of its ends: a filter
never runs across a segment boundary, so a dropped segment's fault cannot leak into the QC of
its kept neighbour, and a segment's residual here is the one in the model file.

Headline figures are over the kept segments, with the same over all data beside them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .._core.filters import butter_sos, filter_stretches, sampling_rate, trim_mask
from .._core.stretches import find_stretches

__all__ = ["PieceResiduals", "piece_labels", "piece_residuals", "rms_summary"]


@dataclass
class PieceResiduals:
    """Band-passed fields per segment piece (see the module docstring).

    Attributes
    ----------
    before_bp, after_bp : ndarray, shape (n,)
        Band-passed ``mag`` and ``mag - mag_tl`` [nT]; NaN on trimmed edges, gaps and pieces
        too short for the filter.
    by_segment : dict
        ``{segment id: rms of after_bp}`` [nT].
    n_by_segment : dict
        ``{segment id: samples used}``.
    kept, all : dict
        ``residual_std_nT``, ``std_before_nT``, ``improvement_ratio``, ``n_samples`` over the
        kept segments and over every piece (segments or not).
    trim_s : float
        Edge dropped at each end of every piece [s].
    """

    before_bp: np.ndarray
    after_bp: np.ndarray
    by_segment: dict[int, float]
    n_by_segment: dict[int, int]
    kept: dict[str, Any]
    all: dict[str, Any]
    trim_s: float


def piece_labels(time_s: np.ndarray, valid: np.ndarray, segment: np.ndarray,
                 max_gap_s: float | None = None) -> np.ndarray:
    """Index of the piece (run of one segment within one stretch) of every sample.

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Times [s].
    valid : ndarray of bool, shape (n,)
        Samples with finite fields.
    segment : ndarray of int, shape (n,)
        Segment id per sample (-1: none; such samples form pieces of their own per stretch).
    max_gap_s : float, optional
        Longest time step inside a stretch [s].

    Returns
    -------
    ndarray of int64, shape (n,)
        Piece index (0, 1, ... in time order), -1 for invalid samples.
    """
    st = find_stretches(np.asarray(time_s, dtype=np.float64), valid, max_gap_s)
    seg = np.asarray(segment, dtype=np.int64)
    n = len(st)
    new = np.ones(n, dtype=bool)
    if n > 1:
        new[1:] = (st[1:] != st[:-1]) | (seg[1:] != seg[:-1])
    lab = np.cumsum(new & (st >= 0)) - 1
    lab[st < 0] = -1
    return lab


def rms_summary(n: float, sum_before2: float, sum_after2: float) -> dict[str, Any]:
    """Headline numbers from sums of squares of the band-passed fields.

    Parameters
    ----------
    n : float
        Samples used.
    sum_before2, sum_after2 : float
        Sums of squares of band-passed ``mag`` and ``mag - mag_tl`` [nT²].

    Returns
    -------
    dict
        ``residual_std_nT`` and ``std_before_nT`` (rms [nT]), ``improvement_ratio`` (their
        ratio), ``n_samples``; None values when ``n`` is 0.
    """
    n = int(n)
    if n == 0:
        return {"residual_std_nT": None, "std_before_nT": None, "improvement_ratio": None,
                "n_samples": 0}
    rb = float(np.sqrt(sum_before2 / n))
    ra = float(np.sqrt(sum_after2 / n))
    return {"residual_std_nT": ra, "std_before_nT": rb,
            "improvement_ratio": rb / ra if ra > 0 else None, "n_samples": n}


def _summary(before: np.ndarray, after: np.ndarray, use: np.ndarray) -> dict[str, Any]:
    return rms_summary(use.sum(), np.sum(before[use] ** 2), np.sum(after[use] ** 2))


def piece_residuals(
    time_s: np.ndarray, mag: np.ndarray, mag_tl: np.ndarray, segment: np.ndarray,
    kept: np.ndarray, band_hz: tuple[float, float], order: int = 4, *,
    trim_s: float | None = None, max_gap_s: float | None = None, fs_hz: float | None = None,
) -> PieceResiduals:
    """Band-pass ``mag`` and ``mag - mag_tl`` piece by piece; rms per segment, kept and all.

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Times [s].
    mag, mag_tl : ndarray, shape (n,)
        Measured total field and modelled interference [nT].
    segment : ndarray of int, shape (n,)
        Segment id per sample (-1: none).
    kept : ndarray of bool, shape (n,)
        Samples of segments the screening kept.
    band_hz : (float, float)
        Fitting band [Hz].
    order : int
        Butterworth order.
    trim_s : float, optional
        Edge dropped at each end of every piece [s]; default ``0.25 / band_hz[0]`` (the fit's).
    max_gap_s : float, optional
        Longest time step inside a stretch [s].
    fs_hz : float, optional
        Sampling rate [Hz] (default: from ``time_s``).

    Returns
    -------
    PieceResiduals
    """
    t = np.asarray(time_s, dtype=np.float64)
    # The two rows written in place (no full-length temporary of mag - mag_tl); every
    # full-length array is let go as soon as it is used (2e6 rows: 16 MB each).
    x = np.empty((2, len(t)))
    x[0] = np.asarray(mag, dtype=np.float64)
    np.subtract(x[0], np.asarray(mag_tl, dtype=np.float64), out=x[1])
    seg = np.asarray(segment, dtype=np.int64)
    lab = piece_labels(t, np.isfinite(x).all(axis=0), seg, max_gap_s)
    fs = sampling_rate(t) if fs_hz is None else fs_hz
    sos = butter_sos("bandpass", band_hz, fs, order)
    xf = filter_stretches(x, lab, sos, axis=1)
    del x
    trim = 0.25 / band_hz[0] if trim_s is None else float(trim_s)
    use = trim_mask(lab, t, trim)
    del lab
    use &= np.isfinite(xf).all(axis=0)
    xf[:, ~use] = np.nan
    before, after = xf
    ok = use & (seg >= 0)
    by_seg: dict[int, float] = {}
    n_by: dict[int, int] = {}
    if ok.any():
        s = seg[ok]
        top = int(s.max())
        if top <= 4 * s.size + 1024:
            # Small non-negative ids: histograms, no sort.  np.bincount adds the weights in
            # sample order per bin either way, so the sums are bitwise those of np.unique's
            # inverse labels.
            cnt_all = np.bincount(s, minlength=top + 1)
            ids = np.flatnonzero(cnt_all)
            ss = np.bincount(s, after[ok] ** 2, minlength=top + 1)[ids]
            cnt = cnt_all[ids]
        else:
            ids, inv = np.unique(s, return_inverse=True)
            cnt = np.bincount(inv)
            ss = np.bincount(inv, after[ok] ** 2)
        del s
        by_seg = {int(i): float(np.sqrt(v / c)) for i, v, c in zip(ids, ss, cnt, strict=True)}
        n_by = {int(i): int(c) for i, c in zip(ids, cnt, strict=True)}
    del ok
    k = np.asarray(kept, dtype=bool) & (seg >= 0) if (seg >= 0).any() \
        else np.asarray(kept, dtype=bool)
    return PieceResiduals(before, after, by_seg, n_by, _summary(before, after, use & k),
                          _summary(before, after, use), trim)
