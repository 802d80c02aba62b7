"""Navigate a canonical log: the columns of ``shared/interface.md`` in, the ``nav_*`` out.

:func:`navigate` is what ``aeromag navigate`` runs between reading and writing, and what a
notebook calls on a DataFrame: it checks the sensor columns (one-line errors and warnings
with the remedy), chooses the GNSS fixes to use (``gps="use" | "none" | (T0, T1)``), builds
the local NED frame at the first fix (or ``origin``), runs :class:`~aeromag.nav.NavFilter`
and returns the log with the navigation columns and a report.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .._core.angles import wrap360_deg
from .._core.geodesy import geodetic_to_ned, ned_to_geodetic
from .._core.sequential import SequentialResult
from ..errors import InputError
from .config import NavConfig
from .filter import ALL_SENSORS, NavFilter, NavInputs
from .report import NavReport
from .ukf import DivergenceError

log = logging.getLogger(__name__)

__all__ = ["GYRO", "ACC", "NAV_COLUMNS", "NavigationResult", "TrackInputs",
           "check_flow_against_gyro", "navigate",
           "parse_gps_mode", "track_inputs"]

GYRO = ("gyro_x", "gyro_y", "gyro_z")
ACC = ("acc_x", "acc_y", "acc_z")
FLOW = ("flow_x", "flow_y")
FLUX = ("flux_x", "flux_y", "flux_z")
GPS_POS = ("lat", "lon", "alt")
GPS_VEL = ("vel_n", "vel_e", "vel_d")
#: Sensor columns the filter reads (besides ``time``).
SENSOR_COLUMNS = GYRO + ACC + FLOW + ("flow_quality", "range_m", "baro_alt") + FLUX + (
    GPS_POS + GPS_VEL + ("heading",))
#: Columns added by ``navigate``, in order.
NAV_COLUMNS = ("nav_lat", "nav_lon", "nav_alt", "nav_n_m", "nav_e_m", "nav_d_m", "nav_vn",
               "nav_ve", "nav_vd", "nav_roll", "nav_pitch", "nav_yaw", "nav_std_n_m",
               "nav_std_e_m", "nav_std_d_m")
#: Largest plausible body rate, rad/s (the MPU-6000's full scale, 2000 °/s).
MAX_RATE_RADS = 34.9
_FIX_GAP_S = 2.0
#: Band of the mean NIS per degree of freedom outside which a sensor's noise model is said
#: not to fit (a WARNING), and the fraction of refused samples that warns.
NIS_BAND = (0.3, 3.0)
LOSS_WARN_FRACTION = 0.05

GpsMode = str | tuple[float, float]


@dataclass
class NavigationResult:
    """The navigated log, the filter's result and the report.

    Attributes
    ----------
    data : DataFrame
        The input log plus :data:`NAV_COLUMNS`.
    result : SequentialResult
        The filter's estimate at every row (the package's sequential result).
    report : NavReport
        ``gps`` (mode, origin, intervals used), ``settings``, ``innovations`` (per sensor),
        ``mean_nis`` (per sensor), ``reference_field``, ``warnings`` (``to_dict()`` is
        OUT.json).
    """

    data: pd.DataFrame
    result: SequentialResult
    report: NavReport = field(default_factory=NavReport)


def parse_gps_mode(gps: GpsMode) -> GpsMode:
    """Check ``--gps``: ``use``, ``none`` or ``T0:T1`` (an outage, seconds of log time).

    Returns
    -------
    str or (float, float)
        ``"use"``, ``"none"`` or the outage ``(T0, T1)``.
    """
    if isinstance(gps, tuple):
        t0, t1 = (float(v) for v in gps)
    else:
        g = str(gps).strip().lower()
        if g in ("use", "none"):
            return g
        parts = g.split(":")
        try:
            if len(parts) != 2:
                raise ValueError
            t0, t1 = float(parts[0]), float(parts[1])
        except ValueError:
            raise InputError(f"gps={gps!r}: write 'use', 'none' or 'T0:T1' (an outage between T0"
                             " and T1 seconds of the log's time, e.g. gps='30:60')") from None
    if not (np.isfinite(t0) and np.isfinite(t1) and t1 > t0):
        raise InputError(f"gps={gps!r}: the outage needs T1 > T0 (seconds of the log's time)")
    return (t0, t1)


def _col(df: pd.DataFrame, name: str, source: str) -> np.ndarray | None:
    if name not in df.columns:
        return None
    s = df[name]
    if s.dtype.kind in "fiub":     # already numbers: nothing to parse
        v = s.to_numpy(dtype=np.float64)
        bad = np.zeros(v.shape, bool)
    else:
        v = pd.to_numeric(s, errors="coerce").to_numpy(dtype=np.float64)
        bad = np.isnan(v) & s.notna().to_numpy() & (s.astype(str).str.strip() != "").to_numpy()
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"{source}: column '{name}', data row {i + 1}: {s.iloc[i]!r} is not a"
                         " number; fix the value or leave the cell empty")
    inf = np.isinf(v)
    if inf.any():
        i = int(np.flatnonzero(inf)[0])
        raise InputError(f"{source}: column '{name}', data row {i + 1}: infinite value; fix"
                         " the value or leave the cell empty")
    return v


def _group(df: pd.DataFrame, names: Sequence[str], source: str) -> np.ndarray | None:
    present = [n in df.columns for n in names]
    if not any(present):
        return None
    if not all(present):
        missing = [n for n, p in zip(names, present, strict=True) if not p]
        raise InputError(f"{source}: column(s) {', '.join(missing)} missing beside "
                         f"{', '.join(n for n, p in zip(names, present, strict=True) if p)};"
                         " a sensor needs all its axes (map them with columns={'NAME': 'SOURCE'})")
    return np.column_stack([_col(df, n, source) for n in names])


def _check_imu(t: np.ndarray, gyro: np.ndarray, acc: np.ndarray, source: str,
               warnings: list[str]) -> None:
    imu = np.isfinite(gyro).all(axis=1) & np.isfinite(acc).all(axis=1)
    if imu.sum() < 2:
        raise InputError(f"{source}: fewer than two rows with all of gyro_x..z and acc_x..z;"
                         " navigate needs the IMU on its rows")
    w = np.linalg.norm(gyro[imu], axis=1)
    big = float(np.quantile(w, 0.999))
    if big > MAX_RATE_RADS:
        msg = (f"{source}: gyro magnitudes reach {big:.3g} rad/s, beyond any plausible body "
               f"rate ({MAX_RATE_RADS} rad/s is 2000 °/s): the gyro is probably in deg/s;"
               " convert it with units={'gyro': 'deg/s'}")
        warnings.append(msg)
        log.warning("%s", msg)
    f = float(np.median(np.linalg.norm(acc[imu], axis=1)))
    if not 5.0 < f < 15.0:
        hint = " (in g? use units={'acc': 'g'})" if 0.5 < f < 1.5 else ""
        msg = (f"{source}: the median specific force is {f:.3g}, not about 9.81 m/s²: check"
               f" the accelerometer's unit{hint}")
        warnings.append(msg)
        log.warning("%s", msg)
    dt = np.diff(t[imu])
    med = float(np.median(dt))
    if (dt > 20 * med).any():
        k = int(np.argmax(dt))
        msg = (f"{source}: the IMU has a gap of {dt[k]:.3g} s after t = {t[imu][k]:.6g} s"
               f" ({dt[k] / med:.0f} intervals); it is bridged with the sample after it")
        warnings.append(msg)
        log.warning("%s", msg)


def _check_gyro_against_mag(t: np.ndarray, gyro: np.ndarray, flux: np.ndarray | None,
                            source: str, warnings: list[str],
                            windows_s: tuple[float, ...] = (0.05, 0.25, 1.0)) -> None:
    """Warn when the gyro turns the body far more than the magnetometer sees (deg/s).

    Over windows of each length in ``windows_s`` (s) the body-frame field measured at the
    window's start is rotated by the gyro's integrated angle and the predicted change is
    compared with the measured one (rms over the windows that turn by less than 1 rad; the
    largest ratio of the lengths counts).  A gyro logged in deg/s turns about 57 times too
    far, which the full-scale test misses on a gentle flight or a hover (where its bias alone
    then spins the attitude at tens of degrees per second).  Noise, a motor-current
    disturbance or a hard-iron offset make the measured change larger or the prediction off
    by a small factor only, so a gyro in rad/s does not trigger the warning (threshold 5x).
    """
    if flux is None:
        return
    imu = np.flatnonzero(np.isfinite(gyro).all(axis=1))
    mrow = np.flatnonzero(np.isfinite(flux).all(axis=1))
    if mrow.size < 10 or imu.size < 10:
        return
    ti = t[imu]
    dt = np.diff(ti, prepend=ti[0])
    theta = np.cumsum(gyro[imu] * dt[:, None], axis=0)  # rows: interval mean ending there
    tm = t[mrow]
    tm_ok = (tm >= ti[0]) & (tm <= ti[-1])
    tm, m = tm[tm_ok], flux[mrow][tm_ok]
    th = np.column_stack([np.interp(tm, ti, theta[:, a]) for a in range(3)])
    ratio, rp, ro = 0.0, 0.0, 1.0
    for w in windows_s:
        j = np.searchsorted(tm, tm + w)
        i = np.flatnonzero(j < tm.size)
        j = j[i]
        phi = th[j] - th[i]                           # body rotation over the window, rad
        ang = np.linalg.norm(phi, axis=1)
        keep = ang < 1.0          # beyond, the change saturates at twice the field
        if keep.sum() < 20:
            continue
        i, j, phi, ang = i[keep], j[keep], phi[keep], ang[keep]
        k = phi / np.maximum(ang, 1e-12)[:, None]
        m0 = m[i]
        c, s_ = np.cos(ang)[:, None], np.sin(ang)[:, None]
        # the field in the rotated body frame: m0 rotated by -phi (Rodrigues)
        m_pred = (m0 * c - s_ * np.cross(k, m0)
                  + (1 - c) * k * np.sum(k * m0, axis=1, keepdims=True))
        p_ = float(np.sqrt(np.mean(np.sum((m_pred - m0) ** 2, axis=1))))
        o_ = float(np.sqrt(np.mean(np.sum((m[j] - m0) ** 2, axis=1))))
        if p_ / max(o_, 1e-12) > ratio:
            ratio, rp, ro = p_ / max(o_, 1e-12), p_, o_
    if rp > 5.0 * ro:
        msg = (f"{source}: the gyro turns the body {rp / max(ro, 1e-12):.0f} times as far as"
               " the magnetometer sees: the gyro is probably in deg/s; convert it with"
               " units={'gyro': 'deg/s'}")
        warnings.append(msg)
        log.warning("%s", msg)


def check_flow_against_gyro(t: np.ndarray, gyro: np.ndarray, flow: np.ndarray | None,
                            source: str) -> float | None:
    """Check the unit and sign of the optical flow against the IMU's gyro.

    The flow holds the body rotation (``flow_x = gyro_x - v_y / h``...): regressed on the
    gyro's mean over each flow interval (centred on the stamp), its slope is about 1 in the
    interface's convention, about -1 with the opposite sign, about 57 in deg/s.  Needs some
    rotation (rms body rate about x, y above 0.03 rad/s) to say anything.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Row times, s.
    gyro : ndarray, shape (N, 3)
        Body rate, rad/s.
    flow : ndarray, shape (N, 2) or None
        Optical flow, expected in rad/s.
    source : str
        Log name for the message.

    Returns
    -------
    float or None
        The slope (None when the log rotates too little to tell).

    Raises
    ------
    InputError
        The flow has the opposite sign or is in deg/s (the message names the remedy).
    """
    if flow is None:
        return None
    imu = np.flatnonzero(np.isfinite(gyro).all(axis=1))
    fr = np.flatnonzero(np.isfinite(flow).all(axis=1))
    if imu.size < 10 or fr.size < 20:
        return None
    ti = t[imu]
    dt = np.diff(ti, prepend=ti[0])
    cum = np.cumsum(gyro[imu, :2] * dt[:, None], axis=0)
    tf = t[fr]
    half = 0.5 * np.r_[np.diff(tf)[0], np.diff(tf)]
    a, b = np.clip(tf - half, ti[0], ti[-1]), np.clip(tf + half, ti[0], ti[-1])
    ok = b - a > 0
    g = np.column_stack([(np.interp(b, ti, cum[:, k]) - np.interp(a, ti, cum[:, k]))
                         for k in range(2)])[ok] / (b - a)[ok, None]
    f = flow[fr][ok]
    if g.shape[0] < 20 or np.sqrt(np.mean(g**2)) < 0.03:
        return None
    slope = float(np.sum(f * g) / np.sum(g * g))
    if slope < -0.3:
        raise InputError(f"{source}: columns flow_x, flow_y: the flow turns against the gyro"
                         f" (slope {slope:.2f} on gyro_x, gyro_y, expected about +1): it has the"
                         " opposite sign to the interface's OPTICAL_FLOW_RAD convention; negate"
                         " both columns, or leave flow out (sensors without 'flow')")
    if slope > 15.0:
        raise InputError(f"{source}: columns flow_x, flow_y: the flow's rotation is {slope:.0f}"
                         " times the gyro's: it is probably in deg/s; convert it with"
                         " units={'flow': 'deg/s'}")
    return slope


def navigate(df: pd.DataFrame, *, gps: GpsMode = "use",
             origin: tuple[float, float, float] | None = None,
             mag_reference_ned_nT: np.ndarray | None = None,
             config: NavConfig | None = None, sensors: Sequence[str] | None = None,
             source: str | None = None,
             declination_deg: float | None = None) -> NavigationResult:
    """Run the navigation filter on a canonical multi-rate log.

    Parameters
    ----------
    df : DataFrame
        Canonical columns (``time`` s; ``gyro_*`` rad/s; ``acc_*`` m/s²; optional
        ``flow_x``, ``flow_y`` rad/s, ``flow_quality``, ``range_m`` m, ``baro_alt`` m,
        ``flux_*`` nT, ``lat``, ``lon`` deg, ``alt`` m, ``vel_*`` m/s, ``heading`` deg);
        empty cells where a sensor has no sample.
    gps : "use", "none" or (T0, T1)
        Fuse every GNSS fix; only the first (to start); or all but those in [T0, T1) s.
    origin : (lat, lon, alt), optional
        Origin of the local frame when the log has no GNSS fix (degrees, degrees, m).
    mag_reference_ned_nT : ndarray, shape (3,), optional
        Earth field in NED, nT (IGRF or explicit); default from the log itself.
    config : NavConfig, optional
        Filter settings.
    sensors : sequence of str, optional
        Measurement models to use (default all, see :data:`aeromag.nav.ALL_SENSORS`).
    source : str, optional
        Name of the log for messages (default ``df.attrs["source"]``).
    declination_deg : float, optional
        Declination, ° east, with the strength and inclination from the log (when
        ``mag_reference_ned_nT`` is absent).

    Returns
    -------
    NavigationResult

    Raises
    ------
    InputError
        No IMU columns, non-numeric values, a sensor with missing axes, a bad ``gps``.
    DivergenceError
        The filter diverged (one line with the time and the remedy).
    """
    src = source or str(df.attrs.get("source", "<log>"))
    cfg = config or NavConfig()
    mode = parse_gps_mode(gps)
    warnings: list[str] = []
    missing = [c for c in ("time",) + GYRO + ACC if c not in df.columns]
    if missing:
        raise InputError(f"{src}: missing column(s) {', '.join(missing)}; navigate needs time, "
                         "the gyro (gyro_x..z, rad/s) and the accelerometer (acc_x..z, m/s²);"
                         " map them with columns={'NAME': 'SOURCE'}")
    t = _col(df, "time", src)
    if not np.isfinite(t).all() or (np.diff(t) <= 0).any():
        k = int(np.flatnonzero(~np.isfinite(t) | np.r_[False, np.diff(t) <= 0])[0])
        raise InputError(f"{src}: column 'time', data row {k + 1}: time must be finite and "
                         "strictly increasing (sort the log or fix the row)")
    gyro = _group(df, GYRO, src)
    acc = _group(df, ACC, src)
    _check_imu(t, gyro, acc, src, warnings)
    use = list(ALL_SENSORS if sensors is None else sensors)
    flow = _group(df, FLOW, src)
    rng = _col(df, "range_m", src)
    has_flow = flow is not None and np.isfinite(flow).all(axis=1).any()
    has_range = rng is not None and np.isfinite(rng).any()
    if has_flow and not has_range and "flow" in use:
        msg = (f"{src}: flow_x/flow_y without range_m: optical flow needs the height above"
               " ground, so it is not used (map the rangefinder with"
               " columns={'range_m': 'SOURCE'})")
        warnings.append(msg)
        log.warning("%s", msg)
        use.remove("flow")
    if has_flow and "flow" in use and not any("deg/s" in w for w in warnings):
        check_flow_against_gyro(t, gyro, flow, src)
    flux = _group(df, FLUX, src)
    if not any("deg/s" in w for w in warnings):
        _check_gyro_against_mag(t, gyro, flux, src, warnings)
    llh = _group(df, GPS_POS, src)
    vel = _group(df, GPS_VEL, src)
    fix = (np.zeros(len(t), bool) if llh is None else np.isfinite(llh).all(axis=1))
    gps_ned = gps_use = None
    if fix.any():
        i_fix = int(np.flatnonzero(fix)[0])
        if origin is not None:
            msg = (f"{src}: origin={tuple(origin)!r} ignored: the local frame's origin is the"
                   " log's first GNSS fix")
            warnings.append(msg)
            log.warning("%s", msg)
        org = tuple(float(v) for v in llh[i_fix])
        gps_ned = np.full((len(t), 3), np.nan)
        gps_ned[fix] = geodetic_to_ned(llh[fix, 0], llh[fix, 1], llh[fix, 2], org)
        if mode == "use":
            gps_use = fix.copy()
        elif mode == "none":
            gps_use = np.zeros(len(t), bool)
            gps_use[i_fix] = True
        else:
            gps_use = fix & ~((t >= mode[0]) & (t < mode[1]))
            gps_use[i_fix] = True
    else:
        org = None if origin is None else tuple(float(v) for v in origin)
        if mode != "none" and any(s in use for s in ("gps_pos", "gps_vel")):
            msg = f"{src}: no GNSS fix in the log: the filter starts at the local frame's origin"
            warnings.append(msg)
            log.info("%s", msg)
    if vel is not None and gps_use is not None:
        vel = np.where(gps_use[:, None], vel, np.nan)
    elif vel is not None and mode != "use":
        vel = None
    inputs = NavInputs(
        time_s=t, gyro=gyro, acc=acc, flow=flow, flow_quality=_col(df, "flow_quality", src),
        range_m=rng, baro_alt=_col(df, "baro_alt", src), flux=flux, gps_ned=gps_ned,
        gps_vel=vel, gps_use=gps_use, heading_deg=_col(df, "heading", src))
    filt = NavFilter(cfg, mag_reference_ned_nT=mag_reference_ned_nT, sensors=use,
                     declination_deg=declination_deg)
    try:
        res = filt.run(inputs)
    except DivergenceError as exc:
        raise DivergenceError(f"{src}: {exc}") from None
    warnings += [w for w in res.info["warnings"] if w not in warnings]
    x, sd = res.state, res.std
    out = df.copy()
    if org is not None:
        geo = ned_to_geodetic(x[:, 0:3], org)
        out["nav_lat"], out["nav_lon"], out["nav_alt"] = geo[:, 0], geo[:, 1], geo[:, 2]
    else:
        for c in ("nav_lat", "nav_lon", "nav_alt"):
            out[c] = np.nan
    for j, c in enumerate(("nav_n_m", "nav_e_m", "nav_d_m", "nav_vn", "nav_ve", "nav_vd")):
        out[c] = x[:, j]
    out["nav_roll"] = np.rad2deg(x[:, 6])
    out["nav_pitch"] = np.rad2deg(x[:, 7])
    out["nav_yaw"] = wrap360_deg(np.rad2deg(x[:, 8]))
    for j, c in enumerate(("nav_std_n_m", "nav_std_e_m", "nav_std_d_m")):
        out[c] = sd[:, j]
    # The GNSS intervals used: runs of used fixes, a run broken by a gap of over 2 s.
    intervals: list[list[float]] = []
    if gps_use is not None and "gps_pos" in use:
        rows = np.flatnonzero(gps_use & fix)
        if rows.size:
            cut = np.flatnonzero(np.r_[True, np.diff(t[rows]) > _FIX_GAP_S])
            ends = np.r_[cut[1:] - 1, rows.size - 1]
            intervals = [[float(t[rows[a]]), float(t[rows[b]])]
                         for a, b in zip(cut, ends, strict=True)]
    stats = {k: v.as_dict() for k, v in res.innovations.items()}
    lo, hi = NIS_BAND
    for k, v in stats.items():
        v["nis_band"] = [lo, hi]
        offered = v["n_fused"] + v["n_rejected"]
        if offered and v["n_rejected"] > LOSS_WARN_FRACTION * offered:
            msg = (f"{src}: {k}: {v['n_rejected']} of {offered} samples refused as gross"
                   f" faults ({100 * v['n_rejected'] / offered:.0f} %)")
            warnings.append(msg)
            log.warning("%s", msg)
        m = v["mean_nis_per_dof"]
        if m is not None and v["n_fused"] >= 20 and not lo <= m <= hi:
            msg = (f"{src}: {k}: mean NIS per degree of freedom {m:.2f} outside [{lo}, {hi}]:"
                   f" the filter's {k} noise model does not fit the data")
            warnings.append(msg)
            log.warning("%s", msg)
    report = NavReport(
        gps={"mode": mode if isinstance(mode, str) else {"outage_s": list(mode)},
                "origin": None if org is None else list(org),
                "origin_from": "first GNSS fix" if fix.any() else (
                    "given origin" if org is not None else None),
                "intervals": intervals,
                "n_fixes_in_log": int(fix.sum()),
                "n_fixes_used": int((gps_use & fix).sum()) if gps_use is not None else 0,
             "n_fixes_fused": int(stats.get("gps_pos", {}).get("n_fused", 0))},
        settings={**cfg.as_dict(), "sensors": use, "states": list(res.state_names),
                  "noise_used": res.info["noise"]},
        innovations=stats,
        mean_nis={k: v["mean_nis"] for k, v in stats.items()},
        reference_field={
            "ned_nT": res.info["mag_reference_ned_nT"],
            "declination_deg": res.info["declination_deg"],
            "from_log": mag_reference_ned_nT is None,
            "declination_from": (None if mag_reference_ned_nT is not None else
                                 "given" if declination_deg is not None else "none (0)")},
        ground_d_m=res.info["d_ground_m"], mag_bias_deg=res.info["mag_bias_deg"],
        imu_interval_s=res.info["imu_interval_s"], warnings=warnings)
    return NavigationResult(data=out, result=res, report=report)


@dataclass
class TrackInputs:
    """Position and heading for the track check, the log's own where it has them.

    Attributes
    ----------
    position : (lat, lon, alt) arrays
        Per row: the log's GNSS fix where it has one, the navigated position elsewhere
        (degrees, degrees, m above the ellipsoid).
    heading_deg : ndarray or None
        The navigation filter's yaw (degrees true) when the log has no ``heading``; None when
        it has one (the detector then uses the log's).
    columns : dict of str to ndarray
        ``pitch``, ``roll`` (degrees) from the same run when the log has no such columns (the
        heading detector tilt-compensates the magnetometer with them).
    info : dict
        ``n_rows_filled`` (rows whose position came from the filter), ``heading_from``
        (``"log"`` or ``"navigation filter without the magnetometer"``), ``added_columns``,
        the filter's ``mean_nis`` and ``warnings``.
    """

    position: tuple[np.ndarray, np.ndarray, np.ndarray]
    heading_deg: np.ndarray | None
    columns: dict
    info: dict


def track_inputs(df: pd.DataFrame, *, mag_reference_ned_nT: np.ndarray | None = None,
                 config: NavConfig | None = None, source: str | None = None) -> TrackInputs:
    """Navigate a log and fill what the track check lacks.

    That is: positions between and in the gaps of the GNSS fixes, and the attitude heading
    when the log has no INS heading.

    Parameters
    ----------
    df : DataFrame
        The log (needs the IMU columns and at least one GNSS fix, see :func:`navigate`).
    mag_reference_ned_nT : ndarray, shape (3,), optional
        Earth field in NED, nT (default from the log).
    config : NavConfig, optional
        Filter settings.
    source : str, optional
        Log name for messages.

    Returns
    -------
    TrackInputs
    """
    src = source or str(df.attrs.get("source", "<log>"))
    if not all(c in df.columns for c in GPS_POS):
        raise InputError(f"{src}: navigating for the track check needs the GNSS columns lat, "
                         "lon, alt (at least one fix); map them with"
                         " columns={'NAME': 'SOURCE'}")
    res = navigate(df, gps="use", mag_reference_ned_nT=mag_reference_ned_nT, config=config,
                   source=src)
    d = res.data
    fix = np.column_stack([pd.to_numeric(df[c], errors="coerce").to_numpy(float)
                           for c in GPS_POS])
    ok = np.isfinite(fix).all(axis=1)
    nav = d[["nav_lat", "nav_lon", "nav_alt"]].to_numpy(float)
    pos = np.where(ok[:, None], fix, nav)
    head = None
    has_heading = "heading" in df.columns and np.isfinite(
        pd.to_numeric(df["heading"], errors="coerce").to_numpy(float)).any()
    warnings = list(res.report.warnings)
    if not has_heading:
        # The heading detector compares the attitude with the magnetometer: its attitude must
        # not come from the magnetometer, so this run leaves it out (it only aligns the yaw at
        # the start); the yaw then rests on the gyro, GNSS velocity and flow.
        sensors = [s for s in res.report.sensors if s != "mag"]
        hres = navigate(df, gps="use", mag_reference_ned_nT=mag_reference_ned_nT,
                        config=config, source=src, sensors=sensors)
        head = hres.data["nav_yaw"].to_numpy(float)
        warnings += [w for w in hres.report.warnings if w not in warnings]
        columns = {c: hres.data[f"nav_{c}"].to_numpy(float) for c in ("pitch", "roll")
                   if c not in df.columns}
    else:
        columns = {}
    info = {"n_rows_filled": int((~ok).sum()),
            "heading_from": ("log" if has_heading else
                             "navigation filter without the magnetometer"),
            "added_columns": sorted(columns), "mean_nis": res.report.mean_nis,
            "warnings": warnings}
    return TrackInputs(position=(pos[:, 0], pos[:, 1], pos[:, 2]), heading_deg=head,
                       columns=columns, info=info)
