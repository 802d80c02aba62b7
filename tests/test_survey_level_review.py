"""Review of ``aeromag level`` against an independent survey generator (numpy + pyproj only).

Other geometry than the project's simulator: lines at 30 degrees azimuth, ties at 117 degrees
(not perpendicular), a line flown in two pieces, uneven speed, heights varying by line, a
magnetometer lag of 0.3 s, a diurnal from sinusoids, the IGRF in the total field, per-line
shifts and trends.  Also the JSON-report collision between ``level`` and ``grid``.
"""

from __future__ import annotations

import datetime as dt
import json

import numpy as np
import pandas as pd
import pyproj
import pytest
from typer.testing import CliRunner

import aeromag as am
from aeromag.cli import app

T0 = dt.datetime(2014, 11, 1, 15, 0, tzinfo=dt.UTC).timestamp()
LAG = 0.3


def _survey(seed: int = 7):
    rng = np.random.default_rng(seed)
    tr = pyproj.Transformer.from_crs("EPSG:32613", "EPSG:4326", always_xy=True)
    x0, y0 = 480000.0, 4440000.0  # near Boulder
    bumps = rng.uniform([-2000, -2000, 300, -150], [2000, 2000, 800, 150], (12, 4))

    def field(x, y):
        return sum(a * np.exp(-((x - bx) ** 2 + (y - by) ** 2) / (2 * w ** 2))
                   for bx, by, w, a in bumps)

    az_l, az_t = np.radians(30.0), np.radians(117.0)
    ul = np.array([np.sin(az_l), np.cos(az_l)])  # along-line unit (east, north)
    nl = np.array([np.cos(az_l), -np.sin(az_l)])
    ut = np.array([np.sin(az_t), np.cos(az_t)])
    nt = np.array([np.cos(az_t), -np.sin(az_t)])
    lines = []
    for i in range(11):
        lines.append((100 + i, "LINE", ul, nl, (i - 5) * 300.0, 1600.0, rng.normal(0, 10),
                      rng.normal(0, 6), 250.0 + 10 * i))
    for j in range(4):
        lines.append((900 + j, "TIE", ut, nt, (j - 1.5) * 900.0, 1900.0, rng.normal(0, 3),
                      0.0, 260.0))
    t = T0
    parts, truth_shift = [], {}
    for k, (num, kind, u, n, off, half, shift, trend, h) in enumerate(lines):
        s = np.linspace(-half, half, 1)  # placeholder
        speed = 40.0 + 8.0 * np.sin(np.arange(4000) / 150.0 + k)  # uneven speed, m/s
        ds = speed * 0.1
        s = -half + np.concatenate([[0.0], np.cumsum(ds)])
        s = s[s <= half]
        if k % 2:
            s = s[::-1]
        tt = t + 0.1 * np.arange(s.size)
        t = tt[-1] + 120.0
        xy = s[:, None] * u + off * n
        xy += 15.0 * np.sin(s / 700.0 + k)[:, None] * n  # wander
        lon, lat = tr.transform(x0 + xy[:, 0], y0 + xy[:, 1])
        truth = field(xy[:, 0], xy[:, 1])
        sn = (s + half) / (2 * half) - 0.5
        err = shift + trend * sn
        d = pd.DataFrame({"time": tt, "lat": lat, "lon": lon, "alt": h, "line": num,
                          "line_type": kind, "truth": truth, "err": err,
                          "x_true": xy[:, 0], "y_true": xy[:, 1]})
        if num == 104:  # flown in two pieces with a gap
            d = d.drop(d.index[d.shape[0] // 2 - 40: d.shape[0] // 2 + 40])
        parts.append(d)
        truth_shift[num] = shift
    df = pd.concat(parts, ignore_index=True)
    import ppigrf

    when = dt.datetime(2014, 11, 1, 15, 30)  # the survey's middle: IGRF moves ~0.3 nT a day
    e, nn, uu = ppigrf.igrf(df["lon"].to_numpy(), df["lat"].to_numpy(),
                            df["alt"].to_numpy() / 1000.0, when)
    igrf = np.sqrt(np.asarray(e) ** 2 + np.asarray(nn) ** 2 + np.asarray(uu) ** 2).ravel()
    tb = np.arange(T0 - 3600, t + 3600, 1.0)
    diur = 52000.0 + 20 * np.sin(2 * np.pi * (tb - T0) / 7200.0) + 5 * np.cos((tb - T0) / 500.0)
    base = pd.DataFrame({"time": tb, "mag": diur})
    # the reading at t is the field at the position of t - lag: shift the field later by LAG
    tt = df["time"].to_numpy()
    total = igrf + df["truth"].to_numpy() + df["err"].to_numpy()
    field_at = np.empty_like(total)
    for _, g in df.groupby("line").groups.items():
        ii = np.asarray(g)
        field_at[ii] = np.interp(tt[ii] - LAG, tt[ii], total[ii])
    dmean = np.interp(tt, tb, diur)
    df["mag"] = field_at + (dmean - dmean.mean()) + rng.normal(0, 0.05, tt.size)
    df["igrf_true"] = igrf
    return df, base, np.interp(tt, tb, diur)


@pytest.fixture(scope="module")
def sv():
    return _survey()


@pytest.fixture(scope="module")
def lev(sv):
    df, base, _ = sv
    return am.level(df.drop(columns=["truth", "err", "x_true", "y_true", "igrf_true"]),
                    base=base, lag="auto")


def test_lag_estimate(lev):
    lag = lev.lag_estimate
    assert abs(lag.lag_s - LAG) < 0.05
    assert 0 < lag.std_s < 0.2  # jackknife over 5 pairs: 0.13 s measured


def test_igrf_matches_ppigrf(sv, lev):
    df = sv[0]
    got = lev.data["igrf"].to_numpy()
    assert np.nanmax(np.abs(got - df["igrf_true"].to_numpy())) < 0.05


def test_levelled_against_truth(sv, lev):
    df = sv[0]
    d = lev.data
    truth = df["truth"].to_numpy()
    r = d["tmi_lev"].to_numpy() - truth
    r -= np.nanmedian(r)  # the datum is arbitrary
    raw = d["tmi"].to_numpy() - truth
    raw -= np.nanmedian(raw)
    rms, rms0 = np.sqrt(np.nanmean(r ** 2)), np.sqrt(np.nanmean(raw ** 2))
    print(rms, rms0, lev.mistie_std_nT)
    assert lev.crossings.n == 11 * 4
    assert rms < 0.25 * rms0 and rms < 2.0
    std = lev.mistie_std_nT
    assert std.before >= 5 * std.after


def test_level_accepts_a_dataframe_and_a_path(sv, tmp_path):
    df, base, _ = sv
    p = tmp_path / "s.csv"
    small = df[df["line"].isin([100, 101, 102, 900, 901])].drop(
        columns=["truth", "err", "x_true", "y_true", "igrf_true"])
    small.to_csv(p, index=False)
    a = am.level(small, igrf=False, method="shift")
    b = am.level(p, igrf=False, method="shift")
    np.testing.assert_allclose(a.data["tmi_lev"], b.data["tmi_lev"], atol=1e-6)


@pytest.fixture(scope="module")
def level_csv(tmp_path_factory, sv):
    df, base, _ = sv
    d = tmp_path_factory.mktemp("coll")
    df.drop(columns=["truth", "err", "x_true", "y_true", "igrf_true"]).to_csv(
        d / "s.csv", index=False)
    base.to_csv(d / "b.csv", index=False)
    return d


def test_grid_refuses_to_replace_the_level_report(level_csv):
    d = level_csv
    r = CliRunner().invoke(app, ["level", str(d / "s.csv"), "--base", str(d / "b.csv"),
                                 "-o", str(d / "lev.csv")])
    assert r.exit_code == 0, r.output
    rep = json.loads((d / "lev.json").read_text())
    assert rep["output"] == "lev.csv"
    r = CliRunner().invoke(app, ["grid", str(d / "lev.csv"), "-o", str(d / "lev.nc")])
    assert r.exit_code == 1
    assert "lev.json" in r.output and "another -o" in r.output
    assert len(r.output.strip().splitlines()) == 1
    assert not (d / "lev.nc").exists()
    assert json.loads((d / "lev.json").read_text()) == rep
    # the same level run again may replace its own report
    r = CliRunner().invoke(app, ["level", str(d / "s.csv"), "--base", str(d / "b.csv"),
                                 "-o", str(d / "lev.csv")])
    assert r.exit_code == 0, r.output


def test_level_refuses_to_replace_the_grid_report(level_csv):
    d = level_csv
    r = CliRunner().invoke(app, ["level", str(d / "s.csv"), "--base", str(d / "b.csv"),
                                 "-o", str(d / "a.csv")])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(app, ["grid", str(d / "a.csv"), "-o", str(d / "g.nc")])
    assert r.exit_code == 0, r.output
    assert json.loads((d / "g.json").read_text())["output"] == "g.nc"
    r = CliRunner().invoke(app, ["level", str(d / "s.csv"), "--base", str(d / "b.csv"),
                                 "-o", str(d / "g.csv")])
    assert r.exit_code == 1 and "g.json" in r.output
    assert not (d / "g.csv").exists()
    assert json.loads((d / "g.json").read_text())["output"] == "g.nc"
