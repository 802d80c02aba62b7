"""The typed QC sub-blocks (issue 26 item 5): objects between layers, JSON at the edge.

``QCMetrics`` holds ``RmsSummary``, ``PerPieceRms``, ``NoiseSummary``, ``ManeuverSummary``,
``FomSummary``, ``FitDiagnostics``, ``HeadlineCheck`` and ``QCSegmentRow`` objects; their
``to_dict()`` must be the blocks the files have always held (keys, order, values) and
``from_dict`` must read every file the commands write back to the same text.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import aeromag as am
from aeromag.compensation.report_types import HeadlineCheck, MagCompCheck
from aeromag.errors import InputError
from aeromag.io.json import _jsonable, dumps_readable
from aeromag.qc import (
    FitDiagnostics,
    FomBox,
    FomManeuver,
    FomSummary,
    FomTableRow,
    ManeuverSummary,
    NoiseSummary,
    PerPieceRms,
    QCMetrics,
    QCSegmentRow,
    RmsSummary,
    compute_qc,
)
from aeromag.qc.fom import fom_not_applicable

ROOT = Path(__file__).resolve().parents[1]

#: (argv, documents written) run in order on a copy of data_samples/.
COMMANDS = [
    (["calibrate", "data_samples/calibration.csv", "-o", "out/aircraft.json", "--plot",
      "out/cal_plot"], ["out/aircraft.json", "out/cal_plot/qc.json"]),
    (["compensate", "data_samples/survey.csv", "--model", "out/aircraft.json", "--chunk-rows",
      "700", "-o", "out/survey_chunk.csv"], ["out/survey_chunk.json"]),
    (["compensate", "data_samples/calibration.csv", "--model", "out/aircraft.json", "-o",
      "out/cal_model.csv"], ["out/cal_model.json"]),
    (["report", "out/cal_model.csv", "-o", "out/rep_cal"], ["out/rep_cal/qc.json"]),
    (["report", "out/survey_chunk.csv", "-o", "out/rep_chunk"], ["out/rep_chunk/qc.json"]),
]


@pytest.fixture(scope="module")
def written(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The documents the commands write (this checkout's code, whatever is installed)."""
    d = tmp_path_factory.mktemp("qc_types")
    shutil.copytree(ROOT / "data_samples", d / "data_samples")
    env = dict(os.environ, COLUMNS="100", NO_COLOR="1",
               PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    out = {}
    for argv, docs in COMMANDS:
        r = subprocess.run([sys.executable, "-m", "aeromag", *argv], cwd=d, env=env,
                           capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, r.stderr
        out.update({p: d / p for p in docs})
    return out


def _qc_of(doc: dict) -> dict:
    return doc if "per_piece_rms" in doc else doc["qc"]


def _text(doc: dict) -> str:
    return dumps_readable(_jsonable(doc)) + "\n"


def test_every_written_document_reads_back_to_the_same_text(written):
    kinds = set()
    for name, path in written.items():
        text = path.read_text(encoding="utf-8")
        doc = json.loads(text)
        qc = _qc_of(doc)
        m = QCMetrics.from_dict(qc)
        again = m.to_dict()
        assert again == qc, name
        assert json.dumps(again) == json.dumps(qc), name  # the same key order
        if qc is doc:
            assert _text(again) == text, name  # byte for byte
        else:
            assert _text({**doc, "qc": again}) == text, name
        kinds.add((m.fom.from_table, m.fit.source if m.fit else None,
                   m.headline_check is not None))
    # both FOM kinds, both fit-diagnostic kinds, with and without a headline check
    assert {k[0] for k in kinds} == {True, False}
    assert {k[1] for k in kinds} >= {None, "the fit (model file)"}
    assert {k[2] for k in kinds} == {True, False}


def test_read_blocks_are_typed(written):
    m = QCMetrics.from_dict(json.loads(written["out/cal_plot/qc.json"].read_text()))
    assert isinstance(m.all_data, RmsSummary) and isinstance(m.per_piece_rms, PerPieceRms)
    assert isinstance(m.noise, NoiseSummary) and isinstance(m.maneuvers, ManeuverSummary)
    assert isinstance(m.fom, FomSummary) and isinstance(m.fit, FitDiagnostics)
    assert isinstance(m.headline_check, HeadlineCheck)
    assert isinstance(m.headline_check.mag_comp, MagCompCheck)
    assert all(isinstance(s, QCSegmentRow) for s in m.segments)
    fom = m.fom
    assert fom.applicable and fom.complete_boxes == [0] and fom.from_table
    assert all(isinstance(b, FomBox) for b in fom.boxes)
    assert all(isinstance(r, FomManeuver) for r in fom.per_maneuver)
    assert all(isinstance(r, FomTableRow) for r in fom.table) and len(fom.table) == 12
    assert fom.boxes[0].kept_reason == "box 0: 1 of its 12 manoeuvres in dropped segments"
    assert fom.fom_kept_after_nT is None and "fom_kept_after_nT" in fom.to_dict()
    assert m.fit.source == "the fit (model file)" and m.fit.max_vif == max(m.fit.vif.values())
    rebuilt = QCMetrics.from_dict(json.loads(written["out/rep_cal/qc.json"].read_text())).fit
    assert rebuilt.source is None and len(rebuilt.terms) == len(rebuilt.vif) == 16
    assert m.headline_check.compared and m.headline_check.agree
    assert set(m.headline_check.differences) >= {"improvement_ratio", "n_samples"}
    assert m.per_piece_rms.kept.n_samples == m.per_piece_rms.to_dict()["kept"]["n_samples"]
    seg9 = next(s for s in m.segments if s.segment == 9)
    assert not seg9.kept and seg9.reason


@pytest.fixture(scope="module")
def cal_qc():
    cal = am.read_log(ROOT / "data_samples" / "calibration.csv")
    res = am.calibrate(cal, source="calibration.csv")
    return res, compute_qc(res)


def test_compute_qc_gives_objects_and_the_json_reads_back(cal_qc):
    res, q = cal_qc
    m = q.metrics
    assert isinstance(res.report.qc, QCMetrics)
    assert isinstance(res.report.qc.fom, FomSummary)
    assert res.report.qc.fom.fom_after_nT == pytest.approx(res.report.qc.fom.fom_after_nT)
    assert m.fit.source == "the fit (model file)" and m.fit.vif == res.report.fit.vif
    assert m.noise.band_hz == list(res.config.band_hz)
    assert m.maneuvers.complete_boxes == [0] and m.maneuvers.n_maneuvers == 12
    assert m.fom.table[0].ptp_truth_nT is not None
    doc = json.loads(json.dumps(_jsonable(m.to_dict())))
    assert json.dumps(QCMetrics.from_dict(doc).to_dict()) == json.dumps(doc)
    # the report's own document holds the same block
    assert res.report.to_dict()["qc"]["fom"] == res.report.qc.fom.to_dict()


def test_rebuilt_fit_diagnostics_keep_their_order():
    d = {"terms": ["cx"], "condition_number": 2.0, "condition_number_scaled": 1.5,
         "vif": {"cx": 1.0}, "max_vif": 1.0, "n_segments_kept": 3,
         "fit_residual_std_nT": 0.1, "cv_residual_std_nT": 0.2, "cv_ratio": None}
    assert list(FitDiagnostics.from_dict(d).to_dict()) == list(d)
    rec = {"source": "the fit (model file)", "condition_number": 2.0,
           "condition_number_scaled": None, "vif": None, "max_vif": None,
           "cv_residual_std_nT": None, "cv_ratio": None, "fit_residual_std_nT": 0.1,
           "n_segments_kept": 3, "vendor": 1}
    back = FitDiagnostics.from_dict(rec)
    assert back.extra == {"vendor": 1} and json.dumps(back.to_dict()) == json.dumps(rec)


def test_not_applicable_fom_block_keeps_its_order():
    d = fom_not_applicable("no pitch/roll/yaw manoeuvre found").to_dict()
    assert list(d) == ["applicable", "reason", "fom_before_nT", "fom_after_nT",
                       "fom_reduction", "boxes", "complete_boxes", "n_maneuvers", "per_maneuver"]
    back = FomSummary.from_dict(d)
    assert not back.from_table and json.dumps(back.to_dict()) == json.dumps(d)


# ----------------------------------------------------------------- any valid block reads back
_F = st.one_of(st.none(), st.floats(0, 1e3))
_BOX_OPTIONAL = {f"fom_{k}_nT": _F for k in ("before", "after", "truth", "kept_before",
                                             "kept_after", "kept_truth")}
_BOX_OPTIONAL |= {"n_maneuvers_kept": st.integers(0, 12),
                  "dropped": st.lists(st.sampled_from(["N pitch", "E roll"]), max_size=2),
                  "kept_reason": st.one_of(st.none(), st.text(max_size=10))}


def _ordered(d: dict, cls: type) -> dict:
    """``d`` in the class's field order (the order the code writes)."""
    names = [f for f in cls.__dataclass_fields__ if f not in ("nulls", "extra", "from_table")]
    return {k: d[k] for k in names if k in d}


@settings(max_examples=60, deadline=None, derandomize=True)
@given(present=st.fixed_dictionaries({}, optional=_BOX_OPTIONAL), box=st.integers(0, 99),
       complete=st.booleans(), vendor=st.booleans())
def test_fom_boxes_round_trip_whatever_keys_they_hold(present, box, complete, vendor):
    """An independent generator: any subset of the optional keys, None values included (a
    key written as null stays a null, an absent key stays absent)."""
    d = _ordered({"box": box, "n_maneuvers": 12, "complete": complete,
                  "missing": [] if complete else ["W yaw"], **present}, FomBox)
    if vendor:
        d["vendor_flag"] = "x"
    out = FomBox.from_dict(d).to_dict()
    assert json.dumps(out) == json.dumps(d)


_SUMMARY_OPTIONAL = {
    "fields": st.just({"ptp_before_nT": "mag"}), "definition": st.text(max_size=10),
    "fom_before_nT": _F, "fom_after_nT": _F, "fom_truth_nT": _F,
    "kept_applicable": st.booleans(), "kept_boxes": st.lists(st.integers(0, 3), max_size=2),
    "fom_kept_before_nT": _F, "fom_kept_after_nT": _F, "fom_kept_truth_nT": _F,
    "kept_reason": st.one_of(st.none(), st.text(max_size=10)),
    "kept_definition": st.text(max_size=10), "n_maneuvers_kept": st.integers(0, 24),
    "table": st.lists(st.fixed_dictionaries(
        {"id": st.integers(0, 9), "box": st.integers(0, 2), "heading_leg": st.integers(0, 3),
         "heading": st.sampled_from("NESW"), "maneuver": st.sampled_from(["pitch", "yaw"]),
         "t_start": st.floats(0, 10), "t_end": st.floats(10, 20)},
        optional={"ptp_before_nT": _F, "ptp_after_nT": _F, "ptp_truth_nT": _F,
                  "kept": st.booleans()}), max_size=3),
}


@settings(max_examples=60, deadline=None, derandomize=True)
@given(present=st.fixed_dictionaries({}, optional=_SUMMARY_OPTIONAL),
       applicable=st.booleans(), reduction=_F)
def test_fom_summaries_round_trip_whatever_keys_they_hold(present, applicable, reduction):
    d = _ordered({"applicable": applicable, "reason": None if applicable else "none",
                  "boxes": [{"box": 0, "n_maneuvers": 12, "complete": True, "missing": [],
                             "fom_before_nT": 1.0}],
                  "complete_boxes": [0], "n_maneuvers": 12, "fom_reduction": reduction,
                  "per_maneuver": [{"heading": "N", "maneuver": "pitch",
                                    "ptp_after_nT": 0.5}], **present}, FomSummary)
    if "table" in d:  # rows in the table's column order
        d["table"] = [_ordered(r, FomTableRow) for r in d["table"]]
    back = FomSummary.from_dict(d)
    assert back.from_table
    assert json.dumps(back.to_dict()) == json.dumps(d)


@settings(max_examples=40, deadline=None, derandomize=True)
@given(compared=st.booleans(), agree=st.one_of(st.none(), st.booleans()),
       mag_comp=st.one_of(st.none(), st.fixed_dictionaries(
           {"compared": st.integers(0, 100), "max_abs_difference_nT": _F,
            "tolerance_nT": st.floats(0, 1), "first_row": st.one_of(st.none(), st.integers(0, 9)),
            "filtered": st.booleans(), "filter_recorded": st.booleans(),
            "warning": st.one_of(st.none(), st.text(max_size=5))},
           optional={"note": st.text(max_size=5)})))
def test_headline_checks_round_trip(compared, agree, mag_comp):
    d = {"compared": compared, "agree": agree, "relative_tolerance": 1e-6, "counts": "equal",
         "recorded_in": "OUT.json", "warning": None, "definition": "words"}
    if compared:
        d |= {"max_relative_difference": 0.0,
              "differences": {"improvement_ratio": {"computed": 2.0, "recorded": 2.0,
                                                    "relative": 0.0}}}
    else:
        d["note"] = "OUT.json has no metrics to compare"
    if mag_comp is not None:
        d["mag_comp"] = _ordered(mag_comp, MagCompCheck)
    assert json.dumps(HeadlineCheck.from_dict(d).to_dict()) == json.dumps(d)


def test_unknown_keys_survive_in_every_block():
    doc = {"band_hz": [0.1, 0.9], "all_data": {"improvement_ratio": 2.0, "n_samples": 3,
                                               "other": 1},
           "noise": {"band_hz": [0.1, 0.9], "extra_noise": 0.3},
           "maneuvers": {"method": "attitude", "vendor": []},
           "segments": [{"segment": 1, "n": 3, "kept": True, "flag": "y"}],
           "vendor_block": {"a": 1}}
    m = QCMetrics.from_dict(doc)
    assert m.all_data.extra == {"other": 1} and m.noise.extra == {"extra_noise": 0.3}
    assert m.segments[0].extra == {"flag": "y"} and m.extra == {"vendor_block": {"a": 1}}
    out = m.to_dict()
    assert out["all_data"]["other"] == 1 and out["segments"][0]["flag"] == "y"
    assert out["vendor_block"] == {"a": 1}


# ----------------------------------------------------------------- consumers
def test_report_page_reads_the_objects_and_the_json_alike(written, cal_qc):
    from aeromag.workflows.report import render_html

    doc = json.loads(written["out/cal_plot/qc.json"].read_text())
    rep = json.loads(written["out/aircraft.json"].read_text())
    page = render_html(QCMetrics.from_dict(doc), rep, {})
    assert page == render_html(doc, rep, {})
    fom = page.split("<h2>Figure of Merit</h2>")[1].split("<h2>")[0]
    assert "box 0: 1 of its 12 manoeuvres in dropped segments" in fom
    assert "true interference" in fom  # the simulation's truth field
    assert "Variance inflation factors" in page and "<td>cz*cy&#x27;</td>" in page
    assert "Headline computed from this log" in page and " agrees with " in page
    assert "<td>9</td>" in page.split("Lines and segments")[1]
    _, q = cal_qc
    page = render_html(q.metrics, rep, {})  # in memory: no headline check, no rows
    assert "Headline as the compensation recorded it." in page


def test_plot_fom_takes_the_typed_block(written, cal_qc):
    pytest.importorskip("matplotlib")
    from aeromag.plot import compensation as pc

    _, q = cal_qc
    doc = json.loads(written["out/cal_plot/qc.json"].read_text())["fom"]

    def heights(*figs):
        return [[p.get_height() for p in f.axes[0].patches] for f in figs]

    for figs in ([pc.plot_fom(q.fom), pc.plot_fom(q.metrics.fom), pc.plot_fom(q)],
                 [pc.plot_fom(doc), pc.plot_fom(FomSummary.from_dict(doc))]):
        h = heights(*figs)
        assert len(h[0]) == 24
        for other in h[1:]:
            np.testing.assert_allclose(other, h[0], rtol=1e-12)
    # the file's table is the in-memory one (the same calibration, fitted on itself)
    np.testing.assert_allclose(heights(pc.plot_fom(doc))[0], heights(pc.plot_fom(q))[0],
                               rtol=1e-9)
    with pytest.raises(InputError, match="not applicable"):
        pc.plot_fom(fom_not_applicable("no manoeuvre found"))
    import matplotlib.pyplot as plt

    plt.close("all")


def test_fom_table_rows_are_the_frame_records(cal_qc):
    _, q = cal_qc
    rows = q.metrics.fom.table
    frame = pd.DataFrame([r.to_dict() for r in rows])
    assert list(frame.columns) == list(q.fom.columns)
    pd.testing.assert_frame_equal(frame, q.fom.reset_index(drop=True), check_dtype=False,
                                  check_categorical=False)
