"""Online Tolles-Lawson (compensate --online): causality, streaming equals batch, the jump
and no-jump flights against batch fits, the scikit-learn estimator, the workflow."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from scipy.signal import sosfiltfilt

from aeromag._core.filters import butter_sos
from aeromag.compensation.online import OnlineTL, causal_derivative, new_stretch_starts
from aeromag.compensation.terms import design_matrix
from aeromag.errors import InputError
from aeromag.synthetic.online_tl import simulate_online_tl
from aeromag.workflows.online_compensate import OnlineReport, compensate_online_file

FLUX = ["flux_x", "flux_y", "flux_z"]
SOS = butter_sos("bandpass", (0.1, 0.9), 10.0, 4)


def _bp(x):
    return sosfiltfilt(SOS, x, axis=0)


def _arrays(log):
    return (log["time"].to_numpy(copy=True), log[FLUX].to_numpy(copy=True),
            log["mag"].to_numpy(copy=True))


def test_causal_derivative_hand_case():
    t = np.array([0.0, 0.1, 0.3, 0.4, 5.0, 5.1])
    v = np.array([1.0, 2.0, 2.0, 4.0, 0.0, 1.0])
    starts = new_stretch_starts(t, np.ones(6, bool), 0.5)
    np.testing.assert_array_equal(starts, [True, False, False, False, True, False])
    np.testing.assert_allclose(causal_derivative(v, t, starts), [0, 10, 0, 20, 0, 10])


@pytest.mark.parametrize("derivative", ["central", "backward", "midpoint"])
def test_no_future_sample_changes_the_past(derivative):
    log, _ = simulate_online_tl(duration_s=120.0, jump_s=None, seed=1)
    t, flux, mag = _arrays(log)
    base = OnlineTL(10.0, derivative=derivative).compensate(t, flux, mag).mag_tl
    k0 = 700
    flux2, mag2 = flux.copy(), mag.copy()
    flux2[k0:] *= 1.01
    mag2[k0:] += 50.0
    pert = OnlineTL(10.0, derivative=derivative).compensate(t, flux2, mag2).mag_tl
    last_equal = k0 - 2 if derivative == "central" else k0 - 1  # one-sample latency
    # equal to rounding (blocked vector arithmetic), while the change itself is of nT
    np.testing.assert_allclose(pert[:last_equal + 1], base[:last_equal + 1], rtol=0, atol=1e-8)
    assert np.abs(pert[last_equal + 2:] - base[last_equal + 2:]).max() > 1e-3


def test_pieces_equal_whole_backward_exact_central_close():
    """State carried between calls: exact with the backward derivative; with the central one
    the last sample of each piece has a one-sided derivative (documented), a small change."""
    log, _ = simulate_online_tl(duration_s=200.0, jump_s=100.0, seed=2)
    t, flux, mag = _arrays(log)
    for derivative in ("backward", "midpoint", "central"):
        whole = OnlineTL(10.0, derivative=derivative).compensate(t, flux, mag)
        est = OnlineTL(10.0, derivative=derivative)
        parts = [est.compensate(t[a:b], flux[a:b], mag[a:b]) for a, b in
                 ((0, 333), (333, 1000), (1000, 1001), (1001, len(t)))]
        tl = np.concatenate([p.mag_tl for p in parts])
        if derivative != "central":  # exact but for rounding (blocked sums)
            np.testing.assert_allclose(tl, whole.mag_tl, rtol=0, atol=1e-7)
            np.testing.assert_allclose(parts[-1].coef, whole.coef, rtol=1e-9, atol=1e-9)
        else:
            assert np.abs(tl - whole.mag_tl).max() < 0.5
            assert np.median(np.abs(tl - whole.mag_tl)) < 0.02
            np.testing.assert_allclose(parts[-1].coef, whole.coef, rtol=0.02, atol=0.2)


def test_bdf2_derivative_hand_case():
    """Exact on a parabola (no half-sample lag), backward on a stretch's second sample."""
    from aeromag.compensation.online import bdf2_derivative

    t = np.array([0.0, 0.1, 0.3, 0.4, 0.5, 0.6])
    v = (t ** 2)[:, None]
    starts = np.array([True, False, False, False, True, False])
    d = bdf2_derivative(v, t, starts)[:, 0]
    np.testing.assert_allclose(d[[2, 3]], 2 * t[[2, 3]], rtol=1e-12)
    np.testing.assert_allclose(d[[0, 4]], 0.0)
    np.testing.assert_allclose(d[[1, 5]], [0.1, 1.1], rtol=1e-12)  # backward differences


def test_midpoint_strictly_causal_and_far_better_than_backward():
    """The strictly causal midpoint fit (rows at t_(k-1/2), no future sample) against the
    backward difference: measured 1.5-1.7x the post-jump batch residual vs 3.6-4.2x."""
    log, _ = simulate_online_tl(duration_s=1200.0, jump_s=300.0, seed=0)
    t, flux, mag = _arrays(log)
    A = design_matrix(flux, t)
    post = t >= 305.0
    c_post = np.linalg.lstsq(_bp(A)[post], _bp(mag)[post], rcond=None)[0]
    ev = t >= 900.0
    r = {d: float(np.std(_bp(mag - OnlineTL(10.0, derivative=d)
                                .compensate(t, flux, mag).mag_tl)[ev]))
         for d in ("midpoint", "backward")}
    r_post = float(np.std(_bp(mag - A @ c_post)[ev]))
    assert r["midpoint"] < 0.5 * r["backward"], r
    assert r["midpoint"] < 2.0 * r_post, (r, r_post)


def test_simulator_eddy_from_true_rate_not_logged_difference():
    """The oracle's eddy interference comes from the attitude's true rate (oversampled), so it
    differs from the central difference of the logged samples that the batch fit uses."""
    from aeromag.synthetic.physics import tl_interference

    log, truth = simulate_online_tl(duration_s=120.0, jump_s=None, seed=0, flux_noise_nT=0.0)
    t, flux, _ = _arrays(log)
    logged = tl_interference(flux, t, np.asarray(truth["coef_before"]))
    d = np.abs(log["truth_mag_tl"].to_numpy() - logged)
    assert d.max() > 1e-3 and d.max() < 0.2


def test_step_equals_run():
    log, _ = simulate_online_tl(duration_s=30.0, jump_s=None, seed=0)
    t, flux, mag = _arrays(log)
    a = OnlineTL(10.0, derivative="backward").compensate(t, flux, mag).mag_tl
    est = OnlineTL(10.0, derivative="backward")
    b, states = [], []
    for k in range(len(t)):
        st = est.step(mag[k], np.r_[t[k], flux[k]])
        b.append(est.last_mag_tl)
        states.append(st.state)
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-9)
    whole = OnlineTL(10.0, derivative="backward").run(mag, np.column_stack([t, flux]))
    np.testing.assert_allclose(np.array(states), whole.state, rtol=0, atol=1e-9)


def test_nan_sample_skipped_not_propagated():
    log, _ = simulate_online_tl(duration_s=60.0, jump_s=None, seed=0)
    t, flux, mag = _arrays(log)
    mag[100] = np.nan
    flux[200, 1] = np.nan
    res = OnlineTL(10.0).compensate(t, flux, mag)
    assert np.isnan(res.mag_tl[[100, 200]]).all()
    assert np.isfinite(np.delete(res.mag_tl, [100, 200])).all()
    assert np.isfinite(res.coef).all() and res.skipped[[100, 200]].all()


def _compare(seed, jump):
    log, truth = simulate_online_tl(duration_s=2400.0, jump_s=jump, seed=seed)
    t, flux, mag = _arrays(log)
    online = OnlineTL(10.0, forgetting=0.999).compensate(t, flux, mag)
    A = design_matrix(flux, t)
    Ab, yb = _bp(A), _bp(mag)
    post = t >= (jump or 0.0) + 5.0
    c_post = np.linalg.lstsq(Ab[post], yb[post], rcond=None)[0]
    c_all = np.linalg.lstsq(Ab, yb, rcond=None)[0]
    ev = (t >= 1800.0) & (t < 2390.0)  # re-converged: 1200 s (12 memories) after the jump

    def resid(tl):
        return float(np.std(_bp(mag - tl)[ev]))

    return resid(online.mag_tl), resid(A @ c_post), resid(A @ c_all)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_jump_online_close_to_post_jump_batch_far_below_whole_flight(seed):
    r_on, r_post, r_all = _compare(seed, 600.0)
    assert r_on <= 1.5 * r_post, (r_on, r_post)
    assert r_on <= 0.1 * r_all, (r_on, r_all)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_no_jump_online_within_13_of_batch(seed):
    r_on, r_post, r_all = _compare(seed, None)
    assert r_on <= 1.3 * r_all, (r_on, r_all)


def test_forgetting_outside_range_refused():
    with pytest.raises(InputError, match=r"\(0, 1\]"):
        OnlineTL(10.0, forgetting=1.01)
    with pytest.raises(InputError, match=r"\(0, 1\]"):
        OnlineTL(10.0, forgetting=0.0)


def test_sklearn_partial_fit_continues():
    pytest.importorskip("sklearn")
    from aeromag.compensation.online_estimator import OnlineTollesLawsonRegressor

    log, truth = simulate_online_tl(duration_s=600.0, jump_s=None, seed=3)
    X = log[["time", *FLUX]]
    y = log["mag"]
    whole = OnlineTollesLawsonRegressor(derivative="backward").fit(X, y)
    est = OnlineTollesLawsonRegressor(derivative="backward")
    for a in range(0, len(X), 1000):
        est.partial_fit(X.iloc[a:a + 1000], y.iloc[a:a + 1000])
    np.testing.assert_allclose(est.coef_, whole.coef_, rtol=1e-9, atol=1e-9)
    assert est.n_samples_seen_ == len(X)
    assert est.get_params()["forgetting"] == 0.999
    pred = est.predict(X)
    assert np.std(_bp(y.to_numpy() - pred)[3000:-100]) < 0.1 * np.std(_bp(y.to_numpy())[3000:-100])


def test_workflow_writes_compensate_columns(tmp_path):
    log, _ = simulate_online_tl(duration_s=600.0, jump_s=300.0, seed=4)
    path = tmp_path / "survey.csv"
    log.to_csv(path, index=False)
    out = tmp_path / "out.csv"
    rep = compensate_online_file(path, out, forgetting=0.998)
    df = pd.read_csv(out)
    for c in ("mag_tl", "mag_comp", "segment", "segment_kept"):
        assert c in df.columns
    assert df["mag_comp"].notna().all() and df["segment_kept"].all()
    js = json.loads(out.with_suffix(".json").read_text())
    assert js == json.loads(json.dumps(rep.to_dict(), default=float))
    assert OnlineReport.from_dict(js).to_dict() == js
    for k in ("terms", "coef", "segments", "metrics", "history", "forgetting"):
        assert k in js
    assert len(js["coef"]) == 16 and len(js["terms"]) == 16
    assert js["metrics"]["improvement_ratio"] > 1.0
    assert len(js["history"]["time"]) == len(js["history"]["coef"]) <= 202
    # bad inputs: one error, no output
    with pytest.raises(InputError, match=r"\(0, 1\]"):
        compensate_online_file(path, tmp_path / "x.csv", forgetting=1.5)
    with pytest.raises(InputError, match="terms"):
        compensate_online_file(path.with_name("short.csv") if log.iloc[:10].to_csv(
            path.with_name("short.csv"), index=False) is None else path, tmp_path / "y.csv")
    assert not (tmp_path / "x.csv").exists() and not (tmp_path / "y.csv").exists()


def test_undetermined_flight_refused_like_the_batch_fit(tmp_path):
    """The mission sample (no scalar magnetometer, heading disturbances of 20 uT) does not
    determine the TL terms: the batch fit refuses it, and so does the online fit."""
    from pathlib import Path

    from aeromag.errors import FitError

    src = Path(__file__).resolve().parents[1] / "data_samples" / "mission.csv"
    out = tmp_path / "m.csv"
    with pytest.raises(FitError, match="no aircraft makes.*forgetting=0.999") as e:
        compensate_online_file(src, out)
    assert "--" not in str(e.value)  # the Python API names parameters; the CLI maps them
    assert not out.exists() and not out.with_suffix(".json").exists()


# -- command line: compensate --online ----------------------------------------------------------

def _survey_csv(tmp_path, **kw):
    log, truth = simulate_online_tl(**{"duration_s": 600.0, "jump_s": 300.0, "seed": 5, **kw})
    path = tmp_path / "survey.csv"
    log.to_csv(path, index=False)
    return path, truth


def test_cli_compensate_online(tmp_path):
    from typer.testing import CliRunner

    from aeromag.cli import app

    path, _ = _survey_csv(tmp_path)
    out = tmp_path / "out.csv"
    r = CliRunner().invoke(app, ["compensate", str(path), "--online", "--forgetting", "0.998",
                                 "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert "online fit" in r.output
    df = pd.read_csv(out)
    for c in ("mag_tl", "mag_comp", "segment", "segment_kept"):
        assert c in df.columns
    js = json.loads(out.with_suffix(".json").read_text())
    assert js["online"] is True and js["forgetting"] == 0.998 and len(js["coef"]) == 16
    # --terms applies online too
    out9 = tmp_path / "out9.csv"
    r = CliRunner().invoke(app, ["compensate", str(path), "--online", "--terms", "9",
                                 "-o", str(out9)])
    assert r.exit_code == 0, r.output
    assert len(json.loads(out9.with_suffix(".json").read_text())["coef"]) == 9


@pytest.mark.parametrize("args,needle", [
    (["--online", "--forgetting", "0"], "(0, 1]"),
    (["--online", "--forgetting", "1.2"], "(0, 1]"),
    (["--forgetting", "0.99"], "--online"),
    (["--online", "--model", "m.json"], "--model"),
])
def test_cli_compensate_online_bad_options(tmp_path, args, needle):
    from typer.testing import CliRunner

    from aeromag.cli import app

    path, _ = _survey_csv(tmp_path, duration_s=60.0, jump_s=None)
    out = tmp_path / "bad.csv"
    r = CliRunner().invoke(app, ["compensate", str(path), *args, "-o", str(out)])
    assert r.exit_code == 1, r.output
    lines = [ln for ln in r.output.strip().splitlines() if ln]
    assert len(lines) == 1 and lines[0].startswith("error: ") and needle in lines[0], r.output
    assert not out.exists() and not out.with_suffix(".json").exists()


def test_cli_compensate_online_short_log(tmp_path):
    from typer.testing import CliRunner

    from aeromag.cli import app

    log, _ = simulate_online_tl(duration_s=1.2, jump_s=None)
    path = tmp_path / "short.csv"
    log.to_csv(path, index=False)
    out = tmp_path / "s.csv"
    r = CliRunner().invoke(app, ["compensate", str(path), "--online", "-o", str(out)])
    assert r.exit_code == 1 and r.output.startswith("error: "), r.output
    assert not out.exists()


def test_cli_compensate_online_subprocess(tmp_path):
    import subprocess
    import sys

    path, _ = _survey_csv(tmp_path, duration_s=120.0, jump_s=None)
    out = tmp_path / "sub.csv"
    p = subprocess.run([sys.executable, "-m", "aeromag", "compensate", str(path), "--online",
                        "-o", str(out)], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    rep = json.loads(out.with_suffix(".json").read_text())
    assert rep["online"] is True and rep["convergence"]["spans"][0]["kind"] == "warmup"
    cols = pd.read_csv(out, nrows=2).columns
    assert {"mag_tl_std", "tl_converged"} <= set(cols)


def test_cli_simulate_online(tmp_path):
    from typer.testing import CliRunner

    from aeromag.cli import app

    r = CliRunner().invoke(app, ["simulate", "-o", str(tmp_path / "sim"), "--small",
                                 "--online"])
    assert r.exit_code == 0, r.output
    for name in ("compass.csv", "compass_truth.json", "online_tl.csv", "online_tl_truth.json"):
        assert (tmp_path / "sim" / name).exists(), name
    comp = pd.read_csv(tmp_path / "sim" / "compass.csv")
    assert {"heading", "pitch", "roll", "lat", "truth_bx"} <= set(comp.columns)
    truth = json.loads((tmp_path / "sim" / "online_tl_truth.json").read_text())
    assert len(truth["coef_before"]) == len(truth["coef_after"]) == 16
