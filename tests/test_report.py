"""aeromag report: qc.json, PNGs and a self-contained HTML page with every image embedded."""

from __future__ import annotations

import base64
import json
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import pytest
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.synthetic import simulate_calibration
from aeromag.workflows.compensate import compensate_file
from aeromag.workflows.report import FIGURES, build_report


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
    return build_report(out_csv, out_csv.parent / "report")


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
    dom = subprocess.run([*cmd[:-2], "--dump-dom", page.resolve().as_uri()], check=True,
                         timeout=60, capture_output=True, text=True).stdout
    p = _Imgs()
    p.feed(dom)
    assert len(p.srcs) == len(FIGURES)


def test_report_without_json(out_csv, tmp_path):
    d = tmp_path / "nojson"
    d.mkdir()
    shutil.copy(out_csv, d / "out.csv")
    page = build_report(d / "out.csv", d / "rep")
    qc = json.loads((page.parent / "qc.json").read_text())
    assert "pca_scores.png" in qc["figures_skipped"]
    assert Path(page).exists()
