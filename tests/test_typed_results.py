"""The typed compensation report (issue 26 item 5): objects between layers, JSON at the edge.

``CompensationReport.to_dict()`` must be the document the files have always held (keys,
order, values) and ``from_dict`` must read every report back to the same document.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import aeromag as am
from aeromag.compensation import (
    CompensationMetrics,
    CompensationReport,
    ScreeningSummary,
    SegmentRow,
)
from aeromag.qc.quality import QCMetrics

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = ROOT / "tests" / "golden"
SAMPLES = ROOT / "data_samples"

#: Top-level keys of a fit's report in the order MODEL.json has always written them.
FIT_ORDER = ["aeromag_version", "created", "source", "terms", "coef", "scale_nT", "band_hz",
             "filter_order", "sampling_rate_hz", "mag_from_fluxgate", "fit", "segments",
             "screening", "config", "metrics", "model_source", "qc", "calibration_box"]
#: ... and of a saved model applied in memory (OUT.json of compensate --model).
APPLIED_ORDER = ["aeromag_version", "created", "source", "terms", "coef", "scale_nT",
                 "model_source", "band_hz", "sampling_rate_hz", "segments", "screening",
                 "metrics", "config", "qc", "residual_screen"]


@pytest.fixture(scope="module")
def runs():
    cal = am.read_log(SAMPLES / "calibration.csv")
    fit = am.calibrate(cal, source="calibration.csv")
    survey = am.read_log(SAMPLES / "survey.csv")
    applied = am.compensate(survey, model=fit.model, source="survey.csv")
    return fit, applied


def test_results_carry_objects_not_dicts(runs):
    fit, applied = runs
    for res in runs:
        assert isinstance(res.report, CompensationReport)
        assert isinstance(res.metrics, CompensationMetrics)
        assert isinstance(res.report.screening, ScreeningSummary)
        assert all(isinstance(s, SegmentRow) for s in res.report.segments)
        assert isinstance(res.report.qc, QCMetrics)
    # the calibration sample's faulty line 9 is dropped, the rest kept (the golden record)
    assert fit.report.screening.dropped == [9]
    assert [s.id for s in fit.report.segments if not s.kept] == [9]
    assert fit.report.segment(9).name == "line 9" and fit.report.segment(9).reason
    assert fit.metrics.improvement_ratio == pytest.approx(277.28, rel=1e-3)
    assert applied.report.fit is None and applied.report.model_source == "given"
    assert applied.report.residual_screen.flagged == [2]  # the survey's faulty line
    assert applied.report.segment(2).residual_flagged is True


def test_to_dict_keeps_the_files_key_order(runs):
    fit, applied = runs
    assert list(fit.report.to_dict()) == FIT_ORDER
    assert list(applied.report.to_dict()) == APPLIED_ORDER
    seg = fit.report.to_dict()["segments"][0]
    assert list(seg)[:9] == ["id", "n", "n_fit", "kept", "scores", "residual_std",
                             "cv_residual_std", "condition_number", "coef"]
    assert list(applied.report.to_dict()["segments"][0]) == [
        "id", "n", "kept", "scores", "residual_std", "residual_flagged"]
    assert list(applied.report.to_dict()["screening"]) == ["enabled", "notes"]


def test_from_dict_reads_every_report_back(runs):
    for res in runs:
        doc = json.loads(json.dumps(res.report.to_dict(), default=float))
        again = CompensationReport.from_dict(doc).to_dict()
        assert json.dumps(again) == json.dumps(doc)  # same keys, same order, same values


@pytest.mark.parametrize("name", ["calibrate__aircraft.json", "compensate_self__survey_comp.json",
                                  "compensate_model__survey_model.json",
                                  "compensate_chunked__survey_chunk.json"])
def test_recorded_golden_reports_round_trip(name):
    doc = json.loads((GOLDEN / name).read_text())
    rep = CompensationReport.from_dict(doc)
    assert rep.to_dict() == doc  # (the records are written with sorted keys)
    assert rep.metrics.n_rows_without_mag == 0
    assert rep.segments and all(isinstance(s.id, int) for s in rep.segments)


def test_unknown_keys_survive_and_nulls_stay_null():
    doc = {"source": "other.csv", "terms": ["a"], "coef": [1.0], "online": True,
           "segments": [{"id": 3, "n": 10, "kept": False, "scores": None, "residual_std": None,
                         "condition_number": None, "vendor_flag": 7}],
           "screening": {"enabled": False, "notes": []}, "metrics": {"improvement_ratio": 2.0,
                                                                     "coverage": "all"}}
    rep = CompensationReport.from_dict(doc)
    assert rep.extra == {"online": True}
    assert rep.segments[0].extra == {"vendor_flag": 7}
    assert rep.metrics.improvement_ratio == 2.0 and rep.metrics.extra == {"coverage": "all"}
    out = rep.to_dict()
    assert out["segments"] == doc["segments"]  # condition_number stays a null, not dropped
    assert out["online"] is True


_ROW_VALUES = {
    "n_fit": st.integers(1, 10_000), "cv_residual_std": st.floats(0, 10),
    "condition_number": st.one_of(st.none(), st.floats(1, 1e6)),
    "coef": st.lists(st.floats(-10, 10), max_size=3), "robust_distance": st.floats(0, 50),
    "pca_outlier": st.booleans(), "pool_residual_nT": st.floats(0, 5),
    "line": st.one_of(st.none(), st.integers(1, 99)),
    "pool_median_nT": st.one_of(st.none(), st.floats(0, 5)),
    "reason": st.text(max_size=20), "start_time": st.floats(0, 1e4),
    "end_time": st.floats(0, 1e4), "heading_deg": st.one_of(st.none(), st.floats(0, 360)),
    "residual_flagged": st.booleans(), "name": st.text(max_size=20),
}


@settings(max_examples=80, deadline=None, derandomize=True)
@given(present=st.fixed_dictionaries({}, optional=_ROW_VALUES), too_short=st.booleans(),
       sid=st.integers(0, 500), residual=st.one_of(st.none(), st.floats(0, 5)))
def test_segment_rows_round_trip_whatever_keys_they_hold(present, too_short, sid, residual):
    """An independent generator: any subset of the optional keys, None values included (a
    key written as null stays a null, an absent key stays absent), reads back the same."""
    d = {"id": sid, "n": 10, "kept": not too_short, "scores": None, "residual_std": residual,
         **present}
    if too_short:
        d |= {"too_short": True, "min_samples": 100, "reason": "too short to fit"}
    out = SegmentRow.from_dict(d).to_dict()
    assert out == d and set(out) == set(d)


def test_plots_take_the_objects_and_json_at_the_edge(runs, tmp_path):
    pytest.importorskip("matplotlib")
    fit, _ = runs
    f1 = am.plot.plot_pca_scores(fit.report)
    f2 = am.plot.plot_pca_scores(json.loads(json.dumps(fit.report.to_dict(), default=float)))
    pts = [np.vstack([c.get_offsets() for c in f.axes[0].collections]) for f in (f1, f2)]
    np.testing.assert_allclose(pts[0], pts[1])
    assert f1.axes[0].get_title() == "PCA score plot: 12 segments, 1 dropped"
