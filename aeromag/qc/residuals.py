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

import numpy as np

from .._core.filters import butter_sos, sampling_rate, trim_mask
from .._core.stretches import find_stretches
from ._blocks import CHUNK, filter_runs, max_gap, run_edges
from .summaries import RmsSummary

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
    kept, all : RmsSummary
        ``residual_std_nT``, ``std_before_nT`` [nT], ``improvement_ratio``, ``n_samples``
        over the kept segments and over every piece (segments or not).
    trim_s : float
        Edge dropped at each end of every piece [s].
    """

    before_bp: np.ndarray
    after_bp: np.ndarray
    by_segment: dict[int, float]
    n_by_segment: dict[int, int]
    kept: RmsSummary
    all: RmsSummary
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


def rms_summary(n: float, sum_before2: float, sum_after2: float) -> RmsSummary:
    """Headline numbers from sums of squares of the band-passed fields.

    Parameters
    ----------
    n : float
        Samples used.
    sum_before2, sum_after2 : float
        Sums of squares of band-passed ``mag`` and ``mag - mag_tl`` [nT²].

    Returns
    -------
    RmsSummary
        ``residual_std_nT`` and ``std_before_nT`` (rms [nT]), ``improvement_ratio`` (their
        ratio), ``n_samples``; None values when ``n`` is 0.
    """
    n = int(n)
    if n == 0:
        return RmsSummary(n_samples=0)
    rb = float(np.sqrt(sum_before2 / n))
    ra = float(np.sqrt(sum_after2 / n))
    return RmsSummary(improvement_ratio=rb / ra if ra > 0 else None, residual_std_nT=ra,
                      std_before_nT=rb, n_samples=n)


def _summary(before: np.ndarray, after: np.ndarray, use: np.ndarray) -> RmsSummary:
    """:func:`rms_summary` over ``use``: ``np.sum(x[use] ** 2)`` of each field.

    The selection is squared in place in one buffer (one temporary, not two per field).
    """
    m = int(np.count_nonzero(use))
    buf = np.empty(m)
    sums = []
    n = len(use)
    for x in (before, after):
        p = 0
        for a in range(0, n, CHUNK):  # x[use] a chunk at a time (no index array)
            sel = x[a:a + CHUNK][use[a:a + CHUNK]]
            buf[p:p + sel.size] = sel
            p += sel.size
        np.multiply(buf, buf, out=buf)
        sums.append(np.sum(buf))
    return rms_summary(m, sums[0], sums[1])


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
    n = len(t)
    mg = np.asarray(mag, dtype=np.float64)
    tl = np.asarray(mag_tl, dtype=np.float64)
    seg = np.asarray(segment)
    if seg.dtype.kind != "i":  # an int32 segment column is used as it is (no 16 MB copy)
        seg = seg.astype(np.int64)
    fs = sampling_rate(t) if fs_hz is None else fs_hz
    sos = butter_sos("bandpass", band_hz, fs, order)
    trim = 0.25 / band_hz[0] if trim_s is None else float(trim_s)

    def rows(a: int, b: int) -> np.ndarray:
        x = np.empty((2, b - a))
        x[0] = mg[a:b]
        np.subtract(x[0], tl[a:b], out=x[1])
        return x

    def valid(a: int, b: int) -> np.ndarray:
        return np.isfinite(rows(a, b)).all(axis=0)

    # A block of pieces at a time (the pieces of piece_labels, each filtered on its own as
    # filter_stretches does over the whole log): the only full-length arrays are the
    # band-passed pair itself and the mask of samples used.  At 2e6 rows the step peaked at
    # +82 MB (the two rows, their labels, the filter's copy, the trim mask).
    g = max_gap(t, max_gap_s)
    xf = np.full((2, n), np.nan)
    use = np.zeros(n, dtype=bool)

    def trimmed(a: int, b: int, lab: np.ndarray) -> None:
        use[a:b] = trim_mask(lab, t[a:b], trim)

    st, sp = run_edges(t, valid, g, lambda a, b: seg[a:b])
    filter_runs(rows, xf, st, sp, sos, each=trimmed, chunk=1 << 16)
    del st, sp
    for a in range(0, n, CHUNK):
        b = min(n, a + CHUNK)
        u = use[a:b]
        u &= np.isfinite(xf[:, a:b]).all(axis=0)
        xf[:, a:b][:, ~u] = np.nan
    before, after = xf
    by_seg, n_by = _by_segment(after, use, seg)
    k = np.asarray(kept, dtype=bool) & (seg >= 0) if (seg >= 0).any() \
        else np.asarray(kept, dtype=bool)
    k = k & use
    return PieceResiduals(before, after, by_seg, n_by, _summary(before, after, k),
                          _summary(before, after, use), trim)


def _by_segment(after: np.ndarray, use: np.ndarray, seg: np.ndarray
                ) -> tuple[dict[int, float], dict[int, int]]:
    """The rms of ``after`` and the samples used per segment id, over ``use & (seg >= 0)``.

    The sums of squares are those of one ``np.bincount`` over the whole log (sequential in
    sample order per bin), computed a chunk at a time: each chunk's bincount starts every
    bin from the running sum (a first weight of each bin), so every addition is the one the
    whole-log bincount makes, and the sums are bitwise the same.
    """
    n = len(after)
    top = -1
    cnt_ok = 0
    for a in range(0, n, CHUNK):
        b = min(n, a + CHUNK)
        ok = use[a:b] & (seg[a:b] >= 0)
        c = int(np.count_nonzero(ok))
        if c:
            cnt_ok += c
            top = max(top, int(seg[a:b][ok].max()))
    if cnt_ok == 0:
        return {}, {}
    if top > 4 * cnt_ok + 1024:  # large ids: one np.unique over the whole log
        ok = use & (seg >= 0)
        ids, inv = np.unique(seg[ok], return_inverse=True)
        cnt = np.bincount(inv)
        w = after[ok]
        del ok
        ss = np.bincount(inv, np.multiply(w, w, out=w))
    else:
        bins = np.arange(top + 1, dtype=np.int64)
        ss_all = np.zeros(top + 1)
        cnt_all = np.zeros(top + 1, dtype=np.int64)
        for a in range(0, n, CHUNK):
            b = min(n, a + CHUNK)
            ok = use[a:b] & (seg[a:b] >= 0)
            s = seg[a:b][ok]
            if not s.size:
                continue
            w = after[a:b][ok]
            np.multiply(w, w, out=w)
            cnt_all += np.bincount(s, minlength=top + 1)
            ss_all = np.bincount(np.concatenate([bins, s]), np.concatenate([ss_all, w]),
                                 minlength=top + 1)
        ids = np.flatnonzero(cnt_all)
        ss, cnt = ss_all[ids], cnt_all[ids]
    by_seg = {int(i): float(np.sqrt(v / c)) for i, v, c in zip(ids, ss, cnt, strict=True)}
    n_by = {int(i): int(c) for i, c in zip(ids, cnt, strict=True)}
    return by_seg, n_by
