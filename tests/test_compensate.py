"""The compensation pipeline on a hand-built flight with a known 16-term aircraft."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from aeromag.compensation.apply import apply_model
from aeromag.compensation.config import CompensationConfig
from aeromag.compensation.fit import fit_model
from aeromag.compensation.model import TLModel
from aeromag.compensation.terms import TERMS_16
from aeromag.errors import FitError, InputError
from aeromag.workflows.compensate import calibrate_file, compensate, compensate_file

from .conftest import COEF16, hand_flight


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_clean_flight_recovers_coefficients_and_keeps_every_segment(seed):
    df, h = hand_flight(seed=seed)
    res = compensate(df)
    coef = np.asarray(res.report.coef)
    # The strongly constrained terms to a fraction of a nT, all terms within 1 nT.
    assert np.max(np.abs(coef - COEF16)) < 1.0
    assert res.report.screening.enabled and res.report.screening.dropped == []
    assert res.report.metrics.improvement_ratio > 100
    # mag_tl matches the true interference up to a constant level.
    d = res.data["mag_tl"].to_numpy() - h
    assert np.std(d - d.mean()) < 0.05


def test_output_columns_and_report_keys_follow_the_interface(flight):
    df, _ = flight
    res = compensate(df)
    out = res.data
    assert list(out.columns[: len(df.columns)]) == list(df.columns)
    for c in ("mag_tl", "mag_comp", "segment", "segment_kept"):
        assert c in out.columns
    assert len(out) == len(df)
    assert out["segment_kept"].dtype == bool
    r = res.report.to_dict()  # the JSON contract (interface.md keys)
    assert r["terms"] == list(TERMS_16) and len(r["coef"]) == 16
    for s in r["segments"]:
        assert {"id", "n", "kept", "scores", "residual_std", "condition_number"} <= set(s)
        assert len(s["coef"]) == 16 and len(s["scores"]) >= 2
    assert {"improvement_ratio", "residual_std_nT"} <= set(r["metrics"])
    assert {"explained_variance_ratio", "rule", "cutoff", "n_components"} <= set(r["screening"])


def test_mag_comp_filter_keeps_level_and_no_filter_leaves_it_raw(flight):
    df, _ = flight
    a = compensate(df).data
    b = compensate(df, CompensationConfig(filter_output=False)).data
    raw = (df["mag"] - b["mag_tl"]).to_numpy()
    np.testing.assert_allclose(b["mag_comp"], raw)
    assert abs(a["mag_comp"].mean() - b["mag_comp"].mean()) < 1e-3
    assert a["mag_comp"].std() < b["mag_comp"].std()


def test_mag_tl_is_a_property_of_the_aircraft_not_of_the_call(flight):
    """Compensating lines one file at a time gives the whole flight's mag_tl."""
    df, _ = flight
    model = fit_model(df).model
    whole, _ = apply_model(df, model)
    parts = [apply_model(g.reset_index(drop=True), model)[0] for _, g in df.groupby("line")]
    joined = pd.concat(parts, ignore_index=True)
    d = np.abs(joined["mag_tl"].to_numpy() - whole["mag_tl"].to_numpy())
    # Identical except at the two end samples of each file (one-sided derivative there).
    ends = np.zeros(len(df), bool)
    starts = np.flatnonzero(np.r_[True, np.diff(df["line"].to_numpy()) != 0])
    ends[starts] = True
    ends[np.r_[starts[1:] - 1, len(df) - 1]] = True
    assert d[~ends].max() < 1e-9
    # (this hand-built flight turns 90 degrees instantly at some line ends, where a central
    # difference across the turn differs from a one-sided one: compare typical ends only)
    assert np.median(d[ends]) < 0.05


def test_time_gaps_split_stretches_and_gaps_do_not_break_the_fit():
    df, _ = hand_flight(seed=3)
    cut = df.drop(index=range(3000, 3400)).reset_index(drop=True)  # a turn cut out: 40 s gap
    cut.loc[5000:5003, "mag"] = np.nan  # a short NaN gap, interpolated
    res = compensate(cut)
    assert res.report.metrics.improvement_ratio > 50
    # Interpolated for the filters, but a row without mag has no mag_comp (review 15, 2).
    assert np.flatnonzero(~np.isfinite(res.data["mag_comp"])).tolist() == [5000, 5001, 5002,
                                                                           5003]
    assert res.report.metrics.n_rows_without_mag == 4


def test_without_mag_column_the_fluxgate_magnitude_is_the_total_field(flight):
    df, _ = flight
    res = compensate(df.drop(columns=["mag"]), CompensationConfig(mag_from_fluxgate=True))
    assert res.report.mag_from_fluxgate is True
    assert "mag" not in res.data.columns and np.isfinite(res.data["mag_comp"]).all()


def test_windows_when_there_is_no_line_column(flight):
    df, _ = flight
    res = compensate(df.drop(columns=["line"]), CompensationConfig(segment_seconds=100))
    assert len(res.report.segments) == 12


def test_too_few_segments_fitted_without_screening(flight):
    df, _ = flight
    one = df.assign(line=0)
    res = compensate(one)
    assert res.report.screening.enabled is False
    assert "without screening" in " ".join(res.report.screening.notes)


def test_short_segments_reported_not_silently_dropped(flight):
    df, _ = flight
    d = df.copy()
    d.loc[100:120, "line"] = 99  # 2 s: far too short
    res = compensate(d)
    s99 = res.report.segment(99)
    assert s99.kept is False and s99.reason.startswith("too short to fit: ")


def test_constant_fluxgate_is_a_fit_error(flight):
    df, _ = flight
    bad = df.assign(flux_x=1.0, flux_y=2.0, flux_z=3.0)
    with pytest.raises(FitError, match="constant"):
        compensate(bad, source="x.csv")


def test_missing_flux_column_is_an_input_error(flight):
    df, _ = flight
    with pytest.raises(InputError, match="flux_z"):
        compensate(df.drop(columns=["flux_z"]), source="x.csv")


def test_calibrate_then_apply_files(tmp_path, flight):
    df, h = flight
    df.to_csv(tmp_path / "cal.csv", index=False)
    calibrate_file(tmp_path / "cal.csv", tmp_path / "model.json")
    m = json.loads((tmp_path / "model.json").read_text())
    assert m["terms"] == list(TERMS_16) and "segments" in m and "metrics" in m
    survey, h2 = hand_flight(seed=9, n=6000)
    survey.to_csv(tmp_path / "survey.csv", index=False)
    res = compensate_file(tmp_path / "survey.csv", tmp_path / "out.csv",
                          model=tmp_path / "model.json")
    out = pd.read_csv(tmp_path / "out.csv")
    assert (tmp_path / "out.json").exists()
    assert set(out["segment_kept"].astype(str)) == {"True"}  # written true/false
    assert res.report.metrics.improvement_ratio > 50
    err = out["mag_tl"].to_numpy() - h2
    assert np.std(err - err.mean()) < 0.05


def test_model_with_other_terms_round_trips(tmp_path, flight):
    df, _ = flight
    res = compensate(df, CompensationConfig(terms="9"))
    assert len(res.report.coef) == 9
    m = TLModel.from_dict(res.report.to_dict())
    assert m.terms == tuple(res.report.terms)


def test_implausible_units_warn_but_never_convert(flight, caplog):
    df, _ = flight
    ut = df.assign(flux_x=df.flux_x / 1000, flux_y=df.flux_y / 1000, flux_z=df.flux_z / 1000)
    with caplog.at_level("WARNING"):
        res = compensate(ut)
    assert "units={'flux': 'uT'}" in caplog.text  # the parameter (the CLI: --units flux=uT)
    assert np.isfinite(res.data["mag_comp"]).all()


def test_high_rate_quiet_sensor_loses_no_clean_segment():
    """1 kHz: in-band residuals of 0.001 nT differ by large ratios that no survey can see."""
    df, h = hand_flight(seed=3, n=300_000, fs=1000.0, seg_s=25)
    res = compensate(df)
    assert res.report.screening.dropped == []
    assert res.report.metrics.improvement_ratio > 1000
    d = res.data["mag_tl"].to_numpy() - h
    assert np.std(d - d.mean()) < 0.02


def _level_flight(headings: list[float], jitter_deg: float, seed: int = 0, n: int = 8000,
                  fs: float = 10.0) -> pd.DataFrame:
    """Survey-style flight: straight lines on ``headings`` with band-limited attitude jitter,
    no manoeuvres, a 16-term aircraft (explicit formula, as in conftest)."""
    from scipy import signal

    from .conftest import ned_to_body

    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    sos = signal.butter(2, 0.5, fs=fs, output="sos")

    def jit() -> np.ndarray:
        x = signal.sosfiltfilt(sos, rng.normal(size=n))
        return np.deg2rad(jitter_deg * x / x.std())

    psi = np.deg2rad(np.repeat(headings, -(-n // len(headings)))[:n]) + jit()
    th, ph = jit() + np.deg2rad(-3.0), jit()
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
    geology = 3.0 * np.sin(2 * np.pi * t / 40.0)
    mag = bt + A @ COEF16 + geology + rng.normal(0, 0.02, n)
    flux = B + rng.normal(0, 0.5, (n, 3))
    return pd.DataFrame({"time": t, "flux_x": flux[:, 0], "flux_y": flux[:, 1],
                         "flux_z": flux[:, 2], "mag": mag, "line": (t // 50).astype(int)})


def test_straight_and_level_flight_is_an_ill_conditioned_fit():
    """No manoeuvres: the terms cannot be separated (interface.md: an ill-conditioned fit is a
    bad input), and the message says what to do."""
    df = _level_flight([90.0], jitter_deg=0.2)
    with pytest.raises(FitError, match="ill-conditioned.*ridge=1e-3"):
        compensate(df)
    # A ridge is the user's explicit way through, and gives a physical interference.
    res = compensate(df, CompensationConfig(ridge=1e-3))
    assert np.percentile(np.abs(res.data["mag_tl"]), 99) < 2000


@pytest.mark.parametrize("seed", [0, 1])
def test_fit_that_is_undetermined_at_low_frequency_is_refused(seed):
    """Two headings with turbulence and in-band geology can be well conditioned in the band,
    yet cz against a constant, cx*cx and cy*cy is free at low frequency: the unfiltered model
    then returns tens of thousands of nT.  That is refused, never written."""
    from scipy import signal

    df = _level_flight([0.0, 180.0], jitter_deg=0.5, seed=seed)
    g = signal.sosfiltfilt(signal.butter(2, 0.5, fs=10.0, output="sos"),
                           np.random.default_rng(100 + seed).normal(size=len(df)))
    df["mag"] += 40.0 * g / g.std()
    cfg = CompensationConfig(max_condition=1e9)  # past the conditioning check
    with pytest.raises(FitError, match="no aircraft makes.*model=MODEL"):
        compensate(df, cfg)
    # The same flight with its aircraft calibrated elsewhere: the model applies (a warning at
    # most, never an error, for a saved model).
    cal, _ = hand_flight(seed=seed)
    out = compensate(df, model=compensate(cal).model)
    assert np.percentile(np.abs(out.data["mag_tl"]), 99) < 500


def test_saved_model_marks_every_sample_kept_even_without_a_line(flight, tmp_path):
    """interface.md: segment_kept is all true when a saved model is applied."""
    df, _ = flight
    model = compensate(df).model
    d2 = df.copy()
    d2["line"] = d2["line"].astype(float)
    d2.loc[100:400, "line"] = np.nan
    d2.loc[500:700, "line"] = -1
    out = compensate(d2, model=model).data
    assert out["segment_kept"].all()
    assert out["segment"].isna().sum() == 301 + 201


def test_output_never_overwrites_the_input(tmp_path, flight):
    df, _ = flight
    src = tmp_path / "log.csv"
    df.to_csv(src, index=False)
    before = src.read_bytes()
    with pytest.raises(InputError, match="overwrite the input"):
        compensate_file(src, tmp_path / "." / "log.csv")
    with pytest.raises(InputError, match="overwrite the input"):
        calibrate_file(src, src)
    assert src.read_bytes() == before


@pytest.mark.parametrize("kw", [{"segment_seconds": float("nan")}, {"segment_seconds": -5},
                                {"band_hz": (0.5, 0.1)}, {"lowpass_hz": 0.0},
                                {"max_gap_s": float("inf")}, {"ridge": -1.0}])
def test_option_values_are_checked(kw):
    """The library names the parameter (the command line maps it to its flag)."""
    from aeromag.compensation.config import ConfigError

    with pytest.raises(ConfigError, match=f"^{next(iter(kw))}=") as err:
        CompensationConfig(**kw)
    assert isinstance(err.value, InputError) and err.value.parameter == next(iter(kw))


def test_output_named_like_its_report_is_refused(tmp_path, flight):
    df, _ = flight
    src = tmp_path / "log.csv"
    df.to_csv(src, index=False)
    with pytest.raises(InputError, match="must not end in .json"):
        compensate_file(src, tmp_path / "out.json")
    assert not (tmp_path / "out.json").exists()


@pytest.mark.parametrize("seed", range(5))
def test_masked_std_equals_numpy_on_any_mask(seed):
    from aeromag._core.moments import masked_std

    rng = np.random.default_rng(seed)
    for _ in range(60):
        n = int(rng.integers(1, 400))
        x = rng.normal(rng.choice([0.0, 5e4]), rng.uniform(0.001, 10), n)
        if rng.random() < 0.5:
            m = rng.random(n) < rng.uniform(0, 1)
        else:
            m = np.zeros(n, bool)
            a, b = sorted(rng.integers(0, n + 1, 2))
            m[a:b] = True
        got = masked_std(x, m)
        if not m.any():
            assert np.isnan(got)
        else:
            assert got == pytest.approx(np.std(x[m]), rel=1e-9, abs=1e-12)
