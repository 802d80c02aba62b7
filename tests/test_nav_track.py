"""``aeromag track --navigate``: the navigated position where the GNSS has gaps, and the
filter's attitude (without the magnetometer) for the heading detector when the log has no
INS heading."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from aeromag._core.geodesy import ned_to_geodetic
from aeromag.cli import app
from aeromag.io import write_csv
from aeromag.nav.pipeline import track_inputs
from aeromag.synthetic.quadrotor import SITE, simulate_quadrotor

runner = CliRunner()


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("navtrack")
    fl = simulate_quadrotor("rectangle", seed=4, duration_s=60.0)
    log = fl.log.copy()
    gap = (log["time"] > 20) & (log["time"] < 40)
    for c in ("lat", "lon", "alt", "vel_n", "vel_e", "vel_d"):
        log.loc[gap, c] = np.nan                   # a 20 s GNSS outage
    corners = np.array([[0, 0, -2], [20, 0, -2], [20, 10, -2], [0, 10, -2], [0, 0, -2.0]])
    plan = pd.DataFrame(ned_to_geodetic(corners, SITE), columns=["lat", "lon", "alt"])
    write_csv(log, d / "log.csv")
    plan.to_csv(d / "plan.csv", index=False)
    return d, log, fl


def test_track_inputs_fill_gaps_and_heading(files):
    _, log, fl = files
    ti = track_inputs(log, source="sim")
    lat, lon, alt = ti.position
    assert np.isfinite(lat).all() and np.isfinite(lon).all() and np.isfinite(alt).all()
    fix = np.isfinite(log["lat"].to_numpy())
    assert ti.info["n_rows_filled"] == int((~fix).sum())
    np.testing.assert_array_equal(lat[fix], log["lat"].to_numpy()[fix])   # fixes kept
    # In the gap the navigated position follows the truth to well under a metre.
    gap = (log["time"] > 20) & (log["time"] < 40)
    e = np.hypot((lat[gap] - fl.truth["lat"][gap]) * 111_000,
                 (lon[gap] - fl.truth["lon"][gap]) * 111_000 * np.cos(np.deg2rad(SITE[0])))
    assert e.mean() < 1.0
    # No INS heading in the log: the yaw of a run without the magnetometer, and its tilt.
    assert ti.info["heading_from"].startswith("navigation filter without")
    dy = (ti.heading_deg - fl.truth["yaw_deg"] + 180) % 360 - 180
    assert np.abs(dy[log["time"] > 2]).mean() < 3.0
    assert set(ti.columns) == {"pitch", "roll"}


def test_cli_track_navigate(files):
    d, log, _ = files
    out = d / "track.csv"
    r = runner.invoke(app, ["track", str(d / "log.csv"), "--plan", str(d / "plan.csv"), "-o",
                            str(out), "--navigate", "--threshold", "10"])
    assert r.exit_code == 0, r.output
    rep = json.loads(out.with_suffix(".json").read_text())
    assert rep["navigation"]["n_rows_filled"] > 0
    assert rep["navigation"]["added_columns"] == ["pitch", "roll"]
    assert rep["heading_detector"]["available"]
    df = pd.read_csv(out)
    gap = (df["time"] > 20) & (df["time"] < 40)
    # Checked through the outage (rows on a leg; turns and ramps belong to none).
    assert df.loc[gap, "xtrack_m"].notna().mean() > 0.5
    assert df.loc[gap, "xtrack_m"].max() < 10.0
    # Without --navigate the same log has no heading detector (no attitude columns).
    out2 = d / "plain.csv"
    r = runner.invoke(app, ["track", str(d / "log.csv"), "--plan", str(d / "plan.csv"), "-o",
                            str(out2), "--threshold", "10"])
    assert r.exit_code == 0, r.output
    assert not json.loads(out2.with_suffix(".json").read_text())["heading_detector"]["available"]
    assert pd.read_csv(out2).loc[gap, "xtrack_m"].isna().all()   # nothing to check there


def test_track_navigate_without_imu_is_a_one_line_error(files, tmp_path):
    d, log, _ = files
    p = tmp_path / "noimu.csv"
    write_csv(log.drop(columns=["acc_x", "acc_y", "acc_z"]), p)
    r = runner.invoke(app, ["track", str(p), "--plan", str(d / "plan.csv"), "-o",
                            str(tmp_path / "o.csv"), "--navigate"])
    assert r.exit_code == 1
    assert r.output.count("error:") == 1 and "acc_x" in r.output and "Traceback" not in r.output
