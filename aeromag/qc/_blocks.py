"""Block means of a fast log for the block-rate manoeuvre detection, a chunk at a time."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

__all__: list[str] = []

#: Samples per chunk of the block means' passes over the full-rate log.
_CHUNK = 1 << 18


def _gap_runs(t: np.ndarray, max_gap_s: float) -> tuple[np.ndarray, np.ndarray]:
    """``run_bounds(find_stretches(t, None, max_gap_s))[:2]`` a chunk of steps at a time.

    The same runs (a new one after every step not ``<= max_gap_s``, NaN steps included)
    without the full-length step and label arrays (36 MB peak at 2e6 rows).
    """
    n = len(t)
    if n == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    brk = [np.zeros(1, dtype=np.int64)]
    for s in range(0, max(n - 1, 0), _CHUNK):
        dt = np.diff(t[s: s + _CHUNK + 1])
        brk.append(np.flatnonzero(~(dt <= max_gap_s)) + (s + 1))
    s0 = np.concatenate(brk)
    return s0, np.r_[s0[1:], n].astype(np.int64)


def _block_means(df: pd.DataFrame, t: np.ndarray, step: int, max_gap_s: float
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
    # Blocks of blocks (about _CHUNK samples each): the heading's and the time's full-length
    # float64 temporaries (five of 16 MB at 2e6 rows: 132 MB peak) are made a chunk at a time.
    # Each block's sum is one reduceat segment whatever the chunk, so the means are the same.
    k_bounds = np.r_[0:nb_all:max(1, _CHUNK // max(step, 1)), nb_all]

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
    for c in ("pitch", "roll", "flux_x", "flux_y", "flux_z"):
        if c in df.columns:
            x = df[c].to_numpy()
            xf = x if x.dtype.kind == "f" else x.astype(np.float64)
            out[c] = mean(lambda s, e, xf=xf: xf[s:e])
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
    small = pd.DataFrame(out, copy=False)  # no consolidated copy of the columns
    small.attrs = dict(df.attrs)
    return small, cnt
