"""Vector calibration (aeromag compass): exactness, the study's behaviour, IGRF, heading,
excitation indicator, bad inputs, command line."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.compass import (
    CompassCalibration,
    calibrate_compass,
    compass_heading,
    convergence_time,
    explicit_field,
    igrf_field,
    reference_in_body,
)
from aeromag.errors import InputError
from aeromag.synthetic.compass import simulate_compass

runner = CliRunner()
FLUX = ["flux_x", "flux_y", "flux_z"]


def _calibrate(log, truth, lam, **kw):
    return calibrate_compass(log[FLUX].to_numpy(), log["heading"].to_numpy(),
                             log["pitch"].to_numpy(), log["roll"].to_numpy(),
                             np.array(truth["earth_ned_nT"]), time_s=log["time"].to_numpy(),
                             forgetting=lam, **kw)


def _rms(e, t, a, b):
    s = (t >= a) & (t < b)
    return float(np.sqrt(np.mean(e[s] ** 2)))


# -- exactness ------------------------------------------------------------------------------

@pytest.mark.parametrize("seed,amp,heading0", [(0, 40.0, 30.0), (1, 25.0, 200.0),
                                               (2, 55.0, -100.0)])
@pytest.mark.parametrize("lam", [1.0, 0.96])
def test_noise_free_twelve_parameters_to_1e9(seed, amp, heading0, lam):
    log, truth = simulate_compass(noise_nT=0.0, switch_s=None, amplitude_deg=amp,
                                  heading0_deg=heading0, seed=seed, duration_s=10.0)
    b = log[["truth_bx", "truth_by", "truth_bz"]].to_numpy()
    D = np.array(truth["matrix_before"])
    e = np.array(truth["offset_before_nT"])
    f0 = float(np.linalg.norm(truth["earth_ned_nT"]))
    run = CompassCalibration(lam, alpha=1e12, field_scale_nT=f0)
    run.run(b, log[FLUX].to_numpy())
    step = CompassCalibration(lam, alpha=1e12, field_scale_nT=f0)
    for f, q in zip(log[FLUX].to_numpy()[:200], b[:200], strict=True):
        step.step(q, f)
    for est in (run,):
        assert np.abs(est.matrix - D).max() < 1e-9
        assert np.abs(est.offset_nT - e).max() / np.abs(e).max() < 1e-9
    step.run(b[200:], log[FLUX].to_numpy()[200:])  # streaming then batched: same estimate
    np.testing.assert_allclose(step.matrix, run.matrix, atol=1e-9)


def test_reference_in_body_matches_simulator_truth():
    log, truth = simulate_compass(duration_s=2.0)
    b = reference_in_body(np.array(truth["earth_ned_nT"]), log["heading"], log["pitch"],
                          log["roll"])
    np.testing.assert_allclose(b, log[["truth_bx", "truth_by", "truth_bz"]], atol=1e-8)


# -- heading ---------------------------------------------------------------------------------

def test_heading_level_hand_case():
    # Level, heading 0: body = NED; field (H cos D, H sin D, Z) -> true heading 0.
    h, dec, z = 20000.0, 10.0, 40000.0
    d = np.deg2rad(dec)
    # Heading 90 (east): the field in body axes is (H sin D, -H cos D, Z).
    b = np.array([[h * np.cos(d), h * np.sin(d), z], [h * np.sin(d), -h * np.cos(d), z]])
    out = compass_heading(b, np.zeros(2), np.zeros(2), dec)
    np.testing.assert_allclose(out, [0.0, 90.0], atol=1e-9)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_heading_tilt_compensated_exact(seed):
    rng = np.random.default_rng(seed)
    n = 500
    hdg = rng.uniform(0, 360, n)
    pitch = rng.uniform(-60, 60, n)
    roll = rng.uniform(-70, 70, n)
    ref = explicit_field(52000.0, 62.0, -7.5)
    b = reference_in_body(ref.ned_nT, hdg, pitch, roll)
    out = compass_heading(b, pitch, roll, -7.5)
    assert ((out >= 0) & (out < 360)).all()
    np.testing.assert_allclose(((out - hdg + 180) % 360) - 180, 0.0, atol=1e-8)


# -- the study's behaviour (methods.md M3) ---------------------------------------------------

@pytest.mark.parametrize("seed", [0, 1, 2])
def test_study_forgetting_096_at_40_degrees(seed):
    log, truth = simulate_compass(amplitude_deg=40.0, seed=seed)
    t = log["time"].to_numpy()
    ff = _calibrate(log, truth, 0.96).heading_err_deg
    plain = _calibrate(log, truth, 1.0).heading_err_deg
    rms_ff, rms_plain = _rms(ff, t, 20, 30), _rms(plain, t, 20, 30)
    assert rms_ff <= 0.6
    assert rms_ff <= 0.25 * rms_plain
    # one-second RMS below 1 deg within 5 s of the switch, and it stays there
    assert convergence_time(t, ff, 15.0) <= 5.0
    # plain RLS never recovers: every one-second RMS after the switch above 1 deg
    for a in np.arange(15.5, 29.0, 0.5):
        assert _rms(plain, t, a, a + 1) > 1.0
    assert convergence_time(t, plain, 15.0) == np.inf


@pytest.mark.parametrize("seed", [0, 3])
def test_convergence_ordered_by_forgetting(seed):
    log, truth = simulate_compass(amplitude_deg=40.0, seed=seed)
    t = log["time"].to_numpy()
    conv = {lam: convergence_time(t, _calibrate(log, truth, lam).heading_err_deg, 15.0)
            for lam in (0.99, 0.975, 0.96)}
    assert conv[0.99] > conv[0.975] > conv[0.96]
    assert np.isfinite(conv[0.99])


@pytest.mark.parametrize("seed", [0, 1])
def test_excitation_indicator_flags_10_degrees(seed):
    small = _calibrate(*simulate_compass(amplitude_deg=10.0, seed=seed), 0.96)
    large = _calibrate(*simulate_compass(amplitude_deg=40.0, seed=seed), 0.96)
    mid = _calibrate(*simulate_compass(amplitude_deg=20.0, seed=seed), 0.96)
    assert not any(w.sufficient for w in small.excitation)
    assert all(w.sufficient for w in large.excitation)
    assert all(w.sufficient for w in mid.excitation)
    w = small.excitation[0]
    assert 19 < w.roll_range_deg <= 20.0 and 19 < w.pitch_range_deg <= 20.0


def test_parameters_follow_the_switch():
    log, truth = simulate_compass(amplitude_deg=40.0, seed=5, noise_nT=20.0)
    res = _calibrate(log, truth, 0.96)
    np.testing.assert_allclose(res.matrix_history[740], truth["matrix_before"], atol=0.01)
    np.testing.assert_allclose(res.matrix, truth["matrix_after"], atol=0.01)
    np.testing.assert_allclose(res.offset_nT, truth["offset_after_nT"], atol=60.0)


# -- IGRF -------------------------------------------------------------------------------------

# NOAA's IGRF-14 calculator values (north, east, down nT; ellipsoidal height), as listed in
# Harmonica's IGRF-14 test suite (harmonica/tests/test_igrf.py), rounded to 0.1 nT.
IGRF14_POINTS = [
    # lat, lon, alt_m, date, (north, east, down)
    (-23.5, -43.7, 700.0, "2020-01-01", (16085.4, -6690.6, -15201.8)),  # Sao Paulo
    (47.9, 106.9, 1300.0, "2020-05-31", (21677.4, -1940.8, 55078.8)),  # Ulaanbaatar
    (9.0, 38.7, 2355.0, "2021-02-01", (35605.6, 1421.6, 1788.7)),  # Addis Ababa
    (47.9, 106.9, 1300.0, "2026-06-01", (21568.1, -2104.8, 55327.5)),  # predicted SV
]


@pytest.mark.parametrize("lat,lon,alt,date,ned", IGRF14_POINTS)
def test_igrf_matches_published_values(lat, lon, alt, date, ned):
    pytest.importorskip("ppigrf", reason="IGRF needs the optional ppigrf package")
    ref = igrf_field([lat], [lon], alt, date)
    np.testing.assert_allclose(ref.ned_nT[0], ned, atol=1.0)
    assert ref.info["model"] == "IGRF-14" and ref.info["date"] == date


def test_igrf_taiyuan_is_the_study_field():
    pytest.importorskip("ppigrf", reason="IGRF needs the optional ppigrf package")
    ref = igrf_field([37.87], [112.55], 800.0, "2017-07-01")
    np.testing.assert_allclose(ref.ned_nT[0], [29270, -2730, 45420], atol=15.0)


@pytest.mark.parametrize("date", ["1899-12-31", "2030-01-01", "2040-06-01", "17/07/2017"])
def test_igrf_date_outside_refused(date):
    with pytest.raises(InputError, match="date='"):
        igrf_field([37.0], [112.0], 0.0, date)


# -- command line ------------------------------------------------------------------------------

@pytest.fixture
def study_log(tmp_path):
    log, truth = simulate_compass(amplitude_deg=40.0, seed=0, duration_s=20.0)
    log["lat"], log["lon"], log["alt"] = 37.87, 112.55, 800.0
    path = tmp_path / "study.csv"
    log.to_csv(path, index=False)
    return path, truth


def test_cli_compass_igrf(study_log, tmp_path):
    pytest.importorskip("ppigrf", reason="IGRF needs the optional ppigrf package")
    path, truth = study_log
    out = tmp_path / "out.csv"
    r = runner.invoke(app, ["compass", str(path), "-o", str(out), "--date", "2017-07-01",
                            "--forgetting", "0.96"])
    assert r.exit_code == 0, r.output
    df = pd.read_csv(out)
    for c in ("flux_cal_x", "flux_cal_y", "flux_cal_z", "mag_heading_cal", "heading_err_deg"):
        assert c in df.columns and df[c].notna().all()
    assert ((df["mag_heading_cal"] >= 0) & (df["mag_heading_cal"] < 360)).all()
    rep = json.loads(out.with_suffix(".json").read_text())
    for k in ("matrix", "offset_nT", "forgetting", "reference", "metrics", "excitation"):
        assert k in rep
    assert rep["forgetting"] == 0.96
    assert rep["reference"]["source"] == "IGRF" and rep["reference"]["date"] == "2017-07-01"
    np.testing.assert_allclose(rep["matrix"], truth["matrix_after"], atol=0.02)
    assert rep["metrics"]["heading_err_rms_deg"] < 2.0
    assert "heading_err_mean_deg" in rep["metrics"]
    assert rep["excitation"]["n_insufficient"] == 0
    # the last rows are converged: the calibrated field is the Earth field in body axes
    tail = df.iloc[-100:]
    bt = tail[["truth_bx", "truth_by", "truth_bz"]].to_numpy()
    cal = tail[["flux_cal_x", "flux_cal_y", "flux_cal_z"]].to_numpy()
    assert np.sqrt(np.mean((cal - bt) ** 2)) < 400.0


def test_cli_compass_explicit_field(study_log, tmp_path):
    path, truth = study_log
    out = tmp_path / "out.csv"
    n, e, d = truth["earth_ned_nT"]
    f = float(np.sqrt(n * n + e * e + d * d))
    inc = float(np.degrees(np.arctan2(d, np.hypot(n, e))))
    dec = float(np.degrees(np.arctan2(e, n)))
    r = runner.invoke(app, ["compass", str(path), "-o", str(out), "--earth-field", str(f),
                            str(inc), str(dec)])
    assert r.exit_code == 0, r.output
    rep = json.loads(out.with_suffix(".json").read_text())
    assert rep["reference"]["source"] == "explicit"
    assert rep["reference"]["intensity_nT"] == pytest.approx(f)
    assert rep["forgetting"] == 0.975


def _bad(tmp_path, df, *args):
    path = tmp_path / "bad.csv"
    df.to_csv(path, index=False)
    out = tmp_path / "bad_out.csv"
    r = runner.invoke(app, ["compass", str(path), "-o", str(out), *args])
    assert r.exit_code == 1, r.output
    lines = [ln for ln in r.output.strip().splitlines() if ln]
    assert len(lines) == 1 and lines[0].startswith("error: "), r.output
    assert "Traceback" not in r.output
    assert not out.exists() and not out.with_suffix(".json").exists()
    return lines[0]


def test_bad_inputs_one_line_no_output(tmp_path):
    log, _ = simulate_compass(duration_s=4.0)
    log["lat"], log["lon"], log["alt"] = 37.87, 112.55, 800.0
    ef = ["--earth-field", "54000", "57", "-5"]
    msg = _bad(tmp_path, log.drop(columns=["pitch", "roll"]), *ef)
    assert "pitch" in msg and "roll" in msg
    msg = _bad(tmp_path, log.drop(columns=["lat", "lon", "alt"]), "--date", "2017-07-01")
    assert "--earth-field" in msg
    msg = _bad(tmp_path, log, "--date", "2031-03-01")
    assert "IGRF" in msg and "bad.csv" in msg
    msg = _bad(tmp_path, log, "--date", "2017-07-01", "--forgetting", "0")
    assert "(0, 1]" in msg
    msg = _bad(tmp_path, log, *ef, "--forgetting", "1.5")
    assert "(0, 1]" in msg
    msg = _bad(tmp_path, log.iloc[:8], *ef)
    assert "12" in msg
    msg = _bad(tmp_path, log.drop(columns=["flux_z"]), *ef)
    assert "flux_z" in msg


def test_cli_compass_subprocess(study_log, tmp_path):
    path, _ = study_log
    out = tmp_path / "sub.csv"
    r = subprocess.run([sys.executable, "-m", "aeromag", "compass", str(path), "-o", str(out),
                        "--earth-field", "54105", "57.09", "-5.34", "--forgetting", "0.96"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "heading error RMS" in r.stdout
    rep = json.loads(out.with_suffix(".json").read_text())
    assert len(rep["matrix"]) == 3 and len(rep["offset_nT"]) == 3


def test_excitation_windows_match_direct_statistics():
    from aeromag.compass import excitation_windows

    log, truth = simulate_compass(amplitude_deg=30.0, seed=4, duration_s=12.0)
    t = log["time"].to_numpy()
    hdg = log["heading"].to_numpy().copy()
    hdg[30] = np.nan  # a row without attitude (another sensor's row)
    b = reference_in_body(np.array(truth["earth_ned_nT"]), hdg, log["pitch"], log["roll"])
    keep = np.ones(len(t), bool)
    keep[252:520] = False  # a gap: the second window keeps 2 samples and is skipped
    wins = excitation_windows(t[keep], hdg[keep], log["pitch"].to_numpy()[keep],
                              log["roll"].to_numpy()[keep], b[keep], window_s=5.0)
    assert [w.start_time for w in wins] == [0.0, 10.4]
    for w in wins:
        s = (t >= w.start_time) & (t <= w.end_time) & keep
        u = b[s] / np.linalg.norm(b[s], axis=1, keepdims=True)
        u = u[np.isfinite(u).all(axis=1)]
        assert w.excitation == pytest.approx(np.sqrt(np.linalg.eigvalsh(np.cov(u.T))[0]),
                                             rel=1e-6)
        r = log["roll"].to_numpy()[s]
        assert w.roll_range_deg == pytest.approx(r.max() - r.min())
        assert np.isfinite(w.heading_range_deg) and w.heading_range_deg > 0
    full = excitation_windows(t, hdg, log["pitch"].to_numpy(), log["roll"].to_numpy(), b)
    assert [w.n for w in full] == [250, 250, 100]
    for w in full:
        s = (t >= w.start_time) & (t <= w.end_time)
        p = log["pitch"].to_numpy()[s]
        assert w.pitch_range_deg == pytest.approx(p.max() - p.min())


# -- multi-rate logs ---------------------------------------------------------------------------

def test_multirate_log_interpolates_attitude_to_magnetometer_rows():
    """Attitude and magnetometer rows interleaved (interface: empty cells where a sensor has
    no sample): the attitude is interpolated to the magnetometer rows, and the heading error
    after convergence is that of the single-rate log.  Before: 'only 0 samples'."""
    from aeromag.workflows.compass import compass_frame

    log, truth = simulate_compass(amplitude_deg=40.0, seed=1, duration_s=20.0, switch_s=None)
    m = np.array(truth["earth_ned_nT"])
    ef = (float(np.linalg.norm(m)), float(np.degrees(np.arctan2(m[2], np.hypot(m[0], m[1])))),
          float(np.degrees(np.arctan2(m[1], m[0]))))
    _, rep1, res1 = compass_frame(log, forgetting=0.975, earth_field=ef)
    att = log[["time", "heading", "pitch", "roll"]].iloc[0::2]
    mag = log[["time", *FLUX]].iloc[1::2]
    mr = pd.concat([att, mag]).sort_values("time").reset_index(drop=True)
    mr.loc[mr["heading"].notna(), "heading"] %= 360.0
    out, rep, _ = compass_frame(mr, forgetting=0.975, earth_field=ef)
    magrow = out["flux_x"].notna().to_numpy().copy()
    # the last row is a magnetometer row with no attitude after it: never extrapolated
    assert rep.metrics.n_attitude_interpolated == magrow.sum() - 1
    magrow[-1] = False
    assert out.loc[magrow, ["flux_cal_x", "mag_heading_cal", "heading_err_deg"]].notna().all().all()
    t = out["time"].to_numpy()
    late = magrow & (t > 10)
    rms = np.sqrt(np.mean(out["heading_err_deg"].to_numpy()[late] ** 2))
    t1 = log["time"].to_numpy()
    rms1 = np.sqrt(np.mean(res1.heading_err_deg[t1 > 10] ** 2))
    assert rms < 1.5 * rms1 + 0.05


def test_attitude_not_interpolated_across_a_gap():
    from aeromag.compass import attitude_at_samples

    t = np.array([0.0, 0.01, 0.02, 0.5, 1.0])
    h = np.array([359.0, np.nan, 1.0, np.nan, 3.0])
    p = np.array([0.0, np.nan, 2.0, np.nan, 2.0])
    want = np.array([False, True, False, True, False])
    hh, pp, rr, filled = attitude_at_samples(t, h, p, p, want)
    assert filled.tolist() == [False, True, False, False, False]
    assert hh[1] == pytest.approx(0.0, abs=1e-9) and pp[1] == pytest.approx(1.0)
    assert np.isnan(hh[3])


def test_step_and_run_one_sequential_convention():
    """step(y, u) and run(ys, us): the same state [D, e nT], std and a-priori innovation, and
    the innovation is the expected field minus the calibrated one."""
    log, truth = simulate_compass(duration_s=4.0, seed=3)
    b = log[["truth_bx", "truth_by", "truth_bz"]].to_numpy()
    flux = log[FLUX].to_numpy()
    f0 = float(np.linalg.norm(truth["earth_ned_nT"]))
    a = CompassCalibration(0.96, field_scale_nT=f0)
    steps = [a.step(q, f) for f, q in zip(flux, b, strict=True)]
    res = CompassCalibration(0.96, field_scale_nT=f0).run(b, flux)
    assert res.state_names[0] == "D_xx" and res.state_names[-1] == "e_z_nT"
    np.testing.assert_allclose(np.array([s.state for s in steps]), res.state, atol=1e-6)
    np.testing.assert_allclose(np.array([s.std for s in steps]), res.std, rtol=1e-6)
    np.testing.assert_allclose(np.array([s.innovation for s in steps]), res.innovation,
                               atol=1e-6)
    np.testing.assert_allclose(res.innovation, b - res.info["flux_cal_nT"], atol=1e-6)
    np.testing.assert_allclose(res.state[-1, :9].reshape(3, 3), a.matrix, atol=1e-9)
    assert res.innovations["field"].n_fused == len(b)
