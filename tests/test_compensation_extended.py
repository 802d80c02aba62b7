"""Compensation beyond the 16 terms (issue 29): ``--extra``, ``--reference``, ``--estimator``.

Physics against the project's simulator (:func:`aeromag.synthetic.add_current_interference`)
and against an independent generator written here (continuous figure-eight manoeuvres at 20 Hz,
another field, PWM-like currents, a quadratic current term, its own TL terms from the
contract's definitions); bad inputs through the library and the command line.
"""

from __future__ import annotations

import json
import logging
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import butter, sosfiltfilt
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.compensation.config import CompensationConfig
from aeromag.compensation.model import TLModel
from aeromag.compensation.pipeline import calibrate
from aeromag.compensation.pipeline import run_compensation as compensate
from aeromag.errors import ConfigError, InputError
from aeromag.synthetic import add_current_interference, simulate_calibration

EXTRAS = ("cur_1", "cur_2", "cur_3", "volt_bus")


def _band_floor(noise: np.ndarray, time: np.ndarray, line: np.ndarray, fs: float,
                band=(0.1, 0.9), trim_s: float = 2.5) -> float:
    """Std of the band-passed sensor noise over the pieces the fit uses (its noise floor)."""
    sos = butter(4, band, btype="bandpass", fs=fs, output="sos")
    gaps = np.r_[0, np.cumsum(np.diff(time) > 1.5 / fs)]
    parts = []
    m = int(trim_s * fs)
    for key in np.unique(np.c_[gaps, line], axis=0):
        sel = (gaps == key[0]) & (line == key[1])
        if sel.sum() > 3 * m + 30:
            parts.append(sosfiltfilt(sos, noise[sel])[m:-m])
    return float(np.std(np.concatenate(parts)))


@pytest.fixture(scope="module")
def sim():
    df0, truth = simulate_calibration(seed=1, n_boxes=2)
    cur, truth_c = add_current_interference(df0, truth, seed=2)
    logged, _ = add_current_interference(df0, truth, seed=2, field_nT_per_A=np.zeros((3, 3)))
    noise = (cur["mag"] - cur["truth_mag_clean"] - cur["truth_mag_tl"]
             - cur["truth_mag_current"]).to_numpy()
    floor = _band_floor(noise, cur["time"].to_numpy(), cur["line"].to_numpy(), 10.0)
    return cur, logged, truth_c, floor


def _held(res):
    return res.report.extended.held_out


def test_simulator_extras_reach_the_noise_floor(sim):
    cur, _, _, floor = sim
    res = calibrate(cur, CompensationConfig(extras=EXTRAS, fom=False), source="sim")
    h = _held(res)
    assert h.tl_only_residual_std_nT > 1.5 * floor  # the 16 terms cannot
    assert h.residual_std_nT <= 1.10 * floor, (h.residual_std_nT, floor)
    names = [c["name"] for c in h.contributions]
    assert names == list(EXTRAS)
    # The model file records the extras and what the reference was (none).
    d = res.model.to_dict()
    assert [e["name"] for e in d["extended"]["extras"]] == list(EXTRAS)
    assert d["extended"]["reference"] is None
    assert d["terms"] == res.report.terms and len(d["coef"]) == 16


def test_simulator_extras_do_not_hurt_without_currents(sim):
    _, logged, _, _ = sim
    h = _held(calibrate(logged, CompensationConfig(extras=EXTRAS, fom=False), source="sim"))
    assert h.residual_std_nT <= 1.02 * h.tl_only_residual_std_nT


def test_simulator_reference_recovers_truth_and_level(sim):
    cur, _, truth, _ = sim
    df = cur.assign(ref=cur["truth_mag_clean"])
    res = calibrate(df, CompensationConfig(reference="ref", extras=EXTRAS[:3], fom=False),
                    source="sim")
    true = np.asarray(truth["coef"])
    err = res.model.coef - true
    assert np.abs(err).max() < 0.01 * np.abs(true).max()
    assert np.sqrt(np.mean(err ** 2)) < 0.005 * np.sqrt(np.mean(true ** 2))
    assert res.model.extended.reference == "ref"
    out = compensate(df, CompensationConfig(filter_output=False), model=res.model)
    level = out.data["mag_comp"].mean() - df["ref"].mean()
    assert abs(level) < 0.01  # nT
    # the model file names the reference and round-trips
    back = TLModel.from_dict(json.loads(json.dumps(res.model.to_dict())))
    assert back.extended.reference == "ref"
    np.testing.assert_allclose(back.extended.extra_coef, res.model.extended.extra_coef)


# --------------------------------------------------------------------------- independent generator
def _independent_flight(seed: int, currents: bool = True, quadratic: float = 0.0):
    """A 20 Hz flight of continuous figure-eights (not boxes), its own TL, PWM currents."""
    rng = np.random.default_rng(seed)
    fs = 20.0
    t = np.arange(0, 1800.0, 1 / fs)
    n = len(t)
    # Attitude: heading sweeping all directions, pitch and roll as slow sums of sines.
    hdg = np.deg2rad(360 * t / 300.0 + 40 * np.sin(2 * np.pi * t / 37))
    pit = np.deg2rad(6 * np.sin(2 * np.pi * t / 9.3) + 2 * np.sin(2 * np.pi * t / 3.1))
    rol = np.deg2rad(12 * np.sin(2 * np.pi * t / 7.7 + 1) + 3 * np.sin(2 * np.pi * t / 2.3))
    inc, dec, F = np.deg2rad(-38.0), np.deg2rad(12.0), 31000.0  # a southern-hemisphere field
    b_ned = F * np.array([np.cos(inc) * np.cos(dec), np.cos(inc) * np.sin(dec), np.sin(inc)])
    ch, sh, cp, sp, cr, sr = (np.cos(hdg), np.sin(hdg), np.cos(pit), np.sin(pit), np.cos(rol),
                              np.sin(rol))
    # NED -> body (Z-Y-X), rows of the matrix applied to b_ned
    bx = cp * ch * b_ned[0] + cp * sh * b_ned[1] - sp * b_ned[2]
    by = ((sr * sp * ch - cr * sh) * b_ned[0] + (sr * sp * sh + cr * ch) * b_ned[1]
          + sr * cp * b_ned[2])
    bz = ((cr * sp * ch + sr * sh) * b_ned[0] + (cr * sp * sh - sr * ch) * b_ned[1]
          + cr * cp * b_ned[2])
    B = np.c_[bx, by, bz]
    Bm = np.linalg.norm(B, axis=1)
    c = B / Bm[:, None]
    dc = np.gradient(c, t, axis=0)
    s = Bm / 50000.0
    cx, cy, cz = c.T
    A = np.c_[cx, cy, cz, s * cx * cx, s * cx * cy, s * cx * cz, s * cy * cy, s * cy * cz,
              s * cx * dc[:, 0], s * cx * dc[:, 1], s * cx * dc[:, 2], s * cy * dc[:, 0],
              s * cy * dc[:, 1], s * cy * dc[:, 2], s * cz * dc[:, 0], s * cz * dc[:, 1]]
    coef = np.r_[rng.normal(0, 30, 3), rng.normal(0, 15, 5), rng.normal(0, 2, 8)]
    tl = A @ coef
    # Currents: PWM-like duty-cycle loads and a ramping heater, logged with 1 mA noise.
    duty = (np.sin(2 * np.pi * t / rng.uniform(4, 9)) > rng.uniform(-0.5, 0.5, n // 200 + 1)
            .repeat(200)[:n]).astype(float)
    i1 = 6 + 4 * duty
    i2 = 3 + 2 * np.clip(np.cumsum(rng.normal(0, 0.05, n)) / 10, -1, 1) + \
        0.8 * np.sin(2 * np.pi * t / 1.7)
    i3 = 8 + 3 * (rng.random(n // 97 + 1).repeat(97)[:n] > 0.5)
    # nT/A: the scalar sees I (v . b), and a single coefficient per current models only its
    # mean projection; with twice these loops the attitude's change of the projection leaves
    # 1.16 x the noise floor on this flight (docs/compensation.md).
    v = np.array([[0.0001, -0.0001, 0.015], [0.0001, 0.0002, -0.025], [-0.0001, 0.0, 0.01]])
    cur_field = i1 * (c @ v[0]) + i2 * (c @ v[1]) + i3 * (c @ v[2])
    cur_field += quadratic * (i2 - 3) ** 2
    # Noise: white plus a little red (a first-order autoregressive part), 0.015 nT rms.
    red = np.zeros(n)
    w = rng.normal(0, 0.004, n)
    for k in range(1, n):
        red[k] = 0.95 * red[k - 1] + w[k]
    noise = rng.normal(0, 0.012, n) + red
    slow = 5 * np.sin(2 * np.pi * t / 1300.0)  # a slow external variation (diurnal-like)
    true_field = F + slow
    mag = true_field + tl + noise + (cur_field if currents else 0.0)
    df = pd.DataFrame({"time": t, "flux_x": bx + rng.normal(0, 0.3, n),
                       "flux_y": by + rng.normal(0, 0.3, n), "flux_z": bz + rng.normal(0, 0.3, n),
                       "mag": mag, "i_a": i1 + rng.normal(0, 1e-3, n),
                       "i_b": i2 + rng.normal(0, 1e-3, n), "i_c": i3 + rng.normal(0, 1e-3, n),
                       "ref": true_field})
    return df, coef, noise, fs


def test_independent_generator_extras_and_reference():
    df, coef, noise, fs = _independent_flight(7)
    floor = _band_floor(noise, df["time"].to_numpy(), np.zeros(len(df), dtype=int), fs)
    res = calibrate(df, CompensationConfig(extras=("i_a", "i_b", "i_c"), fom=False,
                                           segment_seconds=60), source="indep")
    h = _held(res)
    assert h.tl_only_residual_std_nT > 1.5 * floor
    assert h.residual_std_nT <= 1.10 * floor, (h.residual_std_nT, floor)
    # Against the reference over the full band: the TL coefficients of the truth.
    res = calibrate(df, CompensationConfig(extras=("i_a", "i_b", "i_c"), reference="ref",
                                           fom=False, segment_seconds=60), source="indep")
    err = res.model.coef - coef
    assert np.abs(err).max() < 0.02 * np.abs(coef).max(), err
    out = compensate(df, CompensationConfig(filter_output=False), model=res.model)
    assert abs(out.data["mag_comp"].mean() - df["ref"].mean()) < 0.01


def test_mlp_kept_only_where_it_beats_linear(caplog):
    df, _, _, _ = _independent_flight(3, quadratic=0.05)
    cfg = CompensationConfig(extras=("i_a", "i_b", "i_c"), reference="ref", estimator="mlp",
                             fom=False, segment_seconds=60)
    res = calibrate(df, cfg, source="indep")
    rec = res.report.extended.mlp_training
    assert rec["kept"] and rec["mlp_std_nT"] < 0.9 * rec["linear_std_nT"]
    d = json.loads(json.dumps(res.model.to_dict()))  # portable: plain lists only
    assert isinstance(d["extended"]["mlp"]["weights"][0][0], list)
    back = TLModel.from_dict(d)
    a = compensate(df, CompensationConfig(filter_output=False), model=res.model)
    b = compensate(df, CompensationConfig(filter_output=False), model=back)
    np.testing.assert_allclose(a.data["mag_tl"], b.data["mag_tl"], atol=1e-9)
    # Without a non-linear part the network is not kept, and a warning says so.
    df2, _, _, _ = _independent_flight(3)
    with caplog.at_level(logging.WARNING):
        res2 = calibrate(df2, cfg, source="indep")
    assert not res2.report.extended.mlp_training["kept"]
    assert res2.model.extended.mlp is None
    assert "linear model is used" in caplog.text


def test_pls_estimator(sim):
    cur, _, _, floor = sim
    res = calibrate(cur, CompensationConfig(extras=EXTRAS, estimator="pls", fom=False),
                    source="sim")
    h = _held(res)
    assert h.residual_std_nT < 0.8 * h.tl_only_residual_std_nT
    assert 1 <= res.model.extended.param <= 20


# --------------------------------------------------------------------------- bad inputs
def test_constant_and_empty_extras_dropped_with_warning(sim, caplog):
    cur, _, _, _ = sim
    df = cur.assign(const=5.0, empty=np.nan)
    with caplog.at_level(logging.WARNING):
        res = calibrate(df, CompensationConfig(extras=("cur_1", "const", "empty"), fom=False),
                        source="sim")
    assert "--extra const is constant" in caplog.text
    assert "--extra empty is empty" in caplog.text
    assert res.model.extended.extras == ("cur_1",)
    assert res.report.extended.dropped_extras == ["const", "empty"]


def test_reference_with_gaps_rows_left_out(sim, caplog):
    _, logged, truth, _ = sim
    df = logged.assign(ref=logged["truth_mag_clean"])
    df.loc[1000:1400, "ref"] = np.nan
    with caplog.at_level(logging.WARNING):
        res = calibrate(df, CompensationConfig(reference="ref", fom=False), source="sim")
    assert "401 of 6000 rows have no value in ref: left out of the fit" in caplog.text
    assert res.report.extended.rows_left_out == 401
    true = np.asarray(truth["coef"])
    assert np.abs(res.model.coef - true).max() < 0.01 * np.abs(true).max()


def test_config_refusals():
    with pytest.raises(ConfigError):
        CompensationConfig(estimator="mlp", extras=("a",))  # mlp needs a reference
    with pytest.raises(ConfigError):
        CompensationConfig(estimator="pls")  # nothing to choose a fit for
    with pytest.raises(ConfigError):
        CompensationConfig(estimator="lasso", extras=("a",))


def test_missing_extra_and_model_on_log_without_extras(sim, tmp_path):
    cur, logged, _, _ = sim
    with pytest.raises(InputError, match="no column cur_9"):
        calibrate(cur, CompensationConfig(extras=("cur_9",), fom=False), source="sim")
    cal = tmp_path / "cal.csv"
    plain = tmp_path / "plain.csv"
    cur.to_csv(cal, index=False)
    logged.drop(columns=["cur_2", "volt_bus"]).to_csv(plain, index=False)
    runner = CliRunner()
    r = runner.invoke(app, ["calibrate", str(cal), "--extra", "cur_1,cur_9", "-o",
                            str(tmp_path / "bad.json")])
    assert r.exit_code == 1
    assert r.output.strip().count("\n") == 0 and "no column cur_9 (--extra)" in r.output
    assert not (tmp_path / "bad.json").exists()
    model = tmp_path / "m.json"
    r = runner.invoke(app, ["calibrate", str(cal), "--extra", ",".join(EXTRAS), "-o",
                            str(model)])
    assert r.exit_code == 0, r.output
    out = tmp_path / "o.csv"
    r = runner.invoke(app, ["compensate", str(plain), "--model", str(model), "-o", str(out)])
    assert r.exit_code == 1
    assert "no column cur_2, volt_bus" in r.output and r.output.strip().count("\n") == 0
    assert not out.exists() and not out.with_suffix(".json").exists()
    # --extra with --model steers nothing: refused
    r = runner.invoke(app, ["compensate", str(cal), "--model", str(model), "--extra", "cur_1",
                            "-o", str(out)])
    assert r.exit_code == 1 and "--extra" in r.output


def test_cli_subprocess_extra_and_report(sim, tmp_path):
    cur, _, _, _ = sim
    cal = tmp_path / "cal.csv"
    cur.to_csv(cal, index=False)
    out = tmp_path / "o.csv"
    p = subprocess.run([sys.executable, "-m", "aeromag", "compensate", str(cal), "--extra",
                        ",".join(EXTRAS), "-o", str(out)], capture_output=True, text=True,
                       timeout=300)
    assert p.returncode == 0, p.stderr
    rep = json.loads(out.with_suffix(".json").read_text())
    h = rep["extended"]["held_out"]
    assert h["residual_std_nT"] < h["tl_only_residual_std_nT"]
    assert rep["config"]["extras"] == list(EXTRAS)
    from aeromag.workflows.report import render_html

    page = render_html({"band_hz": [0.1, 0.9]}, rep, {}, title="t")
    assert "Beyond the 16 terms" in page and "cur_1" in page


def test_reports_without_the_options_unchanged(sim):
    cur, _, _, _ = sim
    res = calibrate(cur, CompensationConfig(fom=False), source="sim")
    assert "extended" not in res.report.to_dict()
    assert not {"reference", "extras", "estimator"} & set(res.report.config.options())
    assert "extended" not in res.model.to_dict()


def test_malformed_extended_block_is_one_line(sim, tmp_path):
    cur, _, _, _ = sim
    d = calibrate(cur, CompensationConfig(extras=EXTRAS[:1], fom=False),
                  source="sim").model.to_dict()
    for bad in ({"extras": 5}, {"extras": [{"name": "cur_1", "coef_nT_per_unit": "x",
                                            "center": 0, "scale": 1}]},
                {"extras": [], "mlp": {"weights": [[[1.0]]], "biases": [[0.0]],
                                       "x_center": [0.0], "x_scale": [1.0], "y_scale": 1.0}}):
        path = tmp_path / "m.json"
        path.write_text(json.dumps({**d, "extended": bad}))
        with pytest.raises(InputError, match="extended"):
            TLModel.load(path)


def test_simulate_currents_calibration_carries_to_the_survey(tmp_path):
    r = CliRunner().invoke(app, ["simulate", "-o", str(tmp_path), "--small", "--currents", "3"])
    assert r.exit_code == 0, r.output
    truth = json.loads((tmp_path / "truth.json").read_text())
    assert len(truth["survey"]["current_loops"]) == 3
    cal = pd.read_csv(tmp_path / "calibration.csv")
    sur = pd.read_csv(tmp_path / "survey.csv")
    assert {"cur_1", "cur_2", "cur_3", "volt_bus", "truth_mag_current"} <= set(sur.columns)
    errs = {}
    for label, extras in (("tl", ()), ("extras", ("cur_1", "cur_2", "cur_3"))):
        model = calibrate(cal, CompensationConfig(extras=extras, fom=False), source="cal").model
        out = compensate(sur, CompensationConfig(filter_output=False), model=model).data
        e = (out["mag_comp"] - sur["truth_mag_clean"]).to_numpy()
        errs[label] = float(np.std(e - np.mean(e)))
    # The calibration's extras remove most of the survey's current interference.
    assert errs["extras"] < 0.6 * errs["tl"], errs


_json = st.recursive(st.none() | st.booleans() | st.floats(allow_nan=True) | st.integers()
                     | st.just(10 ** 400)
                     | st.text(max_size=5),
                     lambda inner: st.lists(inner, max_size=4)
                     | st.dictionaries(st.text(max_size=5), inner, max_size=4), max_leaves=20)
_extra = st.fixed_dictionaries({"name": st.text(min_size=1, max_size=6),
                                "coef_nT_per_unit": _json, "center": _json, "scale": _json})


@settings(max_examples=150, deadline=None)
@given(st.fixed_dictionaries({}, optional={
    "reference": _json, "extras": st.lists(_extra, max_size=3) | _json, "intercept_nT": _json,
    "param": _json, "estimator": _json, "mlp": _json}))
def test_extended_block_parser_never_crashes(block):
    from aeromag.compensation.extended import ExtendedModel

    try:
        m = ExtendedModel.from_dict(block, 16, "m.json")
    except InputError as exc:
        assert "m.json" in str(exc)
        return
    assert np.isfinite(m.extra_coef).all() and np.isfinite(m.intercept_nT)
    assert len(m.extras) == len(m.extra_coef)
