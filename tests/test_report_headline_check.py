"""The report's headline is computed from the CSV it shows and checked against OUT.json.

Before: ``aeromag report OUT.csv`` headlined OUT.json's metrics whatever the CSV held: a
reviewer zeroed ``mag_tl`` in the CSV, or cut lines out of it, and the report still showed
OUT.json's improvement ratio.  The FOM headline was the all-manoeuvre figure, the kept-segment
one a secondary row.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.compensation import CompensationMetrics
from aeromag.workflows.report import load_compensated, render_html
from aeromag.workflows.report_check import (
    REL_TOL,
    compare_headline,
    headline_from_data,
)

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "data_samples"
runner = CliRunner()


def _cli(*argv: str) -> str:
    r = runner.invoke(app, list(argv))
    assert r.exit_code == 0, r.output
    return r.output


@pytest.fixture(scope="module")
def outs(tmp_path_factory):
    """Unmodified outputs of the shipped samples (self-fit, saved model, chunked, gaps)."""
    d = tmp_path_factory.mktemp("hlcheck")
    for name in ("calibration.csv", "survey.csv"):
        shutil.copy(SAMPLES / name, d / name)
    # short NaN runs of mag (interpolated by the compensation, NaN in OUT.csv) and a long one
    s = pd.read_csv(d / "survey.csv")
    for i in (100, 300, 520, 700):
        s.loc[i:i + 1, "mag"] = np.nan
    s.loc[850:880, "mag"] = np.nan
    s.to_csv(d / "survey_gaps.csv", index=False)
    m = str(d / "model.json")
    _cli("calibrate", str(d / "calibration.csv"), "-o", m)
    runs = {"cal_self": ["calibration.csv"],
            "survey_self": ["survey.csv"],
            "survey_model": ["survey.csv", "--model", m],
            "survey_chunk": ["survey.csv", "--model", m, "--chunk-rows", "300"],
            "gaps_self": ["survey_gaps.csv"],
            "gaps_model": ["survey_gaps.csv", "--model", m],
            "cal_fluxgate": ["calibration.csv", "--mag-from-fluxgate"]}
    for out, (src, *opts) in runs.items():
        _cli("compensate", str(d / src), *opts, "-o", str(d / f"{out}.csv"))
    return d, list(runs)


def _copy(d: Path, name: str, new: str, edit) -> Path:
    data = pd.read_csv(d / f"{name}.csv")
    edit(data).to_csv(d / f"{new}.csv", index=False)
    shutil.copy(d / f"{name}.json", d / f"{new}.json")
    return d / f"{new}.csv"


def test_unmodified_outputs_reproduce_out_json_without_warning(outs, caplog):
    d, names = outs
    for name in names:
        res, cfg = load_compensated(d / f"{name}.csv")
        rep = headline_from_data(res, cfg).report
        check = rep.headline_check
        assert check.compared and check.agree, (name, check)
        assert check.warning is None
        rec = rep.recorded_metrics
        assert rep.metrics.n_samples == rec.n_samples, name
        assert rep.metrics.all_n_samples == rec.all_n_samples, name
        tol = 1e-12 if name != "cal_fluxgate" else 1e-3  # float32 fluxgate in the reader
        assert check.max_relative_difference <= tol, (name, check.max_relative_difference)
    assert "disagrees" not in caplog.text


def test_zeroed_mag_tl_warns_and_headlines_the_csv(outs, capsys):
    d, _ = outs
    csv = _copy(d, "survey_model", "zeroed", lambda x: x.assign(mag_tl=0.0))
    out = d / "rep_zeroed"
    r = runner.invoke(app, ["report", str(csv), "-o", str(out)])
    assert r.exit_code == 0, r.output
    rec = json.loads((d / "survey_model.json").read_text())["metrics"]
    qc = json.loads((out / "qc.json").read_text())
    assert rec["improvement_ratio"] > 5
    assert qc["improvement_ratio"] == pytest.approx(1.0, abs=1e-9)  # mag - 0 is mag
    assert qc["compensation_metrics"]["improvement_ratio"] == rec["improvement_ratio"]
    chk = qc["headline_check"]
    assert chk["agree"] is False
    warning = chk["warning"]
    assert "\n" not in warning
    assert f"{rec['improvement_ratio']:.4g}" in warning and "improvement ratio 1," in warning
    assert "the CSV was changed after compensation, or OUT.json belongs to another run" in warning
    page = (out / "report.html").read_text(encoding="utf-8")
    assert "id='headline-warning'" in page and "belongs to another run" in page
    assert "recorded in zeroed.json" in page
    assert "disagrees with" in r.output  # the terminal (logged warning on stderr)


def test_cut_lines_headline_the_remaining_data(outs):
    d, _ = outs
    csv = _copy(d, "survey_model", "cut", lambda x: x[~x["line"].isin([2, 3, 4])])
    res, cfg = load_compensated(csv)
    rep = headline_from_data(res, cfg).report
    rec = rep.recorded_metrics
    kept_rows = int(res.data["segment_kept"].astype(bool).sum())
    assert rep.metrics.n_samples < rec.n_samples
    assert rep.metrics.n_samples <= kept_rows
    # the same as compensating only the remaining rows' numbers: OUT.json's are of all lines
    assert rep.metrics.improvement_ratio != rec.improvement_ratio
    assert "n_samples" in rep.headline_check.warning
    out = d / "rep_cut"
    _cli("report", str(csv), "-o", str(out))
    qc = json.loads((out / "qc.json").read_text())
    assert qc["n_samples"] == rep.metrics.n_samples
    assert qc["improvement_ratio"] == rep.metrics.improvement_ratio


def test_report_without_mag_tl_says_run_compensate(outs):
    d, _ = outs
    csv = _copy(d, "survey_model", "no_tl", lambda x: x.drop(columns=["mag_tl"]))
    r = runner.invoke(app, ["report", str(csv), "-o", str(d / "rep_no_tl")])
    assert r.exit_code == 1
    assert "no mag_tl column" in r.output and "aeromag compensate" in r.output
    assert not (d / "rep_no_tl" / "report.html").exists()


def test_compare_headline_tolerance_and_counts():
    base = {k: 2.0 for k in ("improvement_ratio", "residual_std_nT", "std_before_nT",
                             "all_improvement_ratio", "all_residual_std_nT",
                             "all_std_before_nT")}
    base |= {"n_samples": 100, "all_n_samples": 120}
    def m(**kw):
        return CompensationMetrics(**(base | kw))

    near = m(improvement_ratio=2.0 * (1 + REL_TOL / 2))
    assert compare_headline(near, m()).agree is True
    far = m(improvement_ratio=2.0 * (1 + 3 * REL_TOL))
    assert compare_headline(far, m()).agree is False
    assert compare_headline(m(n_samples=99), m()).agree is False
    assert compare_headline(far, m(), online=True).agree is False  # online: 1e-6 too
    assert compare_headline(m(), None).compared is False


def test_fom_headline_is_kept_first():
    """FOM table: manoeuvres in kept segments first, all manoeuvres beside them."""
    fom = {"applicable": True, "complete_boxes": [0], "n_maneuvers": 12, "n_maneuvers_kept": 10,
           "fom_before_nT": 40.0, "fom_after_nT": 15.0, "fom_reduction": 40 / 15,
           "fom_kept_before_nT": 30.0, "fom_kept_after_nT": 0.5}
    metrics = {"band_hz": [0.1, 0.9], "fom": fom}
    page = render_html(metrics, {"source": "x.csv"}, {})
    sec = page.split("<h2>Figure of Merit</h2>")[1].split("<h2>")[0]
    head = sec.split("<thead>")[1].split("</thead>")[0]
    assert head.index("manoeuvres in kept segments") < head.index("all manoeuvres")
    rows = sec.split("<tbody>")[1].split("</tr>")
    assert "<td>30</td><td>40</td>" in rows[0]  # before: kept, all
    assert "<td>0.5</td><td>15</td>" in rows[1]  # after: kept, all
    assert "<td>60</td><td>2.667</td>" in rows[2]  # reduction: kept, all
    assert "10 of 12" in sec


def test_fom_not_applicable_keeps_its_reason():
    metrics = {"band_hz": [0.1, 0.9],
               "fom": {"applicable": False, "reason": "no complete calibration box"}}
    page = render_html(metrics, {"source": "x.csv"}, {})
    sec = page.split("<h2>Figure of Merit</h2>")[1].split("<h2>")[0]
    assert "no complete calibration box" in sec and "<table>" not in sec
