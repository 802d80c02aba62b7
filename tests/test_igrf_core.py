"""The one IGRF evaluation (aeromag._core.igrf.igrf_ned) against ppigrf called directly.

Both users (the compass reference and the survey chain's IGRF column) go through it; the
lattice interpolation it uses for many samples must stay within 0.01 nT of the model.
"""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest

from aeromag.compass import igrf_field
from aeromag.errors import InputError
from aeromag.survey.igrf import igrf_total_intensity

ppigrf = pytest.importorskip("ppigrf", reason="IGRF needs ppigrf (a base dependency)")


def _exact(lat, lon, h, when):
    e, n, u = ppigrf.igrf(lon, lat, h / 1000.0, when)
    return np.column_stack([np.ravel(n), np.ravel(e), -np.ravel(u)])


def test_many_samples_on_the_lattice_match_the_model():
    rng = np.random.default_rng(3)
    n = 50_000  # more samples than lattice nodes: the interpolated path
    lat = -33.0 + rng.uniform(0, 0.4, n)
    lon = 151.0 + rng.uniform(0, 0.6, n)
    h = 200.0 + rng.uniform(0, 900, n)
    ref = igrf_field(lat, lon, h, "2021-03-04")
    i = rng.choice(n, 500, replace=False)
    err = np.abs(ref.ned_nT[i] - _exact(lat[i], lon[i], h[i], dt.datetime(2021, 3, 4)))
    assert err.max() < 0.01


def test_few_samples_are_exact_and_time_interpolates_between_midnights():
    lat, lon, h = np.array([40.1, 40.3]), np.array([-105.2, -104.9]), np.array([1700.0, 2100.0])
    t0 = (dt.datetime(2014, 11, 2) - dt.datetime(1970, 1, 1)).total_seconds()
    f = igrf_total_intensity(lat, lon, h, np.array([t0, t0 + 43200.0])).igrf_nT
    a = np.linalg.norm(_exact(lat, lon, h, dt.datetime(2014, 11, 2)), axis=1)
    b = np.linalg.norm(_exact(lat, lon, h, dt.datetime(2014, 11, 3)), axis=1)
    assert f[0] == pytest.approx(a[0], abs=1e-6)
    assert f[1] == pytest.approx(0.5 * (a[1] + b[1]), abs=1e-6)


def test_refusals():
    with pytest.raises(InputError, match="outside IGRF-14"):
        igrf_total_intensity(np.array([40.0]), np.array([-105.0]), np.array([0.0]),
                             np.array([-3e9]))
    with pytest.raises(InputError, match="no complete sample"):
        igrf_total_intensity(np.array([np.nan]), np.array([-105.0]), np.array([0.0]), 1.4e9)
