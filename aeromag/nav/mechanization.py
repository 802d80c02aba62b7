"""Strapdown inertial mechanisation in NED, vectorised over sigma points and IMU samples.

State layout (see :mod:`aeromag.nav.filter`): position NED (m), velocity NED (m/s), Z-Y-X
Euler angles roll, pitch, yaw (rad), gyro biases (rad/s) and, optionally, accelerometer biases
(m/s²).  Flat, non-rotating Earth with constant gravity (Earth rate 7.3e-5 rad/s and the
transport rate are far below an MEMS gyro's noise over the minutes of a UAV flight).

One IMU sample holds the mean angular rate and mean specific force over the interval that
ends at its time (the interface's convention), so over an interval ``dt``::

    C_k   = C_(k-1) exp([(w_k - b_g) dt]x)                (Rodrigues, exact for a constant rate)
    a_k   = (C_(k-1) + C_k) / 2 (f_k - b_a) + g_n          (trapezoid in attitude)
    v_k   = v_(k-1) + a_k dt,   p_k = p_(k-1) + (v_(k-1) + v_k) / 2 dt

:func:`propagate` runs a whole batch of IMU samples (those between two measurement epochs)
for all sigma points in a fixed number of numpy calls: the attitude products are a parallel
prefix scan (``log2(N)`` batched 3x3 products), velocity and position cumulative sums.
"""

from __future__ import annotations

import numpy as np

from .._core.rotations import dcm_body_to_ned, euler_from_dcm

__all__ = ["GRAVITY", "propagate", "rotation_matrices"]

#: Standard gravity, m/s² (the simulator uses the same constant).
GRAVITY = 9.80665


def rotation_matrices(w: np.ndarray) -> np.ndarray:
    """Rotation matrices ``exp([w]x)`` of rotation vectors (Rodrigues' formula).

    Parameters
    ----------
    w : ndarray, shape (..., 3)
        Rotation vectors, rad.

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    w = np.asarray(w, dtype=np.float64)
    th2 = np.einsum("...i,...i->...", w, w)
    th = np.sqrt(th2)
    small = th2 < 1e-12
    safe = np.where(small, 1.0, th)
    a = np.where(small, 1.0 - th2 / 6.0, np.sin(safe) / safe)             # sin(t)/t
    b = np.where(small, 0.5 - th2 / 24.0, (1.0 - np.cos(safe)) / (safe * safe))  # (1-cos)/t^2
    x, y, z = w[..., 0], w[..., 1], w[..., 2]
    R = np.empty(w.shape[:-1] + (3, 3))
    R[..., 0, 0] = 1.0 - b * (y * y + z * z)
    R[..., 1, 1] = 1.0 - b * (x * x + z * z)
    R[..., 2, 2] = 1.0 - b * (x * x + y * y)
    bxy, bxz, byz = b * x * y, b * x * z, b * y * z
    R[..., 0, 1] = bxy - a * z
    R[..., 1, 0] = bxy + a * z
    R[..., 0, 2] = bxz + a * y
    R[..., 2, 0] = bxz - a * y
    R[..., 1, 2] = byz - a * x
    R[..., 2, 1] = byz + a * x
    return R


def _matmul3(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Batched 3x3 products (faster than ``np.matmul`` on many tiny matrices)."""
    return np.einsum("...ij,...jk->...ik", A, B, optimize=False)


def _prefix_products(R: np.ndarray) -> np.ndarray:
    """Inclusive prefix products ``R_0 R_1 ... R_k`` along axis -3 (Hillis-Steele scan)."""
    P = R.copy()
    N = P.shape[-3]
    s = 1
    while s < N:
        P[..., s:, :, :] = _matmul3(P[..., :-s, :, :], P[..., s:, :, :])
        s *= 2
    return P


def propagate(X: np.ndarray, gyro: np.ndarray, acc: np.ndarray, dt: np.ndarray,
              accel_bias: bool = False, keep_path: bool = False
              ) -> tuple[np.ndarray, np.ndarray | None]:
    """Propagate sigma points through a batch of IMU samples.

    Parameters
    ----------
    X : ndarray, shape (S, n)
        Sigma points (``n`` = 12, or 15 with ``accel_bias``).
    gyro : ndarray, shape (N, 3)
        Mean body rates over each sample's interval, rad/s.
    acc : ndarray, shape (N, 3)
        Mean specific force over each interval, m/s² (body axes).
    dt : ndarray, shape (N,)
        Interval lengths, s.
    accel_bias : bool
        Whether ``X`` carries accelerometer biases in columns 12..14.
    keep_path : bool
        Also return the states after every sample.

    Returns
    -------
    X_end : ndarray, shape (S, n)
        Sigma points after the last sample.
    path : ndarray, shape (S, N, n) or None
        States after every sample (``keep_path``).
    """
    S, n = X.shape
    N = gyro.shape[0]
    bg = X[:, 9:12]
    C0 = dcm_body_to_ned(X[:, 6], X[:, 7], X[:, 8])                     # (S, 3, 3)
    w = (gyro[None, :, :] - bg[:, None, :]) * dt[None, :, None]          # (S, N, 3)
    Pk = _prefix_products(rotation_matrices(w))                          # (S, N, 3, 3)
    Ck = _matmul3(C0[:, None], Pk)
    Cprev = np.concatenate([C0[:, None], Ck[:, :-1]], axis=1)
    fb = acc[None, :, :] - (X[:, None, 12:15] if accel_bias else 0.0)
    a = 0.5 * np.einsum("snij,snj->sni", Cprev + Ck, np.broadcast_to(fb, (S, N, 3)))
    a[..., 2] += GRAVITY
    dv = a * dt[None, :, None]
    v = X[:, None, 3:6] + np.cumsum(dv, axis=1)
    vprev = np.concatenate([X[:, None, 3:6], v[:, :-1]], axis=1)
    p = X[:, None, 0:3] + np.cumsum(0.5 * (vprev + v) * dt[None, :, None], axis=1)
    if keep_path:
        roll, pitch, yaw = euler_from_dcm(Ck)
        path = np.empty((S, N, n))
        path[..., 0:3] = p
        path[..., 3:6] = v
        path[..., 6], path[..., 7], path[..., 8] = roll, pitch, yaw
        path[..., 9:] = X[:, None, 9:]
        return path[:, -1].copy(), path
    out = X.copy()
    out[:, 0:3] = p[:, -1]
    out[:, 3:6] = v[:, -1]
    out[:, 6], out[:, 7], out[:, 8] = euler_from_dcm(Ck[:, -1])
    return out, None
