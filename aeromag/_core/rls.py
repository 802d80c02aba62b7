"""Recursive least squares with a forgetting factor: the one kernel every online estimator uses.

Model: ``y_k = Theta.T @ phi_k + v_k`` with a regressor ``phi_k`` of ``n`` numbers shared by
``m`` outputs (``Theta`` is n x m).  The vector-magnetometer calibration is this with
``phi = [flux, 1]`` (n = 4) and the three body axes as outputs (m = 3): one 4 x 4 covariance
instead of a 12 x 12 one, and exactly the same estimate, because with ``A_k = I_3 (x) phi_k.T``
and ``P_0 = alpha I`` the 12 x 12 covariance stays ``I_3 (x) P``.  Scalar Tolles-Lawson
compensation is n = 16, m = 1.

The estimate after sample k minimises

    J_k(Theta) = sum_j lam^(k-j) |y_j - Theta.T phi_j|^2  +  w_k |Theta - Theta_0|^2,
    w_k = lam^k / alpha + (1 - lam^k) * floor,

the exponentially weighted least-squares criterion with the prior ``P_0 = alpha I`` around
``Theta_0``.  With ``floor = 0`` this is textbook RLS (the prior decays as ``lam^k``).

**Bounded covariance (no wind-up).**  With lam < 1 and a regressor that does not move in
some direction (a flight that does not excite a parameter), textbook RLS divides the
covariance by lam at every step in that direction and it grows as ``lam^-k`` without bound,
so the first disturbance throws the estimate far off.  Here each step adds the constant
information ``(1 - lam) * floor * I`` (regularised forgetting, also called leakage towards
the prior): the information never falls below ``min(1/alpha, floor)`` in any direction, so
``P <= max(alpha, 1/floor) I`` at every sample.  The default ``floor = 1/alpha`` keeps the
prior's weight constant (``w_k = 1/alpha``) and ``P <= alpha I`` exactly.  This keeps the
criterion above exact, so the step-by-step and the batched forms agree to rounding.

**Two equal forms.**  :meth:`RecursiveLeastSquares.step` is the covariance form for streaming:
``S = lam + phi.T P phi``, ``K = P phi / S``, ``Theta += K (y - Theta.T phi).T``,
``P = (P - K K.T S) / lam`` symmetrised, then the floor added to the information
(``P <- P (I + c P)^-1``, ``Theta += c P (Theta_0 - Theta)``, ``c = (1 - lam) floor``).
:meth:`RecursiveLeastSquares.run` is the information form vectorised over samples: the
normal equations ``R_k = lam R_(k-1) + phi phi.T + c I`` and ``B_k = lam B_(k-1) + phi y.T
+ c Theta_0`` are a one-pole filter over time (``scipy.signal.lfilter`` with ``R_0 = P_0^-1``
as its initial state, so the prior is included exactly), followed by batched solves
``Theta_k = R_k^-1 B_k``, block by block.

**Missing data.**  A sample whose regressor or measurement is not finite is skipped: no
update and no forgetting (time does not advance for the estimator); it is counted and
flagged in the result, and its parameter history repeats the previous estimate.  NaN is
never propagated into the estimate.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

log = logging.getLogger(__name__)

__all__ = ["RLSResult", "RecursiveLeastSquares", "check_forgetting"]

#: Samples per block of the batched form (outer products and solves stay in cache).
BLOCK = 8192


def check_forgetting(forgetting: float, *, option: str = "forgetting") -> float:
    """Validate a forgetting factor.

    Parameters
    ----------
    forgetting : float
        Forgetting factor lambda [dimensionless].
    option : str
        Parameter name used in the error message (``forgetting=0.0: ...``; the command
        line shows its flag).

    Returns
    -------
    float
        ``forgetting`` as a float.

    Raises
    ------
    InputError
        Unless ``0 < forgetting <= 1``.
    """
    lam = float(forgetting)
    if not (np.isfinite(lam) and 0.0 < lam <= 1.0):
        raise InputError(f"{option}={forgetting!r}: a forgetting factor must be in (0, 1] (1:"
                         " plain recursive least squares); use e.g. 0.975")
    return lam


@dataclass
class RLSResult:
    """What :meth:`RecursiveLeastSquares.run` returns.

    Attributes
    ----------
    theta : ndarray, shape (N, n, m)
        Parameter history: the estimate after each sample (a skipped sample repeats the
        previous estimate).
    theta_final : ndarray, shape (n, m)
        Estimate after the last sample.
    covariance : ndarray, shape (n, n)
        Final ``P`` (inverse information), in the regressor's units.
    skipped : ndarray of bool, shape (N,)
        Samples skipped because the regressor or the measurement was not finite.
    forgetting : float
        lambda.
    alpha : float
        Prior scale (``P_0 = alpha I``).
    floor : float
        Information floor (see the module docstring).
    """

    theta: np.ndarray
    theta_final: np.ndarray
    covariance: np.ndarray
    skipped: np.ndarray
    forgetting: float
    alpha: float
    floor: float

    @property
    def n_skipped(self) -> int:
        """Number of skipped (non-finite) samples."""
        return int(self.skipped.sum())


def _upper_products(ft: np.ndarray, offs: np.ndarray) -> np.ndarray:
    """Upper-triangle outer products ``f_i f_j`` (i <= j) of each sample, in
    ``triu_indices`` order, samples along the last axis: ``ft`` is (n, k), the result
    (n (n + 1) / 2, k), every row a contiguous product of two contiguous rows."""
    n, k = ft.shape
    out = np.empty((offs[-1], k))
    for i in range(n):
        np.multiply(ft[i], ft[i:], out=out[offs[i]:offs[i + 1]])
    return out


def _symmetric_index(n: int) -> np.ndarray:
    """For each (i, j) of an n x n matrix, the position of (min, max) in ``triu_indices``."""
    iu, ju = np.triu_indices(n)
    pos = np.empty((n, n), dtype=np.intp)
    pos[iu, ju] = np.arange(len(iu))
    pos[ju, iu] = np.arange(len(iu))
    return pos.ravel()


class RecursiveLeastSquares:
    """Recursive least squares with forgetting factor and a shared regressor.

    Parameters
    ----------
    n_params : int
        Regressor length ``n``.
    n_outputs : int
        Number of outputs ``m`` sharing the regressor (3 for the vector calibration).
    forgetting : float
        lambda, 0 < lambda <= 1 (1: plain RLS, every sample weighs the same).
    alpha : float
        Prior covariance scale, ``P_0 = alpha I`` (in the regressor's units; 1e3-1e6 for a
        regressor of order one).
    theta0 : ndarray, shape (n, m), optional
        Prior estimate ``Theta_0`` (zeros when omitted).
    floor : float, optional
        Information added per step as ``(1 - lambda) floor I`` (bounded covariance);
        ``1/alpha`` when omitted, 0 for textbook RLS.

    Attributes
    ----------
    theta : ndarray, shape (n, m)
        Current estimate.
    P : ndarray, shape (n, n)
        Current covariance (symmetric).
    n_updates, n_skipped : int
        Samples used and skipped so far.
    """

    def __init__(self, n_params: int, n_outputs: int = 1, *, forgetting: float = 1.0,
                 alpha: float = 1e4, theta0: np.ndarray | None = None,
                 floor: float | None = None) -> None:
        self.n = int(n_params)
        self.m = int(n_outputs)
        if self.n < 1 or self.m < 1:
            raise ValueError("n_params and n_outputs must be positive")
        self.forgetting = check_forgetting(forgetting)
        self.alpha = float(alpha)
        if not (np.isfinite(self.alpha) and self.alpha > 0):
            raise ValueError(f"alpha must be positive, got {alpha!r}")
        self.floor = 1.0 / self.alpha if floor is None else float(floor)
        if not (np.isfinite(self.floor) and self.floor >= 0):
            raise ValueError(f"floor must be >= 0, got {floor!r}")
        t0 = np.zeros((self.n, self.m)) if theta0 is None else np.array(theta0, dtype=float)
        self.theta0 = t0.reshape(self.n, self.m)
        self.reset()

    # -- state --------------------------------------------------------------------------
    def reset(self) -> None:
        """Return to the prior: ``Theta = Theta_0``, ``P = alpha I``."""
        self.theta = self.theta0.copy()
        self.P = self.alpha * np.eye(self.n)
        self.n_updates = 0
        self.n_skipped = 0

    @property
    def _leak(self) -> float:
        return (1.0 - self.forgetting) * self.floor

    # -- streaming ----------------------------------------------------------------------
    def step(self, phi: np.ndarray, y: np.ndarray | float) -> bool:
        """Update with one sample (covariance form).

        Parameters
        ----------
        phi : ndarray, shape (n,)
            Regressor.
        y : ndarray, shape (m,) or float
            Measurement(s).

        Returns
        -------
        bool
            True when the sample was used, False when it was skipped (not finite).
        """
        phi = np.asarray(phi, dtype=np.float64).reshape(self.n)
        y = np.asarray(y, dtype=np.float64).reshape(self.m)
        if not (np.isfinite(phi).all() and np.isfinite(y).all()):
            self.n_skipped += 1
            return False
        lam = self.forgetting
        P = self.P
        Pphi = P @ phi
        s = lam + phi @ Pphi
        k = Pphi / s
        err = y - phi @ self.theta
        self.theta = self.theta + np.outer(k, err)
        P = (P - np.outer(k, Pphi)) / lam
        P = 0.5 * (P + P.T)
        c = self._leak
        if c > 0.0:
            # Information += c I:  P <- (P^-1 + c I)^-1 = P (I + c P)^-1, and the estimate
            # moves to the minimiser of the criterion with the added prior weight.
            P = np.linalg.solve(np.eye(self.n) + c * P, P)
            P = 0.5 * (P + P.T)
            self.theta = self.theta + c * (P @ (self.theta0 - self.theta))
        self.P = P
        self.n_updates += 1
        return True

    # -- batched ------------------------------------------------------------------------
    def run(self, phi: np.ndarray, y: np.ndarray, *, history: bool = True) -> RLSResult:
        """Update with many samples at once (information form, vectorised); continues from
        the current state, so consecutive calls equal one call on the joined arrays.

        Parameters
        ----------
        phi : ndarray, shape (N, n)
            Regressors, one row per sample.
        y : ndarray, shape (N, m) or (N,)
            Measurements.
        history : bool
            Keep the estimate after every sample (``theta`` of the result); when False the
            result's ``theta`` has shape (0, n, m) and only the final state is computed
            at every block end (faster for long logs when the history is not needed).

        Returns
        -------
        RLSResult
            Parameter history, final estimate and covariance, skipped samples.
        """
        from scipy.signal import lfilter

        phi = np.asarray(phi, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64).reshape(len(phi), -1)
        N = len(phi)
        if phi.shape != (N, self.n) or y.shape[1] != self.m:
            raise ValueError(f"phi must be (N, {self.n}) and y (N, {self.m}); got "
                             f"{phi.shape} and {y.shape}")
        n, m, lam, c = self.n, self.m, self.forgetting, self._leak
        ok = np.isfinite(phi).all(axis=1) & np.isfinite(y).all(axis=1)
        idx = np.flatnonzero(ok)
        iu, ju = np.triu_indices(n)
        offs = np.r_[0, np.cumsum(np.arange(n, 0, -1))]  # row i of the upper triangle
        sym = _symmetric_index(n)
        R = np.linalg.inv(self.P)
        R = 0.5 * (R + R.T)
        B = R @ self.theta
        # Filter states: y[-1] = R_prev gives zi = lam * R_prev.
        zr = lam * R[iu, ju]
        zb = lam * B.reshape(-1)
        hist = np.empty((N if history else 0, n, m))
        prev = self.theta.copy()
        last_fill = 0
        diag = iu == ju
        leak_b = (c * self.theta0).reshape(-1)
        a = [1.0, -lam]
        for s0 in range(0, len(idx), BLOCK):
            rows = idx[s0:s0 + BLOCK]
            k = len(rows)
            if rows[-1] - rows[0] == k - 1:  # no skipped sample: slices, no gathers
                ft = np.ascontiguousarray(phi[rows[0]:rows[-1] + 1].T)
                yt = y[rows[0]:rows[-1] + 1].T
            else:
                ft = np.ascontiguousarray(phi[rows].T)
                yt = y[rows].T
            # Samples along the last axis: the filter and the products run on contiguous rows.
            xr = _upper_products(ft, offs)
            if c > 0.0:
                xr[diag] += c
            xb = (ft[:, None, :] * yt[None, :, :]).reshape(n * m, k)
            if c > 0.0:
                xb += leak_b[:, None]
            Rk, zr = lfilter([1.0], a, xr, axis=-1, zi=zr[:, None])
            Bk, zb = lfilter([1.0], a, xb, axis=-1, zi=zb[:, None])
            zr, zb = zr[:, 0], zb[:, 0]
            if history:
                th = np.linalg.solve(np.ascontiguousarray(Rk[sym].T).reshape(k, n, n),
                                     Bk.T.reshape(k, n, m))
                # Skipped samples before each used one repeat the previous estimate.
                hist[last_fill:rows[0]] = prev
                hist[rows[0]:rows[-1] + 1] = th if k == rows[-1] - rows[0] + 1 else prev
                if k != rows[-1] - rows[0] + 1:
                    hist[rows] = th
                    gaps = np.flatnonzero(np.diff(rows) > 1)
                    for g in gaps:
                        hist[rows[g] + 1:rows[g + 1]] = th[g]
                prev = th[-1]
                last_fill = rows[-1] + 1
            R_last = Rk[:, -1]
            B_last = Bk[:, -1]
        if len(idx):
            Rf = np.empty((n, n))
            Rf[iu, ju] = R_last
            Rf[ju, iu] = R_last
            theta = np.linalg.solve(Rf, B_last.reshape(n, m))
            P = np.linalg.inv(Rf)
            self.P = 0.5 * (P + P.T)
            self.theta = theta
            prev = theta
        if history:
            hist[last_fill:] = prev
        self.n_updates += len(idx)
        self.n_skipped += N - len(idx)
        if N - len(idx):
            log.info("RLS: %d of %d samples skipped (not finite)", N - len(idx), N)
        return RLSResult(theta=hist, theta_final=self.theta.copy(), covariance=self.P.copy(),
                         skipped=~ok, forgetting=lam, alpha=self.alpha, floor=self.floor)
