"""The computations behind the long-series figures of :mod:`aeromag.plot.compensation`.

Block by block, so that a figure of a 2e6-row log costs a few MB of temporaries above the
log, not several full-length arrays (issue 15): the uncompensated field, the blocks of rows
that :func:`aeromag.plot._style._streamed_envelopes` envelopes, the stretches and Welch PSD
of :func:`_welch`, and the term contributions (:func:`term_contributions`) with the
standard deviation of each group (:class:`NanStd`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
from scipy import signal

from .._core.filters import sampling_rate
from .._core.stretches import find_stretches
from ..compensation.terms import BIAS, EDDY_9, INDUCED_6, PERMANENT, design_matrix
from ..errors import InputError
from ._style import ENVELOPE_BLOCK, TimeAxis, median_step, new_stretch, stretch_gap_s

__all__ = ["TERM_BLOCK", "term_contributions"]


def field_before_rows(data: pd.DataFrame) -> Any:
    """``rows(a, b)``: the uncompensated field [nT] of rows ``[a, b)`` as float64.

    ``mag``, or the fluxgate's magnitude when there is no ``mag`` (row by row, the same
    values as ``np.linalg.norm`` of the whole ``(n, 3)`` float64 matrix).
    """
    if "mag" in data.columns:
        mag = data["mag"].to_numpy()  # as stored: no copy of a float64 column
        return lambda a, b: np.asarray(mag[a:b], dtype=np.float64)
    fl = [data[k].to_numpy() for k in ("flux_x", "flux_y", "flux_z")]
    return lambda a, b: np.linalg.norm(
        np.column_stack([f[a:b] for f in fl]).astype(np.float64, copy=False), axis=1)


def field_before(data: pd.DataFrame) -> np.ndarray:
    """The uncompensated field [nT] of every row (``mag``, else the fluxgate's magnitude)."""
    if "mag" in data.columns:
        return data["mag"].to_numpy(dtype=np.float64)
    rows, n = field_before_rows(data), len(data)
    out = np.empty(n)
    for a in range(0, n, ENVELOPE_BLOCK):
        out[a:a + ENVELOPE_BLOCK] = rows(a, min(n, a + ENVELOPE_BLOCK))
    return out


def time_blocks(t: np.ndarray, lines: Any, block: int = ENVELOPE_BLOCK) -> Any:
    """``blocks()`` for :func:`_streamed_envelopes`: time axis, stretch starts, ``lines(a, b)``.

    The stretches are ``find_stretches(t)``'s (gap: 5 median steps), decided block by block.
    """
    ax = TimeAxis(t)
    gap = stretch_gap_s(t)
    n = len(t)

    def blocks() -> Any:
        for a in range(0, n, block):
            b = min(n, a + block)
            yield a, ax(t[a:b]), new_stretch(t, a, b, gap), lines(a, b)
    return ax, blocks


def _finite_stretch_bounds(t: np.ndarray, x: np.ndarray, gap_s: float,
                           block: int = ENVELOPE_BLOCK) -> tuple[np.ndarray, np.ndarray]:
    """``run_bounds(find_stretches(t, np.isfinite(x)))``'s starts and stops, block by block.

    A stretch starts at a finite sample whose predecessor is missing, not finite or more than
    ``gap_s`` before it, and stops after a finite sample whose successor is; the same runs as
    the full-length labels, without them (16 MB and 50 MB of temporaries at 2e6 rows).
    """
    n = len(t)
    starts, stops = [], []
    for a in range(0, n, block):
        b = min(n, a + block)
        lo, hi = max(a - 1, 0), min(b + 1, n)
        ok = np.isfinite(x[lo:hi])
        cont = np.less_equal(np.diff(t[lo:hi]), gap_s)  # sample i + 1 continues sample i
        cont &= ok[1:]
        cont &= ok[:-1]
        i0 = a - lo  # index of row a in the window
        mine = ok[i0:i0 + b - a]
        first = mine & ~np.r_[False, cont][i0:i0 + b - a]
        last = mine & ~np.r_[cont, False][i0:i0 + b - a]
        starts.append(np.flatnonzero(first) + a)
        stops.append(np.flatnonzero(last) + a + 1)
    if not starts:
        e = np.zeros(0, dtype=np.int64)
        return e, e
    return np.concatenate(starts), np.concatenate(stops)


def _welch(x: np.ndarray, t: np.ndarray, nperseg: int,
           step_s: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Welch PSD averaged over continuous stretches (weighted by their length), vectorised.

    The segments of every stretch (Hann window, 50 % overlap, linear detrend, density scaling:
    :func:`scipy.signal.welch`'s defaults) are transformed in batches, each weighted by its
    stretch's length over its number of segments: a log cut into thousands of stretches costs
    a few FFT batches, not one call per stretch.  ``step_s`` is ``t``'s median step (computed
    when not given); the stretches are ``find_stretches(t, np.isfinite(x))``'s.
    """
    dt = median_step(t) if step_s is None else step_s
    if not dt > 0:
        sampling_rate(t)  # raises its error (too short, not increasing)
    fs = 1.0 / dt  # sampling_rate(t), without its two full-length temporaries
    starts, stops = _finite_stretch_bounds(t, x, 5.0 * dt)
    if len(starts) == 0:
        raise InputError("no continuous stretch long enough for a spectrum")
    nps = min(nperseg, int(max(stops - starts)))
    lens = stops - starts
    ok = lens >= max(nps, 2)
    if not ok.any():
        raise InputError("no continuous stretch long enough for a spectrum")
    step = nps - nps // 2
    k = (lens[ok] - nps) // step + 1
    first = np.cumsum(k) - k
    seg0 = np.repeat(starts[ok], k) + step * (np.arange(int(k.sum())) - np.repeat(first, k))
    weight = np.repeat(lens[ok] / k, k)
    win = signal.get_window("hann", nps)
    scale = 1.0 / (fs * float(win @ win))
    acc = np.zeros(nps // 2 + 1)
    xv = np.asarray(x, dtype=np.float64)
    # Linear detrend as a projection (the least-squares line of each segment removed: what
    # scipy.signal.detrend computes through lstsq, to rounding; 0.8 s -> 0.1 s on 2e6 rows).
    tc = np.arange(nps) - (nps - 1) / 2.0
    tc_w = tc / float(tc @ tc)
    rows = np.lib.stride_tricks.sliding_window_view(xv, nps)  # a view: row i is x[i:i + nps]
    for i in range(0, len(seg0), 2048):
        seg = rows[seg0[i:i + 2048]]  # the batch's segments (no index matrix)
        seg -= seg.mean(axis=-1, keepdims=True)
        slope = seg @ tc_w
        for r in range(0, len(seg), 256):  # the detrend line, a few rows at a time
            seg[r:r + 256] -= slope[r:r + 256, None] * tc
        seg *= win
        p = np.abs(np.fft.rfft(seg, axis=-1))
        del seg
        np.square(p, out=p)
        acc += weight[i:i + 2048] @ p
        del p
    acc *= scale / lens[ok].sum()
    acc[1:None if nps % 2 else -1] *= 2.0  # one-sided: all but DC (and Nyquist)
    return np.fft.rfftfreq(nps, 1.0 / fs), acc


#: The term groups drawn (and summed) by :func:`term_contributions`, in this order.
_GROUPS = {"permanent": PERMANENT, "induced": INDUCED_6, "eddy": EDDY_9, "bias": BIAS}

#: Rows per block of the term contributions (with 2 rows of context on either side).
TERM_BLOCK = 50_000


def term_groups(terms: tuple[str, ...]) -> dict[str, list[int]]:
    """Column indices of each non-empty term group, in :data:`_GROUPS` order."""
    idx = {g: [j for j, x in enumerate(terms) if x in m] for g, m in _GROUPS.items()}
    return {g: v for g, v in idx.items() if v}


def term_blocks(data: pd.DataFrame, terms: Any, coef: Any, block: int = TERM_BLOCK) -> Any:
    """Yield ``(a, b, {group: values [nT] of rows [a, b)})`` for consecutive blocks of rows.

    Each block's design matrix is built from the rows ``[a - 2, b + 2)`` (derivatives at the
    block's ends are the whole log's) with the stretches of ``find_stretches(t, ok)`` (``ok``:
    a finite fluxgate sample), decided inside the block with the whole log's gap: only
    changes of label matter to the derivatives, and those are the same.
    """
    terms = tuple(terms)
    c = np.asarray(coef, dtype=np.float64)
    t = data["time"].to_numpy(dtype=np.float64)
    # The fluxgate as stored (float32 in the report), converted block by block below.
    fcols = [data[k].to_numpy() for k in ("flux_x", "flux_y", "flux_z")]
    idx = term_groups(terms)
    n = len(t)
    gap = stretch_gap_s(t)
    pad = 2
    for a in range(0, n, block):
        b = min(n, a + block)
        lo, hi = max(0, a - pad), min(n, b + pad)
        f = [x[lo:hi] for x in fcols]
        sel = np.isfinite(f[0]) & np.isfinite(f[1]) & np.isfinite(f[2])
        if not sel.any():
            yield a, b, {g: np.full(b - a, np.nan) for g in idx}
            continue
        st = find_stretches(t[lo:hi], sel, max_gap_s=gap)
        flux = np.column_stack(f).astype(np.float64, copy=False)
        A = np.full((hi - lo, len(terms)), np.nan)
        A[sel] = design_matrix(flux[sel], t[lo:hi][sel], terms, stretch=st[sel])
        yield a, b, {g: (A[:, j] @ c[j])[a - lo:b - lo] for g, j in idx.items()}


def term_contributions(data: pd.DataFrame, terms: Any, coef: Any,
                       block: int = TERM_BLOCK) -> pd.DataFrame:
    """Permanent, induced and eddy parts of the modelled interference.

    Built block by block (a 16-column design matrix of the whole log never exists); each block
    is taken with a few samples of context so derivatives at its ends are the whole log's.

    Parameters
    ----------
    data : DataFrame
        Log with ``time`` [s] and ``flux_x/y/z`` [nT].
    terms : sequence of str
        Term names of the model.
    coef : array_like
        Coefficients [nT; eddy nT*s].
    block : int
        Samples per block.

    Returns
    -------
    DataFrame
        ``permanent``, ``induced``, ``eddy`` (and ``bias``) [nT] per sample; their sum is
        ``mag_tl``.
    """
    n = len(data)
    out = {g: np.full(n, np.nan) for g in term_groups(tuple(terms))}
    for a, b, parts in term_blocks(data, terms, coef, block):
        for g, y in parts.items():
            out[g][a:b] = y
    return pd.DataFrame(out, index=data.index, copy=False)  # the arrays, not a copy


class NanStd:
    """``np.nanstd`` of a series given block by block (Chan's pairwise update, float64)."""

    def __init__(self) -> None:
        self.n, self.mean, self.m2 = 0, 0.0, 0.0

    def add(self, y: np.ndarray) -> None:
        """Add a block of values (NaN ignored)."""
        v = y[~np.isnan(y)]
        m = len(v)
        if not m:
            return
        mu = float(v.mean())
        v -= mu
        m2 = float(v @ v)
        delta, tot = mu - self.mean, self.n + m
        self.mean += delta * m / tot
        self.m2 += m2 + delta * delta * self.n * m / tot
        self.n = tot

    def text(self) -> str | None:
        """The standard deviation as ``.2f`` text, None when rounding could change it.

        ``np.nanstd`` sums the whole series at once, this block by block: the two agree to
        ~1e-15 relative, so the text is theirs unless the value sits within 1e-9 of a rounding
        boundary (or is not finite); then the caller takes ``np.nanstd`` itself.
        """
        if not self.n:
            return None
        sd = float(np.sqrt(self.m2 / self.n))
        lo, hi = f"{sd * (1 - 1e-9):.2f}", f"{sd * (1 + 1e-9):.2f}"
        return lo if np.isfinite(sd) and lo == hi else None
