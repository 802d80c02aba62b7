"""Review of ``aeromag grid``: the transforms' signs, and the solve against a direct one.

An independent generator written here (not the project's simulator, not test_survey_grid's):
point dipoles under north-south lines 150 m apart, 7 m along-line steps, heading jitter.
"""

from __future__ import annotations

import numpy as np
import pytest

from aeromag.survey.grids import grid_dataset
from aeromag.survey.transforms import Transform, apply_transform

#: (east, north, depth below the sensor [m], moment [A m^2])
SOURCES = [(1800.0, 2500.0, 350.0, 3e8), (3300.0, 1400.0, 500.0, -2e8)]


def _unit(inc: float, dec: float) -> np.ndarray:
    i, d = np.radians(inc), np.radians(dec)
    return np.array([np.cos(i) * np.cos(d), np.cos(i) * np.sin(d), np.sin(i)])


def field(e: np.ndarray, n: np.ndarray, up: float = 0.0, inc: float = 90.0,
          dec: float = 0.0) -> np.ndarray:
    """Total-field anomaly [nT] of induced dipoles, ``up`` metres above the survey."""
    f = _unit(inc, dec)
    out = np.zeros(np.shape(e))
    for xe, yn, depth, m in SOURCES:
        r = np.stack([n - yn, e - xe, np.full(np.shape(e), -(depth + up))], -1)
        rn = np.linalg.norm(r, axis=-1)
        b = 1e-7 * m * (3 * (r @ f)[..., None] * r / rn[..., None] ** 2 - f) / rn[..., None] ** 3
        out += (b @ f) * 1e9
    return out


@pytest.fixture(scope="module")
def pole_grid():
    x = np.arange(0.0, 5000.0, 25.0)
    gx, gy = np.meshgrid(x, x)
    return grid_dataset(x, x, field(gx, gy), "t", 32633)


def test_tilt_is_positive_over_the_source_and_dz_positive_over_a_positive_anomaly(pole_grid):
    # before the review: harmonica's upward derivative made tilt -90 deg and dz -12 nT/m over
    # the 1395 nT peak of the shallow source (Oasis's 1VD and Miller & Singh's tilt: positive)
    peak = {"x": 1800.0, "y": 2500.0}
    assert pole_grid["t"].sel(peak).item() > 1000.0
    tilt = apply_transform(pole_grid["t"], Transform("tilt"))
    dz = apply_transform(pole_grid["t"], Transform("dz"))
    assert tilt.sel(peak).item() > 85.0
    assert dz.sel(peak).item() > 5.0 and dz.attrs["units"] == "nT/m"
    # the reversed (negative) source: negative tilt over it
    assert tilt.sel(x=3300.0, y=1400.0).item() < -60.0
    # dz against the analytic downward derivative of the dipoles
    gx, gy = np.meshgrid(pole_grid.x.values, pole_grid.y.values)
    true = (field(gx, gy, up=-1.0) - field(gx, gy, up=1.0)) / 2.0
    inner = (gx > 800) & (gx < 4200) & (gy > 800) & (gy < 4200)
    err = dz.values[inner] - true[inner]
    assert np.sqrt(np.mean(err ** 2)) < 0.05 * true[inner].std()


def test_dz_is_the_finite_difference_of_two_upward_continuations(pole_grid):
    up = {h: apply_transform(pole_grid["t"], Transform("up", h)) for h in (20.0, 30.0, 40.0)}
    fd = (up[20.0] - up[40.0]) / 20.0  # downward derivative at 30 m
    dz = apply_transform(up[30.0].rename("t"), Transform("dz"))
    inner = slice(40, -40)
    a, b = dz.values[inner, inner], fd.values[inner, inner]
    assert np.corrcoef(a.ravel(), b.ravel())[0, 1] > 0.999
    assert np.sqrt(np.mean((a - b) ** 2)) < 0.02 * b.std()
