"""Filter-side models of the particle-filter benchmarks (methods M5), and a Kalman reference.

The simulators in :mod:`aeromag.synthetic.benchmarks` are the oracles; the models here are
written independently from the published equations (the reactor's is a different
discretisation, with the unmeasured feed disturbances as random-walk states), so a test that
compares the two compares two implementations.

* :func:`growth_model` -- the univariate non-stationary growth model;
* :func:`linear_gaussian_model` and :func:`kalman_filter` -- the exact reference;
* :func:`cstr_model` -- the controlled stirred-tank reactor under one fault hypothesis, and
  :func:`cstr_detect_isolate` -- detection by the nominal filter's ``S_k`` and isolation by a
  bank of hypothesis filters.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._core.particles import (
    FilterBank,
    ParticleFilter,
    StateSpaceModel,
    Threshold,
    threshold_from_runs,
)

__all__ = [
    "CSTR_HYPOTHESES",
    "CSTR_WARMUP_STEPS",
    "CSTRStudy",
    "cstr_detect_isolate",
    "cstr_model",
    "cstr_threshold",
    "growth_model",
    "kalman_filter",
    "linear_gaussian_model",
]

_LOG2PI = float(np.log(2.0 * np.pi))


# --------------------------------------------------------------------------- growth
def growth_model(Q: float = 10.0, R: float = 1.0, x0: float = 0.1,
                 P0: float = 2.0) -> StateSpaceModel:
    """The growth model ``x_k = 0.5x + 25x/(1+x^2) + 8cos(1.2(k-1)) + u``, ``y = x^2/20 + v``.

    Parameters
    ----------
    Q, R : float
        Process and measurement noise variances.
    x0, P0 : float
        Prior mean and variance of ``x_0``.

    Returns
    -------
    StateSpaceModel
    """
    def f(x, k, u):
        return 0.5 * x + 25.0 * x / (1.0 + x * x) + 8.0 * np.cos(1.2 * (k - 1))

    def h(x, k):
        return x * x / 20.0

    def loglik(y, x, k):
        d = y[..., 0] - x[..., 0] ** 2 / 20.0
        return -0.5 * (d * d / R + np.log(R) + _LOG2PI)

    return StateSpaceModel(f=f, Q=[[Q]], loglik=loglik, x0=[x0], P0=[[P0]], h=h, R=[[R]])


# --------------------------------------------------------------------------- linear Gaussian
def linear_gaussian_model(F, H, Q, R, x0, P0) -> StateSpaceModel:
    """``x_k = F x + w``, ``y = H x + v`` as a :class:`StateSpaceModel`.

    Parameters
    ----------
    F, H, Q, R : array_like
        Transition (n, n), measurement (m, n) and noise covariances.
    x0, P0 : array_like
        Prior mean and covariance of ``x_0``.

    Returns
    -------
    StateSpaceModel
    """
    F, H, R = (np.atleast_2d(np.asarray(a, dtype=np.float64)) for a in (F, H, R))
    Ri = np.linalg.inv(R)
    logdet = float(np.linalg.slogdet(R)[1])
    m = H.shape[0]

    def f(x, k, u):
        return x @ F.T

    def h(x, k):
        return x @ H.T

    def loglik(y, x, k):
        d = y - x @ H.T
        return -0.5 * (np.einsum("...i,ij,...j->...", d, Ri, d) + logdet + m * _LOG2PI)

    return StateSpaceModel(f=f, Q=Q, loglik=loglik, x0=x0, P0=P0, h=h, R=R)


def kalman_filter(ys, F, H, Q, R, x0, P0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Kalman filter: posterior means, covariances and the log-likelihood of each step.

    Parameters
    ----------
    ys : ndarray, shape (T, m)
        Measurements.
    F, H, Q, R, x0, P0 : array_like
        Model (see :func:`linear_gaussian_model`).

    Returns
    -------
    mean : ndarray, shape (T, n)
    cov : ndarray, shape (T, n, n)
    loglik : ndarray, shape (T,)
        ``log p(y_k | y_1..y_{k-1})``.
    """
    F, H, Q, R, P = (np.atleast_2d(np.asarray(a, dtype=np.float64)) for a in (F, H, Q, R, P0))
    x = np.atleast_1d(np.asarray(x0, dtype=np.float64))
    ys = np.asarray(ys, dtype=np.float64).reshape(len(ys), -1)
    T, n = len(ys), x.size
    means, covs, ll = np.empty((T, n)), np.empty((T, n, n)), np.empty(T)
    for k in range(T):
        x = F @ x
        P = F @ P @ F.T + Q
        S = H @ P @ H.T + R
        d = ys[k] - H @ x
        Si = np.linalg.inv(S)
        ll[k] = -0.5 * (d @ Si @ d + np.linalg.slogdet(S)[1] + len(d) * _LOG2PI)
        K = P @ H.T @ Si
        x = x + K @ d
        P = P - K @ S @ K.T
        means[k], covs[k] = x, P
    return means, covs, ll


# --------------------------------------------------------------------------- reactor
#: Hypotheses of the reactor bank: nominal and the three faults of methods M5.
CSTR_HYPOTHESES: dict[str, dict[str, float]] = {
    "nominal": {},
    "setpoint": {"d_T_sp": 3.0},
    "sensor_bias": {"bias_T": 4.0},
    "feed_flow": {"d_Q_F": 10.0},
}

# Operating point and constants (methods M5), written out here independently of the simulator.
_C = dict(C_A=0.037, C_AF=1.0, T=402.35, T_F=320.0, T_C=345.44, T_CF=300.0, Q_F=100.0,
          Q=100.0, Q_C=15.0, h=0.6, E_R=8750.0, k0=7.2e10, rho_cp=239.0, rho_cp_c=4175.0,
          dH=-5.0e4, UA_C=5.0e4, V_c=10.0, A=100.0 / 0.6, Kc=2.0, tau_I=2.0, K_h=500.0)
_MEAS_SD = np.array([0.1, 0.001, 0.1, 0.002])


def cstr_model(hypothesis: str = "nominal", dt_min: float = 0.05,
               onset_step: np.ndarray | int | None = None, substeps: int = 2,
               meas_sd: np.ndarray = _MEAS_SD) -> StateSpaceModel:
    """The controlled reactor as a state-space model under one fault hypothesis.

    State ``[C_A, T, T_C, h, I, dT_F, dC_AF]``: the reactor's four states, the temperature
    controller's integral (K min) and the unmeasured feed-temperature and feed-concentration
    deviations (random walks).  The controllers are in the model and act on the model's own
    measured temperature (``T + bias``) and level.  Measurement ``[T + bias, C_A, T_C, h]``.

    Parameters
    ----------
    hypothesis : str
        A key of :data:`CSTR_HYPOTHESES`.
    dt_min : float
        Sampling interval, min.
    onset_step : int or ndarray of int, optional
        The fault acts from this step on (per batch element when an array); default from the
        first step.
    substeps : int
        Runge-Kutta steps per sample.
    meas_sd : ndarray, shape (4,)
        Measurement noise standard deviations [K, mol/L, K, m].

    Returns
    -------
    StateSpaceModel
    """
    if hypothesis not in CSTR_HYPOTHESES:
        raise ValueError(f"hypothesis must be one of {sorted(CSTR_HYPOTHESES)}")
    fz = CSTR_HYPOTHESES[hypothesis]
    c = _C
    sd = np.asarray(meas_sd, dtype=np.float64)
    onset = None if onset_step is None else np.asarray(onset_step)

    def active(k: int) -> np.ndarray | bool:
        if onset is None:
            return True
        a = k >= onset
        return a[:, None] if np.ndim(a) else a

    k0, e_r, dh_rc = c["k0"], c["E_R"], -c["dH"] / c["rho_cp"]
    ua_rc, ua_rcc = c["UA_C"] / c["rho_cp"], c["UA_C"] / (c["rho_cp_c"] * c["V_c"])
    area, t_cf, v_c = c["A"], c["T_CF"], c["V_c"]

    def rhs(C_A, T, T_C, h, q_c, q_out, q_f, c_af, t_f):
        inv_vol = 1.0 / (area * np.maximum(h, 1e-3))
        r = k0 * np.exp(-e_r / T) * C_A
        dT_TC = T - T_C
        fv = q_f * inv_vol
        dC = fv * (c_af - C_A) - r
        dT = r * dh_rc + fv * (t_f - T) - ua_rc * dT_TC * inv_vol
        dTc = q_c * (t_cf - T_C) / v_c + ua_rcc * dT_TC
        dh = (q_f - q_out) / area
        return dC, dT, dTc, dh

    def f(z, k, u):
        on = active(k)
        bias = np.where(on, fz.get("bias_T", 0.0), 0.0)
        sp = c["T"] + np.where(on, fz.get("d_T_sp", 0.0), 0.0)
        q_f = c["Q_F"] + np.where(on, fz.get("d_Q_F", 0.0), 0.0)
        e = z[..., 1] + bias - sp
        q_c = np.clip(c["Q_C"] + c["Kc"] * e + (c["Kc"] / c["tau_I"]) * z[..., 4], 0.0, 60.0)
        q_out = np.maximum(c["Q"] + c["K_h"] * (z[..., 3] - c["h"]), 0.0)
        c_af, t_f = c["C_AF"] + z[..., 6], c["T_F"] + z[..., 5]
        x = [z[..., i] for i in range(4)]
        hs = dt_min / substeps
        for _ in range(substeps):
            k1 = rhs(*x, q_c, q_out, q_f, c_af, t_f)
            k2 = rhs(*(xi + 0.5 * hs * ki for xi, ki in zip(x, k1, strict=True)),
                     q_c, q_out, q_f, c_af, t_f)
            k3 = rhs(*(xi + 0.5 * hs * ki for xi, ki in zip(x, k2, strict=True)),
                     q_c, q_out, q_f, c_af, t_f)
            k4 = rhs(*(xi + hs * ki for xi, ki in zip(x, k3, strict=True)),
                     q_c, q_out, q_f, c_af, t_f)
            x = [xi + (hs / 6.0) * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
                 for xi, a1, a2, a3, a4 in zip(x, k1, k2, k3, k4, strict=True)]
        out = z.copy()
        for i in range(4):
            out[..., i] = x[i]
        out[..., 4] = z[..., 4] + e * dt_min
        return out

    def h(z, k):
        bias = np.where(active(k), fz.get("bias_T", 0.0), 0.0)
        return np.stack([z[..., 1] + bias, z[..., 0], z[..., 2], z[..., 3]], axis=-1)

    def loglik(y, z, k):
        d = (y - h(z, k)) / sd
        return -0.5 * np.sum(d * d, axis=-1) - np.sum(np.log(sd)) - 2.0 * _LOG2PI

    # Process noise per step: the controllers' jitter from measurement noise and the
    # feed disturbances' random walk (5 min correlation, 1 K and 0.01 mol/L).
    q = np.array([2e-4, 0.03, 0.06, 4e-4, 0.006, 0.15, 0.0015]) ** 2
    x0 = np.array([c["C_A"], c["T"], c["T_C"], c["h"], 0.0, 0.0, 0.0])
    P0 = np.diag([1e-3, 0.3, 1.0, 2e-3, 0.1, 1.0, 0.01]) ** 2
    return StateSpaceModel(f=f, Q=np.diag(q), loglik=loglik, x0=x0, P0=P0, h=h,
                           R=np.diag(sd**2))


@dataclass
class CSTRStudy:
    """Result of :func:`cstr_detect_isolate` over a batch of runs.

    Attributes
    ----------
    stat_nominal : ndarray, shape (runs, T)
        ``S_k`` of the nominal filter.
    detected : ndarray of bool, shape (runs,)
        Nominal ``S_k`` above the threshold at or after the fault onset.
    false_alarm : ndarray of bool, shape (runs,)
        Nominal ``S_k`` above the threshold before the onset.
    delay_min : ndarray, shape (runs,)
        First alarm after the onset minus the onset, min (NaN when not detected).
    isolated : list of str
        Most likely hypothesis per run at the end of the isolation window ("" if none).
    bank_stat : ndarray, shape (H, runs, T) or None
        ``S_k`` of each hypothesis of the bank.
    names : list of str
        Hypotheses of the bank.
    """

    stat_nominal: np.ndarray
    detected: np.ndarray
    false_alarm: np.ndarray
    delay_min: np.ndarray
    isolated: list[str]
    bank_stat: np.ndarray | None
    names: list[str]


#: Samples at the start of a run whose S_k is not used (the filter's convergence from its
#: prior: the simulator's feed disturbances start away from zero), 2 min.
CSTR_WARMUP_STEPS = 40


def cstr_threshold(y_free: np.ndarray, n_particles: int = 300, window: int = 10,
                   percentile: float = 99.0, seed: int = 0, dt_min: float = 0.05,
                   warmup_steps: int = CSTR_WARMUP_STEPS,
                   fit: str = "empirical") -> tuple[Threshold, np.ndarray]:
    """Threshold of the nominal reactor filter from fault-free runs.

    Parameters
    ----------
    y_free : ndarray, shape (runs, T, 4)
        Measurements of fault-free runs.
    n_particles, window : int
        Filter size and ``M``.
    percentile : float
        Percentile of the runs' maxima of ``S_k``.
    seed : int
        Random seed.
    dt_min : float
        Sampling interval, min.
    warmup_steps : int
        Leading samples whose ``S_k`` is set to NaN (the filter converging from its prior).
    fit : {"empirical", "gumbel"}
        How the percentile of the maxima is taken (see
        :func:`~aeromag._core.particles.threshold_from_runs`).

    Returns
    -------
    Threshold, ndarray
        The threshold and the fault-free ``S_k`` (runs, T).
    """
    pf = ParticleFilter(cstr_model("nominal", dt_min), n_particles, window=window,
                        batch=len(y_free), seed=seed)
    stat = pf.run(y_free).info["stat"]
    stat[:, :warmup_steps] = np.nan
    return threshold_from_runs(stat, percentile, fit), stat


def cstr_detect_isolate(y: np.ndarray, time_min: np.ndarray, onset_min: float,
                        threshold: float, *, n_particles: int = 300, window: int = 10,
                        isolation_steps: int = 100, seed: int = 1,
                        dt_min: float = 0.05,
                        warmup_steps: int = CSTR_WARMUP_STEPS) -> CSTRStudy:
    """Detect with the nominal filter, then isolate with a bank started at the detection.

    Each run's hypothesis filters switch their fault on ``window`` steps before that run's
    first alarm (the window that raised it); the isolated hypothesis is the one with the
    smallest ``S_k`` ``isolation_steps`` after the alarm (or at the end of the run).

    Parameters
    ----------
    y : ndarray, shape (runs, T, 4)
        Measurements.
    time_min : ndarray, shape (T,)
        Sample times, min.
    onset_min : float
        True fault onset, min (for the delay and the false-alarm split).
    threshold : float
        Threshold on the nominal ``S_k``.
    n_particles, window, isolation_steps : int
        Filter size, ``M`` and the isolation horizon in steps.
    seed : int
        Random seed.
    dt_min : float
        Sampling interval, min.
    warmup_steps : int
        Leading samples whose ``S_k`` is set to NaN (never alarm).

    Returns
    -------
    CSTRStudy
    """
    runs, T = y.shape[:2]
    pf = ParticleFilter(cstr_model("nominal", dt_min), n_particles, window=window, batch=runs,
                        seed=seed)
    stat = pf.run(y).info["stat"]
    stat[:, :warmup_steps] = np.nan
    with np.errstate(invalid="ignore"):
        alarm = stat > threshold
    pre = time_min < onset_min
    false_alarm = np.any(alarm & pre, axis=1)
    post = alarm & ~pre
    detected = np.any(post, axis=1)
    first = np.where(detected, np.argmax(post, axis=1), -1)
    delay = np.where(detected, time_min[np.maximum(first, 0)] - onset_min, np.nan)
    names = list(CSTR_HYPOTHESES)
    isolated = [""] * runs
    bank_stat = None
    if np.any(detected):
        # Step index k of sample t is t + 1 (the filter counts steps from 1).
        onset_step = np.where(detected, first + 1 - window + 1, T + 10)
        models = {nm: cstr_model(nm, dt_min, onset_step=onset_step) for nm in names}
        bank = FilterBank(models, seed=seed + 1, n_particles=n_particles, window=window,
                          batch=runs)
        res = bank.run(y)
        bank_stat = res.stat
        at = np.minimum(np.maximum(first, 0) + isolation_steps, T - 1)
        choice = res.most_likely[np.arange(runs), at]
        isolated = [names[int(c)] if d and c >= 0 else "" for c, d in
                    zip(choice, detected, strict=True)]
    return CSTRStudy(stat_nominal=stat, detected=detected, false_alarm=false_alarm,
                     delay_min=delay, isolated=isolated, bank_stat=bank_stat, names=names)
