"""A generic unscented Kalman filter.

The filter follows the package's sequential convention (:mod:`aeromag._core.sequential`):
construct it with its parameters, ``step(y, u=None)`` one sample (predict, then update) ->
:class:`~aeromag._core.sequential.Step`, ``run(ys, us=None)`` over arrays ->
:class:`~aeromag._core.sequential.SequentialResult`.  Process and measurement functions
are vectorised over sigma points: they receive all ``2n + 1`` points as one
``(2n + 1, n)`` array.  Angles (radians) are handled by index: their means are
circular and their residuals wrapped to [-pi, pi).

The square root of the covariance never fails on a finite matrix (symmetrised, jittered
Cholesky, eigen fallback; :func:`aeromag._core.unscented.robust_sqrt`); a covariance that is
no longer finite raises :class:`DivergenceError` with one line naming the time.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence

import numpy as np

from .._core.sequential import InnovationStats, SequentialResult, Step
from .._core.unscented import (
    CovarianceError,
    angle_mean_fn,
    angle_residual_fn,
    sigma_points,
    symmetrize,
)
from ..errors import AeromagError

log = logging.getLogger(__name__)

__all__ = ["DivergenceError", "UnscentedKalmanFilter"]

SigmaFn = Callable[..., np.ndarray]


class DivergenceError(AeromagError, ArithmeticError):
    """The filter's state or covariance is no longer finite or plausible."""


class UnscentedKalmanFilter:
    """Unscented Kalman filter with additive process and measurement noise.

    Parameters
    ----------
    x0 : ndarray, shape (n,)
        Initial state.
    P0 : ndarray, shape (n, n)
        Initial covariance.
    fx : callable
        Process model ``fx(X, *args)``: sigma points ``(2n+1, n)`` -> ``(2n+1, n)``.
    Q : ndarray, shape (n, n)
        Process noise covariance added at each predict (per call).
    hx : callable, optional
        Default measurement model ``hx(X, *args)`` -> ``(2n+1, m)``.
    R : ndarray, shape (m, m), optional
        Default measurement noise covariance.
    alpha, beta, kappa : float
        Sigma-point scaling (see :func:`aeromag._core.unscented.sigma_weights`).
    angle_idx : sequence of int
        State components that are angles (rad).
    gate : float or None
        Innovation gate: a measurement whose normalised innovation squared exceeds it is
        rejected (None: never).
    state_names : sequence of str, optional
        Names for the result.
    """

    def __init__(self, x0: np.ndarray, P0: np.ndarray, fx: SigmaFn | None = None,
                 Q: np.ndarray | None = None, *, hx: SigmaFn | None = None,
                 R: np.ndarray | None = None, alpha: float = 1.0, beta: float = 2.0,
                 kappa: float = 0.0, angle_idx: Sequence[int] = (),
                 gate: float | None = None, state_names: Sequence[str] | None = None) -> None:
        self.x = np.asarray(x0, dtype=np.float64).copy()
        self.P = symmetrize(np.asarray(P0, dtype=np.float64))
        n = self.x.size
        if self.P.shape != (n, n):
            raise ValueError(f"P0 must be {n}x{n}")
        self.fx, self.hx = fx, hx
        self.Q = np.zeros((n, n)) if Q is None else np.asarray(Q, dtype=np.float64)
        self.R = None if R is None else np.atleast_2d(np.asarray(R, dtype=np.float64))
        self.alpha, self.beta, self.kappa = alpha, beta, kappa
        self.angle_idx = tuple(int(i) for i in angle_idx)
        self._mean = angle_mean_fn(self.angle_idx)
        self._res = angle_residual_fn(self.angle_idx)
        self.gate = gate
        self.state_names = tuple(state_names) if state_names else tuple(
            f"x{i}" for i in range(n))
        self.innovations: dict[str, InnovationStats] = {}
        self.last_innovation = np.zeros(0)
        self.time_s = 0.0

    # -- sigma points ----------------------------------------------------------------------
    def sigma_points(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Sigma points ``(2n+1, n)`` and weights of the current estimate."""
        try:
            return sigma_points(self.x, self.P, self.alpha, self.beta, self.kappa)
        except CovarianceError as exc:
            raise DivergenceError(f"filter diverged at t = {self.time_s:.3f} s: {exc}") from None

    def set_from_sigma(self, Y: np.ndarray, Wm: np.ndarray, Wc: np.ndarray,
                       Q: np.ndarray | None = None) -> None:
        """Set the estimate to the moments of propagated sigma points (plus ``Q``)."""
        x = self._mean(Y, Wm)
        d = self._res(Y, x[None, :])
        P = (Wc[:, None] * d).T @ d
        if Q is not None:
            P = P + Q
        self.x, self.P = self._wrap(x), symmetrize(P)

    def _wrap(self, x: np.ndarray) -> np.ndarray:
        if self.angle_idx:
            idx = list(self.angle_idx)
            x[..., idx] = np.mod(x[..., idx] + np.pi, 2.0 * np.pi) - np.pi
        return x

    # -- predict / update ------------------------------------------------------------------
    def predict(self, *args: object, fx: SigmaFn | None = None,
                Q: np.ndarray | None = None) -> None:
        """Propagate the estimate through the process model.

        Parameters
        ----------
        *args
            Passed to ``fx`` after the sigma points (inputs, time step...).
        fx : callable, optional
            Process model for this call (default: the constructor's).
        Q : ndarray, optional
            Process noise for this call (default: the constructor's).
        """
        f = fx or self.fx
        if f is None:
            raise ValueError("no process model")
        X, Wm, Wc = self.sigma_points()
        self.set_from_sigma(np.asarray(f(X, *args), dtype=np.float64), Wm, Wc,
                            self.Q if Q is None else Q)

    def update(self, z: np.ndarray, *args: object, hx: SigmaFn | None = None,
               R: np.ndarray | None = None, angle_idx: Sequence[int] = (),
               name: str = "z", gate: float | None = None) -> float:
        """Fuse one measurement.

        Parameters
        ----------
        z : ndarray, shape (m,)
            The measurement.
        *args
            Passed to ``hx`` after the sigma points.
        hx : callable, optional
            Measurement model for this call.
        R : ndarray, shape (m, m), optional
            Measurement noise covariance for this call.
        angle_idx : sequence of int
            Measurement components that are angles (rad).
        name : str
            Sensor name for the innovation statistics.
        gate : float, optional
            Innovation gate for this call (default: the constructor's).

        Returns
        -------
        float
            The normalised innovation squared (NaN when rejected by the gate).
        """
        h = hx or self.hx
        Rm = self.R if R is None else np.atleast_2d(np.asarray(R, dtype=np.float64))
        if h is None or Rm is None:
            raise ValueError("no measurement model or noise")
        z = np.atleast_1d(np.asarray(z, dtype=np.float64))
        X, Wm, Wc = self.sigma_points()
        Z = np.asarray(h(X, *args), dtype=np.float64).reshape(X.shape[0], -1)
        return self.update_from_sigma(z, X, Z, Wm, Wc, Rm, angle_idx, name,
                                      self.gate if gate is None else gate)

    def update_from_sigma(self, z: np.ndarray, X: np.ndarray, Z: np.ndarray, Wm: np.ndarray,
                          Wc: np.ndarray, R: np.ndarray, angle_idx: Sequence[int] = (),
                          name: str = "z", gate: float | None = None) -> float:
        """Update from sigma points ``X`` and their predicted measurements ``Z``."""
        zres = angle_residual_fn(angle_idx)
        zp = angle_mean_fn(angle_idx)(Z, Wm)
        dZ = zres(Z, zp[None, :])
        dX = self._res(X, self.x[None, :])
        S = symmetrize((Wc[:, None] * dZ).T @ dZ + R)
        Pxz = (Wc[:, None] * dX).T @ dZ
        nu = zres(z, zp)
        stats = self.innovations.setdefault(name, InnovationStats(dof=z.size))
        try:
            Sinv_nu = np.linalg.solve(S, nu)
            K = np.linalg.solve(S, Pxz.T).T
        except np.linalg.LinAlgError:
            raise DivergenceError(f"filter diverged at t = {self.time_s:.3f} s: singular"
                                  f" innovation covariance of {name}") from None
        nis = float(nu @ Sinv_nu)
        self.last_innovation = nu
        if not np.isfinite(nis):
            raise DivergenceError(f"filter diverged at t = {self.time_s:.3f} s: non-finite"
                                  f" innovation of {name}")
        if gate is not None and nis > gate:
            stats.n_rejected += 1
            return float("nan")
        stats.n_fused += 1
        stats.nis_sum += nis
        self.x = self._wrap(self.x + K @ nu)
        self.P = symmetrize(self.P - K @ S @ K.T)
        return nis

    # -- sequential convention -------------------------------------------------------------
    def step(self, y: np.ndarray | None, u: object = None) -> Step:
        """Process one sample: predict (``fx(X, u)`` when ``u`` is not None), then fuse ``y``.

        ``y`` is skipped when None or not finite.  Returns the estimate after the sample.
        """
        if u is None:
            self.predict()
        else:
            self.predict(u)
        used, nu = False, np.zeros(0)
        if y is not None and np.all(np.isfinite(y)):
            nis = self.update(y)
            used = bool(np.isfinite(nis))
            nu = np.atleast_1d(np.asarray(self.last_innovation, dtype=np.float64))
        return Step(state=self.x.copy(), std=np.sqrt(np.clip(np.diag(self.P), 0.0, None)),
                    innovation=nu, used=used)

    def run(self, ys: np.ndarray, us: np.ndarray | None = None,
            time_s: np.ndarray | None = None, keep_cov: bool = False) -> SequentialResult:
        """Run over a sequence of measurements (rows of NaN are predict-only).

        Parameters
        ----------
        ys : ndarray, shape (N, m)
            Measurements.
        us : ndarray, shape (N, ...), optional
            Inputs passed to the process model.
        time_s : ndarray, shape (N,), optional
            Sample times for the result (default 0..N-1).
        keep_cov : bool
            Keep the full covariance at every sample (``info["cov"]``, shape (N, n, n)).

        Returns
        -------
        SequentialResult
        """
        zs = np.asarray(ys, dtype=np.float64)
        if zs.ndim == 1:
            zs = zs[:, None]
        N, n = zs.shape[0], self.x.size
        xs, stds = np.empty((N, n)), np.empty((N, n))
        nus = np.full(zs.shape, np.nan)
        covs = np.empty((N, n, n)) if keep_cov else None
        for k in range(N):
            self.time_s = float(time_s[k]) if time_s is not None else float(k)
            st = self.step(zs[k], None if us is None else us[k])
            xs[k], stds[k] = st.state, st.std
            if st.innovation.size == zs.shape[1]:
                nus[k] = st.innovation
            if covs is not None:
                covs[k] = self.P
        t = np.arange(N, dtype=np.float64) if time_s is None else np.asarray(time_s, float)
        info = {"cov": covs, "cov_index": np.arange(N)} if keep_cov else {}
        return SequentialResult(time_s=t, state=xs, std=stds, state_names=self.state_names,
                                loglik=np.full(N, np.nan), innovation=nus,
                                innovations=dict(self.innovations), info=info)
