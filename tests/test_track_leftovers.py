"""Left-overs of the track review: plans flown backwards or out of order (transits must not
alarm), plain GNSS with a correlated position error (legs must still be assigned), and the
datum check on such flights."""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd
import pytest

from aeromag._core.geodesy import geodetic_to_ned, ned_to_geodetic
from aeromag.synthetic.mission import plan_waypoints_ned, simulate_mission
from aeromag.track import check_track
from aeromag.track.assign import drop_transit_runs

ORIGIN = (47.3, 8.5, 500.0)


def _reverse_order_flight(seed: int = 0, disturbances: dict[int, str] | None = None,
                          backwards: bool = False) -> tuple[pd.DataFrame, pd.DataFrame]:
    """A 3-line plan whose legs are flown last first: each leg forward with a ferry from its
    end to the previous leg's start (straight, a few degrees off the lines), or backwards
    (the plan reversed).  ``truth_plan_leg`` is the plan leg flown (-1 off legs)."""
    P = plan_waypoints_ned(3, 150.0, 20.0)
    K = len(P) - 1
    seq: list[np.ndarray] = []
    for k in range(K - 1, -1, -1):
        seq += [P[k + 1], P[k]] if backwards else [P[k], P[k + 1]]
    fw = np.array(seq)
    fw = fw[np.r_[True, np.linalg.norm(np.diff(fw, axis=0), axis=1) > 0]]
    o = tuple(ned_to_geodetic(fw[:1], ORIGIN)[0])
    df, _, _ = simulate_mission(seed=seed, origin=o, waypoints_ned=fw - fw[0],
                                disturbances=disturbances or {}, home_ne_m=(-30.0, -20.0),
                                ground_s=10.0)
    pg = ned_to_geodetic(P - fw[0], o)
    plan = pd.DataFrame({"lat": pg[:, 0], "lon": pg[:, 1], "alt": pg[:, 2]})
    flight_to_plan = []
    for a, b in zip(fw[:-1], fw[1:], strict=True):
        same = [k for k in range(K) if {tuple(a), tuple(b)} == {tuple(P[k]), tuple(P[k + 1])}]
        flight_to_plan.append(same[0] if same else -1)
    tl = df["truth_leg"].to_numpy()
    df["truth_plan_leg"] = np.where(tl >= 0, np.array(flight_to_plan + [-1])[tl], -1)
    return df, plan


def _gauss_markov(n: int, dt: float, sigma: float, tau: float, rng: np.random.Generator
                  ) -> np.ndarray:
    a = np.exp(-dt / tau)
    e = np.empty(n)
    e[0] = rng.normal(0.0, sigma)
    w = rng.normal(0.0, sigma * np.sqrt(1.0 - a * a), n)
    for i in range(1, n):
        e[i] = a * e[i - 1] + w[i]
    return e


def _with_gnss_error(df: pd.DataFrame, sigma: float, tau: float, seed: int) -> pd.DataFrame:
    """Plain GNSS: a Gauss-Markov error (sigma m per axis, correlation time tau s)."""
    rng = np.random.default_rng(seed)
    dt = float(np.median(np.diff(df["time"])))
    o = (float(df["lat"].iloc[0]), float(df["lon"].iloc[0]), float(df["alt"].iloc[0]))
    ned = geodetic_to_ned(df["lat"], df["lon"], df["alt"], o)
    err = np.c_[[_gauss_markov(len(df), dt, sigma, tau, rng) for _ in range(3)]].T
    g = ned_to_geodetic(ned + err, o)
    return df.assign(lat=g[:, 0], lon=g[:, 1], alt=g[:, 2])


def _labels(res) -> np.ndarray:
    return res.data["leg"].fillna(-1).to_numpy()


def test_legs_flown_last_first_with_ferries_do_not_alarm():
    # before: the ferries (4-8 deg off the lines, converging or diverging) were taken for
    # legs out of order and 658 rows alarmed, legs 0, 2, 4 flagged
    df, plan = _reverse_order_flight()
    res = check_track(df, plan)
    truth = df["truth_plan_leg"].to_numpy()
    on = truth >= 0
    lab = _labels(res)
    assert int(res.data["alarm"].sum()) == 0
    assert res.report.flagged_legs == []
    assert (lab[~on] < 0).all()
    assert (lab[on] == truth[on]).mean() > 0.85
    assert res.report.plan_check["mismatch"] is None, res.report.plan_check


def test_a_real_deviation_on_legs_flown_last_first_is_flagged():
    # flight leg 4 is plan leg 2 (a line), flown after two ferries
    df, plan = _reverse_order_flight(disturbances={4: "fast"})
    res = check_track(df, plan)
    on = (df["truth_plan_leg"] >= 0).to_numpy()
    assert res.report.flagged_legs == [2]
    assert not res.data["alarm"].to_numpy()[~on].any()


@pytest.fixture(scope="module")
def full_mission():
    return simulate_mission(seed=0, line_m=250.0, home_ne_m=(-30.0, -20.0), ground_s=20.0,
                            refly_legs=(3,))


def test_a_mission_flown_backwards_is_checked_along_its_legs(full_mission):
    # before: nothing was assigned against the reversed plan (0 of the leg rows checked, the
    # disturbed legs missed); transits, hover, ground never alarm
    df, plan, _ = full_mission
    rev = plan.iloc[::-1].reset_index(drop=True)
    fwd, res = check_track(df, plan), check_track(df, rev)
    k = len(plan) - 2
    truth = df["truth_leg"].to_numpy()
    on = (df["truth_phase"] == "leg").to_numpy()
    lab, lab_f = _labels(res), _labels(fwd)
    assert (lab[on] == k - truth[on]).mean() == pytest.approx((lab_f[on] == truth[on]).mean(),
                                                              abs=0.005)
    assert res.report.flagged_legs == sorted(k - j for j in fwd.report.flagged_legs)
    assert not res.data["alarm"].to_numpy()[~on].any()
    chk = res.report.plan_check
    assert chk["mismatch"] == "reversed" and chk["assignment"]["direction"] == "reversed"
    assert any("checked in that direction" in w for w in res.report.warnings)


def test_a_clean_mission_flown_backwards_has_no_alarm():
    df, plan, _ = simulate_mission(seed=2, line_m=250.0, disturbances={},
                                   home_ne_m=(-30.0, -20.0), ground_s=20.0, refly_legs=(3,))
    res = check_track(df, plan.iloc[::-1].reset_index(drop=True))
    assert int(res.data["alarm"].sum()) == 0
    assert res.report.n_on_leg == check_track(df, plan).report.n_on_leg > 0


@pytest.mark.parametrize(("sigma", "tau", "seed"), [(5.0, 60.0, 0), (5.0, 300.0, 0)])
def test_correlated_gnss_error_keeps_the_legs_assigned(full_mission, sigma, tau, seed):
    # before: 0.746 (5 m, 60 s) and 0.815 (5 m, 300 s) of the leg rows were given their leg,
    # now 0.876 and 0.898 (0.928 on RTK: the first and last metres of a leg, accelerating and
    # settling, are off plan); the 10 m tolerance cut the legs where the error wandered
    df, plan, _ = full_mission
    noisy = _with_gnss_error(df, sigma, tau, seed + 10)
    res = check_track(noisy, plan, threshold_m=4.0 * sigma)
    truth = df["truth_leg"].to_numpy()
    on = truth >= 0
    lab = _labels(res)
    assert (lab[on] == truth[on]).mean() > 0.85
    a = res.report.plan_check["assignment"]
    assert 3.0 < a["sigma_h_m"] < 8.0 and a["tolerance_m"] > 10.0
    assert any("scatter" in w for w in res.report.warnings)
    # no transit, climb, landing or ground row is given a leg, no alarm off the legs
    moving_off = ((df["truth_phase"] != "leg") & (df["truth_phase"] != "hover")).to_numpy()
    assert (lab[moving_off] < 0).mean() > 0.98
    assert not res.data["alarm"].to_numpy()[~on].any()


def test_rtk_keeps_the_default_tolerance(full_mission):
    df, plan, _ = full_mission
    a = check_track(df, plan).report.plan_check["assignment"]
    assert a["tolerance_m"] == 10.0 and a["sigma_h_m"] < 0.5 and a["gate_h_m"] == 2.0
    assert np.hypot(*a["offset_ne_m"]) < 0.2


def test_a_plan_above_ground_flown_backwards_is_said_to_be_a_datum(caplog):
    # heights above the take-off point against an ellipsoidal log, the mission flown
    # backwards without a re-flown leg: the datum is found along the reversed legs
    df, plan, _ = simulate_mission(seed=1, line_m=250.0, home_ne_m=(-30.0, -20.0),
                                   ground_s=20.0)
    agl = plan.assign(alt=plan["alt"] - float(plan["alt"].iloc[0]) + 40.0)
    with caplog.at_level(logging.WARNING):
        res = check_track(df, agl.iloc[::-1].reset_index(drop=True))
    off = res.report.altitude_offset
    assert off["applied_m"] == pytest.approx(460.0, abs=0.5)
    assert "constant 460.0 m above the plan" in caplog.text
    assert res.report.flagged_legs == [2, 4, 6, 8]


def test_drop_transit_runs_keeps_a_veering_pass_and_drops_a_converging_ferry():
    wps = np.array([[0.0, 0.0, 0.0], [150.0, 0.0, 0.0]])
    t = np.arange(300) * 0.1
    x = 5.0 * t
    ferry = np.c_[x, 20.0 * (1.0 - x / 150.0), np.zeros_like(x)]     # 20 m -> 0 at B
    veer = np.c_[x, np.clip(x - 50.0, 0.0, None) * 0.2, np.zeros_like(x)]  # on, then off
    lab = np.r_[np.full(150, -1), np.zeros(150, dtype=int)]          # last 75 m decoded
    out, n = drop_transit_runs(lab, ferry, t, wps, 2.0)
    assert n == 1 and (out < 0).all()
    lab = np.zeros(300, dtype=int)
    out, n = drop_transit_runs(lab, veer, t, wps, 2.0)
    assert n == 0 and (out == 0).all()


def test_a_flight_3_m_beside_its_plan_is_checked_not_dropped():
    # the on-line gate is centred on the flight's constant offset: the lines alarm (the
    # east-west cross legs run along the shift and do not), nothing is left unchecked
    df, plan, _ = simulate_mission(seed=0, line_m=250.0, disturbances={},
                                   home_ne_m=(-30.0, -20.0), ground_s=20.0)
    sh = plan.assign(lon=plan["lon"] + 3.0 / (111320.0 * np.cos(np.radians(47.3))))
    res = check_track(df, sh)
    assert res.report.flagged_legs == [0, 2, 4, 6, 8, 10]
    assert res.report.n_on_leg > 0.97 * check_track(df, plan).report.n_on_leg
