"""The ``armed`` / ``landed`` state columns of the PX4 ULog and ArduPilot DataFlash readers.

PX4: ``vehicle_status.arming_state`` (ARMED = 2; ``actuator_armed.armed`` without it),
``vehicle_land_detected.landed``.  ArduPilot: ``ARM.ArmState`` (``EV`` 10/11 without it),
``EV`` 18/28 for ``landed``.  States are held forward from each message onto the union of the
sensors' sample times and empty before the first one.  Checked on message tables against a
plain loop written here, on files written to the formats' specifications, on the real PX4
ULog of ``../shared``, and through ``aeromag track``: the state is what keeps ground rows off
the legs.
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from aeromag._core.runs import true_runs
from aeromag.cli import app
from aeromag.io import read_log
from aeromag.io.uav_logs import dataflash_to_canonical, hold_state, ulog_to_canonical
from aeromag.synthetic.mission import simulate_mission

from .test_nav_uav_logs import _write_dataflash, _write_ulog

HAS_PYULOG = importlib.util.find_spec("pyulog") is not None
HAS_PYMAVLINK = importlib.util.find_spec("pymavlink") is not None
REAL_ULOG = (Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"
             / "flights" / "px4_mag_rotation.ulg")
needs_pyulog = pytest.mark.skipif(not HAS_PYULOG, reason="pyulog is not installed (pip "
                                  "install 'aeromag[ulog]')")
needs_pymavlink = pytest.mark.skipif(not HAS_PYMAVLINK, reason="pymavlink is not installed "
                                     "(pip install 'aeromag[dataflash]')")


def _held(rows_t, msg_t, msg_v):
    """The expected state per row, by a plain loop: the last message at or before the row."""
    out = []
    for t in rows_t:
        last = None
        for mt, mv in zip(msg_t, msg_v, strict=True):
            if mt <= t:
                last = bool(mv)
        out.append(last)
    return out


def _as_list(col):
    return [None if pd.isna(v) else bool(v) for v in col]


ROWS_US = np.arange(0, 8_000_001, 500_000) + 100_000_000        # 2 Hz IMU, 100-108 s


def _imu(us=ROWS_US):
    return pd.DataFrame({"timestamp": us, **{f"gyro_rad[{i}]": np.zeros(len(us)) for i in
                                              range(3)},
                         **{f"accelerometer_m_s2[{i}]": np.zeros(len(us)) for i in range(3)}})


def test_ulog_states_are_held_forward_from_their_changes():
    st_us = np.array([101_200_000, 103_000_000, 106_000_000, 106_000_000]) # last of equal wins
    arming = np.array([1, 2, 2, 1], dtype=np.uint8)                        # STANDBY, ARMED
    land_us = np.array([100_700_000, 103_400_000, 106_100_000])
    landed = np.array([True, False, True])
    got = ulog_to_canonical({
        "sensor_combined": _imu(),
        "vehicle_status": pd.DataFrame({"timestamp": st_us, "arming_state": arming}),
        "vehicle_land_detected": pd.DataFrame({"timestamp": land_us, "landed": landed})})
    assert len(got) == len(ROWS_US)                     # state messages add no rows
    assert str(got["armed"].dtype) == "boolean" and str(got["landed"].dtype) == "boolean"
    t = got["time"].to_numpy()
    assert _as_list(got["armed"]) == _held(t, st_us[[0, 1, 3]] / 1e6, [False, True, False])
    assert _as_list(got["landed"]) == _held(t, land_us / 1e6, landed)
    # before the first message: empty, never a guessed state
    assert got["armed"].isna().sum() == 3 and got["landed"].isna().sum() == 2
    assert not got.loc[got["time"] == 106.0, "armed"].item()


def test_ulog_arming_state_is_armed_only_at_2_and_actuator_armed_is_the_fallback(caplog):
    us = np.array([100_000_000, 101_000_000, 102_000_000, 103_000_000, 104_000_000])
    vs = pd.DataFrame({"timestamp": us, "arming_state": np.array([0, 1, 2, 4, 1], np.uint8)})
    aa = pd.DataFrame({"timestamp": us, "armed": np.array([1, 1, 1, 1, 1], np.int8)})
    both = ulog_to_canonical({"sensor_combined": _imu(us), "vehicle_status": vs,
                              "actuator_armed": aa})
    assert _as_list(both["armed"]) == [False, False, True, False, False]
    aa_old = aa.assign(armed=np.array([0, 0, 1, 1, 0], np.int8))
    old = ulog_to_canonical({"sensor_combined": _imu(us), "actuator_armed": aa_old})
    assert _as_list(old["armed"]) == [False, False, True, True, False]
    # 3: ARMED_ERROR (armed) in old PX4, STANDBY_ERROR (disarmed) in later ones: the
    # unambiguous actuator_armed decides, and without it there is no column (and a warning)
    vs3 = vs.assign(arming_state=np.array([1, 2, 3, 3, 1], np.uint8))
    amb = ulog_to_canonical({"sensor_combined": _imu(us), "vehicle_status": vs3,
                             "actuator_armed": aa_old})
    assert _as_list(amb["armed"]) == [False, False, True, True, False]
    with caplog.at_level("WARNING", logger="aeromag.io.uav_logs"):
        alone = ulog_to_canonical({"sensor_combined": _imu(us), "vehicle_status": vs3})
    assert "armed" not in alone and "arming_state 3" in caplog.text
    none = ulog_to_canonical({"sensor_combined": _imu(us)})
    assert "armed" not in none and "landed" not in none


def test_dataflash_events_and_arm_message_become_states():
    rows = pd.DataFrame({"TimeUS": ROWS_US, "I": 0, **{f"Gyr{a}": 0.0 for a in "XYZ"},
                         **{f"Acc{a}": 0.0 for a in "XYZ"}})
    ev_us = np.array([100_900_000, 101_000_000, 102_300_000, 104_000_000, 105_000_000,
                      105_500_000, 106_200_000, 107_000_000])
    ids = np.array([25, 10, 28, 17, 18, 11, 21, 10])   # SET_HOME, ARMED, NOT_LANDED, MAYBE...
    got = dataflash_to_canonical({"IMU": rows, "EV": pd.DataFrame({"TimeUS": ev_us,
                                                                   "Id": ids})})
    t = got["time"].to_numpy()
    arm_ev = np.isin(ids, [10, 11])
    land_ev = np.isin(ids, [18, 28])
    assert _as_list(got["armed"]) == _held(t, ev_us[arm_ev] / 1e6, ids[arm_ev] == 10)
    assert _as_list(got["landed"]) == _held(t, ev_us[land_ev] / 1e6, ids[land_ev] == 18)
    assert not got.loc[got["time"] == 104.5, "landed"].item()    # 17 (maybe) ignored
    # the ARM message, when logged, gives `armed` (EV still gives `landed`)
    arm = pd.DataFrame({"TimeUS": [100_400_000, 103_100_000], "ArmState": [1, 0]})
    got = dataflash_to_canonical({"IMU": rows, "EV": pd.DataFrame({"TimeUS": ev_us,
                                                                   "Id": ids}), "ARM": arm})
    assert _as_list(got["armed"]) == _held(t, [100.4, 103.1], [True, False])
    assert _as_list(got["landed"]) == _held(t, ev_us[land_ev] / 1e6, ids[land_ev] == 18)
    # events that are no state: no column
    got = dataflash_to_canonical({"IMU": rows, "EV": pd.DataFrame({"TimeUS": ev_us[:1],
                                                                   "Id": [25]})})
    assert "armed" not in got and "landed" not in got


@settings(max_examples=60, deadline=None)
@given(msg=st.lists(st.tuples(st.integers(0, 50), st.booleans()), max_size=12),
       rows=st.lists(st.integers(-5, 60), min_size=1, max_size=30, unique=True))
def test_property_hold_state_is_the_last_message_at_or_before(msg, rows):
    rows_t = np.sort(np.asarray(rows, dtype=float))
    msg_t = np.asarray([m[0] for m in msg], dtype=float)
    msg_v = np.asarray([m[1] for m in msg], dtype=bool)
    got = hold_state(rows_t, msg_t, msg_v)
    # the loop needs the messages in time order (the file's order among equal times)
    order = np.argsort(msg_t, kind="stable")
    assert _as_list(got) == _held(rows_t, msg_t[order], msg_v[order])


# --------------------------------------------------------------------- files, by the spec

@needs_pyulog
def test_ulog_file_has_the_state_columns(tmp_path):
    p = tmp_path / "states.ulg"
    st_us = np.array([101_200_000, 103_000_000, 106_000_000])
    _write_ulog(p, {"sensor_combined": _imu(),
                    "vehicle_status": pd.DataFrame({"timestamp": st_us, "arming_state":
                                                    np.array([1, 2, 1], np.int64)}),
                    "vehicle_land_detected": pd.DataFrame({"timestamp": st_us + 1000,
                                                           "landed": [True, False, True]})})
    df = read_log(p)
    t = df["time"].to_numpy()
    assert _as_list(df["armed"]) == _held(t, st_us / 1e6, [False, True, False])
    assert _as_list(df["landed"]) == _held(t, (st_us + 1000) / 1e6, [True, False, True])


@needs_pymavlink
def test_dataflash_file_has_the_state_columns(tmp_path):
    rows = pd.DataFrame({"TimeUS": ROWS_US, "I": 0, **{f"Gyr{a}": 0.0 for a in "XYZ"},
                         **{f"Acc{a}": 0.0 for a in "XYZ"}})
    ev_us, ids = np.array([101_000_000, 102_300_000, 105_000_000, 105_500_000]), [10, 28, 18,
                                                                                  11]
    p = tmp_path / "states.bin"
    _write_dataflash(p, {"IMU": rows, "EV": pd.DataFrame({"TimeUS": ev_us, "Id": ids})})
    df = read_log(p)
    t = df["time"].to_numpy()
    assert _as_list(df["armed"]) == _held(t, ev_us[[0, 3]] / 1e6, [True, False])
    assert _as_list(df["landed"]) == _held(t, ev_us[[1, 2]] / 1e6, [False, True])
    p2 = tmp_path / "arm.bin"
    arm = pd.DataFrame({"TimeUS": [100_400_000, 103_100_000], "ArmState": [1, 0],
                        "ArmChecks": 0, "Forced": 0, "Method": 0})
    _write_dataflash(p2, {"IMU": rows, "ARM": arm})
    df = read_log(p2)
    assert _as_list(df["armed"]) == _held(df["time"].to_numpy(), [100.4, 103.1], [True, False])
    assert "landed" not in df


@needs_pyulog
def test_real_px4_ulog_on_the_bench_is_disarmed_and_landed():
    if not REAL_ULOG.exists():
        pytest.skip(f"real data not present ({REAL_ULOG}; ../shared is absent)")
    df = read_log(REAL_ULOG)
    # a magnetometer rotation on the bench: vehicle_status.arming_state 1 (STANDBY) and
    # vehicle_land_detected.landed true throughout; the first status precedes the first row
    assert len(df) == 16635
    assert df["armed"].notna().all() and not df["armed"].any()
    assert df["landed"].notna().all() and df["landed"].all()


# --------------------------------------------------------------------- aeromag track

@pytest.fixture(scope="module")
def day():
    wps = np.array([[0.0, 0.0, 0.0], [100.0, 0.0, 0.0]])
    return simulate_mission(seed=4, waypoints_ned=wps, height_m=20.0, flights=3, ground_s=10.0,
                            disturbances={}, wp_radius_m=2.0, armed_column=True)


def _day_ulog(path, log, armed):
    """The simulated day as a ULog: IMU and GNSS on every row, vehicle_status only where the
    arming state changes (the reader must hold it forward)."""
    us = np.round(log["time"].to_numpy() * 1e6).astype(np.int64) + 100_000_000
    change = np.r_[True, armed[1:] != armed[:-1]]
    n = len(log)
    _write_ulog(path, {
        "sensor_combined": pd.DataFrame({"timestamp": us, **{
            f"gyro_rad[{i}]": log[f"gyro_{a}"].to_numpy() for i, a in enumerate("xyz")},
            **{f"accelerometer_m_s2[{i}]": np.zeros(n) for i in range(3)}}),
        "vehicle_gps_position": pd.DataFrame({
            "timestamp": us, "lat": np.round(log["lat"].to_numpy() * 1e7).astype(np.int64),
            "lon": np.round(log["lon"].to_numpy() * 1e7).astype(np.int64),
            "alt_ellipsoid": np.round(log["alt"].to_numpy() * 1e3).astype(np.int64),
            "fix_type": np.full(n, 3, np.int64)}),
        "vehicle_status": pd.DataFrame({"timestamp": us[change], "arming_state": np.where(
            armed[change], 2, 1).astype(np.int64)})})


def _track(tmp_path, name, log, plan, armed):
    _day_ulog(tmp_path / f"{name}.ulg", log, armed)
    plan.to_csv(tmp_path / "plan.csv", index=False)
    out = tmp_path / f"{name}.csv"
    r = CliRunner().invoke(app, ["track", str(tmp_path / f"{name}.ulg"), "--plan",
                                 str(tmp_path / "plan.csv"), "-o", str(out)])
    assert r.exit_code == 0, r.output
    res = pd.read_csv(out)
    assert len(res) == len(log)
    return res, json.loads(out.with_suffix(".json").read_text())


@needs_pyulog
def test_track_on_a_ulog_uses_its_arming_state(day, tmp_path):
    log, plan, _ = day
    ph = log["truth_phase"].to_numpy()
    armed = log["armed"].to_numpy(dtype=bool)
    res, rep = _track(tmp_path, "day", log, plan, armed)
    assert rep["ground"]["source"] == "armed"
    assert rep["ground"]["n_rows"] == int((~armed).sum())
    lab = res["leg"].to_numpy()
    assert np.isnan(lab[np.isin(ph, ["ground", "carry"])]).all()      # carries: no leg
    assert rep["legs"][0]["n_passes"] == 3
    # the state is what decides: the same log disarmed over its second pass and the hovers
    # about it (2 s; a state the motion contradicts) loses that pass, given the leg with its
    # true state
    a, b = (np.asarray(x)[1] for x in true_runs(log["truth_leg"].to_numpy() == 0))
    assert (ph[a - 20:a] == "hover").all() and (ph[b:b + 20] == "hover").all()
    a, b = a - 20, b + 20
    off = armed.copy()
    off[a:b] = False
    res2, rep2 = _track(tmp_path, "off", log, plan, off)
    lab2 = res2["leg"].to_numpy()
    assert np.isnan(lab2[a:b]).all() and rep2["legs"][0]["n_passes"] == 2
    assert (lab[a:b] == 0).mean() > 0.8
