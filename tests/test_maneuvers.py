"""Manoeuvre and heading-leg detection on the simulated calibration box."""

from __future__ import annotations

import numpy as np
import pytest

from aeromag.errors import InputError
from aeromag.qc.maneuvers import MANEUVERS, detect_maneuvers, moving_mean
from aeromag.synthetic import simulate_calibration


@pytest.fixture(scope="module")
def cal():
    return simulate_calibration(seed=3, n_boxes=1)[0]


def test_finds_the_12_manoeuvres_of_the_box(cal):
    r = detect_maneuvers(cal)
    assert r.method == "attitude"
    assert len(r.table) == 12
    assert r.complete_boxes == [0]
    got = set(zip(r.table["heading_leg"], r.table["maneuver"], strict=True))
    assert got == {(h, m) for h in range(4) for m in MANEUVERS}
    m = cal["truth_maneuver"].isin(MANEUVERS).to_numpy()
    assert (r.labels["heading_leg"].to_numpy()[m] == cal["truth_heading_leg"].to_numpy()[m]).all()
    agree = (r.labels["maneuver"].to_numpy()[m] == cal["truth_maneuver"].to_numpy()[m]).mean()
    assert agree > 0.95
    # Every detected interval lies inside the true manoeuvre of the same name.
    for row in r.table.itertuples():
        sel = (cal["time"] >= row.t_start) & (cal["time"] <= row.t_end)
        assert (cal.loc[sel, "truth_maneuver"] == row.maneuver).mean() > 0.9


def test_two_boxes_with_kept_turns():
    df = simulate_calibration(seed=4, n_boxes=2, cut_turns=False)[0]
    r = detect_maneuvers(df)
    assert r.complete_boxes == [0, 1]
    assert len(r.table) == 24
    assert (r.labels["maneuver"].to_numpy()[df["truth_maneuver"] == "turn"] == "").mean() > 0.7


def test_user_column_and_fluxgate_legs(cal):
    r = detect_maneuvers(cal, maneuver_column="truth_maneuver")
    assert r.method == "column:truth_maneuver"
    assert len(r.table) == 12
    flux_only = cal.drop(columns=["heading", "pitch", "roll"])
    r2 = detect_maneuvers(flux_only)
    assert r2.method == "fluxgate"
    m = cal["truth_maneuver"].isin(MANEUVERS).to_numpy()
    assert (r2.labels["heading_leg"].to_numpy()[m] == cal["truth_heading_leg"].to_numpy()[m]).all()
    # Pitch is always separable from roll on N/S headings (roll/yaw ambiguity documented).
    ns = r2.table[r2.table["heading"].isin(["N", "S"])]
    assert (ns["maneuver"] == "pitch").sum() >= 1


def test_errors(cal):
    with pytest.raises(InputError):
        detect_maneuvers(cal.iloc[:5])
    with pytest.raises(InputError):
        detect_maneuvers(cal, maneuver_column="nope")


def test_moving_mean_respects_stretches():
    x = np.r_[np.zeros(5), np.full(5, 10.0)]
    st = np.r_[np.zeros(5, int), np.ones(5, int)]
    assert np.allclose(moving_mean(x, st, 3), x)
    st[2] = -1
    assert np.isnan(moving_mean(x, st, 1)[2])
