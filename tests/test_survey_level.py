"""Levelling chain (issue 27, level side): simulator, an independent generator, bad inputs.

Figures these tests hold (seeds 0, 1, 2 of the project's simulator; 16 lines, 4 ties, lag
0.4 s, 30 nT diurnal, line shifts 6 nT and trends 4 nT, ties 5 m higher): lag within 0.05 s
(0.393, 0.421, 0.408 s), diurnal removed to <= 0.3 nT rms (0.04), mistie std reduced >= 5x
(5.5 -> 0.97, 4.2 -> 0.48, 5.8 -> 0.78 nT), levelled anomaly against the truth <= 0.6 nT rms
after the datum constant (0.49, 0.41, 0.50 nT; 0.25-0.49 with ties at the lines' height).
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pyproj
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

import aeromag as am
from aeromag.cli import app
from aeromag.errors import InputError
from aeromag.survey.crossings import find_crossings
from aeromag.survey.diurnal import BaseRecord
from aeromag.survey.geometry import build_geometry
from aeromag.synthetic.level_survey import simulate_level_survey


def _base(b: pd.DataFrame) -> BaseRecord:
    return BaseRecord(b["time"].to_numpy(), b["mag"].to_numpy(), "base.csv")


def _rms_vs_truth(res, col="tmi_lev"):
    d = res.data
    st_ = res.geometry.straight
    e = (d[col] - d["truth_anomaly"]).to_numpy()[st_]
    e = e[np.isfinite(e)]
    return float(np.sqrt(np.mean((e - e.mean()) ** 2)))


@pytest.fixture(scope="module")
def sims():
    out = {}
    for seed in (0, 1, 2):
        df, base, truth = simulate_level_survey(seed)
        out[seed] = (df, base, truth, am.level(df, base=_base(base), lag="auto"))
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_simulator_chain(sims, seed):
    df, base, truth, res = sims[seed]
    assert abs(res.lag_s - truth["lag_s"]) <= 0.05
    assert res.lag_estimate.n_pairs >= 10 and np.isfinite(res.lag_estimate.std_s)
    d = res.data
    e = (d["diurnal"] - d["truth_diurnal"]).to_numpy()
    assert np.sqrt(np.mean((e - e.mean()) ** 2)) <= 0.3
    assert np.nanmax(np.abs(d["igrf"] - d["truth_igrf"])) < 0.05
    std = res.mistie_std_nT
    assert std.before >= 5.0 * std.after
    assert _rms_vs_truth(res) < 0.6
    assert _rms_vs_truth(res) < 0.2 * _rms_vs_truth(res, "tmi")
    rep = res.to_report()
    assert rep["crs"] == 32754 and rep["n_crossovers"] == 16 * 4
    keys = {"line", "tie", "x_m", "y_m", "mistie_nT", "mistie_lev_nT"}
    assert keys <= rep["crossovers"][0].keys()
    assert len(rep["lines"]) == 20 and rep["lines"][0]["type"] in ("line", "tie")
    assert rep["diurnal"]["datum_nT"] == pytest.approx(50500.0, abs=40)
    passes = rep["levelling"]["passes"]
    assert passes[0]["kind"] == "weighted" and passes[-1]["kind"] == "bisquare"


def test_decorrugation_bounded(sims):
    """On the simulator (compact dipoles, 4-km lines) the directional filter cannot tell the
    sources from corrugation: what it removes is held to the bound (3 x robust mistie std),
    and the crossing check rejects it (tests/test_survey_quality.py)."""
    df, base, truth, _ = sims[1]
    res = am.level(df, base=_base(base), lag=0.4, decorrugate=True)
    dec = res.decorrugation
    corr = (res.data["tmi_lev"] - res.data["tmi_mlev"]).to_numpy()
    assert np.nanmax(np.abs(corr)) <= dec.limit_nT + 1e-9
    assert dec.limit_nT == pytest.approx(3 * res.mistie_robust_std_nT.after, rel=1e-6)
    assert dec.std_removed_nT and max(dec.std_removed_nT.values()) <= dec.limit_nT
    assert np.all(np.nan_to_num(corr[res.geometry.is_tie]) == 0)


def test_decorrugation_removes_corrugation_over_broad_geology():
    """Independent: 30 lines of 20 km, broad geology (3-6 km), 1 nT line shifts left over.

    Shifts are white across lines; the high-pass at 4 line spacings sees the upper part of
    that band, so about half the std goes (measured 0.85 -> 0.48 nT)."""
    rng = np.random.default_rng(11)
    x = np.arange(0, 20000.0, 20.0)
    xs, ys, ln, err = [], [], [], []
    for i in range(30):
        xs.append(x)
        ys.append(np.full(x.size, 200.0 * i + 5.0 * np.sin(x / 3000.0 + i)))
        ln.append(np.full(x.size, i + 1.0))
        err.append(np.full(x.size, rng.normal(0, 1.0)))
    x_, y_, ln_, err_ = map(np.concatenate, (xs, ys, ln, err))
    geology = (60 * np.exp(-((x_ - 8000) ** 2 + (y_ - 3000) ** 2) / (2 * 2500.0 ** 2))
               + 30 * np.sin(x_ / 2500.0) * np.cos(y_ / 3000.0))
    from aeromag.survey.decorrugation import decorrugate

    geom = build_geometry(None, None, ln_, x_m=x_, y_m=y_, crs=32633)
    res = decorrugate(geom, geology + err_, limit_nT=3.0)
    inner = (x_ > 3000) & (x_ < 17000) & (y_ > 600) & (y_ < 5200)
    before = err_[inner] - err_[inner].mean()
    after = (err_ - res.correction_nT)[inner]
    after = after - after.mean()
    assert np.std(after) < 0.65 * np.std(before)  # measured 0.85 -> 0.48 nT


def test_decorrugation_keeps_geology_along_lines():
    """A ridge striking along the lines (40 nT, 400 m wide) loses at most the bound."""
    rng = np.random.default_rng(5)
    x_list, y_list, line = [], [], []
    for i in range(20):
        x = np.arange(0, 3000.0, 10.0)
        x_list.append(x)
        y_list.append(np.full(x.size, 200.0 * i))
        line.append(np.full(x.size, i + 1.0))
    x, y, ln = map(np.concatenate, (x_list, y_list, line))
    geom = build_geometry(None, None, ln, x_m=x, y_m=y, crs=32633)
    ridge = 40.0 * np.exp(-((y - 2000.0) / 200.0) ** 2)
    from aeromag.survey.decorrugation import decorrugate

    res = decorrugate(geom, ridge + rng.normal(0, 0.01, x.size), limit_nT=1.0)
    assert np.max(np.abs(res.correction_nT)) <= 1.0
    assert res.fraction_clipped > 0  # the ridge is what the filter sees; the bound holds it


# ----------------------------------------------------------------- independent generator
def _independent_survey(seed: int):
    """Other geometry (north-south lines, 30 m wander, east-west ties at 1.5 km), other
    noise (red, 0.2 nT), Gaussian-bump geology, no lag, a line_type column, no time."""
    rng = np.random.default_rng(seed)
    tr = pyproj.Transformer.from_crs("EPSG:32611", "EPSG:4326", always_xy=True)
    x0, y0 = 500000.0, 4000000.0
    rows = []
    bumps = rng.uniform([0, 0, 200, -80], [3000, 6000, 600, 80], (15, 4))

    def field(x, y):
        return sum(a * np.exp(-((x - bx) ** 2 + (y - by) ** 2) / (2 * w ** 2))
                   for bx, by, w, a in bumps)

    for i in range(13):  # lines: north-south, 250 m apart, alternate directions
        y = np.arange(-100.0, 6100.0, 8.0)[:: 1 if i % 2 else -1]
        x = 250.0 * i + 30.0 * np.sin(y / 900.0 + i)
        rows.append((x, y, 1000.0 + i, "LINE", rng.normal(0, 8), rng.normal(0, 5)))
    for j in range(5):  # ties: east-west, 1.5 km apart
        x = np.arange(-100.0, 3100.0, 8.0)
        y = 1500.0 * j + 20.0 * np.cos(x / 700.0)
        rows.append((x, y, 2000.0 + j, "TIE", rng.normal(0, 3), 0.0))
    parts = []
    for x, y, num, kind, shift, trend in rows:
        red = np.cumsum(rng.normal(0, 0.02, x.size))
        red -= np.linspace(red[0], red[-1], x.size)
        s = np.linspace(-0.5, 0.5, x.size)
        truth = field(x, y)
        lon, lat = tr.transform(x0 + x, y0 + y)
        parts.append(pd.DataFrame({"lat": lat, "lon": lon, "alt": 300.0, "line": num,
                                   "line_type": kind, "mag": truth + shift + trend * s + red,
                                   "truth_anomaly": truth}))
    return pd.concat(parts, ignore_index=True)


@pytest.mark.parametrize("seed", [3, 4])
def test_independent_generator(seed):
    df = _independent_survey(seed)
    res = am.level(df, igrf=False)
    g = res.geometry
    assert g.tie_source == "line_type" and g.piece_is_tie.sum() == 5
    assert res.crossings.n == 13 * 5
    assert g.crs == 32611
    std = res.mistie_std_nT
    assert std.before >= 5.0 * std.after
    assert _rms_vs_truth(res) < 0.3 * _rms_vs_truth(res, "tmi")
    assert _rms_vs_truth(res) < 1.5


# ----------------------------------------------------------------- geometry properties
@settings(max_examples=25, deadline=None)
@given(angle=st.floats(0, 180), n_lines=st.integers(2, 7), n_ties=st.integers(1, 4),
       step=st.floats(3.0, 30.0))
def test_crossings_of_a_rotated_grid(angle, n_lines, n_ties, step):
    """Every line crosses every tie once, at the analytic intersection."""
    th = np.deg2rad(angle)
    rot = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    pts, line, kind = [], [], []
    for i in range(n_lines):
        u = np.arange(0.0, 2000.0, step)
        pts.append(np.column_stack([u, np.full(u.size, 100.0 * i + 50.0)]))
        line.append(np.full(u.size, i + 1.0))
        kind += ["line"] * u.size
    for j in range(n_ties):
        v = np.arange(0.0, 100.0 * n_lines + 100.0, step)
        pts.append(np.column_stack([np.full(v.size, 300.0 + 400.0 * j + 0.37), v]))
        line.append(np.full(v.size, 100.0 + j))
        kind += ["tie"] * v.size
    p = np.vstack(pts) @ rot.T
    ln = np.concatenate(line)
    geom = build_geometry(None, None, ln, x_m=p[:, 0], y_m=p[:, 1], crs=32633, line_type=kind)
    cx = find_crossings(geom, p[:, 0] * 0.01)
    assert cx.n == n_lines * n_ties
    local = np.column_stack([cx.x_m, cx.y_m]) @ rot
    i = np.rint((local[:, 1] - 50.0) / 100.0)
    j = np.rint((local[:, 0] - 300.37) / 400.0)
    np.testing.assert_allclose(local[:, 1], 100.0 * i + 50.0, atol=1e-6)
    np.testing.assert_allclose(local[:, 0], 300.37 + 400.0 * j, atol=1e-6)
    np.testing.assert_allclose(cx.mistie_nT, 0.0, atol=1e-9)  # a planar field has no mistie


def test_line_in_pieces_keeps_its_number():
    x = np.r_[np.arange(0, 1000.0, 10), np.arange(2000, 3000.0, 10)]
    geom = build_geometry(None, None, np.full(x.size, 7.0), x_m=x, y_m=np.zeros(x.size),
                          crs=32633)
    assert geom.n_pieces == 2 and set(geom.piece_line) == {7.0}


# ----------------------------------------------------------------- diurnal and bad inputs
def test_base_spike_removed_and_reported(sims, caplog):
    df, base, truth, _ = sims[0]
    b = base.copy()
    i = len(b) // 2
    b.loc[i, "mag"] += 250.0
    res = am.level(df, base=b, lag=0.4)
    assert res.diurnal.spikes_s == [float(b["time"][i])]
    assert any("spike" in w for w in res.warnings)
    e = (res.data["diurnal"] - res.data["truth_diurnal"]).to_numpy()
    assert np.std(e) <= 0.3


@pytest.mark.parametrize(("shift_s", "words"), [(86400.0, "a day off"),
                                                 (-10 * 3600.0, "local time"),
                                                 (9 * 3600.0, "local time")])
def test_base_in_another_time_base(sims, shift_s, words):
    df, base, truth, _ = sims[0]
    b = base.copy()
    b["time"] = b["time"] + shift_s
    with pytest.raises(InputError, match="does not cover") as exc:
        am.level(df, base=b)
    assert words in str(exc.value)


def test_base_not_covering_the_survey(sims):
    df, base, truth, _ = sims[0]
    half = base.iloc[len(base) // 3:]  # the first lines are not covered, the ties are
    with pytest.raises(InputError, match="does not cover .* survey samples"):
        am.level(df, base=half)
    res = am.level(df, base=half, allow_base_gaps=True)
    dn = res.data["diurnal"].to_numpy()
    assert np.isnan(dn).any() and np.isfinite(dn).any()
    assert np.isnan(res.data["tmi"].to_numpy()[np.isnan(dn)]).all()  # never extrapolated
    assert any("outside the base's coverage" in w for w in res.warnings)


def test_refusals(sims):
    df, base, truth, _ = sims[0]
    with pytest.raises(InputError, match="no line column"):
        am.level(df.drop(columns="line"))
    no_ties = df[~df["line"].isin(truth["ties"])]
    with pytest.raises(InputError, match="--level none"):
        am.level(no_ties)
    assert "tmi_lev" in am.level(no_ties, method="none").data
    with pytest.raises(InputError, match="--date 2014-13-02: not a date"):
        am.level(df.assign(time=df["time"] % 86400.0), date="2014-13-02")
    with pytest.raises(InputError, match="seconds since midnight.*--date"):
        am.level(df.assign(time=df["time"] % 86400.0))
    res = am.level(df.assign(time=df["time"] % 86400.0), date="2014-11-02", base=base)
    assert np.isfinite(res.data["igrf"]).all()
    with pytest.raises(InputError, match="opposite directions"):
        one_way = df[df["line"].isin([100, 120, 140, 160, 180, *truth["ties"]])]
        am.level(one_way, lag="auto")


# ----------------------------------------------------------------- files and the CLI
@pytest.fixture(scope="module")
def sim_files(tmp_path_factory):
    out = tmp_path_factory.mktemp("lvl")
    res = CliRunner().invoke(app, ["simulate", "--survey", "--small", "-o", str(out)])
    assert res.exit_code == 0, res.output
    return out


def test_cli_level_writes_csv_json_and_figures(sim_files, tmp_path):
    out = tmp_path / "lev.csv"
    r = CliRunner().invoke(app, ["level", str(sim_files / "level_survey.csv"), "--base",
                                 str(sim_files / "level_base.csv"), "--lag", "0.4",
                                 "--decorrugate", "--plot", str(tmp_path / "qc"), "-o",
                                 str(out)])
    assert r.exit_code == 0, r.output
    assert "mistie std" in r.output
    d = pd.read_csv(out)
    for c in ("x_m", "y_m", "line_type", "igrf", "diurnal", "tmi", "tmi_lev", "tmi_mlev"):
        assert c in d.columns
    rep = json.loads(out.with_suffix(".json").read_text())
    for k in ("crs", "lag_s", "igrf", "diurnal", "crossovers", "mistie_std_nT", "lines"):
        assert k in rep
    assert rep["lag_s"] == 0.4 and rep["igrf"]["model"] == "IGRF-14"
    assert rep["mistie_std_nT"]["after"] < rep["mistie_std_nT"]["before"]
    assert (tmp_path / "qc" / "misties.png").stat().st_size > 1000
    assert (tmp_path / "qc" / "profiles.png").exists()


def test_cli_xyz_keeps_lines_and_ties(sim_files, tmp_path):
    out = tmp_path / "lev.xyz"
    r = CliRunner().invoke(app, ["level", str(sim_files / "level_survey.csv"), "--base",
                                 str(sim_files / "level_base.csv"), "-o", str(out)])
    assert r.exit_code == 0, r.output
    text = out.read_text()
    assert text.count("\nTie ") == 5 and text.count("\nLine ") == 8
    back = am.read_log(out, required=())
    assert set(back["line_type"]) == {"line", "tie"}


def test_cli_bad_inputs_one_line_nothing_written(sim_files, tmp_path):
    out = tmp_path / "bad.csv"
    src = pd.read_csv(sim_files / "level_survey.csv")
    noline = tmp_path / "noline.csv"
    src.drop(columns="line").to_csv(noline, index=False)
    noties = tmp_path / "noties.csv"
    src[src["line"] < 9000].to_csv(noties, index=False)
    cases = [
        ([str(noline)], "no line column"),
        ([str(sim_files / "level_survey.csv"), "--date", "2014-02-30"], "not a date"),
        ([str(noties)], "--level none"),
        ([str(sim_files / "level_survey.csv"), "--ties", "123"], "not a line number"),
        ([str(sim_files / "level_survey.csv"), "--base", str(tmp_path / "nope.min")], "nope"),
    ]
    for args, words in cases:
        r = CliRunner().invoke(app, ["level", *args, "-o", str(out)])
        assert r.exit_code == 1, (args, r.output)
        err = r.output.strip().splitlines()
        assert err[-1].startswith("error:") and words in err[-1], (args, r.output)
        assert "Traceback" not in r.output
        assert not out.exists() and not out.with_suffix(".json").exists()


def test_level_as_a_subprocess(sim_files, tmp_path):
    out = tmp_path / "sub.csv"
    r = subprocess.run([sys.executable, "-m", "aeromag", "level",
                        str(sim_files / "level_survey.csv"), "--no-igrf", "--level", "shift",
                        "-o", str(out)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "no diurnal correction" in r.stderr
    assert json.loads(out.with_suffix(".json").read_text())["igrf"] is None


def test_shipped_level_samples_match_the_recipe(tmp_path):
    from pathlib import Path

    from aeromag.workflows.simulate_level import write_level_simulation

    samples = Path(__file__).resolve().parents[1] / "data_samples"
    if not (samples / "level_survey.csv").exists():
        pytest.skip("data_samples not generated (cli/make_samples.sh)")
    assert "--survey" in (samples.parent / "cli" / "make_samples.sh").read_text()
    write_level_simulation(tmp_path, seed=1, small=True)
    for name in ("level_survey.csv", "level_base.csv"):
        assert (samples / name).stat().st_size < 500_000
        pd.testing.assert_frame_equal(pd.read_csv(samples / name), pd.read_csv(tmp_path / name),
                                      check_exact=False, atol=2e-3, rtol=0)


@settings(max_examples=20, deadline=None)
@given(values=st.lists(st.one_of(st.floats(20000, 70000), st.just(99999.0), st.just(88888.0)),
                       min_size=3, max_size=40),
       elements=st.sampled_from(["HDZF", "XYZF", "XYZG", "HDZG"]))
def test_iaga2002_round_trip(tmp_path_factory, values, elements):
    """Written IAGA-2002 rows read back: UTC times, F (or F from the components), 88888/99999
    empty (a file whose F is all empty gets F from the components: not drawn here)."""
    from aeromag.io.base import read_iaga2002

    values = [50000.0, *values]
    path = tmp_path_factory.mktemp("iaga") / "x.min"
    head = [f" Format                 IAGA-2002{'|':>37}",
            f" Reported               {elements}{'|':>42}",
            "DATE       TIME         DOY     ABC" + "      ABC".join(elements) + "   |"]
    rows = []
    for i, v in enumerate(values):
        comps = [20000.0, -5.0 if elements[1] == "D" else 100.0, 45000.0, v]
        if elements[3] == "G":
            comps[3] = 0.5  # a G (delta-F) column is not F
        hh, mm = divmod(i, 60)
        rows.append(f"2014-11-01 {hh:02d}:{mm:02d}:00.000 305  "
                    + "  ".join(f"{c:9.2f}" for c in comps))
    path.write_text("\n".join(head + rows) + "\n")
    df = read_iaga2002(path)
    assert np.all(np.diff(df["time"]) == 60.0)
    assert df["time"].iloc[0] == 1414800000.0
    if elements[3] == "F":
        want = np.where(np.isin(values, [88888.0, 99999.0]), np.nan, np.round(values, 2))
        np.testing.assert_allclose(df["mag"], want, atol=1e-6)
        assert df.attrs["f_source"] == "F"
    else:
        assert df.attrs["f_source"].startswith("sqrt")
        if elements.startswith("XYZ"):
            expect = np.sqrt(20000.0 ** 2 + 100.0 ** 2 + 45000.0 ** 2)
        else:
            expect = np.hypot(20000.0, 45000.0)
        np.testing.assert_allclose(df["mag"], expect)


def test_methods_progress_and_lag_spelling():
    df = _independent_survey(6)
    steps = []
    shift = am.level(df, igrf=False, method="shift", progress=lambda d, t, s: steps.append(s))
    smooth = am.level(df, igrf=False, method="smooth")
    assert steps[0] == "geometry" and steps[-1] == "done" and len(steps) == 7
    for res in (shift, smooth):
        assert res.mistie_std_nT.after < 0.5 * res.mistie_std_nT.before
    # 5 crossings per line: at most 5 // 3 knots, i.e. smooth falls back to a trend there.
    assert max(len(k) for k in smooth.levelling.knots_m) == 2
    from aeromag.survey.levelling import level_network

    g = smooth.geometry
    fine = level_network(smooth.crossings, g.n_pieces, g.piece_is_tie, method="smooth",
                         knot_m=1000.0, tie_trend=True)
    # the ties (13 crossings over 3.2 km): ceil(3.2) + 1 = 5 knots, capped at 13 // 3 = 4
    assert max(len(k) for k in fine.knots_m) == 4
    assert np.std(fine.mistie_lev_nT) < 0.5 * np.std(smooth.crossings.mistie_nT)
    assert {len(k) for k in shift.levelling.knots_m} == {1}
    with pytest.raises(InputError, match="--lag soon: give seconds"):
        am.level(df, igrf=False, lag="soon")
    with pytest.raises(InputError, match="--lag 0.3 needs a time column"):
        am.level(df, igrf=False, lag=0.3)
