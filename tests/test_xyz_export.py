"""Geosoft XYZ export that Oasis montaj imports: a line header before every row, numbers only.

Oasis reads rows under a ``Line``/``Tie`` header, and its channels are numbers: a log without
``line`` used to get no header at all, and ``segment_kept`` was written as the text ``true``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.io import read_log
from aeromag.io.formats import XYZ_LINE_HEADER, read_xyz, write_xyz

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "data_samples"
runner = CliRunner()


def _data_rows(path: Path) -> list[str]:
    return [x for x in path.read_text().split("\n")[2:] if x]


def test_table_without_line_gets_its_segments_as_lines(tmp_path):
    df = pd.DataFrame({"time": np.arange(7.0), "mag": 50000.0 + np.arange(7.0),
                       "segment": [-1, 0, 0, 1, 1, 1, 2],
                       "segment_kept": [False, True, True, False, False, False, True]})
    p = write_xyz(df, tmp_path / "s.xyz")
    rows = _data_rows(p)
    assert rows[0] == "Line -1"  # a header before the first data row
    assert [r for r in rows if XYZ_LINE_HEADER.match(r)] == ["Line -1", "Line 0", "Line 1",
                                                              "Line 2"]
    assert rows[1] == "0.0 50000.0 -1 0" and rows[3] == "1.0 50001.0 0 1"
    assert "true" not in p.read_text() and "false" not in p.read_text()
    back = read_xyz(p)
    assert back["line"].tolist() == df["segment"].tolist()
    assert back["segment"].tolist() == df["segment"].tolist()
    assert back["segment_kept"].astype(bool).tolist() == df["segment_kept"].tolist()
    np.testing.assert_array_equal(back["mag"].to_numpy(), df["mag"].to_numpy())


def test_table_without_line_or_segment_is_one_line_zero(tmp_path):
    df = pd.DataFrame({"time": [0.0, 1.0, 2.0], "ok": [True, None, False]}).astype(
        {"ok": "boolean"})
    p = write_xyz(df, tmp_path / "n.xyz")
    assert _data_rows(p) == ["Line 0", "0.0 1", "1.0 *", "2.0 0"]
    back = read_xyz(p)
    assert back["line"].tolist() == [0, 0, 0]
    assert back["ok"].tolist()[::2] == [1, 0] and np.isnan(back["ok"].iloc[1])
    # a segment that is no line number (text, fractions) does not stand in for one
    for seg in (["a", "a", "b"], [0.5, 0.5, 1.5]):
        p = write_xyz(df.assign(segment=seg), tmp_path / "t.xyz")
        assert _data_rows(p)[0] == "Line 0"
        assert sum(bool(XYZ_LINE_HEADER.match(r)) for r in _data_rows(p)) == 1


def test_line_column_still_decides_the_headers(tmp_path):
    df = pd.DataFrame({"time": [0.0, 1.0, 2.0], "line": [10, 10, 11], "segment": [3, 4, 4],
                       "segment_kept": [True, True, False]})
    p = write_xyz(df, tmp_path / "l.xyz")
    assert _data_rows(p) == ["Line 10", "0.0 3 1", "1.0 4 1", "Line 11", "2.0 4 0"]


@pytest.fixture(scope="module")
def noline_run(tmp_path_factory):
    """'aeromag compensate' of the survey without its line column, to CSV and to XYZ."""
    d = tmp_path_factory.mktemp("xyz_export")
    log = d / "noline.csv"
    pd.read_csv(SAMPLES / "survey.csv").drop(columns=["line"]).to_csv(log, index=False)
    for ext in ("csv", "xyz"):
        r = runner.invoke(app, ["compensate", str(log), "-o", str(d / f"o.{ext}")])
        assert r.exit_code == 0, r.output
    return d


def test_compensate_xyz_of_a_log_without_lines_reads_back(noline_run):
    d = noline_run
    want = read_log(d / "o.csv")
    rows = _data_rows(d / "o.xyz")
    assert XYZ_LINE_HEADER.match(rows[0])
    n_seg = want["segment"].nunique()
    assert sum(bool(XYZ_LINE_HEADER.match(r)) for r in rows) == n_seg > 1
    got = read_log(d / "o.xyz")
    assert len(got) == len(want)
    for c in ("mag_comp", "mag_tl", "segment"):
        np.testing.assert_array_equal(got[c].to_numpy(), want[c].to_numpy())
    assert got["line"].tolist() == want["segment"].tolist()
    kept = want["segment_kept"].astype(str).str.lower().eq("true").tolist()
    assert got["segment_kept"].tolist() == [int(k) for k in kept]


def test_report_reads_the_xyz_as_the_csv(noline_run):
    d = noline_run
    qc = {}
    for ext in ("csv", "xyz"):
        r = runner.invoke(app, ["report", str(d / f"o.{ext}"), "-o", str(d / f"rep_{ext}")])
        assert r.exit_code == 0, r.output
        qc[ext] = json.loads((d / f"rep_{ext}" / "qc.json").read_text())
    a, b = qc["csv"], qc["xyz"]
    for key in ("improvement_ratio", "residual_std_nT"):
        va, vb = a.get(key), b.get(key)
        if va is None:  # nested under metrics in some versions
            va, vb = a["metrics"][key], b["metrics"][key]
        assert va == pytest.approx(vb, rel=1e-9)
