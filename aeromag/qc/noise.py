"""Band-limited and white-noise levels of a field, and grouped standard deviations.

* :func:`band_passed` - zero-phase band-pass per continuous stretch (never across a gap);
* :func:`fourth_difference_noise` - white-noise level ``std(d4 x) / sqrt(70)``;
* :func:`grouped_std` - std per label in one vectorised pass.
"""

from __future__ import annotations

import numpy as np

from .._core.filters import butter_sos, filter_stretches, sampling_rate, trim_mask
from .._core.stretches import find_stretches

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
    t = np.asarray(time_s, dtype=np.float64)
    st = find_stretches(t, np.isfinite(xv), max_gap_s)
    if split is not None and len(st) > 1:
        # The same labels as cumsum(...) - 1 then where(st >= 0, ., -1), in place: three
        # full-length int64 temporaries fewer (16 MB each at 2e6 rows).
        sp = np.asarray(split)
        new = np.empty(len(st), dtype=bool)
        new[0] = True
        np.not_equal(st[1:], st[:-1], out=new[1:])
        new[1:] |= sp[1:] != sp[:-1]
        neg = st < 0
        np.cumsum(new, out=st)  # st's own buffer (its signs kept in neg)
        del new
        st -= 1
        st[neg] = -1
    fs = sampling_rate(t) if fs_hz is None else fs_hz
    sos = butter_sos("bandpass", band_hz, fs, order)
    out = filter_stretches(xv[None, :], st, sos, axis=1)[0]
    if trim_s > 0:
        out[~trim_mask(st, t, trim_s)] = np.nan
    return out


def fourth_difference_noise(x: np.ndarray, time_s: np.ndarray,
                            max_gap_s: float | None = None) -> float:
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

    Returns
    -------
    float
        Noise std [nT] (NaN when fewer than 5 contiguous samples).
    """
    xv = np.asarray(x, dtype=np.float64)
    st = find_stretches(np.asarray(time_s, dtype=np.float64), np.isfinite(xv), max_gap_s)
    if len(xv) < 5:
        return float("nan")
    # Moments of the fourth difference block by block, in one pass (no n-sized temporaries):
    # sums of (d - K) and (d - K)^2 about K, the first block's mean, so the variance has no
    # cancellation (the fourth difference of a log is centred near 0 anyway).
    n = len(xv) - 4
    step = 1 << 16
    cnt = 0
    s1 = 0.0
    s2 = 0.0
    shift = None
    for a in range(0, n, step):
        b = min(n, a + step)
        seg = xv[a:b + 4]
        d4 = np.diff(np.where(np.isfinite(seg), seg, 0.0), n=4)
        same = (st[a + 4:b + 4] == st[a:b]) & (st[a + 4:b + 4] >= 0)
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
