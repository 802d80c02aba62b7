"""Plain (non-RTK) GNSS: ferries converging on a line must not be taken for the line.

The flights are those of ``tests/test_track_reversed_offset.py`` (an independent numpy
generator: 5 lines of 300 m, 40 m apart, the plan's cross legs flown too) with a plain GNSS
error: a 1.5 m Gauss-Markov part (tau 120 s) and 0.3 m white noise per axis, threshold 6 m.
Flown with the legs in reverse order, or each leg end to start in mission order, the ferries
between a line and the next cross leg run 8 deg off the lines, converging on (or diverging
from) them.

Before: the on-line gate was widened to 4 sigma (about 6 m, more with the ferries in the
scatter), the same as the widened tolerance, so every run the decoding kept was within the gate
and passed the "min(5 s, half the run) within the gate" rule: 1,270-1,600 ferry rows were given
a leg and 470-1,000 rows alarmed off the legs at offsets 0-10 m (1,230-1,530 at 20 m), the
cross leg 7 flagged by a ferry.  A pass is parallel to its line: a run is now kept only when it
has a stretch of that length within the gate whose lateral distance has no steady slope.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest

from aeromag.track import check_track
from aeromag.track.assign import drop_transit_runs

from .test_track_reversed_offset import flight

PLAIN = {"gm_m": 1.5, "gm_tau_s": 120.0, "white_m": 0.3}
THRESHOLD_M = 6.0


def _run(reverse_order: bool, reverse_direction: bool, offset_m: float, seed: int):
    log, plan, truth, phase = flight(reverse_order=reverse_order,
                                     reverse_direction=reverse_direction, offset_m=offset_m,
                                     seed=seed, **PLAIN)
    logging.disable(logging.WARNING)
    try:
        res = check_track(log, plan, threshold_m=THRESHOLD_M)
    finally:
        logging.disable(logging.NOTSET)
    return res, truth, phase


@pytest.mark.parametrize(("reverse_order", "reverse_direction"), [(True, False), (False, True)])
@pytest.mark.parametrize(("offset_m", "seed"), [(0.0, 1), (10.0, 3), (20.0, 1)])
def test_ferries_converging_on_the_lines_are_not_legs_on_plain_gnss(
        reverse_order, reverse_direction, offset_m, seed):
    # before: 1,273-1,407 ferry rows on legs and 490-890 alarms off legs at 0 and 10 m,
    # 1,226-1,329 at 20 m; leg 7 (a cross leg) flagged by a ferry
    res, truth, phase = _run(reverse_order, reverse_direction, offset_m, seed)
    lab = res.data["leg"].fillna(-1).to_numpy()
    on = truth >= 0
    alarm = res.data["alarm"].to_numpy().astype(bool)
    assert int(((lab >= 0) & ~on).sum()) == 0
    assert int((alarm & ~on).sum()) == 0
    assert (lab[np.isin(phase, ["landed", "ground"])] < 0).all()
    assert (lab[on] == truth[on]).mean() > 0.95
    assert ((lab >= 0) & on & (lab != truth)).sum() == 0
    lines = [0, 2, 4, 6, 8]   # the east offset is across the lines, along the cross legs
    assert res.report.flagged_legs == (lines if offset_m > THRESHOLD_M else [])
    a = res.report.plan_check["assignment"]
    assert a["direction"] == ("reversed" if reverse_direction else "as planned")


def test_drop_transit_runs_drops_a_converging_ferry_within_a_wide_gate():
    # a gate as wide as the decoded run (plain GNSS): the ferry's last 75 m, 8 deg off the
    # line, are all within 10 m of it; a pass wandering by 1.5 m (and a pass that starts on
    # its line and then veers) stays
    rng = np.random.default_rng(0)
    wps = np.array([[0.0, 0.0, 0.0], [300.0, 0.0, 0.0]])
    t = np.arange(600) * 0.1
    x = 5.0 * t
    z = np.zeros_like(x)
    ferry = np.c_[x, 0.14 * (300.0 - x), z]
    lab = np.where(x >= 225.0, 0, -1)
    out, n = drop_transit_runs(lab, ferry, t, wps, 10.0)
    assert n == 1 and (out < 0).all()
    wander = 1.5 * np.sin(2 * np.pi * t / 60.0) + rng.normal(0.0, 0.3, t.size)
    out, n = drop_transit_runs(np.zeros(600, dtype=int), np.c_[x, wander, z], t, wps, 6.0)
    assert n == 0 and (out == 0).all()
    veer = np.c_[x, np.clip(x - 50.0, 0.0, None) * 0.2 + rng.normal(0.0, 0.3, t.size), z]
    out, n = drop_transit_runs(np.zeros(600, dtype=int), veer, t, wps, 6.0)
    assert n == 0 and (out == 0).all()


def test_a_run_of_two_fixes_across_a_time_gap_is_kept():
    # the shipped survey sample (turns cut out) has its 25 m cross legs as two fixes 18 s
    # apart: two points show no trend, the gate decides (a first version dropped all nine and
    # changed the batch golden)
    wps = np.array([[0.0, 0.0, 0.0], [0.0, 25.0, 0.0]])
    ned = np.array([[0.0, 0.02, 0.0], [0.02, 25.0, 0.0]])
    out, n = drop_transit_runs(np.zeros(2, dtype=int), ned, np.array([20.0, 38.2]), wps, 2.0)
    assert n == 0 and (out == 0).all()
