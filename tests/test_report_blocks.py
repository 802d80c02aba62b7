"""The report's blocks are typed, and read back to the very JSON the commands write.

Issue 26, item 5: ``config``, ``extended``, ``segmentation``, ``calibration_box``,
``self_calibration``, ``chunked``, ``headline_check``, the online run's report and
``TLModel.meta`` were dicts handed between layers.  Each is a dataclass now; ``to_dict()``
gives the block the files hold (same keys, same order, same values) and ``from_dict()``
reads it back.  Checked on the golden documents and on the documents the workflows write
on ``data_samples/`` (calibrate, compensate self-fit / --model / chunked / --online, an
extended fit and its model applied, a calibration without lines, ``aeromag report``).
"""

from __future__ import annotations

import dataclasses
import json
import logging
from pathlib import Path

import pytest
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.compensation.config import CompensationConfig
from aeromag.compensation.config_record import ConfigRecord
from aeromag.compensation.model import ModelMeta, TLModel
from aeromag.compensation.report_types import (
    CalibrationCheck,
    ChunkSettings,
    CompensationReport,
    ExtendedSummary,
    HeadlineCheck,
    HeldOut,
    MagCompCheck,
    Segmentation,
)
from aeromag.qc.quality import QCMetrics, config_of
from aeromag.workflows.chunked import apply_model_chunked
from aeromag.workflows.compensate import calibrate_file, compensate_file
from aeromag.workflows.online_compensate import (
    ConvergenceSummary,
    OnlineReport,
    compensate_online_file,
)
from aeromag.workflows.report_check import HeadlineRecord, headline_record

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "data_samples"
GOLDEN = Path(__file__).resolve().parent / "golden"
EXTRAS = ("cur_1", "cur_2", "cur_3", "volt_bus")


def _same(a: dict, b: dict) -> None:
    """Equal documents, keys in the same order (the bytes json writes)."""
    assert json.dumps(a) == json.dumps(b)


@pytest.fixture(scope="module")
def docs(tmp_path_factory):
    """The documents the workflows write on data_samples/ and on a log with currents."""
    import pandas as pd

    from aeromag.synthetic import add_current_interference, simulate_calibration

    d = tmp_path_factory.mktemp("report_blocks")
    logging.disable(logging.WARNING)
    try:
        calibrate_file(SAMPLES / "calibration.csv", d / "aircraft.json")
        compensate_file(SAMPLES / "survey.csv", d / "self.csv")
        compensate_file(SAMPLES / "survey.csv", d / "model.csv", model=d / "aircraft.json")
        apply_model_chunked(SAMPLES / "survey.csv", d / "chunk.csv", d / "aircraft.json",
                            chunk_rows=700)
        online = compensate_online_file(SAMPLES / "survey.csv", d / "online.csv")
        compensate_online_file(SAMPLES / "survey.csv", d / "online_m.csv",
                               mark_unconverged=True)
        cal = pd.read_csv(SAMPLES / "calibration.csv").drop(columns="line")
        cal.to_csv(d / "noline.csv", index=False)
        calibrate_file(d / "noline.csv", d / "noline.json")
        df0, truth = simulate_calibration(seed=1, n_boxes=1)
        cur, _ = add_current_interference(df0, truth, seed=2)
        cur.to_csv(d / "cur.csv", index=False)
        cfg = CompensationConfig(extras=EXTRAS)
        calibrate_file(d / "cur.csv", d / "ext.json", cfg)
        compensate_file(d / "cur.csv", d / "ext_applied.csv", model=d / "ext.json")
        r = CliRunner().invoke(app, ["report", str(d / "model.csv"), "-o", str(d / "rep")])
        assert r.exit_code == 0, r.output
    finally:
        logging.disable(logging.NOTSET)
    return d, online


REPORTS = ("aircraft.json", "self.json", "model.json", "chunk.json", "noline.json",
           "ext.json", "ext_applied.json")


@pytest.mark.parametrize("name", REPORTS)
def test_reports_read_back_to_the_same_json(docs, name):
    d, _ = docs
    doc = json.loads((d / name).read_text())
    rep = CompensationReport.from_dict(doc)
    _same(rep.to_dict(), doc)
    assert rep.extra == {}  # every block of a report the commands write is known
    assert isinstance(rep.config, ConfigRecord) and rep.config.extra == {}


@pytest.mark.parametrize("path", sorted(p.name for p in GOLDEN.glob("*.json")
                                        if p.name.startswith(("calibrate", "compensate",
                                                              "batch_model"))))
def test_golden_reports_read_back_to_the_same_json(path):
    doc = json.loads((GOLDEN / path).read_text())  # recorded with sorted keys, masked
    assert CompensationReport.from_dict(doc).to_dict() == doc


def test_blocks_are_typed_where_the_workflows_write_them(docs):
    d, _ = docs

    def rep(name: str) -> CompensationReport:
        return CompensationReport.from_dict(json.loads((d / name).read_text()))

    box = rep("aircraft.json").calibration_box
    assert isinstance(box, CalibrationCheck) and box.calibration_box and box.metrics is None
    assert box.headings == ["E", "N", "S", "W"]
    sc = rep("self.json").self_calibration
    assert isinstance(sc, CalibrationCheck) and not sc.calibration_box
    assert "in-sample" in sc.metrics
    assert list(sc.to_dict()) == ["metrics", "calibration_box", "headings", "maneuvers"]
    ch = rep("chunk.json").chunked
    assert isinstance(ch, ChunkSettings) and ch.chunk_rows == 700 and ch.overlap_rows > 0
    seg = rep("noline.json").segmentation
    assert isinstance(seg, Segmentation) and seg.method == "detected maneuvers"
    assert seg.n_segments == 12 and seg.segment_seconds is None
    applied = rep("model.json").config
    assert applied.terms is None and applied.ridge is None  # fit-only keys left out
    assert "lowpass_hz" in applied.nulls and applied.to_dict()["lowpass_hz"] is None
    ext = rep("ext.json").extended
    assert isinstance(ext, ExtendedSummary) and isinstance(ext.held_out, HeldOut)
    assert ext.fitted and [e["name"] for e in ext.extras] == list(EXTRAS)
    assert ext.held_out.residual_std_nT < ext.held_out.tl_only_residual_std_nT
    # a saved model's block writes the fit's record before the model's keys, as it did
    back = rep("ext_applied.json").extended
    assert not back.fitted and list(back.to_dict())[:2] == ["rows_left_out", "dropped_extras"]
    assert rep("ext.json").config.extras == list(EXTRAS)


def test_time_window_segmentation_block():
    block = {"method": "time windows", "segment_seconds": 60.0, "reason": "none found"}
    seg = Segmentation.from_dict(block)
    assert seg.segment_seconds == 60.0 and seg.detector is None
    _same(seg.to_dict(), block)


def test_config_record_follows_compensation_config():
    """One attribute per CompensationConfig keyword, in its order (config_dict's keys)."""
    names = [f.name for f in dataclasses.fields(CompensationConfig)]
    assert [f.name for f in dataclasses.fields(ConfigRecord)][:len(names)] == names
    cfg = CompensationConfig(extras=("a", "b"), ridge=0.1, band_hz=(0.2, 1.0))
    rec = ConfigRecord.from_config(cfg)
    assert rec.extras == ["a", "b"] and rec.reference is None and "reference" not in rec.nulls
    assert rec.to_config() == cfg
    applied = ConfigRecord.from_config(cfg, applied=True)
    assert applied.ridge is None and applied.extras is None and applied.band_hz == [0.2, 1.0]
    assert config_of(CompensationReport(config=applied)).band_hz == (0.2, 1.0)
    assert config_of(CompensationReport(band_hz=[0.3, 1.2])).band_hz == (0.3, 1.2)


def test_online_report_is_typed_and_reads_back(docs):
    d, online = docs
    assert isinstance(online, OnlineReport) and isinstance(online.convergence,
                                                           ConvergenceSummary)
    assert online.convergence.spans[0].kind == "warmup"
    assert online.metrics.extra["n_skipped"] == 0 and online.segments[0].kept
    assert online.warnings is not None  # recorded when the file was written
    for name in ("online.json", "online_m.json"):
        doc = json.loads((d / name).read_text())
        _same(OnlineReport.from_dict(doc).to_dict(), doc)
    _same(online.to_dict(), json.loads((d / "online.json").read_text()))
    # aeromag report reads it as a compensation report, the online keys in extra
    doc = json.loads((d / "online.json").read_text())
    rep = CompensationReport.from_dict(doc)
    assert rep.extra["online"] is True
    assert {"input", "forgetting", "convergence", "history"} <= set(rep.extra)
    assert rep.to_dict()["convergence"] == doc["convergence"]


def test_headline_check_reads_back_from_qc_json(docs):
    d, _ = docs
    qc = json.loads((d / "rep" / "qc.json").read_text())
    chk = HeadlineCheck.from_dict(qc["headline_check"])
    assert chk.compared and chk.agree and isinstance(chk.mag_comp, MagCompCheck)
    assert chk.mag_comp.filter_recorded and chk.mag_comp.warning is None
    _same(chk.to_dict(), qc["headline_check"])
    m = QCMetrics.from_dict(qc)
    assert isinstance(m.headline_check, HeadlineCheck)
    _same(m.to_dict()["headline_check"], qc["headline_check"])
    not_compared = HeadlineCheck(compared=False, relative_tolerance=1e-6, counts="equal",
                                 recorded_in="OUT.json", definition="d", note="no metrics")
    assert list(not_compared.to_dict()) == ["compared", "agree", "relative_tolerance",
                                            "counts", "recorded_in", "warning",
                                            "definition", "note"]


def test_headline_record_is_typed(docs):
    from aeromag.workflows.report import load_compensated
    from aeromag.workflows.report_check import headline_from_data

    d, _ = docs
    res, cfg = load_compensated(d / "model.csv")
    rec = headline_record(headline_from_data(res, cfg).report)
    assert isinstance(rec, HeadlineRecord) and rec.headline_check.agree
    assert list(rec.to_dict()) == ["headline_check", "compensation_metrics"]
    assert headline_record(CompensationReport()).to_dict() == {}


def test_model_meta_is_the_report_it_was_fitted_or_read_with(docs):
    d, _ = docs
    doc = json.loads((d / "aircraft.json").read_text())
    model = TLModel.load(d / "aircraft.json")
    assert isinstance(model.meta, ModelMeta) and model.meta.path is None
    assert model.meta.report.terms == []  # the model's terms are the model's alone
    assert model.meta.mag_from_fluxgate is False
    assert model.meta.report.calibration_box.calibration_box
    assert model.to_dict() == doc  # the same document (the model keys written last)
    ext = TLModel.load(d / "ext.json")
    assert ext.to_dict() == json.loads((d / "ext.json").read_text())
    # a fit's model carries the fit's own report: what calibrate added to it is the model's
    import pandas as pd

    from aeromag.workflows.compensate import calibrate

    cal = pd.read_csv(d / "noline.csv")
    logging.disable(logging.WARNING)
    try:
        res = calibrate(cal, source="noline.csv")
    finally:
        logging.disable(logging.NOTSET)
    assert res.model.meta.report is res.report
    assert res.model.to_dict()["segmentation"] == res.report.segmentation.to_dict()
    # a dict given as meta (a model file's other keys) is read as the report
    m = TLModel(("cx",), [1.0], meta={"band_hz": [0.1, 0.9], "mag_from_fluxgate": True})
    assert m.meta.report.band_hz == [0.1, 0.9] and m.meta.mag_from_fluxgate is True
    assert TLModel(("cx",), [1.0]).to_dict() == {"terms": ["cx"], "coef": [1.0],
                                                  "scale_nT": 50000.0}
