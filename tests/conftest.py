"""Shared fixtures: a small hand-built flight independent of the simulator module."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest


def ned_to_body(phi: np.ndarray, theta: np.ndarray, psi: np.ndarray) -> np.ndarray:
    """NED->body direction cosine matrices (aerospace ZYX), shape (n, 3, 3)."""
    cph, sph = np.cos(phi), np.sin(phi)
    cth, sth = np.cos(theta), np.sin(theta)
    cps, sps = np.cos(psi), np.sin(psi)
    C = np.empty((len(phi), 3, 3))
    C[:, 0] = np.stack([cth * cps, cth * sps, -sth], axis=1)
    C[:, 1] = np.stack([sph * sth * cps - cph * sps, sph * sth * sps + cph * cps, sph * cth], 1)
    C[:, 2] = np.stack([cph * sth * cps + sph * sps, cph * sth * sps - sph * cps, cph * cth], 1)
    return C


COEF16 = np.array([30, -20, 15, 40, -10, 8, 25, -5, 2, -1, 0.5, 1.5, -2, 0.8, -0.6, 1.0])


def hand_flight(seed: int = 0, n: int = 12000, fs: float = 10.0, noise: float = 0.02,
                flux_noise: float = 0.5, coef: np.ndarray = COEF16,
                seg_s: float = 50.0) -> tuple[pd.DataFrame, np.ndarray]:
    """A flight on four headings with pitch/roll/yaw oscillations and a known 16-term model.

    The interference is computed with an explicit formula here (not with aeromag), from the
    true body-frame field, so it is an independent reference for the fitter.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    psi = np.deg2rad(np.repeat([0.0, 90.0, 180.0, 270.0], -(-n // 4))[:n]
                     + 5 * np.sin(2 * np.pi * t / 7.1))
    th = np.deg2rad(5 * np.sin(2 * np.pi * t / 5.3 + 1.0))
    ph = np.deg2rad(10 * np.sin(2 * np.pi * t / 3.1))
    inc = np.deg2rad(65.0)
    b_ned = 50000.0 * np.array([np.cos(inc), 0.05, np.sin(inc)])
    B = np.einsum("nij,j->ni", ned_to_body(ph, th, psi), b_ned)
    bt = np.linalg.norm(B, axis=1)
    cx, cy, cz = (B / bt[:, None]).T
    dx, dy, dz = (np.gradient(c, t) for c in (cx, cy, cz))
    s = bt / 50000.0
    cols = [cx, cy, cz, s * cx * cx, s * cx * cy, s * cx * cz, s * cy * cy, s * cy * cz,
            s * cx * dx, s * cx * dy, s * cx * dz, s * cy * dx, s * cy * dy, s * cy * dz,
            s * cz * dx, s * cz * dy]
    h = np.column_stack(cols) @ coef
    mag = bt + h + rng.normal(0, noise, n)
    flux = B + rng.normal(0, flux_noise, (n, 3))
    df = pd.DataFrame({"time": t, "flux_x": flux[:, 0], "flux_y": flux[:, 1],
                       "flux_z": flux[:, 2], "mag": mag, "line": (t // seg_s).astype(int),
                       "truth_mag_tl": h, "truth_clean": bt})
    return df, h


@pytest.fixture(scope="session")
def flight() -> tuple[pd.DataFrame, np.ndarray]:
    return hand_flight()


@pytest.fixture(scope="session")
def sample_model(tmp_path_factory):
    """The model of data_samples/calibration.csv, written by 'aeromag calibrate'."""
    from pathlib import Path

    from typer.testing import CliRunner

    from aeromag.cli import app

    m = tmp_path_factory.mktemp("sample_model") / "model.json"
    cal = Path(__file__).resolve().parents[1] / "data_samples" / "calibration.csv"
    r = CliRunner().invoke(app, ["calibrate", str(cal), "-o", str(m)])
    assert r.exit_code == 0, r.output
    return m
