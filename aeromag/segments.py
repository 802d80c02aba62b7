"""Continuous stretches, short-gap interpolation and flight segments.

A *stretch* is a run of valid samples with no time gap: derivatives and filters never cross
its ends.  A *segment* is the unit of the per-segment fit and of PCA screening: a flight line
(the ``line`` column) or, without one, a fixed window of ``segment_seconds`` inside a stretch.
"""

from __future__ import annotations

import logging

import numpy as np

log = logging.getLogger(__name__)


def find_stretches(
    time_s: np.ndarray, valid: np.ndarray | None = None, max_gap_s: float | None = None
) -> np.ndarray:
    """Label continuous stretches of valid samples.

    A new stretch starts after an invalid sample and wherever the time step exceeds
    ``max_gap_s`` (default: 5 times the median time step).

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Strictly increasing times [s].
    valid : ndarray of bool, shape (n,), optional
        Samples usable for fitting/applying; invalid samples get label -1.
    max_gap_s : float, optional
        Largest time step inside a stretch [s].

    Returns
    -------
    ndarray of int64, shape (n,)
        Stretch label (0, 1, ...) per sample, -1 for invalid samples.
    """
    t = np.asarray(time_s, dtype=np.float64)
    n = len(t)
    ok = np.ones(n, dtype=bool) if valid is None else np.asarray(valid, dtype=bool)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    dt = np.diff(t)
    if max_gap_s is None:
        med = float(np.median(dt)) if len(dt) else 1.0
        max_gap_s = 5.0 * med
    new = np.ones(n, dtype=bool)
    # A sample continues the previous stretch when both are valid and the step is small.
    np.less_equal(dt, max_gap_s, out=new[1:])
    del dt
    new[1:] &= ok[1:]
    new[1:] &= ok[:-1]
    np.logical_not(new[1:], out=new[1:])
    new &= ok
    lab = np.cumsum(new, dtype=np.int64)
    lab -= 1
    lab[~ok] = -1
    return lab


def interpolate_short_gaps(
    values: np.ndarray, time_s: np.ndarray, max_gap_s: float, *, copy: bool = True
) -> tuple[np.ndarray, int]:
    """Linearly interpolate NaN runs that last at most ``max_gap_s``.

    The duration of a run is the time between the valid samples that bound it; runs at the
    ends of the log, or longer than ``max_gap_s``, stay NaN (they will split stretches).

    Parameters
    ----------
    values : ndarray, shape (n,)
        Samples with NaN gaps.
    time_s : ndarray, shape (n,)
        Times [s].
    max_gap_s : float
        Longest gap filled [s]; 0 fills nothing.
    copy : bool
        False returns ``values`` itself (as float64) when there is nothing to fill, saving a
        copy of the column; the caller must then not modify the result.

    Returns
    -------
    filled : ndarray, shape (n,)
        A copy with short gaps filled (see ``copy``).
    n_filled : int
        Samples filled.
    """
    x = np.asarray(values, dtype=np.float64)
    t = np.asarray(time_s, dtype=np.float64)
    bad = ~np.isfinite(x)
    if not bad.any() or max_gap_s <= 0 or bad.all():
        return (x.copy() if copy else x), 0
    x = x.copy()
    n = len(x)
    idx = np.arange(n)
    prev = np.maximum.accumulate(np.where(~bad, idx, -1))
    nxt = np.minimum.accumulate(np.where(~bad, idx, n)[::-1])[::-1]
    inside = bad & (prev >= 0) & (nxt < n)
    span = np.full(n, np.inf)
    span[inside] = t[nxt[inside]] - t[prev[inside]]
    fill = inside & (span <= max_gap_s)
    if fill.any():
        good = ~bad
        x[fill] = np.interp(t[fill], t[good], x[good])
    return x, int(fill.sum())


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
        from .errors import InputError

        raise InputError(f"--segment-seconds {segment_seconds}: must be positive")
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
