"""Runs of a label or of a boolean mask: the one "runs" helper of the package.

A *run* is a maximal half-open range ``[start, stop)`` of consecutive samples sharing one value.
"""

from __future__ import annotations

import numpy as np

__all__ = ["run_bounds", "true_runs"]


def run_bounds(labels: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Runs of equal, non-negative labels.

    Parameters
    ----------
    labels : ndarray of int, shape (n,)
        Label per sample; negative labels (invalid samples) belong to no run.

    Returns
    -------
    starts, stops, values : ndarray
        Half-open ``[start, stop)`` sample ranges of each run and its label.
    """
    lab = np.asarray(labels)
    n = len(lab)
    if n == 0:
        e = np.zeros(0, dtype=np.int64)
        return e, e, e
    change = np.flatnonzero(np.r_[True, lab[1:] != lab[:-1]])
    stops = np.r_[change[1:], n]
    vals = lab[change]
    keep = vals >= 0
    return change[keep], stops[keep], vals[keep]


def true_runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Runs of ``True`` in a boolean mask.

    Parameters
    ----------
    mask : ndarray of bool, shape (n,)

    Returns
    -------
    starts, stops : ndarray of int
        Half-open ``[start, stop)`` ranges of each run of ``True``.
    """
    m = np.asarray(mask, dtype=bool)
    if m.size == 0:
        e = np.zeros(0, dtype=np.int64)
        return e, e
    d = np.diff(np.r_[0, m.view(np.int8), 0])
    return np.flatnonzero(d == 1), np.flatnonzero(d == -1)
