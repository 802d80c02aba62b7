"""Moments of samples: masked standard deviations and streaming (Chan) accumulators."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["StreamingMoments", "masked_std"]


def masked_std(x: np.ndarray, mask: np.ndarray) -> float:
    """``np.std(x[mask])`` without the copy: moments over the mask's runs of True.

    A trimmed band-pass mask is a few long runs (the stretches minus their edges), so the
    runs are summed as slices (sums and dot products, no temporaries); equal to ``np.std`` to
    rounding.  A mask of many short runs is indexed as usual.

    Parameters
    ----------
    x : ndarray, shape (n,)
        Samples.
    mask : ndarray of bool, shape (n,)
        Samples to use.

    Returns
    -------
    float
        Population standard deviation (NaN when the mask is empty).
    """
    m = np.asarray(mask, dtype=bool)
    if m.size == 0:
        return float("nan")
    step = np.diff(m.view(np.int8))
    starts = np.flatnonzero(step == 1) + 1
    stops = np.flatnonzero(step == -1) + 1
    if m[0]:
        starts = np.r_[0, starts]
    if m[-1]:
        stops = np.r_[stops, len(m)]
    cnt = int((stops - starts).sum())
    if cnt == 0:
        return float("nan")
    if len(starts) > 1000:
        return float(np.std(x[m]))
    runs = list(zip(starts.tolist(), stops.tolist(), strict=True))
    mean = sum(float(x[a:b].sum()) for a, b in runs) / cnt
    s2 = sum(float(x[a:b] @ x[a:b]) for a, b in runs)
    if mean * mean > 1e-6 * s2 / cnt:  # far from zero mean: deviations, not raw squares
        return float(np.sqrt(sum(float(((x[a:b] - mean) ** 2).sum()) for a, b in runs) / cnt))
    # Band-passed data are centred: the raw second moment loses nothing to cancellation.
    return float(np.sqrt(max(s2 / cnt - mean * mean, 0.0)))



@dataclass
class StreamingMoments:
    """Streaming count / mean / M2 (Chan et al.'s parallel variance) of one or more series.

    Attributes
    ----------
    n : int
        Samples added.
    mean, m2 : ndarray, shape (k,)
        Mean and sum of squared deviations of each of the ``k`` series.
    """

    n: int = 0
    mean: np.ndarray = field(default_factory=lambda: np.zeros(2))
    m2: np.ndarray = field(default_factory=lambda: np.zeros(2))

    def add(self, x: np.ndarray) -> None:
        """Add a block of samples, shape (k, n_block)."""
        k = x.shape[1]
        if k == 0:
            return
        mb = x.mean(axis=1)
        m2b = ((x - mb[:, None]) ** 2).sum(axis=1)
        n = self.n + k
        delta = mb - self.mean
        self.mean = self.mean + delta * k / n
        self.m2 = self.m2 + m2b + delta**2 * self.n * k / n
        self.n = n

    def std(self) -> np.ndarray:
        """Population standard deviation of each series (NaN before any sample)."""
        return np.sqrt(self.m2 / self.n) if self.n else np.full(len(self.mean), np.nan)
