"""Band-passed per-segment normal equations of the TL fit and residuals from them."""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from .._core.filters import butter_sos, min_filter_length, piece_normal_equations
from ..errors import FitError
from .config import CompensationConfig
from .prepare import Prepared, _every
from .segments import segment_counts
from .terms import FIELD_SCALE_NT, direction_cosines, terms_from_cosines, time_derivative_rows

log = logging.getLogger(__name__)


@dataclass
class SegmentStats:
    """Band-passed normal equations per segment."""

    ids: np.ndarray
    n: np.ndarray
    gram: np.ndarray
    rhs: np.ndarray
    yy: np.ndarray
    too_short: dict[int, int]
    min_samples: int = 0  # fewest band-passed samples a segment needs to be fitted



def segment_normal_equations(
    prep: Prepared, terms: tuple[str, ...], cfg: CompensationConfig,
    design: np.ndarray | None = None,
) -> SegmentStats:
    """Band-pass the design matrix and target per segment piece; normal equations per segment.

    Parameters
    ----------
    prep : Prepared
        Arrays from :func:`prepare`.
    terms : tuple of str
        Fitted terms (no ``bias``: it vanishes in the band).
    cfg : CompensationConfig
        Options (band, order, trimming, shortest segment).
    design : ndarray, shape (len(terms) + 1, n_valid), optional
        The terms and the centred target already built, one column per valid sample of
        ``prep`` (the decimated fit: :func:`aeromag.compensation.decimation.fit_arrays`);
        by default they are built here from ``prep.flux`` and ``prep.mag``.

    Returns
    -------
    SegmentStats
    """
    sos = butter_sos("bandpass", cfg.band_hz, prep.fs, cfg.order, source=prep.source)
    # Views, not copies, when every sample is valid (at 1e7 samples that is 0.5 GB less).
    v = slice(None) if prep.valid.all() else prep.valid
    t = prep.time[v]
    st = prep.stretch[v]
    seg = prep.segment[v]
    k = len(terms)
    flux = prep.flux[v]
    y = prep.mag[v]
    y_level = float(np.median(y[:: _every(y)]))  # centring only (the band-pass removes it)
    nv = len(t)

    def rows(idx: np.ndarray) -> np.ndarray:
        # The terms of q pieces of L samples, built batch by batch from the fluxgate (the
        # 17 x n design matrix and even the n x 3 cosines never exist).  Each piece is taken
        # with one sample of context on either side, so its derivatives are exactly those
        # of whole stretches, as when the model is applied.
        q, L = idx.shape
        ext = np.empty((q, L + 2), dtype=np.int64)
        ext[:, 1:-1] = idx
        ext[:, 0] = idx[:, 0] - 1
        ext[:, -1] = idx[:, -1] + 1
        outside = (ext < 0) | (ext >= nv)
        np.clip(ext, 0, nv - 1, out=ext)
        cos, bt = direction_cosines(flux[ext.ravel()])
        cos = cos.reshape(q, L + 2, 3)
        lab = st[ext]
        lab[outside] = -2  # beyond the log: a stretch of its own, so never a neighbour
        dcos = time_derivative_rows(cos, t[ext], lab)
        bt = bt.reshape(q, L + 2)[:, 1:-1]
        bt /= FIELD_SCALE_NT
        out = np.empty((k + 1, q * L))
        terms_from_cosines(cos[:, 1:-1].reshape(-1, 3), dcos[:, 1:-1].reshape(-1, 3),
                           bt.reshape(-1), terms, out=out[:k].T)
        np.subtract(y[idx.ravel()], y_level, out=out[k])
        return out.reshape(k + 1, q, L)

    # Each segment is filtered on its own (within each stretch): a fault in one segment must
    # not leak through the filter into its neighbours' fits.
    # Pieces: maximal runs of one (stretch, segment) with a segment (no n-sized int arrays).
    brk = np.empty(len(seg), dtype=bool)
    brk[:1] = True
    np.not_equal(st[1:], st[:-1], out=brk[1:])
    brk[1:] |= seg[1:] != seg[:-1]
    p_start = np.flatnonzero(brk)
    del brk
    p_stop = np.r_[p_start[1:], len(seg)]
    has_seg = seg[p_start] >= 0
    p_start, p_stop = p_start[has_seg], p_stop[has_seg]
    p_seg = seg[p_start]
    trim = (0.25 / cfg.band_hz[0]) if cfg.trim_s is None else cfg.trim_s
    M, n_used = piece_normal_equations(rows if design is None else design, t, p_start, p_stop,
                                       sos, trim)
    if not n_used.any():
        nmin = min_filter_length(sos) / prep.fs
        raise FitError(
            f"{prep.source}: no continuous stretch is long enough to band-pass and trim"
            f" (needs > {max(nmin, 2 * trim):.0f} s without gaps); use longer stretches,"
            " a higher low edge of band_hz, or a larger max_gap_s"
        )
    # Sum the pieces of each segment (a line flown twice, or cut by a gap, has several).
    ids, inv = np.unique(p_seg, return_inverse=True)
    counts = np.bincount(inv, weights=n_used).astype(np.int64)
    Mseg = np.zeros((len(ids), k + 1, k + 1))
    np.add.at(Mseg, inv, M)
    min_s = (1.0 / cfg.band_hz[0]) if cfg.min_segment_seconds is None else cfg.min_segment_seconds
    nmin = max(int(np.ceil(min_s * prep.fs)), 3 * k)
    ok = counts >= nmin
    too_short = {int(i): int(c) for i, c in zip(ids[~ok], counts[~ok], strict=True)}
    # Segments with no valid sample at all are too short too.
    all_ids = segment_counts(prep.segment)[0]
    for i in np.setdiff1d(all_ids, ids):
        too_short[int(i)] = 0
    gram = Mseg[ok, :k, :k]
    rhs = Mseg[ok, :k, k]
    yy = Mseg[ok, k, k]
    return SegmentStats(ids[ok], counts[ok], gram, rhs, yy, too_short, nmin)


def _residual_std(stats: SegmentStats, coef: np.ndarray) -> np.ndarray:
    """Band-passed residual std per segment for coefficients ``coef`` (k,) or (m, k)."""
    c = np.broadcast_to(coef, stats.rhs.shape)
    sse = stats.yy - 2 * np.einsum("mk,mk->m", c, stats.rhs) + np.einsum(
        "mk,mkj,mj->m", c, stats.gram, c
    )
    return np.sqrt(np.maximum(sse, 0.0) / stats.n)
