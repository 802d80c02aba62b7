"""How the summary, OUT.json and the HTML name what a fit left out (issue 15, item 10).

Segments screened out and segments too short to fit are told apart; segments that are no
flight lines (time windows, or heading legs / maneuvers detected in a log without a ``line``
column) are named ``segment 9 (240.0–258.9 s)``, never ``line 9``.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.compensation import CompensationReport, SegmentRow
from aeromag.compensation.report import dropped_summary, segment_name

SAMPLES = Path(__file__).resolve().parents[1] / "data_samples"
runner = CliRunner()
NAME = re.compile(r"segment (\d+) \((\d+\.\d)–(\d+\.\d) s\)")


def _summary_line(output: str) -> str:
    lines = [ln for ln in output.splitlines() if ln.startswith("wrote ") and "segments kept" in ln]
    assert len(lines) == 1, output
    return lines[0]


def _not_kept(rep: dict) -> list[dict]:
    return [e for e in rep["segments"] if not e["kept"]]


def _dropped_html_rows(page: str) -> list[list[str]]:
    """Cells of the dropped rows of the HTML's segment table."""
    table = page[page.index("Lines and segments"):]
    rows = re.findall(r"<tr class='dropped'>(.*?)</tr>", table)
    return [re.findall(r"<td>(.*?)</td>", r) for r in rows]


def test_calibrate_without_lines_names_segments_by_id_and_time(tmp_path):
    """The calibration box without its line column: the detected maneuvers are the segments;
    the faulty one (9) was called "line 9" in the summary, the model file and the HTML."""
    src = tmp_path / "cal_nolines.csv"
    pd.read_csv(SAMPLES / "calibration.csv").drop(columns="line").to_csv(src, index=False)
    model = tmp_path / "m.json"
    r = runner.invoke(app, ["calibrate", str(src), "-o", str(model), "--plot",
                            str(tmp_path / "plot")])
    assert r.exit_code == 0, r.output
    line = _summary_line(r.output)
    rep = json.loads(model.read_text())
    assert rep["segmentation"]["method"] == "detected maneuvers"
    (e,) = _not_kept(rep)
    assert "line" not in e and all("line" not in s for s in rep["segments"])
    m = NAME.fullmatch(e["name"])
    assert m and int(m[1]) == e["id"]
    assert float(m[2]) == pytest.approx(e["start_time"], abs=0.05)
    assert float(m[3]) == pytest.approx(e["end_time"], abs=0.05)
    assert f"(dropped 1 segment: {e['name']})" in line and "line " not in line
    assert "line" not in e["reason"]
    page = (tmp_path / "plot" / "report.html").read_text()
    (cells,) = _dropped_html_rows(page)
    assert cells[0] == str(e["id"]) and cells[1] in ("", "–")  # no line number
    assert f"line {e['id']}" not in re.sub(r"src='data:[^']*'", "", page)
    # With its lines the same flight names the line.
    r = runner.invoke(app, ["calibrate", str(SAMPLES / "calibration.csv"), "-o",
                            str(tmp_path / "m2.json")])
    assert "(dropped 1 segment: line 9)" in r.output


@pytest.fixture(scope="module")
def survey():
    return pd.read_csv(SAMPLES / "survey.csv")


def test_survey_without_lines_time_windows_are_named_segments(survey, tmp_path):
    src = tmp_path / "nolines.csv"
    survey.drop(columns="line").to_csv(src, index=False)
    out = tmp_path / "o.csv"
    r = runner.invoke(app, ["compensate", str(src), "-o", str(out)])
    assert r.exit_code == 0, r.output
    rep = json.loads(out.with_suffix(".json").read_text())
    (e,) = _not_kept(rep)
    assert "line" not in e and NAME.fullmatch(e["name"])
    assert f"(dropped 1 segment: {e['name']})" in _summary_line(r.output)


def test_too_short_segments_are_listed_apart_with_reason_times_and_n(survey, tmp_path):
    """A short piece of line 9 relabelled 77: not fitted (too short), said apart from the
    screened-out line 2, and kept in OUT.json with its reason, times and sample count."""
    df = survey.copy()
    short = df["time"] > 360.0
    df.loc[short, "line"] = 77
    src = tmp_path / "short_line.csv"
    df.to_csv(src, index=False)
    out = tmp_path / "o.csv"
    r = runner.invoke(app, ["compensate", str(src), "-o", str(out)])
    assert r.exit_code == 0, r.output
    line = _summary_line(r.output)
    assert "(dropped 1 segment: line 2; 1 segment not fitted (too short): line 77)" in line
    rep = json.loads(out.with_suffix(".json").read_text())
    e77 = next(e for e in rep["segments"] if e["id"] == 77)
    assert e77["kept"] is False and e77["too_short"] is True
    assert e77["reason"].startswith("too short to fit: ") and e77["name"] == "line 77"
    assert e77["n"] == int(short.sum())
    t = df.loc[short, "time"]
    assert (e77["start_time"], e77["end_time"]) == (pytest.approx(t.min()),
                                                    pytest.approx(t.max()))
    e2 = next(e for e in rep["segments"] if e["id"] == 2)
    assert "too_short" not in e2 and e2["reason"].startswith("PCA outlier")


def test_too_short_time_windows_are_named_by_time(survey, tmp_path):
    """Without lines: a gap leaves two pieces of the last line too short to fit; named
    ``segment N (a–b s)`` in the summary, listed in OUT.json."""
    df = survey.drop(columns="line")
    df = df[~((df["time"] > 350.0) & (df["time"] < 356.0))]
    src = tmp_path / "gap.csv"
    df.to_csv(src, index=False)
    out = tmp_path / "o.csv"
    r = runner.invoke(app, ["compensate", str(src), "-o", str(out)])
    assert r.exit_code == 0, r.output
    rep = json.loads(out.with_suffix(".json").read_text())
    short = [e for e in rep["segments"] if e.get("too_short")]
    assert len(short) == 2
    for e in short:
        assert "line" not in e and NAME.fullmatch(e["name"]) and e["n"] > 0
        assert e["start_time"] > 340.0
    line = _summary_line(r.output)
    assert f"2 segments not fitted (too short): {short[0]['name']}, {short[1]['name']}" in line
    assert "line" not in line.split("kept")[1].split(";")[0]


def test_dropped_summary_phrases():
    segs = [{"id": 1, "kept": True},
            {"id": 2, "kept": False, "line": 2, "name": "line 2"},
            {"id": 3, "kept": False, "line": 3, "name": "line 3"},
            {"id": 7, "kept": False, "reason": "too short to fit", "too_short": True,
             "start_time": 120.0, "end_time": 185.31, "name": "segment 7 (120.0–185.3 s)"}]
    assert dropped_summary(CompensationReport.from_dict({"segments": segs})) == (
        "dropped 2 segments: line 2, line 3; 1 segment not fitted (too short):"
        " segment 7 (120.0–185.3 s)")
    assert dropped_summary(CompensationReport.from_dict({"segments": segs[:1]})) == ""
    # Reports written before the names: the phrase is built from the entries.
    old = [{"id": 9, "kept": False, "reason": "too short to fit"}]
    assert (dropped_summary(CompensationReport.from_dict({"segments": old}))
            == "1 segment not fitted (too short): segment 9")
    e = {"id": 9, "line": 9, "start_time": 1.0, "end_time": 2.0}
    assert segment_name(SegmentRow.from_dict(e)) == "line 9"
    assert segment_name(SegmentRow.from_dict(e), lines=False) == "segment 9 (1.0–2.0 s)"
