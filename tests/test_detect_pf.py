"""The particle-filter detector on the mission simulator and on messy logs; `aeromag detect`."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.detection.alarms import Alarms
from aeromag.detection.heading import heading_detector
from aeromag.detection.particle import (
    DEFAULT_PARTICLES,
    DEFAULT_WINDOW,
    particle_detector,
    prepare_pf_inputs,
)
from aeromag.errors import InputError
from aeromag.synthetic.mission import simulate_mission


@pytest.fixture(scope="module", params=[0, 3])
def mission(request):
    df, plan, truth = simulate_mission(seed=request.param, line_m=250.0)
    log = df.drop(columns=[c for c in df.columns if c.startswith("truth_")])
    pf = particle_detector(log)
    hd = heading_detector(log)
    return df, truth, pf, hd


def _first(alarm: np.ndarray, mask: np.ndarray, t: np.ndarray) -> float | None:
    i = np.flatnonzero(alarm & mask)
    return float(t[i[0]]) if i.size else None


def test_no_alarm_on_calm_legs(mission):
    df, truth, pf, _ = mission
    leg = df["truth_leg"].to_numpy()
    disturbed = [g["leg"] for g in truth["legs"] if g["disturbance"]]
    calm = (leg >= 0) & ~np.isin(leg, disturbed)
    assert isinstance(pf, Alarms) and pf.name == "pf"
    assert not np.any(pf.alarm & calm), np.unique(leg[pf.alarm & calm])
    # Off the legs (hover, turns, climb) the only alarms are the removal of a disturbance,
    # which on these short lines happens at the end of its leg: within 10 s of that end.
    t = df["time"].to_numpy()
    ends = [t[leg == k][-1] for k in disturbed]
    off = np.flatnonzero(pf.alarm & (leg < 0))
    for i in off:
        assert any(0.0 <= t[i] - e <= 10.0 for e in ends), t[i]


def test_slow_disturbance_earlier_than_heading_fast_within_one_second(mission):
    df, truth, pf, hd = mission
    t = df["time"].to_numpy()
    leg = df["truth_leg"].to_numpy()
    n_slow = n_fast = 0
    for g in truth["legs"]:
        if not g["disturbance"]:
            continue
        on = leg == g["leg"]
        onset = g["onset_time"]
        t_pf = _first(pf.alarm, on & (t >= onset), t)
        t_hd = _first(hd.alarm, on & (t >= onset), t)
        assert _first(pf.alarm, on & (t < onset), t) is None   # nothing before the onset
        assert t_pf is not None, g
        if g["disturbance"] == "slow":
            n_slow += 1
            # the 5-sigma heading detector may never fire on a slow leg
            assert t_hd is None or t_pf < t_hd, (g, t_pf - onset, t_hd)
            assert t_pf - onset < 10.0
        else:
            n_fast += 1
            assert t_hd is not None
            assert t_pf <= t_hd + 1.0, (g, t_pf - onset, t_hd - onset)
    assert n_slow >= 2 and n_fast >= 2


def test_stat_is_finite_after_warm_up_and_reproducible(mission):
    df, _, pf, _ = mission
    stat = pf.stat
    first = int(np.flatnonzero(np.isfinite(stat))[0])
    assert first == DEFAULT_WINDOW - 1
    # NaN only where a stretch is warming up (after a restart), never propagated
    nan_runs = np.flatnonzero(~np.isfinite(stat[first:]))
    assert nan_runs.size <= pf.info["n_resets"] * DEFAULT_WINDOW
    log = df.drop(columns=[c for c in df.columns if c.startswith("truth_")])
    again = particle_detector(log.iloc[:800])
    again2 = particle_detector(log.iloc[:800])
    np.testing.assert_array_equal(again.stat, again2.stat)
    assert pf.info["particles"] == DEFAULT_PARTICLES and pf.threshold == pytest.approx(
        pf.threshold)


# --------------------------------------------------------------------------- messy logs
def _synthetic_log(seed: int = 0, fs: float = 10.0, duration: float = 300.0,
                   landed_s: float = 60.0) -> pd.DataFrame:
    """Landed (quiet compass, no rotation), then hovering with yaw turns (noisy compass)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 1.0 / fs)
    rate = np.where(t < landed_s, 0.0, 0.3 * np.sin(2 * np.pi * t / 40.0))     # rad/s
    psi = np.cumsum(rate) / fs + 0.4
    noise = np.where(t < landed_s, 0.05, 2.0)                                   # deg
    mag = np.rad2deg(psi) + noise * rng.standard_normal(t.size) + 3.0           # offset
    return pd.DataFrame({"time": t, "gyro_z": rate + 1e-4 * rng.standard_normal(t.size),
                         "mag_heading": np.mod(mag, 360.0)})


def test_landed_then_hovering_gives_no_alarm_storm():
    df = _synthetic_log()
    res = particle_detector(df)        # calm window: the first 30 s, landed and quiet
    assert res.alarm.mean() < 0.005, res.alarm.mean()
    assert len(res.events) <= 2
    assert res.info["sigma_y_deg"] > 1.0     # near the flight's 2 deg, not the landed 0.05


def test_gap_restarts_the_filter_without_alarms_or_nan():
    df = _synthetic_log(seed=1, landed_s=0.0)
    keep = (df["time"] < 100.0) | (df["time"] >= 130.0)
    gap = df[keep].copy()
    after = gap["time"] >= 130.0
    # the vehicle turned during the gap: the compass jumps by 90 degrees
    gap.loc[after, "mag_heading"] = np.mod(gap.loc[after, "mag_heading"] + 90.0, 360.0)
    res = particle_detector(gap)
    assert res.info["n_stretches"] == 2
    assert not np.any(res.alarm)
    i = int(np.flatnonzero(after.to_numpy())[0])
    assert np.all(np.isnan(res.stat[i:i + DEFAULT_WINDOW - 1]))
    assert np.all(np.isfinite(res.stat[i + DEFAULT_WINDOW - 1:]))


def test_multirate_log_and_missing_compass_rows():
    df = _synthetic_log(seed=2, landed_s=0.0, fs=50.0, duration=120.0)
    # the compass at 10 Hz, the gyro at 50 Hz, on one table of the union of sample times
    df.loc[df.index % 5 != 0, "mag_heading"] = np.nan
    res = particle_detector(df, window=10)
    assert not np.any(res.alarm)
    assert res.info["rate_source"] == "gyro_z"
    # S_k is carried over the rows without a compass sample
    fin = np.isfinite(res.stat)
    assert fin[100:].all()


def test_disturbance_ramp_is_detected_on_a_synthetic_log():
    df = _synthetic_log(seed=3, landed_s=0.0)
    t = df["time"].to_numpy()
    ramp = np.clip(t - 150.0, 0.0, None) * 3.0          # 3 deg/s after 150 s
    df["mag_heading"] = np.mod(df["mag_heading"] + ramp, 360.0)
    res = particle_detector(df)
    assert res.first_alarm_time is not None
    assert 150.0 < res.first_alarm_time < 158.0


def _slow_ramp_log(seed: int = 5, fs: float = 20.0, duration: float = 110.0,
                   onset: float = 60.0) -> pd.DataFrame:
    """A hover (2 deg/s yaw) with a 0.3 deg/s gyro bias; from ``onset`` a cross-axis field
    ramping at 0.0125 G/s in a 0.6 G horizontal field for 30 s, which turns the compass by
    about 1 deg/s (up to 30 deg): the slow disturbance of the review of the detector."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 1.0 / fs)
    rate = np.where(t > 20.0, np.deg2rad(2.0), 0.0)
    psi = 0.3 + np.concatenate([[0.0], np.cumsum(rate[1:]) / fs])
    gz = rate + np.deg2rad(0.3) + 0.01 * rng.standard_normal(t.size)
    h = 0.6e5
    dy = np.clip(t - onset, 0.0, 30.0) * (t < onset + 30.0) * 0.0125e5
    mag = np.rad2deg(np.arctan2(h * np.sin(psi) - dy, h * np.cos(psi)))
    mag += 0.5 * rng.standard_normal(t.size)
    return pd.DataFrame({"time": t, "gyro_z": gz, "mag_heading": np.mod(mag, 360.0)})


def test_slow_ramp_with_gyro_bias_is_detected_and_stays_alarmed():
    # A heading-only random walk that absorbs the gyro bias also follows this ramp: it
    # alarmed late and for under a second.  With the bias a state of its own the compass
    # drifting off the bias-corrected gyro is alarmed early and for most of the ramp.
    onset = 60.0
    df = _slow_ramp_log(onset=onset)
    res = particle_detector(df, n_particles=200)
    t = res.time_s
    assert not np.any(res.alarm[t < onset])
    assert res.first_alarm_time is not None
    assert onset < res.first_alarm_time < onset + 9.0, res.first_alarm_time
    during = (t >= onset + 9.0) & (t < onset + 30.0)
    assert res.alarm[during].mean() > 0.9, res.alarm[during].mean()
    assert abs(res.info["gyro_bias_prior_deg_s"] - 0.3) < 0.1


def test_fluxgate_and_attitude_heading_sources(mission):
    df, _, _, _ = mission
    inp = prepare_pf_inputs(df.iloc[:500])
    assert inp.rate_source == "gyro_xyz" and inp.compass_source == "flux"
    no_gyro = df.iloc[:600].drop(columns=["gyro_x", "gyro_y", "gyro_z"])
    assert prepare_pf_inputs(no_gyro).rate_source == "heading"


def test_bad_inputs_are_input_errors():
    df = _synthetic_log(duration=60.0)
    with pytest.raises(InputError, match="gyro"):
        particle_detector(df.drop(columns=["gyro_z"]))
    with pytest.raises(InputError, match="particles"):
        particle_detector(df, n_particles=1)
    with pytest.raises(InputError, match="calm window"):
        particle_detector(df, calm_window="0.5")
    bad = df.copy()
    bad.loc[10, "time"] = bad.loc[9, "time"]
    with pytest.raises(InputError, match="strictly increasing"):
        particle_detector(bad)


# --------------------------------------------------------------------------- command line
def test_cli_detect_writes_csv_and_json(tmp_path):
    df = _synthetic_log(seed=4, duration=120.0, landed_s=0.0)
    src = tmp_path / "log.csv"
    df.to_csv(src, index=False)
    out = tmp_path / "out.csv"
    r = CliRunner().invoke(app, ["detect", str(src), "-o", str(out), "--particles", "200",
                                 "--window", "15"])
    assert r.exit_code == 0, r.output
    res = pd.read_csv(out)
    assert {"pf_stat", "pf_alarm"} <= set(res.columns)
    assert len(res) == len(df)
    rep = json.loads(out.with_suffix(".json").read_text())
    assert rep["particles"] == 200 and rep["window"] == 15
    assert {"threshold", "events"} <= set(rep)
    assert rep["settings"]["threshold_source"] == "calm"
    r2 = CliRunner().invoke(app, ["detect", str(src), "-o", str(tmp_path / "o2.csv"),
                                  "--threshold", "1e6"])
    assert r2.exit_code == 0
    assert json.loads((tmp_path / "o2.json").read_text())["threshold"] == 1e6


def test_cli_detect_errors_are_one_line_and_leave_nothing(tmp_path):
    df = _synthetic_log(duration=60.0).drop(columns=["mag_heading"])
    src = tmp_path / "log.csv"
    df.to_csv(src, index=False)
    out = tmp_path / "out.csv"
    r = CliRunner().invoke(app, ["detect", str(src), "-o", str(out)])
    assert r.exit_code == 1
    assert r.output.startswith("error: ") and "compass" in r.output
    assert len(r.output.strip().splitlines()) == 1
    assert not out.exists() and not out.with_suffix(".json").exists()


def test_detect_subprocess(tmp_path):
    df = _synthetic_log(seed=5, duration=60.0, landed_s=0.0)
    src = tmp_path / "log.csv"
    df.to_csv(src, index=False)
    out = tmp_path / "o.csv"
    p = subprocess.run([sys.executable, "-m", "aeromag", "detect", str(src), "-o", str(out),
                        "--particles", "100", "--calm-window", "20"],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert "alarm event" in p.stdout and out.exists()


def test_cli_defaults_match_the_library():
    from aeromag.cli import detect as cli_detect

    assert cli_detect.DEFAULT_PARTICLES == DEFAULT_PARTICLES
    assert cli_detect.DEFAULT_WINDOW == DEFAULT_WINDOW


def test_track_pf_adds_the_particle_filter_to_the_verdict(tmp_path):
    df, plan, truth = simulate_mission(seed=1, line_m=250.0)
    log = df.drop(columns=[c for c in df.columns if c.startswith("truth_")])
    src, pln = tmp_path / "mission.csv", tmp_path / "plan.csv"
    log.to_csv(src, index=False)
    plan.to_csv(pln, index=False)
    out = tmp_path / "track.csv"
    r = CliRunner().invoke(app, ["track", str(src), "--plan", str(pln), "-o", str(out),
                                 "--pf"])
    assert r.exit_code == 0, r.output
    res = pd.read_csv(out)
    assert "pf_alarm" in res.columns
    pf_alarm = res["pf_alarm"].astype(bool).to_numpy()
    assert np.all(res["alarm"].astype(bool).to_numpy()[pf_alarm])   # pf alarms are alarms
    rep = json.loads(out.with_suffix(".json").read_text())
    names = [d["detector"] for d in rep["detectors"]]
    assert "pf" in names
    # the disturbed legs, and only they, are flagged; on the slow ones the pf fired first
    disturbed = {g["leg"]: g["disturbance"] for g in truth["legs"] if g["disturbance"]}
    assert sorted(rep["flagged_legs"]) == sorted(disturbed)
    for row in rep["legs"]:
        if disturbed.get(row["leg"]) == "slow":
            assert row["first_detector"] == "pf", row
    t = res["time"].to_numpy()
    for g in truth["legs"]:
        if g["disturbance"] == "slow":
            on = (df["truth_leg"].to_numpy() == g["leg"]) & (t >= g["onset_time"])
            first_pf = t[np.flatnonzero(pf_alarm & on)[0]]
            assert first_pf - g["onset_time"] < 10.0


def _held_log(kind: str, seed: int = 4) -> pd.DataFrame:
    """Hand-built 50 Hz log: a gyro with a 0.3 deg/s bias, a compass with 0.5 deg noise and
    a disturbance from 40 s to 70 s: ``"step"`` a 10 deg offset switched on and held,
    ``"ramp"`` 1.2 deg/s (0.0125 G/s in a 0.6 G field)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 90.0, 0.02)
    psi = np.deg2rad(20.0 + 2.0 * t)                      # slow yaw, 2 deg/s
    gz = np.full(t.size, np.deg2rad(2.0 + 0.3)) + 0.002 * rng.standard_normal(t.size)
    on = (t >= 40.0) & (t < 70.0)
    dist = np.where(on, 10.0 if kind == "step" else 1.2 * (t - 40.0), 0.0)
    mh = np.rad2deg(psi) + dist + 0.5 * rng.standard_normal(t.size)
    return pd.DataFrame({"time": t, "gyro_z": gz, "mag_heading": (mh + 180) % 360 - 180})


@pytest.mark.parametrize("kind", ["step", "ramp"])
def test_held_disturbance_stays_alarmed_until_removed(kind):
    # The filter re-locks on the disturbed compass (a restart after M far samples); the
    # alarm must stay latched while the compass stays off the gyro's heading, not only mark
    # the onset and the removal.
    # A ramp the filter followed (no trustworthy gyro reference) must not latch after its
    # removal.
    df = _held_log(kind)
    res = particle_detector(df, n_particles=200)
    t = res.time_s
    assert not res.alarm[t < 40.0].any()
    assert not res.alarm[t > 75.0].any(), res.events
    assert np.isfinite(res.stat[t > 1.0]).all()      # no hole after a restart
    if kind == "step":
        held = (t >= 40.0) & (t < 70.0)
        assert res.alarm[held].all(), res.events
        assert len(res.events) == 1 and res.events[0]["end_time"] < 71.0
        assert res.info["n_latched"] == 1 and res.info["latched_s"] > 29.0
    else:
        assert res.alarm[(t >= 40.0) & (t < 70.0)].any()


def test_gyro_in_deg_per_s_warns_and_units_converts(tmp_path, caplog):
    # A gyro logged in deg/s (the interface wants rad/s) gives a warning naming the remedy;
    # --units gyro=deg/s converts it, and the result equals the rad/s log's.
    df = _held_log("step").iloc[:1500]                     # 30 s, clean
    src = tmp_path / "degs.csv"
    d = df.copy()
    d["gyro_z"] = np.rad2deg(d["gyro_z"])
    d.to_csv(src, index=False)
    with caplog.at_level("WARNING"):
        prepare_pf_inputs(d, source="degs.csv")
    assert "units={'gyro': 'deg/s'}" in caplog.text  # the CLI: --units gyro=deg/s
    caplog.clear()
    with caplog.at_level("WARNING"):
        prepare_pf_inputs(df, source="rads.csv")
    assert "deg/s" not in caplog.text
    r = CliRunner().invoke(app, ["detect", str(src), "-o", str(tmp_path / "o.csv"),
                                 "--particles", "50", "--units", "gyro=deg/s",
                                 "--calm-window", "20"])
    assert r.exit_code == 0, r.output
    ref = particle_detector(df, n_particles=50, calm_window="20")
    rep = json.loads((tmp_path / "o.json").read_text())
    assert rep["threshold"] == pytest.approx(ref.threshold, rel=1e-9)
    assert "latch" in rep["events_note"] and "onset and removal" in rep["events_note"]
    r = CliRunner().invoke(app, ["detect", str(src), "-o", str(tmp_path / "p.csv"),
                                 "--units", "gyro=furlong"])
    assert r.exit_code == 1 and "unknown gyro unit" in r.output
    assert "Traceback" not in r.output and not (tmp_path / "p.csv").exists()


def test_detector_result_holds_the_filter_run():
    """The detection result holds the particle filter's SequentialResult (one row per log
    row): the filter heading follows the true heading, the bias is near the gyro's 0, and
    log L_k is given wherever the compass was fused."""
    df = _synthetic_log(seed=2, landed_s=0.0, duration=120.0)
    res = particle_detector(df, n_particles=200)
    fit = res.fit
    assert fit is not None and fit.state_names == ("heading_rad", "gyro_bias_rad_s")
    assert fit.state.shape == (len(df), 2) and fit.std.shape == (len(df), 2)
    t = df["time"].to_numpy()
    truth = np.cumsum(0.3 * np.sin(2 * np.pi * t / 40.0)) / 10.0 + 0.4 + np.deg2rad(3.0)
    d = np.angle(np.exp(1j * (fit.state[:, 0] - truth)))
    late = t > 20.0
    assert np.sqrt(np.mean(d[late] ** 2)) < np.deg2rad(1.5)
    assert np.all(np.abs(fit.state[late, 1]) < np.deg2rad(0.2))
    assert np.isfinite(fit.loglik).sum() == fit.innovations["heading"].n_fused > 0.9 * len(df)
