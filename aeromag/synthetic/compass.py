"""Simulator of the forgetting-factor compass-calibration study (methods.md M3).

Pitch, roll and heading oscillate together at 1.2 pi rad/s (0.6 Hz) with a common amplitude,
sampled at 50 Hz; the vector magnetometer measures ``flux = C (C_nb.T m) + h + noise`` with
soft-iron matrix ``C`` and hard-iron offset ``h`` that switch from (C1, Hp1) to (C2, Hp2) at
t = 15 s.  The study's hard-iron vectors are kept; its soft-iron matrices are lost, so C1 and
C2 are chosen here (near identity, a few per cent of scale and cross-coupling, as for a
small UAV, and different from each other so the switch moves all 12 parameters):

    C1 = [[1.03, 0.02, -0.01], [0.01, 0.97, 0.03], [-0.02, 0.01, 1.02]]
    C2 = [[0.94, -0.05, 0.04], [0.06, 1.05, -0.03], [0.03, -0.04, 0.96]]

The ideal calibration that maps the measurement back to the Earth field in body axes is
``D = C^-1``, ``e = -C^-1 h`` (``D @ flux + e = C_nb.T m + D @ noise``).  The default Earth
field is the study's (Taiyuan, mid-2017, IGRF): N 29.27, E -2.73, D 45.42 uT.

This module is an oracle: it imports no fitting code.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .._core.angles import wrap360_deg
from .._core.rotations import rotate_ned_to_body

__all__ = ["C1", "C2", "HP1_NT", "HP2_NT", "TAIYUAN_NED_NT", "CompassScenario",
           "simulate_compass"]

C1 = np.array([[1.03, 0.02, -0.01], [0.01, 0.97, 0.03], [-0.02, 0.01, 1.02]])
C2 = np.array([[0.94, -0.05, 0.04], [0.06, 1.05, -0.03], [0.03, -0.04, 0.96]])
#: The study's hard-iron vectors before and after the switch [nT].
HP1_NT = np.array([0.170, 0.994, -3.416]) * 1000.0
HP2_NT = np.array([11.394, 1.336, -3.086]) * 1000.0
#: The study's Earth field (Taiyuan, 37.87 N, 112.55 E, 0.8 km, mid-2017) in NED [nT].
TAIYUAN_NED_NT = np.array([29270.0, -2730.0, 45420.0])


@dataclass
class CompassScenario:
    """Parameters of :func:`simulate_compass` (units in the names).

    Attributes
    ----------
    amplitude_deg : float
        Common amplitude of the pitch, roll and heading oscillations [deg].
    duration_s, rate_hz : float
        Length [s] and sample rate [Hz].
    omega_rad_s : float
        Angular frequency of the oscillations [rad/s] (the study: 1.2 pi).
    phases_rad : tuple of float
        Phases of roll, pitch and heading [rad].  The study says only "together"; equal
        phases make the attitude path almost a rotation about one axis, so these default to
        roll, pitch and heading a third of a cycle apart.
    heading0_deg : float
        Mean true heading [deg].
    noise_nT : float
        Standard deviation of the magnetometer noise per axis [nT] (the study: 0.2 uT).
    switch_s : float or None
        Time of the interference switch [s]; None for no switch.
    earth_ned_nT : ndarray, shape (3,)
        Earth field in north-east-down [nT].
    C1, C2 : ndarray, shape (3, 3)
        Soft-iron matrices before and after the switch.
    hp1_nT, hp2_nT : ndarray, shape (3,)
        Hard-iron offsets before and after the switch [nT].
    seed : int
        Random seed of the noise.
    """

    amplitude_deg: float = 40.0
    duration_s: float = 30.0
    rate_hz: float = 50.0
    omega_rad_s: float = 1.2 * np.pi
    phases_rad: tuple[float, float, float] = (0.0, 2.0 * np.pi / 3.0, 4.0 * np.pi / 3.0)
    heading0_deg: float = 30.0
    noise_nT: float = 200.0
    switch_s: float | None = 15.0
    earth_ned_nT: np.ndarray = field(default_factory=lambda: TAIYUAN_NED_NT.copy())
    C1: np.ndarray = field(default_factory=lambda: C1.copy())
    C2: np.ndarray = field(default_factory=lambda: C2.copy())
    hp1_nT: np.ndarray = field(default_factory=lambda: HP1_NT.copy())
    hp2_nT: np.ndarray = field(default_factory=lambda: HP2_NT.copy())
    seed: int = 0


def simulate_compass(scenario: CompassScenario | None = None, **overrides: object
                     ) -> tuple[pd.DataFrame, dict]:
    """Simulate the study's calibration flight.

    Parameters
    ----------
    scenario : CompassScenario, optional
        All parameters; the defaults when omitted.
    **overrides
        Fields of :class:`CompassScenario` to change (``amplitude_deg=20``, ``seed=3``...).

    Returns
    -------
    log : pandas.DataFrame
        Columns ``time`` [s], ``heading``, ``pitch``, ``roll`` [deg, heading true in
        [0, 360)], ``flux_x``, ``flux_y``, ``flux_z`` [nT], and truth columns
        ``truth_bx``, ``truth_by``, ``truth_bz`` (Earth field in body axes [nT]) and
        ``truth_regime`` (0 before the switch, 1 after).
    truth : dict
        ``matrix_before``/``matrix_after`` (the ideal ``D = C^-1``), ``offset_before_nT``/
        ``offset_after_nT`` (``e = -C^-1 h``), ``C1``, ``C2``, ``hp1_nT``, ``hp2_nT``,
        ``earth_ned_nT``, ``declination_deg``, and the scenario's parameters.
    """
    sc = scenario if scenario is not None else CompassScenario()
    if overrides:
        sc = CompassScenario(**{**sc.__dict__, **overrides})
    n = int(round(sc.duration_s * sc.rate_hz))
    t = np.arange(n) / sc.rate_hz
    amp = np.deg2rad(sc.amplitude_deg)
    ph = sc.phases_rad
    roll = amp * np.sin(sc.omega_rad_s * t + ph[0])
    pitch = amp * np.sin(sc.omega_rad_s * t + ph[1])
    yaw = np.deg2rad(sc.heading0_deg) + amp * np.sin(sc.omega_rad_s * t + ph[2])
    m = np.asarray(sc.earth_ned_nT, dtype=float)
    b = rotate_ned_to_body(m, roll, pitch, yaw)
    regime = np.zeros(n, dtype=int)
    if sc.switch_s is not None:
        regime[t >= sc.switch_s] = 1
    Cs = np.stack([sc.C1, sc.C2])
    hs = np.stack([sc.hp1_nT, sc.hp2_nT])
    rng = np.random.default_rng(sc.seed)
    flux = np.einsum("kij,kj->ki", Cs[regime], b) + hs[regime]
    flux += sc.noise_nT * rng.standard_normal((n, 3))
    log = pd.DataFrame({
        "time": t,
        "heading": wrap360_deg(np.rad2deg(yaw)),
        "pitch": np.rad2deg(pitch),
        "roll": np.rad2deg(roll),
        "flux_x": flux[:, 0], "flux_y": flux[:, 1], "flux_z": flux[:, 2],
        "truth_bx": b[:, 0], "truth_by": b[:, 1], "truth_bz": b[:, 2],
        "truth_regime": regime,
    })
    D = [np.linalg.inv(c) for c in Cs]
    truth = {
        "matrix_before": D[0].tolist(), "matrix_after": D[1].tolist(),
        "offset_before_nT": (-D[0] @ hs[0]).tolist(), "offset_after_nT": (-D[1] @ hs[1]).tolist(),
        "C1": np.asarray(sc.C1).tolist(), "C2": np.asarray(sc.C2).tolist(),
        "hp1_nT": np.asarray(sc.hp1_nT).tolist(), "hp2_nT": np.asarray(sc.hp2_nT).tolist(),
        "earth_ned_nT": m.tolist(),
        "declination_deg": float(np.rad2deg(np.arctan2(m[1], m[0]))),
        "amplitude_deg": sc.amplitude_deg, "duration_s": sc.duration_s, "rate_hz": sc.rate_hz,
        "omega_rad_s": sc.omega_rad_s, "phases_rad": list(sc.phases_rad),
        "heading0_deg": sc.heading0_deg, "noise_nT": sc.noise_nT, "switch_s": sc.switch_s,
        "seed": sc.seed,
    }
    return log, truth
