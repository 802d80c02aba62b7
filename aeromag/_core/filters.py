"""Zero-phase Butterworth filters that never run across a time gap.

Filters come from :mod:`scipy.signal`: ``butter`` in second-order sections and the public
``sosfiltfilt`` (odd extension, steady-state initial conditions, forward and backward
passes).  Many rows are filtered on the package's one thread pool
(:func:`aeromag._core.parallel.parallel_map`; scipy's kernel releases the GIL).
Every function takes stretch labels (see :func:`aeromag._core.stretches.find_stretches`): each
continuous stretch is filtered on its own, and a stretch too short for the filter is left NaN.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence

import numpy as np

from ..errors import InputError
from .parallel import THREADED_MIN_SAMPLES, THREADS, parallel_map, signal_module
from .runs import run_bounds

log = logging.getLogger(__name__)


def sampling_rate(time_s: np.ndarray) -> float:
    """Nominal sampling rate: 1 / median time step [Hz].

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Strictly increasing times [s].

    Returns
    -------
    float
        Sampling rate [Hz].
    """
    t = np.asarray(time_s, dtype=np.float64)
    if len(t) < 2:
        raise InputError("need at least 2 samples to know the sampling rate")
    dt = float(np.median(np.diff(t)))
    if not dt > 0:
        raise InputError("time is not increasing; cannot derive a sampling rate")
    return 1.0 / dt


def butter_sos(
    kind: str, cutoff_hz: float | tuple[float, float], fs_hz: float, order: int = 4,
    *, source: str = "", option: str = "band_hz",
) -> np.ndarray:
    """Design a Butterworth filter in second-order sections, validated against Nyquist.

    Parameters
    ----------
    kind : {"bandpass", "lowpass", "highpass"}
        Filter type.
    cutoff_hz : float or (float, float)
        Cut-off frequency [Hz] (two edges for a band-pass).
    fs_hz : float
        Sampling rate [Hz].
    order : int
        Butterworth order (a band-pass has twice this order).
    source : str
        File name quoted in errors.
    option : str
        Parameter name quoted in errors (a Python keyword such as ``band_hz`` or
        ``lowpass_hz``; the command line shows its flag instead).

    Returns
    -------
    ndarray, shape (n_sections, 6)
        Second-order sections for :func:`scipy.signal.sosfiltfilt`.
    """
    nyq = fs_hz / 2.0
    where = f"{source}: " if source else ""
    edges = np.atleast_1d(np.asarray(cutoff_hz, dtype=np.float64))
    if kind == "bandpass":
        if edges.size != 2 or not (0 < edges[0] < edges[1]):
            raise InputError(f"{where}{option} {edges.tolist()}: need 0 < LOW < HIGH in Hz")
    elif edges.size != 1 or not edges[0] > 0:
        raise InputError(f"{where}{option} {edges.tolist()}: need a positive frequency in Hz")
    if edges.max() >= nyq:
        raise InputError(
            f"{where}{option}: {edges.max():g} Hz is not below the Nyquist frequency"
            f" {nyq:g} Hz of this log (sampled at {fs_hz:g} Hz); choose a lower cut-off"
        )
    wn = edges if kind == "bandpass" else float(edges[0])
    return signal_module().butter(order, wn, btype=kind, fs=fs_hz, output="sos")


def min_filter_length(sos: np.ndarray) -> int:
    """Fewest samples :func:`scipy.signal.sosfiltfilt` accepts with its default padding."""
    ntaps = 2 * len(sos) + 1
    ntaps -= min(int((sos[:, 2] == 0).sum()), int((sos[:, 5] == 0).sum()))
    return 3 * ntaps + 1


def filter_stretches(
    x: np.ndarray, stretch: np.ndarray, sos: np.ndarray, *, axis: int = 0
) -> np.ndarray:
    """Zero-phase filter each continuous stretch separately.

    Parameters
    ----------
    x : ndarray
        Samples along ``axis`` (for speed pass a (m, n) array with ``axis=1``).
    stretch : ndarray of int, shape (n,)
        Stretch labels; negative = invalid sample (output NaN).
    sos : ndarray
        Second-order sections (:func:`butter_sos`).
    axis : int
        The sample axis of ``x``.

    Returns
    -------
    ndarray
        Filtered samples, NaN outside stretches and on stretches too short to filter.
    """
    xa = np.asarray(x, dtype=np.float64)
    starts, stops, _ = run_bounds(stretch)
    nmin = min_filter_length(sos)
    n = xa.shape[axis]
    if len(starts) == 1 and starts[0] == 0 and stops[0] == n and n >= nmin \
            and np.isfinite(xa).all():
        return _sosfiltfilt(sos, xa, axis)  # one stretch over everything: no copies
    out = np.full_like(xa, np.nan)
    short = 0
    batched = np.zeros(len(starts), dtype=bool)
    if xa.ndim == 2 and len(starts) >= _MIN_BATCHED_STRETCHES:
        batched, short = _filter_equal_lengths(xa, out, starts, stops, sos, axis, nmin)
    for a, b in zip(starts[~batched], stops[~batched], strict=True):
        if b - a < nmin:
            short += 1
            continue
        sl = [slice(None)] * xa.ndim
        sl[axis] = slice(a, b)
        seg = xa[tuple(sl)]
        if not np.all(np.isfinite(seg)):
            # NaN inside a stretch would poison the whole stretch: leave it NaN.
            short += 1
            continue
        out[tuple(sl)] = _sosfiltfilt(sos, seg, axis)
    if short:
        log.info("%d stretch(es) too short or not finite for the filter were left NaN", short)
    return out


#: Stretches from which :func:`filter_stretches` stacks those of one length into one call.
_MIN_BATCHED_STRETCHES = 8
#: Samples per stretch up to which stretches of one length are stacked (longer ones are
#: filtered one by one, their rows on the thread pool).
_BATCH_MAX_LENGTH = 65_536


def _filter_equal_lengths(xa: np.ndarray, out: np.ndarray, starts: np.ndarray,
                          stops: np.ndarray, sos: np.ndarray, axis: int, nmin: int,
                          batch_samples: int = 65_536) -> tuple[np.ndarray, int]:
    """Filter the short stretches of ``xa`` (2-D) in stacks of one length, into ``out``.

    A log cut into segments has thousands of stretches of a few lengths: one filter call per
    stack instead of one per stretch (1,667 pieces of a 1e6-row log: 1,669 calls, now 3).
    Every row is filtered on its own either way, so the values are bitwise the same.  Returns
    which stretches were handled here and how many of them were too short or not finite.
    """
    xr = xa if axis % 2 == 1 else xa.T  # rows: (r, n)
    res = out if axis % 2 == 1 else out.T
    r = xr.shape[0]
    lens = stops - starts
    handled = (lens < nmin) | (lens <= _BATCH_MAX_LENGTH)
    short = int((lens < nmin).sum())
    tasks = []
    for L in np.unique(lens[handled & (lens >= nmin)]):
        sel = np.flatnonzero(lens == L)
        per = max(1, batch_samples // (int(L) * max(r, 1)))
        tasks += [sel[b0:b0 + per] for b0 in range(0, len(sel), per)]
    bad = np.zeros(len(starts), dtype=bool)

    def run(sel: np.ndarray) -> None:
        L = int(lens[sel[0]])
        idx = starts[sel][:, None] + np.arange(L)  # (q, L)
        rows = xr[:, idx]  # (r, q, L)
        fin = np.isfinite(rows).all(axis=(0, 2))
        if not fin.all():  # NaN inside a stretch would poison it: leave it NaN
            bad[sel[~fin]] = True
            rows, idx = rows[:, fin], idx[fin]
            if not len(idx):
                return
        q = len(idx)
        res[:, idx] = zero_phase_rows(sos, rows.reshape(r * q, L)).reshape(r, q, L)

    if len(tasks) > 1 and xr.size >= THREADED_MIN_SAMPLES:
        parallel_map(run, tasks)
    else:
        for task in tasks:
            run(task)
    return handled, short + int(bad.sum())


def pad_length(sos: np.ndarray) -> int:
    """Samples of odd extension that :func:`scipy.signal.sosfiltfilt` adds at each end."""
    return min_filter_length(sos) - 1


def zero_phase_rows(sos: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Zero-phase filter every row of ``x`` (:func:`scipy.signal.sosfiltfilt`, axis 1).

    Parameters
    ----------
    sos : ndarray, shape (n_sections, 6)
        Second-order sections.
    x : ndarray, shape (m, L)
        Rows to filter; ``L`` must exceed :func:`pad_length`.

    Returns
    -------
    ndarray, shape (m, L)
        Filtered rows.
    """
    return signal_module().sosfiltfilt(sos, np.asarray(x, dtype=np.float64), axis=1)


def _sosfiltfilt(sos: np.ndarray, x: np.ndarray, axis: int) -> np.ndarray:
    """``sosfiltfilt`` along ``axis``, the rows of a large 2-D array split over threads."""
    if x.ndim != 2 or x.size < THREADED_MIN_SAMPLES or THREADS < 2:
        return signal_module().sosfiltfilt(sos, x, axis=axis)
    rows = x if axis % 2 == 1 else x.T
    m = rows.shape[0]
    if m < 2:
        return signal_module().sosfiltfilt(sos, x, axis=axis)
    parts = np.array_split(np.arange(m), min(THREADS, m))
    out = np.concatenate(parallel_map(lambda i: zero_phase_rows(sos, rows[i]), parts))
    return out if axis % 2 == 1 else out.T


def filter_stretches_each(
    series: Sequence[np.ndarray], stretch: np.ndarray, sos: np.ndarray
) -> list[np.ndarray]:
    """:func:`filter_stretches` of several 1-D series at once, one per thread.

    Parameters
    ----------
    series : sequence of ndarray, each shape (n,)
        Samples.
    stretch : ndarray of int, shape (n,)
        Stretch labels (negative = invalid).
    sos : ndarray
        Second-order sections.

    Returns
    -------
    list of ndarray
        The filtered series, in order.
    """

    def one(x: np.ndarray) -> np.ndarray:
        return filter_stretches(np.asarray(x, dtype=np.float64)[None, :], stretch, sos,
                                axis=1)[0]

    if len(stretch) < 100_000:
        return [one(x) for x in series]
    return parallel_map(one, list(series))


def bandpass_stretches(
    x: np.ndarray, time_s: np.ndarray, stretch: np.ndarray,
    band_hz: tuple[float, float] = (0.1, 0.9), order: int = 4,
) -> np.ndarray:
    """Band-pass a 1-D series stretch by stretch (zero phase).

    Parameters
    ----------
    x : ndarray, shape (n,)
        Samples.
    time_s : ndarray, shape (n,)
        Times [s] (for the sampling rate).
    stretch : ndarray of int, shape (n,)
        Stretch labels (negative = invalid).
    band_hz : (float, float)
        Pass band [Hz].
    order : int
        Butterworth order.

    Returns
    -------
    ndarray, shape (n,)
        Band-passed samples (NaN where not filterable).
    """
    sos = butter_sos("bandpass", band_hz, sampling_rate(time_s), order)
    return filter_stretches(np.asarray(x, dtype=np.float64)[None, :], stretch, sos, axis=1)[0]


def lowpass_stretches(
    x: np.ndarray, time_s: np.ndarray, stretch: np.ndarray, cutoff_hz: float, order: int = 4,
    *, fs_hz: float | None = None,
) -> np.ndarray:
    """Low-pass a 1-D series stretch by stretch (zero phase; keeps the level).

    Parameters
    ----------
    x : ndarray, shape (n,)
        Samples.
    time_s : ndarray, shape (n,)
        Times [s].
    stretch : ndarray of int, shape (n,)
        Stretch labels (negative = invalid).
    cutoff_hz : float
        Cut-off frequency [Hz].
    order : int
        Butterworth order.
    fs_hz : float, optional
        Sampling rate [Hz] when already known (default: from ``time_s``).

    Returns
    -------
    ndarray, shape (n,)
        Low-passed samples; stretches too short to filter are returned unfiltered.
    """
    xv = np.asarray(x, dtype=np.float64)
    fs = sampling_rate(time_s) if fs_hz is None else fs_hz
    sos = butter_sos("lowpass", cutoff_hz, fs, order, option="lowpass_hz")
    out = filter_stretches(xv[None, :], stretch, sos, axis=1)[0]
    # A stretch too short to filter keeps its unfiltered values rather than vanishing.
    fill = np.isnan(out) & (np.asarray(stretch) >= 0)
    out[fill] = xv[fill]
    return out


def trim_mask(stretch: np.ndarray, time_s: np.ndarray, trim_s: float) -> np.ndarray:
    """Mask of samples at least ``trim_s`` seconds from either end of their stretch.

    Parameters
    ----------
    stretch : ndarray of int, shape (n,)
        Stretch labels (negative = invalid, never kept).
    time_s : ndarray, shape (n,)
        Times [s].
    trim_s : float
        Edge length dropped at each end of every stretch [s].

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    t = np.asarray(time_s, dtype=np.float64)
    keep = np.asarray(stretch) >= 0
    starts, stops, _ = run_bounds(stretch)
    if trim_s <= 0 or len(starts) == 0:
        return keep
    n = len(t)
    if n > 1 and not (t[1:] > t[:-1]).all():
        return _trim_mask_any(t, keep, starts, stops, trim_s)
    # Time increases, so each stretch keeps one contiguous range [lo, hi): found by binary
    # search, then marked with a difference array (a few passes, no n-sized gathers).  The
    # ends are then nudged so the test is exactly ``t - t_start >= trim`` and
    # ``t_end - t >= trim`` (rounding of ``t_start + trim`` can differ by one sample).
    t0 = t[starts]
    t1 = t[stops - 1]
    lo = np.clip(np.searchsorted(t, t0 + trim_s, side="left"), starts, stops)
    hi = np.clip(np.searchsorted(t, t1 - trim_s, side="right"), starts, stops)
    for _ in range(2):
        back = (lo > starts) & (t[np.maximum(lo - 1, 0)] - t0 >= trim_s)
        lo[back] -= 1
        fwd = (lo < stops) & (t[np.minimum(lo, n - 1)] - t0 < trim_s)
        lo[fwd] += 1
        up = (hi < stops) & (t1 - t[np.minimum(hi, n - 1)] >= trim_s)
        hi[up] += 1
        down = (hi > starts) & (t1 - t[np.maximum(hi - 1, 0)] < trim_s)
        hi[down] -= 1
    ok = hi > lo
    mark = np.zeros(len(t) + 1, dtype=np.int32)
    np.add.at(mark, lo[ok], 1)
    np.add.at(mark, hi[ok], -1)
    return np.cumsum(mark[:-1], dtype=np.int32) > 0


def _trim_mask_any(t: np.ndarray, keep: np.ndarray, starts: np.ndarray, stops: np.ndarray,
                   trim_s: float) -> np.ndarray:
    """:func:`trim_mask` for times that do not increase (gathers per sample)."""
    lens = stops - starts
    t0 = np.repeat(t[starts], lens)
    t1 = np.repeat(t[stops - 1], lens)
    idx = np.flatnonzero(keep)  # the runs cover exactly the valid samples, in order
    inner = np.zeros(len(t), dtype=bool)
    inner[idx] = (t[idx] - t0 >= trim_s) & (t1 - t[idx] >= trim_s)
    return keep & inner


def bandpass_pieces(
    A: np.ndarray, y: np.ndarray, time_s: np.ndarray, stretch: np.ndarray,
    band_hz: tuple[float, float] = (0.1, 0.9), order: int = 4, trim_s: float | None = None,
) -> tuple[np.ndarray, np.ndarray, float, int]:
    """Band-pass the design matrix and target per stretch and form the normal equations.

    Parameters
    ----------
    A : ndarray, shape (n, k)
        Design matrix.
    y : ndarray, shape (n,)
        Target [nT].
    time_s : ndarray, shape (n,)
        Times [s].
    stretch : ndarray of int, shape (n,)
        Stretch labels.
    band_hz : (float, float)
        Pass band [Hz].
    order : int
        Butterworth order.
    trim_s : float, optional
        Filter edge dropped at each stretch end [s]; default ``0.5 / band_hz[0]``.

    Returns
    -------
    gram : ndarray, shape (k, k)
        ``Af.T @ Af``.
    rhs : ndarray, shape (k,)
        ``Af.T @ yf``.
    yy : float
        ``yf @ yf`` [nT^2].
    n : int
        Samples used.
    """
    sos = butter_sos("bandpass", band_hz, sampling_rate(time_s), order)
    X = np.vstack([np.asarray(A, dtype=np.float64).T, np.asarray(y, dtype=np.float64)[None, :]])
    Xf = filter_stretches(X, stretch, sos, axis=1)
    trim = 0.5 / band_hz[0] if trim_s is None else trim_s
    use = trim_mask(stretch, time_s, trim) & np.all(np.isfinite(Xf), axis=0)
    Xu = Xf[:, use]
    k = A.shape[1]
    M = Xu @ Xu.T
    return M[:k, :k], M[:k, k], float(M[k, k]), int(use.sum())


def piece_normal_equations(
    X: np.ndarray | Callable[[np.ndarray], np.ndarray], time_s: np.ndarray,
    starts: np.ndarray, stops: np.ndarray, sos: np.ndarray, trim_s: float, *,
    batch_samples: int = 65_536,
) -> tuple[np.ndarray, np.ndarray]:
    """Zero-phase filter every piece on its own and form its cross-product matrix.

    Pieces of equal length are stacked and filtered in one call (many short segments cost no
    more than one long one); the cross products are batched matrix products.  The result is
    identical to filtering each piece with ``sosfiltfilt`` and forming ``Xf @ Xf.T``.

    Parameters
    ----------
    X : ndarray, shape (r, n), or callable
        Rows to filter (e.g. the design matrix's terms and the target), samples along axis 1;
        or a function ``rows(idx)`` that builds them for the sample indices ``idx`` (shape
        (q, L): q pieces of L samples) and returns shape (r, q, L), so that the whole (r, n)
        array never exists (memory bounded by ``batch_samples``).
    time_s : ndarray, shape (n,)
        Times [s] (for the edge trimming).
    starts, stops : ndarray of int, shape (p,)
        Half-open sample ranges of the pieces.
    sos : ndarray
        Second-order sections.
    trim_s : float
        Samples within this many seconds of either end of a piece are left out [s].
    batch_samples : int
        Samples stacked per filtering call.  It bounds the extra memory, and small batches
        reuse the allocator's memory instead of page-faulting fresh 100 MB temporaries on every
        call (at 1e6 samples: 0.55 s steady, against 0.5-1.9 s with 1e6-sample batches).

    Returns
    -------
    M : ndarray, shape (p, r, r)
        ``Xf_p @ Xf_p.T`` over each piece's kept samples (zero for pieces too short to filter).
    n_used : ndarray of int, shape (p,)
        Samples kept per piece.
    """
    build = X if callable(X) else (lambda idx: X[:, idx])
    r = build(np.asarray(starts[:1])[:, None]).shape[0] if len(starts) else 0
    p = len(starts)
    M = np.zeros((p, r, r))
    n_used = np.zeros(p, dtype=np.int64)
    lens = np.asarray(stops) - np.asarray(starts)
    nmin = min_filter_length(sos)
    # Batches of pieces of one length; each is built, filtered and reduced on a pool thread
    # (the filter kernel, numpy and BLAS release the GIL) and writes its own rows of M.
    tasks = []
    for L in np.unique(lens):
        if L < nmin:
            continue
        sel = np.flatnonzero(lens == L)
        per = max(1, batch_samples // int(L))
        tasks += [sel[b0:b0 + per] for b0 in range(0, len(sel), per)]

    def run(s: np.ndarray) -> None:
        q = len(s)
        L = int(lens[s[0]])
        idx = starts[s][:, None] + np.arange(L)  # (q, L)
        Xf = zero_phase_rows(sos, build(idx).reshape(r * q, L)).reshape(r, q, L)
        tg = time_s[idx]
        keep = ((tg - tg[:, :1]) >= trim_s) & ((tg[:, -1:] - tg) >= trim_s)
        lo = np.argmax(keep, axis=1)
        hi = L - np.argmax(keep[:, ::-1], axis=1)
        n_used[s] = keep.sum(axis=1)
        if (lo == lo[0]).all() and (hi == hi[0]).all() and (n_used[s] == hi - lo).all():
            # Every piece keeps the same contiguous range (the usual case): slice it.
            Xq = np.ascontiguousarray(np.transpose(Xf[:, :, lo[0]:hi[0]], (1, 0, 2)))
        else:
            Xq = np.ascontiguousarray(np.transpose(Xf * keep[None], (1, 0, 2)))  # (q, r, L)
        M[s] = Xq @ np.transpose(Xq, (0, 2, 1))

    parallel_map(run, tasks)
    return M, n_used
