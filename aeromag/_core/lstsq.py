"""The one least-squares solve of the package: (ridge-)regularised normal equations.

Columns are scaled to unit norm before solving (the ridge is then dimensionless); a batch of
normal equations is solved at once by :func:`solve_normal_batch`, condition numbers by
:func:`scaled_condition`.
"""

from __future__ import annotations

import numpy as np

from ..errors import FitError


def solve_normal(
    gram: np.ndarray, rhs: np.ndarray, ridge: float = 0.0
) -> tuple[np.ndarray, float, float]:
    """Solve the (ridge-)regularised normal equations ``(G + ridge*D) c = b``.

    The ridge penalty is scaled by the diagonal ``D`` of ``G`` so ``ridge`` is dimensionless
    (0 = plain least squares; 1e-3 a light touch).

    Parameters
    ----------
    gram : ndarray, shape (k, k)
        ``A.T @ A`` of the (band-passed) design matrix.
    rhs : ndarray, shape (k,)
        ``A.T @ y``.
    ridge : float
        Relative ridge parameter (>= 0).

    Returns
    -------
    coef : ndarray, shape (k,)
        Coefficients [nT; eddy nT*s].
    cond : float
        Condition number of ``A`` (square root of that of ``G``).
    cond_scaled : float
        Condition number of ``A`` with unit-norm columns: the collinearity of the terms
        independent of their units.

    Raises
    ------
    FitError
        When ``G`` is singular (a term never varies, e.g. a constant fluxgate).
    """
    d = np.diag(gram).copy()
    if not np.all(np.isfinite(gram)) or not np.all(np.isfinite(rhs)):
        raise FitError("the fit matrix has non-finite values; check the fluxgate and mag columns")
    if np.any(d <= 0):
        raise FitError(
            "a model term never varies in the fitting band (constant fluxgate or no maneuvers);"
            " fly maneuvers, widen band_hz or choose a smaller term set (terms=...)"
        )
    ev = np.linalg.eigvalsh(gram)
    cond = float(np.sqrt(ev[-1] / ev[0])) if ev[0] > 0 else float("inf")
    inv = 1.0 / np.sqrt(d)
    gs = gram * inv[:, None] * inv[None, :]
    evs = np.linalg.eigvalsh(gs)
    cond_s = float(np.sqrt(evs[-1] / evs[0])) if evs[0] > 0 else float("inf")
    if ridge <= 0 and not (evs[0] > 1e-14 * evs[-1]):
        raise FitError(
            f"the fit is ill-conditioned (scaled condition number {cond_s:.3g}); the terms are"
            " collinear: add maneuvers, use ridge=1e-3, or choose a smaller term set (terms=...)"
        )
    g = gs + ridge * np.eye(len(d))
    try:
        z = np.linalg.solve(g, rhs * inv)
    except np.linalg.LinAlgError:
        raise FitError("the fit matrix is singular; add maneuvers or use ridge=1e-3") from None
    return z * inv, cond, cond_s



def _unit_scale(gram: np.ndarray) -> np.ndarray:
    """``1 / sqrt(diag(G))`` of one or many Gram matrices (guarded against zeros)."""
    return 1.0 / np.sqrt(np.maximum(np.diagonal(gram, axis1=-2, axis2=-1), 1e-300))


def solve_normal_batch(gram: np.ndarray, rhs: np.ndarray, ridge: float = 0.0) -> np.ndarray:
    """:func:`solve_normal` for many normal equations at once, without its checks.

    Parameters
    ----------
    gram : ndarray, shape (m, k, k)
        Gram matrices.
    rhs : ndarray, shape (m, k)
        Right-hand sides.
    ridge : float
        Relative ridge parameter (>= 0).

    Returns
    -------
    ndarray, shape (m, k)
        Coefficients.
    """
    inv = _unit_scale(gram)
    gs = gram * inv[:, :, None] * inv[:, None, :] + ridge * np.eye(gram.shape[-1])
    return np.linalg.solve(gs, (rhs * inv)[..., None])[..., 0] * inv


def scaled_condition(gram: np.ndarray) -> np.ndarray:
    """Condition number of ``A`` with unit-norm columns, from ``G = A.T @ A``.

    Parameters
    ----------
    gram : ndarray, shape (..., k, k)
        Gram matrices.

    Returns
    -------
    ndarray, shape (...)
        ``sqrt(lambda_max / lambda_min)`` of the unit-diagonal Gram matrix (inf if singular).
    """
    d = np.sqrt(np.maximum(np.diagonal(gram, axis1=-2, axis2=-1), 1e-300))
    gs = gram / d[..., :, None] / d[..., None, :]
    ev = np.linalg.eigvalsh(gs)
    with np.errstate(divide="ignore"):
        return np.sqrt(ev[..., -1] / np.where(ev[..., 0] > 0, ev[..., 0], 0.0))
