"""Block means of a fast log for the manoeuvre detection, and filtering a block of runs at a time.

The runs (stretches, segment pieces) are found and filtered without full-length labels or
temporaries.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd

from .._core.filters import filter_stretches

__all__: list[str] = []

#: Samples per chunk of the block means' passes over the full-rate log.
CHUNK = 1 << 18


def _gap_runs(t: np.ndarray, max_gap_s: float) -> tuple[np.ndarray, np.ndarray]:
    """``run_bounds(find_stretches(t, None, max_gap_s))[:2]`` a chunk of steps at a time.

    The same runs (a new one after every step not ``<= max_gap_s``, NaN steps included)
    without the full-length step and label arrays (36 MB peak at 2e6 rows).
    """
    n = len(t)
    if n == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    brk = [np.zeros(1, dtype=np.int64)]
    for s in range(0, max(n - 1, 0), CHUNK):
        dt = np.diff(t[s: s + CHUNK + 1])
        brk.append(np.flatnonzero(~(dt <= max_gap_s)) + (s + 1))
    s0 = np.concatenate(brk)
    return s0, np.r_[s0[1:], n].astype(np.int64)


def block_means(df: pd.DataFrame, t: np.ndarray, step: int, max_gap_s: float
                 ) -> tuple[pd.DataFrame, np.ndarray]:
    """Means over blocks of ``step`` samples that never cross a time gap.

    Returns the reduced log (``time``: the block's mean time plus a large offset per stretch,
    so that the reduced log keeps every gap whatever the block length; headings as circular
    means about the block's first heading) and the number of samples in each block.
    """
    n = len(t)
    s0, s1 = _gap_runs(t, max_gap_s)
    nb = -(-(s1 - s0) // step)
    sid = np.repeat(np.arange(len(s0)), nb)
    off = np.cumsum(nb) - nb
    first = s0[sid] + step * (np.arange(int(nb.sum())) - off[sid])
    cnt = np.diff(np.r_[first, n])

    nb_all = len(first)
    ends = np.r_[first[1:], n]
    # Blocks of blocks (about CHUNK samples each): the heading's and the time's full-length
    # float64 temporaries (five of 16 MB at 2e6 rows: 132 MB peak) are made a chunk at a time.
    # Each block's sum is one reduceat segment whatever the chunk, so the means are the same.
    k_bounds = np.r_[0:nb_all:max(1, CHUNK // max(step, 1)), nb_all]

    def mean(get: Any) -> np.ndarray:
        """Block means of ``get(s, e)`` (samples ``[s, e)``, any float dtype) in float64."""
        res = np.empty(nb_all)
        for k0, k1 in zip(k_bounds[:-1], k_bounds[1:], strict=True):
            s, e = int(first[k0]), int(ends[k1 - 1])
            x = get(s, e)
            idx = first[k0:k1] - s
            # Summed in float64 from the column's own dtype (no float64 copy of float32).
            tot = np.add.reduceat(x, idx, dtype=np.float64)
            c = cnt[k0:k1]
            if np.isfinite(tot).all():  # then every sample is finite (NaN and inf propagate)
                res[k0:k1] = tot / c
                continue
            fin = np.isfinite(x)
            k = np.add.reduceat(fin, idx, dtype=np.float64)
            with np.errstate(invalid="ignore", divide="ignore"):
                res[k0:k1] = np.where(k > 0, np.add.reduceat(np.where(fin, x, 0), idx,
                                                             dtype=np.float64) / k, np.nan)
        return res

    out = {"time": mean(lambda s, e: t[s:e] - t[0]) + t[0] + 1e6 * sid}
    for c in ("pitch", "roll"):
        if c in df.columns:
            x = df[c].to_numpy()
            xf = x if x.dtype.kind == "f" else x.astype(np.float64)
            out[c] = mean(lambda s, e, xf=xf: xf[s:e])
    _heading_means(df, out, first, cnt, mean)
    # The detection reads the fluxgate only when the reduced log's attitude is not usable
    # (_detect_full's test, on the same means): then no block means of it (3 x 3.2 MB at
    # 2e6 rows, held through the detection).
    att = [out[c] for c in ("heading", "pitch", "roll") if c in out]
    if not (len(att) == 3 and float(np.mean(~np.isnan(np.column_stack(att)).any(axis=1)))
            > 0.5):
        for c in ("flux_x", "flux_y", "flux_z"):
            if c in df.columns:
                x = df[c].to_numpy()
                xf = x if x.dtype.kind == "f" else x.astype(np.float64)
                out[c] = mean(lambda s, e, xf=xf: xf[s:e])
    small = pd.DataFrame(out, copy=False)  # no consolidated copy of the columns
    small.attrs = dict(df.attrs)
    return small, cnt


def _heading_means(df: pd.DataFrame, out: dict[str, np.ndarray], first: np.ndarray,
                   cnt: np.ndarray, mean: Any) -> None:
    """``out["heading"]``: circular block means of the heading about each block's first."""
    if "heading" in df.columns:
        hcol = df["heading"].to_numpy()
        h_first = hcol[first].astype(np.float64)
        ref_first = np.where(np.isfinite(h_first), h_first, 0.0)

        def about_first(s: int, e: int) -> np.ndarray:
            k0 = int(np.searchsorted(first, s))
            k1 = int(np.searchsorted(first, e))
            d = hcol[s:e].astype(np.float64)
            d -= np.repeat(ref_first[k0:k1], cnt[k0:k1])
            d -= 360.0 * np.rint(d / 360.0)  # about the block's first heading, [-180, 180]
            return d

        out["heading"] = (mean(about_first) + ref_first) % 360.0


# --------------------------------------------------------------------------- pieces in blocks
def max_gap(t: np.ndarray, max_gap_s: float | None) -> float:
    """The largest step inside a stretch [s].

    ``max_gap_s``, else 5 median steps (as :func:`aeromag._core.stretches.find_stretches`).
    """
    if max_gap_s is not None:
        return max_gap_s
    dt = np.diff(np.asarray(t, dtype=np.float64))
    # the median of the steps, partitioned in their own buffer (no second copy)
    return 5.0 * float(np.median(dt, overwrite_input=True)) if len(dt) else 5.0


def run_edges(t: np.ndarray, valid: Callable[[int, int], np.ndarray], max_gap_s: float,
              split: Callable[[int, int], np.ndarray] | None = None,
              chunk: int = CHUNK) -> tuple[np.ndarray, np.ndarray]:
    """``[start, stop)`` of the stretches of a log, a chunk of samples at a time.

    The runs of :func:`~aeromag._core.stretches.find_stretches`, also cut where ``split``
    changes.
    The runs ``run_bounds`` finds in the stretch labels of ``band_passed``/``piece_labels``,
    without their full-length label, step and mask arrays (three to five of 16 MB at 2e6
    rows).

    Parameters
    ----------
    t : ndarray, shape (n,)
        Times [s].
    valid : callable
        ``valid(a, b)``: bool array, whether samples ``[a, b)`` are usable.
    max_gap_s : float
        Largest time step inside a run [s] (:func:`max_gap`).
    split : callable, optional
        ``split(a, b)``: labels of samples ``[a, b)``; a run also ends where they change.
    chunk : int
        Samples per chunk.

    Returns
    -------
    starts, stops : ndarray of int64
    """
    n = len(t)
    starts: list[np.ndarray] = []
    stops: list[np.ndarray] = []
    prev_ok = False
    for s in range(0, n, chunk):
        e = min(n, s + chunk)
        a = max(s - 1, 0)
        v = np.asarray(valid(a, e), dtype=bool)
        # cont[j]: sample a + j continues the run of sample a + j - 1 (j >= 1)
        cont = np.zeros(e - a, dtype=bool)
        np.less_equal(np.diff(t[a:e]), max_gap_s, out=cont[1:])
        cont[1:] &= v[1:]
        cont[1:] &= v[:-1]
        if split is not None:
            sp = np.asarray(split(a, e))
            cont[1:] &= sp[1:] == sp[:-1]
        j0 = 1 if s > 0 else 0  # the first sample of the log has no predecessor
        new = v[j0:] & ~cont[j0:]
        starts.append(np.flatnonzero(new) + (a + j0))
        end = v[:-1] & ~cont[1:]  # the run of sample a + j - 1 ends before a + j
        stops.append(np.flatnonzero(end) + (a + 1))
        prev_ok = bool(v[-1])
    if prev_ok:
        stops.append(np.array([n], dtype=np.int64))
    if not starts:
        e0 = np.zeros(0, dtype=np.int64)
        return e0, e0
    return (np.concatenate(starts).astype(np.int64, copy=False),
            np.concatenate(stops).astype(np.int64, copy=False) if stops
            else np.zeros(0, dtype=np.int64))


def run_blocks(starts: np.ndarray, stops: np.ndarray, chunk: int = CHUNK
               ) -> list[tuple[int, int, np.ndarray, np.ndarray]]:
    """Consecutive runs grouped into blocks of about ``chunk`` samples (a longer run alone).

    Returns
    -------
    list of (a, b, starts, stops)
        Block ``[a, b)`` and its runs' bounds relative to ``a``.
    """
    out = []
    i, k = 0, len(starts)
    while i < k:
        a = int(starts[i])
        j = int(np.searchsorted(stops, a + chunk, side="right"))
        j = max(j, i + 1)
        b = int(stops[j - 1])
        out.append((a, b, starts[i:j] - a, stops[i:j] - a))
        i = j
    return out


def local_labels(m: int, starts: np.ndarray, stops: np.ndarray) -> np.ndarray:
    """Run index of each of ``m`` samples (-1 outside the runs), int64."""
    mark = np.zeros(m + 1, dtype=np.int64)
    j = np.arange(1, len(starts) + 1, dtype=np.int64)
    mark[starts] += j
    mark[stops] -= j
    lab = np.cumsum(mark[:-1])
    lab -= 1
    return lab


def filter_runs(get: Callable[[int, int], np.ndarray], out: np.ndarray, starts: np.ndarray,
                stops: np.ndarray, sos: np.ndarray, *,
                each: Callable[[int, int, np.ndarray], None] | None = None,
                chunk: int = CHUNK) -> None:
    """Zero-phase filter every run on its own, a block of runs at a time, into ``out``.

    Every row of every run is filtered alone whatever the grouping
    (:func:`aeromag._core.filters.filter_stretches`), so ``out`` holds bitwise what one
    ``filter_stretches`` call over the whole log gives; samples outside the runs are left
    as they are (the caller fills ``out`` with NaN).

    Parameters
    ----------
    get : callable
        ``get(a, b)``: the rows of samples ``[a, b)``, shape (r, b - a).
    out : ndarray, shape (r, n)
        Filtered rows, written in place.
    starts, stops : ndarray of int
        The runs (:func:`run_edges`).
    sos : ndarray
        Second-order sections.
    each : callable, optional
        ``each(a, b, lab)``: called per block with its local run labels.
    chunk : int
        Samples per block.
    """
    for a, b, s0, s1 in run_blocks(starts, stops, chunk):
        lab = local_labels(b - a, s0, s1)
        out[:, a:b] = filter_stretches(get(a, b), lab, sos, axis=1)
        if each is not None:
            each(a, b, lab)
