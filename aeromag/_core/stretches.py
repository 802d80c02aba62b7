"""Continuous stretches and short-gap interpolation.

A *stretch* is a run of valid samples with no time gap: derivatives and filters never cross
its ends.
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


