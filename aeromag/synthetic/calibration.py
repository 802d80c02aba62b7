"""The calibration flight: boxes on the four cardinal headings with pitch/roll/yaw maneuvers."""


import logging
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from ..errors import InputError
from .faults import assemble, check_nonneg, check_positive, common_truth, resolve_faults
from .physics import (
    CAL_HEADINGS_DEG,
    DEFAULT_ORIGIN,
    MANEUVER_AMPLITUDE_DEG,
    MANEUVERS,
    EarthField,
    band_noise,
    diurnal_field,
    flight_setup,
    taper,
)

log = logging.getLogger(__name__)


def simulate_calibration(
    *,
    seed: int = 0,
    rate_hz: float = 10.0,
    n_boxes: int = 2,
    maneuver_s: float = 25.0,
    noise_nT: float = 0.02,
    flux_noise_nT: float = 0.5,
    earth: EarthField | None = None,
    coef: Any | None = None,
    faults: float | Mapping[int, str] | None = None,
    cut_turns: bool = True,
    origin: tuple[float, float, float] = DEFAULT_ORIGIN,
    speed_mps: float = 8.0,
    height_m: float = 100.0,
    turn_s: float = 20.0,
    turbulence_deg: float = 0.3,
    trim_pitch_deg: float = -3.0,
    diurnal_nT: float = 3.0,
    pos_noise_m: float = 0.02,
    manoeuvre_s: float | None = None,
) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Simulate a calibration flight: boxes on the four cardinal headings with maneuvers.

    Each box flies north, east, south and west (a square); on each heading the aircraft makes
    a pitch (+-5 deg), a roll (+-10 deg) and a yaw (+-5 deg) oscillation of ``maneuver_s``
    seconds each (a few cycles at a random period of 2.5-8 s, tapered at the ends), with small
    turbulence on all axes.  Each maneuver is its own ``line`` (``12 * n_boxes`` segments,
    ids from 0).  No geology (a calibration is flown high over quiet ground).

    Parameters
    ----------
    seed : int
        Random seed; the same seed gives the same flight.
    rate_hz : float
        Sample rate [Hz].
    n_boxes : int
        Number of boxes (four headings each).
    maneuver_s : float
        Duration of each maneuver [s] (``manoeuvre_s``, the old spelling, is accepted too).
    noise_nT : float
        Scalar magnetometer white noise [nT rms].
    flux_noise_nT : float
        Fluxgate white noise per axis [nT rms].
    earth : EarthField, optional
        Main field; ``EarthField()`` when omitted.
    coef : array_like, shape (16,), optional
        Aircraft TL coefficients [nT, nT*s]; :func:`default_aircraft_coef` when omitted.
    faults : float or dict or None
        None: no faults; a fraction in [0, 1]: that share of segments chosen at random, kinds
        cycled over :data:`FAULT_KINDS`; a dict ``{segment_id: kind}``.
    cut_turns : bool
        Cut the turns between headings out of the log (a time gap of ``turn_s``); otherwise
        keep them: the aircraft hovers at the corner and yaws by 90 deg over ``turn_s``
        (``line`` -1, ``truth_maneuver`` "turn", ``truth_heading_leg`` -1).
    origin : (lat, lon, alt)
        Take-off point and local-frame origin [deg, deg, m above the ellipsoid].
    speed_mps : float
        Ground speed along each leg [m/s].
    height_m : float
        Flight height above the origin [m].
    turn_s : float
        Duration of each cut turn [s].
    turbulence_deg : float
        Turbulence on heading, pitch and roll [deg rms], 0.05-1.5 Hz.
    trim_pitch_deg : float
        Mean pitch in forward flight [deg] (nose down is negative).
    diurnal_nT : float
        Diurnal amplitude scale [nT].
    pos_noise_m : float
        RTK position noise per axis [m rms].

    Returns
    -------
    log : DataFrame
        ``time`` [s], ``line``, ``lat``/``lon`` [deg], ``alt`` [m], ``heading``/``pitch``/
        ``roll`` [deg], ``flux_x/y/z`` [nT], ``mag`` [nT], ``truth_mag_tl`` [nT],
        ``truth_mag_clean`` [nT], ``truth_anomaly`` [nT], ``truth_diurnal`` [nT],
        ``truth_fault`` (kind or ""), ``truth_fault_nT`` (fault effect on ``mag``, nT),
        ``truth_maneuver`` ("pitch"/"roll"/"yaw"), ``truth_heading_leg`` (N=0, E=1, S=2, W=3).
    truth : dict
        JSON-ready ground truth: terms, coef, earth field, noise levels, rate, seed, faults
        (``[{"segment", "kind", "params"}]``), segments and diurnal components.
    """
    if manoeuvre_s is not None:
        maneuver_s = manoeuvre_s
    check_positive(rate_hz=rate_hz, maneuver_s=maneuver_s, speed_mps=speed_mps)
    check_nonneg(noise_nT=noise_nT, flux_noise_nT=flux_noise_nT, turn_s=turn_s,
                  turbulence_deg=turbulence_deg, pos_noise_m=pos_noise_m)
    if int(n_boxes) < 1:
        raise InputError(f"n_boxes: must be at least 1, got {n_boxes!r}")
    earth, k, rng, rng_noise, rng_fault = flight_setup(seed, 1, earth, coef)
    m = int(round(maneuver_s * rate_hz))
    if m < 20:
        raise InputError(f"maneuver_s: {maneuver_s} s at {rate_hz} Hz gives under 20 samples")
    n_leg = len(MANEUVERS) * m
    gap = float(turn_s) if cut_turns else 0.0

    times, lines, enus, hdgs, pits, rols, mans, legs = [], [], [], [], [], [], [], []
    segments: list[dict[str, Any]] = []
    t0 = 0.0
    pos = np.array([0.0, 0.0, float(height_m)])  # east, north, up
    seg = 0
    ramp = int(round(2.0 * rate_hz))
    for box in range(int(n_boxes)):
        for leg, hdg in enumerate(CAL_HEADINGS_DEG):
            last = box == int(n_boxes) - 1 and leg == len(CAL_HEADINGS_DEG) - 1
            tau = np.arange(n_leg) / rate_hz
            t = t0 + tau
            direction = np.array([np.sin(np.deg2rad(hdg)), np.cos(np.deg2rad(hdg)), 0.0])
            enus.append(pos + np.outer(tau * speed_mps, direction))
            att = {
                ax: band_noise(rng, n_leg, rate_hz, 0.05, 1.5, turbulence_deg)
                for ax in MANEUVERS
            }
            man_col = np.empty(n_leg, dtype=object)
            line_col = np.empty(n_leg, dtype=int)
            for j, man in enumerate(MANEUVERS):
                sl = slice(j * m, (j + 1) * m)
                period = float(rng.uniform(2.5, 8.0))
                phase = float(rng.uniform(0, 2 * np.pi))
                amp = MANEUVER_AMPLITUDE_DEG[man]
                att[man][sl] += (
                    amp * taper(m, ramp) * np.sin(2 * np.pi * tau[:m] / period + phase)
                )
                man_col[sl] = man
                line_col[sl] = seg
                segments.append({
                    "line": seg, "maneuver": man, "heading_deg": hdg, "heading_leg": leg,
                    "period_s": period, "amplitude_deg": amp,
                    "t_start": float(t[sl][0]), "t_end": float(t[sl][-1]),
                })  # fmt: skip
                seg += 1
            times.append(t)
            lines.append(line_col)
            hdgs.append(hdg + att["yaw"])
            pits.append(trim_pitch_deg + att["pitch"])
            rols.append(att["roll"])
            mans.append(man_col)
            legs.append(np.full(n_leg, leg))
            pos = enus[-1][-1] + direction * speed_mps / rate_hz
            t0 = t[-1] + 1.0 / rate_hz + gap
            if not cut_turns and turn_s > 0 and not last:
                # Kept turn: hover at the corner and yaw smoothly by +90 deg (line -1).
                nt = max(2, int(round(turn_s * rate_hz)))
                frac = 0.5 - 0.5 * np.cos(np.pi * np.arange(nt) / nt)
                times.append(t0 + np.arange(nt) / rate_hz)
                lines.append(np.full(nt, -1))
                enus.append(np.repeat(pos[None, :], nt, axis=0))
                hdgs.append(hdg + 90.0 * frac + band_noise(rng, nt, rate_hz, 0.05, 1.5,
                                                             turbulence_deg))
                pits.append(band_noise(rng, nt, rate_hz, 0.05, 1.5, turbulence_deg))
                rols.append(band_noise(rng, nt, rate_hz, 0.05, 1.5, turbulence_deg))
                mans.append(np.full(nt, "turn", dtype=object))
                legs.append(np.full(nt, -1))
                t0 += nt / rate_hz

    time = np.concatenate(times)
    diurnal, diurnal_comps = diurnal_field(rng, time, diurnal_nT)
    line = np.concatenate(lines)
    plan = resolve_faults(faults, np.unique(line[line >= 0]), rng_fault)
    df, records = assemble(
        time=time, line=line, enu=np.concatenate(enus), heading=np.concatenate(hdgs),
        pitch=np.concatenate(pits), roll=np.concatenate(rols),
        anomaly_ned=np.zeros((len(time), 3)), diurnal=diurnal, earth=earth, coef=k,
        noise_nT=noise_nT, flux_noise_nT=flux_noise_nT, pos_noise_m=pos_noise_m,
        origin=origin, rate_hz=rate_hz, fault_plan=plan, rng_noise=rng_noise,
        rng_fault=rng_fault,
    )  # fmt: skip
    df["truth_maneuver"] = np.concatenate(mans).astype(str)
    df["truth_heading_leg"] = np.concatenate(legs).astype(int)
    truth = common_truth(
        "calibration", seed=seed, rate_hz=rate_hz, earth=earth, coef=k, noise_nT=noise_nT,
        flux_noise_nT=flux_noise_nT, pos_noise_m=pos_noise_m, origin=origin,
    )  # fmt: skip
    truth.update({
        "n_boxes": int(n_boxes), "manoeuvre_s": float(maneuver_s), "cut_turns": bool(cut_turns),
        "turn_s": float(gap), "speed_mps": float(speed_mps), "height_m": float(height_m),
        "headings_deg": list(CAL_HEADINGS_DEG), "faults": records, "segments": segments,
        "diurnal": diurnal_comps,
    })  # fmt: skip
    log.info("calibration: %d samples, %d segments, %d faults", len(df), seg, len(records))
    return df, truth


