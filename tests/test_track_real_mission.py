"""A day's work in one log (issue 30, "Track on a real mission").

A real ArduCopter log: one 100 m leg flown forward six times at the plan's altitude (about
20 m above the take-off point); between flights the disarmed vehicle is on the ground, 19-21 m
below the plan, carried back along the line.  ``track`` called the plan "reversed" and the
log "a constant 21.0 m below the plan", gave the leg to 179 ground rows, none of the six passes,
and raised 172 alarms.  Reproduced here in the project's simulator (``flights=6``) and in an
independent generator (other timing, noise, a GNSS altitude bias, terrain, two legs).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from aeromag._core.geodesy import ned_to_geodetic
from aeromag._core.runs import true_runs
from aeromag.cli import app
from aeromag.errors import InputError
from aeromag.synthetic.mission import simulate_mission
from aeromag.track import check_track

ORIGIN = (52.1, -1.3, 120.0)


def _passes_found(res, truth_leg: np.ndarray, min_share: float = 0.9) -> list[float]:
    """Share of each true pass's rows given its leg."""
    lab = res.data["leg"].fillna(-1).to_numpy(dtype=np.int64)
    shares = []
    for leg in np.unique(truth_leg[truth_leg >= 0]):
        for a, b in zip(*true_runs(truth_leg == leg), strict=True):
            shares.append(float((lab[a:b] == leg).mean()))
    assert min(shares) >= min_share, shares
    return shares


def _no_leg_on_ground(res, on_ground: np.ndarray) -> None:
    lab = res.data["leg"].fillna(-1).to_numpy(dtype=np.int64)
    assert int((lab[on_ground] >= 0).sum()) == 0
    assert not res.data["alarm"].to_numpy()[on_ground].any()


def _as_planned(res) -> None:
    rep = res.report
    assert rep.altitude_offset["applied_m"] == 0.0
    assert rep.plan_check["assignment"]["direction"] == "as planned"
    assert rep.plan_check["mismatch"] is None
    assert not any("reversed" in w or "below the plan" in w or "beside" in w
                   for w in rep.warnings), rep.warnings


# ----------------------------------------------------------------------- project simulator

@pytest.fixture(scope="module")
def day():
    wps = np.array([[0.0, 0.0, 0.0], [100.0, 0.0, 0.0]])
    return simulate_mission(seed=4, waypoints_ned=wps, height_m=20.0, flights=6, ground_s=10.0,
                            disturbances={}, wp_radius_m=2.0, armed_column=True)


def test_simulator_day_is_the_reported_case(day):
    df, plan, _ = day
    ph = df["truth_phase"].to_numpy()
    assert (np.diff(np.r_[0, (df["truth_leg"] == 0).to_numpy().astype(int)]) == 1).sum() == 6
    carry = ph == "carry"
    assert (np.diff(np.r_[0, carry.astype(int)]) == 1).sum() == 5
    # carried back along the line reversed, about 19-20 m below the plan, disarmed
    below = float(plan["alt"].iloc[0]) - df["alt"].to_numpy()[carry]
    assert 18.8 < below.min() and below.max() < 19.5
    assert not df["armed"].to_numpy()[carry].any()
    assert df["armed"].to_numpy()[ph == "leg"].all()


@pytest.mark.parametrize("armed", [False, True])
def test_simulated_day_gets_its_six_passes(day, armed):
    df, plan, _ = day
    log = df if armed else df.drop(columns=["armed"])
    res = check_track(log, plan)
    ph = df["truth_phase"].to_numpy()
    assert res.legs[0].n_passes == 6
    _passes_found(res, df["truth_leg"].to_numpy())
    _no_leg_on_ground(res, np.isin(ph, ["ground", "carry"]))
    assert not res.data["alarm"].to_numpy()[ph != "leg"].any()
    _as_planned(res)
    g = res.report.ground
    assert g["source"] == ("armed" if armed else "inferred")
    # every carry is inside a ground stretch
    assert g["n_rows"] >= int((ph == "carry").sum())


def test_simulated_day_horizontal_keeps_the_carries_off_the_leg(day):
    # without the vertical term the carries back along the line are the leg reversed, by
    # motion; only the ground rule keeps them off
    df, plan, _ = day
    res = check_track(df.drop(columns=["armed"]), plan, horizontal=True)
    ph = df["truth_phase"].to_numpy()
    assert res.legs[0].n_passes == 6
    _no_leg_on_ground(res, np.isin(ph, ["ground", "carry"]))
    assert res.report.plan_check["assignment"]["direction"] == "as planned"


def test_a_whole_day_flown_30_m_off_is_still_a_datum_named_by_its_passes(day):
    df, plan, _ = day
    res = check_track(df.drop(columns=["armed"]).assign(alt=df["alt"] - 30.0), plan)
    off = res.report.altitude_offset
    assert off["applied_m"] == pytest.approx(-30.0, abs=0.1)
    assert off["n_passes"] == 6 and off["n_passes_at_plan_altitude"] == 0
    msg = next(w for w in res.report.warnings if "30.0 m below the plan" in w)
    assert "6 airborne pass(es)" in msg
    t0, t1 = off["passes"][0][1:]
    assert f"leg 0 {t0:.1f}-{t1:.1f} s" in msg
    assert res.legs[0].n_passes == 6
    _no_leg_on_ground(res, np.isin(df["truth_phase"].to_numpy(), ["ground", "carry"]))


def test_ground_rows_are_no_evidence_even_without_the_ground_rule(day):
    # the datum and direction are chosen by the distance their passes cover, not by the rows
    # (walking is 4 times slower than flying): with the ground rows given as airborne
    # ("armed" everywhere), the passes at the plan's altitude still win
    df, plan, _ = day
    res = check_track(df.assign(armed=True), plan)
    assert res.report.ground["n_rows"] == 0
    _as_planned(res)
    assert res.legs[0].n_passes == 6
    _no_leg_on_ground(res, np.isin(df["truth_phase"].to_numpy(), ["ground", "carry"]))
    # horizontally, the carries are the leg reversed by motion, with 3 times the rows of the
    # passes: the direction is chosen by the distance covered too (before: "reversed", 5
    # passes of carries)
    res = check_track(df.assign(armed=True), plan, horizontal=True)
    _as_planned(res)
    assert res.legs[0].n_passes == 6


def test_a_bad_state_value_is_a_one_line_error(day):
    df, plan, _ = day
    bad = df.assign(armed=df["armed"].astype(object))
    bad.loc[7, "armed"] = "maybe"
    with pytest.raises(InputError, match=r"column 'armed', line 9: 'maybe'"):
        check_track(bad, plan)


# ----------------------------------------------------------------- independent generator

def _segment(p0, p1, speed, dt):
    """Straight segment at a trapezoidal speed (accelerations of 1.5 m/s^2)."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    length = float(np.linalg.norm(p1 - p0))
    acc = 1.5
    ta = speed / acc
    if length < speed * ta:
        ta = np.sqrt(length / acc)
        speed = acc * ta
    total = 2 * ta + (length - speed * ta) / speed
    t = np.arange(0.0, total, dt)
    s = np.where(t < ta, 0.5 * acc * t**2,
                 np.where(t < total - ta, 0.5 * acc * ta**2 + speed * (t - ta),
                          length - 0.5 * acc * (total - t) ** 2))
    return p0 + np.clip(s / length, 0, 1)[:, None] * (p1 - p0)


def _hold(p, seconds, dt):
    return np.repeat(np.asarray(p, float)[None, :], max(1, int(round(seconds / dt))), axis=0)


def day_log(*, seed=0, rate_hz=5.0, flights=6, height=24.0, heading_deg=35.0, legs=(130.0, 70.0),
            turn_deg=70.0, walk=1.4, bias_up=1.8, column=None):
    """Six flights of a two-leg plan, carried back along the legs reversed between them.

    Numpy only: trapezoidal speeds (4 m/s on the legs), hovers at the waypoints, terrain that
    falls 3 m along the first leg, GNSS noise 3 cm white + a 0.15 m random walk per flight in
    height, a constant +1.8 m GNSS altitude bias, a log at 5 Hz with 3 % of the rows dropped.
    Returns the log, the plan and the truth (leg per row, -1 off; on-ground per row).
    """
    rng = np.random.default_rng(seed)
    dt = 1.0 / rate_hz
    h = np.deg2rad(heading_deg)
    u0 = np.array([np.cos(h), np.sin(h)])
    h1 = h + np.deg2rad(turn_deg)
    u1 = np.array([np.cos(h1), np.sin(h1)])
    a = np.zeros(2)
    b = a + legs[0] * u0
    c = b + legs[1] * u1
    plan_up = height

    def ground_up(ne):
        # terrain: down 3 m along the first leg, flat after
        s = np.clip((np.asarray(ne) - a) @ u0 / legs[0], 0.0, 1.0)
        return -3.0 * s

    rows, leg_of, gnd = [], [], []

    def add(ne, up, leg, on_ground):
        rows.append(np.c_[ne, up])
        leg_of.append(np.full(len(ne), leg))
        gnd.append(np.full(len(ne), on_ground))

    for f in range(flights):
        add(_hold(a, 12.0 + 3 * f % 5, dt)[:, :2], np.full(int(round((12.0 + 3 * f % 5) / dt)),
                                                            ground_up(a)), -1, True)
        climb = np.arange(ground_up(a), plan_up, 2.0 * dt)
        add(np.repeat(a[None], len(climb), 0), climb, -1, False)
        add(_hold(a, 4.0, dt), np.full(int(round(4.0 / dt)), plan_up), -1, False)
        for leg, (p, q) in enumerate(((a, b), (b, c))):
            seg = _segment(p, q, 4.0, dt)
            add(seg, np.full(len(seg), plan_up), leg, False)
            add(_hold(q, 3.0, dt), np.full(int(round(3.0 / dt)), plan_up), -1, False)
        down = np.arange(plan_up, ground_up(c), -1.0 * dt)
        add(np.repeat(c[None], len(down), 0), down, -1, False)
        add(_hold(c, 8.0, dt), np.full(int(round(8.0 / dt)), ground_up(c)), -1, True)
        if f < flights - 1:
            # carried by hand along the legs reversed, a metre above the ground, with a bob
            for p, q in ((c, b), (b, a)):
                seg = _segment(p, q, walk, dt)
                tt = np.arange(len(seg)) * dt
                up = np.array([ground_up(x) for x in seg]) + 1.0 + 0.15 * np.sin(2 * np.pi * tt)
                side = 0.6 * np.sin(2 * np.pi * tt / 45.0)
                nrm = np.array([-(q - p)[1], (q - p)[0]]) / np.linalg.norm(q - p)
                add(seg + side[:, None] * nrm, up, -1, True)
    pos = np.vstack(rows)
    truth_leg = np.concatenate(leg_of)
    on_ground = np.concatenate(gnd)
    n = len(pos)
    t = np.arange(n) * dt + rng.uniform(-0.01, 0.01, n)
    noise = rng.normal(0.0, 0.03, (n, 3))
    noise[:, 2] += np.cumsum(rng.normal(0.0, 0.15 / np.sqrt(n), n)) + bias_up
    ned = np.c_[pos[:, :2], -pos[:, 2]] + noise * np.array([1, 1, -1])
    geo = ned_to_geodetic(ned, ORIGIN)
    log = pd.DataFrame({"time": t, "lat": geo[:, 0], "lon": geo[:, 1], "alt": geo[:, 2]})
    if column == "landed":
        log["landed"] = on_ground.astype(int)
    elif column == "armed":
        log["armed"] = np.where(on_ground, "false", "true")
    keep = rng.random(n) > 0.03
    keep[[0, -1]] = True
    wp = ned_to_geodetic(np.array([[*a, -plan_up], [*b, -plan_up], [*c, -plan_up]]), ORIGIN)
    plan = pd.DataFrame({"lat": wp[:, 0], "lon": wp[:, 1], "alt": wp[:, 2]})
    return (log[keep].reset_index(drop=True), plan, truth_leg[keep], on_ground[keep])


@pytest.mark.parametrize("column", [None, "landed", "armed"])
def test_independent_day_gets_its_six_passes_per_leg(column):
    log, plan, truth_leg, on_ground = day_log(column=column)
    res = check_track(log, plan)
    assert [row.n_passes for row in res.legs] == [6, 6]
    _passes_found(res, truth_leg, 0.85)
    _no_leg_on_ground(res, on_ground)
    # the 1.8 m GNSS altitude bias is below a datum (3 m): a deviation on the passes, which
    # alarm; nothing off them does
    assert not res.data["alarm"].to_numpy()[truth_leg < 0].any()
    assert res.report.flagged_legs == [0, 1]
    _as_planned(res)
    assert res.report.ground["source"] == (column or "inferred")
    if column is None:   # without the bias, nothing alarms at all
        clean = check_track(day_log(column=column, bias_up=0.0)[0], plan)
        assert not clean.data["alarm"].any() and clean.report.flagged_legs == []


def test_independent_day_30_m_off_is_a_datum():
    log, plan, truth_leg, on_ground = day_log(seed=2)
    res = check_track(log.assign(alt=log["alt"] + 30.0), plan)
    off = res.report.altitude_offset
    assert off["applied_m"] == pytest.approx(31.8, abs=0.3)   # 30 m + the 1.8 m GNSS bias
    assert off["n_passes"] == 12
    assert [row.n_passes for row in res.legs] == [6, 6]
    _no_leg_on_ground(res, on_ground)


def test_cli_day_log_with_an_armed_column(tmp_path):
    log, plan, truth_leg, on_ground = day_log(seed=3, column="armed", flights=3)
    log.to_csv(tmp_path / "day.csv", index=False)
    plan.to_csv(tmp_path / "plan.csv", index=False)
    out = tmp_path / "out.csv"
    r = CliRunner().invoke(app, ["track", str(tmp_path / "day.csv"), "--plan",
                                 str(tmp_path / "plan.csv"), "-o", str(out)])
    assert r.exit_code == 0, r.output
    rep = json.loads(out.with_suffix(".json").read_text())
    # the rest before the first take-off, each landing + carry + rest, the last landing
    assert rep["ground"]["source"] == "armed" and len(rep["ground"]["spans"]) == 3 + 1
    assert [row["n_passes"] for row in rep["legs"]] == [3, 3]
    lab = pd.read_csv(out)["leg"].to_numpy()
    assert np.isnan(lab[on_ground]).all()


# ----------------------------------------------------------------------- property

@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(heading=st.floats(0.0, 360.0), first=st.floats(60.0, 200.0), second=st.floats(30.0, 120.0),
       turn=st.floats(-150.0, 150.0).filter(lambda x: abs(x) > 20.0),
       height=st.floats(12.0, 40.0), walk=st.floats(0.8, 1.8), seed=st.integers(0, 1000))
def test_property_ground_never_on_a_leg_and_every_pass_found(heading, first, second, turn,
                                                             height, walk, seed):
    log, plan, truth_leg, on_ground = day_log(seed=seed, flights=3, heading_deg=heading,
                                              legs=(first, second), turn_deg=turn,
                                              height=height, walk=walk)
    res = check_track(log, plan)
    _no_leg_on_ground(res, on_ground)
    assert [row.n_passes for row in res.legs] == [3, 3]
    _passes_found(res, truth_leg, 0.8)
    assert res.report.altitude_offset["applied_m"] == 0.0
    assert res.report.plan_check["assignment"]["direction"] == "as planned"


def test_passes_at_the_plan_altitude_beat_a_datum_that_more_passes_show():
    # four flights 30 m above the plan, two at it: the plan's own altitude explains passes,
    # so nothing is removed (the high passes are deviations, off the legs), and a warning says
    # why (before: "reversed", 2,048 ground rows on the legs, none of the passes)
    log, plan, truth_leg, on_ground = day_log(seed=5)
    t = log["time"].to_numpy()
    starts = t[np.flatnonzero(np.diff(np.r_[0, (truth_leg == 0).astype(int)]) == 1)]
    high = t >= starts[2] - 20.0
    res = check_track(log.assign(alt=log["alt"] + np.where(high, 30.0, 0.0)), plan)
    off = res.report.altitude_offset
    assert off["estimated_m"] == pytest.approx(31.8, abs=0.3)
    assert off["applied_m"] == 0.0 and off["n_passes_at_plan_altitude"] == 4
    assert any("2 pass" not in w and "4 pass(es) are flown at the plan's own altitude" in w
               for w in res.report.warnings), res.report.warnings
    assert [row.n_passes for row in res.legs] == [2, 2]
    _no_leg_on_ground(res, on_ground)


def test_a_log_leg_column_is_cleared_where_the_log_says_the_vehicle_is_on_the_ground(day):
    df, plan, _ = day
    res = check_track(df.assign(leg=0), plan)
    lab = res.data["leg"].fillna(-1).to_numpy(dtype=np.int64)
    assert (lab[~df["armed"].to_numpy()] == -1).all()
    assert (lab[df["armed"].to_numpy()] == 0).all()
    # inferred ground does not override the autopilot's own leg column
    res = check_track(df.drop(columns=["armed"]).assign(leg=0), plan)
    assert res.data["leg"].notna().all()


REAL_FLIGHT = (Path(__file__).resolve().parents[2] / "shared" / "data" / "real" / "flights"
               / "px4_optical_flow.csv")  # ../shared


def test_real_low_flight_is_not_taken_for_ground():
    # a real PX4 flight 1-2 m above the ground (the rangefinder says so) whose GNSS height
    # wanders over 40 m, landing at the end: no row flown before the landing is ground (a
    # rule of "the lowest heights are the ground" would take whole stretches of it)
    if not REAL_FLIGHT.exists():
        pytest.skip("../shared/data/real/flights (the real PX4 flight) is absent")
    from aeromag._core.geodesy import geodetic_to_ned
    from aeromag.track.ground import ground_rows
    from aeromag.track.legs import LegModel, velocity_for_legs

    d = pd.read_csv(REAL_FLIGHT)
    g = d.dropna(subset=["lat", "lon", "alt"]).reset_index(drop=True)
    o = (float(g["lat"][0]), float(g["lon"][0]), float(g["alt"][0]))
    ned = geodetic_to_ned(g["lat"].to_numpy(), g["lon"].to_numpy(), g["alt"].to_numpy(), o)
    t = g["time"].to_numpy()
    assert np.ptp(ned[:, 2]) > 30.0          # the GNSS height wanders
    vel, _ = velocity_for_legs(t, ned, LegModel(), g[["vel_n", "vel_e", "vel_d"]].to_numpy())
    ground, info = ground_rows(t, ned, vel, g)
    rng = d[["time", "range_m"]].dropna()
    landed = float(rng["time"][rng["range_m"] < 0.3].min())
    assert not ground[t < landed].any(), info
