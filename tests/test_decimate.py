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

from aeromag._core.decimate import (
    BAND_FACTOR,
    anti_alias_taps,
    decimate_stretches,
    decimation_factor,
)


# --------------------------------------------------------------------------- the factor
@pytest.mark.parametrize(("fs", "band", "q"), [
    (10.0, (0.1, 0.9), 1),      # 10 Hz logs never change
    (100.0, (0.1, 0.9), 1),     # 100 / 72 Hz < 2
    (100.0, (0.1, 0.5), 2),     # 50 Hz >= 40 Hz
    (144.0, (0.1, 0.9), 2),     # exactly 2 x 72 Hz
    (200.0, (0.1, 0.9), 2),     # 100 Hz
    (1000.0, (0.1, 0.9), 13),   # 76.9 Hz
    (1000.0, (0.1, 0.5), 25),   # 40 Hz
    (1000.0, (0.01, 0.02), 500),  # the 2 Hz floor (80 x 0.02 Hz = 1.6 Hz)
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


def _gain(h: np.ndarray, f_hz: np.ndarray, fs_hz: float) -> np.ndarray:
    """|H(f)| of a symmetric FIR centred on its middle tap."""
    n = np.arange(len(h)) - (len(h) - 1) / 2
    return np.abs(np.exp(-2j * np.pi * np.outer(f_hz, n) / fs_hz) @ h)


@pytest.mark.parametrize(("fs", "q", "flat", "reject_db"), [
    (1000.0, 13, 1e-6, 110.0),   # the default 1 kHz case (the old Kaiser FIR: 1e-3, 72 dB)
    (200.0, 2, 1e-6, 80.0),
    (1000.0, 12, 1e-6, 95.0),    # an even factor (third boxcar of q + 1)
    (1000.0, 27, 2e-5, 90.0),
])
def test_anti_alias_filter_is_flat_in_band_and_rejects_what_folds_into_it(fs, q, flat,
                                                                           reject_db):
    h = anti_alias_taps(q)
    assert len(h) % 2 == 1 and np.allclose(h, h[::-1]) and abs(h.sum() - 1) < 1e-12
    assert len(h) <= 5 * q  # 5 multiply-adds per input sample
    band = np.linspace(0.0, 0.9, 91)
    assert np.max(np.abs(_gain(h, band, fs) - 1)) < flat
    folds = np.concatenate([k * fs / q + np.linspace(-0.9, 0.9, 37) for k in range(1, q)])
    assert 20 * np.log10(np.max(_gain(h, folds, fs))) < -reject_db


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


# --------------------------------------------------------------------------- the fit
SIM_COLUMNS = ["time", "line", "flux_x", "flux_y", "flux_z", "mag"]


#: (rate [Hz], band [Hz], decimation factor): 100 Hz is decimated only with a band whose
#: upper edge is at most 100 / 160 Hz (here 0.5 Hz: q = 2); 1 kHz with the default band.
HIGH_RATES = [(100.0, (0.1, 0.5), 2), (1000.0, (0.1, 0.9), 13)]


@pytest.fixture(scope="module", params=HIGH_RATES, ids=["100Hz", "1kHz"])
def high_rate_fits(request):
    """One simulated calibration at 100 Hz or 1 kHz, fitted decimated and at full rate."""
    from aeromag.compensation import CompensationConfig
    from aeromag.compensation import run_compensation as compensate
    from aeromag.synthetic import simulate_calibration

    rate, band, q = request.param
    df, truth = simulate_calibration(rate_hz=rate, n_boxes=2, seed=11)
    log = df[SIM_COLUMNS].copy()
    dec = compensate(log, CompensationConfig(band_hz=band))
    full = compensate(log, CompensationConfig(band_hz=band, decimate=False))
    return (rate, band, q), df, np.asarray(truth["coef"]), dec, full


def test_high_rate_fit_is_decimated_and_reported(high_rate_fits):
    (rate, band, q), _, _, dec, full = high_rate_fits
    assert decimation_factor(rate, band) == q
    assert dec.report.fit.decimation_factor == q
    assert full.report.fit.decimation_factor == 1
    assert dec.report.config.decimate is True
    assert full.report.config.decimate is False
    # The fit used the decimated samples; the model was applied to every original one.
    assert dec.report.fit.n_samples < full.report.fit.n_samples / (q * 0.9)
    assert len(dec.data) == len(full.data)
    assert np.isfinite(dec.data["mag_tl"]).all()


def test_high_rate_coefficients_unchanged_within_noise(high_rate_fits):
    _, _, truth, dec, full = high_rate_fits
    c_dec, c_full = np.asarray(dec.model.coef), np.asarray(full.model.coef)
    # The noise of the fit itself, over seeds 10-15 (coefficients of 1-45 nT or nT s): the
    # rms error against the truth is 0.012-0.108 at 100 Hz (band 0.1-0.5 Hz, q = 2) and
    # 0.010-0.027 at 1 kHz (q = 13), largest 0.34 and 0.08; decimated and full-rate fits
    # differ by rms 0.003-0.030 (largest 0.093).
    rms = float(np.sqrt(np.mean((c_dec - c_full) ** 2)))
    assert rms < 0.05 and np.abs(c_dec - c_full).max() < 0.2, (c_dec - c_full)
    assert np.abs(c_full - truth).max() < 0.5
    assert np.abs(c_dec - truth).max() < 0.5


def test_high_rate_residuals_unchanged_within_noise(high_rate_fits):
    _, df, _, dec, full = high_rate_fits
    truth_tl = df["truth_mag_tl"].to_numpy()
    err = {k: r.data["mag_tl"].to_numpy() - truth_tl for k, r in (("dec", dec), ("full", full))}
    # The interference on every original sample varies as the truth does: the error's std is
    # the differentiated fluxgate noise, the same for both (0.019 nT at 1 kHz, 0.002-0.003 nT at
    # 100 Hz) ...
    sd = {k: float(np.std(e)) for k, e in err.items()}
    assert sd["dec"] <= 1.05 * sd["full"] + 1e-3, sd
    # ... and its level (the permanent terms' error: 0.02-0.34 nT at 100 Hz, 0.007-0.08 nT at
    # 1 kHz over seeds 10-15, either way) is no further from the truth than that noise allows.
    lvl = {k: abs(float(np.mean(e))) for k, e in err.items()}
    assert lvl["dec"] <= lvl["full"] + 0.1 and max(lvl.values()) < 0.5, lvl
    rd = dec.report.metrics.residual_std_nT
    rf = full.report.metrics.residual_std_nT
    assert rd <= 1.1 * rf + 1e-4, (rd, rf)
    assert dec.report.metrics.improvement_ratio > 100


def test_ten_hertz_fit_is_never_decimated():
    from aeromag.compensation import CompensationConfig, prepare
    from aeromag.compensation.decimation import fit_arrays

    from .conftest import hand_flight

    df, _ = hand_flight(n=3000)
    prep = prepare(df, CompensationConfig())
    assert fit_arrays(prep, CompensationConfig(), ('cx', 'cy')) == (prep, 1, None)


def test_cli_no_decimate_flag(tmp_path):
    from typer.testing import CliRunner

    from aeromag.cli import app
    from aeromag.synthetic import simulate_calibration

    df, _ = simulate_calibration(rate_hz=200.0, n_boxes=1, seed=2)
    src = tmp_path / "cal.csv"
    df[SIM_COLUMNS].to_csv(src, index=False)
    runner = CliRunner()
    for extra, q in (([], 2), (["--no-decimate"], 1)):
        out = tmp_path / f"m{q}.json"
        res = runner.invoke(app, ["calibrate", str(src), "-o", str(out), *extra])
        assert res.exit_code == 0, res.output
        rep = __import__("json").loads(out.read_text())
        assert rep["fit"]["decimation_factor"] == q


def test_decimate_is_a_filter_option():
    from aeromag.compensation.config import CompensationConfig, FilterOptions

    assert CompensationConfig().filter.decimate is True
    assert CompensationConfig(decimate=False).filter.decimate is False
    cfg = CompensationConfig.from_groups(filter=FilterOptions(decimate=False))
    assert cfg.decimate is False


def _stepped_flight(step_deg: float, vib_deg: float, n: int = 300_000, fs: float = 1000.0,
                    seed: int = 3):
    """A 1 kHz flight on four headings (turns over 4 s) with a heading step of ``step_deg``
    within one sample every 12.5 s (inside segments and on their boundaries) and rotor
    vibration of ``vib_deg`` at 97 Hz (pitch, 0.7 of it in roll); a 16-term aircraft by the
    explicit formula of conftest (not aeromag's code), differentiated at the full rate."""
    import pandas as pd
    from scipy.ndimage import uniform_filter1d

    from .conftest import COEF16, ned_to_body

    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    turns = uniform_filter1d(np.repeat([0.0, 90.0, 180.0, 270.0], n // 4), size=4000,
                             mode="nearest")
    vib = np.deg2rad(vib_deg) * np.sin(2 * np.pi * 97.0 * t)
    psi = np.deg2rad(turns + step_deg * ((t // 12.5) % 2) + 5 * np.sin(2 * np.pi * t / 7.1))
    th = np.deg2rad(5 * np.sin(2 * np.pi * t / 5.3 + 1.0)) + vib
    ph = np.deg2rad(10 * np.sin(2 * np.pi * t / 3.1)) + 0.7 * vib
    inc = np.deg2rad(65.0)
    B = np.einsum("nij,j->ni", ned_to_body(ph, th, psi),
                  50000.0 * np.array([np.cos(inc), 0.05, np.sin(inc)]))
    bt = np.linalg.norm(B, axis=1)
    cx, cy, cz = (B / bt[:, None]).T
    dx, dy, dz = (np.gradient(c, t) for c in (cx, cy, cz))
    s = bt / 50000.0
    A = np.column_stack([cx, cy, cz, s * cx * cx, s * cx * cy, s * cx * cz, s * cy * cy,
                         s * cy * cz, s * cx * dx, s * cx * dy, s * cx * dz, s * cy * dx,
                         s * cy * dy, s * cy * dz, s * cz * dx, s * cz * dy])
    h = A @ COEF16
    flux = B + rng.normal(0, 0.5, (n, 3))
    df = pd.DataFrame({"time": t, "flux_x": flux[:, 0], "flux_y": flux[:, 1],
                       "flux_z": flux[:, 2], "mag": bt + h + rng.normal(0, 0.02, n),
                       "line": (t // 25).astype(int)})
    return df, h, COEF16


@pytest.mark.parametrize(("step_deg", "vib_deg"), [(90.0, 0.0), (2.0, 0.0), (0.0, 0.3)],
                         ids=["90deg-steps", "2deg-steps", "0.3deg-97Hz"])
def test_out_of_band_attitude_is_fitted_decimated_as_at_full_rate(step_deg, vib_deg, caplog):
    """Heading steps within one sample and rotor vibration far above the fitting rate put
    out-of-band energy into the fluxgate and (through the non-linear terms) into the scalar.
    The terms are built at the full rate and decimated like the scalar, so the decimated fit
    equals the full-rate one within its noise, drops no clean segment and warns of nothing.
    (Decimating the fluxgate before building the terms fell back to the full rate with a
    warning on the 90 deg steps, gave a coefficient rms error of 0.042 on the 2 deg steps and
    dropped a clean segment with the vibration.)"""
    from aeromag.compensation import CompensationConfig
    from aeromag.compensation import run_compensation as compensate

    df, h, truth = _stepped_flight(step_deg, vib_deg)
    with caplog.at_level("WARNING"):
        dec = compensate(df, CompensationConfig())
    assert not [r for r in caplog.records if r.levelname == "WARNING"]
    full = compensate(df, CompensationConfig(decimate=False))
    assert dec.report.fit.decimation_factor == 13
    assert dec.report.screening.dropped == []
    c_dec, c_full = np.asarray(dec.model.coef), np.asarray(full.model.coef)
    err_dec = float(np.sqrt(np.mean((c_dec - truth) ** 2)))
    err_full = float(np.sqrt(np.mean((c_full - truth) ** 2)))
    # measured (90 deg / 2 deg / 0.3 deg): 0.043 / 0.011 / 0.013 decimated, 0.039 / 0.0097 /
    # 0.0092 at the full rate
    assert err_full < 0.05 and err_dec < err_full + 0.01, (err_dec, err_full)
    assert float(np.sqrt(np.mean((c_dec - c_full) ** 2))) < 0.02
    d = dec.data["mag_tl"].to_numpy() - h
    assert np.std(d - d.mean()) < 0.03
    assert dec.report.metrics.improvement_ratio > 1000


def test_built_rows_decimate_as_the_whole_stretch():
    """Blocks with FIR overlap give the whole stretch's filtered samples (to rounding)."""
    from aeromag._core.decimate import decimate_built

    rng = np.random.default_rng(0)
    n = 60_001
    X = np.cumsum(rng.normal(size=(2, n)), axis=1)
    stretch = np.zeros(n, int)
    stretch[20_000:20_003] = -1
    stretch[20_003:] = 1
    stretch[-1] = 2
    calls = []

    def build(lo, hi, a, b):
        assert a <= lo < hi <= b and np.all(stretch[a:b] == stretch[a])
        calls.append(hi - lo)
        return X[:, lo:hi]

    for q in (1, 13, 55):
        calls.clear()
        d, idx = decimate_built(build, 2, stretch, q, block=5000)
        ref = [decimate_stretches([X[0], X[1]], stretch, q)]
        (r0, r1), ridx = ref[0]
        assert idx.tolist() == ridx.tolist()
        np.testing.assert_allclose(d, np.vstack([r0, r1]), rtol=0, atol=1e-9 * np.abs(X).max())
        assert max(calls) <= max(5000 // q * q, 4 * 11 * q) + 2 * 11 * q  # memory bounded
