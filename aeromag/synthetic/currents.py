"""Interference from aircraft current loops, with the currents logged (truth for ``--extra``).

A wire loop carrying a current ``I(t)`` makes a field ``I(t) * v`` at the sensor, ``v`` a fixed
body-frame vector [nT/A]; a scalar magnetometer measures its projection on the total field's
direction, ``I(t) * (v . b)`` with ``b`` the unit field vector in the body frame.  Each loop's
current switches between load levels, wanders (band-limited noise) and drifts slowly; the log
gets the currents (``cur_1``...) and a bus voltage that sags with the total load
(``volt_bus``), each with its own measurement noise, and ``mag`` gets the sum of the loops.
Written independently of the compensation code (it imports no fitting or filtering code).
"""

import logging
from typing import Any

import numpy as np
import pandas as pd

from ..errors import InputError
from .physics import band_noise

log = logging.getLogger(__name__)

__all__ = ["add_current_interference", "current_channels"]


def current_channels(n_loops: int) -> list[str]:
    """The logged current columns of :func:`add_current_interference` (``cur_1``, ...).

    Parameters
    ----------
    n_loops : int
        Number of loops.

    Returns
    -------
    list of str
    """
    return [f"cur_{i + 1}" for i in range(int(n_loops))]


def add_current_interference(
    df: pd.DataFrame, truth: dict[str, Any] | None = None, *, seed: int = 0, n_loops: int = 3,
    field_nT_per_A: Any | None = None, base_A: float = 10.0, step_A: float = 3.0,
    wander_A: float = 0.5, drift_A: float = 2.0, drift_period_s: float = 900.0,
    current_noise_A: float = 0.002, voltage: bool = True,
) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Add current-loop interference to a simulated log and log the currents.

    Parameters
    ----------
    df : DataFrame
        A simulated log (``time`` [s], ``flux_x/y/z`` [nT], ``mag`` [nT]), e.g. from
        :func:`aeromag.synthetic.simulate_calibration`.
    truth : dict, optional
        Its ground truth; a copy is returned with ``current_loops``.
    seed : int
        Random seed of the currents and the field vectors.
    n_loops : int
        Number of current loops.
    field_nT_per_A : array_like, shape (n_loops, 3), optional
        Body-frame field of each loop per ampere at the sensor [nT/A]; default random vectors
        of 0.01-0.03 nT/A, mostly along body z (wiring below the sensor).
    base_A, step_A : float
        Mean current and the size of its load switches (every 5-30 s) [A].
    wander_A : float
        Band-limited (0.05-1.5 Hz) current noise [A rms].
    drift_A, drift_period_s : float
        Amplitude [A] and period [s] of each current's slow drift.
    current_noise_A : float
        White noise of the logged currents [A rms].
    voltage : bool
        Also log ``volt_bus`` [V]: 28 V sagging 0.05 V/A with the total current, 0.01 V noise.

    Returns
    -------
    log : DataFrame
        A copy of ``df`` with ``mag`` changed, the current columns, ``volt_bus`` and
        ``truth_mag_current`` (the interference added, nT).
    truth : dict
        ``truth`` with ``current_loops``: ``[{"column", "field_nT_per_A"}]``.
    """
    if int(n_loops) < 1:
        raise InputError(f"n_loops: must be at least 1, got {n_loops!r}")
    for col in ("time", "flux_x", "flux_y", "flux_z", "mag"):
        if col not in df.columns:
            raise InputError(f"add_current_interference: the log has no column {col}")
    rng = np.random.default_rng([int(seed), 29])
    t = df["time"].to_numpy(dtype=np.float64)
    n = len(t)
    dt = float(np.median(np.diff(t))) if n > 1 else 0.1
    rate = 1.0 / dt
    if field_nT_per_A is None:
        v = rng.normal(size=(int(n_loops), 3)) * np.array([0.02, 0.02, 1.0])
        v[:, 2] = np.abs(v[:, 2]) + 0.5
        v *= rng.uniform(0.01, 0.03, size=(int(n_loops), 1)) / np.linalg.norm(v, axis=1)[:, None]
    else:
        v = np.asarray(field_nT_per_A, dtype=np.float64).reshape(int(n_loops), 3)
    flux = df[["flux_x", "flux_y", "flux_z"]].to_numpy(dtype=np.float64)
    b = flux / np.linalg.norm(flux, axis=1)[:, None]
    out = df.copy()
    total = np.zeros(n)
    mag_i = np.zeros(n)
    loops = []
    for i, col in enumerate(current_channels(n_loops)):
        # Load switches: a level held 5-30 s, then a new one.
        level = np.empty(n)
        a = 0
        while a < n:
            hold = int(rng.uniform(5.0, 30.0) * rate)
            level[a:a + hold] = base_A + step_A * rng.integers(-1, 2)
            a += max(hold, 1)
        phase = rng.uniform(0, 2 * np.pi)
        cur = (level + band_noise(rng, n, rate, 0.05, 1.5, wander_A)
               + drift_A * np.sin(2 * np.pi * t / drift_period_s + phase))
        total += cur
        mag_i += cur * (b @ v[i])
        out[col] = cur + rng.normal(0.0, current_noise_A, n)
        loops.append({"column": col, "field_nT_per_A": v[i].tolist()})
    if voltage:
        out["volt_bus"] = 28.0 - 0.05 * total + rng.normal(0.0, 0.01, n)
    out["mag"] = df["mag"].to_numpy(dtype=np.float64) + mag_i
    out["truth_mag_current"] = mag_i
    tr = dict(truth or {})
    tr["current_loops"] = loops
    log.info("current interference: %d loops, %.3g nT rms", n_loops, float(np.std(mag_i)))
    return out, tr
