"""UAV flight logs: PX4 ULog (pyulog) and ArduPilot DataFlash (pymavlink) as canonical tables.

The canonical multi-rate table is that of ``shared/interface.md``.

Each reader has two halves: the file's messages as one table per topic (``ulog_tables``,
``dataflash_tables``; the optional package does this) and the mapping of those tables onto the
canonical columns (``ulog_to_canonical``, ``dataflash_to_canonical``; pure pandas, tested on
synthetic message tables).  The rows of the result are the union of every sensor topic's sample
times; a sensor's columns are empty on rows where it has no sample.

=============  =============================================  ================================
column         PX4 ULog                                       ArduPilot DataFlash
=============  =============================================  ================================
``time``       ``timestamp`` (µs since boot) / 1e6            ``TimeUS`` / 1e6
``gyro_*``     ``sensor_combined.gyro_rad[0..2]``             ``IMU.GyrX..Z`` (instance 0)
``acc_*``      ``sensor_combined.accelerometer_m_s2[0..2]``   ``IMU.AccX..Z``
``flux_*``     ``vehicle_magnetometer.magnetometer_ga`` x1e5  ``MAG.MagX..Z`` (mGauss) x100
``flow_x/y``   ``sensor_optical_flow.pixel_flow`` or          ``OF.flowX``, ``OF.flowY``
               ``optical_flow.pixel_flow_*_integral``
               / integration time
``flow_quality`` ``quality``                                  ``OF.Qual``
``range_m``    ``distance_sensor.current_distance``           ``RFND.Dist`` (downward)
               (downward, orientation 25)
``baro_alt``   ``vehicle_air_data.baro_alt_meter``            ``BARO.Alt``
``lat/lon``    ``vehicle_gps_position`` / ``sensor_gps``      ``GPS.Lat``, ``GPS.Lng``
               ``lat``, ``lon`` (1e-7 deg), 3-D fix only       (3-D fix only)
``alt``        ``alt_ellipsoid`` (mm) / 1e3                   ``GPS.Alt`` (MSL: DataFlash has
                                                              no ellipsoidal height)
``vel_n/e/d``  ``vel_n_m_s``, ``vel_e_m_s``, ``vel_d_m_s``    ``GPS.Spd``, ``GCrs``, ``VZ``
``roll``,      ``vehicle_attitude.q`` (Z-Y-X Euler, deg)      ``ATT.Roll``, ``Pitch``, ``Yaw``
``pitch``,
``heading``
``armed``      ``vehicle_status.arming_state`` == 2 (ARMED);  ``ARM.ArmState``; without ARM
               ``actuator_armed.armed`` without it or when    ``EV`` Id 10 (ARMED) / 11
               it holds the ambiguous 3 (see below)           (DISARMED)
``landed``     ``vehicle_land_detected.landed``               ``EV`` Id 18 (LAND_COMPLETE) /
                                                              28 (NOT_LANDED)
=============  =============================================  ================================

``armed`` and ``landed`` are states, not samples (nullable booleans, pandas ``boolean``): on
every row of the table the last state logged at or before the row's time, held until the next
change; empty before the state's first message, absent when the log has none.  The state
messages add no rows.  PX4's ``arming_state`` 3 is ARMED_ERROR (armed) in old releases and
STANDBY_ERROR (disarmed) in later ones: a log holding it takes ``actuator_armed.armed``, or
has no ``armed`` (a logged warning) without that topic.  ArduPilot's ``MODE`` (a LAND mode is
not yet on the ground) and ``LAND_COMPLETE_MAYBE`` (17) are not used.

Both packages are optional extras: ``pip install 'aeromag[ulog]'`` / ``'aeromag[dataflash]'``;
without them the formats are refused with that remedy.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import InputError
from .formats import Format, register
from .rows import ROWS_ATTR, rows_numbered

log = logging.getLogger(__name__)

__all__ = ["DF_EVENTS", "PX4_ARMING_STATE_AMBIGUOUS", "PX4_ARMING_STATE_ARMED",
           "dataflash_tables", "dataflash_to_canonical", "hold_state", "read_dataflash",
           "read_ulog", "ulog_tables", "ulog_to_canonical", "union_rows"]

_DOWNWARD = 25  # MAV_SENSOR_ROTATION_PITCH_270: a downward-facing sensor
_GAUSS_TO_NT = 1.0e5

#: ``vehicle_status.arming_state`` of an armed PX4 (``ARMING_STATE_ARMED``: 2 in every
#: release, from INIT/STANDBY/ARMED to today's DISARMED = 1 / ARMED = 2).
PX4_ARMING_STATE_ARMED = 2

#: ``arming_state`` 3 is ARMED_ERROR (armed) in old PX4 releases and STANDBY_ERROR
#: (disarmed) in later ones: a log holding it takes ``actuator_armed.armed`` instead.
PX4_ARMING_STATE_AMBIGUOUS = 3

#: ArduPilot ``EV`` ids (``AP_Logger`` ``LogEvent``) read as states: id -> (column, value).
DF_EVENTS = {10: ("armed", True), 11: ("armed", False), 18: ("landed", True),
             28: ("landed", False)}


def union_rows(parts: list[pd.DataFrame]) -> pd.DataFrame:
    """One table whose rows are the union of the parts' ``time`` values.

    Parts sampled at the same time share a row; each column is empty where its part has no
    sample.  Duplicate times within one part keep the first sample.
    """
    parts = [p.drop_duplicates("time").set_index("time") for p in parts if len(p)]
    if not parts:
        return pd.DataFrame({"time": np.zeros(0)})
    out = pd.concat(parts, axis=1, join="outer", sort=True)
    out = out.loc[:, ~out.columns.duplicated()]
    out.index.name = "time"
    return out.reset_index()


def hold_state(time_s: np.ndarray, msg_time_s: np.ndarray, state: np.ndarray) -> pd.Series:
    """A state logged at its changes, held forward onto the rows' times.

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Times of the table's rows, s.
    msg_time_s : ndarray, shape (m,)
        Times of the state's messages, s (any order; of equal times the last logged wins).
    state : ndarray of bool, shape (m,)
        The state each message reports.

    Returns
    -------
    Series of pandas ``boolean``, length n
        Per row the state of the last message at or before it; empty (``<NA>``) before the
        first message.
    """
    mt = np.asarray(msg_time_s, dtype=np.float64)
    order = np.argsort(mt, kind="stable")
    mt, st = mt[order], np.asarray(state, dtype=bool)[order]
    i = np.searchsorted(mt, np.asarray(time_s, dtype=np.float64), side="right") - 1
    out = pd.array(st[np.maximum(i, 0)] if len(st) else np.zeros(len(i), bool),
                   dtype="boolean")
    out[i < 0] = pd.NA
    return pd.Series(out)


def _add_states(df: pd.DataFrame, states: dict[str, tuple[np.ndarray, np.ndarray]]
                ) -> pd.DataFrame:
    for name, (mt, st) in states.items():
        if len(mt):
            df[name] = hold_state(df["time"].to_numpy(), mt, st).array
    return df


def _q_to_euler_deg(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    w, x, y, z = (q[:, i] for i in range(4))
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1, 1))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.rad2deg(roll), np.rad2deg(pitch), np.mod(np.rad2deg(yaw), 360.0)


def _cols(df: pd.DataFrame, names: list[str]) -> np.ndarray:
    return np.column_stack([df[n].to_numpy(dtype=np.float64) for n in names])


# ----------------------------------------------------------------------------- PX4 ULog
def ulog_to_canonical(tables: Mapping[str, pd.DataFrame]) -> pd.DataFrame:
    """Map PX4 ULog topics onto the canonical columns.

    One table per topic (instance 0), with ``timestamp`` in µs and pyulog's field names such
    as ``gyro_rad[0]``.

    Parameters
    ----------
    tables : mapping of str to DataFrame
        Topic name -> its messages.

    Returns
    -------
    DataFrame
        The canonical multi-rate table (see the module's table).
    """
    parts = []

    def t_of(df: pd.DataFrame) -> np.ndarray:
        return df["timestamp"].to_numpy(dtype=np.float64) / 1e6

    sc = tables.get("sensor_combined")
    if sc is not None and len(sc):
        g = _cols(sc, [f"gyro_rad[{i}]" for i in range(3)])
        a = _cols(sc, [f"accelerometer_m_s2[{i}]" for i in range(3)])
        t = t_of(sc)
        if "accelerometer_timestamp_relative" in sc:
            # The accelerometer sample is logged beside the gyro's; its own time offset is
            # below one sample and not modelled (the filter reads both on the gyro's row).
            pass
        parts.append(pd.DataFrame({"time": t, "gyro_x": g[:, 0], "gyro_y": g[:, 1],
                                   "gyro_z": g[:, 2], "acc_x": a[:, 0], "acc_y": a[:, 1],
                                   "acc_z": a[:, 2]}))
    mag = tables.get("vehicle_magnetometer")
    if mag is not None and len(mag):
        m = _cols(mag, [f"magnetometer_ga[{i}]" for i in range(3)]) * _GAUSS_TO_NT
        parts.append(pd.DataFrame({"time": t_of(mag), "flux_x": m[:, 0], "flux_y": m[:, 1],
                                   "flux_z": m[:, 2]}))
    of = tables.get("sensor_optical_flow")
    if of is not None and len(of):
        dt = of["integration_timespan_us"].to_numpy(dtype=np.float64) / 1e6
        fx, fy = of["pixel_flow[0]"].to_numpy(float), of["pixel_flow[1]"].to_numpy(float)
        q = of["quality"].to_numpy(float)
    else:
        of = tables.get("optical_flow")
        if of is not None and len(of):
            dt = of["integration_timespan"].to_numpy(dtype=np.float64) / 1e6
            fx = of["pixel_flow_x_integral"].to_numpy(float)
            fy = of["pixel_flow_y_integral"].to_numpy(float)
            q = of["quality"].to_numpy(float)
    if of is not None and len(of):
        ok = dt > 0
        parts.append(pd.DataFrame({"time": t_of(of)[ok], "flow_x": fx[ok] / dt[ok],
                                   "flow_y": fy[ok] / dt[ok], "flow_quality": q[ok]}))
    ds = tables.get("distance_sensor")
    if ds is not None and len(ds):
        down = (ds["orientation"].to_numpy() == _DOWNWARD) if "orientation" in ds else np.ones(
            len(ds), bool)
        parts.append(pd.DataFrame({"time": t_of(ds)[down],
                                   "range_m": ds["current_distance"].to_numpy(float)[down]}))
    air = tables.get("vehicle_air_data")
    if air is not None and len(air):
        parts.append(pd.DataFrame({"time": t_of(air),
                                   "baro_alt": air["baro_alt_meter"].to_numpy(float)}))
    gps = tables.get("vehicle_gps_position")
    if gps is None or not len(gps):
        gps = tables.get("sensor_gps")
    if gps is not None and len(gps):
        fix = gps["fix_type"].to_numpy() >= 3 if "fix_type" in gps else np.ones(len(gps), bool)
        if "latitude_deg" in gps:                      # PX4 1.15+: degrees and metres
            lat, lon = gps["latitude_deg"].to_numpy(float), gps["longitude_deg"].to_numpy(float)
            alt = gps["altitude_ellipsoid_m"].to_numpy(float)
        else:                                          # integer 1e-7 degrees, millimetres
            lat, lon = gps["lat"].to_numpy(float) * 1e-7, gps["lon"].to_numpy(float) * 1e-7
            alt_col = "alt_ellipsoid" if "alt_ellipsoid" in gps else "alt"
            alt = gps[alt_col].to_numpy(float) / 1e3
        d = {"time": t_of(gps), "lat": lat, "lon": lon, "alt": alt}
        for c, src in (("vel_n", "vel_n_m_s"), ("vel_e", "vel_e_m_s"), ("vel_d", "vel_d_m_s")):
            if src in gps:
                d[c] = gps[src].to_numpy(float)
        parts.append(pd.DataFrame(d).loc[fix])
    att = tables.get("vehicle_attitude")
    if att is not None and len(att):
        r, p, y = _q_to_euler_deg(_cols(att, [f"q[{i}]" for i in range(4)]))
        parts.append(pd.DataFrame({"time": t_of(att), "roll": r, "pitch": p, "heading": y}))
    states = {}
    vs, aa = tables.get("vehicle_status"), tables.get("actuator_armed")
    has_aa = aa is not None and len(aa) > 0 and "armed" in aa
    arming = vs["arming_state"].to_numpy() if (
        vs is not None and len(vs) and "arming_state" in vs) else None
    ambiguous = arming is not None and bool(np.any(arming == PX4_ARMING_STATE_AMBIGUOUS))
    if arming is not None and not ambiguous:
        states["armed"] = (t_of(vs), arming == PX4_ARMING_STATE_ARMED)
    elif has_aa:               # logs without vehicle_status, or with an ambiguous state 3
        states["armed"] = (t_of(aa), aa["armed"].to_numpy().astype(bool))
    elif ambiguous:
        log.warning("vehicle_status.arming_state 3 is ARMED_ERROR (armed) in old PX4 releases "
                    "and STANDBY_ERROR (disarmed) in later ones, and the log has no "
                    "actuator_armed: no 'armed' column")
    ld = tables.get("vehicle_land_detected")
    if ld is not None and len(ld) and "landed" in ld:
        states["landed"] = (t_of(ld), ld["landed"].to_numpy().astype(bool))
    return _add_states(union_rows(parts), states)


def ulog_tables(path: str | Path) -> dict[str, pd.DataFrame]:
    """Read the topics :func:`ulog_to_canonical` needs from a PX4 ULog file (instance 0)."""
    try:
        from pyulog import ULog
    except ImportError:
        raise InputError(f"{path}: reading PX4 ULog needs pyulog: pip install "
                         "'aeromag[ulog]'") from None
    topics = ["sensor_combined", "vehicle_magnetometer", "sensor_optical_flow",
              "optical_flow", "distance_sensor", "vehicle_air_data", "vehicle_gps_position",
              "sensor_gps", "vehicle_attitude", "vehicle_status", "actuator_armed",
              "vehicle_land_detected"]
    try:
        ulog = ULog(str(path), topics)
    except Exception as exc:  # noqa: BLE001 - any parser failure is a bad file
        raise InputError(f"{path}: cannot read as PX4 ULog ({str(exc)[:200]}); is it a "
                         ".ulg file, complete and undamaged?") from None
    out: dict[str, pd.DataFrame] = {}
    for d in ulog.data_list:
        if d.multi_id == 0 and d.name not in out:
            out[d.name] = pd.DataFrame({k: np.asarray(v) for k, v in d.data.items()})
    return out


def read_ulog(path: Path) -> pd.DataFrame:
    """Read a PX4 ULog file into the canonical multi-rate table (format ``ulog``)."""
    df = ulog_to_canonical(ulog_tables(path))
    if len(df) == 0 or "gyro_x" not in df:
        raise InputError(f"{path}: no sensor_combined (IMU) messages in this ULog")
    df.attrs[ROWS_ATTR] = rows_numbered("row")
    return df


# ----------------------------------------------------------------------- ArduPilot DataFlash
def dataflash_to_canonical(tables: Mapping[str, pd.DataFrame]) -> pd.DataFrame:
    """Map ArduPilot DataFlash messages onto the canonical columns.

    One table per message type, with ``TimeUS`` and the log's field names.

    Parameters
    ----------
    tables : mapping of str to DataFrame
        Message type (``IMU``, ``MAG``, ``OF``, ``RFND``, ``BARO``, ``GPS``, ``ATT``, ``ARM``,
        ``EV``) -> its messages (instance 0 where a message has an ``I`` or ``Instance`` field).

    Returns
    -------
    DataFrame
        The canonical multi-rate table.
    """
    def first_instance(df: pd.DataFrame) -> pd.DataFrame:
        for c in ("I", "Instance"):
            if c in df:
                return df[df[c] == df[c].min()]
        return df

    parts = []

    def t_of(df: pd.DataFrame) -> np.ndarray:
        return df["TimeUS"].to_numpy(dtype=np.float64) / 1e6

    imu = tables.get("IMU")
    if imu is not None and len(imu):
        imu = first_instance(imu)
        parts.append(pd.DataFrame({"time": t_of(imu), **{
            f"gyro_{a}": imu[f"Gyr{a.upper()}"].to_numpy(float) for a in "xyz"}, **{
            f"acc_{a}": imu[f"Acc{a.upper()}"].to_numpy(float) for a in "xyz"}}))
    mag = tables.get("MAG")
    if mag is not None and len(mag):
        mag = first_instance(mag)
        parts.append(pd.DataFrame({"time": t_of(mag), **{
            f"flux_{a}": mag[f"Mag{a.upper()}"].to_numpy(float) * 100.0 for a in "xyz"}}))
    of = tables.get("OF")
    if of is not None and len(of):
        parts.append(pd.DataFrame({"time": t_of(of), "flow_x": of["flowX"].to_numpy(float),
                                   "flow_y": of["flowY"].to_numpy(float),
                                   "flow_quality": of["Qual"].to_numpy(float)}))
    rf = tables.get("RFND")
    if rf is not None and len(rf):
        if "Orient" in rf:
            rf = rf[rf["Orient"] == _DOWNWARD]
        rf = first_instance(rf)
        parts.append(pd.DataFrame({"time": t_of(rf), "range_m": rf["Dist"].to_numpy(float)}))
    baro = tables.get("BARO")
    if baro is not None and len(baro):
        baro = first_instance(baro)
        parts.append(pd.DataFrame({"time": t_of(baro), "baro_alt": baro["Alt"].to_numpy(float)}))
    gps = tables.get("GPS")
    if gps is not None and len(gps):
        gps = first_instance(gps)
        if "Status" in gps:
            gps = gps[gps["Status"] >= 3]
        spd, crs = gps["Spd"].to_numpy(float), np.deg2rad(gps["GCrs"].to_numpy(float))
        parts.append(pd.DataFrame({
            "time": t_of(gps), "lat": gps["Lat"].to_numpy(float),
            "lon": gps["Lng"].to_numpy(float), "alt": gps["Alt"].to_numpy(float),
            "vel_n": spd * np.cos(crs), "vel_e": spd * np.sin(crs),
            "vel_d": gps["VZ"].to_numpy(float) if "VZ" in gps else np.nan}))
    att = tables.get("ATT")
    if att is not None and len(att):
        parts.append(pd.DataFrame({"time": t_of(att), "roll": att["Roll"].to_numpy(float),
                                   "pitch": att["Pitch"].to_numpy(float),
                                   "heading": np.mod(att["Yaw"].to_numpy(float), 360.0)}))
    states = {}
    ev = tables.get("EV")
    if ev is not None and len(ev) and "TimeUS" in ev and "Id" in ev:
        ids = ev["Id"].to_numpy()
        for name in ("armed", "landed"):
            keys = [k for k, (col, _) in DF_EVENTS.items() if col == name]
            on = np.isin(ids, keys)
            states[name] = (t_of(ev)[on], np.array([DF_EVENTS[int(k)][1] for k in ids[on]],
                                                   dtype=bool))
    arm = tables.get("ARM")
    if arm is not None and len(arm) and "ArmState" in arm:
        states["armed"] = (t_of(arm), arm["ArmState"].to_numpy() != 0)
    return _add_states(union_rows(parts), states)


_DF_TYPES = ("IMU", "MAG", "OF", "RFND", "BARO", "GPS", "ATT", "ARM", "EV")


def dataflash_tables(path: str | Path) -> dict[str, pd.DataFrame]:
    """Read the messages :func:`dataflash_to_canonical` needs from a DataFlash ``.bin`` log."""
    try:
        from pymavlink import DFReader
    except ImportError:
        raise InputError(f"{path}: reading ArduPilot DataFlash needs pymavlink: pip install "
                         "'aeromag[dataflash]'") from None
    rows: dict[str, list[dict]] = {k: [] for k in _DF_TYPES}
    try:
        reader = DFReader.DFReader_binary(str(path), zero_time_base=True)
        while True:
            m = reader.recv_match(type=list(_DF_TYPES))
            if m is None:
                break
            d = m.to_dict()
            d.pop("mavpackettype", None)
            rows[m.get_type()].append(d)
    except Exception as exc:  # noqa: BLE001 - any parser failure is a bad file
        raise InputError(f"{path}: cannot read as ArduPilot DataFlash ({str(exc)[:200]}); is "
                         "it a .bin log, complete and undamaged?") from None
    return {k: pd.DataFrame(v) for k, v in rows.items() if v}


def read_dataflash(path: Path) -> pd.DataFrame:
    """Read an ArduPilot DataFlash ``.bin`` log into the canonical table (``dataflash``)."""
    df = dataflash_to_canonical(dataflash_tables(path))
    if len(df) == 0 or "gyro_x" not in df:
        raise InputError(f"{path}: no IMU messages in this DataFlash log")
    df.attrs[ROWS_ATTR] = rows_numbered("row")
    return df


register(Format("ulog", (".ulg",), read=read_ulog))
register(Format("dataflash", (".bin",), read=read_dataflash))
