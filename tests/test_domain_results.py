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


# --------------------------------------------------------------------------- compass
def _compass_log():
    import numpy as np

    from aeromag.synthetic.compass import simulate_compass

    log, truth = simulate_compass(amplitude_deg=40.0, seed=1, duration_s=20.0, switch_s=None)
    m = np.array(truth["earth_ned_nT"])
    ef = (float(np.linalg.norm(m)), float(np.degrees(np.arctan2(m[2], np.hypot(m[0], m[1])))),
          float(np.degrees(np.arctan2(m[1], m[0]))))
    return log, ef


def test_heading_error_stats_are_typed():
    import numpy as np

    from aeromag.compass import HeadingErrorStats, heading_error_stats

    s = heading_error_stats(np.array([1.0, -3.0, np.nan]))
    assert s == HeadingErrorStats(rms_deg=np.sqrt(5.0), mean_deg=-1.0, max_abs_deg=3.0)
    assert list(s.to_dict()) == ["heading_err_rms_deg", "heading_err_mean_deg",
                                 "heading_err_max_abs_deg"]
    assert HeadingErrorStats.from_dict(s.to_dict()) == s
    assert heading_error_stats(np.array([np.nan])) == HeadingErrorStats()


def test_compass_file_returns_the_typed_report_it_writes(tmp_path):
    from aeromag.compass import CompassReport
    from aeromag.workflows.compass import compass_file, compass_frame

    log, ef = _compass_log()
    log.to_csv(tmp_path / "log.csv", index=False)
    rep = compass_file(tmp_path / "log.csv", tmp_path / "out.csv", earth_field=ef)
    assert isinstance(rep, CompassReport)
    assert rep.metrics.n_samples == len(log) and rep.metrics.rms_deg is not None
    assert rep.excitation.n_windows == len(rep.excitation.windows) == 4
    doc = json.loads((tmp_path / "out.json").read_text())
    assert list(doc) == ["input", "matrix", "offset_nT", "forgetting", "alpha", "reference",
                         "metrics", "excitation", "history", "warnings"]
    assert list(doc["metrics"]) == ["heading_err_rms_deg", "heading_err_mean_deg",
                                    "heading_err_max_abs_deg", "n_samples", "n_skipped",
                                    "n_attitude_interpolated"]
    assert doc == json.loads(json.dumps(rep.to_dict()))
    assert CompassReport.from_dict(doc).to_dict() == doc
    # the in-memory run says the same as the library's calibration
    _, mem, res = compass_frame(log, earth_field=ef)
    assert mem.metrics.rms_deg == res.metrics.rms_deg == rep.metrics.rms_deg


def test_compass_cli_summary_reads_the_report(tmp_path):
    from typer.testing import CliRunner

    from aeromag.cli import app

    log, ef = _compass_log()
    log.to_csv(tmp_path / "log.csv", index=False)
    r = CliRunner().invoke(app, ["compass", str(tmp_path / "log.csv"), "-o",
                                 str(tmp_path / "o.csv"), "--earth-field",
                                 *(str(v) for v in ef)])
    assert r.exit_code == 0, r.output
    m = json.loads((tmp_path / "o.json").read_text())["metrics"]
    assert (f"heading error RMS {m['heading_err_rms_deg']:.2f} deg, mean "
            f"{m['heading_err_mean_deg']:.2f} deg") in r.output


# --------------------------------------------------------------------------- batch
def test_batch_job_and_file_result_are_typed_and_picklable(tmp_path):
    import pickle
    from dataclasses import asdict

    from aeromag.compensation.config import CompensationConfig
    from aeromag.workflows.batch import process_file
    from aeromag.workflows.batch_jobs import BatchJob, FileResult

    job = BatchJob(input=str(tmp_path / "missing.csv"), out_dir=str(tmp_path / "out"),
                   cfg=CompensationConfig(), plan=str(tmp_path / "plan.csv"))
    assert pickle.loads(pickle.dumps(job)) == job
    res = process_file(job)
    assert isinstance(res, FileResult) and res.input == job.input
    assert res.status == "failed" and "missing.csv" in res.error and res.outputs == []
    assert " | track: " in res.error and "plan.csv" in res.error   # both steps ran
    assert FileResult(**asdict(res)) == res   # the row batch_summary.json writes
    lost = FileResult.failure(job, "worker failed")
    assert (lost.input, lost.status, lost.error) == (job.input, "failed", "worker failed")


# --------------------------------------------------------------------------- level
def test_mistie_spreads_are_typed_and_written_as_before():
    import aeromag as am
    from aeromag.survey.crossings import MistieStd
    from aeromag.synthetic.level_survey import simulate_level_survey

    df, _, _ = simulate_level_survey(0)
    res = am.level(df.drop(columns=[c for c in df.columns if c.startswith("truth_")]),
                   igrf=False, method="shift", decorrugate=True)
    std, rob = res.mistie_std_nT, res.mistie_robust_std_nT
    assert isinstance(std, MistieStd) and std.before > std.after
    assert rob.before is not None and rob.after <= rob.before
    rep = res.to_report()
    assert rep["mistie_std_nT"] == {"before": std.before, "after": std.after}
    assert MistieStd.from_dict(rep["mistie_robust_std_nT"]) == rob
    dec = res.decorrugation
    assert isinstance(dec.mistie_robust_std_nT, MistieStd)
    assert dec.to_dict()["mistie_robust_std_nT"] == dec.mistie_robust_std_nT.to_dict()
    assert "mistie_std_nT" in repr(res)
    assert MistieStd().to_dict() == {"before": None, "after": None}


# --------------------------------------------------------------------------- navigate
def test_navigation_report_is_typed_and_its_json_round_trips(tmp_path):
    from aeromag.io import write_csv
    from aeromag.nav import NavReport
    from aeromag.synthetic.quadrotor import simulate_quadrotor
    from aeromag.workflows.navigate import navigate_file

    flight = simulate_quadrotor("rectangle", seed=11, duration_s=12.0)
    write_csv(flight.log, tmp_path / "log.csv")
    res = navigate_file(tmp_path / "log.csv", tmp_path / "out.csv", gps="use")
    rep = res.report
    assert isinstance(rep, NavReport) and rep.input == str(tmp_path / "log.csv")
    assert rep.sensors == rep.settings["sensors"] and "gps_pos" in rep.innovations
    doc = json.loads((tmp_path / "out.json").read_text())
    assert list(doc) == ["gps", "settings", "innovations", "mean_nis", "reference_field",
                         "ground_d_m", "mag_bias_deg", "imu_interval_s", "warnings", "input"]
    assert doc == json.loads(json.dumps(rep.to_dict()))
    assert json.loads(json.dumps(NavReport.from_dict(doc).to_dict())) == doc
    assert NavReport.from_dict({**doc, "x": 1}).extra == {"x": 1}
