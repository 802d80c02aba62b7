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
    assert [row["leg"] for row in res.legs] == [0, 1]
    assert res.legs[0]["flagged"] and not res.legs[1]["flagged"]
    assert res.legs[1]["n_samples"] == 0 and res.legs[1]["first_alarm_time"] is None
    on = res.data["leg"].notna().to_numpy()
    assert np.allclose(res.data["xtrack_m"][on], 1.5, atol=2e-3)
    assert not res.data["alarm"][~on].any()
    assert "heading_diff_deg" not in res.data.columns
