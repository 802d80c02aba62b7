"""A demanding user's review of the survey chain on a multirotor UAV survey (issue 27).

The survey comes from an independent generator written here (not aeromag.synthetic): a
MagArrow/MagDrone under a multirotor, lines 20 m apart flown back and forth at 5 m/s with
10 m-radius U-turns flown at 1.5 m/s (1.5 m/s^2 into and out of them), ties across flown
after the lines with stop-and-go transits (no line number), terrain following at 30 m AGL
(the height lags the terrain by 2 s), GNSS error as a Gauss-Markov wander (1.5 m, 60 s) plus
white noise (0.5-2 m), a base station with a 25 nT diurnal and pulsations, a 0.2 s lag,
per-line shifts of 1-5 nT and the field of five shallow induced dipoles (5-30 m deep) or,
the clean variant, two deep sources and a regional gradient; IGRF from ppigrf directly.

Figures measured with this generator (seeds 1-4; 12 lines x 400 m, 3 ties; before -> after
the fixes in this branch):
- straight parts: 82-98 % of the U-turn samples were called straight (the direction over
  +-5 samples of 0.15-0.5 m is the GNSS noise's) -> 0-2 %; 1-6 % of the true straight
  (the slow run-in and run-out) trimmed.
- grid line spacing (20 m lines): 3.3-7.1 m (turn fragments counted as lines; default cell
  0.65 m) -> 19.5-20.2 m (cell 3.9-4.0 m).
- crossings: 36 of 36 line-tie intersections; ties 900, 910, 920 found by direction.
- lag (true 0.2 s): 0.13-0.16 +- 0.06-0.11 s (jackknife).  With no terrain-following height
  lag and no GNSS noise it is 0.206-0.208 s: the bias is the height difference between lines
  flown in opposite directions (a herring-bone of its own), not the search.
- levelling: tmi rms error against the truth 2.5-3.7 nT (datum removed) -> tmi_lev 0.09-0.73
  nT; mistie std 3.1-4.4 -> 0.5-0.76 nT.
- grid (cell 4 m, tension 0.25) against the truth on the drape, inside the block: rms 0.9-1.1
  nT for a field std of 8.9-11.3 nT (shallow) and 0.9 nT for 25.8 nT (deep); between lines
  0.87-1.16 nT, on lines 0.85-1.03 nT (the 1.5 m GNSS wander times the gradient dominates:
  0.62 nT without it).
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np
import pandas as pd
import ppigrf
import pytest
from pyproj import Transformer
from typer.testing import CliRunner

import aeromag as am
from aeromag.cli import app
from aeromag.errors import InputError
from aeromag.survey.crossings import find_crossings
from aeromag.survey.diurnal import BaseRecord
from aeromag.survey.geometry import build_geometry
from aeromag.survey.gridding import estimate_line_spacing
from aeromag.survey.lag import estimate_lag

EPSG = 32750  # UTM 50S
LAT0, LON0 = -31.9, 115.9
T0 = pd.Timestamp("2024-06-15T01:00:00Z").timestamp()


@dataclass
class UavSurvey:
    survey: pd.DataFrame   # time, lat, lon, alt, mag, line
    base: pd.DataFrame     # time, mag
    truth: pd.DataFrame    # true x, y, z (UTM m), anomaly at the true position, straight flag
    anomaly: object        # callable(x, y, z) -> nT (UTM metres, ellipsoidal height)
    ground: object         # callable(x, y) -> ground height (m)
    n_lines: int
    n_ties: int
    spacing_m: float
    lag_s: float
    origin: tuple[float, float]
    direction_deg: float


def _path(n_lines, spacing, length, tie_along, overrun):
    """Polyline (along, across) at 0.05 m, with a label per point and a cap speed class."""
    pts, lab, cls = [], [], []   # cls 0 straight, 1 turn, 2 stop corner
    ds = 0.05

    def straight(p0, p1, label):
        d = np.hypot(p1[0] - p0[0], p1[1] - p0[1])
        k = max(2, int(d / ds))
        f = np.linspace(0, 1, k, endpoint=False)
        pts.append(np.column_stack([p0[0] + f * (p1[0] - p0[0]), p0[1] + f * (p1[1] - p0[1])]))
        lab.append(np.full(k, label, dtype=float))
        cls.append(np.zeros(k, dtype=int))

    def uturn(p0, p1, sign_along, l0, l1):
        # semicircle from p0 to p1 (laterally separated), bulging along sign_along
        c = ((p0[0] + p1[0]) / 2, (p0[1] + p1[1]) / 2)
        r = np.hypot(p1[0] - p0[0], p1[1] - p0[1]) / 2
        k = max(4, int(np.pi * r / ds))
        a = np.linspace(0, np.pi, k, endpoint=False)
        # the unit vector from centre to p0 and the bulge direction
        e = ((p0[0] - c[0]) / r, (p0[1] - c[1]) / r)
        b = (sign_along, 0.0) if abs(e[0]) < 0.5 else (0.0, sign_along)
        pts.append(np.column_stack([c[0] + r * (np.cos(a) * e[0] + np.sin(a) * b[0]),
                                    c[1] + r * (np.cos(a) * e[1] + np.sin(a) * b[1])]))
        lab.append(np.where(a < np.pi / 2, l0, l1).astype(float))
        cls.append(np.ones(k, dtype=int))

    ends = []
    for i in range(n_lines):
        a0, a1 = (-overrun, length + overrun) if i % 2 == 0 else (length + overrun, -overrun)
        c = i * spacing
        straight((a0, c), (a1, c), 100 + 10 * i)
        ends.append((a1, c))
        if i < n_lines - 1:
            uturn((a1, c), (a1, c + spacing), 1.0 if i % 2 == 0 else -1.0,
                  100 + 10 * i, 110 + 10 * i)
    width = (n_lines - 1) * spacing
    # transit to the first tie (stop at the corners)
    last = ends[-1]
    t_ext = 2 * spacing
    first = (tie_along[0], width + t_ext)
    straight(last, first, np.nan)
    cls[-1][[0, -1]] = 2
    for j, a in enumerate(tie_along):
        c0, c1 = (width + t_ext, -t_ext) if j % 2 == 0 else (-t_ext, width + t_ext)
        straight((a, c0), (a, c1), 900 + 10 * j)
        if j < len(tie_along) - 1:
            straight((a, c1), (tie_along[j + 1], c1), np.nan)
            cls[-1][[0, -1]] = 2
    return np.vstack(pts), np.concatenate(lab), np.concatenate(cls)


def simulate_uav(seed=0, *, fs=10.0, speed=5.0, spacing=20.0, length=400.0, n_lines=12,
                 n_ties=3, agl=30.0, lag_s=0.2, gnss_white=0.5, gnss_walk=1.5,
                 diurnal_nT=25.0, shift_nT=3.0, deep=False, direction_deg=30.0, terrain=1.0,
                 follow_lag_s=2.0, tie_margin=0.05):
    rng = np.random.default_rng(seed)
    tie_along = np.linspace(tie_margin * length, (1 - tie_margin) * length, n_ties)
    pa, label, cls = _path(n_lines, spacing, length, tie_along, overrun=5.0)
    # arc length and speed profile: cruise on straights, 1.5 m/s in turns, 0.3 at corners,
    # acceleration limited to 1.5 m/s^2 (v^2 <= cap^2 + 2 a |s - s_j| for every slow point j)
    seg = np.hypot(np.diff(pa[:, 0]), np.diff(pa[:, 1]))
    s = np.r_[0.0, np.cumsum(seg)]
    cap = np.where(cls == 0, speed, np.where(cls == 1, 1.5, 0.3))
    acc = 1.5
    w = cap ** 2
    fwd = np.minimum.accumulate(w - 2 * acc * s) + 2 * acc * s
    bwd = (np.minimum.accumulate((w + 2 * acc * s)[::-1]) - 2 * acc * s[::-1])[::-1]
    v = np.sqrt(np.maximum(np.minimum(np.minimum(fwd, bwd), w), 0.09))
    t_of_s = np.r_[0.0, np.cumsum(seg / (0.5 * (v[1:] + v[:-1])))]
    t = np.arange(0.0, t_of_s[-1], 1.0 / fs)
    ss = np.interp(t, t_of_s, s)
    idx = np.clip(np.searchsorted(s, ss, side="right") - 1, 0, s.size - 1)
    lab = label[idx]
    along = np.interp(ss, s, pa[:, 0])
    across = np.interp(ss, s, pa[:, 1])
    straight_true = cls[idx] == 0
    # rotate (along direction at direction_deg east of north) and place in UTM
    th = np.deg2rad(direction_deg)
    ua = np.array([np.sin(th), np.cos(th)])
    uc = np.array([np.cos(th), -np.sin(th)])
    tr = Transformer.from_crs(4326, EPSG, always_xy=True)
    e0, n0 = tr.transform(LON0, LAT0)
    x = e0 + along * ua[0] + across * uc[0]
    y = n0 + along * ua[1] + across * uc[1]

    def ground(xx, yy):
        return (40.0 + terrain * 4.0 * np.sin((xx - e0) / 90.0) * np.cos((yy - n0) / 120.0)
                + terrain * 3.0 * np.sin((xx - e0 + yy - n0) / 60.0))

    # terrain following: the height command lags the terrain by ~2 s, plus 0.3 m of noise
    gz = ground(x, y)
    k = int(follow_lag_s * fs)
    gz_lag = np.r_[np.full(k, gz[0]), gz[:gz.size - k]]
    z = gz_lag + agl + 0.3 * np.cumsum(rng.normal(0, 0.05, t.size)).clip(-1, 1)
    # field: induced dipoles along the IGRF direction
    tobs = pd.Timestamp(T0, unit="s").to_pydatetime()
    be, bn, bu = ppigrf.igrf(LON0, LAT0, 0.04, tobs)
    f = np.array([float(np.ravel(be)[0]), float(np.ravel(bn)[0]), float(np.ravel(bu)[0])])
    fhat = f / np.linalg.norm(f)
    if deep:
        src = [(60.0, 30.0, 150.0, 4e6), (300.0, 200.0, 220.0, 6e6)]
    else:
        src = [(a, c, d, m) for a, c, d, m in zip(
            rng.uniform(0.15, 0.85, 5) * length, rng.uniform(0.1, 0.9, 5) * (n_lines - 1) * spacing,
            rng.uniform(5.0, 30.0, 5), rng.uniform(3e3, 3e4, 5), strict=True)]
    dip = []
    for a, c, d, m in src:
        xd = e0 + a * ua[0] + c * uc[0]
        yd = n0 + a * ua[1] + c * uc[1]
        dip.append((xd, yd, float(ground(xd, yd)) - d, m))

    def anomaly(xx, yy, zz):
        out = np.zeros(np.shape(xx))
        for xd, yd, zd, m in dip:
            r = np.stack([xx - xd, yy - yd, zz - zd])  # east, north, up
            rn = np.sqrt((r ** 2).sum(0))
            rh = r / rn
            mv = m * fhat[:, None] if np.ndim(xx) == 1 else m * fhat.reshape(3, *(1,) * np.ndim(xx))
            mdot = (mv * rh).sum(0)
            b = 100.0 * (3 * mdot * rh - mv) / rn ** 3
            out += np.tensordot(fhat, b, axes=1)
        if deep:
            out += 0.02 * (xx - e0) - 0.01 * (yy - n0)  # a regional gradient, nT/m
        return out

    # the reading at t is the field at the position of t - lag
    tl = t - lag_s
    xl, yl, zl = (np.interp(tl, t, q) for q in (x, y, z))
    anom_lagged = anomaly(xl, yl, zl)
    anom_true = anomaly(x, y, z)
    # diurnal: a slow swing plus pulsations, seen the same at the base and the drone
    tt = T0 + t
    span = t[-1]
    def diurnal(tabs):
        u = tabs - T0
        return (diurnal_nT * np.sin(2 * np.pi * u / (2.5 * span))
                + 2.0 * np.sin(2 * np.pi * u / 300.0) + 0.8 * np.sin(2 * np.pi * u / 47.0))
    lat, lon = (np.asarray(q) for q in Transformer.from_crs(EPSG, 4326, always_xy=True)
                .transform(x, y)[::-1])
    bE, bN, bU = ppigrf.igrf(lon, lat, z / 1000.0, tobs)
    igrf = np.sqrt(np.ravel(bE) ** 2 + np.ravel(bN) ** 2 + np.ravel(bU) ** 2)
    lines = np.unique(lab[np.isfinite(lab)])
    shifts = dict(zip(lines, rng.uniform(1.0, 5.0, lines.size) * rng.choice([-1, 1], lines.size)
                      * shift_nT / 3.0, strict=True))
    shift = np.array([shifts.get(v, 0.0) for v in lab])
    mag = igrf + anom_lagged + diurnal(tt) + shift + rng.normal(0, 0.02, t.size)
    # logged positions: true + Gauss-Markov wander (tau 60 s) + white
    a = np.exp(-1.0 / (60.0 * fs))
    wx = np.zeros(t.size)
    wy = np.zeros(t.size)
    qx = rng.normal(0, gnss_walk * np.sqrt(1 - a * a), t.size)
    qy = rng.normal(0, gnss_walk * np.sqrt(1 - a * a), t.size)
    wx[0], wy[0] = rng.normal(0, gnss_walk, 2)
    for i in range(1, t.size):
        wx[i] = a * wx[i - 1] + qx[i]
        wy[i] = a * wy[i - 1] + qy[i]
    xo = x + wx + rng.normal(0, gnss_white, t.size)
    yo = y + wy + rng.normal(0, gnss_white, t.size)
    lato, lono = (np.asarray(q) for q in Transformer.from_crs(EPSG, 4326, always_xy=True)
                  .transform(xo, yo)[::-1])
    survey = pd.DataFrame({"time": tt, "lat": lato, "lon": lono,
                           "alt": z + rng.normal(0, 0.5, t.size), "mag": mag, "line": lab})
    tb = np.arange(T0 - 600.0, T0 + span + 600.0, 1.0)
    base = pd.DataFrame({"time": tb, "mag": 57000.0 + diurnal(tb) + rng.normal(0, 0.05, tb.size)})
    truth = pd.DataFrame({"x": x, "y": y, "z": z, "x_obs": xo, "y_obs": yo, "anomaly": anom_true,
                          "straight": straight_true, "shift": shift, "speed": np.r_[0, np.hypot(
                              np.diff(x), np.diff(y)) * fs]})
    return UavSurvey(survey, base, truth, anomaly, ground, n_lines, n_ties, spacing, lag_s,
                     (e0, n0), direction_deg)


runner = CliRunner()


@pytest.fixture(scope="module")
def noisy25():
    return simulate_uav(seed=4, fs=25.0, gnss_white=2.0, n_lines=8, length=300.0)


def test_straight_parts_leave_the_slow_noisy_turns_out(noisy25):
    s = noisy25
    d, tr = s.survey, s.truth
    g = build_geometry(d.lat.to_numpy(), d.lon.to_numpy(), d.line.to_numpy())
    lab = np.isfinite(d.line.to_numpy())
    true_straight = tr.straight.to_numpy() & lab
    turn = lab & ~true_straight
    assert g.n_pieces == s.n_lines + s.n_ties
    assert np.mean(g.straight[turn]) < 0.25  # was 0.98: the turns were "straight"
    assert np.mean(~g.straight[true_straight]) < 0.05
    assert abs(g.line_spacing_m - s.spacing_m) < 1.0


def test_grid_line_spacing_ignores_turn_fragments(noisy25):
    tr = noisy25.truth
    line = noisy25.survey.line.to_numpy()
    est = estimate_line_spacing(tr.x_obs.to_numpy(), tr.y_obs.to_numpy(), line)
    assert abs(est - noisy25.spacing_m) < 0.1 * noisy25.spacing_m  # was 3-7 m for 20 m


@pytest.mark.parametrize("deep", [False, True])
def test_level_and_grid_a_uav_survey_through_the_cli(tmp_path, deep):
    s = simulate_uav(seed=1 if not deep else 3, fs=10.0, n_lines=10, length=300.0, deep=deep)
    sv, bs = tmp_path / "s.csv", tmp_path / "b.csv"
    s.survey.to_csv(sv, index=False)
    s.base.to_csv(bs, index=False)
    lev = tmp_path / "lev.csv"
    r = runner.invoke(app, ["level", str(sv), "--base", str(bs), "--lag", "auto",
                            "-o", str(lev)])
    assert r.exit_code == 0, r.output
    rep = json.loads(lev.with_suffix(".json").read_text())
    assert rep["n_crossovers"] == s.n_lines * s.n_ties
    assert abs(rep["line_spacing_m"] - s.spacing_m) < 1.0
    est = rep["lag_estimate"]
    # the terrain-following height lag biases it (see the module's docstring): within its
    # jackknife error, never wildly off
    assert abs(est["lag_s"] - s.lag_s) < max(2.0 * est["std_s"], 0.05)
    out = pd.read_csv(lev)
    assert set(out.loc[out.line_type == "tie", "line"].unique()) == {900.0, 910.0, 920.0}
    truth = s.truth.anomaly.to_numpy()

    def rms(col):
        e = out[col].to_numpy() - truth
        e = e[np.isfinite(e)]
        e -= np.median(e)  # the datum is not observable
        return float(np.sqrt(np.mean(e ** 2)))

    # deep: 1.32 of 3.33 nT with the default trend levelling (--level shift: 0.45 nT): two
    # unknowns per line from 3 crossings fit the misties' GNSS-position error (not fixed here)
    assert rms("tmi_lev") < (0.5 if deep else 0.35) * rms("tmi")
    assert rep["mistie_std_nT"]["after"] < 0.35 * rep["mistie_std_nT"]["before"]
    g = tmp_path / "g.nc"
    r = runner.invoke(app, ["grid", str(lev), "-o", str(g)])
    assert r.exit_code == 0, r.output
    gj = json.loads(g.with_suffix(".json").read_text())
    assert gj["cell_m"] in (3.8, 3.9, 4.0, 4.1, 4.2)  # a fifth of 20 m
    import xarray as xr

    with xr.open_dataset(g) as ds:
        v = ds["tmi_lev"]
        X, Y = np.meshgrid(v.x.values, v.y.values)
        val = v.values
    th = np.deg2rad(s.direction_deg)
    e0, n0 = s.origin
    al = (X - e0) * np.sin(th) + (Y - n0) * np.cos(th)
    ac = (X - e0) * np.cos(th) - (Y - n0) * np.sin(th)
    w = (s.n_lines - 1) * s.spacing_m
    inside = ((al > 15) & (al < 285) & (ac > s.spacing_m) & (ac < w - s.spacing_m)
              & np.isfinite(val))
    t = s.anomaly(X[inside], Y[inside], s.ground(X[inside], Y[inside]) + 30.0)
    e = val[inside] - t
    e -= np.median(e)
    assert np.sqrt(np.mean(e ** 2)) < 0.15 * t.std()


def test_lag_is_recovered_without_the_height_herringbone():
    s = simulate_uav(seed=3, fs=25.0, deep=True, gnss_walk=0.0,
                     gnss_white=0.0, follow_lag_s=0.0)
    d = s.survey
    g = build_geometry(d.lat.to_numpy(), d.lon.to_numpy(), d.line.to_numpy())
    base = np.interp(d.time, s.base.time, s.base.mag)
    est = estimate_lag(g, d.time.to_numpy(), d.mag.to_numpy() - base)
    assert abs(est.lag_s - s.lag_s) < 0.03


def test_north_south_lines_slow_and_noisy_keep_every_crossing_and_the_lag_search():
    # Lines along grid north have directions near 0 and near 180 degrees: their median
    # direction was anything between, and --lag auto refused ("the opposite-direction lines
    # do not overlap").  3 m/s at 25 Hz with 1.5 m of white GNSS noise: the straight parts
    # must still hold every line-tie crossing (ties at the very ends of the lines).
    s = simulate_uav(seed=7, fs=25.0, spacing=30.0, speed=3.0, length=300.0, n_lines=6,
                     n_ties=3, direction_deg=0.0, gnss_white=1.5, tie_margin=0.0, deep=True)
    d = s.survey
    g = build_geometry(d.lat.to_numpy(), d.lon.to_numpy(), d.line.to_numpy())
    assert g.lines_direction_deg < 2.0 or g.lines_direction_deg > 178.0
    assert find_crossings(g, d.mag.to_numpy()).n == s.n_lines * s.n_ties
    base = np.interp(d.time, s.base.time, s.base.mag)
    est = estimate_lag(g, d.time.to_numpy(), d.mag.to_numpy() - base)
    assert est.n_pairs >= 3 and abs(est.lag_s - s.lag_s) < max(2.5 * est.std_s, 0.05)


def test_lag_auto_refuses_when_the_lines_do_not_determine_it():
    # Shallow sources (5-30 m deep, 30 m AGL) under lines 30 m apart flown at 3 m/s: the
    # field changes more from line to line than a 0.2 s lag (0.6 m) moves it; the misfit is
    # within 10 % from -2.0 to -0.26 s and the estimate was -1.13 +- 0.13 s, silently applied.
    s = simulate_uav(seed=7, fs=25.0, spacing=30.0, speed=3.0, length=300.0, n_lines=6,
                     n_ties=3, direction_deg=0.0, gnss_white=1.5, tie_margin=0.0)
    d = s.survey
    g = build_geometry(d.lat.to_numpy(), d.lon.to_numpy(), d.line.to_numpy())
    base = np.interp(d.time, s.base.time, s.base.mag)
    with pytest.raises(InputError, match="do not determine the lag"):
        estimate_lag(g, d.time.to_numpy(), d.mag.to_numpy() - base)


def test_grid_help_lists_value_and_crs_once():
    # the shared level rows also named grid, whose own grid_value / grid_crs rows took the
    # flags: --help showed both, one of them dead
    out = runner.invoke(app, ["grid", "--help"], terminal_width=100).output
    assert out.count("--value") == 1 and out.count("--crs") == 1


def test_decorrugation_runs_along_north_south_lines():
    # N-S lines have directions near 0 and 180 degrees; their median (about 90) turned the
    # micro-levelling across the lines, where it found nothing to remove (tmi_mlev == tmi_lev).
    # Without tie-line levelling the line shifts are left for it to find (after it, the
    # crossing check of the micro-levelling rejects what the crossings do not support).
    def corrugation(direction):
        s = simulate_uav(seed=2, fs=10.0, n_lines=8, length=300.0, direction_deg=direction)
        base = BaseRecord(s.base.time.to_numpy(), s.base.mag.to_numpy(), "b")
        r = am.level(s.survey, base=base, lag=0.2, decorrugate=True, method="none")
        d = (r.data["tmi_mlev"] - r.data["tmi_lev"]).to_numpy()
        return float(np.sqrt(np.nanmean(d ** 2)))

    ns, oblique = corrugation(0.0), corrugation(0.7)
    assert oblique > 0.01 and ns > 0.5 * oblique
