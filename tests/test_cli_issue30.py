"""Issue 30, the command line: calibrate warns on a log that is no calibration flight, the
error promise (``error: FILE: ...`` and what to do) for --date without IGRF and a missing
--model, the help texts, and progress bars (on a terminal only, quiet under CliRunner)."""

from __future__ import annotations

import contextlib
import json
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.io import write_csv
from aeromag.synthetic.quadrotor import simulate_quadrotor

DATA = Path(__file__).resolve().parents[1] / "data_samples"
runner = CliRunner()


def _error_line(r) -> str:
    assert r.exit_code == 1, r.output
    assert "Traceback" not in r.output
    err = [ln for ln in r.output.splitlines() if ln.startswith("error:")]
    assert len(err) == 1, r.output
    return err[0]


def test_calibrate_on_a_survey_warns_like_compensate(tmp_path):
    """Before: exit 0 and no console warning (the JSON only said "FOM not applicable")."""
    r = runner.invoke(app, ["calibrate", str(DATA / "survey.csv"), "-o", str(tmp_path / "m.json")])
    assert r.exit_code == 0, r.output
    assert "not a calibration flight: no calibration box" in r.output
    rep = json.loads((tmp_path / "m.json").read_text())
    assert rep["calibration_box"]["calibration_box"] is False
    assert any("not a calibration flight" in w for w in rep["warnings"])
    r = runner.invoke(app, ["calibrate", str(DATA / "calibration.csv"), "-o",
                            str(tmp_path / "c.json")])
    assert r.exit_code == 0 and "not a calibration flight" not in r.output, r.output
    assert json.loads((tmp_path / "c.json").read_text())["calibration_box"]["calibration_box"]


def test_navigate_date_without_ppigrf_names_the_file(tmp_path, monkeypatch):
    flight = simulate_quadrotor("rectangle", seed=11, duration_s=6.0)
    log = tmp_path / "flight.csv"
    write_csv(flight.log, log)
    monkeypatch.setitem(sys.modules, "ppigrf", None)  # import ppigrf raises ImportError
    r = runner.invoke(app, ["navigate", str(log), "-o", str(tmp_path / "n.csv"), "--date",
                            "2024-06-01"])
    line = _error_line(r)
    assert line.startswith(f"error: {log}: ") and "pip install ppigrf" in line, line
    assert "--earth-field" in line and not (tmp_path / "n.csv").exists()


def test_a_missing_model_file_says_what_to_do(tmp_path):
    missing = tmp_path / "nope.json"
    for args in (["compensate", str(DATA / "survey.csv"), "--model", str(missing), "-o",
                  str(tmp_path / "o.csv")],
                 ["compensate", str(DATA / "survey.csv"), "--model", str(missing),
                  "--chunk-rows", "500", "-o", str(tmp_path / "o.csv")]):
        line = _error_line(runner.invoke(app, args))
        assert line.startswith(f"error: {missing}: ") and "check the path" in line, line
        assert "aeromag calibrate" in line


def test_help_names_every_command_and_the_output_formats():
    top = runner.invoke(app, ["--help"]).output
    summary = top.split("Options:")[0].lower()
    for word in ("compass", "navigation", "fault detection", "compensation", "track"):
        assert word in summary, summary
    comp = runner.invoke(app, ["compensate", "--help"]).output
    assert "Parquet" in comp and "XYZ" in comp and "Output CSV" not in comp


@pytest.mark.parametrize("module,args", [
    ("detect", ["detect", "{mission}", "-o", "{o}/d.csv", "--particles", "50"]),
    ("track", ["track", "{mission}", "--plan", "{plan}", "-o", "{o}/t.csv"]),
    ("compensate", ["compensate", "{survey}", "-o", "{o}/c.csv"]),
])
def test_long_commands_draw_a_bar_only_on_a_terminal(tmp_path, monkeypatch, module, args):
    import importlib

    mod = importlib.import_module(f"aeromag.cli.{module}")
    entered = []
    real = mod.progress_bar

    @contextlib.contextmanager
    def spy(label, **kw):
        entered.append(label)
        with real(label, **kw) as cb:
            yield cb

    monkeypatch.setattr(mod, "progress_bar", spy)
    sub = {"mission": str(DATA / "mission.csv"), "plan": str(DATA / "mission_plan.csv"),
           "survey": str(DATA / "survey.csv"), "o": str(tmp_path)}
    r = runner.invoke(app, [a.format(**sub) for a in args])
    assert r.exit_code == 0, r.output
    assert entered == [f"aeromag {module}"]
    assert "━" not in r.output and "\r" not in r.output  # not a terminal: no bar at all
