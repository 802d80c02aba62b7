"""Review 17 of ``aeromag report``: mag_comp checked, shuffled time refused, file kind named,
no findfont warning.

Before: a CSV whose ``mag_comp`` was zeroed raised no warning while the compensated-field, PSD
and map figures drew the zeros; a time-shuffled log failed with a ``--band`` Nyquist error
(no file name, a flag the report does not have); the headline warning called a Parquet or XYZ
output "the CSV"; and every report printed matplotlib ``findfont`` warnings (mathtext tick
labels of the PSD's log axes).
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
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.io import json_path_for
from aeromag.plot.compensation import plot_psd
from aeromag.workflows.report import load_compensated
from aeromag.workflows.report_check import (
    MAG_COMP_TOL_FLUXGATE_NT,
    MAG_COMP_TOL_NT,
    headline_from_data,
    log_kind,
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
    """Unmodified outputs: saved model (CSV, Parquet, XYZ, chunked, unfiltered), online
    (filtered and not), self-fit, fluxgate magnitude as total field."""
    d = tmp_path_factory.mktemp("rev17")
    for name in ("calibration.csv", "survey.csv"):
        shutil.copy(SAMPLES / name, d / name)
    m = str(d / "aircraft.json")
    _cli("calibrate", str(d / "calibration.csv"), "-o", m)
    runs = {"model.csv": ["survey.csv", "--model", m],
            "model.parquet": ["survey.csv", "--model", m],
            "model.xyz": ["survey.csv", "--model", m],
            "chunk.csv": ["survey.csv", "--model", m, "--chunk-rows", "300"],
            "nofilter.csv": ["survey.csv", "--model", m, "--no-filter"],
            "online.csv": ["survey.csv", "--online"],
            "online_nofilter.csv": ["survey.csv", "--online", "--no-filter"],
            "self.csv": ["calibration.csv"],
            "fluxgate.csv": ["calibration.csv", "--mag-from-fluxgate"]}
    for out, (src, *opts) in runs.items():
        _cli("compensate", str(d / src), *opts, "-o", str(d / out))
    return d, list(runs)


def _copy(d: Path, name: str, new: str, edit) -> Path:
    src = d / name
    stem, suffix = Path(new).stem, Path(name).suffix
    if suffix == ".parquet":
        edit(pd.read_parquet(src)).to_parquet(d / f"{stem}{suffix}", index=False)
    else:
        edit(pd.read_csv(src)).to_csv(d / f"{stem}{suffix}", index=False)
    shutil.copy(json_path_for(src), json_path_for(d / f"{stem}{suffix}"))
    return d / f"{stem}{suffix}"


def test_unmodified_outputs_mag_comp_agrees(outs, caplog):
    d, names = outs
    for name in names:
        res, cfg = load_compensated(d / name)
        chk = headline_from_data(res, cfg).report.headline_check.mag_comp
        assert chk.compared > 1000, (name, chk)
        assert chk.warning is None, (name, chk)
        # measured: exactly 0 nT, and 2.0e-3 nT with the (float32-read) fluxgate magnitude
        tol = MAG_COMP_TOL_NT / 100 if name != "fluxgate.csv" else MAG_COMP_TOL_FLUXGATE_NT / 5
        assert chk.max_abs_difference_nT <= tol, (name, chk)
    assert "mag_comp" not in caplog.text


def test_zeroed_mag_comp_warns_in_terminal_qc_json_and_html(outs):
    d, _ = outs
    csv = _copy(d, "model.csv", "comp0.csv", lambda x: x.assign(mag_comp=0.0))
    out = d / "rep_comp0"
    r = runner.invoke(app, ["report", str(csv), "-o", str(out)])
    assert r.exit_code == 0, r.output
    qc = json.loads((out / "qc.json").read_text())
    assert qc["headline_check"]["agree"] is True  # mag and mag_tl untouched
    chk = qc["headline_check"]["mag_comp"]
    assert chk["max_abs_difference_nT"] > 1e4 and chk["first_row"] == 0
    warning = chk["warning"]
    assert "\n" not in warning and "column 'mag_comp'" in warning
    assert str(csv) in warning and "the CSV was changed after compensation" in warning
    assert warning in r.output.replace("\n", " ") or "column 'mag_comp' differs" in r.output
    page = (out / "report.html").read_text(encoding="utf-8")
    assert "id='mag-comp-warning'" in page
    assert page.index("id='mag-comp-warning'") < page.index("<table")


def test_small_mag_comp_change_beyond_tolerance_warns(outs):
    d, _ = outs
    csv = _copy(d, "chunk.csv", "comp_off.csv",
                lambda x: x.assign(mag_comp=x["mag_comp"] + np.where(x.index == 500, 0.01, 0)))
    res, cfg = load_compensated(csv)
    chk = headline_from_data(res, cfg).report.headline_check.mag_comp
    assert chk.first_row == 500 and chk.warning
    assert chk.max_abs_difference_nT == pytest.approx(0.01, rel=1e-6)


def test_online_nofilter_zeroed_mag_comp_warns(outs):
    d, _ = outs
    csv = _copy(d, "online_nofilter.csv", "onl0.csv", lambda x: x.assign(mag_comp=0.0))
    res, cfg = load_compensated(csv)
    chk = headline_from_data(res, cfg).report.headline_check.mag_comp
    assert chk.warning and "unfiltered or low-passed" in chk.warning


def test_parquet_and_xyz_warnings_name_the_file_kind(outs):
    d, _ = outs
    pq = _copy(d, "model.parquet", "tl0.parquet", lambda x: x.assign(mag_tl=0.0))
    res, cfg = load_compensated(pq)
    rep = headline_from_data(res, cfg).report
    w = rep.headline_check.warning
    assert "the Parquet file was changed after compensation" in w and "CSV" not in w
    assert "the Parquet file was changed" in rep.headline_check.mag_comp.warning
    assert log_kind("a/OUT.xyz") == "the XYZ file"
    assert log_kind("OUT.CSV") == "the CSV"
    assert log_kind("OUT.dat") == "the log"


def test_shuffled_time_is_compensates_one_line_error(outs):
    d, _ = outs
    rng = np.random.default_rng(3)
    shuf = _copy(d, "model.csv", "shuf.csv", lambda x: x.iloc[rng.permutation(len(x))])
    r = runner.invoke(app, ["report", str(shuf), "-o", str(d / "rep_shuf")])
    assert r.exit_code == 1
    msg = r.output.strip().splitlines()[-1]
    assert "Nyquist" not in r.output and "--band" not in r.output
    c = runner.invoke(app, ["compensate", str(shuf), "-o", str(d / "shuf_again.csv")])
    assert c.exit_code == 1
    assert msg == c.output.strip().splitlines()[-1]
    assert str(shuf) in msg and "column 'time'" in msg and "strictly increasing" in msg


def test_psd_tick_labels_are_plain_text(outs):
    d, _ = outs
    res, _ = load_compensated(d / "model.csv")
    fig = plot_psd(res.data, band_hz=(0.1, 0.9))
    fig.canvas.draw()
    labels = [t.get_text() for ax in fig.axes for axis in (ax.xaxis, ax.yaxis)
              for t in axis.get_ticklabels(which="both")]
    assert any(labels)
    assert not [s for s in labels if "$" in s], labels


@pytest.mark.parametrize("name", ["model.csv", "self.csv"])  # a survey; a box with its FOM
def test_report_prints_no_findfont_line(outs, name):
    d, _ = outs
    # the user's matplotlib font cache as it is (one that did not list the mathtext fonts
    # printed four findfont warnings per report; the FOM figure's log axis two more)
    r = subprocess.run([sys.executable, "-m", "aeromag", "report", str(d / name),
                        "-o", str(d / f"rep_font_{Path(name).stem}")], capture_output=True,
                       text=True,
                       env=dict(os.environ), timeout=600, check=False)
    assert r.returncode == 0, r.stderr
    assert "findfont" not in r.stdout + r.stderr
