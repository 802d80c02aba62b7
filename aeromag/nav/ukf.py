"""A generic unscented Kalman filter and the one result type of the navigation filters.

The filter follows the package's sequential convention: construct it with its parameters,
``step(...)`` one sample (predict, then update), ``run(...)`` over arrays returning one
:class:`FilterResult`.  Process and measurement functions are vectorised over sigma points:
they receive all ``2n + 1`` points as one ``(2n + 1, n)`` array.  Angles (radians) are
handled by index: their means are circular and their residuals wrapped to [-pi, pi).

The square root of the covariance never fails on a finite matrix (symmetrised, jittered
Cholesky, eigen fallback; :func:`aeromag._core.unscented.robust_sqrt`); a covariance that is
no longer finite raises :class:`DivergenceError` with one line naming the time.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from .._core.unscented import (
    CovarianceError,
    angle_mean_fn,
    angle_residual_fn,
    sigma_points,
    symmetrize,
)
from ..errors import AeromagError

log = logging.getLogger(__name__)

__all__ = ["DivergenceError", "FilterResult", "InnovationStats", "UnscentedKalmanFilter"]

SigmaFn = Callable[..., np.ndarray]


class DivergenceError(AeromagError, ArithmeticError):
    """The filter's state or covariance is no longer finite or plausible."""


@dataclass
class InnovationStats:
    """Innovation statistics of one sensor (or measurement model).

    Attributes
    ----------
    dof : int
        Dimension of one measurement.
    n_fused : int
        Measurements fused.
    n_rejected : int
        Measurements rejected by the innovation gate.
    n_gated : int
        Measurements not used because a validity gate failed (quality, tilt, range limits,
        field strength, acceleration...).
    nis_sum : float
        Sum of the normalised innovation squared over the fused measurements.
    """

    dof: int
    n_fused: int = 0
    n_rejected: int = 0
    n_gated: int = 0
    nis_sum: float = 0.0

    @property
    def mean_nis(self) -> float | None:
        """Mean normalised innovation squared of the fused measurements.

        About ``dof`` when the filter is consistent; None when nothing was fused.
        """
        return self.nis_sum / self.n_fused if self.n_fused else None

    def as_dict(self) -> dict[str, float | int | None]:
        """Plain dictionary for reports."""
        m = self.mean_nis
        return {"dof": self.dof, "n_fused": self.n_fused, "n_rejected": self.n_rejected,
                "n_gated": self.n_gated, "mean_nis": m,
                "mean_nis_per_dof": None if m is None else m / self.dof}


@dataclass
class FilterResult:
    """What every filter run returns.

    Attributes
    ----------
    time_s : ndarray, shape (N,)
        Time of each output sample, s.
    x : ndarray, shape (N, n)
        State estimate after processing each sample (angles in rad).
    std : ndarray, shape (N, n)
        One-sigma uncertainty of each state component, same units.
    state_names : tuple of str
        Name of each state component.
    innovations : dict of str to InnovationStats
        Per-sensor innovation statistics.
    cov : ndarray, shape (M, n, n) or None
        Full covariance at the samples ``cov_index`` (kept on request).
    cov_index : ndarray of int, shape (M,) or None
        Output samples at which ``cov`` was kept.
    info : dict
        Anything else the filter reports (settings, references, warnings).
    """

    time_s: np.ndarray
    x: np.ndarray
    std: np.ndarray
    state_names: tuple[str, ...]
    innovations: dict[str, InnovationStats] = field(default_factory=dict)
    cov: np.ndarray | None = None
    cov_index: np.ndarray | None = None
    info: dict = field(default_factory=dict)

    def column(self, name: str) -> np.ndarray:
        """The estimate of one named state component over time."""
        return self.x[:, self.state_names.index(name)]


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
    def step(self, z: np.ndarray | None, u: object = None) -> np.ndarray:
        """Process one sample: predict, then fuse ``z``; return the state estimate.

        ``u`` is passed to ``fx`` when not None; ``z`` is skipped when None or not finite.
        """
        if u is None:
            self.predict()
        else:
            self.predict(u)
        if z is not None and np.all(np.isfinite(z)):
            self.update(z)
        return self.x.copy()

    def run(self, zs: np.ndarray, us: np.ndarray | None = None,
            time_s: np.ndarray | None = None, keep_cov: bool = False) -> FilterResult:
        """Run over a sequence of measurements (rows of NaN are predict-only).

        Parameters
        ----------
        zs : ndarray, shape (N, m)
            Measurements.
        us : ndarray, shape (N, ...), optional
            Inputs passed to the process model.
        time_s : ndarray, shape (N,), optional
            Sample times for the result (default 0..N-1).
        keep_cov : bool
            Keep the full covariance at every sample.

        Returns
        -------
        FilterResult
        """
        zs = np.asarray(zs, dtype=np.float64)
        if zs.ndim == 1:
            zs = zs[:, None]
        N, n = zs.shape[0], self.x.size
        xs, stds = np.empty((N, n)), np.empty((N, n))
        covs = np.empty((N, n, n)) if keep_cov else None
        for k in range(N):
            self.time_s = float(time_s[k]) if time_s is not None else float(k)
            self.step(zs[k], None if us is None else us[k])
            xs[k] = self.x
            stds[k] = np.sqrt(np.clip(np.diag(self.P), 0.0, None))
            if covs is not None:
                covs[k] = self.P
        t = np.arange(N, dtype=np.float64) if time_s is None else np.asarray(time_s, float)
        return FilterResult(time_s=t, x=xs, std=stds, state_names=self.state_names,
                            innovations=dict(self.innovations), cov=covs,
                            cov_index=np.arange(N) if keep_cov else None)
