"""Defects found by the independent review of ``aeromag track`` (plans that do not match the
flight, noisy positions, veering vehicles, --horizontal), each on a small simulated mission."""

from __future__ import annotations

import numpy as np
import pytest

from aeromag.synthetic.mission import simulate_mission
from aeromag.track import check_track


@pytest.fixture(scope="module")
def lawnmower():
    """Three 150 m lines, take-off 36 m away, leg 2 flown twice with the transit back."""
    return simulate_mission(seed=3, n_lines=3, line_m=150.0, home_ne_m=(-30.0, -20.0),
                            ground_s=10.0, refly_legs=(2,))


def test_the_right_plan_gets_no_mismatch(lawnmower):
    df, plan, _ = lawnmower
    res = check_track(df, plan)
    assert res.report["plan_check"]["mismatch"] is None
    assert res.report["warnings"] == []


def test_a_reversed_plan_is_said_to_be_reversed(lawnmower):
    # the transits (back to re-fly leg 2, between lines) follow the reversed plan's legs: more
    # than 1 % of the samples are on a leg, so the old check never compared with the reversal
    df, plan, _ = lawnmower
    rev = plan.iloc[::-1].reset_index(drop=True)
    res = check_track(df, rev)
    chk = res.report["plan_check"]
    assert chk["mismatch"] == "reversed", chk
    assert chk["n_reversed"] > 2 * chk["n_on_leg"] > 0
    assert any("reversed" in w for w in res.report["warnings"])
    # the survey passes are flown backwards along the reversed plan's legs: never assigned
    lab = res.data["leg"].fillna(-1).to_numpy()
    on_truth = (df["truth_phase"] == "leg").to_numpy()
    assert (lab[on_truth] < 0).mean() > 0.95


@pytest.mark.parametrize("shift_m", [15.0, 30.0])
def test_a_plan_of_the_neighbouring_field_is_said_to_be_offset(lawnmower, shift_m):
    df, plan, _ = lawnmower
    sh = plan.copy()
    sh["lon"] += shift_m / (111320.0 * np.cos(np.radians(float(plan["lat"].iloc[0]))))
    res = check_track(df, sh)
    chk = res.report["plan_check"]
    assert chk["mismatch"] == "offset", chk
    assert abs(chk["offset_m"] - shift_m) < 1.0
    assert any("offset or for another field" in w for w in res.report["warnings"])
    assert not any("reversed" in w for w in res.report["warnings"])
