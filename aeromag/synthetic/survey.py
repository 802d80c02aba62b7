"""The survey flight: parallel lines over buried dipoles, its plan, and rounding as shipped."""


import logging
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from ..errors import InputError
from .faults import assemble, check_nonneg, check_positive, common_truth, resolve_faults
from .physics import (
    DEFAULT_ORIGIN,
    MU0_4PI_NT,
    EarthField,
    band_noise,
    dipole_field_ned,
    diurnal_field,
    flight_setup,
    local_to_geodetic,
    taper,
)

log = logging.getLogger(__name__)


def simulate_survey(
    *,
    seed: int = 0,
    rate_hz: float = 10.0,
    n_lines: int = 8,
    line_length_m: float = 400.0,
    spacing_m: float = 25.0,
    speed_mps: float = 8.0,
    line_azimuth_deg: float = 0.0,
    height_m: float = 50.0,
    noise_nT: float = 0.02,
    flux_noise_nT: float = 0.5,
    earth: EarthField | None = None,
    coef: Any | None = None,
    faults: float | Mapping[int, str] | None = None,
    origin: tuple[float, float, float] = DEFAULT_ORIGIN,
    n_dipoles: int = 5,
    gust_deg: float = 2.0,
    yaw_wobble_deg: float = 1.0,
    trim_pitch_deg: float = -3.0,
    diurnal_nT: float = 3.0,
    wander_m: float = 0.1,
    pos_noise_m: float = 0.02,
    turn_s: float = 15.0,
) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Simulate a survey: parallel lines flown alternately in opposite directions.

    Line ``k`` (``line`` id ``k``) starts at ``k * spacing_m`` to the right of the first line;
    even lines fly along ``line_azimuth_deg``, odd lines the opposite way; the first line starts
    at the origin.  Turns between lines are cut out (a time gap).  A multirotor in gusty wind:
    pitch/roll wobble of ``gust_deg`` rms at 0.1-1 Hz and ``yaw_wobble_deg`` of yaw, enough
    in-band attitude motion for the survey to be self-compensated.  Geology (``n_dipoles``
    buried dipoles, 30-120 m deep, peaks of 5-30 nT), diurnal, a small smooth cross-track and
    vertical wander and RTK noise on the positions.

    Parameters
    ----------
    seed : int
        Random seed.
    rate_hz : float
        Sample rate [Hz].
    n_lines : int
        Number of survey lines.
    line_length_m : float
        Line length [m]; the first and last sample of each line are at its ends.
    spacing_m : float
        Line spacing [m].
    speed_mps : float
        Ground speed [m/s] (adjusted slightly so that a line holds a whole number of samples).
    line_azimuth_deg : float
        Direction of the even lines [deg from north].
    height_m : float
        Flight height above the origin (ground) [m].
    noise_nT, flux_noise_nT : float
        Scalar and per-axis fluxgate white noise [nT rms].
    earth : EarthField, optional
        Main field.
    coef : array_like, shape (16,), optional
        Aircraft TL coefficients [nT, nT*s].
    faults : float or dict or None
        As in :func:`simulate_calibration` (segments are survey lines).
    origin : (lat, lon, alt)
        Take-off point / local-frame origin [deg, deg, m above the ellipsoid].
    n_dipoles : int
        Number of buried dipoles.
    gust_deg : float
        Pitch and roll wobble [deg rms], 0.1-1 Hz.
    yaw_wobble_deg : float
        Yaw wobble [deg rms], 0.05-0.5 Hz.
    trim_pitch_deg : float
        Mean pitch in forward flight [deg].
    diurnal_nT : float
        Diurnal amplitude scale [nT].
    wander_m : float
        Smooth cross-track wander [m rms] (half of it vertically), 0.01-0.2 Hz.
    pos_noise_m : float
        RTK position noise per axis [m rms].
    turn_s : float
        Duration of each cut turn [s] (plus the transit between lines).

    Returns
    -------
    log : DataFrame
        The columns of :func:`simulate_calibration` without ``truth_maneuver`` and
        ``truth_heading_leg``.
    truth : dict
        JSON-ready ground truth as for the calibration, plus ``plan`` (waypoints
        ``{"lat", "lon", "alt"}`` in flight order: start and end of each line), ``lines`` and
        ``dipoles``.
    """
    check_positive(rate_hz=rate_hz, line_length_m=line_length_m, spacing_m=spacing_m,
                    speed_mps=speed_mps, height_m=height_m)
    check_nonneg(noise_nT=noise_nT, flux_noise_nT=flux_noise_nT, gust_deg=gust_deg,
                  yaw_wobble_deg=yaw_wobble_deg, wander_m=wander_m, pos_noise_m=pos_noise_m,
                  turn_s=turn_s)
    if int(n_lines) < 1:
        raise InputError(f"n_lines: must be at least 1, got {n_lines!r}")
    earth, k, rng, rng_noise, rng_fault = flight_setup(seed, 2, earth, coef)
    n = int(round(line_length_m / speed_mps * rate_hz)) + 1
    if n < 20:
        raise InputError(f"line_length_m: {line_length_m} m at {speed_mps} m/s is too short")
    az = np.deg2rad(line_azimuth_deg)
    along = np.array([np.sin(az), np.cos(az), 0.0])  # east, north, up
    right = np.array([np.cos(az), -np.sin(az), 0.0])
    up = np.array([0.0, 0.0, 1.0])
    s_along = np.linspace(0.0, line_length_m, n)
    tau = np.arange(n) / rate_hz
    gap = float(turn_s + spacing_m / speed_mps)

    times, lines, enus, hdgs, pits, rols = [], [], [], [], [], []
    waypoints_enu: list[np.ndarray] = []
    line_info: list[dict[str, Any]] = []
    t0 = 0.0
    for i in range(int(n_lines)):
        base = i * spacing_m * right + float(height_m) * up
        a, b = (base, base + line_length_m * along)
        if i % 2:
            a, b = b, a
        hdg = np.rad2deg(az) + (180.0 if i % 2 else 0.0)
        u = (b - a) / line_length_m
        xt = band_noise(rng, n, rate_hz, 0.01, 0.2, wander_m) * taper(n, int(rate_hz * 3))
        zt = band_noise(rng, n, rate_hz, 0.01, 0.2, 0.5 * wander_m) * taper(n, int(rate_hz * 3))
        enus.append(a + np.outer(s_along, u) + np.outer(xt, right) + np.outer(zt, up))
        hdgs.append(hdg + band_noise(rng, n, rate_hz, 0.05, 0.5, yaw_wobble_deg))
        pits.append(trim_pitch_deg + band_noise(rng, n, rate_hz, 0.1, 1.0, gust_deg))
        rols.append(band_noise(rng, n, rate_hz, 0.1, 1.0, gust_deg))
        t = t0 + tau
        times.append(t)
        lines.append(np.full(n, i))
        waypoints_enu += [a, b]
        line_info.append({"line": i, "heading_deg": float(np.mod(hdg, 360.0)),
                          "t_start": float(t[0]), "t_end": float(t[-1])})
        t0 = t[-1] + 1.0 / rate_hz + gap

    time = np.concatenate(times)
    enu = np.concatenate(enus)
    line = np.concatenate(lines)

    # Geology: dipoles under the survey area (plus a margin), moments mostly induced.
    wp = np.array(waypoints_enu)
    lo, hi = wp[:, :2].min(axis=0) - 50.0, wp[:, :2].max(axis=0) + 50.0
    e_unit = earth.ned / np.linalg.norm(earth.ned)
    sensor_ned = np.column_stack([enu[:, 1], enu[:, 0], -enu[:, 2]])
    anomaly_ned = np.zeros_like(sensor_ned)
    dipoles: list[dict[str, Any]] = []
    for _ in range(int(n_dipoles)):
        east, north = rng.uniform(lo, hi)
        depth = float(rng.uniform(30.0, 120.0))
        peak = float(rng.uniform(5.0, 30.0)) * rng.choice([-1.0, 1.0], p=[0.2, 0.8])
        rem = rng.normal(size=3)
        direction = e_unit + 0.5 * rem / np.linalg.norm(rem)
        direction /= np.linalg.norm(direction)
        moment = peak * (depth + height_m) ** 3 / (2.0 * MU0_4PI_NT) * direction
        src = np.array([north, east, depth])
        anomaly_ned += dipole_field_ned(sensor_ned, src, moment)
        dipoles.append({"north_m": float(north), "east_m": float(east), "depth_m": depth,
                        "moment_ned_Am2": moment.tolist(), "nominal_peak_nT": float(peak)})

    diurnal, diurnal_comps = diurnal_field(rng, time, diurnal_nT)
    plan = resolve_faults(faults, np.unique(line), rng_fault)
    df, records = assemble(
        time=time, line=line, enu=enu, heading=np.concatenate(hdgs),
        pitch=np.concatenate(pits), roll=np.concatenate(rols), anomaly_ned=anomaly_ned,
        diurnal=diurnal, earth=earth, coef=k, noise_nT=noise_nT, flux_noise_nT=flux_noise_nT,
        pos_noise_m=pos_noise_m, origin=origin, rate_hz=rate_hz, fault_plan=plan,
        rng_noise=rng_noise, rng_fault=rng_fault,
    )  # fmt: skip
    lat, lon, alt = local_to_geodetic(wp[:, 0], wp[:, 1], wp[:, 2], origin)
    truth = common_truth(
        "survey", seed=seed, rate_hz=rate_hz, earth=earth, coef=k, noise_nT=noise_nT,
        flux_noise_nT=flux_noise_nT, pos_noise_m=pos_noise_m, origin=origin,
    )  # fmt: skip
    truth.update({
        "n_lines": int(n_lines), "line_length_m": float(line_length_m),
        "spacing_m": float(spacing_m), "speed_mps": float(line_length_m / ((n - 1) / rate_hz)),
        "line_azimuth_deg": float(line_azimuth_deg), "height_m": float(height_m),
        "turn_s": gap, "wander_m": float(wander_m), "faults": records, "lines": line_info,
        "dipoles": dipoles, "diurnal": diurnal_comps,
        "plan": [{"lat": float(a), "lon": float(b), "alt": float(c)}
                 for a, b, c in zip(lat, lon, alt, strict=True)],
        "plan_enu_m": wp.tolist(),
    })  # fmt: skip
    log.info("survey: %d samples, %d lines, %d faults", len(df), n_lines, len(records))
    return df, truth


def survey_plan(truth: Mapping[str, Any]) -> pd.DataFrame:
    """The survey's mission plan as a table.

    Parameters
    ----------
    truth : mapping
        The truth dict of :func:`simulate_survey`.

    Returns
    -------
    DataFrame
        Waypoints in flight order: ``lat``, ``lon`` [deg], ``alt`` [m above the ellipsoid];
        waypoints ``2k`` and ``2k+1`` are the start and end of survey line ``k``.
    """
    if "plan" not in truth:
        raise InputError("truth: no 'plan' (only survey truths carry one)")
    return pd.DataFrame.from_records(list(truth["plan"]), columns=["lat", "lon", "alt"])


#: Decimals written per column by :func:`write_simulation`.
ROUNDING: dict[str, int] = {
    "time": 3, "lat": 9, "lon": 9, "alt": 3, "heading": 4, "pitch": 4, "roll": 4,
    "flux_x": 4, "flux_y": 4, "flux_z": 4, "mag": 4, "truth_mag_tl": 4,
    "truth_mag_clean": 4, "truth_anomaly": 4, "truth_diurnal": 4, "truth_fault_nT": 4,
}  # fmt: skip


def round_log(df: pd.DataFrame) -> pd.DataFrame:
    """Round a simulated log for writing (see :data:`ROUNDING`; lat/lon 9 decimals ~0.1 mm).

    Parameters
    ----------
    df : DataFrame
        A simulated log.

    Returns
    -------
    DataFrame
        A rounded copy.
    """
    return df.round({k: v for k, v in ROUNDING.items() if k in df.columns})

