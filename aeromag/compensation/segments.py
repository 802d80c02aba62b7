"""Flight segments: the unit of the per-segment fit and of PCA screening.

A *segment* is a flight line (the ``line`` column) or, without one, a fixed window of
``segment_seconds`` inside a stretch (:mod:`aeromag._core.stretches`).
"""

from __future__ import annotations

import logging

import numpy as np

from ..errors import InputError

log = logging.getLogger(__name__)


def assign_segments(
    time_s: np.ndarray,
    stretch: np.ndarray,
    line: np.ndarray | None = None,
    segment_seconds: float = 60.0,
) -> np.ndarray:
    """Segment id per sample.

    With a ``line`` column the segment is the line number (a line interrupted by a gap stays
    one segment; each continuous piece is filtered on its own; a negative line number marks a
    turn or transit and belongs to no segment, with a warning); non-integer line numbers
    (e.g. ``1002.02``) are numbered 0, 1, ... in sorted order (see :func:`line_labels`).
    Without it, every stretch is cut into ``round(duration / segment_seconds)`` (at least
    one) windows of equal duration, numbered consecutively over the flight.

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Times [s].
    stretch : ndarray of int, shape (n,)
        Stretch labels (-1 = invalid sample).
    line : ndarray, shape (n,), optional
        Line numbers (NaN = no line).
    segment_seconds : float
        Window length without a line column [s].

    Returns
    -------
    ndarray of int64, shape (n,)
        Segment id, -1 for samples in no segment.
    """
    st = np.asarray(stretch)
    if line is not None:
        ln = np.asarray(line, dtype=np.float64)
        ok = np.isfinite(ln) & (st >= 0)
        seg = np.full(len(st), -1, dtype=np.int64)
        vals = ln[ok]
        if np.array_equal(vals, np.rint(vals)):
            seg[ok] = vals.astype(np.int64)
            neg = int((vals < 0).sum())
            if neg:
                log.warning("%d sample(s) have a negative line number (turns, by convention):"
                            " they belong to no segment and are not fitted", neg)
        else:
            # Line numbers such as 1002.02 / 1002.20 (SGL): number them 0, 1, ... in sorted
            # order so that distinct lines never merge; line_labels() gives the originals.
            _, codes = np.unique(vals, return_inverse=True)
            seg[ok] = codes
            log.info("non-integer line numbers: segments numbered 0..%d in line order",
                     int(codes.max()))
        return seg
    if segment_seconds <= 0:

        raise InputError(f"segment_seconds={segment_seconds}: must be positive")
    t = np.asarray(time_s, dtype=np.float64)
    seg = np.full(len(st), -1, dtype=np.int64)
    ok = st >= 0
    if not ok.any():
        return seg
    sid = st[ok]
    tt = t[ok]
    nst = int(sid.max()) + 1
    t0 = np.full(nst, np.inf)
    t1 = np.full(nst, -np.inf)
    np.minimum.at(t0, sid, tt)
    np.maximum.at(t1, sid, tt)
    dur = np.maximum(t1 - t0, 0.0)
    nwin = np.maximum(1, np.round(dur / segment_seconds)).astype(np.int64)
    width = np.where(dur > 0, dur / nwin, 1.0)
    win = np.minimum(((tt - t0[sid]) / width[sid]).astype(np.int64), nwin[sid] - 1)
    offset = np.r_[0, np.cumsum(nwin)[:-1]]
    seg[ok] = offset[sid] + win
    return seg


def line_labels(line: np.ndarray | None) -> dict[int, float] | None:
    """Map segment ids back to the original line numbers when those are not integers.

    Parameters
    ----------
    line : ndarray or None
        The ``line`` column.

    Returns
    -------
    dict or None
        ``{segment_id: line_number}``, or None when line numbers are integers (segment id =
        line number) or absent.
    """
    if line is None:
        return None
    ln = np.asarray(line, dtype=np.float64)
    fin = ln[np.isfinite(ln)]
    if fin.size == 0 or np.array_equal(fin, np.rint(fin)):  # integers: no sort needed
        return None
    vals = np.unique(fin)
    return {i: float(v) for i, v in enumerate(vals)}


def segment_counts(segment: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Segment ids present (ascending) and their sample counts (-1 = no segment).

    Parameters
    ----------
    segment : ndarray of int, shape (n,)
        Segment id per sample.

    Returns
    -------
    ids, counts : ndarray of int64
    """
    seg = np.asarray(segment)
    good = seg[seg >= 0]
    if good.size == 0:
        e = np.zeros(0, dtype=np.int64)
        return e, e
    top = int(good.max())
    if top <= 4 * good.size + 1024:  # small ids: a histogram, no sort
        counts = np.bincount(good, minlength=top + 1)
        ids = np.flatnonzero(counts)
        return ids.astype(np.int64), counts[ids].astype(np.int64)
    ids, counts = np.unique(good, return_counts=True)
    return ids.astype(np.int64), counts.astype(np.int64)

