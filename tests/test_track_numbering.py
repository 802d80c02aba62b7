"""Every leg number the track check gives the user is the plan's, whichever direction decoded.

Before: a partial flight decoded against the plan reversed (legs 10 -> 8 of an 11-leg plan
flown backwards, 8 m beside it) warned "leg(s) 3, 4, 5, 6, 7, 8, 9, 10 of plan.csv have no
sample" (the reversed plan's numbering: its legs 0-2 are the plan's 10-8) while the same run
flagged legs 8, 9 and 10 and reported legs 0-7 unchecked: the two lists overlapped.  The
flights here are drawn by a small numpy generator of their own (lines along east, a climb, a
transit to the first leg, straight legs with hovers at the waypoints, a transit home, a
landed period), flown in any subset and order of legs, each leg either way, beside the plan.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from aeromag._core.geodesy import geodetic_to_ned, ned_to_geodetic
from aeromag.cli import app
from aeromag.track import check_track

ORIGIN = (46.0, 8.0, 500.0)
HEIGHT = 40.0


def _plan(n_lines: int, line_m: float, spacing_m: float) -> np.ndarray:
    """Lawn-mower waypoints (NED, m): lines along east, spaced north, joined by cross legs."""
    pts = []
    for i in range(n_lines):
        a, b = (0.0, line_m) if i % 2 == 0 else (line_m, 0.0)
        pts += [(i * spacing_m, a, -HEIGHT), (i * spacing_m, b, -HEIGHT)]
    return np.array(pts)


def _move(p0: np.ndarray, p1: np.ndarray, v: float, fs: float) -> np.ndarray:
    n = max(1, int(np.ceil(np.linalg.norm(p1 - p0) / v * fs)))
    return p0 + (np.arange(1, n + 1) / n)[:, None] * (p1 - p0)


def flight(legs: list[int], *, backwards: bool, offset_north_m: float = 0.0,
           n_lines: int = 6, line_m: float = 300.0, spacing_m: float = 50.0, seed: int = 0,
           fs: float = 10.0) -> tuple[pd.DataFrame, pd.DataFrame, np.ndarray]:
    """The plan's ``legs`` flown in that order (each end to start when ``backwards``), the
    whole flight ``offset_north_m`` north of the plan; the log, the plan and the true leg of
    each row (-1 off the legs)."""
    rng = np.random.default_rng(seed)
    wps = _plan(n_lines, line_m, spacing_m)
    home = np.array([-80.0, -60.0, 0.0]) - np.array([offset_north_m, 0.0, 0.0])
    up = home + np.array([0.0, 0.0, -HEIGHT])
    parts = [(np.repeat(home[None], int(5 * fs), 0), -1), (_move(home, up, 2.0, fs), -1)]
    cur = up
    for k in legs:
        a, b = (wps[k + 1], wps[k]) if backwards else (wps[k], wps[k + 1])
        if np.linalg.norm(cur - a) > 0.01:
            parts.append((_move(cur, a, 8.0, fs), -1))
        parts += [(np.repeat(a[None], int(2 * fs), 0), -1), (_move(a, b, 8.0, fs), k)]
        cur = b
    parts += [(np.repeat(cur[None], int(2 * fs), 0), -1), (_move(cur, up, 8.0, fs), -1),
              (_move(up, home, 2.0, fs), -1), (np.repeat(home[None], int(20 * fs), 0), -1)]
    ned = np.vstack([p for p, _ in parts]) + np.array([offset_north_m, 0.0, 0.0])
    truth = np.concatenate([np.full(len(p), k) for p, k in parts])
    g = ned_to_geodetic(ned + rng.normal(0.0, 0.05, ned.shape), ORIGIN)
    log = pd.DataFrame({"time": 1.7e9 + np.arange(len(ned)) / fs, "lat": g[:, 0],
                        "lon": g[:, 1], "alt": g[:, 2]})
    pg = ned_to_geodetic(wps, ORIGIN)
    return log, pd.DataFrame({"lat": pg[:, 0], "lon": pg[:, 1], "alt": pg[:, 2]}), truth


_NOT_FLOWN = re.compile(r"leg\(s\) ([\d, ]+) of .* have no sample")


def not_flown(warnings: list[str]) -> list[int] | None:
    """The legs the warnings name as having no sample (None: no such warning)."""
    hits = [m for w in warnings if (m := _NOT_FLOWN.search(w))]
    assert len(hits) <= 1, warnings
    return [int(x) for x in hits[0].group(1).split(",")] if hits else None


def check_consistent(report: dict, data: pd.DataFrame) -> tuple[list[int] | None, list[int]]:
    """The not-flown warning, legs[], flagged_legs, n_legs_checked and the leg column tell one
    story in one numbering; returns (warned not flown, flagged)."""
    legs = report["legs"]
    assert [row["leg"] for row in legs] == list(range(report["n_legs"]))
    with_rows = sorted(int(k) for k in data["leg"].dropna().unique())
    checked = [row["leg"] for row in legs if row["checked"]]
    assert checked == with_rows
    assert [row["n_samples"] for row in legs] == [
        int((data["leg"] == k).sum()) for k in range(report["n_legs"])]
    assert report["n_legs_checked"] == len(checked)
    flagged = report["flagged_legs"]
    assert set(flagged) <= set(checked)
    missing = not_flown(report["warnings"])
    if missing is not None:
        assert missing == [k for k in range(report["n_legs"]) if k not in checked]
        assert not set(missing) & set(flagged)
    return missing, flagged


def test_the_reviewers_partial_reversed_flight_names_the_plans_legs():
    # legs 10, 9, 8 of 11 flown backwards, 8 m beside the plan; before: "leg(s) 3, 4, 5, 6, 7,
    # 8, 9, 10 ... have no sample" next to flagged legs [8, 9, 10]
    log, plan, truth = flight([10, 9, 8], backwards=True, offset_north_m=8.0)
    res = check_track(log, plan)
    assert res.report.plan_check["assignment"]["direction"] == "reversed"
    missing, flagged = check_consistent(res.report.to_dict(), res.data)
    assert missing == list(range(8))
    assert {8, 10} <= set(flagged) <= {8, 9, 10}   # the lines 8 m beside; the cross leg 9
    lab = res.data["leg"].fillna(-1).to_numpy()
    on = truth >= 0
    assert (lab[on] == truth[on]).mean() > 0.9
    assert ((lab >= 0) & on & (lab != truth)).sum() == 0


@pytest.mark.parametrize("backwards", [False, True], ids=["as-planned", "backwards"])
@pytest.mark.parametrize("order", ["forward", "reversed"])
@pytest.mark.parametrize("offset_m", [0.0, 8.0])
@pytest.mark.parametrize("subset", [(0, 1, 2), (8, 9, 10), (2, 4, 6), tuple(range(11))],
                         ids=["first3", "last3", "lines", "all"])
def test_not_flown_and_flagged_are_in_plan_numbering_and_disjoint(backwards, order,
                                                                   offset_m, subset):
    legs = list(subset)[::-1] if order == "reversed" else list(subset)
    log, plan, truth = flight(legs, backwards=backwards, offset_north_m=offset_m, seed=3)
    res = check_track(log, plan)
    missing, flagged = check_consistent(res.report.to_dict(), res.data)
    flown = set(subset)
    checked = {row.leg for row in res.legs if row.checked}
    assert flown <= checked
    if missing is not None:
        assert set(missing) <= set(range(11)) - flown
    if len(flown) < 11 and res.report.plan_check["mismatch"] in (None, "reversed"):
        # nothing else to say about the plan: the legs not flown are named
        assert missing is not None
    # beside the plan (north), the east-west lines alarm; on it, nothing does
    lines = sorted(k for k in flown if k % 2 == 0)
    if offset_m > 0:
        assert set(lines) <= set(flagged)
    else:
        assert flagged == []


@settings(max_examples=12, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(subset=st.sets(st.integers(0, 6), min_size=1, max_size=7),
       reverse_order=st.booleans(), backwards=st.booleans(),
       offset_m=st.sampled_from([0.0, 3.0, 8.0]), seed=st.integers(0, 1000))
def test_the_warned_not_flown_legs_are_the_complement_of_the_legs_with_samples(
        subset, reverse_order, backwards, offset_m, seed):
    legs = sorted(subset, reverse=reverse_order)
    log, plan, _ = flight(legs, backwards=backwards, offset_north_m=offset_m, n_lines=4,
                          line_m=200.0, seed=seed, fs=5.0)
    res = check_track(log, plan)
    missing, _ = check_consistent(res.report.to_dict(), res.data)
    complement = [row.leg for row in res.legs if not row.checked]
    if missing is not None:
        assert missing == complement
    elif res.report.plan_check["mismatch"] is None:
        assert complement == []


def test_cli_outputs_and_map_use_the_plans_numbering(tmp_path):
    pytest.importorskip("matplotlib")
    log, plan, truth = flight([10, 9, 8], backwards=True, offset_north_m=8.0, seed=1)
    log.to_csv(tmp_path / "log.csv", index=False)
    plan.to_csv(tmp_path / "plan.csv", index=False)
    out = tmp_path / "out.csv"
    r = CliRunner().invoke(app, ["track", str(tmp_path / "log.csv"), "--plan",
                                 str(tmp_path / "plan.csv"), "-o", str(out),
                                 "--plot", str(tmp_path / "plots")])
    assert r.exit_code == 0, r.output
    assert "leg(s) 0, 1, 2, 3, 4, 5, 6, 7 of" in r.output
    rep = json.loads(out.with_suffix(".json").read_text())
    # the summary line names the flagged legs as OUT.json does
    assert f"({', '.join(map(str, rep['flagged_legs']))})" in r.output.splitlines()[-1]
    data = pd.read_csv(out)
    data["leg"] = data["leg"].astype("Int64")
    missing, flagged = check_consistent(rep, data)
    assert missing == list(range(8)) and {8, 10} <= set(flagged) <= {8, 9, 10}
    lab = data["leg"].fillna(-1).to_numpy()
    assert (lab[truth >= 0] == truth[truth >= 0]).mean() > 0.9

    from aeromag.plot.track import plot_track_map

    res = check_track(log, plan)
    fig = plot_track_map(res)
    ax = fig.axes[0]
    assert str(flagged) in ax.get_title()
    # each leg's label sits at the middle of the plan's leg of that number
    wps = geodetic_to_ned(plan["lat"], plan["lon"], plan["alt"], tuple(plan.iloc[0]))
    labels = {int(t.get_text()): t.xy for t in ax.texts}
    assert sorted(labels) == list(range(11))
    for k, (east, north) in labels.items():
        mid = 0.5 * (wps[k] + wps[k + 1])
        assert (north, east) == pytest.approx((mid[0], mid[1]), abs=1e-6)
