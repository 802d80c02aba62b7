"""Track geometry against an independent ECEF computation, plan validation, leg assignment."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aeromag._core.geodesy import geodetic_to_ned, ned_to_geodetic
from aeromag.errors import InputError
from aeromag.track import (
    assign_legs,
    check_track,
    cross_track,
    track_alarm,
    validate_plan,
)

A_WGS, F_WGS = 6378137.0, 1 / 298.257223563
E2 = F_WGS * (2 - F_WGS)


def ecef_ref(lat, lon, h):
    """Closed-form WGS84 geodetic -> ECEF (independent of pyproj)."""
    ph, la = np.deg2rad(lat), np.deg2rad(lon)
    n = A_WGS / np.sqrt(1 - E2 * np.sin(ph) ** 2)
    return np.stack([(n + h) * np.cos(ph) * np.cos(la), (n + h) * np.cos(ph) * np.sin(la),
                     (n * (1 - E2) + h) * np.sin(ph)], axis=-1)


def dest(lat, lon, north, east):
    """Rough offset in degrees (only used to place points; exactness not needed)."""
    return lat + north / 111_000.0, lon + east / (111_000.0 * np.cos(np.deg2rad(lat)))


@pytest.mark.parametrize("lat0,lon0,length", [
    (0.1, 10.0, 100.0), (-0.2, 30.0, 1000.0),      # near the equator
    (45.0, 5.9995, 800.0),                         # across the UTM 31/32 boundary at 6 deg E
    (65.0, -18.0, 500.0), (65.0, 24.0, 1000.0),    # high latitude
])
def test_cross_track_matches_ecef(lat0, lon0, length):
    rng = np.random.default_rng(1)
    ang = rng.uniform(0, 2 * np.pi)
    blat, blon = dest(lat0, lon0, length * np.cos(ang), length * np.sin(ang))
    plan = pd.DataFrame({"lat": [lat0, blat], "lon": [lon0, blon], "alt": [100.0, 130.0]})
    n = 200
    s = rng.uniform(-0.2, 1.2, n)
    xlat = lat0 + s * (blat - lat0) + rng.normal(0, 5e-5, n)
    xlon = lon0 + s * (blon - lon0) + rng.normal(0, 5e-5, n)
    xalt = 100 + 30 * s + rng.normal(0, 3, n)
    wp = geodetic_to_ned(plan.lat, plan.lon, plan.alt, (lat0, lon0, 100.0))
    ned = geodetic_to_ned(xlat, xlon, xalt, (lat0, lon0, 100.0))
    d, h, v, along = cross_track(ned, wp[0], wp[1])
    # independent: everything in ECEF, no local frame at all
    a, b = ecef_ref(lat0, lon0, 100.0), ecef_ref(blat, blon, 130.0)
    x = ecef_ref(xlat, xlon, xalt)
    ref = np.linalg.norm(np.cross(x - a, b - a), axis=1) / np.linalg.norm(b - a)
    ref_along = (x - a) @ (b - a) / np.linalg.norm(b - a)
    assert np.max(np.abs(d - ref)) <= 1e-3
    assert np.max(np.abs(along - ref_along)) <= 1e-3
    assert np.allclose(np.hypot(h, v), d, atol=1e-9)
    assert abs(np.linalg.norm(wp[1] - wp[0]) - np.linalg.norm(b - a)) <= 1e-3


def test_horizontal_vertical_signs():
    d, h, v, along = cross_track(np.array([[5.0, 2.0, -1.0]]), np.zeros(3), np.array([10, 0, 0.]))
    assert d[0] == pytest.approx(np.sqrt(5)) and h[0] == pytest.approx(2.0)  # right of north
    assert v[0] == pytest.approx(1.0) and along[0] == pytest.approx(5.0)     # above the line


vec = st.tuples(*[st.floats(-1000, 1000, allow_nan=False) for _ in range(3)]).map(np.array)


@settings(max_examples=60, deadline=None)
@given(a=vec, b=vec, x=vec, k=st.floats(0.01, 100))
def test_cross_track_properties(a, b, x, k):
    if np.linalg.norm(b - a) < 1e-3:
        return
    d, h, v, _ = cross_track(x, a, b)
    d2, _, _, _ = cross_track(x, b, a)          # symmetry in the endpoints
    assert d[0] == pytest.approx(d2[0], rel=1e-9, abs=1e-6)
    t = 0.37
    on, _, _, _ = cross_track(a + t * (b - a), a, b)  # zero on the line
    assert on[0] == pytest.approx(0.0, abs=1e-6)
    dk, _, _, _ = cross_track(k * x, k * a, k * b)    # scaling
    assert dk[0] == pytest.approx(k * d[0], rel=1e-6, abs=1e-6)
    assert np.hypot(h[0], v[0]) == pytest.approx(d[0], rel=1e-9, abs=1e-6)


def test_plan_validation():
    ok = pd.DataFrame({"lat": [0, 0.001], "lon": [0, 0], "alt": [10, 10]})
    validate_plan(ok)
    with pytest.raises(InputError, match="at least 2"):
        validate_plan(ok.iloc[:1])
    with pytest.raises(InputError, match="zero-length"):
        validate_plan(pd.DataFrame({"lat": [0, 0.001, 0.001], "lon": [0, 0, 0],
                                    "alt": [10, 10, 10]}))
    with pytest.raises(InputError, match="missing column"):
        validate_plan(ok.drop(columns="alt"))


def _flight(wps, speed=5.0, fs=10.0, hover=5.0):
    """Straight-line flight through NED waypoints with hovering, climb and landing."""
    pts = [np.array([0, 0, 30.0]) + f * (wps[0] - np.array([0, 0, 30.0]))
           for f in np.linspace(0, 1, 60)]
    for k in range(len(wps) - 1):
        pts += [wps[k]] * int(hover * fs)
        n = int(np.linalg.norm(wps[k + 1] - wps[k]) / speed * fs)
        pts += [wps[k] + f * (wps[k + 1] - wps[k]) for f in np.linspace(0, 1, n)]
    pts += [wps[-1]] * int(hover * fs)
    pts += [wps[-1] + np.array([0, 0, f * 30]) for f in np.linspace(0, 1, 60)]
    return np.array(pts)


def test_assign_legs_skips_takeoff_turns_landing_and_handles_refly():
    wps = np.array([[0, 0, 0], [200, 0, 0], [200, 20, 0], [0, 20, 0.]])
    pos = _flight(wps)
    lab = assign_legs(pos, wps)
    assert (lab[:60] == -1).all() and (lab[-60:] == -1).all()   # take-off and landing
    assert set(np.unique(lab)) == {-1, 0, 1, 2}
    assert (np.diff(lab[lab >= 0]) >= 0).all()
    # re-fly leg 0: after leg 0 go back to A (transit) and fly it again
    back = [wps[1] + f * (wps[0] - wps[1]) + np.array([0, 8.0 * np.sin(np.pi * f), 0])
            for f in np.linspace(0, 1, 400)]
    pos2 = np.vstack([_flight(wps[:2])[:-60 - 50], np.array(back), _flight(wps)[60:]])
    lab2 = assign_legs(pos2, wps)
    runs = [int(v) for i, v in enumerate(lab2) if v >= 0 and (i == 0 or lab2[i - 1] != v)]
    assert runs == [0, 0, 1, 2]
    # the off-line transit back is on no leg
    nb = len(_flight(wps[:2])) - 60 - 50
    assert (lab2[nb + 50: nb + 350] == -1).all()


def test_track_alarm_min_duration():
    t = np.arange(20) * 0.5
    x = np.r_[np.zeros(5), np.full(6, 2.0), np.zeros(9)]
    lab = np.zeros(20, dtype=int)
    assert track_alarm(x, lab, t).sum() == 6
    a = track_alarm(x, lab, t, min_duration_s=1.0)
    assert np.flatnonzero(a).tolist() == [7, 8, 9, 10]
    assert not track_alarm(x, np.full(20, -1), t).any()


def test_check_track_uses_leg_column_and_reports_every_leg():
    wps = np.array([[0, 0, 0], [200, 0, 0], [200, 20, 0.]])
    origin = (60.0, 5.0, 100.0)
    pg = ned_to_geodetic(wps, origin)
    pos = _flight(wps[:2]) + np.array([0, 1.5, 0])  # 1.5 m east of leg 0 throughout
    g = ned_to_geodetic(pos, origin)
    i = np.arange(len(pos))
    leg = np.where((i < 60) | (i >= len(pos) - 60), -1, 0)
    df = pd.DataFrame({"time": np.arange(len(pos)) * 0.1, "lat": g[:, 0], "lon": g[:, 1],
                       "alt": g[:, 2], "leg": leg})
    res = check_track(df, pd.DataFrame(pg, columns=["lat", "lon", "alt"]))
    assert [row.leg for row in res.legs] == [0, 1]
    assert res.legs[0].flagged and not res.legs[1].flagged
    assert res.legs[1].n_samples == 0 and res.legs[1].first_alarm_time is None
    on = res.data["leg"].notna().to_numpy()
    assert np.allclose(res.data["xtrack_m"][on], 1.5, atol=2e-3)
    assert not res.data["alarm"][~on].any()
    assert "heading_diff_deg" not in res.data.columns


# --------------------------------------------------------------------------- issue 14 / 15
from aeromag.detection.alarms import Alarms  # noqa: E402
from aeromag.synthetic.mission import simulate_mission  # noqa: E402


@pytest.fixture(scope="module")
def small_mission():
    return simulate_mission(seed=5, line_m=200.0, n_lines=2, disturbances={2: "fast"})


def test_heading_sigma_floor_stops_alarm_storms_on_clean_lines():
    """A calm window quieter than the compass (here a noise-free fluxgate, sigma ~0.005 deg)
    made every tiny later wobble a 5-sigma heading alarm; the floor (0.5 deg) stops it."""
    df, plan, _ = simulate_mission(seed=2, line_m=200.0, n_lines=2, disturbances={},
                                   flux_noise_nT=1.0, gust_m_s=0.05)
    raw = check_track(df, plan, heading_sigma_floor_deg=0.0)
    hd = raw.report.heading_detector
    assert hd["sigma_raw_deg"] < 0.05 and int(raw.data["heading_alarm"].sum()) >= 10
    res = check_track(df, plan)
    hd = res.report.heading_detector
    assert hd["sigma_floor_deg"] == 0.5 and hd["sigma_deg"] == 0.5 and hd["floored"]
    assert not res.data["heading_alarm"].any() and res.report.flagged_legs == []
    with pytest.raises(InputError, match="sigma_floor_deg="):  # the CLI: --heading-sigma-floor
        check_track(df, plan, heading_sigma_floor_deg=-1.0)


def test_altitude_relative_to_home_is_found_and_removed(small_mission):
    df, plan, _ = small_mission
    ref = check_track(df, plan)
    rel = df.assign(alt=df["alt"] - float(plan["alt"].iloc[0]) + 40.0)  # relative to take-off
    res = check_track(rel, plan)
    off = res.report.altitude_offset
    assert off["mode"] == "auto"
    assert off["applied_m"] == pytest.approx(40.0 - float(plan["alt"].iloc[0]), abs=0.05)
    assert any("altitude reference" in w for w in res.report.warnings)
    assert res.report.flagged_legs == ref.report.flagged_legs == [2]
    np.testing.assert_allclose(res.data["xtrack_m"], ref.data["xtrack_m"], atol=0.05)
    # without the correction every sample is off the legs, and the report says what to check
    none = check_track(rel, plan, altitude_offset="none")
    assert none.report.n_on_leg == 0 and none.report.flagged_legs == []
    assert any("altitude reference" in w for w in none.report.warnings)
    # horizontal only: the legs are found and the distance ignores the datum
    hor = check_track(rel, plan, altitude_offset="none", horizontal=True)
    assert hor.report.distance == "horizontal" and hor.report.flagged_legs == [2]
    x = hor.data["xtrack_m"].to_numpy()
    np.testing.assert_allclose(x[np.isfinite(x)],
                               np.abs(hor.data["xtrack_h_m"].to_numpy()[np.isfinite(x)]))
    # a given offset; and a small constant error is not a datum (it is reported as deviation)
    given = check_track(rel, plan, altitude_offset=40.0 - float(plan["alt"].iloc[0]))
    assert given.report.altitude_offset["mode"] == "given"
    assert given.report.flagged_legs == [2]
    high = check_track(df.assign(alt=df["alt"] + 2.0), plan)
    assert high.report.altitude_offset["applied_m"] == 0.0
    assert high.report.flagged_legs == [0, 1, 2]
    with pytest.raises(InputError, match="altitude_offset="):
        check_track(df, plan, altitude_offset="ellipsoid")


def test_reversed_and_far_plans_warn(small_mission):
    df, plan, _ = small_mission
    rev = check_track(df, plan.iloc[::-1].reset_index(drop=True))
    ok = check_track(df, plan)
    # a mission flown against its plan reversed is checked along the reversed legs
    assert rev.report.n_on_leg == ok.report.n_on_leg > 0
    assert rev.report.flagged_legs == sorted(len(plan) - 2 - k
                                                for k in ok.report.flagged_legs)
    assert any("backwards" in w and "reversed" in w for w in rev.report.warnings)
    far = check_track(df, plan.assign(lat=plan["lat"] + 0.05))
    assert any("within" in w and "site" in w for w in far.report.warnings)
    ok = check_track(df, plan)
    assert ok.report.warnings == []


def test_session_of_flights_with_landings_between():
    """One 100.5 m leg flown in three separate flights (take-off, leg, landing, ground time)
    concatenated into one session log, as an ArduCopter session is (the autopilot's leg ends
    2 m before the waypoint, its WPNAV_RADIUS): every flight is a pass,
    >= 95 % of the rows flown on the leg get it, and the track alarms are no more than the
    rows whose true deviation is beyond the threshold plus 2 % of the log."""
    wps = np.array([[0.0, 0.0, 0.0], [100.5, 0.0, 0.0]])
    parts, t0 = [], 0.0
    for seed in range(3):
        df, plan, _ = simulate_mission(seed=seed, waypoints_ned=wps, ground_s=20.0,
                                       disturbances={0: "fast"} if seed == 1 else {},
                                       onset_after_s=6.0, wp_radius_m=2.0)
        parts.append(df.assign(time=df["time"] + t0))
        t0 = float(parts[-1]["time"].iloc[-1]) + 0.1
    log = pd.concat(parts, ignore_index=True)
    res = check_track(log, plan)
    row = res.legs[0]
    assert row.n_passes == 3
    flown = (log["truth_leg"] == 0).to_numpy()
    lab = res.data["leg"].fillna(-1).to_numpy(dtype=np.int64)
    assert (lab[flown] == 0).mean() >= 0.95
    beyond = int((log["truth_xtrack_m"] > 1.0).sum())
    assert int(res.data["track_alarm"].sum()) <= beyond + 0.02 * len(log)
    assert not res.data["alarm"].to_numpy()[log["truth_phase"].to_numpy() != "leg"].any()
    assert [p.flagged for p in row.passes] == [False, True, False]


def test_more_detectors_and_given_inputs(small_mission):
    """A third detector (e.g. the particle filter) is one more Alarms; position and heading can
    come from elsewhere (a navigation filter)."""
    df, plan, _ = small_mission
    n = len(df)
    fake = np.zeros(n, bool)
    fake[n // 2: n // 2 + 3] = True
    pf = Alarms(name="pf", time_s=df["time"], stat=fake.astype(float), alarm=fake,
                threshold=0.5)
    res = check_track(df, plan, detectors=[pf])
    assert "pf_alarm" in res.data.columns
    on = res.data["leg"].notna().to_numpy()
    assert (res.data["pf_alarm"].to_numpy() == (fake & on)).all()
    assert all("pf" in row.first_alarm_times for row in res.legs)
    assert [d["detector"] for d in res.report.detectors] == ["track", "heading", "pf"]
    base = check_track(df, plan)
    assert (res.data["alarm"] >= base.data["alarm"]).all()
    # explicit position and heading arrays give the same result as the log's columns
    same = check_track(df.drop(columns=["lat", "lon", "alt"]), plan,
                       position=(df["lat"], df["lon"], df["alt"]),
                       heading_deg=df["heading"].to_numpy())
    assert same.report.position_input == "given"
    pd.testing.assert_series_equal(same.data["alarm"], base.data["alarm"])
    assert same.legs == base.legs


def test_messy_logs(small_mission):
    """GNSS on one row in ten (the other rows empty), repeated time stamps, times going
    backwards, absurd plan altitudes."""
    df, plan, _ = small_mission
    base = check_track(df, plan)
    keep = np.arange(len(df)) % 10 == 0
    sparse = df.assign(lat=np.where(keep, df["lat"], np.nan))
    res = check_track(sparse, plan)
    assert res.report.flagged_legs == base.report.flagged_legs == [2]
    lab, ref = (r.data["leg"].fillna(-1).to_numpy() for r in (res, base))
    assert (lab[~keep] == -1).all()
    assert (lab[keep] == ref[keep]).mean() > 0.97
    coarse = check_track(df.assign(time=np.floor(df["time"])), plan)
    assert coarse.report.flagged_legs == [2]
    assert coarse.report.n_on_leg > 0.9 * base.report.n_on_leg
    with pytest.raises(InputError, match=r"column 'time', row 2: .* \(sort the log"):
        check_track(df.iloc[::-1].reset_index(drop=True), plan)
    with pytest.raises(InputError, match="column 'alt', line 2: altitude 1e\\+300 m"):
        check_track(df, plan.assign(alt=[1e300, 0.0, 0.0, 0.0]))


def test_noisy_positions_and_gnss_velocity():
    """Non-RTK positions (0.5 m white noise per axis per sample): the velocity window widens
    with the measured jitter and the legs are still found; GNSS velocity columns are used."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from test_track_legs import _scores

    df, plan, _ = simulate_mission(seed=0, rtk_noise_m=0.5, line_m=250.0,
                                   home_ne_m=(-30.0, -20.0), ground_s=20.0, refly_legs=(3,))
    res = check_track(df, plan, threshold_m=2.0)
    v = res.report.velocity
    assert v["source"] == "positions" and 0.4 < v["position_jitter_m"] < 0.6
    assert v["window_s"] == pytest.approx(7.0 * v["position_jitter_m"])
    s = _scores(df, plan, res)
    assert s["recall"] > 0.99 and s["precision"] > 0.98, s
    assert not res.data["alarm"].to_numpy()[(df["truth_phase"] != "leg").to_numpy()].any()
    from aeromag.track.legs import LegModel, motion_velocity

    o = tuple(float(plan[c].iloc[0]) for c in ("lat", "lon", "alt"))
    from aeromag._core.geodesy import geodetic_to_ned

    ned = geodetic_to_ned(df["lat"], df["lon"], df["alt"], o)
    vel = motion_velocity(df["time"].to_numpy(), ned, v["window_s"])
    withv = df.assign(vel_n=vel[:, 0], vel_e=vel[:, 1], vel_d=vel[:, 2])
    res2 = check_track(withv, plan, threshold_m=2.0)
    assert res2.report.velocity["source"] == "gnss"
    pd.testing.assert_series_equal(res2.data["leg"], res.data["leg"])
    assert LegModel().velocity_window_s == 1.0
