"""Benchmark systems for the particle-filter library (methods M5): oracles, no filter code.

* :func:`simulate_growth` -- the univariate non-stationary growth model
  ``x_k = 0.5 x + 25 x / (1 + x^2) + 8 cos(1.2 (k - 1)) + u_k``, ``y_k = x_k^2 / 20 + v_k``;
* :func:`simulate_linear_gaussian` -- ``x_k = F x + w``, ``y_k = H x + v`` (the particle
  filter must reproduce the Kalman filter on it);
* :func:`simulate_cstr` -- the continuous stirred-tank reactor of methods M5 (Henson-Seborg
  kinetics with coolant and level dynamics) under closed-loop control, with its three faults:
  ``"setpoint"`` (temperature set-point +3 K), ``"sensor_bias"`` (temperature-sensor bias
  +4 K), ``"feed_flow"`` (feed flow +10 L/min).

Reactor choices (documented in ``docs/detect.md``):

* controllers: a PI loop moves the coolant flow ``Q_C`` on the *measured* temperature,
  ``Q_C = Q_C0 + Kc e + (Kc / tau_I) int e``, ``e = T_meas - T_sp`` (Kc = 2 L/(min K),
  tau_I = 2 min), clipped to [0, 60] L/min; a proportional loop moves the outflow on the
  measured level, ``Q = Q0 + K_h (h_meas - h_sp)`` (K_h = 500 L/(min m)), so a feed-flow step
  leaves a level offset of ``dQ_F / K_h``;
* measurements ``y = [T + bias, C_A, T_C, h]`` with white Gaussian noise of standard deviation
  :data:`CSTR_MEAS_SD` = [0.1 K, 0.001 mol/L, 0.1 K, 0.002 m], sampled every ``dt_min``;
* unmeasured disturbances: the feed temperature and concentration wander as
  Ornstein-Uhlenbeck processes (1 K and 0.01 mol/L standard deviation, 5 min correlation);
* integration: classical Runge-Kutta with ``substeps`` steps per sample (the reaction's time
  constant is about 0.04 min).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "CSTR_FAULTS",
    "CSTR_MEAS_SD",
    "CSTRParams",
    "CSTRRun",
    "cstr_rhs",
    "simulate_cstr",
    "simulate_growth",
    "simulate_linear_gaussian",
]


# --------------------------------------------------------------------------- growth model
def simulate_growth(T: int = 100, Q: float = 10.0, R: float = 1.0, x0: float = 0.1,
                    seed: int | np.random.Generator | None = 0, n_runs: int | None = None,
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Simulate the univariate non-stationary growth model.

    ``x_k = 0.5 x_{k-1} + 25 x_{k-1} / (1 + x_{k-1}^2) + 8 cos(1.2 (k - 1)) + u_k``,
    ``u_k ~ N(0, Q)``; ``y_k = x_k^2 / 20 + v_k``, ``v_k ~ N(0, R)``; ``k = 1..T``.

    Parameters
    ----------
    T : int
        Number of steps.
    Q, R : float
        Process and measurement noise variances.
    x0 : float
        Initial state ``x_0``.
    seed : int or Generator
        Random source.
    n_runs : int, optional
        Simulate this many independent runs at once (leading axis).

    Returns
    -------
    x, y : ndarray, shape (T,) (``(n_runs, T)``)
        States ``x_1..x_T`` and measurements ``y_1..y_T``.
    """
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    shape = (1 if n_runs is None else int(n_runs),)
    x = np.full(shape, float(x0))
    xs = np.empty(shape + (T,))
    ys = np.empty(shape + (T,))
    for k in range(1, T + 1):
        x = (0.5 * x + 25.0 * x / (1.0 + x * x) + 8.0 * np.cos(1.2 * (k - 1))
             + np.sqrt(Q) * rng.standard_normal(shape))
        xs[:, k - 1] = x
        ys[:, k - 1] = x * x / 20.0 + np.sqrt(R) * rng.standard_normal(shape)
    if n_runs is None:
        return xs[0], ys[0]
    return xs, ys


# --------------------------------------------------------------------------- linear Gaussian
def simulate_linear_gaussian(F: np.ndarray, H: np.ndarray, Q: np.ndarray, R: np.ndarray,
                             x0: np.ndarray, P0: np.ndarray, T: int,
                             seed: int | np.random.Generator | None = 0,
                             ) -> tuple[np.ndarray, np.ndarray]:
    """Simulate ``x_k = F x_{k-1} + w``, ``y_k = H x_k + v`` with ``x_0 ~ N(x0, P0)``.

    Parameters
    ----------
    F, H, Q, R : ndarray
        Transition (n, n), measurement (m, n), process (n, n) and measurement (m, m)
        noise covariances.
    x0, P0 : ndarray
        Prior mean (n,) and covariance (n, n) of ``x_0``.
    T : int
        Number of steps.
    seed : int or Generator
        Random source.

    Returns
    -------
    x : ndarray, shape (T, n)
        States ``x_1..x_T``.
    y : ndarray, shape (T, m)
        Measurements.
    """
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    F, H, Q, R = (np.atleast_2d(np.asarray(a, dtype=np.float64)) for a in (F, H, Q, R))
    x = rng.multivariate_normal(np.atleast_1d(x0), np.atleast_2d(P0))
    xs = np.empty((T, F.shape[0]))
    ys = np.empty((T, H.shape[0]))
    for k in range(T):
        x = F @ x + rng.multivariate_normal(np.zeros(F.shape[0]), Q)
        xs[k] = x
        ys[k] = H @ x + rng.multivariate_normal(np.zeros(H.shape[0]), R)
    return xs, ys


# --------------------------------------------------------------------------- reactor
#: Fault hypotheses of the reactor and their sizes.
CSTR_FAULTS: dict[str, dict[str, float]] = {
    "setpoint": {"d_T_sp": 3.0},       # temperature set-point +3 K
    "sensor_bias": {"bias_T": 4.0},    # temperature-sensor bias +4 K
    "feed_flow": {"d_Q_F": 10.0},      # feed flow +10 L/min
}

#: Measurement noise standard deviations of y = [T, C_A, T_C, h]: K, mol/L, K, m.
CSTR_MEAS_SD = np.array([0.1, 0.001, 0.1, 0.002])


@dataclass
class CSTRParams:
    """Operating point, physical constants and controllers of the stirred-tank reactor.

    Units: concentrations mol/L, temperatures K, flows L/min, time min, level m, volumes L,
    energies J.  ``area_L_m`` is the tank cross-section (L per m of level) such that
    ``A h = 100 L`` at the operating level.
    """

    C_A: float = 0.037
    C_AF: float = 1.0
    T: float = 402.35
    T_F: float = 320.0
    T_C: float = 345.44
    T_CF: float = 300.0
    Q_F: float = 100.0
    Q: float = 100.0
    Q_C: float = 15.0
    h: float = 0.6
    E_R: float = 8750.0
    k0: float = 7.2e10
    rho_cp: float = 239.0
    rho_cp_c: float = 4175.0
    dH: float = -5.0e4
    UA_C: float = 5.0e4
    V_c: float = 10.0
    area_L_m: float = 100.0 / 0.6
    Kc: float = 2.0
    tau_I: float = 2.0
    K_h: float = 500.0
    Q_C_max: float = 60.0
    meas_sd: np.ndarray = field(default_factory=lambda: CSTR_MEAS_SD.copy())
    feed_T_sd: float = 1.0
    feed_C_sd: float = 0.01
    feed_tau_min: float = 5.0


def cstr_rhs(x: np.ndarray, Q_C: np.ndarray, Q_out: np.ndarray, Q_F: np.ndarray,
             T_F: np.ndarray, C_AF: np.ndarray, p: CSTRParams) -> np.ndarray:
    """Time derivative of the reactor state ``x = [C_A, T, T_C, h]`` (per minute).

    Parameters
    ----------
    x : ndarray, shape (..., 4)
        Concentration [mol/L], reactor temperature [K], coolant temperature [K], level [m].
    Q_C, Q_out, Q_F : ndarray, shape (...)
        Coolant flow, outflow and feed flow, L/min.
    T_F, C_AF : ndarray, shape (...)
        Feed temperature [K] and concentration [mol/L].
    p : CSTRParams
        Constants.

    Returns
    -------
    ndarray, shape (..., 4)
        d/dt of ``x``, per minute.
    """
    C_A, T, T_C, h = x[..., 0], x[..., 1], x[..., 2], x[..., 3]
    vol = p.area_L_m * np.maximum(h, 1e-3)
    r = p.k0 * np.exp(-p.E_R / T) * C_A
    ua = p.UA_C * (T - T_C)
    dC = -r + Q_F * (C_AF - C_A) / vol
    dT = r * (-p.dH) / p.rho_cp + Q_F * (T_F - T) / vol - ua / (p.rho_cp * vol)
    dTc = Q_C * (p.T_CF - T_C) / p.V_c + ua / (p.rho_cp_c * p.V_c)
    dh = (Q_F - Q_out) / p.area_L_m
    return np.stack([dC, dT, dTc, dh], axis=-1)


@dataclass
class CSTRRun:
    """Output of :func:`simulate_cstr` (runs along the leading axis).

    Attributes
    ----------
    time_min : ndarray, shape (T,)
        Sample times, min (the first sample is at ``dt_min``).
    y : ndarray, shape (runs, T, 4)
        Measurements ``[T + bias, C_A, T_C, h]``.
    x : ndarray, shape (runs, T, 4)
        True state ``[C_A, T, T_C, h]``.
    Q_C : ndarray, shape (runs, T)
        Coolant flow applied over the interval ending at each sample, L/min.
    fault : str or None
        Fault injected.
    onset_min : float
        Fault onset, min (inf without a fault).
    params : CSTRParams
        Constants used.
    """

    time_min: np.ndarray
    y: np.ndarray
    x: np.ndarray
    Q_C: np.ndarray
    fault: str | None
    onset_min: float
    params: CSTRParams


def simulate_cstr(fault: str | None = None, *, n_runs: int = 1, duration_min: float = 20.0,
                  onset_min: float = 5.0, dt_min: float = 0.05, substeps: int = 10,
                  seed: int | np.random.Generator | None = 0,
                  params: CSTRParams | None = None) -> CSTRRun:
    """Simulate the controlled stirred-tank reactor, optionally with one fault.

    Parameters
    ----------
    fault : {None, "setpoint", "sensor_bias", "feed_flow"}
        Fault switched on at ``onset_min`` (sizes in :data:`CSTR_FAULTS`).
    n_runs : int
        Independent runs simulated at once.
    duration_min : float
        Length of each run, min.
    onset_min : float
        Fault onset, min.
    dt_min : float
        Sampling (and control) interval, min.
    substeps : int
        Runge-Kutta steps per sample.
    seed : int or Generator
        Random source.
    params : CSTRParams, optional
        Constants (default :class:`CSTRParams`).

    Returns
    -------
    CSTRRun
    """
    if fault is not None and fault not in CSTR_FAULTS:
        raise ValueError(f"fault must be None or one of {sorted(CSTR_FAULTS)}, not {fault!r}")
    p = params or CSTRParams()
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    nt = int(round(duration_min / dt_min))
    R = int(n_runs)
    size = CSTR_FAULTS.get(fault, {}) if fault else {}
    x = np.tile([p.C_A, p.T, p.T_C, p.h], (R, 1)).astype(np.float64)
    integ = np.zeros(R)
    fa = np.exp(-dt_min / p.feed_tau_min)
    fb = np.sqrt(1.0 - fa * fa)
    dTF = p.feed_T_sd * rng.standard_normal(R)
    dCF = p.feed_C_sd * rng.standard_normal(R)
    t = np.arange(1, nt + 1) * dt_min
    ys = np.empty((R, nt, 4))
    xs = np.empty((R, nt, 4))
    qcs = np.empty((R, nt))
    sd = np.asarray(p.meas_sd, dtype=np.float64)
    y_prev = np.asarray(x, dtype=np.float64)[:, [1, 0, 2, 3]] + sd * rng.standard_normal((R, 4))
    hstep = dt_min / substeps
    for i in range(nt):
        t_start = i * dt_min
        on = t_start >= onset_min
        T_sp = p.T + (size.get("d_T_sp", 0.0) if on else 0.0)
        Q_F = np.full(R, p.Q_F + (size.get("d_Q_F", 0.0) if on else 0.0))
        # Controllers act on the last measurement (zero-order hold over the interval).
        e = y_prev[:, 0] - T_sp
        Q_C = np.clip(p.Q_C + p.Kc * e + (p.Kc / p.tau_I) * integ, 0.0, p.Q_C_max)
        integ = integ + e * dt_min
        Q_out = np.maximum(p.Q + p.K_h * (y_prev[:, 3] - p.h), 0.0)
        T_F = p.T_F + dTF
        C_AF = p.C_AF + dCF
        for _ in range(substeps):
            k1 = cstr_rhs(x, Q_C, Q_out, Q_F, T_F, C_AF, p)
            k2 = cstr_rhs(x + 0.5 * hstep * k1, Q_C, Q_out, Q_F, T_F, C_AF, p)
            k3 = cstr_rhs(x + 0.5 * hstep * k2, Q_C, Q_out, Q_F, T_F, C_AF, p)
            k4 = cstr_rhs(x + hstep * k3, Q_C, Q_out, Q_F, T_F, C_AF, p)
            x = x + (hstep / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        dTF = fa * dTF + fb * p.feed_T_sd * rng.standard_normal(R)
        dCF = fa * dCF + fb * p.feed_C_sd * rng.standard_normal(R)
        on_end = t[i] > onset_min
        bias = size.get("bias_T", 0.0) if on_end else 0.0
        y = x[:, [1, 0, 2, 3]] + sd * rng.standard_normal((R, 4))
        y[:, 0] += bias
        ys[:, i], xs[:, i], qcs[:, i] = y, x, Q_C
        y_prev = y
    return CSTRRun(time_min=t, y=ys, x=xs, Q_C=qcs, fault=fault,
                   onset_min=float(onset_min) if fault else float("inf"), params=p)
