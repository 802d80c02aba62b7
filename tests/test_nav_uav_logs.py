"""PX4 ULog and ArduPilot DataFlash readers: the mapping onto the canonical columns on
synthetic message tables, and small real files written here to the formats' specifications
(pyulog and pymavlink read them; the tests skip with a reason when they are absent)."""

from __future__ import annotations

import importlib.util
import struct

import numpy as np
import pandas as pd
import pytest

from aeromag.io import read_log
from aeromag.io.uav_logs import dataflash_to_canonical, ulog_to_canonical, union_rows
from aeromag.synthetic.quadrotor import simulate_quadrotor

HAS_PYULOG = importlib.util.find_spec("pyulog") is not None
HAS_PYMAVLINK = importlib.util.find_spec("pymavlink") is not None


@pytest.fixture(scope="module")
def flight():
    fl = simulate_quadrotor("rectangle", seed=2, duration_s=6.0)
    log = fl.log.copy()
    log["time"] = np.round(log["time"] + 100.0, 6)   # since boot, whole microseconds
    return log


def _rows(log, cols):
    d = log[["time", *cols]].dropna()
    return d.reset_index(drop=True)


def _ulog_topics(log):
    """The sim's sensors as PX4 topics (field name -> values), instance 0."""
    us = lambda d: np.round(d["time"].to_numpy() * 1e6).astype(np.int64)  # noqa: E731
    imu = _rows(log, ["gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z"])
    mag = _rows(log, ["flux_x", "flux_y", "flux_z"])
    of = _rows(log, ["flow_x", "flow_y", "flow_quality"])
    rng = _rows(log, ["range_m"])
    baro = _rows(log, ["baro_alt"])
    gps = _rows(log, ["lat", "lon", "alt", "vel_n", "vel_e", "vel_d"])
    T = 0.1
    return {
        "sensor_combined": pd.DataFrame({
            "timestamp": us(imu), **{f"gyro_rad[{i}]": imu[c] for i, c in enumerate(
                ["gyro_x", "gyro_y", "gyro_z"])},
            **{f"accelerometer_m_s2[{i}]": imu[c] for i, c in enumerate(
                ["acc_x", "acc_y", "acc_z"])}}),
        "vehicle_magnetometer": pd.DataFrame({
            "timestamp": us(mag), **{f"magnetometer_ga[{i}]": mag[c] / 1e5 for i, c in
                                     enumerate(["flux_x", "flux_y", "flux_z"])}}),
        "sensor_optical_flow": pd.DataFrame({
            "timestamp": us(of), "pixel_flow[0]": of["flow_x"] * T,
            "pixel_flow[1]": of["flow_y"] * T, "integration_timespan_us": np.full(len(of),
                                                                              100000),
            "quality": of["flow_quality"].astype(int)}),
        "distance_sensor": pd.DataFrame({"timestamp": us(rng),
                                         "current_distance": rng["range_m"],
                                         "orientation": np.full(len(rng), 25)}),
        "vehicle_air_data": pd.DataFrame({"timestamp": us(baro),
                                          "baro_alt_meter": baro["baro_alt"]}),
        "vehicle_gps_position": pd.DataFrame({
            "timestamp": us(gps), "lat": np.round(gps["lat"] * 1e7).astype(np.int64),
            "lon": np.round(gps["lon"] * 1e7).astype(np.int64),
            "alt_ellipsoid": np.round(gps["alt"] * 1e3).astype(np.int64),
            "vel_n_m_s": gps["vel_n"], "vel_e_m_s": gps["vel_e"], "vel_d_m_s": gps["vel_d"],
            "fix_type": np.full(len(gps), 3)}),
    }


def _compare(got, log, cols, atol):
    a = got[["time", *cols]].dropna().reset_index(drop=True)
    b = _rows(log, cols)
    assert len(a) == len(b)
    np.testing.assert_allclose(a["time"], b["time"], atol=1e-6)
    for c in cols:
        np.testing.assert_allclose(a[c], b[c], atol=atol.get(c, 1e-5), rtol=1e-6, err_msg=c)


ATOL = {"lat": 2e-7, "lon": 2e-7, "alt": 1e-3, "flux_x": 0.02, "flux_y": 0.02, "flux_z": 0.02}


def test_ulog_mapping_reproduces_the_canonical_table(flight):
    got = ulog_to_canonical(_ulog_topics(flight))
    assert got["time"].is_monotonic_increasing and got["time"].is_unique
    assert len(got) == len(flight)
    for cols in (["gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z"],
                 ["flux_x", "flux_y", "flux_z"], ["flow_x", "flow_y", "flow_quality"],
                 ["range_m"], ["baro_alt"], ["lat", "lon", "alt", "vel_n", "vel_e", "vel_d"]):
        _compare(got, flight, cols, ATOL)


def test_ulog_attitude_quaternion_becomes_euler_degrees():
    r, p, y = np.deg2rad([10.0, -5.0, 250.0])
    cr, sr, cp, sp, cy, sy = (np.cos(r / 2), np.sin(r / 2), np.cos(p / 2), np.sin(p / 2),
                              np.cos(y / 2), np.sin(y / 2))
    q = [cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
         cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy]
    att = pd.DataFrame({"timestamp": [1_000_000], **{f"q[{i}]": [q[i]] for i in range(4)}})
    got = ulog_to_canonical({"vehicle_attitude": att})
    assert got.loc[0, "roll"] == pytest.approx(10.0)
    assert got.loc[0, "pitch"] == pytest.approx(-5.0)
    assert got.loc[0, "heading"] == pytest.approx(250.0)


def test_dataflash_mapping_reproduces_the_canonical_table(flight):
    got = dataflash_to_canonical(_dataflash_tables(flight))
    assert len(got) == len(flight)
    for cols in (["gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z"],
                 ["flux_x", "flux_y", "flux_z"], ["flow_x", "flow_y", "flow_quality"],
                 ["range_m"], ["baro_alt"], ["lat", "lon", "alt", "vel_n", "vel_e"]):
        _compare(got, flight, cols, {**ATOL, "vel_n": 1e-4, "vel_e": 1e-4})


def test_union_rows_share_equal_times_and_leave_gaps_empty():
    a = pd.DataFrame({"time": [0.0, 1.0, 2.0], "x": [1.0, 2.0, 3.0]})
    b = pd.DataFrame({"time": [1.0, 1.5], "y": [10.0, 20.0]})
    u = union_rows([a, b])
    assert list(u["time"]) == [0.0, 1.0, 1.5, 2.0]
    assert np.isnan(u.loc[2, "x"]) and u.loc[1, "y"] == 10.0 and np.isnan(u.loc[0, "y"])


def _dataflash_tables(log):
    imu = _rows(log, ["gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z"])
    mag = _rows(log, ["flux_x", "flux_y", "flux_z"])
    of = _rows(log, ["flow_x", "flow_y", "flow_quality"])
    rng = _rows(log, ["range_m"])
    baro = _rows(log, ["baro_alt"])
    gps = _rows(log, ["lat", "lon", "alt", "vel_n", "vel_e", "vel_d"])
    us = lambda d: np.round(d["time"].to_numpy() * 1e6).astype(np.int64)  # noqa: E731
    return {
        "IMU": pd.DataFrame({"TimeUS": us(imu), "I": 0, "GyrX": imu.gyro_x, "GyrY": imu.gyro_y,
                             "GyrZ": imu.gyro_z, "AccX": imu.acc_x, "AccY": imu.acc_y,
                             "AccZ": imu.acc_z}),
        "MAG": pd.DataFrame({"TimeUS": us(mag), "I": 0, "MagX": mag.flux_x / 100,
                             "MagY": mag.flux_y / 100, "MagZ": mag.flux_z / 100}),
        "OF": pd.DataFrame({"TimeUS": us(of), "Qual": of.flow_quality.astype(int),
                            "flowX": of.flow_x, "flowY": of.flow_y, "bodyX": 0.0,
                            "bodyY": 0.0}),
        "RFND": pd.DataFrame({"TimeUS": us(rng), "Instance": 0, "Dist": rng.range_m,
                              "Stat": 4, "Orient": 25}),
        "BARO": pd.DataFrame({"TimeUS": us(baro), "I": 0, "Alt": baro.baro_alt}),
        "GPS": pd.DataFrame({"TimeUS": us(gps), "I": 0, "Status": 3, "Lat": gps.lat,
                             "Lng": gps.lon, "Alt": gps.alt,
                             "Spd": np.hypot(gps.vel_n, gps.vel_e),
                             "GCrs": np.mod(np.rad2deg(np.arctan2(gps.vel_e, gps.vel_n)), 360),
                             "VZ": gps.vel_d}),
    }


# --------------------------------------------------------------------- files, by the spec
_ULOG_TYPES = {"uint64_t": "Q", "float": "f", "int32_t": "i", "uint8_t": "B", "uint32_t": "I",
               "int64_t": "q", "double": "d", "uint16_t": "H", "bool": "?"}


def _write_ulog(path, topics):
    """A ULog file (format version 1) per the PX4 specification: header, flag bits, formats,
    subscriptions, data messages in time order."""
    buf = bytearray(b"ULog\x01\x12\x35" + bytes([1]) + struct.pack("<Q", 0))
    flags = bytes(16) + struct.pack("<3Q", 0, 0, 0)
    buf += struct.pack("<HB", len(flags), ord("B")) + flags
    specs = {}
    for name, df in topics.items():
        fields = [("uint64_t", "timestamp", 0)]
        seen = set()
        for c in df.columns:
            if c == "timestamp":
                continue
            base = c.split("[")[0]
            if base in seen:
                continue
            seen.add(base)
            n = sum(1 for k in df.columns if k.split("[")[0] == base)
            kind = df[c].dtype.kind
            typ = "bool" if kind == "b" else "int32_t" if kind in "iu" else "float"
            if base in ("lat", "lon", "alt_ellipsoid"):
                typ = "int32_t"
            if base in ("fix_type", "orientation", "quality", "arming_state"):
                typ = "uint8_t"
            if base == "integration_timespan_us":
                typ = "uint32_t"
            fields.append((typ, base, n if "[" in c else 0))
        fmt = name + ":" + "".join(
            f"{t}[{n}] {b};" if n else f"{t} {b};" for t, b, n in fields)
        buf += struct.pack("<HB", len(fmt), ord("F")) + fmt.encode()
        specs[name] = fields
    for msg_id, name in enumerate(topics):
        payload = struct.pack("<BH", 0, msg_id) + name.encode()
        buf += struct.pack("<HB", len(payload), ord("A")) + payload
    items = []
    for msg_id, (name, df) in enumerate(topics.items()):
        code = "<" + "".join((str(n) if n else "") + _ULOG_TYPES[t] for t, _, n in specs[name])
        cols = ["timestamp"] + [c for c in df.columns if c != "timestamp"]
        for row in df[cols].itertuples(index=False):
            vals = [int(v) if i == 0 else v for i, v in enumerate(row)]
            vals = [int(v) if isinstance(v, np.integer) else float(v) if isinstance(
                v, np.floating) else v for v in vals]
            data = struct.pack("<H", msg_id) + struct.pack(code, *vals)
            items.append((vals[0], msg_id, data))
    items.sort(key=lambda x: (x[0], x[1]))
    for _, _, data in items:
        buf += struct.pack("<HB", len(data), ord("D")) + data
    path.write_bytes(bytes(buf))


@pytest.mark.skipif(not HAS_PYULOG, reason="pyulog is not installed (pip install "
                    "'aeromag[ulog]')")
def test_ulog_file_reads_and_navigates(flight, tmp_path):
    p = tmp_path / "flight.ulg"
    _write_ulog(p, _ulog_topics(flight))
    df = read_log(p)
    assert df.attrs.get("source") == str(p)
    for cols in (["gyro_x", "acc_z"], ["flux_x"], ["flow_x", "flow_quality"], ["range_m"],
                 ["lat", "lon", "alt", "vel_n"]):
        _compare(df, flight, cols, {**ATOL, "gyro_x": 1e-6, "acc_z": 1e-5, "flow_x": 1e-6,
                                    "flux_x": 0.05, "range_m": 1e-6, "vel_n": 1e-6})
    import aeromag as am

    res = am.navigate(df, gps="none")
    assert np.isfinite(res.data[["nav_n_m", "nav_e_m", "nav_yaw"]].to_numpy()).all()


_DF_STRUCT = {"Q": "Q", "B": "B", "f": "f", "L": "i", "I": "I", "n": "4s", "N": "16s",
              "Z": "64s"}
_DF_FORMATS = {
    "IMU": ("QBffffff", "TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ"),
    "MAG": ("QBfff", "TimeUS,I,MagX,MagY,MagZ"),
    "OF": ("QBffff", "TimeUS,Qual,flowX,flowY,bodyX,bodyY"),
    "RFND": ("QBfBB", "TimeUS,Instance,Dist,Stat,Orient"),
    "BARO": ("QBf", "TimeUS,I,Alt"),
    "GPS": ("QBBLLffff", "TimeUS,I,Status,Lat,Lng,Alt,Spd,GCrs,VZ"),
    "EV": ("QB", "TimeUS,Id"),
    "ARM": ("QBIBB", "TimeUS,ArmState,ArmChecks,Forced,Method"),
}


def _write_dataflash(path, tables):
    """A DataFlash .bin log per ArduPilot's format: FMT messages (type 128) defining each
    message, then the messages, each ``A3 95 <type> <payload>``."""
    head = b"\xa3\x95"
    buf = bytearray()
    fmt_fmt = struct.pack("<BB4s16s64s", 128, 89, b"FMT", b"BBnNZ",
                          b"Type,Length,Name,Format,Columns")
    buf += head + bytes([128]) + fmt_fmt
    ids = {}
    for k, (name, (fmt, cols)) in enumerate(_DF_FORMATS.items()):
        code = "<" + "".join(_DF_STRUCT[c] for c in fmt)
        ids[name] = (130 + k, code, cols.split(","), fmt)
        buf += head + bytes([128]) + struct.pack(
            "<BB4s16s64s", 130 + k, 3 + struct.calcsize(code), name.encode(), fmt.encode(),
            cols.encode())
    items = []
    for name, df in tables.items():
        mid, code, cols, fmt = ids[name]
        for row in df[cols].itertuples(index=False):
            vals = []
            for c, v in zip(fmt, row, strict=True):
                if c == "L":
                    vals.append(int(round(float(v) * 1e7)))
                elif c in "QBI":
                    vals.append(int(v))
                else:
                    vals.append(float(v))
            items.append((vals[0], head + bytes([mid]) + struct.pack(code, *vals)))
    items.sort(key=lambda x: x[0])
    for _, data in items:
        buf += data
    path.write_bytes(bytes(buf))


@pytest.mark.skipif(not HAS_PYMAVLINK, reason="pymavlink is not installed (pip install "
                    "'aeromag[dataflash]')")
def test_dataflash_file_reads_and_navigates(flight, tmp_path):
    p = tmp_path / "flight.bin"
    _write_dataflash(p, _dataflash_tables(flight))
    df = read_log(p)
    for cols in (["gyro_x", "acc_z"], ["flux_x"], ["flow_x", "flow_quality"], ["range_m"],
                 ["lat", "lon", "alt"]):
        _compare(df, flight, cols, {**ATOL, "gyro_x": 1e-6, "acc_z": 1e-5, "flow_x": 1e-6,
                                    "flux_x": 0.05, "range_m": 1e-5, "alt": 1e-3})
    import aeromag as am

    res = am.navigate(df, gps="none")
    assert np.isfinite(res.data[["nav_n_m", "nav_e_m", "nav_yaw"]].to_numpy()).all()


def test_a_damaged_log_is_a_one_line_error(tmp_path):
    from aeromag.errors import InputError

    for name in ("broken.ulg", "broken.bin"):
        p = tmp_path / name
        p.write_bytes(b"\x00garbage" * 10)
        with pytest.raises(InputError) as err:
            read_log(p)
        assert "\n" not in str(err.value) and str(p) in str(err.value)
