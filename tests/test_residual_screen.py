"""Issue 30: applying a saved model flags the segments whose residual is far above the others'
(robust median + k * MAD rule), in OUT.json and as a warning, in the in-memory, chunked and
batch paths; ``segment_kept`` stays true (interface.md: all true when a model is applied).
Before, ``compensate --model`` on data_samples/survey.csv (a fault on line 2: residual 0.49 nT
against a median of 0.06 nT) kept 10/10 segments and said nothing."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.compensation import CompensationReport, SegmentRow
from aeromag.compensation.report import flag_residual_outliers

DATA = Path(__file__).resolve().parents[1] / "data_samples"
runner = CliRunner()


@pytest.fixture(scope="module")
def model(sample_model):
    return sample_model


@pytest.mark.parametrize("extra,report", [([], "o.json"), (["--chunk-rows", "600"], "o.json"),
                                          (None, "b/survey_comp.json")])
def test_the_faulty_line_is_flagged_in_every_path(model, tmp_path, extra, report):
    truth = pd.read_csv(DATA / "survey.csv", usecols=["line", "truth_fault"])
    faulty = sorted(truth.loc[truth["truth_fault"].notna(), "line"].unique().tolist())
    assert faulty == [2]
    if extra is None:
        args = ["batch", str(DATA / "survey.csv"), "--model", str(model), "-o", str(tmp_path / "b")]
    else:
        args = ["compensate", str(DATA / "survey.csv"), "--model", str(model), "-o",
                str(tmp_path / "o.csv"), *extra]
    r = runner.invoke(app, args)
    assert r.exit_code == 0, r.output
    rep = json.loads((tmp_path / report).read_text())
    assert rep["residual_screen"]["flagged"] == [2]  # segment 2 is line 2 here
    assert [s["id"] for s in rep["segments"] if s["residual_flagged"]] == [2]
    assert all(s["kept"] for s in rep["segments"])
    assert any("residual far above the others'" in w and "segment 2" in w
               for w in rep["warnings"])
    if extra is not None:
        out = pd.read_csv(tmp_path / "o.csv", usecols=["segment_kept"])
        assert out["segment_kept"].astype(str).eq("True").all()


def test_a_clean_flight_flags_nothing(tmp_path):
    """The project's simulator without faults: every segment passes the screen."""
    d = tmp_path / "sim"
    assert runner.invoke(app, ["simulate", "--small", "--faults", "0", "--seed", "3", "-o",
                               str(d)]).exit_code == 0
    assert runner.invoke(app, ["calibrate", str(d / "calibration.csv"), "-o",
                               str(d / "m.json")]).exit_code == 0
    r = runner.invoke(app, ["compensate", str(d / "survey.csv"), "--model", str(d / "m.json"),
                            "-o", str(tmp_path / "o.csv")])
    assert r.exit_code == 0, r.output
    rep = json.loads((tmp_path / "o.json").read_text())
    assert rep["residual_screen"]["flagged"] == [] and rep["warnings"] == []


def _report(res):
    return CompensationReport(source="x.csv", segments=[SegmentRow(i, residual_std=r)
                                                        for i, r in enumerate(res)])


@settings(max_examples=60, deadline=None, derandomize=True)
@given(base=st.lists(st.floats(0.04, 0.1), min_size=4, max_size=30),
       scale=st.floats(1e-3, 1e3), bad=st.integers(0, 29), factor=st.floats(20.0, 1e3))
def test_the_rule_is_robust_and_scale_free(base, scale, bad, factor):
    """An independent generator: residuals within a factor of 2.5 of each other pass; one raised
    20x or more is flagged whatever the others; multiplying all by a constant changes nothing."""
    assert flag_residual_outliers(_report(base)) == []
    res = list(base)
    j = bad % len(res)
    res[j] = max(res) * factor
    flagged = flag_residual_outliers(_report(res))
    assert flagged == [j]
    assert flag_residual_outliers(_report([v * scale for v in res])) == [j]


def test_too_few_or_unknown_residuals_are_not_screened():
    rep = _report([0.05, None, 5.0])
    assert flag_residual_outliers(rep) == []
    assert "not screened" in rep.residual_screen.note
    assert not any(s.residual_flagged for s in rep.segments)
    rep = _report([0.05, 0.05, 0.05, np.nan, 0.5])
    assert flag_residual_outliers(rep) == [4]
