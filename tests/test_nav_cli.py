"""``aeromag navigate`` through typer's CliRunner and as a real process; bad inputs give one
line (error or warning with the remedy), never a traceback or a NaN-filled output."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.io import write_csv
from aeromag.nav import ALL_SENSORS, NAV_COLUMNS
from aeromag.synthetic.quadrotor import FIELD_NED_NT, simulate_quadrotor

runner = CliRunner()
F = float(np.linalg.norm(FIELD_NED_NT))
INC = float(np.rad2deg(np.arcsin(FIELD_NED_NT[2] / F)))
DEC = float(np.rad2deg(np.arctan2(FIELD_NED_NT[1], FIELD_NED_NT[0])))
FIELD = ["--earth-field", f"{F}", f"{INC}", f"{DEC}"]


@pytest.fixture(scope="module")
def flight():
    return simulate_quadrotor("rectangle", seed=11, duration_s=12.0)


@pytest.fixture(scope="module")
def log_csv(flight, tmp_path_factory):
    p = tmp_path_factory.mktemp("nav") / "flight.csv"
    write_csv(flight.log, p)
    return p


def _write(df, tmp_path, name="bad.csv"):
    p = tmp_path / name
    write_csv(df, p)
    return p


def _one_line_error(r, *words):
    assert r.exit_code == 1, r.output
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    err = [ln for ln in lines if ln.startswith("error:")]
    assert len(err) == 1, r.output
    assert "Traceback" not in r.output
    for w in words:
        assert w in err[0], err[0]
    return err[0]


def test_cli_navigate_outputs(log_csv, flight, tmp_path):
    out = tmp_path / "nav.csv"
    r = runner.invoke(app, ["navigate", str(log_csv), "-o", str(out), "--gps", "none", *FIELD])
    assert r.exit_code == 0, r.output
    assert "mean NIS/dof" in r.output
    df = pd.read_csv(out)
    src = pd.read_csv(log_csv)
    assert len(df) == len(src)
    assert list(df.columns[: len(src.columns)]) == list(src.columns)
    assert list(df.columns[len(src.columns):]) == list(NAV_COLUMNS)
    assert np.isfinite(df[list(NAV_COLUMNS)].to_numpy()).all()
    assert df["nav_yaw"].between(0, 360, inclusive="left").all()
    rep = json.loads(out.with_suffix(".json").read_text())
    assert rep["gps"]["mode"] == "none" and rep["gps"]["n_fixes_used"] == 1
    assert rep["gps"]["origin"] == pytest.approx(src[["lat", "lon", "alt"]].dropna().iloc[0])
    assert {"settings", "innovations", "mean_nis", "warnings"} <= set(rep)
    assert rep["mean_nis"]["flow"] > 0 and rep["innovations"]["flow"]["dof"] == 2
    assert rep["reference_field"]["source"]["source"] == "explicit"
    # The navigated track follows the truth (displacement since the start).
    t = flight.truth
    e = (df[["nav_n_m", "nav_e_m"]].to_numpy() - df[["nav_n_m", "nav_e_m"]].to_numpy()[1]
         - (t[["n_m", "e_m"]].to_numpy() - t[["n_m", "e_m"]].to_numpy()[1]))
    assert np.hypot(*e.T).mean() < 0.5


def test_cli_gps_use_and_outage(log_csv, tmp_path):
    out = tmp_path / "use.csv"
    r = runner.invoke(app, ["navigate", str(log_csv), "-o", str(out), *FIELD])
    assert r.exit_code == 0, r.output
    rep = json.loads(out.with_suffix(".json").read_text())
    assert rep["gps"]["mode"] == "use" and len(rep["gps"]["intervals"]) == 1
    assert rep["innovations"]["gps_pos"]["n_fused"] > 50
    out2 = tmp_path / "gap.csv"
    r = runner.invoke(app, ["navigate", str(log_csv), "-o", str(out2), "--gps", "4:8", *FIELD,
                            "--without", "baro"])
    assert r.exit_code == 0, r.output
    rep = json.loads(out2.with_suffix(".json").read_text())
    iv = rep["gps"]["intervals"]
    assert len(iv) == 2 and iv[0][1] < 4.0 and iv[1][0] >= 8.0
    assert rep["gps"]["mode"] == {"outage_s": [4.0, 8.0]}
    assert "baro" not in rep["settings"]["sensors"] and rep["settings"]["accel_bias"]
    assert "bax_ms2" in rep["settings"]["states"]          # the default estimates them
    out3 = tmp_path / "study.csv"
    r = runner.invoke(app, ["navigate", str(log_csv), "-o", str(out3), *FIELD,
                            "--no-accel-bias"])
    assert r.exit_code == 0, r.output
    rep = json.loads(out3.with_suffix(".json").read_text())
    assert not rep["settings"]["accel_bias"] and "bax_ms2" not in rep["settings"]["states"]


def test_navigate_as_a_real_process(log_csv, tmp_path):
    out = tmp_path / "p.csv"
    p = subprocess.run([sys.executable, "-m", "aeromag", "navigate", str(log_csv), "-o",
                        str(out), "--gps", "none", "--date", "2024-06-01"],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert out.exists() and out.with_suffix(".json").exists()
    rep = json.loads(out.with_suffix(".json").read_text())
    assert rep["reference_field"]["source"]["source"] == "IGRF"
    assert rep["reference_field"]["declination_deg"] == pytest.approx(DEC, abs=0.05)


def test_no_imu_columns_is_a_one_line_error(flight, tmp_path):
    p = _write(flight.log.drop(columns=["gyro_x", "gyro_y", "gyro_z"]), tmp_path)
    out = tmp_path / "o.csv"
    r = runner.invoke(app, ["navigate", str(p), "-o", str(out)])
    _one_line_error(r, str(p), "gyro_x", "--col")
    assert not out.exists() and not out.with_suffix(".json").exists()


def test_time_running_backwards_is_a_one_line_error(flight, tmp_path):
    df = flight.log.copy()
    df.loc[100, "time"] = df.loc[90, "time"]
    p = _write(df, tmp_path)
    out = tmp_path / "o.csv"
    r = runner.invoke(app, ["navigate", str(p), "-o", str(out)])
    _one_line_error(r, str(p), "time", "increasing")
    assert not out.exists()


def test_flow_without_range_warns_and_navigates_without_flow(flight, tmp_path):
    p = _write(flight.log.drop(columns=["range_m"]), tmp_path)
    out = tmp_path / "o.csv"
    r = runner.invoke(app, ["navigate", str(p), "-o", str(out), *FIELD])
    assert r.exit_code == 0, r.output
    assert "without range_m" in r.output and "--col range_m=" in r.output
    assert "Traceback" not in r.output
    rep = json.loads(out.with_suffix(".json").read_text())
    assert "flow" not in rep["settings"]["sensors"]
    assert any("without range_m" in w for w in rep["warnings"])
    assert np.isfinite(pd.read_csv(out)[list(NAV_COLUMNS)].to_numpy()).all()


def test_gyro_in_degrees_per_second_warns_with_the_units_remedy(flight, tmp_path):
    df = flight.log.copy()
    for c in ("gyro_x", "gyro_y", "gyro_z"):
        df[c] = np.rad2deg(df[c])
    df.loc[df["gyro_z"].notna().to_numpy().nonzero()[0][200:400], "gyro_z"] += 45.0
    p = _write(df, tmp_path)
    out = tmp_path / "o.csv"
    r = runner.invoke(app, ["navigate", str(p), "-o", str(out), *FIELD])
    assert "Traceback" not in r.output
    assert "--units gyro=deg/s" in r.output
    if r.exit_code == 0:
        assert np.isfinite(pd.read_csv(out)[list(NAV_COLUMNS)].to_numpy()).all()
    else:
        _one_line_error(r, "diverged")
    # The remedy works: the converted log gives the rad/s log's answer.
    out2 = tmp_path / "fixed.csv"
    df2 = flight.log.copy()
    for c in ("gyro_x", "gyro_y", "gyro_z"):
        df2[c] = np.rad2deg(df2[c])
    p2 = _write(df2, tmp_path, "deg.csv")
    r = runner.invoke(app, ["navigate", str(p2), "-o", str(out2), *FIELD, "--units",
                            "gyro=deg/s"])
    assert r.exit_code == 0, r.output
    ref = tmp_path / "ref.csv"
    r = runner.invoke(app, ["navigate", str(_write(flight.log, tmp_path, "rad.csv")), "-o",
                            str(ref), *FIELD])
    a, b = pd.read_csv(out2), pd.read_csv(ref)
    np.testing.assert_allclose(a["nav_n_m"], b["nav_n_m"], atol=1e-6)


def test_a_diverging_filter_ends_with_one_line(flight, tmp_path):
    df = flight.log.copy()
    k = df["acc_x"].notna().to_numpy().nonzero()[0]
    df.loc[k[500:], "acc_x"] = 5.0e4          # a broken accelerometer
    p = _write(df, tmp_path)
    out = tmp_path / "o.csv"
    r = runner.invoke(app, ["navigate", str(p), "-o", str(out), *FIELD])
    _one_line_error(r, str(p), "diverged at t =", "s")
    assert not out.exists() and not out.with_suffix(".json").exists()


@pytest.mark.parametrize("args,words", [
    (["--gps", "sometimes"], ["--gps", "T0:T1"]),
    (["--gps", "9:3"], ["T1 > T0"]),
    (["--without", "sonar"], ["--without sonar", "range"]),
    (["--range-limits", "5", "1"], ["--range-limits MIN MAX"]),
    (["--units", "gyro=furlongs"], ["--units gyro=furlongs", "deg/s"]),
])
def test_bad_options_are_one_line_errors(log_csv, tmp_path, args, words):
    out = tmp_path / "o.csv"
    r = runner.invoke(app, ["navigate", str(log_csv), "-o", str(out), *args])
    _one_line_error(r, *words)
    assert not out.exists()


def test_date_without_any_position_is_a_one_line_error(flight, tmp_path):
    p = _write(flight.log.drop(columns=["lat", "lon", "alt", "vel_n", "vel_e", "vel_d"]),
               tmp_path)
    out = tmp_path / "o.csv"
    r = runner.invoke(app, ["navigate", str(p), "-o", str(out), "--date", "2024-06-01"])
    _one_line_error(r, "--origin")
    # With --origin it runs; without GNSS the frame starts at the origin.
    r = runner.invoke(app, ["navigate", str(p), "-o", str(out), "--date", "2024-06-01",
                            "--origin", "59.9", "10.75", "102"])
    assert r.exit_code == 0, r.output
    df = pd.read_csv(out)
    assert np.isfinite(df[list(NAV_COLUMNS)].to_numpy()).all()
    assert df["nav_lat"].iloc[0] == pytest.approx(59.9, abs=1e-6)


def test_no_gnss_and_no_origin_leaves_geodetic_columns_empty(flight, tmp_path):
    p = _write(flight.log.drop(columns=["lat", "lon", "alt", "vel_n", "vel_e", "vel_d"]),
               tmp_path)
    out = tmp_path / "o.csv"
    r = runner.invoke(app, ["navigate", str(p), "-o", str(out), *FIELD])
    assert r.exit_code == 0, r.output
    df = pd.read_csv(out)
    assert df["nav_lat"].isna().all()
    rest = [c for c in NAV_COLUMNS if c not in ("nav_lat", "nav_lon", "nav_alt")]
    assert np.isfinite(df[rest].to_numpy()).all()
    assert df["nav_n_m"].iloc[0] == pytest.approx(0.0, abs=1e-6)


def test_cli_sensor_names_match_the_filter():
    from aeromag.cli.navigate import SENSORS

    assert tuple(SENSORS) == tuple(ALL_SENSORS)


def test_simulate_quadrotor_files_then_navigate(tmp_path):
    r = runner.invoke(app, ["simulate", "-o", str(tmp_path / "sim"), "--small", "--quadrotor"])
    assert r.exit_code == 0, r.output
    d = tmp_path / "sim"
    for name in ("quadrotor_hover.csv", "quadrotor_rectangle.csv", "quadrotor_hover_truth.csv",
                 "quadrotor_rectangle_truth.csv", "quadrotor_truth.json"):
        assert (d / name).stat().st_size > 0, name
    info = json.loads((d / "quadrotor_truth.json").read_text())
    assert info["hover"]["date"] == "2024-06-01"
    log = pd.read_csv(d / "quadrotor_hover.csv")
    truth = pd.read_csv(d / "quadrotor_hover_truth.csv")
    assert len(log) == len(truth) and (log["time"] == truth["time"]).all()
    assert log["gyro_x"].notna().sum() == 14999 and log["flow_x"].notna().sum() == 600
    out = tmp_path / "nav.csv"
    r = runner.invoke(app, ["navigate", str(d / "quadrotor_rectangle.csv"), "-o", str(out),
                            "--gps", "none", "--date", "2024-06-01"])
    assert r.exit_code == 0, r.output


def test_a_non_numeric_sensor_cell_is_a_one_line_error(flight, tmp_path):
    df = flight.log.copy().astype({"gyro_x": object})
    k = int(df["gyro_x"].notna().to_numpy().nonzero()[0][10])
    df.loc[k, "gyro_x"] = "n/a?"
    p = _write(df, tmp_path)
    r = runner.invoke(app, ["navigate", str(p), "-o", str(tmp_path / "o.csv")])
    _one_line_error(r, str(p), "gyro_x", "not a number")
