"""Band-limited and white-noise levels of a field, and grouped standard deviations.

* :func:`band_passed` - zero-phase band-pass per continuous stretch (never across a gap);
* :func:`fourth_difference_noise` - white-noise level ``std(d4 x) / sqrt(70)``;
* :func:`grouped_std` - std per label in one vectorised pass.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .._core.filters import butter_sos, sampling_rate, trim_mask
from ._blocks import filter_runs, max_gap, run_edges

__all__ = ["FOURTH_DIFF_NORM", "band_passed", "fourth_difference_noise", "grouped_std"]

#: Divisor turning the std of a fourth difference into the std of white noise: sqrt(70).
FOURTH_DIFF_NORM = float(np.sqrt(70.0))


def band_passed(
    x: np.ndarray, time_s: np.ndarray, band_hz: tuple[float, float], order: int = 4,
    max_gap_s: float | None = None, trim_s: float = 0.0, fs_hz: float | None = None,
    split: np.ndarray | None = None,
) -> np.ndarray:
    """Zero-phase band-pass of a series, per continuous finite stretch.

    Parameters
    ----------
    x : ndarray, shape (n,)
        Samples [nT].
    time_s : ndarray, shape (n,)
        Times [s].
    band_hz : (float, float)
        Pass band [Hz].
    order : int
        Butterworth order.
    max_gap_s : float, optional
        A longer time step starts a new stretch [s].
    trim_s : float
        Samples closer than this to a stretch end become NaN [s].
    fs_hz : float, optional
        Sampling rate [Hz] when known (default: from ``time_s``).
    split : ndarray of int, shape (n,), optional
        A stretch also ends wherever this label changes (e.g. each dropped segment's id, -1
        elsewhere: a fault then never rings through the filter into its neighbours).

    Returns
    -------
    ndarray, shape (n,)
        Band-passed samples [nT], NaN where not filterable.
    """
    xv = np.asarray(x, dtype=np.float64)
    sp = None if split is None else np.asarray(split)
    return band_passed_blocks(lambda a, b: xv[a:b], len(xv), time_s, band_hz, order,
                              max_gap_s, trim_s, fs_hz,
                              None if sp is None else (lambda a, b: sp[a:b]))


def band_passed_blocks(
    get: Callable[[int, int], np.ndarray], n: int, time_s: np.ndarray,
    band_hz: tuple[float, float], order: int = 4, max_gap_s: float | None = None,
    trim_s: float = 0.0, fs_hz: float | None = None,
    split: Callable[[int, int], np.ndarray] | None = None,
) -> np.ndarray:
    """:func:`band_passed` of a series given a block at a time.

    The stretches are found and filtered a block of them at a time
    (:func:`aeromag.qc._blocks.filter_runs`), bitwise as one pass over the whole log: the
    only full-length array is the result (at 2e6 rows the stretch labels, their steps and
    the filter's copy peaked at +36 MB).

    Parameters
    ----------
    get : callable
        ``get(a, b)``: samples ``[a, b)`` [nT], float64.
    n : int
        Samples.
    time_s, band_hz, order, max_gap_s, trim_s, fs_hz
        As :func:`band_passed`.
    split : callable, optional
        ``split(a, b)``: the labels of :func:`band_passed`'s ``split`` for samples ``[a, b)``.

    Returns
    -------
    ndarray, shape (n,)
        Band-passed samples [nT], NaN where not filterable.
    """
    t = np.asarray(time_s, dtype=np.float64)
    fs = sampling_rate(t) if fs_hz is None else fs_hz
    sos = butter_sos("bandpass", band_hz, fs, order)
    g = max_gap(t, max_gap_s)  # before the output (a full-length step array without a gap)
    out = np.full((1, n), np.nan)

    def trimmed(a: int, b: int, lab: np.ndarray) -> None:
        out[0, a:b][~trim_mask(lab, t[a:b], trim_s)] = np.nan

    st, sp = run_edges(t, lambda a, b: np.isfinite(get(a, b)), g, split)
    filter_runs(lambda a, b: get(a, b)[None, :], out, st, sp, sos,
                each=trimmed if trim_s > 0 else None)
    return out[0]


def fourth_difference_noise(x: np.ndarray, time_s: np.ndarray,
                            max_gap_s: float | None = None, *,
                            minus: np.ndarray | None = None) -> float:
    """White-noise level from the fourth difference: ``std(d4 x) / sqrt(70)`` [nT].

    Differences spanning a time gap or a NaN are ignored.

    Parameters
    ----------
    x : ndarray, shape (n,)
        Samples [nT].
    time_s : ndarray, shape (n,)
        Times [s].
    max_gap_s : float, optional
        Longest time step inside a stretch [s].
    minus : ndarray, shape (n,), optional
        The noise of ``x - minus`` [nT], the difference taken a block at a time.

    Returns
    -------
    float
        Noise std [nT] (NaN when fewer than 5 contiguous samples).
    """
    xv = np.asarray(x, dtype=np.float64)
    mv = None if minus is None else np.asarray(minus, dtype=np.float64)
    t = np.asarray(time_s, dtype=np.float64)
    if len(xv) < 5:
        return float("nan")
    g = max_gap(t, max_gap_s)
    # Moments of the fourth difference block by block, in one pass (no n-sized temporaries):
    # sums of (d - K) and (d - K)^2 about K, the first block's mean, so the variance has no
    # cancellation (the fourth difference of a log is centred near 0 anyway).  A difference
    # is used when its five samples lie in one stretch of find_stretches: all finite, and
    # no step between them above the gap (tested per block, no full-length labels).
    n = len(xv) - 4
    step = 1 << 16
    cnt = 0
    s1 = 0.0
    s2 = 0.0
    shift = None
    for a in range(0, n, step):
        b = min(n, a + step)
        seg = xv[a:b + 4] if mv is None else xv[a:b + 4] - mv[a:b + 4]
        fin = np.isfinite(seg)
        d4 = np.diff(np.where(fin, seg, 0.0), n=4)
        ok = np.less_equal(np.diff(t[a:b + 4]), g)
        same = fin[:-4] & fin[4:]
        for k in range(1, 4):
            same &= fin[k:k + b - a]
        for k in range(4):
            same &= ok[k:k + b - a]
        d = d4 if same.all() else d4[same]
        if d.size == 0:
            continue
        if shift is None:
            shift = float(d.mean())
        d -= shift
        cnt += d.size
        s1 += float(d.sum())
        s2 += float(d @ d)
    if cnt == 0:
        return float("nan")
    var = max(s2 / cnt - (s1 / cnt) ** 2, 0.0)
    return float(np.sqrt(var) / FOURTH_DIFF_NORM)


def grouped_std(x: np.ndarray, groups: np.ndarray) -> dict[int, float]:
    """Std of ``x`` per non-negative group label, ignoring NaN (vectorised bincount).

    Parameters
    ----------
    x : ndarray, shape (n,)
        Samples.
    groups : ndarray of int, shape (n,)
        Group labels (negative = none).

    Returns
    -------
    dict
        ``{group: std}``.
    """
    g = np.asarray(groups)
    ok = np.isfinite(x) & (g >= 0)
    if not ok.any():
        return {}
    own = not ok.all()  # xk is then our own copy: its squares go in place (16 MB at 2e6)
    if not own:  # no copies of the whole log
        gk, xk = g.astype(np.int64, copy=False), np.asarray(x)
    else:
        gk = g[ok].astype(np.int64, copy=False)
        xk = np.asarray(x)[ok]
    del ok

    def squares() -> np.ndarray:
        return np.multiply(xk, xk, out=xk) if own else xk * xk

    top = int(gk.max())
    if top <= 4 * gk.size + 1024:  # small labels: histograms, no sort
        n = np.bincount(gk, minlength=top + 1)
        ids = np.flatnonzero(n)
        s1 = np.bincount(gk, xk, minlength=top + 1)[ids]
        s2 = np.bincount(gk, squares(), minlength=top + 1)[ids]
        n = n[ids]
    else:
        ids, inv = np.unique(gk, return_inverse=True)
        del gk
        n = np.bincount(inv)
        s1 = np.bincount(inv, xk)
        s2 = np.bincount(inv, squares())
    mean = s1 / n
    std = np.sqrt(np.maximum(s2 / n - mean * mean, 0.0))
    return {int(i): float(s) for i, s in zip(ids, std, strict=True)}
