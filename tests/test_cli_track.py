"""``aeromag track`` through typer's CliRunner and as a real process."""

from __future__ import annotations

import json
import subprocess
import sys

import pandas as pd
import pytest
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.workflows.mission import write_mission_files

runner = CliRunner()


@pytest.fixture(scope="module")
def mission(tmp_path_factory):
    return write_mission_files(tmp_path_factory.mktemp("mission"), seed=1)


def test_cli_track_outputs(mission, tmp_path):
    out = tmp_path / "out.csv"
    r = runner.invoke(app, ["track", str(mission["mission"]), "--plan", str(mission["plan"]),
                            "-o", str(out), "--plot", str(tmp_path / "plots")])
    assert r.exit_code == 0, r.output
    assert "legs flagged" in r.output
    df = pd.read_csv(out, keep_default_na=False, dtype=str)
    src = pd.read_csv(mission["mission"])
    assert list(df.columns[: len(src.columns)]) == list(src.columns)
    for c in ("leg", "xtrack_m", "xtrack_h_m", "xtrack_v_m", "along_m", "track_alarm",
              "heading_diff_deg", "heading_alarm", "alarm"):
        assert c in df.columns
    assert set(df["alarm"]) <= {"true", "false"}
    off = df["leg"] == ""
    assert off.any() and (df.loc[off, "alarm"] == "false").all()
    rep = json.loads(out.with_suffix(".json").read_text())
    truth = json.loads(mission["truth"].read_text())
    assert len(rep["legs"]) == len(truth["legs"])
    for row, tl in zip(rep["legs"], truth["legs"], strict=True):
        assert {"leg", "max_xtrack_m", "first_alarm_time", "flagged"} <= set(row)
        assert row["flagged"] == (tl["disturbance"] is not None)
        if not row["flagged"]:
            assert row["first_alarm_time"] is None
    assert (tmp_path / "plots" / "track_map.png").stat().st_size > 0
    assert (tmp_path / "plots" / "track_timeseries.png").stat().st_size > 0


def test_cli_options(mission, tmp_path):
    out = tmp_path / "o.csv"
    r = runner.invoke(app, ["track", str(mission["mission"]), "--plan", str(mission["plan"]),
                            "-o", str(out), "--threshold", "50", "--combine", "and",
                            "--calm-window", "0:30", "--heading-sigmas", "6",
                            "--min-duration", "1"])
    assert r.exit_code == 0, r.output
    rep = json.loads(out.with_suffix(".json").read_text())
    assert rep["n_flagged"] == 0 and rep["combine"] == "and"


def _bad(tmp_path, mission, plan_text=None, log_df=None, extra=()):
    plan = mission["plan"]
    if plan_text is not None:
        plan = tmp_path / "plan.csv"
        plan.write_text(plan_text)
    log = mission["mission"]
    if log_df is not None:
        log = tmp_path / "log.csv"
        log_df.to_csv(log, index=False)
    out = tmp_path / "bad.csv"
    r = runner.invoke(app, ["track", str(log), "--plan", str(plan), "-o", str(out), *extra])
    assert r.exit_code != 0
    assert not out.exists() and not out.with_suffix(".json").exists()
    msg = r.output.strip()
    assert msg.startswith("error:") and "\n" not in msg and "Traceback" not in msg
    return msg


def test_bad_plans_and_logs(mission, tmp_path):
    assert "at least 2" in _bad(tmp_path, mission, "lat,lon,alt\n47.3,8.5,500\n")
    assert "zero-length" in _bad(tmp_path, mission,
                                 "lat,lon,alt\n47.3,8.5,500\n47.3,8.5,500\n47.31,8.5,500\n")
    assert "alt" in _bad(tmp_path, mission, "lat,lon\n47.3,8.5\n47.31,8.5\n")
    assert "plan.csv" in _bad(tmp_path, mission, "lat,lon,alt\n47.3,x,500\n47.31,8.5,500\n")
    src = pd.read_csv(mission["mission"]).head(400)
    msg = _bad(tmp_path, mission, log_df=src.drop(columns=["lat", "lon"]))
    assert "lat" in msg and "log.csv" in msg
    assert "--combine" in _bad(tmp_path, mission, extra=("--combine", "xor"))


def test_cli_subprocess(mission, tmp_path):
    out = tmp_path / "p.csv"
    cmd = [sys.executable, "-c", "from aeromag.cli import main; main()", "track",
           str(mission["mission"]), "--plan", str(mission["plan"]), "-o", str(out)]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert out.exists() and out.with_suffix(".json").exists()
    bad = subprocess.run(cmd[:3] + ["track", str(mission["mission"]), "--plan",
                                     str(tmp_path / "missing.csv"), "-o", str(out)],
                         capture_output=True, text=True, timeout=120)
    assert bad.returncode == 1 and bad.stderr.startswith("error:")
    assert len(bad.stderr.strip().splitlines()) == 1


def test_cli_sigma_floor_default_matches_the_library():
    from aeromag.cli import track as cli_track
    from aeromag.detection.heading import DEFAULT_SIGMA_FLOOR_DEG

    assert cli_track.DEFAULT_SIGMA_FLOOR_DEG == DEFAULT_SIGMA_FLOOR_DEG


def test_plan_errors_say_what_a_plan_needs(mission, tmp_path):
    msg = _bad(tmp_path, mission, "lat,lon\n47.3,8.5\n47.31,8.5\n")
    assert "--col" not in msg  # --col maps the log's columns, not the plan's
    assert "alt" in msg and "lat, lon (degrees" in msg and "one row per waypoint" in msg
    for text in ("", "\n\n", "\ufeff"):
        msg = _bad(tmp_path, mission, text)
        assert "plan.csv: the plan is empty" in msg and "expected a CSV log" not in msg
        assert "lat, lon (degrees" in msg


def test_output_never_overwrites_the_log_or_the_plan(mission, tmp_path):
    log = tmp_path / "log.csv"
    plan = tmp_path / "plan.csv"
    log.write_bytes(mission["mission"].read_bytes())
    plan.write_bytes(mission["plan"].read_bytes())
    before = (log.read_bytes(), plan.read_bytes())
    for out, what in ((log, "input log"), (plan, "plan"), (tmp_path / "x.json", ".json")):
        r = runner.invoke(app, ["track", str(log), "--plan", str(plan), "-o", str(out)])
        assert r.exit_code == 1, r.output
        msg = r.output.strip()
        assert msg.startswith("error:") and "\n" not in msg and what in msg, msg
    assert (log.read_bytes(), plan.read_bytes()) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["log.csv", "plan.csv"]


def test_cli_new_options_and_plots_in_the_report(mission, tmp_path):
    src = pd.read_csv(mission["mission"])
    plan = pd.read_csv(mission["plan"])
    rel = tmp_path / "rel.csv"
    src.assign(alt=src["alt"] - plan["alt"][0] + 40.0).to_csv(rel, index=False)
    out = tmp_path / "r.csv"
    r = runner.invoke(app, ["track", str(rel), "--plan", str(mission["plan"]), "-o", str(out),
                            "--heading-sigma-floor", "1.5", "--plot", str(tmp_path / "p")])
    assert r.exit_code == 0, r.output
    assert "1 warning(s) in r.json" in r.output
    rep = json.loads(out.with_suffix(".json").read_text())
    assert rep["altitude_offset"]["applied_m"] == pytest.approx(40.0 - plan["alt"][0], abs=0.1)
    assert rep["heading_detector"]["sigma_floor_deg"] == 1.5
    assert [p.rsplit("/", 1)[-1] for p in rep["plots"]] == ["track_map.png",
                                                            "track_timeseries.png"]
    out2 = tmp_path / "h.csv"
    r = runner.invoke(app, ["track", str(rel), "--plan", str(mission["plan"]), "-o", str(out2),
                            "--horizontal", "--altitude-offset", "none"])
    assert r.exit_code == 0, r.output
    rep2 = json.loads(out2.with_suffix(".json").read_text())
    assert rep2["distance"] == "horizontal" and rep2["flagged_legs"] == rep["flagged_legs"]
    r = runner.invoke(app, ["track", str(rel), "--plan", str(mission["plan"]), "-o",
                            str(tmp_path / "x.csv"), "--altitude-offset", "sea"])
    assert r.exit_code == 1 and "--altitude-offset" in r.output
    assert not (tmp_path / "x.csv").exists()


def test_cli_reversed_plan_warns(mission, tmp_path):
    plan = pd.read_csv(mission["plan"])
    rev = tmp_path / "rev.csv"
    plan.iloc[::-1].to_csv(rev, index=False)
    out = tmp_path / "o.csv"
    r = subprocess.run([sys.executable, "-m", "aeromag", "track", str(mission["mission"]),
                        "--plan", str(rev), "-o", str(out)], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    # checked along the reversed legs: the disturbed legs 2, 4, 6, 8 are legs 8, 6, 4, 2
    assert "reversed" in r.stderr and "4/11 legs flagged (2, 4, 6, 8)" in r.stdout
    assert "warning(s)" in r.stdout


def test_cli_summary_says_how_many_legs_were_checked(tmp_path):
    # The calibration box against the survey's 19-leg plan: one leg has flown rows.  "0/19 legs
    # flagged" alone read as a clean survey of 19 legs.
    from pathlib import Path

    samples = Path(__file__).resolve().parents[1] / "data_samples"
    out = tmp_path / "t.csv"
    r = runner.invoke(app, ["track", str(samples / "calibration.csv"), "--plan",
                            str(samples / "plan.csv"), "-o", str(out)])
    assert r.exit_code == 0, r.output
    rep = json.loads(out.with_suffix(".json").read_text())
    n, checked = rep["n_legs"], rep["n_legs_checked"]
    assert checked < n
    assert (f"0 of {checked} checked leg{'s' if checked != 1 else ''} flagged"
            f" ({n - checked} of {n} not flown" in r.output)
    assert f"0/{n} legs flagged" not in r.output
