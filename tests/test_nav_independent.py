"""aeromag navigate against a quadrotor simulator written here, independently of the filter.

Neither ``aeromag.synthetic`` nor the simulator of ``tests/test_nav_robust.py``: numpy only,
other noise and other timing so that a filter tuned to one simulator's assumptions fails here:

- IMU 200 Hz (mean over the interval ending at the row), gyro and accelerometer biases that
  random-walk (not constants), white noise 0.15 °/s and 0.1 m/s²;
- flow 10 Hz, the mean over its 0.1-s integration interval stamped at the MIDDLE, with
  coloured noise (AR(1), correlation 0.8 from one sample to the next) and a few samples of
  quality 0;
- sonar 15 Hz, 0.015 m, 4 % dropouts (readings of 0 m) and 2 % saturated at its maximum;
- magnetometer 75 Hz, southern-hemisphere field (inclination −64°, declination 12.8°);
- GNSS 5 Hz whose error is a Gauss-Markov process (0.8 m, 20 s) plus white 0.3 m;
- trajectories: a hover with sway, and a 24 m × 12 m rectangle at 1.5 m/s (60 s), the body
  kept at 30° to the track and the yaw swung out by 70° and back at each corner while stopped.

Checked: the issue-12 bars with margin (hover < 0.5 m / 0.15 m/s, rectangle < 2.5 m /
0.2 m/s, mean horizontal errors, GNSS used only to start), no reject storms, NIS per dof of
each sensor in the filter's own band, ``nav_std_*`` consistent with the error (coverage), and a
10-s GNSS jump that is refused without dragging the track.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from aeromag._core.geodesy import geodetic_to_ned, ned_to_geodetic
from aeromag.nav import navigate

FIELD = np.array([24350.0, 5530.0, -51230.0])     # nT, NED: Sydney-like
SITE = (-33.9, 151.2, 50.0)
FS = 1000.0                                        # truth grid, Hz
HEIGHT = 2.0


def _smooth(x: np.ndarray, width_s: float) -> np.ndarray:
    n = max(int(width_s * FS), 1)
    k = np.ones(n) / n
    pad = np.pad(x, ((n, n), (0, 0)), mode="edge")
    return np.column_stack([np.convolve(pad[:, j], k, mode="same")[n:-n]
                            for j in range(x.shape[1])])


def _trajectory(kind: str, duration_s: float):
    t = np.arange(0.0, duration_s + 1.0, 1.0 / FS)
    vel = np.zeros((t.size, 3))
    yaw = np.full(t.size, np.deg2rad(30.0))
    if kind == "rectangle":
        t0 = 3.0
        for dn, de in [(24.0, 0.0), (0.0, 12.0), (-24.0, 0.0), (0.0, -12.0)]:
            L = np.hypot(dn, de)
            T = L / 1.5 + 1.0                          # trapezoid, 1-s ramps
            s = t - t0
            sp = 1.5 * np.clip(np.minimum(np.minimum(s, T - s), 1.0), 0.0, None)
            vel[:, 0] += sp * dn / L
            vel[:, 1] += sp * de / L
            t0 += T
            m = (t >= t0) & (t < t0 + 3.0)             # corner: stopped, yaw swing
            yaw[m] += np.deg2rad(70.0) * np.sin(np.pi * (t[m] - t0) / 3.0)
            t0 += 3.0
        vel = _smooth(_smooth(vel, 0.4), 0.4)          # finite jerk
    else:
        vel[:, 0] = 0.25 * 2 * np.pi / 13.0 * np.cos(2 * np.pi * t / 13.0)
        vel[:, 1] = 0.15 * 2 * np.pi / 19.0 * np.cos(2 * np.pi * t / 19.0)
        yaw += np.deg2rad(10.0) * np.sin(2 * np.pi * t / 29.0)
    pos = np.cumsum(vel, axis=0) / FS
    pos[:, 2] = -HEIGHT
    acc = np.gradient(vel, 1.0 / FS, axis=0)
    return t, pos, vel, acc, yaw


def _attitude(acc: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """Body-to-NED DCMs of a multirotor: thrust (−z body) along the needed specific force."""
    f = acc - np.array([0.0, 0.0, 9.80665])
    zb = -f / np.linalg.norm(f, axis=1)[:, None]
    xh = np.column_stack([np.cos(yaw), np.sin(yaw), np.zeros(yaw.size)])
    yb = np.cross(zb, xh)
    yb /= np.linalg.norm(yb, axis=1)[:, None]
    xb = np.cross(yb, zb)
    return np.stack([xb, yb, zb], axis=2)


def _interval_mean(t: np.ndarray, x: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    c = np.vstack([np.zeros(x.shape[1]), np.cumsum(x[:-1], axis=0) / FS])
    return np.column_stack([np.interp(b, t, c[:, j]) - np.interp(a, t, c[:, j])
                            for j in range(x.shape[1])]) / (b - a)[:, None]


def _random_walk(rng, n: int, dt: float, start_sd: float, walk: float) -> np.ndarray:
    return rng.normal(0, start_sd, 3) + np.cumsum(rng.normal(0, walk * np.sqrt(dt), (n, 3)),
                                                  axis=0)


def fly(kind: str, seed: int = 5, duration_s: float = 60.0, gnss_jump: float = 0.0):
    """The log (canonical columns, union of sample times) and the truth at its rows."""
    rng = np.random.default_rng(seed)
    t, pos, vel, acc, yaw = _trajectory(kind, duration_s)
    C = _attitude(acc, yaw)
    dC = np.einsum("kji,kjl->kil", C[:-1], C[1:])       # C_k^T C_(k+1)
    w = 0.5 * np.column_stack([dC[:, 2, 1] - dC[:, 1, 2], dC[:, 0, 2] - dC[:, 2, 0],
                               dC[:, 1, 0] - dC[:, 0, 1]]) * FS
    w = np.vstack([w, w[-1]])
    f_b = np.einsum("kji,kj->ki", C, acc - np.array([0.0, 0.0, 9.80665]))
    v_b = np.einsum("kji,kj->ki", C, vel)
    h = HEIGHT / C[:, 2, 2]
    flow_true = np.column_stack([w[:, 0] - v_b[:, 1] / h, w[:, 1] + v_b[:, 0] / h])

    ti = np.arange(0.005, duration_s, 0.005)
    gyro = (_interval_mean(t, w, ti - 0.005, ti)
            + _random_walk(rng, ti.size, 0.005, np.deg2rad(0.3), np.deg2rad(0.005))
            + rng.normal(0, np.deg2rad(0.15), (ti.size, 3)))
    accm = (_interval_mean(t, f_b, ti - 0.005, ti)
            + _random_walk(rng, ti.size, 0.005, 0.05, 0.002)
            + rng.normal(0, 0.1, (ti.size, 3)))
    tf = np.arange(0.25, duration_s - 0.1, 0.1)         # middles of 0.1-s intervals
    flow = _interval_mean(t, flow_true, tf - 0.05, tf + 0.05)
    e = np.zeros((tf.size, 2))
    white = rng.normal(0, 0.02 * np.sqrt(1 - 0.8**2), (tf.size, 2))
    for k in range(1, tf.size):                          # AR(1): coloured, 0.02 m/s rms
        e[k] = 0.8 * e[k - 1] + white[k]
    flow += e / HEIGHT
    qual = np.where(rng.random(tf.size) < 0.03, 0.0, 180.0)
    tr = np.arange(0.011, duration_s, 1 / 15)
    rg = np.interp(tr, t, h) + rng.normal(0, 0.015, tr.size)
    u = rng.random(tr.size)
    rg[u < 0.04] = 0.0
    rg[(u >= 0.04) & (u < 0.06)] = 5.0
    tm = np.arange(0.003, duration_s, 1 / 75)
    Cm = C[np.searchsorted(t, tm)]
    mag = np.einsum("kji,j->ki", Cm, FIELD) + rng.normal(0, 150.0, (tm.size, 3))
    tg = np.arange(0.1, duration_s, 0.2)
    gm = np.zeros((tg.size, 3))
    a = np.exp(-0.2 / 20.0)
    drive = rng.normal(0, 0.8 * np.sqrt(1 - a * a), (tg.size, 3))
    gm[0] = rng.normal(0, 0.8, 3)
    for k in range(1, tg.size):
        gm[k] = a * gm[k - 1] + drive[k]
    gpos = pos[np.searchsorted(t, tg)] + gm + rng.normal(0, 0.3, (tg.size, 3))
    if gnss_jump:
        gpos[(tg >= 30.0) & (tg < 40.0), 1] += gnss_jump   # metres east for 10 s
    llh = ned_to_geodetic(gpos, SITE)
    gvel = vel[np.searchsorted(t, tg)] + rng.normal(0, 0.1, (tg.size, 3))

    times = np.unique(np.concatenate([ti, tf, tr, tm, tg]))
    cols: dict[str, np.ndarray] = {"time": times}

    def put(names, ts, v):
        idx = np.searchsorted(times, ts)
        v = v.reshape(len(ts), -1)
        for j, c in enumerate(names):
            a = np.full(times.size, np.nan)
            a[idx] = v[:, j]
            cols[c] = a

    put(["gyro_x", "gyro_y", "gyro_z"], ti, gyro)
    put(["acc_x", "acc_y", "acc_z"], ti, accm)
    put(["flow_x", "flow_y"], tf, flow)
    put(["flow_quality"], tf, qual)
    put(["range_m"], tr, rg)
    put(["flux_x", "flux_y", "flux_z"], tm, mag)
    put(["lat", "lon", "alt"], tg, llh)
    put(["vel_n", "vel_e", "vel_d"], tg, gvel)
    k = np.searchsorted(t, times)
    return pd.DataFrame(cols), pos[k], vel[k]


def _run(kind: str, gps="none", **kw):
    log, pos, vel = fly(kind, **kw)
    res = navigate(log, gps=gps, mag_reference_ned_nT=FIELD, source="independent")
    org = tuple(res.report.gps["origin"])
    truth = geodetic_to_ned(*ned_to_geodetic(pos, SITE).T, org)
    d = res.data
    k0 = np.flatnonzero(np.isfinite(log["gyro_x"].to_numpy()))[0]
    est = d[["nav_n_m", "nav_e_m"]].to_numpy()[k0:]
    ep = est - truth[k0:, :2]          # absolute: the first fix's error included
    ev = d[["nav_vn", "nav_ve"]].to_numpy()[k0:] - vel[k0:, :2]
    sd = d[["nav_std_n_m", "nav_std_e_m"]].to_numpy()[k0:]
    return res, ep, ev, sd


@pytest.fixture(scope="module")
def runs():
    return {"hover": _run("hover"), "rectangle": _run("rectangle"),
            "rectangle_gnss": _run("rectangle", gps="use"),
            "jump": _run("rectangle", gps="use", gnss_jump=20.0)}


@pytest.mark.parametrize("kind,pos_bar,vel_bar", [("hover", 0.5, 0.15),
                                                  ("rectangle", 2.5, 0.2)])
def test_issue12_bars_with_margin_without_reject_storms(runs, kind, pos_bar, vel_bar):
    res, ep, ev, _ = runs[kind]
    ep = ep - ep[0]             # GNSS only to start: its first fix's error is an offset
    e_p, e_v = np.hypot(*ep.T).mean(), np.hypot(*ev.T).mean()
    assert e_p < 0.6 * pos_bar and e_v < 0.6 * vel_bar, (e_p, e_v)
    assert not any("in a row" in w for w in res.report.warnings), res.report.warnings
    for name in ("flow", "range", "mag"):
        s = res.report.innovations[name]
        assert s["n_fused"] > 0 and s["n_rejected"] <= 0.02 * s["n_fused"], (name, s)
    s = res.report.innovations["range"]   # the 6 % dropouts and saturations are gated
    assert s["n_gated"] >= 0.04 * (s["n_gated"] + s["n_fused"]), s


@pytest.mark.parametrize("kind", ["hover", "rectangle", "rectangle_gnss"])
def test_nis_per_sensor_in_the_band_or_named(runs, kind):
    """Flow, range and GNSS velocity, whose noise here is near or above the defaults, are in
    the band; no sensor is overconfident (above it).  The magnetometer (150 nT: 0.35°),
    gravity and GNSS position (0.85 m) are better than the defaults here; the adaptive
    noise only inflates (the configured noise is its floor), so their NIS is below the band
    and the run must say so in a warning."""
    res = runs[kind][0]
    for name, s in res.report.innovations.items():
        if s["n_fused"] < 20:
            continue
        lo, hi = s["nis_band"]
        m = s["mean_nis_per_dof"]
        assert m <= hi, (name, s)
        if name in ("flow", "range", "gps_vel"):
            assert lo <= m, (name, s)
        elif m < lo:
            assert any(f"{name}: mean NIS" in w for w in res.report.warnings), name


def _coverage(ep, sd):
    late = slice(ep.shape[0] // 10, None)
    z = np.abs(ep[late]) / sd[late]
    return np.mean(z <= 1.0), np.mean(z <= 3.0)


def test_position_sigma_covers_the_error_without_gnss():
    """GNSS only to start: the per-axis error (the first fix's included) is inside 1 sigma
    on at least 45 % of the rows, inside 3 sigma on 97 %, and sigma is not absurdly wide."""
    res, ep, _, sd = _run("rectangle", seed=6)
    c1, c3 = _coverage(ep, sd)
    assert c1 >= 0.45 and c3 >= 0.97, (c1, c3)
    assert np.median(sd) < 3.0, np.median(sd)


@pytest.mark.xfail(strict=True, reason="GNSS error correlated over 20 s is fused as white: "
                   "with GNSS, nav_std is about 2.5x too small (1-sigma coverage 0.36, 3-sigma "
                   "0.86); needs a GNSS error state (Gauss-Markov), see docs/navigate.md")
def test_position_sigma_covers_the_error_with_gnss(runs):
    c1, c3 = _coverage(runs["rectangle_gnss"][1], runs["rectangle_gnss"][3])
    assert c1 >= 0.45 and c3 >= 0.95, (c1, c3)


def test_gnss_aiding_holds_the_position_near_the_receivers_own_error(runs):
    res, ep, ev, _ = runs["rectangle_gnss"]
    assert np.sqrt(np.mean(np.sum(ep**2, axis=1))) < 1.5       # GM 0.8 m per axis + white
    assert np.hypot(*ev.T).mean() < 0.12


def test_ten_second_gnss_jump_is_refused_and_does_not_drag_the_track(runs):
    res, ep, _, _ = runs["jump"]
    _, ep_clean, _, _ = runs["rectangle_gnss"]
    s = res.report.innovations["gps_pos"]
    assert s["n_rejected"] + s["n_downweighted"] >= 0.8 * 50, s
    e, c = np.hypot(*ep.T), np.hypot(*ep_clean.T)
    assert e.max() < c.max() + 2.0, (e.max(), c.max())
