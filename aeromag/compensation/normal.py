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
    design: np.ndarray | None = None, *, batch_samples: int = 65_536,
    extra: np.ndarray | None = None,
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
    batch_samples : int
        Samples per filtering batch (:func:`aeromag._core.filters.piece_normal_equations`):
        each filter-pool thread holds about 0.5 kB per sample of its batch (17 design rows
        and the filter's padded copies), 33 MB at the default; the values do not depend on
        it.
    extra : ndarray, shape (e, n), optional
        More regressors (``--extra``), one row per column, one value per sample of ``prep``
        (finite on its valid samples); band-passed and trimmed like the terms and placed after
        them, so the statistics have ``len(terms) + e`` columns.

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
    if prep.flux is not None:
        flux = prep.flux[v]

        def flux_rows(i: np.ndarray) -> np.ndarray:
            return flux[i]
    else:
        # The log's own columns (prepare(flux_columns=True)): each batch's rows are cast to
        # float64 as it is built, the same values as prepare's (n, 3) float64 copy.
        cols = [c[v] for c in prep.flux_columns]

        def flux_rows(i: np.ndarray) -> np.ndarray:
            f = np.empty((len(i), 3))
            for j, c in enumerate(cols):
                f[:, j] = c[i]
            return f
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
        cos, bt = direction_cosines(flux_rows(ext.ravel()))
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
    # The pieces go to the filter in blocks of about _BLOCK_SAMPLES samples, each block's
    # cross products added into its segments' sums at once: the (pieces, k+1, k+1) array of
    # every piece and a second (segments, k+1, k+1) copy never exist (40 MB at 2e6 rows).
    # The sums are the same: each segment's pieces are added in piece order, as one
    # np.add.at over all pieces adds them, and a piece's cross products do not depend on
    # which pieces share its filter batch.
    ids, inv = np.unique(p_seg, return_inverse=True)
    n_used = np.zeros(len(p_start), dtype=np.int64)
    build = rows if design is None else design
    if extra is not None and len(extra):
        ex = extra[:, v]
        e = ex.shape[0]
        base = build

        def build(idx: np.ndarray) -> np.ndarray:  # terms, extras, target
            r = base(idx) if callable(base) else base[:, idx]
            out = np.empty((k + e + 1,) + idx.shape)
            out[:k] = r[:k]
            out[k:k + e] = ex[:, idx]
            out[k + e] = r[k]
            return out
        k_all = k + e
    else:
        k_all = k
    gram = np.zeros((len(ids), k_all, k_all))
    rhs = np.zeros((len(ids), k_all))
    yy = np.zeros(len(ids))
    cum = np.cumsum(p_stop - p_start)
    cuts = np.searchsorted(cum, np.arange(_BLOCK_SAMPLES, cum[-1] if len(cum) else 0,
                                          _BLOCK_SAMPLES), side="right")
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, len(p_start)], strict=True):
        if b <= a:
            continue
        M, n_used[a:b] = piece_normal_equations(build, t, p_start[a:b], p_stop[a:b], sos,
                                                trim, batch_samples=batch_samples)
        np.add.at(gram, inv[a:b], M[:, :k_all, :k_all])
        np.add.at(rhs, inv[a:b], M[:, :k_all, k_all])
        np.add.at(yy, inv[a:b], M[:, k_all, k_all])
        del M
    if not n_used.any():
        nmin = min_filter_length(sos) / prep.fs
        raise FitError(
            f"{prep.source}: no continuous stretch is long enough to band-pass and trim"
            f" (needs > {max(nmin, 2 * trim):.0f} s without gaps); use longer stretches,"
            " a higher low edge of band_hz, or a larger max_gap_s"
        )
    # Sum the pieces of each segment (a line flown twice, or cut by a gap, has several).
    counts = np.bincount(inv, weights=n_used).astype(np.int64)
    min_s = (1.0 / cfg.band_hz[0]) if cfg.min_segment_seconds is None else cfg.min_segment_seconds
    nmin = max(int(np.ceil(min_s * prep.fs)), 3 * k_all)
    ok = counts >= nmin
    too_short = {int(i): int(c) for i, c in zip(ids[~ok], counts[~ok], strict=True)}
    # Segments with no valid sample at all are too short too.
    all_ids = _segment_ids(prep.segment)
    for i in np.setdiff1d(all_ids, ids):
        too_short[int(i)] = 0
    if not ok.all():
        gram, rhs, yy = _compact(gram, ok), _compact(rhs, ok), yy[ok]
    return SegmentStats(ids[ok], counts[ok], gram, rhs, yy, too_short, nmin)


#: Samples of the pieces filtered per block by :func:`segment_normal_equations`.
_BLOCK_SAMPLES = 262_144


def _segment_ids(segment: np.ndarray, block: int = 1 << 18) -> np.ndarray:
    """Segment ids present (ascending; :func:`segment_counts`' ids), block by block.

    No full-length selection or sort: at 2e6 samples that saves 16-32 MB of temporaries.
    """
    found = [segment_counts(segment[a:a + block])[0] for a in range(0, len(segment), block)]
    return np.unique(np.concatenate(found)) if found else np.zeros(0, dtype=np.int64)


def _compact(x: np.ndarray, keep: np.ndarray, block: int = 1024) -> np.ndarray:
    """``x[keep]`` along axis 0 written into ``x`` itself (no second copy of ``x``).

    Returns the contiguous leading rows of ``x``; rows are moved forward in blocks, each
    gathered before it is written, so no row is overwritten before it is moved.
    """
    idx = np.flatnonzero(keep)
    for a in range(0, len(idx), block):
        rows = idx[a:a + block]
        x[a:a + len(rows)] = x[rows]
    return x[:len(idx)]



def segment_residual_std(stats: SegmentStats, coef: np.ndarray) -> np.ndarray:
    """Band-passed residual std per segment for coefficients ``coef`` (k,) or (m, k)."""
    c = np.broadcast_to(coef, stats.rhs.shape)
    sse = stats.yy - 2 * np.einsum("mk,mk->m", c, stats.rhs) + np.einsum(
        "mk,mkj,mj->m", c, stats.gram, c
    )
    return np.sqrt(np.maximum(sse, 0.0) / stats.n)
