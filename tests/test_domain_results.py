"""Typed results between the layers of the domain commands (issue 26 item 5).

Each result is a dataclass the command line, the plots and the workflows read by attribute;
``to_dict()`` is exactly the JSON the command writes and ``from_dict()`` reads it back.
"""

from __future__ import annotations

import json

import pytest

from aeromag.synthetic import simulate_mission
from aeromag.track import LegSummary, PassSummary, TrackReport, check_track


@pytest.fixture(scope="module")
def mission():
    df, plan, _ = simulate_mission(seed=4, line_m=120.0, n_lines=2, refly_legs=(1,))
    return df, plan


# --------------------------------------------------------------------------- track
def test_track_result_is_typed_and_its_json_round_trips(mission):
    df, plan = mission
    res = check_track(df, plan)
    rep = res.report
    assert isinstance(rep, TrackReport) and rep.legs is res.legs
    assert all(isinstance(row, LegSummary) for row in res.legs)
    assert all(isinstance(p, PassSummary) for row in res.legs for p in row.passes)
    assert rep.flagged_legs == [row.leg for row in res.legs if row.flagged]
    assert rep.n_flagged == len(rep.flagged_legs)
    assert rep.n_legs_checked == sum(row.checked for row in res.legs)
    doc = rep.to_dict()
    assert list(doc)[:4] == ["legs", "n_legs", "n_flagged", "flagged_legs"]
    assert doc["legs"][1]["passes"][0]["pass"] == res.legs[1].passes[0].pass_number == 1
    row = doc["legs"][0]
    assert list(row)[8:11] == ["first_alarm_time", "first_track_alarm_time",
                               "first_heading_alarm_time"]
    assert row["first_track_alarm_time"] == res.legs[0].first_alarm_times["track"]
    text = json.dumps(doc)
    back = TrackReport.from_dict(json.loads(text))
    assert json.dumps(back.to_dict()) == text
    assert back.legs == res.legs


def test_track_file_writes_the_report_and_reads_back(mission, tmp_path):
    from aeromag.workflows.track import track_file

    df, plan = mission
    df.to_csv(tmp_path / "log.csv", index=False)
    plan.to_csv(tmp_path / "plan.csv", index=False)
    res = track_file(tmp_path / "log.csv", tmp_path / "plan.csv", tmp_path / "out.csv")
    doc = json.loads((tmp_path / "out.json").read_text())
    assert doc == json.loads(json.dumps(res.report.to_dict()))
    assert list(doc)[-3:] == ["input", "plan", "plan_format"]
    back = TrackReport.from_dict(doc)
    assert back.input == str(tmp_path / "log.csv") and back.plan_format == "csv"
    assert back.to_dict() == doc


def test_unknown_keys_of_a_read_track_report_are_kept():
    leg = {"leg": 0, "n_samples": 0, "checked": False, "t_start": None, "t_end": None,
           "max_xtrack_m": None, "max_abs_xtrack_h_m": None, "max_abs_xtrack_v_m": None,
           "first_alarm_time": None, "first_track_alarm_time": None,
           "first_pf_alarm_time": None, "time_above_threshold_s": 0.0, "flagged": False,
           "first_detector": None}
    row = LegSummary.from_dict(leg)
    assert row.first_alarm_times == {"track": None, "pf": None} and row.passes is None
    assert row.to_dict() == leg
    doc = {**TrackReport(legs=[row], n_legs=1).to_dict(), "other_tool": {"x": 1}}
    assert TrackReport.from_dict(doc).extra == {"other_tool": {"x": 1}}
    assert TrackReport.from_dict(doc).to_dict() == doc


# --------------------------------------------------------------------------- detect
def test_detect_file_returns_the_typed_report_it_writes(mission, tmp_path):
    from aeromag.detection.report import EVENTS_NOTE, DetectReport
    from aeromag.workflows.detect import detect_file

    df, _ = mission
    df.to_csv(tmp_path / "log.csv", index=False)
    rep = detect_file(tmp_path / "log.csv", tmp_path / "out.csv", n_particles=50, window=10)
    assert isinstance(rep, DetectReport)
    assert rep.particles == 50 and rep.window == 10 and rep.events_note == EVENTS_NOTE
    assert rep.threshold_source == rep.settings["threshold_source"] == "calm"
    assert rep.n_samples == len(df) and rep.n_stat <= rep.n_samples
    text = (tmp_path / "out.json").read_text()
    doc = json.loads(text)
    assert list(doc) == ["input", "threshold", "window", "particles", "events", "events_note",
                         "n_alarms", "n_samples", "n_stat", "settings", "warnings"]
    assert doc == json.loads(json.dumps(rep.to_dict()))
    assert DetectReport.from_dict(doc).to_dict() == doc


def test_detect_cli_summary_reads_the_report(mission, tmp_path):
    from typer.testing import CliRunner

    from aeromag.cli import app

    df, _ = mission
    df.to_csv(tmp_path / "log.csv", index=False)
    r = CliRunner().invoke(app, ["detect", str(tmp_path / "log.csv"), "-o",
                                 str(tmp_path / "o.csv"), "--particles", "50",
                                 "--threshold", "1e6"])
    assert r.exit_code == 0, r.output
    n = len(json.loads((tmp_path / "o.json").read_text())["events"])
    assert f": {n} alarm event(s), threshold 1000000.00 (given)" in r.output
