"""Issue 30: every command's report has a ``warnings`` list (``[]`` when nothing was said;
compensate left the key out while track wrote ``[]``), and the report of an output that is
not a CSV is named after the whole output name (``-o d/survey.parquet`` and ``-o
d/survey.xyz`` both wrote ``d/survey.json``, the second replacing the first's)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.io import json_path_for

DATA = Path(__file__).resolve().parents[1] / "data_samples"
runner = CliRunner()


@pytest.fixture(scope="module")
def model(sample_model):
    return sample_model


def test_the_report_name_rule():
    assert json_path_for(Path("d/survey.csv")) == Path("d/survey.json")  # interface.md
    assert json_path_for(Path("d/survey.TXT")) == Path("d/survey.json")
    assert json_path_for(Path("d/survey.parquet")) == Path("d/survey.parquet.json")
    assert json_path_for(Path("d/survey.xyz")) == Path("d/survey.xyz.json")


def test_parquet_and_xyz_outputs_keep_their_own_reports(model, tmp_path):
    for ext in ("parquet", "xyz", "csv"):
        r = runner.invoke(app, ["compensate", str(DATA / "survey.csv"), "--model", str(model),
                                "-o", str(tmp_path / f"survey.{ext}")])
        assert r.exit_code == 0, r.output
    reports = {p.name for p in tmp_path.glob("*.json")}
    assert reports == {"survey.json", "survey.parquet.json", "survey.xyz.json"}
    assert "survey.xyz.json" in r.output or "survey.json" in r.output


@pytest.mark.parametrize("args,report", [
    (["compensate", "{survey}", "--model", "{model}", "-o", "{o}/c.csv"], "c.json"),
    (["compensate", "{survey}", "--model", "{model}", "--chunk-rows", "700", "-o",
      "{o}/ch.csv"], "ch.json"),
    (["calibrate", "{cal}", "-o", "{o}/m.json"], "m.json"),
    (["track", "{mission}", "--plan", "{plan}", "-o", "{o}/t.csv"], "t.json"),
    (["detect", "{mission}", "-o", "{o}/d.csv", "--particles", "50"], "d.json"),
    (["batch", "{survey}", "--model", "{model}", "-o", "{o}/b"], "b/batch_summary.json"),
])
def test_every_report_has_a_warnings_list(model, tmp_path, args, report):
    sub = {"survey": str(DATA / "survey.csv"), "cal": str(DATA / "calibration.csv"),
           "mission": str(DATA / "mission.csv"), "plan": str(DATA / "mission_plan.csv"),
           "model": str(model), "o": str(tmp_path)}
    r = runner.invoke(app, [a.format(**sub) for a in args])
    assert r.exit_code == 0, r.output
    doc = json.loads((tmp_path / report).read_text())
    assert isinstance(doc.get("warnings"), list), sorted(doc)
