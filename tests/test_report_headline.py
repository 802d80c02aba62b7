"""One headline everywhere, and FOM windows that stay on their line (review of the QC report).

Before: ``aeromag report`` on the calibration sample headlined its own per-piece rms ratio
(282.43 / 0.00798 nT) while OUT.json ``metrics`` and the CLI said 277.28 / 0.00782 nT; the W roll
window ran 259.0-280.4 s into the dropped line 9 (a scalar drift), ptp_after 2.37 nT against
0.03-0.05 nT for the other kept manoeuvres.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from aeromag.cli import app

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "data_samples"
HEAD = ("improvement_ratio", "residual_std_nT", "std_before_nT", "n_samples")
ALL = {"improvement_ratio": "all_improvement_ratio", "residual_std_nT": "all_residual_std_nT",
       "std_before_nT": "all_std_before_nT", "n_samples": "all_n_samples"}

runner = CliRunner()


@pytest.fixture(scope="module")
def cal_report(tmp_path_factory):
    """The calibration sample self-compensated and reported by the real CLI (subprocesses)."""
    d = tmp_path_factory.mktemp("headline")
    shutil.copy(SAMPLES / "calibration.csv", d / "calibration.csv")
    for argv in (["compensate", "calibration.csv", "-o", "cal.csv"],
                 ["report", "cal.csv", "-o", "rep"]):
        r = subprocess.run([sys.executable, "-m", "aeromag", *argv], cwd=d, capture_output=True,
                           text=True, timeout=600)
        assert r.returncode == 0, r.stderr
    out = json.loads((d / "cal.json").read_text())
    qc = json.loads((d / "rep" / "qc.json").read_text())
    html = (d / "rep" / "report.html").read_text()
    return d, out, qc, html


def _assert_same_headline(qc: dict, metrics: dict) -> None:
    for k in HEAD:
        assert qc[k] == metrics[k], k
        assert qc["all_data"][k] == metrics[ALL[k]], k
    assert qc["definition"] == metrics["definition"]


def test_report_headline_is_out_json_metrics_exactly(cal_report):
    _, out, qc, html = cal_report
    _assert_same_headline(qc, out["metrics"])
    _assert_same_headline(out["qc"], out["metrics"])
    # the per-piece rms figures are kept, under their own names and definition
    pp = qc["per_piece_rms"]
    assert set(pp["kept"]) == {"per_piece_rms_ratio", "per_piece_rms_after_nT",
                               "per_piece_rms_before_nT", "n_samples"}
    assert "not the improvement ratio" in pp["definition"]
    assert pp["kept"]["per_piece_rms_ratio"] != qc["improvement_ratio"]  # a different figure
    assert f"{out['metrics']['improvement_ratio']:.4g}" in html
    assert f"{pp['kept']['per_piece_rms_ratio']:.4g}" not in html
    assert qc["noise"]["band_std_after_nT"] == out["metrics"]["all_residual_std_nT"]


def test_report_headline_survey_with_model(tmp_path):
    """A saved model on the survey sample: report (CliRunner) and OUT.json say the same."""
    shutil.copy(SAMPLES / "survey.csv", tmp_path / "survey.csv")
    shutil.copy(SAMPLES / "calibration.csv", tmp_path / "calibration.csv")
    for argv in (["calibrate", str(tmp_path / "calibration.csv"), "-o", str(tmp_path / "m.json")],
                 ["compensate", str(tmp_path / "survey.csv"), "--model", str(tmp_path / "m.json"),
                  "-o", str(tmp_path / "s.csv")],
                 ["report", str(tmp_path / "s.csv"), "-o", str(tmp_path / "rep")]):
        r = runner.invoke(app, argv)
        assert r.exit_code == 0, r.output
    out = json.loads((tmp_path / "s.json").read_text())
    qc = json.loads((tmp_path / "rep" / "qc.json").read_text())
    _assert_same_headline(qc, out["metrics"])
    _assert_same_headline(out["qc"], out["metrics"])


def test_fom_windows_never_span_two_lines(cal_report):
    """Every manoeuvre lies on one line; the W roll no longer samples dropped line 9."""
    d, out, qc, _ = cal_report
    data = pd.read_csv(d / "cal.csv")
    t, line = data["time"].to_numpy(float), data["line"].to_numpy()
    fom = qc["fom"]
    for r in fom["table"]:
        inside = (t >= r["t_start"]) & (t <= r["t_end"])
        assert len(np.unique(line[inside])) == 1, (r["heading"], r["maneuver"])
    dropped = set(out["screening"]["dropped"])
    assert dropped  # the sample's line 9 is a scalar drift fault
    kept_rows = [r for r in fom["table"] if r["kept"]]
    assert len(kept_rows) == fom["n_maneuvers_kept"] < fom["n_maneuvers"]
    assert max(r["ptp_after_nT"] for r in kept_rows) < 0.2  # W roll was 2.37 nT
    w_roll = next(r for r in fom["table"] if r["heading"] == "W" and r["maneuver"] == "roll")
    assert w_roll["t_start"] >= t[line == 10].min()
    # one box, its W pitch dropped: no kept FOM (11 p-p values are not a box FOM), and why
    assert fom["fom_kept_after_nT"] is None and fom["kept_boxes"] == []
    assert "box 0: 1 of its 12 manoeuvres in dropped segments" in fom["kept_reason"]
    assert fom["fom_after_nT"] > 1.0


def test_clip_to_lines_hand_case():
    """A manoeuvre 0-9 s across lines 1 (0-2.9 s) and 2 (3-9.9 s) keeps its line-2 part."""
    from aeromag.qc._lines import clip_to_lines
    from aeromag.qc.maneuvers import MANEUVERS, ManeuverResult

    n = 100
    t = np.arange(n) * 0.1
    line = np.where(t < 3.0, 1, 2)
    mid = np.where(t < 9.0, 0, -1)
    lab = pd.DataFrame({"heading_leg": 0, "leg_id": 0, "box": 0, "maneuver_id": mid})
    lab["maneuver"] = pd.Categorical.from_codes(np.where(mid == 0, 2, 0),
                                                categories=["", *MANEUVERS])
    tab = pd.DataFrame({"id": [0], "box": [0], "heading_leg": [0], "heading": ["N"],
                        "maneuver": ["roll"], "t_start": [0.0], "t_end": [8.9],
                        "duration_s": [9.0], "n": [90]})
    res = ManeuverResult(lab, tab, pd.DataFrame(), "column:maneuver")
    got = clip_to_lines(res, line, t, 10.0)
    assert got.table.loc[0, ["t_start", "t_end", "n"]].tolist() == pytest.approx([3.0, 8.9, 60])
    assert got.table.loc[0, "duration_s"] == pytest.approx(6.0)
    m = got.labels["maneuver_id"].to_numpy()
    assert (m[t < 3.0] == -1).all() and (m[(t >= 3.0) & (t < 9.0)] == 0).all()
    assert (got.labels["maneuver"][t < 3.0] == "").all()
    assert res.table.loc[0, "t_start"] == 0.0  # the input is not changed
    assert clip_to_lines(got, line, t, 10.0) is got  # nothing left to clip
