"""Survey-style flight whose aircraft interference changes mid-flight (for online TL).

Straight lines on alternating headings (north, south, east, west, joined by 20-s turns),
gusty attitude (band-limited roll, pitch and yaw), a smooth geological anomaly, the scalar
magnetometer reading ``|B| + anomaly + TL interference + noise`` and a fluxgate reading the
body-frame field.  At ``jump_s`` the 16 Tolles-Lawson coefficients change from ``coef_before``
to ``coef_after`` (a payload switched on: the permanent and induced terms move by tens of nT,
the eddy terms by a few nT*s); ``jump_s=None`` keeps them fixed.

This module is an oracle: the interference comes from :mod:`aeromag.synthetic.physics`,
never from the fitting code.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .._core.angles import wrap360_deg
from .physics import EarthField, band_noise, body_field, default_aircraft_coef, tl_interference

__all__ = ["OnlineTLScenario", "coef_after_jump", "simulate_online_tl"]


def coef_after_jump() -> np.ndarray:
    """The 16 coefficients after the payload switch [nT; eddy nT*s].

    Returns
    -------
    ndarray, shape (16,)
        :func:`default_aircraft_coef` with the permanent terms moved by (+60, +35, -50) nT,
        the induced by (-40, +25, -20, +30, +15) nT and the eddy terms by +-2 nT*s.
    """
    c = default_aircraft_coef().copy()
    c[:3] += [60.0, 35.0, -50.0]
    c[3:8] += [-40.0, 25.0, -20.0, 30.0, 15.0]
    c[8:] += [2.0, -1.5, 1.0, -2.0, 1.5, 2.0, -1.0, 1.5]
    return c


@dataclass
class OnlineTLScenario:
    """Parameters of :func:`simulate_online_tl` (units in the names).

    Attributes
    ----------
    duration_s, rate_hz : float
        Length [s] and sample rate [Hz].
    line_s : float
        Length of each straight line [s] (turn included).
    turn_s : float
        Length of the turn at the end of each line [s].
    jump_s : float or None
        Time of the coefficient change [s]; None for none.
    roll_rms_deg, pitch_rms_deg, yaw_rms_deg : float
        Gust attitude (0.05-0.8 Hz) [deg].
    noise_nT : float
        Scalar magnetometer noise [nT].
    flux_noise_nT : float
        Fluxgate noise per axis [nT].
    anomaly_nT : float
        Standard deviation of the geological anomaly (below 0.05 Hz) [nT].
    earth : EarthField
        Main field.
    coef_before, coef_after : ndarray, shape (16,)
        TL coefficients before and after the jump.
    seed : int
    oversample : int
        The flight is simulated at ``oversample`` times ``rate_hz`` and the log keeps every
        ``oversample``-th sample, so the eddy interference comes from the attitude's true
        rate of change (to a fraction of a per cent), not from a difference of the logged
        samples (which would favour a fit that uses that same difference).
    """

    duration_s: float = 1200.0
    rate_hz: float = 10.0
    line_s: float = 120.0
    turn_s: float = 20.0
    jump_s: float | None = 600.0
    roll_rms_deg: float = 4.0
    pitch_rms_deg: float = 2.5
    yaw_rms_deg: float = 2.5
    noise_nT: float = 0.05
    flux_noise_nT: float = 0.5
    anomaly_nT: float = 5.0
    earth: EarthField = field(default_factory=EarthField)
    coef_before: np.ndarray = field(default_factory=default_aircraft_coef)
    coef_after: np.ndarray = field(default_factory=coef_after_jump)
    seed: int = 0
    oversample: int = 10


def simulate_online_tl(scenario: OnlineTLScenario | None = None, **overrides: object
                       ) -> tuple[pd.DataFrame, dict]:
    """Simulate a survey flight whose interference coefficients may jump.

    Parameters
    ----------
    scenario : OnlineTLScenario, optional
        All parameters (defaults when omitted).
    **overrides
        Fields of :class:`OnlineTLScenario` to change.

    Returns
    -------
    log : pandas.DataFrame
        ``time`` [s], ``heading``, ``pitch``, ``roll`` [deg], ``flux_x/y/z`` [nT], ``mag``
        [nT], ``line``, and truth columns ``truth_mag_tl`` [nT], ``truth_anomaly`` [nT],
        ``truth_regime`` (0 before the jump, 1 after).
    truth : dict
        ``coef_before``, ``coef_after``, ``jump_s``, ``earth`` and the scenario.
    """
    sc = scenario if scenario is not None else OnlineTLScenario()
    if overrides:
        sc = OnlineTLScenario(**{**sc.__dict__, **overrides})
    rng = np.random.default_rng(sc.seed)
    os_ = max(1, int(sc.oversample))
    n_out = int(round(sc.duration_s * sc.rate_hz))
    n = n_out * os_
    t = np.arange(n) / (sc.rate_hz * os_)
    # Line headings cycle N, S, E, W; 20-s smooth turns between lines.
    seq = np.array([0.0, 180.0, 90.0, 270.0])
    k = np.floor(t / sc.line_s).astype(int)
    base = seq[k % 4]
    nxt = seq[(k + 1) % 4]
    into = t - k * sc.line_s
    turn = sc.turn_s
    frac = np.clip((into - (sc.line_s - turn)) / turn, 0.0, 1.0)
    frac = 0.5 - 0.5 * np.cos(np.pi * frac)
    dpsi = ((nxt - base + 180.0) % 360.0) - 180.0
    heading = base + frac * dpsi
    fs = sc.rate_hz * os_
    roll = band_noise(rng, n, fs, 0.05, 0.8, sc.roll_rms_deg) + 25.0 * np.sin(np.pi * frac)
    pitch = band_noise(rng, n, fs, 0.05, 0.8, sc.pitch_rms_deg)
    heading = heading + band_noise(rng, n, fs, 0.05, 0.8, sc.yaw_rms_deg)
    b_ned = sc.earth.ned
    b = body_field(b_ned, heading, pitch, roll)
    regime = np.zeros(n, dtype=int)
    if sc.jump_s is not None:
        regime[t >= sc.jump_s] = 1
    h = np.where(regime == 0, tl_interference(b, t, sc.coef_before),
                 tl_interference(b, t, sc.coef_after))
    anomaly = band_noise(rng, n, fs, 0.0005, 0.05, sc.anomaly_nT)
    keep = slice(None, None, os_)  # the logged samples
    t, heading, pitch, roll, b, h, anomaly, regime, k = (
        x[keep] for x in (t, heading, pitch, roll, b, h, anomaly, regime, k))
    n = n_out
    mag = np.linalg.norm(b_ned) + anomaly + h + sc.noise_nT * rng.standard_normal(n)
    flux = b + sc.flux_noise_nT * rng.standard_normal((n, 3))
    log = pd.DataFrame({
        "time": t, "heading": wrap360_deg(heading), "pitch": pitch, "roll": roll,
        "flux_x": flux[:, 0], "flux_y": flux[:, 1], "flux_z": flux[:, 2], "mag": mag,
        "line": k, "truth_mag_tl": h, "truth_anomaly": anomaly, "truth_regime": regime,
    })
    truth = {"coef_before": np.asarray(sc.coef_before, dtype=float).tolist(),
             "coef_after": np.asarray(sc.coef_after, dtype=float).tolist(),
             "jump_s": sc.jump_s, "earth": sc.earth.to_dict(), "rate_hz": sc.rate_hz,
             "duration_s": sc.duration_s, "noise_nT": sc.noise_nT,
             "flux_noise_nT": sc.flux_noise_nT, "seed": sc.seed,
             "oversample": os_}
    return log, truth
