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
import math

import numpy as np

from ..errors import InputError
from .sequential import InnovationStats, SequentialResult, Step

log = logging.getLogger(__name__)

__all__ = ["RecursiveLeastSquares", "check_forgetting", "state_names"]

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


def _upper_products(ft: np.ndarray, offs: np.ndarray) -> np.ndarray:
    """Upper-triangle outer products ``f_i f_j`` (i <= j) of each sample, in
    ``triu_indices`` order, samples along the last axis: ``ft`` is (n, k), the result
    (n (n + 1) / 2, k), every row a contiguous product of two contiguous rows."""
    n, k = ft.shape
    out = np.empty((offs[-1], k))
    for i in range(n):
        np.multiply(ft[i], ft[i:], out=out[offs[i]:offs[i + 1]])
    return out


def _repeat_columns(a: np.ndarray, m: int) -> np.ndarray:
    """Each column of ``a`` (N, n) repeated ``m`` times side by side: (N, n m)."""
    if m == 1:
        return a
    out = np.empty((a.shape[0], a.shape[1], m))
    out[:] = a[:, :, None]
    return out.reshape(a.shape[0], a.shape[1] * m)


def _symmetric_index(n: int) -> np.ndarray:
    """For each (i, j) of an n x n matrix, the position of (min, max) in ``triu_indices``."""
    iu, ju = np.triu_indices(n)
    pos = np.empty((n, n), dtype=np.intp)
    pos[iu, ju] = np.arange(len(iu))
    pos[ju, iu] = np.arange(len(iu))
    return pos.ravel()



def state_names(n: int, m: int = 1) -> tuple[str, ...]:
    """Names of the flattened parameters ``Theta.reshape(-1)``: ``theta_i`` (one output) or
    ``theta_i_j`` (row i of the regressor, output j)."""
    if m == 1:
        return tuple(f"theta_{i}" for i in range(n))
    return tuple(f"theta_{i}_{j}" for i in range(n) for j in range(m))


class RecursiveLeastSquares:
    """Recursive least squares with forgetting factor and a shared regressor.

    The package's sequential-filter convention (:mod:`aeromag._core.sequential`): the
    measurement is ``y`` (m outputs) and the regressor is the input ``u`` (n numbers);
    :meth:`step` returns a :class:`~aeromag._core.sequential.Step`, :meth:`run` a
    :class:`~aeromag._core.sequential.SequentialResult` whose state is ``Theta.reshape(-1)``.

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
    noise_std : float
        One-sigma measurement noise [units of y]: scales the reported ``std`` (the parameter
        covariance is ``noise_std**2 P``), the innovation variance and the log-likelihood.

    Attributes
    ----------
    theta : ndarray, shape (n, m)
        Current estimate.
    P : ndarray, shape (n, n)
        Current covariance (symmetric positive definite), for unit measurement noise.
    n_updates, n_skipped : int
        Samples used and skipped so far.
    stats : InnovationStats
        Consistency of the a-priori innovations so far (``dof = m``).

    Notes
    -----
    The a-priori innovation of sample k is ``e_k = y_k - Theta_(k-1).T phi_k``; its variance
    is ``noise_std**2 (1 + phi_k.T P_(k-1) phi_k / lambda)`` (the forgetting inflates the
    prior covariance by ``1/lambda``), which gives the NIS and the log-likelihood.
    """

    def __init__(self, n_params: int, n_outputs: int = 1, *, forgetting: float = 1.0,
                 alpha: float = 1e4, theta0: np.ndarray | None = None,
                 floor: float | None = None, noise_std: float = 1.0) -> None:
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
        self.noise_std = float(noise_std)
        if not (np.isfinite(self.noise_std) and self.noise_std > 0):
            raise ValueError(f"noise_std must be positive, got {noise_std!r}")
        t0 = np.zeros((self.n, self.m)) if theta0 is None else np.array(theta0, dtype=float)
        self.theta0 = t0.reshape(self.n, self.m)
        self.state_names = state_names(self.n, self.m)
        self._eye = np.eye(self.n)
        self.reset()

    # -- state --------------------------------------------------------------------------
    def reset(self) -> None:
        """Return to the prior: ``Theta = Theta_0``, ``P = alpha I``."""
        self.theta = self.theta0.copy()
        self.P = self.alpha * np.eye(self.n)
        self.n_updates = 0
        self.n_skipped = 0
        self.stats = InnovationStats(dof=self.m)

    @property
    def _leak(self) -> float:
        return (1.0 - self.forgetting) * self.floor

    def _std(self, P: np.ndarray) -> np.ndarray:
        sd = np.sqrt(P.diagonal()) * self.noise_std
        return sd if self.m == 1 else np.repeat(sd, self.m)

    def _loglik(self, e2: np.ndarray | float, s: np.ndarray | float) -> np.ndarray | float:
        """Log-likelihood of innovations with squared norm ``e2`` and variance ``s`` each."""
        return -0.5 * (self.m * np.log(2.0 * np.pi * s) + e2 / s)

    # -- streaming ----------------------------------------------------------------------
    def step(self, y: np.ndarray | float, u: np.ndarray | None = None) -> Step:
        """Update with one sample (covariance form).

        Parameters
        ----------
        y : ndarray, shape (m,) or float
            Measurement(s) [units of y].
        u : ndarray, shape (n,)
            Regressor (required).

        Returns
        -------
        Step
            State ``Theta.reshape(-1)`` and its std after the sample, the a-priori
            innovation (m,), its log-likelihood; ``used`` False (and NaN innovation) when
            the sample was skipped because the regressor or the measurement is not finite.
        """
        if u is None:
            raise ValueError("RecursiveLeastSquares.step needs the regressor u")
        phi = np.asarray(u, dtype=np.float64).reshape(self.n)
        y = np.asarray(y, dtype=np.float64).reshape(self.m)
        lam = self.forgetting
        P = self.P
        Pphi = P @ phi
        s = float(lam + phi @ Pphi)
        err = y - phi @ self.theta
        e2 = float(err @ err)
        # A regressor or measurement not finite makes s or e2 not finite (P is positive
        # definite): one check of two scalars instead of two array scans.
        if not (math.isfinite(s) and math.isfinite(e2)):
            self.n_skipped += 1
            self.stats.n_gated += 1
            return Step(self.theta.reshape(-1).copy(), self._std(self.P),
                        np.full(self.m, np.nan), float("nan"), False)
        k = Pphi / s
        sv = self.noise_std ** 2 * s / lam  # variance of each a-priori innovation
        stats = self.stats
        stats.n_fused += 1
        stats.nis_sum += e2 / sv
        theta = self.theta + k[:, None] * err[None, :]
        P = (P - k[:, None] * Pphi[None, :]) / lam
        P = 0.5 * (P + P.T)
        c = self._leak
        if c > 0.0:
            # Information += c I:  P <- (P^-1 + c I)^-1 = P (I + c P)^-1, and the estimate
            # moves to the minimiser of the criterion with the added prior weight.
            P = np.linalg.solve(self._eye + c * P, P)
            P = 0.5 * (P + P.T)
            theta = theta + c * (P @ (self.theta0 - theta))
        self.theta = theta
        self.P = P
        self.n_updates += 1
        loglik = -0.5 * (self.m * math.log(2.0 * math.pi * sv) + e2 / sv)
        return Step(theta.reshape(-1), self._std(P), err, loglik, True)

    # -- batched ------------------------------------------------------------------------
    def run(self, ys: np.ndarray, us: np.ndarray | None = None, *, history: bool = True,
            std: bool = True, predict: np.ndarray | None = None) -> SequentialResult:
        """Update with many samples at once (information form, vectorised); continues from
        the current state, so consecutive calls equal one call on the joined arrays.

        Parameters
        ----------
        ys : ndarray, shape (N, m) or (N,)
            Measurements [units of y].
        us : ndarray, shape (N, n)
            Regressors, one row per sample (required).
        history : bool
            Keep the estimate after every sample and the a-priori innovations; when False
            the result's ``state``, ``std``, ``loglik`` have no rows, ``innovation`` is None
            and only the final state is computed at every block end (faster for long logs).
        std : bool
            With ``history``: also the std of every parameter after every sample (one
            n x n inverse per sample: about 2.5x the solve of the estimate at n = 16); when
            False ``std`` has no rows.
        predict : ndarray, shape (N, n), optional
            Other regressors ``x_k`` whose a-priori prediction variance is wanted: the
            result's ``info["predict_var"][k] = noise_std**2 x_k.T P_(k-1) x_k / lambda``
            (the variance of ``Theta_(k-1).T x_k`` from the parameter uncertainty), with
            ``history`` only.

        Returns
        -------
        SequentialResult
            ``state`` (N, n m) = ``Theta_k.reshape(-1)`` after each sample (a skipped sample
            repeats the previous estimate), ``std``, ``loglik`` and ``innovation`` (N, m),
            a-priori, NaN where skipped; ``innovations["y"]``; ``info``: ``skipped`` (bool,
            N), ``theta_final`` (n, m), ``covariance`` (final ``P``, unit noise),
            ``prior_var`` (N: ``phi_k.T P_(k-1) phi_k / lambda``), ``forgetting``,
            ``alpha``, ``floor``, ``noise_std`` and ``predict_var`` when asked.
        """
        from scipy.signal import lfilter

        if us is None:
            raise ValueError("RecursiveLeastSquares.run needs the regressors us")
        phi = np.asarray(us, dtype=np.float64)
        N = len(phi)
        y = np.asarray(ys, dtype=np.float64).reshape(N, -1)
        if phi.shape != (N, self.n) or y.shape[1] != self.m:
            raise ValueError(f"us must be (N, {self.n}) and ys (N, {self.m}); got "
                             f"{phi.shape} and {y.shape}")
        n, m, lam, c = self.n, self.m, self.forgetting, self._leak
        want_std = history and std
        xp = None
        if predict is not None and history:
            xp = np.asarray(predict, dtype=np.float64).reshape(N, n)
        ok = np.isfinite(phi).all(axis=1) & np.isfinite(y).all(axis=1)
        idx = np.flatnonzero(ok)
        iu, ju = np.triu_indices(n)
        offs = np.r_[0, np.cumsum(np.arange(n, 0, -1))]  # row i of the upper triangle
        sym = _symmetric_index(n)
        R = np.linalg.inv(self.P)
        R = 0.5 * (R + R.T)
        B = R @ self.theta
        P_prev = self.P  # covariance before the next used sample
        sd_start = np.sqrt(np.diag(self.P))
        # Filter states: y[-1] = R_prev gives zi = lam * R_prev.
        zr = lam * R[iu, ju]
        zb = lam * B.reshape(-1)
        rows_out = N if history else 0
        hist = np.empty((rows_out, n, m))
        sd = np.full((N if want_std else 0, n), np.nan)
        innov = np.full((rows_out, m), np.nan)
        pvar = np.full(rows_out, np.nan)
        xvar = np.full(N, np.nan) if xp is not None else None
        prev = self.theta.copy()
        last_fill = 0
        diag = iu == ju
        leak_b = (c * self.theta0).reshape(-1)
        a = [1.0, -lam]
        extra = 1 + (xp is not None)  # right-hand sides for the next sample's prior forms
        for s0 in range(0, len(idx), BLOCK):
            rows = idx[s0:s0 + BLOCK]
            k = len(rows)
            if rows[-1] - rows[0] == k - 1:  # no skipped sample: slices, no gathers
                rsel = slice(rows[0], rows[-1] + 1)
            else:
                rsel = rows
            fk = phi[rsel]  # (k, n), samples along the first axis
            ft = np.ascontiguousarray(fk.T)
            yt = y[rsel].T
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
                # One batched solve: the estimate, P_k times the next sample's regressor
                # (and predictor), and P_k itself when the std is wanted.
                rhs = np.zeros((k, n, m + extra))
                rhs[:, :, :m] = Bk.T.reshape(k, n, m)
                rhs[:-1, :, m] = fk[1:]
                xk = None
                if xp is not None:
                    xk = xp[rsel]
                    rhs[:-1, :, m + 1] = xk[1:]
                Rb = np.ascontiguousarray(Rk[sym].T).reshape(k, n, n)
                if want_std:  # the inverse itself is wanted: one inverse, then products
                    Pk = np.linalg.inv(Rb)
                    sol = Pk @ rhs
                    sol += Pk @ (rhs - Rb @ sol)  # one refinement: the solve's accuracy
                else:
                    sol = np.linalg.solve(Rb, rhs)
                th = sol[:, :, :m]
                # The first sample of the block: its prior forms with the covariance before.
                f0 = ft[:, 0]
                q = np.empty(k)
                q[0] = f0 @ P_prev @ f0
                q[1:] = np.einsum("kn,kn->k", fk[1:], sol[:-1, :, m])
                pvar[rsel] = q / lam
                e = np.empty((k, m))
                e[0] = yt[:, 0] - f0 @ prev
                e[1:] = yt.T[1:] - np.einsum("kn,knm->km", fk[1:], th[:-1])
                innov[rsel] = e
                if xk is not None:
                    x0 = xk[0]
                    xq = np.empty(k)
                    xq[0] = x0 @ P_prev @ x0
                    xq[1:] = np.einsum("kn,kn->k", xk[1:], sol[:-1, :, m + 1])
                    xvar[rsel] = xq / lam
                if want_std:
                    sd[rows] = np.sqrt(np.einsum("kii->ki", Pk))
                    P_prev = Pk[-1]
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
            if history and not want_std:
                Rf = np.empty((n, n))
                Rf[iu, ju] = R_last
                Rf[ju, iu] = R_last
                P_prev = np.linalg.inv(Rf)
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
        if want_std and N > len(idx):  # a skipped sample repeats the previous std
            have = np.where(ok, np.arange(N), -1)
            np.maximum.accumulate(have, out=have)
            sd = np.where((have >= 0)[:, None], sd[np.maximum(have, 0)], sd_start)
        self.n_updates += len(idx)
        self.n_skipped += N - len(idx)
        sv = self.noise_std ** 2 * (1.0 + pvar) if history else pvar
        e2 = np.einsum("km,km->k", innov, innov) if history else innov[:, 0]
        loglik = self._loglik(e2, sv) if history else np.empty(0)
        stats = InnovationStats(dof=m, n_fused=len(idx), n_gated=N - len(idx),
                                nis_sum=float(np.sum((e2 / sv)[ok])) if history else 0.0)
        self.stats.n_fused += stats.n_fused
        self.stats.n_gated += stats.n_gated
        self.stats.nis_sum += stats.nis_sum
        if N - len(idx):
            log.info("RLS: %d of %d samples skipped (not finite)", N - len(idx), N)
        info = {"skipped": ~ok, "theta_final": self.theta.copy(), "covariance": self.P.copy(),
                "prior_var": pvar, "forgetting": lam, "alpha": self.alpha,
                "floor": self.floor, "noise_std": self.noise_std}
        if xvar is not None:
            info["predict_var"] = self.noise_std ** 2 * xvar
        return SequentialResult(
            time_s=np.arange(N, dtype=np.float64),
            state=hist.reshape(rows_out, n * m),
            std=_repeat_columns(self.noise_std * sd, m),
            state_names=self.state_names, loglik=loglik,
            innovation=innov if history else None,
            innovations={"y": stats}, info=info)
