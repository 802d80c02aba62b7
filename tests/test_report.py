"""aeromag report: qc.json, PNGs and a self-contained HTML page with every image embedded."""

from __future__ import annotations

import base64
import json
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.synthetic import simulate_calibration
from aeromag.workflows.compensate import compensate_file
from aeromag.workflows.report import FIGURES, load_compensated, report_file


class _Imgs(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.srcs: list[str] = []
        self.external: list[str] = []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "img":
            self.srcs.append(a.get("src", ""))
        if tag in ("script", "link") and (a.get("src") or a.get("href")):
            self.external.append(tag)


@pytest.fixture(scope="module")
def out_csv(tmp_path_factory):
    d = tmp_path_factory.mktemp("rep")
    df, _ = simulate_calibration(seed=7, n_boxes=1)
    df.to_csv(d / "cal.csv", index=False)
    compensate_file(d / "cal.csv", d / "out.csv")
    return d / "out.csv"


@pytest.fixture(scope="module")
def page(out_csv):
    return report_file(out_csv, out_csv.parent / "report")


def test_html_embeds_every_image(page):
    p = _Imgs()
    p.feed(page.read_text(encoding="utf-8"))
    assert not p.external
    assert len(p.srcs) == len(FIGURES)
    for src in p.srcs:
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1]).startswith(b"\x89PNG")
    for name in FIGURES:
        assert (page.parent / name).stat().st_size > 0
    text = page.read_text(encoding="utf-8")
    assert "FOM before" in text and "improvement ratio" in text


def test_qc_json(page):
    qc = json.loads((page.parent / "qc.json").read_text())
    assert qc["fom"]["fom_after_nT"] < qc["fom"]["fom_before_nT"]
    assert qc["figures_skipped"] == {}
    assert not list(page.parent.glob("*.tmp*"))


def test_cli(out_csv, tmp_path):
    r = CliRunner().invoke(app, ["report", str(out_csv), "-o", str(tmp_path / "r")])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "r" / "report.html").exists()
    r = CliRunner().invoke(app, ["report", str(tmp_path / "missing.csv"), "-o",
                                 str(tmp_path / "x")])
    assert r.exit_code == 1 and "not found" in r.output
    assert not (tmp_path / "x" / "report.html").exists()


def _chromium() -> str | None:
    for n in ("chromium", "chromium-browser", "google-chrome", "chrome"):
        if shutil.which(n):
            return shutil.which(n)
    return None


@pytest.mark.skipif(_chromium() is None, reason="Chromium is not installed")
def test_renders_in_headless_chromium(page, tmp_path):
    shot = tmp_path / "shot.png"
    cmd = [_chromium(), "--headless", "--no-sandbox", "--disable-gpu",
           "--disable-background-networking", "--no-first-run",
           f"--user-data-dir={tmp_path / 'profile'}", f"--screenshot={shot}",
           "--window-size=1200,3000", page.resolve().as_uri()]
    subprocess.run(cmd, check=True, timeout=60, capture_output=True)
    assert shot.read_bytes().startswith(b"\x89PNG") and shot.stat().st_size > 10000
    from PIL import Image

    px = np.asarray(Image.open(shot).convert("L"))
    assert (px < 200).mean() > 0.02  # text, tables and figures drawn, not a blank page
    dom = subprocess.run([*cmd[:-2], "--dump-dom", page.resolve().as_uri()], check=True,
                         timeout=60, capture_output=True, text=True).stdout
    p = _Imgs()
    p.feed(dom)
    assert len(p.srcs) == len(FIGURES)


def test_report_without_json(out_csv, tmp_path):
    d = tmp_path / "nojson"
    d.mkdir()
    shutil.copy(out_csv, d / "out.csv")
    page = report_file(d / "out.csv", d / "rep")
    qc = json.loads((page.parent / "qc.json").read_text())
    assert "pca_scores.png" in qc["figures_skipped"]
    assert Path(page).exists()


def test_report_contents(page):
    """Issue 15 items 3, 4, 13: headline kept/all, FOM, the model applied, per-line table."""
    text = page.read_text(encoding="utf-8")
    for s in ("kept segments", "all data", "Model applied", "fitted on this log",
              "Lines and segments", "model file residual", "Figure of Merit", "FOM after",
              "id='residuals'", "id='map'"):
        assert s in text, s
    qc = json.loads((page.parent / "qc.json").read_text())
    assert qc["fom"]["applicable"] is True and qc["fom"]["reason"] is None
    seg = qc["segments"]
    assert len(seg) == 12 and all(s["kept"] for s in seg)
    for s in seg:  # the qc's residual is the model file's
        assert s["residual_std_nT"] == pytest.approx(s["model_residual_std_nT"], rel=1e-6)
    assert "residuals.png" in qc["figures"]


def test_report_on_a_survey_says_why_there_is_no_fom(tmp_path):
    from aeromag.synthetic import simulate_survey

    df, _ = simulate_survey(seed=2)
    df.to_csv(tmp_path / "s.csv", index=False)
    compensate_file(tmp_path / "s.csv", tmp_path / "out.csv")
    page = report_file(tmp_path / "out.csv", tmp_path / "rep")
    qc = json.loads((page.parent / "qc.json").read_text())
    assert qc["fom"]["applicable"] is False and qc["fom"]["fom_after_nT"] is None
    assert "fom.png" in qc["figures_skipped"]
    text = page.read_text(encoding="utf-8")
    assert "FOM not applicable" in text and "FOM before" not in text


def test_report_on_an_uncompensated_log(tmp_path):
    df, _ = simulate_calibration(seed=7, n_boxes=1)
    df.to_csv(tmp_path / "raw.csv", index=False)
    r = CliRunner().invoke(app, ["report", str(tmp_path / "raw.csv"), "-o", str(tmp_path / "r")])
    assert r.exit_code == 1
    assert "run `aeromag compensate" in r.output and "Traceback" not in r.output
    assert not (tmp_path / "r" / "report.html").exists()


def test_progress_callback(out_csv, tmp_path):
    calls = []
    report_file(out_csv, tmp_path / "p", progress=lambda d, t, s: calls.append((d, t, s)))
    done = [c[0] for c in calls]
    assert done == sorted(done) and done[-1] == calls[-1][1] and len(calls) >= 5


def test_progress_bar_draws_on_a_terminal():
    import io

    from rich.console import Console

    from aeromag.cli import _progress

    with _progress.progress_bar("x", enabled=False) as cb:
        cb(1, 2, "a")  # a no-op off a terminal
    buf = io.StringIO()
    orig = Console.__init__

    def fake(self, *a, **k):
        k.update(file=buf, force_terminal=True, width=80)
        k.pop("stderr", None)
        orig(self, *a, **k)

    Console.__init__ = fake
    try:
        with _progress.progress_bar("aeromag report", enabled=True) as cb:
            cb(1, 3, "quality metrics")
            cb(3, 3, "report.html")
    finally:
        Console.__init__ = orig
    assert "aeromag report" in buf.getvalue()


def test_subprocess_report(out_csv, tmp_path):
    import sys

    p = subprocess.run([sys.executable, "-m", "aeromag", "report", str(out_csv), "-o",
                        str(tmp_path / "sp")], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "sp" / "report.html").exists()


def test_dropped_segment_row_says_why(tmp_path):
    df, _ = simulate_calibration(seed=4, n_boxes=1, faults={3: "noise_burst"})
    df.to_csv(tmp_path / "cal.csv", index=False)
    compensate_file(tmp_path / "cal.csv", tmp_path / "out.csv")
    page = report_file(tmp_path / "out.csv", tmp_path / "rep")
    rows = json.loads((page.parent / "qc.json").read_text())["segments"]
    bad = [r for r in rows if not r["kept"]]
    assert [r["segment"] for r in bad] == [3] and bad[0]["line"] == 3
    assert "robust distance" in bad[0]["reason"] and "x the median" in bad[0]["reason"]
    assert bad[0]["t_end"] > bad[0]["t_start"]
    assert "class='dropped'" in page.read_text(encoding="utf-8")


def test_load_compensated_reads_the_report_columns_exactly(tmp_path):
    """The report reads its log through read_log: only the columns it uses, with their
    values (single precision for the drawn columns of REPORT_DTYPES)."""
    from aeromag.compensation.pipeline import run_compensation as pipe_compensate
    from aeromag.io import write_csv as io_write_csv
    from aeromag.synthetic import simulate_calibration as sim
    from aeromag.workflows.report import REPORT_COLUMNS, REPORT_DTYPES

    df, _ = sim(seed=4, n_boxes=1)
    res = pipe_compensate(df)
    io_write_csv(res.data.assign(unused=1.0), tmp_path / "out.csv")
    want = pd.read_csv(tmp_path / "out.csv")
    got = load_compensated(tmp_path / "out.csv")[0].data
    assert list(got.columns) == [c for c in want.columns if c in REPORT_COLUMNS]
    assert len(got) == len(want)
    for c in got.columns:
        x = got[c].to_numpy()
        if c in REPORT_DTYPES:
            assert x.dtype == np.float32, c
        if x.dtype.kind == "f":
            np.testing.assert_allclose(x, want[c].to_numpy(float), rtol=1e-6 if
                                       x.dtype == np.float32 else 0, equal_nan=True)
        else:
            assert list(x) == list(want[c]), c

