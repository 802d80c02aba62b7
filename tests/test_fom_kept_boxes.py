"""The kept FOM is the sum of 12 peak-to-peak values of a wholly kept box, never fewer.

Before: the report's "manoeuvres in kept segments" FOM averaged a box of which only 9 of its
12 manoeuvres were kept (its 9-manoeuvre sum, 79.6 nT before) with two complete 12-manoeuvre
boxes (109.6 nT), under the label "sum of 12 p-p": 99.63 -> 1.086 nT, reduction 91.7, where
the two wholly kept boxes give 109.66 -> 1.161 nT, reduction 94.5 (review 17, cal_fault.csv).
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.compensation.pipeline import run_compensation as compensate
from aeromag.qc import compute_qc, fom_summary
from aeromag.qc.maneuvers import MANEUVERS
from aeromag.synthetic import simulate_calibration
from aeromag.workflows.report import render_html


def _table(n_boxes: int, dropped: dict[int, int]) -> pd.DataFrame:
    """A FOM table: box b's manoeuvres ptp before b + 1, after 0.1 (b + 1) nT each;
    ``dropped[b]`` of box b's manoeuvres (the first ones) in dropped segments."""
    rows = []
    for b in range(n_boxes):
        i = 0
        for h in range(4):
            for m in MANEUVERS:
                rows.append({"id": len(rows), "box": b, "heading_leg": h, "heading": "NESW"[h],
                             "maneuver": m, "t_start": 0.0, "t_end": 1.0,
                             "ptp_before_nT": float(b + 1), "ptp_after_nT": 0.1 * (b + 1),
                             "kept": i >= dropped.get(b, 0)})
                i += 1
    return pd.DataFrame(rows)


def test_partly_dropped_box_has_no_kept_fom_hand_case():
    """Boxes 0 and 2 wholly kept (12 and 36 nT before), box 1 with 3 dropped: kept FOM 24 nT."""
    s = fom_summary(_table(3, {1: 3}))
    assert s.applicable and s.complete_boxes == [0, 1, 2]
    assert s.fom_before_nT == pytest.approx(24.0)  # all data: every box, as before
    assert s.fom_kept_before_nT == pytest.approx((12.0 + 36.0) / 2)  # was (12+18+36)/3
    assert s.fom_kept_after_nT == pytest.approx((1.2 + 3.6) / 2)
    assert s.kept_applicable and s.kept_boxes == [0, 2]
    b1 = s.boxes[1]
    assert b1.fom_kept_before_nT is None and b1.fom_kept_after_nT is None
    assert b1.kept_reason == "box 1: 3 of its 12 manoeuvres in dropped segments"
    assert b1.fom_before_nT == pytest.approx(24.0)  # its all-data FOM stays
    assert s.boxes[0].kept_reason is None
    assert "box 1: 3 of its 12 manoeuvres in dropped segments" in s.kept_reason
    # every box wholly kept: no reason, the kept FOM is the all-data FOM
    s = fom_summary(_table(2, {}))
    assert s.kept_reason is None and s.kept_boxes == [0, 1]
    assert s.fom_kept_before_nT == s.fom_before_nT


def test_no_wholly_kept_box_kept_fom_not_applicable_hand_case():
    s = fom_summary(_table(2, {0: 1, 1: 12}))
    assert s.applicable and s.fom_before_nT == pytest.approx(18.0)
    assert s.fom_kept_before_nT is None and s.fom_kept_after_nT is None
    assert not s.kept_applicable and s.kept_boxes == []
    assert "not applicable" in s.kept_reason
    assert "box 0: 1 of its 12 manoeuvres in dropped segments" in s.kept_reason
    assert "box 1: 12 of its 12 manoeuvres in dropped segments" in s.kept_reason


@pytest.fixture(scope="module")
def faulted():
    """Two simulated boxes; segments 3 and 4 (box 0's E pitch and E roll) a noise burst."""
    df, _ = simulate_calibration(seed=4, n_boxes=2, faults={3: "noise_burst", 4: "noise_burst"})
    res = compensate(df)
    assert res.report.screening.dropped == [3, 4]
    return res


def test_kept_fom_only_from_the_wholly_kept_box(faulted):
    q = compute_qc(faulted, fit=False)
    fom = q.metrics.fom
    b0, b1 = fom.boxes
    assert b0.n_maneuvers_kept == 10 and sorted(b0.dropped) == ["E pitch", "E roll"]
    # the kept FOM is box 1's 12-manoeuvre sum, not the mean with box 0's 10-manoeuvre one
    for c in ("before", "after"):
        assert getattr(fom, f"fom_kept_{c}_nT") == getattr(b1, f"fom_{c}_nT")
        assert getattr(fom, f"fom_{c}_nT") == pytest.approx(
            (getattr(b0, f"fom_{c}_nT") + getattr(b1, f"fom_{c}_nT")) / 2)
    assert fom.complete_boxes == [0, 1] and fom.kept_boxes == [1]
    kept1 = q.fom[(q.fom["box"] == 1)]
    assert fom.fom_kept_before_nT == pytest.approx(kept1["ptp_before_nT"].sum())
    assert b0.fom_kept_after_nT is None
    why = "box 0: 2 of its 12 manoeuvres in dropped segments"
    assert b0.kept_reason == why and why in fom.kept_reason
    assert fom.kept_reason in q.metrics.notes
    # the page shows the reason in the FOM section
    page = render_html(q.metrics, faulted.report, {})
    sec = page.split("<h2>Figure of Merit</h2>")[1].split("<h2>")[0]
    assert why in sec


def test_one_box_with_a_dropped_manoeuvre_report_cli(tmp_path):
    """One box, its E pitch dropped: qc.json and the page say why there is no kept FOM; the
    all-data FOM is still given."""
    df, _ = simulate_calibration(seed=4, n_boxes=1, faults={3: "noise_burst"})
    df.to_csv(tmp_path / "cal.csv", index=False)
    runner = CliRunner()
    for argv in (["compensate", str(tmp_path / "cal.csv"), "-o", str(tmp_path / "c.csv")],
                 ["report", str(tmp_path / "c.csv"), "-o", str(tmp_path / "rep")]):
        r = runner.invoke(app, argv)
        assert r.exit_code == 0, r.output
    fom = json.loads((tmp_path / "rep" / "qc.json").read_text())["fom"]
    assert fom["applicable"] and np.isfinite(fom["fom_after_nT"])
    assert fom["fom_kept_before_nT"] is None and fom["fom_kept_after_nT"] is None
    assert fom["kept_applicable"] is False and fom["kept_boxes"] == []
    why = "box 0: 1 of its 12 manoeuvres in dropped segments"
    assert why in fom["kept_reason"] and "not applicable" in fom["kept_reason"]
    page = (tmp_path / "rep" / "report.html").read_text()
    sec = page.split("<h2>Figure of Merit</h2>")[1].split("<h2>")[0]
    assert why in sec
