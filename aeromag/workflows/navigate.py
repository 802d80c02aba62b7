"""``aeromag navigate``, file in, files out.

Read a multi-rate log, navigate, write OUT.csv (the log plus the ``nav_*`` columns) and
OUT.json (GNSS intervals used, settings, per-sensor innovation statistics) as a set.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import InputError
from ..io import atomic_path, json_path_for, read_log, write_csv, write_json
from ..io.outputs import check_outputs
from ..nav.config import NavConfig
from ..nav.pipeline import GPS_POS, GpsMode, NavigationResult, navigate, parse_gps_mode

log = logging.getLogger(__name__)

__all__ = ["NAV_UNITS", "NOMINAL_DATE", "navigate_file", "navigate_frame", "split_units"]

#: Units ``units=`` converts for the navigation sensors: {group or column: {unit: factor}}.
_ANGULAR = {"rad/s": 1.0, "deg/s": np.pi / 180.0, "dps": np.pi / 180.0}
_ACCEL = {"m/s2": 1.0, "m/s^2": 1.0, "g": 9.80665, "mg": 9.80665e-3}
NAV_UNITS: dict[str, tuple[tuple[str, ...], dict[str, float]]] = {
    "gyro": (("gyro_x", "gyro_y", "gyro_z"), _ANGULAR),
    "flow": (("flow_x", "flow_y"), _ANGULAR),
    "acc": (("acc_x", "acc_y", "acc_z"), _ACCEL),
}
for _g, (_cols, _u) in list(NAV_UNITS.items()):
    for _c in _cols:
        NAV_UNITS[_c] = ((_c,), _u)


def split_units(units: Mapping[str, str] | None) -> tuple[dict[str, str], dict[str, str]]:
    """Split ``units`` into the navigation sensors' (gyro, flow, acc) and the field ones."""
    nav, rest = {}, {}
    for k, v in (units or {}).items():
        (nav if k in NAV_UNITS else rest)[k] = v
    return nav, rest


def _convert_nav_units(df: pd.DataFrame, units: Mapping[str, str], source: str) -> None:
    for key, unit in units.items():
        cols, table = NAV_UNITS[key]
        u = unit.strip().lower().replace("°", "deg").replace("²", "2")
        if u not in table:
            raise InputError(f"{source}: units={{'{key}': '{unit}'}}: unknown unit; use one of "
                             f"{', '.join(table)}")
        present = [c for c in cols if c in df.columns]
        if not present:
            raise InputError(f"{source}: units={{'{key}': '{unit}'}}: no column {key!r} in the "
                             "log")
        for c in present:
            df[c] = pd.to_numeric(df[c], errors="coerce") * table[u]


#: Date of the IGRF reference when neither ``date`` nor the log's time gives one (a recent
#: epoch: the declination moves by a few tenths of a degree per decade at most places).
NOMINAL_DATE = "2025-01-01"
_EPOCH_2000_S = 946684800.0   # a ``time`` beyond this is UTC seconds since 1970


def _first_fix(df: pd.DataFrame) -> tuple[float, float, float] | None:
    if not all(c in df.columns for c in GPS_POS):
        return None
    llh = df[list(GPS_POS)].apply(pd.to_numeric, errors="coerce").to_numpy(float)
    ok = np.flatnonzero(np.isfinite(llh).all(axis=1))
    return tuple(float(v) for v in llh[ok[0]]) if ok.size else None


def navigate_frame(
    df: pd.DataFrame,
    *,
    gps: GpsMode = "use",
    origin: tuple[float, float, float] | None = None,
    date: str | None = None,
    earth_field: tuple[float, float, float] | None = None,
    config: NavConfig | None = None,
    sensors: Sequence[str] | None = None,
    source: str | None = None,
) -> NavigationResult:
    """Navigate a log already read, with a true magnetic reference whenever possible.

    The reference field (and so the declination that makes the yaw true) is, in order: the
    explicit ``earth_field``; IGRF at the first fix (or ``origin``) on ``date``; on the date
    of the log's own ``time`` when it is UTC seconds since 1970; else IGRF on
    :data:`NOMINAL_DATE`, with a warning naming the declination used.  Without any position
    the reference comes from the log (declination 0: the yaw is magnetic, with a warning).

    Parameters
    ----------
    df : DataFrame
        Canonical columns (see :func:`aeromag.nav.navigate`).
    gps, origin, config, sensors, source
        As for :func:`aeromag.nav.navigate`.
    date : str, optional
        Flight date YYYY-MM-DD for IGRF.
    earth_field : (F nT, I deg, D deg), optional
        Explicit reference field.

    Returns
    -------
    NavigationResult
        ``report["reference_field"]["source"]`` says how the reference was obtained.
    """
    from ..compass.reference import explicit_field, igrf_field

    src = source or str(df.attrs.get("source", "<log>"))
    if date is not None and earth_field is not None:
        raise InputError("date='YYYY-MM-DD' and earth_field=(F, I, D) are both given: give one "
                         "magnetic reference, not both")
    ref, note, auto = None, None, False
    if earth_field is not None:
        ref = explicit_field(*earth_field)
    else:
        where = _first_fix(df) or origin
        if date is not None and where is None:
            raise InputError(f"{src}: date={date!r} needs a position for IGRF: the log has no"
                             " GNSS fix; give origin=(LAT, LON, ALT) (or earth_field=(F, I, D))")
        if where is not None:
            how = "given date"
            if date is None:
                t = pd.to_numeric(df["time"], errors="coerce").to_numpy(float) if (
                    "time" in df.columns) else np.zeros(1)
                t0 = float(np.nanmin(t)) if np.isfinite(t).any() else 0.0
                if t0 > _EPOCH_2000_S:
                    date = pd.Timestamp(t0, unit="s").strftime("%Y-%m-%d")
                    how = "the log's UTC time"
                else:
                    date, how = NOMINAL_DATE, "nominal date"
                auto = True
            try:
                ref = igrf_field(where[0], where[1], where[2], date)
            except InputError as exc:  # a bad date, the package missing: name the log
                raise InputError(f"{src}: {exc}") from None
            if how == "nominal date":
                d = float(np.atleast_1d(ref.declination_deg)[0])
                note = (f"{src}: no date='YYYY-MM-DD' and the log's time is not UTC: the magnetic"
                        f" reference is IGRF on the nominal date {date}, declination"
                        f" {d:.1f}° at the first fix (it moves slowly; give"
                        " date='YYYY-MM-DD' for the flight's own)")
                log.warning("%s", note)
    ref_ned = None if ref is None else np.atleast_2d(ref.ned_nT)[0]
    decl = None
    if auto:
        # No date given: the declination from IGRF, the strength and inclination from the log
        # (an uncalibrated magnetometer's strength differs from IGRF's; its heading does not).
        decl, ref_ned = float(np.atleast_1d(ref.declination_deg)[0]), None
    res = navigate(df, gps=gps, origin=origin, mag_reference_ned_nT=ref_ned, config=config,
                   sensors=sensors, source=src, declination_deg=decl)
    if note is not None:
        res.report.warnings.insert(0, note)
    if ref is not None:
        res.report.reference_field["source"] = ref.info
    return res


def navigate_file(
    log_path: str | os.PathLike[str],
    out_path: str | os.PathLike[str],
    *,
    gps: GpsMode = "use",
    origin: tuple[float, float, float] | None = None,
    date: str | None = None,
    earth_field: tuple[float, float, float] | None = None,
    config: NavConfig | None = None,
    sensors: Sequence[str] | None = None,
    columns: dict[str, str] | None = None,
    units: dict[str, str] | None = None,
    fmt: str | None = None,
) -> NavigationResult:
    """Read a log, run the navigation filter, write OUT.csv and OUT.json as a set.

    Parameters
    ----------
    log_path : path-like
        Multi-rate log with ``time``, ``gyro_*`` (rad/s), ``acc_*`` (m/s²) and any of the
        aiding sensors (see :func:`aeromag.nav.navigate`).
    out_path : path-like
        Output CSV; the report goes to the same path with suffix ``.json``.
    gps : "use", "none" or "T0:T1"
        GNSS use (``--gps``).
    origin : (lat, lon, alt), optional
        Local frame origin when the log has no GNSS fix (degrees, degrees, m).
    date : str, optional
        Flight date YYYY-MM-DD: the magnetic reference is IGRF at the first fix or origin
        (without it: the log's UTC time, else a nominal date; see :func:`navigate_frame`).
    earth_field : (F nT, I deg, D deg), optional
        Explicit magnetic reference instead of IGRF.
    config : NavConfig, optional
        Filter settings (noise, gates).
    sensors : sequence of str, optional
        Measurement models to use (default all).
    columns : dict, optional
        Column map ``{canonical: source}``.
    units : dict, optional
        Unit conversions: ``gyro``/``flow`` (rad/s, deg/s), ``acc`` (m/s2, g, mg), or any
        field column or group (to nT).
    fmt : str, optional
        Log format (default from the extension).

    Returns
    -------
    NavigationResult
    """
    out = Path(out_path)
    out_json = json_path_for(out)
    check_outputs(log_path, out, out_json)
    mode = parse_gps_mode(gps)
    nav_units, field_units = split_units(units)
    df = read_log(log_path, columns=columns, units=field_units or None, required=("time",),
                  fmt=fmt)
    source = str(log_path)
    _convert_nav_units(df, nav_units, source)
    res = navigate_frame(df, gps=mode, origin=origin, date=date, earth_field=earth_field,
                         config=config, sensors=sensors, source=source)
    res.report.input = source
    with atomic_path(out) as tmp_csv, atomic_path(out_json) as tmp_json:
        write_csv(res.data, tmp_csv)
        doc = res.report.to_dict()
        write_json(doc, tmp_json)
    res.report.warnings = doc["warnings"]   # with those the command logged, as in the file
    return res
