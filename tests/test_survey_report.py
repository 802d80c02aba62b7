"""The levelling QC page (`aeromag level --plot DIR`, `am.workflows.write_survey_report`):
the anomaly map, the mistie histograms, the stacked profiles and one self-contained HTML page
with the steps' figures; and `aeromag report` refusing a levelled log with the command that
fits."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

import aeromag as am
from aeromag.cli import app

SAMPLES = Path(__file__).resolve().parents[1] / "data_samples"


@pytest.fixture(scope="module")
def levelled(tmp_path_factory):
    d = tmp_path_factory.mktemp("lev")
    out = d / "lev.csv"
    r = CliRunner().invoke(app, ["level", str(SAMPLES / "level_survey.csv"), "--base",
                                 str(SAMPLES / "level_base.csv"), "--lag", "0.4",
                                 "--decorrugate", "--plot", str(d / "qc"), "-o", str(out)])
    assert r.exit_code == 0, r.output
    return out, d / "qc"


def test_level_plot_writes_map_misties_profiles_and_one_page(levelled):
    out, qc = levelled
    for name in ("map.png", "misties.png", "profiles.png"):
        assert (qc / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
    page = (qc / "report.html").read_text()
    assert page.count("data:image/png;base64,") == 3
    rep = json.loads(out.with_suffix(".json").read_text())
    assert sorted(Path(p).name for p in rep["figures"]) == [
        "map.png", "misties.png", "profiles.png", "report.html"]
    # The page states the report's figures, not other ones.
    before = rep["mistie_std_nT"]["before"]
    assert f"{before:.4g}" in page
    assert "degrees of freedom" in page and "Levelling passes" in page
    assert len(re.findall(r"<tr><td>\d+</td><td>(?:line|tie)</td>", page)) == len(rep["lines"])
    assert "Warning:" not in page  # 5 ties on 8 lines: enough degrees of freedom


def test_report_refuses_a_levelled_log_in_one_line(levelled, tmp_path):
    out, _ = levelled
    r = subprocess.run([sys.executable, "-m", "aeromag", "report", str(out), "-o",
                        str(tmp_path / "rep")], capture_output=True, text=True)
    assert r.returncode == 1
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {out}: a levelled survey")
    assert "aeromag level" in lines[0] and "--plot DIR" in lines[0]
    assert not (tmp_path / "rep" / "report.html").exists()


def test_python_api_writes_the_page_for_a_table_without_ties_as_a_warning(tmp_path):
    # An independent survey: 6 N-S lines 300 m apart, no ties, levelling off; the map,
    # profiles and page are still written, the misties figure is not (no crossings).
    rng = np.random.default_rng(2)
    parts = []
    for k in range(6):
        y = np.arange(0.0, 3000.0, 10.0)
        x = np.full_like(y, 300.0 * k) + rng.normal(0, 2, y.size)
        parts.append(pd.DataFrame({"lat": -31.0 + y / 110_900.0,
                                   "lon": 116.0 + x / (111_320.0 * np.cos(np.radians(31.0))),
                                   "alt": 120.0, "line": 10 + k,
                                   "mag": 30 * np.exp(-((x - 800) ** 2 + (y - 1500) ** 2)
                                                      / 4e5)}))
    res = am.level(pd.concat(parts, ignore_index=True), igrf=False, method="none")
    files = am.workflows.write_survey_report(res, tmp_path / "qc")
    assert [f.name for f in files] == ["map.png", "profiles.png", "report.html"]
    assert "levelling</td><td>none" in (tmp_path / "qc" / "report.html").read_text()


def test_grid_file_reports_its_steps(levelled, tmp_path):
    out, _ = levelled
    seen = []
    am.workflows.grid_file(out, tmp_path / "g.nc", map_path=tmp_path / "g.png",
                           progress=lambda done, total, step: seen.append((done, total, step)))
    assert [s for _, _, s in seen] == ["reading", "gridding", "writing", "map", "done"]
    assert all(total == 4 for _, total, _ in seen) and seen[-1][0] == 4


def test_level_result_describes_itself_in_one_line_and_a_table():
    res = am.level(SAMPLES / "level_survey.csv", base=SAMPLES / "level_base.csv", lag=0.4)
    text = repr(res)
    assert "\n" not in text and text.startswith("LevelResult(samples=4350, lines / ties=8 / 5")
    assert "mistie_std_nT=" in text and "dof" in text and "warning" not in text
    page = res._repr_html_()
    assert page.startswith("<table>") and "effective parameters" in page


def test_stacked_profiles_take_adjacent_lines_of_one_block():
    # Two blocks side by side along E-W lines (as Osborne's two networks): lines 1-8 over
    # x 0-3 km, lines 101-108 over x 4-7 km, across-line positions interleaved. The profiles
    # must be neighbours across one block, not lines of both stacked by number.
    rng = np.random.default_rng(4)
    parts = []
    for base, x0, y0 in ((1, 0.0, 0.0), (101, 4000.0, 100.0)):
        for k in range(8):
            x = np.arange(x0, x0 + 3000.0, 15.0)
            y = np.full_like(x, y0 + 200.0 * k) + rng.normal(0, 1, x.size)
            parts.append(pd.DataFrame({"x_m": x, "y_m": y, "line": base + k,
                                       "mag": 20 * np.sin(x / 700.0) + rng.normal(0, .1, x.size)}))
    df = pd.concat(parts, ignore_index=True)
    from pyproj import Transformer

    from aeromag.plot.levelling import plot_stacked_profiles

    tr = Transformer.from_crs(32633, 4326, always_xy=True)
    lon_, lat_ = tr.transform(df["x_m"].to_numpy() + 500_000.0, df["y_m"].to_numpy() + 5e6)
    df = df.drop(columns=["x_m", "y_m"]).assign(lat=lat_, lon=lon_, alt=100.0)
    res = am.level(df, igrf=False, method="none")
    fig = plot_stacked_profiles(res, n_lines=6)
    labels = sorted(int(float(t.get_text())) for t in fig.axes[0].texts)
    assert len(labels) == 6
    assert all(v < 100 for v in labels) or all(v > 100 for v in labels), labels
