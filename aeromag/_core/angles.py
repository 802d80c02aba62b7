"""Angle wrapping and circular statistics: the one implementation used by every module."""

from __future__ import annotations

import numpy as np

__all__ = ["wrap_deg", "wrap_rad", "wrap360_deg", "circular_mean_rad"]


def wrap_deg(angle: np.ndarray | float) -> np.ndarray:
    """Wrap angles to [-180, 180) degrees.

    Parameters
    ----------
    angle : array_like
        Angles, degrees.

    Returns
    -------
    ndarray
        The same angles, degrees, in [-180, 180).
    """
    a = np.asarray(angle, dtype=np.float64)
    # np.mod(-tiny, 360) rounds to 360.0: fold that case back so that the result is always
    # in the half-open range (an angle just below -180 would otherwise come out as +180).
    w = np.mod(a + 180.0, 360.0)
    w = np.where(w >= 360.0, 0.0, w) - 180.0
    return np.where(w >= 180.0, -180.0, w)


def wrap360_deg(angle: np.ndarray | float) -> np.ndarray:
    """Wrap angles to [0, 360) degrees (headings).

    Parameters
    ----------
    angle : array_like
        Angles, degrees.

    Returns
    -------
    ndarray
        The same angles, degrees, in [0, 360).
    """
    a = np.mod(np.asarray(angle, dtype=np.float64), 360.0)
    return np.where(a >= 360.0, 0.0, a)


def wrap_rad(angle: np.ndarray | float) -> np.ndarray:
    """Wrap angles to [-pi, pi) radians.

    Parameters
    ----------
    angle : array_like
        Angles, rad.

    Returns
    -------
    ndarray
        The same angles, rad, in [-pi, pi).
    """
    a = np.asarray(angle, dtype=np.float64)
    w = np.mod(a + np.pi, 2.0 * np.pi)
    w = np.where(w >= 2.0 * np.pi, 0.0, w) - np.pi
    return np.where(w >= np.pi, -np.pi, w)


def circular_mean_rad(angle: np.ndarray, weights: np.ndarray | None = None,
                      axis: int = 0) -> np.ndarray:
    """Weighted circular mean of angles.

    Parameters
    ----------
    angle : ndarray
        Angles, rad.
    weights : ndarray, optional
        Weights broadcastable to ``angle`` along ``axis`` (need not sum to one; may be
        negative, as unscented-transform weights are).
    axis : int
        Axis to average over.

    Returns
    -------
    ndarray
        Mean angle, rad, in [-pi, pi).
    """
    a = np.asarray(angle, dtype=np.float64)
    if weights is None:
        s, c = np.sin(a).mean(axis=axis), np.cos(a).mean(axis=axis)
    else:
        w = np.asarray(weights, dtype=np.float64)
        shape = [1] * a.ndim
        shape[axis] = -1
        w = w.reshape(shape)
        s, c = (w * np.sin(a)).sum(axis=axis), (w * np.cos(a)).sum(axis=axis)
    return wrap_rad(np.arctan2(s, c))
