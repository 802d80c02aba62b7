"""The scaled unscented transform: sigma points, weights, and the transform of a Gaussian.

This is the one implementation used by the navigation UKF (:mod:`aeromag.nav`) and by the
unscented proposal of the particle filter.  Everything is vectorised over the sigma points
(the function you transform receives all ``2n + 1`` points in one array) and over optional
leading batch dimensions (many Gaussians at once, e.g. one per particle).

Conventions
-----------
* A state is a vector of length ``n``; a batch of states has shape ``(..., n)`` and its
  covariances shape ``(..., n, n)``.
* Sigma points have shape ``(..., 2n + 1, n)``: point 0 is the mean, points ``1..n`` are
  ``x + S[:, i]`` and ``n+1..2n`` are ``x - S[:, i]``, where ``S S^T = (n + lambda) P``.
* Scaled weights (Julier 2002; Wan & van der Merwe 2000) with
  ``lambda = alpha**2 (n + kappa) - n``::

      Wm[0] = lambda / (n + lambda)
      Wc[0] = Wm[0] + (1 - alpha**2 + beta)
      Wm[i] = Wc[i] = 1 / (2 (n + lambda)),  i = 1..2n

  ``alpha = 1, beta = 2, kappa = 0`` (the defaults) keep every weight non-negative, which
  keeps the transformed covariance positive semi-definite; small ``alpha`` (1e-3) gives the
  classic "local" spread with a large negative ``Wc[0]``.
* Angles and other manifold quantities: pass ``mean_fn(Y, Wm)`` (a weighted mean that knows
  which components are angles), ``residual_fn(a, b)`` (``a - b`` wrapped) for the output and
  ``state_residual_fn`` for the input (the cross-covariance).  :func:`angle_mean_fn` and
  :func:`angle_residual_fn` build them from a list of angle indices.

Example
-------
>>> import numpy as np
>>> from aeromag._core.unscented import unscented_transform
>>> A = np.array([[1.0, 0.1], [0.0, 1.0]])
>>> m, S, C = unscented_transform(lambda X: X @ A.T, np.zeros(2), np.eye(2))
>>> bool(np.allclose(S, A @ A.T))
True
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from ..errors import AeromagError

__all__ = [
    "CovarianceError",
    "angle_mean_fn",
    "angle_residual_fn",
    "robust_sqrt",
    "sigma_points",
    "sigma_weights",
    "symmetrize",
    "unscented_transform",
]

ArrayFn = Callable[[np.ndarray], np.ndarray]


class CovarianceError(AeromagError, ArithmeticError):
    """A covariance is not finite (the filter diverged); no square root exists."""


def symmetrize(P: np.ndarray) -> np.ndarray:
    """Symmetric part ``(P + P^T) / 2`` over the last two axes."""
    P = np.asarray(P, dtype=np.float64)
    return 0.5 * (P + np.swapaxes(P, -1, -2))


def robust_sqrt(P: np.ndarray, jitter: float = 1e-12, max_tries: int = 6) -> np.ndarray:
    """A matrix square root ``S`` with ``S @ S.T == P`` that never fails on a finite ``P``.

    The matrix is symmetrised; a Cholesky factor is tried first.  If it fails (rounding made
    ``P`` slightly indefinite), a growing diagonal jitter ``jitter * 10**k * mean(diag(P))``
    is added, ``k = 0..max_tries-1``; if that still fails, the eigen-decomposition with the
    negative eigenvalues clipped to zero gives ``S = V sqrt(max(w, 0))``.

    Parameters
    ----------
    P : ndarray, shape (..., n, n)
        Covariance matrix (or a batch), any unit squared.
    jitter : float
        Relative size of the first diagonal jitter.
    max_tries : int
        Number of jitter sizes tried before the eigen-decomposition.

    Returns
    -------
    ndarray, shape (..., n, n)
        A square root, in the unit of ``P``'s square root (lower-triangular when Cholesky
        succeeded).

    Raises
    ------
    CovarianceError
        ``P`` holds NaN or infinite values (a diverged filter).
    """
    P = symmetrize(P)
    if not np.all(np.isfinite(P)):
        raise CovarianceError("covariance is not finite: the filter diverged")
    try:
        return np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        pass
    n = P.shape[-1]
    scale = np.abs(np.trace(P, axis1=-2, axis2=-1)) / n
    scale = np.where(scale > 0, scale, 1.0)[..., None, None]
    eye = np.eye(n)
    for k in range(max_tries):
        try:
            return np.linalg.cholesky(P + (jitter * 10.0**k) * scale * eye)
        except np.linalg.LinAlgError:
            continue
    w, V = np.linalg.eigh(P)
    return V * np.sqrt(np.clip(w, 0.0, None))[..., None, :]


def sigma_weights(n: int, alpha: float = 1.0, beta: float = 2.0,
                  kappa: float = 0.0) -> tuple[np.ndarray, np.ndarray, float]:
    """Scaled unscented weights.

    Parameters
    ----------
    n : int
        State dimension.
    alpha, beta, kappa : float
        Spread (0 < alpha <= 1), prior knowledge (2 is optimal for a Gaussian) and secondary
        scaling parameter.

    Returns
    -------
    Wm, Wc : ndarray, shape (2n + 1,)
        Weights of the mean and of the covariance.
    gamma : float
        ``sqrt(n + lambda)``, the factor applied to the covariance square root.
    """
    if n < 1:
        raise ValueError("state dimension must be at least 1")
    if not alpha > 0:
        raise ValueError("alpha must be positive")
    lam = alpha**2 * (n + kappa) - n
    c = n + lam
    if not c > 0:
        raise ValueError("n + lambda must be positive (raise alpha or kappa)")
    Wm = np.full(2 * n + 1, 0.5 / c)
    Wc = Wm.copy()
    Wm[0] = lam / c
    Wc[0] = lam / c + (1.0 - alpha**2 + beta)
    return Wm, Wc, float(np.sqrt(c))


def sigma_points(x: np.ndarray, P: np.ndarray, alpha: float = 1.0, beta: float = 2.0,
                 kappa: float = 0.0, sqrt: np.ndarray | None = None,
                 add_fn: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Scaled sigma points of a Gaussian (or of a batch of Gaussians).

    Parameters
    ----------
    x : ndarray, shape (..., n)
        Mean(s).
    P : ndarray, shape (..., n, n)
        Covariance(s).
    alpha, beta, kappa : float
        Scaling parameters (see :func:`sigma_weights`).
    sqrt : ndarray, shape (..., n, n), optional
        A precomputed square root of ``P`` (skips :func:`robust_sqrt`).
    add_fn : callable, optional
        ``add_fn(x, d)`` -> ``x + d`` on a manifold (e.g. wrapping angles), applied to
        ``x[..., None, :]`` and the ``(..., 2n, n)`` offsets.  Default: plain addition.

    Returns
    -------
    X : ndarray, shape (..., 2n + 1, n)
        Sigma points.
    Wm, Wc : ndarray, shape (2n + 1,)
        Weights of the mean and covariance.
    """
    x = np.asarray(x, dtype=np.float64)
    n = x.shape[-1]
    Wm, Wc, gamma = sigma_weights(n, alpha, beta, kappa)
    S = robust_sqrt(P) if sqrt is None else np.asarray(sqrt, dtype=np.float64)
    cols = gamma * np.swapaxes(S, -1, -2)              # (..., n, n): row i = column i of S
    offsets = np.concatenate([cols, -cols], axis=-2)   # (..., 2n, n)
    xb = x[..., None, :]
    moved = xb + offsets if add_fn is None else add_fn(xb, offsets)
    X = np.concatenate([np.broadcast_to(xb, moved.shape[:-2] + (1, n)), moved], axis=-2)
    return X, Wm, Wc


def _weighted_mean(Y: np.ndarray, Wm: np.ndarray) -> np.ndarray:
    return np.einsum("k,...ki->...i", Wm, Y)


def unscented_transform(f: ArrayFn, x: np.ndarray, P: np.ndarray, alpha: float = 1.0,
                        beta: float = 2.0, kappa: float = 0.0,
                        noise_cov: np.ndarray | None = None,
                        mean_fn: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
                        residual_fn: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
                        state_residual_fn: Callable[[np.ndarray, np.ndarray], np.ndarray]
                        | None = None,
                        sigma: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Propagate a Gaussian through ``f`` by the scaled unscented transform.

    Parameters
    ----------
    f : callable
        Vectorised map: ``f(X)`` with ``X`` of shape ``(..., 2n + 1, n)`` returns
        ``(..., 2n + 1, m)``.  It is called once.
    x : ndarray, shape (..., n)
        Input mean(s).
    P : ndarray, shape (..., n, n)
        Input covariance(s).
    alpha, beta, kappa : float
        Scaling parameters (see :func:`sigma_weights`).
    noise_cov : ndarray, shape (m, m) or (..., m, m), optional
        Additive noise covariance added to the output covariance.
    mean_fn : callable, optional
        ``mean_fn(Y, Wm)`` -> weighted mean over axis -2 (default: the weighted sum).
    residual_fn : callable, optional
        ``residual_fn(Y, y)`` -> ``Y - y`` for outputs (default: subtraction).
    state_residual_fn : callable, optional
        ``state_residual_fn(X, x)`` -> ``X - x`` for inputs (default: subtraction).
    sigma : tuple, optional
        Precomputed ``(X, Wm, Wc)`` from :func:`sigma_points` (then ``x``, ``P`` and the
        scaling parameters are used only for the cross-covariance's reference mean).

    Returns
    -------
    mean : ndarray, shape (..., m)
        Transformed mean.
    cov : ndarray, shape (..., m, m)
        Transformed covariance (plus ``noise_cov``), symmetrised.
    cross_cov : ndarray, shape (..., n, m)
        Cross-covariance between input and output.
    """
    X, Wm, Wc = sigma_points(x, P, alpha, beta, kappa) if sigma is None else sigma
    Y = np.asarray(f(X), dtype=np.float64)
    if Y.shape[:-1] != X.shape[:-1]:
        raise ValueError(f"f must map (..., 2n+1, n) to (..., 2n+1, m); got {Y.shape} "
                         f"from {X.shape}")
    y = (mean_fn or _weighted_mean)(Y, Wm)
    dY = residual_fn(Y, y[..., None, :]) if residual_fn else Y - y[..., None, :]
    x0 = np.asarray(x, dtype=np.float64)[..., None, :]
    dX = state_residual_fn(X, x0) if state_residual_fn else X - x0
    cov = np.einsum("k,...ki,...kj->...ij", Wc, dY, dY)
    if noise_cov is not None:
        cov = cov + noise_cov
    cross = np.einsum("k,...ki,...kj->...ij", Wc, dX, dY)
    return y, symmetrize(cov), cross


def _angle_index(angle_idx: Sequence[int]) -> np.ndarray:
    """The angle components' indices as an integer array (for fancy indexing)."""
    return np.asarray(list(angle_idx), dtype=np.intp)


def angle_residual_fn(angle_idx: Sequence[int]) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """Residual ``a - b`` with the components ``angle_idx`` (radians) wrapped to [-pi, pi).

    Parameters
    ----------
    angle_idx : sequence of int
        Indices (last axis) of the components that are angles in radians.

    Returns
    -------
    callable
        ``fn(a, b)`` broadcasting like ``a - b``.
    """
    idx = _angle_index(angle_idx)

    def residual(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        d = np.asarray(a, dtype=np.float64) - b
        if idx.size:
            d[..., idx] = np.mod(d[..., idx] + np.pi, 2.0 * np.pi) - np.pi
        return d

    return residual


def angle_mean_fn(angle_idx: Sequence[int]) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """Weighted mean over sigma points with the components ``angle_idx`` averaged circularly.

    The angle components are averaged as ``atan2(sum w sin, sum w cos)`` (valid for the
    signed unscented weights while the spread is well below pi).

    Parameters
    ----------
    angle_idx : sequence of int
        As in :func:`angle_residual_fn`.

    Returns
    -------
    callable
        ``fn(Y, Wm)`` with ``Y`` of shape ``(..., k, m)`` returning ``(..., m)``.
    """
    idx = _angle_index(angle_idx)

    def mean(Y: np.ndarray, Wm: np.ndarray) -> np.ndarray:
        y = _weighted_mean(Y, Wm)
        if idx.size:
            a = Y[..., idx]
            s = np.einsum("k,...ki->...i", Wm, np.sin(a))
            c = np.einsum("k,...ki->...i", Wm, np.cos(a))
            y[..., idx] = np.arctan2(s, c)
        return y

    return mean
