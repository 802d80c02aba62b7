"""Multirotor survey-mission simulator with injected magnetic heading disturbances (methods M2).

A quadrotor flies a lawn-mower plan (north-south survey lines joined by short east-west cross
legs) on RTK DGPS.  Its flight controller:

* estimates heading with a complementary filter: a perfect gyro plus a correction towards the
  tilt-compensated magnetometer heading with time constant ``tau_s``;
* follows the line with a velocity loop (drag feed-forward, gain ``kv``) and a cross-track
  position loop (gain ``kp``); the commanded horizontal acceleration, computed in the NED frame,
  is turned into body-frame thrust with the *estimated* heading, so the acceleration actually
  applied is the command rotated by the heading error ``dpsi = psi_true - psi_est``;
* holds its yaw on the leg direction using the estimated heading.

Wind gusts (an Ornstein-Uhlenbeck process, zero mean) push the vehicle through linear drag; the
logged position has RTK noise (2 cm per axis by default).  A disturbance is a field added to the
magnetometer's body Y axis, ramping at a given rate (G/s, 1 G = 1e5 nT) from its onset to a
ceiling (0.2 G), held, and removed ``hold_s`` (60 s) after onset or at the end of the leg.  The
vehicle hovers at each waypoint (turning to the next leg) long enough for the filter to
re-converge.  Options add what real sessions hold: a take-off point away from the plan with the
transits to and from it, time on the ground, legs flown twice with the transit back, any plan,
and a leg that ends before its waypoint (ArduCopter's ``WPNAV_RADIUS``).

The log has the body rates ``gyro_x/y/z`` (rad/s, the mean over the interval that ends at the
row, from the true attitude), as the interface defines them.

Truth columns: ``truth_xtrack_m`` (noise-free distance to the current leg's line in NED, NaN off
leg), ``truth_leg`` (the leg being flown, -1 otherwise), ``truth_heading`` (true heading, deg),
``truth_dpsi_deg`` (heading error of the estimate, deg), ``truth_disturbance_nT``,
``truth_mag_heading``, and with the options ``truth_phase`` (ground, climb, hover, leg, transit,
land).
``mission_truth.json`` lists per leg the disturbance kind, onset time and rate.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd
from scipy.signal import lfilter

from .._core.angles import wrap_rad
from .._core.geodesy import ned_to_geodetic

__all__ = ["simulate_mission", "plan_waypoints_ned", "ned_to_geodetic", "DEFAULT_DISTURBANCES",
           "FAST_RATE_G_S", "SLOW_RATE_G_S"]

#: Disturbance ramp rates of the study, G/s.
FAST_RATE_G_S = 0.06
SLOW_RATE_G_S = 0.0125

#: Default disturbance per leg: legs not listed are undisturbed.
DEFAULT_DISTURBANCES: dict[int, str] = {2: "fast", 4: "slow", 6: "fast", 8: "slow"}


def _wrap_rad(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


#: Flight phases of the simulator (``truth_phase``); ``carry``: the disarmed vehicle carried
#: on the ground between two flights (``flights`` > 1).
_PHASES = ("ground", "climb", "hover", "leg", "transit", "land", "carry")

#: Height at which a person carries the vehicle above the ground, m (and the bob of the walk).
CARRY_HEIGHT_M = 0.8
CARRY_BOB_M = 0.1
#: How far the walker strays either side of the straight line, m.
CARRY_WANDER_M = 1.5


def _body_rates(rec: np.ndarray, dt: float, noise_rad_s: float, seed: int
                ) -> dict[str, np.ndarray]:
    """Body angular rates over each sampling interval, as a strapdown gyro logs them.

    On each row the mean rate over the interval that ends at that row (the interface's
    convention), from the change of the true Euler angles (roll, pitch, yaw) across the
    interval, evaluated at its midpoint: ``p = phi' - psi' sin(theta)``,
    ``q = theta' cos(phi) + psi' sin(phi) cos(theta)``,
    ``r = psi' cos(phi) cos(theta) - theta' sin(phi)``.  Level, ``r = (psi_k - psi_k-1) / dt``
    exactly.  The vehicle is at rest and level with yaw 0 before the first row.

    Parameters
    ----------
    rec : ndarray
        Simulator record (roll deg in column 6, pitch deg in 5, true heading deg in 12).
    dt : float
        Sample interval, s.
    noise_rad_s : float
        White-noise standard deviation added per axis, rad/s.
    seed : int
        Seed of the noise stream (independent of the simulator's main stream).

    Returns
    -------
    dict
        ``gyro_x``, ``gyro_y``, ``gyro_z`` arrays, rad/s.
    """
    eul = np.deg2rad(rec[:, [6, 5, 12]])
    prev = np.vstack([np.zeros((1, 3)), eul[:-1]])
    d = eul - prev
    d[:, 2] = wrap_rad(d[:, 2])
    phid, thd, psid = (d / dt).T
    phm, thm = (prev + 0.5 * d)[:, 0], (prev + 0.5 * d)[:, 1]
    rates = np.column_stack([
        phid - psid * np.sin(thm),
        thd * np.cos(phm) + psid * np.sin(phm) * np.cos(thm),
        psid * np.cos(phm) * np.cos(thm) - thd * np.sin(phm),
    ])
    if noise_rad_s > 0:
        rates = rates + np.random.default_rng([seed, 17]).normal(0.0, noise_rad_s, rates.shape)
    return {"gyro_x": rates[:, 0], "gyro_y": rates[:, 1], "gyro_z": rates[:, 2]}


def _armed(phase: np.ndarray, fs_hz: float) -> np.ndarray:
    """Armed per row: in flight, from 2 s before each take-off to 1 s after touchdown."""
    on_ground = np.isin(phase, [_PHASES.index("ground"), _PHASES.index("carry")])
    armed = ~on_ground
    pre, post = int(round(2.0 * fs_hz)), int(round(1.0 * fs_hz))
    edges = np.flatnonzero(np.diff(on_ground.astype(np.int8)))
    for i in edges:
        if on_ground[i]:                 # take-off after row i
            armed[max(0, i + 1 - pre):i + 1] = True
        else:                            # touchdown at row i + 1
            armed[i + 1:i + 1 + post] = True
    return armed


def plan_waypoints_ned(n_lines: int = 6, line_m: float = 450.0, spacing_m: float = 20.0
                       ) -> np.ndarray:
    """Waypoints of a lawn-mower plan in NED (origin at the first waypoint).

    Parameters
    ----------
    n_lines : int
        Number of north-south survey lines.
    line_m : float
        Line length, m.
    spacing_m : float
        Line spacing (length of the cross legs), m.

    Returns
    -------
    ndarray, shape (2 * n_lines, 3)
        North, east, down, m (all at down = 0).
    """
    pts = []
    for i in range(n_lines):
        e = i * spacing_m
        ends = (0.0, line_m) if i % 2 == 0 else (line_m, 0.0)
        pts += [(ends[0], e, 0.0), (ends[1], e, 0.0)]
    return np.asarray(pts, dtype=np.float64)


def simulate_mission(
    *,
    seed: int = 0,
    origin: tuple[float, float, float] = (47.3, 8.5, 500.0),
    n_lines: int = 6,
    line_m: float = 450.0,
    spacing_m: float = 20.0,
    height_m: float = 40.0,
    speed_m_s: float = 5.0,
    fs_hz: float = 10.0,
    disturbances: dict[int, str] | None = None,
    onset_after_s: float = 12.0,
    ceiling_g: float = 0.2,
    hold_s: float = 60.0,
    earth_field_g: float = 0.6,
    inclination_deg: float = 60.0,
    declination_deg: float = 0.0,
    tau_s: float = 1.0,
    flux_noise_nT: float = 1200.0,
    flux_noise_tau_s: float = 0.3,
    rtk_noise_m: float = 0.02,
    gust_m_s: float = 0.4,
    gust_tau_s: float = 4.0,
    hover_s: float = 10.0,
    gyro_noise_rad_s: float = 0.0,
    waypoints_ned: np.ndarray | None = None,
    home_ne_m: tuple[float, float] | None = None,
    ground_s: float = 0.0,
    refly_legs: tuple[int, ...] = (),
    wp_radius_m: float = 0.0,
    flights: int = 1,
    carry_speed_m_s: float = 1.2,
    armed_column: bool = False,
) -> tuple[pd.DataFrame, pd.DataFrame, dict[str, Any]]:
    """Simulate a lawn-mower survey mission with magnetic heading disturbances.

    Parameters
    ----------
    seed : int
        Random seed.
    origin : (float, float, float)
        First waypoint: latitude [deg], longitude [deg], ellipsoidal height [m]; take-off is
        ``height_m`` below it.
    n_lines, line_m, spacing_m : int, float, float
        Plan layout: number of north-south lines, their length [m] and spacing [m].
    height_m : float
        Survey height above the take-off point, m.
    speed_m_s : float
        Cruise speed, m/s.
    fs_hz : float
        Sample (and integration) rate, Hz.
    disturbances : dict, optional
        ``{leg: "fast" | "slow"}`` (default :data:`DEFAULT_DISTURBANCES`); rates
        :data:`FAST_RATE_G_S` and :data:`SLOW_RATE_G_S`.
    onset_after_s : float
        Onset of a leg's disturbance after the vehicle leaves the leg's first waypoint, s.
    ceiling_g : float
        Largest disturbance, G.
    hold_s : float
        The disturbance is removed this long after its onset (or at the end of the leg), s.
    earth_field_g, inclination_deg, declination_deg : float
        Earth field magnitude [G], inclination [deg] and declination [deg].
    tau_s : float
        Time constant of the heading complementary filter, s.
    flux_noise_nT : float
        Fluxgate noise per axis (motor interference included), nT; an Ornstein-Uhlenbeck
        process with correlation time ``flux_noise_tau_s`` [s] (white when 0).
    rtk_noise_m : float
        RTK position noise per axis, m.
    gust_m_s, gust_tau_s : float
        Gust standard deviation per horizontal axis [m/s] and correlation time [s].
    hover_s : float
        Hover at each waypoint (turning), s.
    gyro_noise_rad_s : float
        White noise added to the logged body rates ``gyro_x/y/z``, rad/s (0: the perfect gyro
        the heading filter uses; drawn from its own random stream so the other columns do not
        change).
    waypoints_ned : ndarray, shape (m, 3), optional
        The plan's waypoints in NED at ``origin`` [m] instead of the lawn-mower
        (``n_lines``, ``line_m``, ``spacing_m`` then unused); the first must be (0, 0, 0).
    home_ne_m : (float, float), optional
        Take-off and landing point, north and east of the first waypoint [m]: the vehicle
        climbs there, transits to the first waypoint, and after the last leg transits back
        and lands there (default: take-off under the first waypoint, landing under the last).
    ground_s : float
        Time on the ground before take-off and after landing, s.
    refly_legs : tuple of int
        Legs flown twice: after the first pass the vehicle transits back to the leg's first
        waypoint (off plan, along the leg reversed) and flies it again; a disturbance of the
        leg acts on the first pass only.
    wp_radius_m : float
        The leg ends when the vehicle is this close to its last waypoint, m (ArduCopter's
        ``WPNAV_RADIUS``; it then settles there in the hover phase); 0: the leg lasts until
        the vehicle has stopped at the waypoint.
    flights : int
        The mission is flown this many times in one log (a day's work): after each landing
        the vehicle rests ``ground_s`` (at least 5 s) on the ground, disarmed, is carried on
        the ground (``CARRY_HEIGHT_M`` above it, walking at ``carry_speed_m_s`` [m/s] with a
        bob of ``CARRY_BOB_M``, straying ``CARRY_WANDER_M`` either side) back to its take-off
        point, rests again and takes off for the next flight.  Without ``home_ne_m`` it lands
        under the last waypoint and is carried back under the first: along the plan's line
        reversed, ``height_m`` below it.
    carry_speed_m_s : float
        Walking speed of the carry between flights, m/s.
    armed_column : bool
        Add ``armed`` (bool): true from 2 s before each take-off to 1 s after its touchdown,
        as an autopilot logs it (ArduPilot ``EV`` arm/disarm, PX4 ``vehicle_status``).

    Returns
    -------
    log, plan : DataFrame
        The mission log (canonical columns + ``truth_*``; with any of ``waypoints_ned``,
        ``home_ne_m``, ``ground_s``, ``refly_legs`` also ``truth_phase``: ``ground``,
        ``climb``, ``hover``, ``leg``, ``transit``, ``land``, and ``carry`` with ``flights``
        > 1) and the plan (``lat``, ``lon``, ``alt``).
    truth : dict
        ``{"legs": [{"leg", "disturbance", "rate_G_s", "onset_time"}...], ...}``.
    """
    rng = np.random.default_rng(seed)
    dist = DEFAULT_DISTURBANCES if disturbances is None else dict(disturbances)
    flights = int(flights)
    if flights < 1 or not carry_speed_m_s > 0:
        raise ValueError("flights must be >= 1 and carry_speed_m_s > 0")
    if flights > 1:
        ground_s = max(ground_s, 5.0)
    extended = (waypoints_ned is not None or home_ne_m is not None or ground_s > 0
                or bool(refly_legs) or flights > 1)
    if waypoints_ned is None:
        wps = plan_waypoints_ned(n_lines, line_m, spacing_m)
    else:
        wps = np.asarray(waypoints_ned, dtype=np.float64)
        if wps.ndim != 2 or wps.shape[1] != 3 or len(wps) < 2 or np.any(wps[0] != 0.0):
            raise ValueError("waypoints_ned must be (m >= 2, 3) NED metres starting at 0, 0, 0")
    n_legs = len(wps) - 1
    home = (0.0, 0.0) if home_ne_m is None else (float(home_ne_m[0]), float(home_ne_m[1]))
    refly = {int(k) for k in refly_legs}
    reflown: set[int] = set()
    dt = 1.0 / fs_hz
    g = 9.81
    kd, kv, kp = 0.3, 1.5, 0.5
    inc, dec = math.radians(inclination_deg), math.radians(declination_deg)
    b0 = earth_field_g * 1e5
    bn, be, bd = (b0 * math.cos(inc) * math.cos(dec), b0 * math.cos(inc) * math.sin(dec),
                  b0 * math.sin(inc))

    max_steps = int((120.0 + n_legs * (line_m / speed_m_s + 3.0 * hover_s + 60.0)) * fs_hz)
    if extended:
        legs_m = np.linalg.norm(np.diff(wps, axis=0), axis=1)
        total = float(legs_m.sum() + sum(2.0 * legs_m[k] for k in refly if k < n_legs)
                      + 2.0 * (np.hypot(*home) + np.linalg.norm(wps[-1, :2] - np.array(home))))
        max_steps = int((200.0 + 2.0 * ground_s + 2.0 * total / speed_m_s
                         + (n_legs + 2 * len(refly)) * (3.0 * hover_s + 30.0)) * fs_hz)
    if flights > 1:
        span = float(np.linalg.norm(np.asarray(home) - (wps[-1, :2] if home_ne_m is None
                                                         else np.asarray(home))))
        max_steps = flights * (max_steps + int((2.0 * ground_s + span / carry_speed_m_s
                                                + 10.0) * fs_hz))
    gust_a = math.exp(-dt / gust_tau_s)
    gust_b = gust_m_s * math.sqrt(1.0 - gust_a * gust_a)
    white = rng.standard_normal((max_steps, 2))
    fnoise = rng.standard_normal((max_steps, 3)) * flux_noise_nT
    if flux_noise_tau_s > 0:
        fa = math.exp(-dt / flux_noise_tau_s)
        fnoise = lfilter([math.sqrt(1.0 - fa * fa)], [1.0, -fa], fnoise, axis=0)

    rec = np.full((max_steps, 17), np.nan)
    pn, pe, pd_ = home[0], home[1], height_m
    vn, ve, vd = 0.0, 0.0, 0.0
    psi = 0.0
    psi_est = 0.0
    wn, we = 0.0, 0.0
    phase, leg, phase_t = ("ground" if ground_s > 0 else "climb"), -1, 0.0
    tr_a = tr_b = wps[0]
    after_transit = "hover"
    landed_t = -1.0
    flights_done = 0
    carry_from = np.zeros(2)
    carry_t = s_c = 0.0
    u_c = np.zeros(2)
    ground_ne: tuple[float, float] | None = None
    onset: dict[int, float] = {}
    start_t: dict[int, float] = {}
    delta = 0.0
    t = 0.0
    i = 0
    for i in range(max_steps):
        t = i * dt
        # ---------------------------------------------------------------- guidance
        psi_des = psi_est
        an_c = ae_c = 0.0
        if phase == "ground":
            vd_c = 0.0
            if landed_t < 0 and t >= (ground_s if flights_done == 0 else phase_t + ground_s):
                phase, phase_t = "climb", t
                reflown.clear()
            elif landed_t >= 0 and t - landed_t >= ground_s:
                if flights_done >= flights:
                    break
                phase, carry_t, carry_from, s_c = "carry", t, np.array([pn, pe]), 0.0
        elif phase == "carry":
            vd_c = 0.0
            to = np.asarray(home) - carry_from
            dist_c = float(np.hypot(*to))
            s_c = min(carry_speed_m_s * (t - carry_t), dist_c)
            u_c = to / dist_c if dist_c > 0 else np.zeros(2)
            if s_c >= dist_c:
                phase, phase_t, landed_t, leg = "ground", t, -1.0, -1
        elif phase == "climb":
            vd_c = -2.0 if pd_ > 1.0 else -max(0.3, 2.0 * pd_)
            if pd_ <= 0.05:
                phase, phase_t = "hover", t
                vd_c = 0.0
                if home_ne_m is not None:
                    phase, tr_a, tr_b = "transit", np.array([home[0], home[1], 0.0]), wps[0]
                    after_transit = "hover"
            an_c = kv * (0.0 - vn) + kp * (home[0] - pn)
            ae_c = kv * (0.0 - ve) + kp * (home[1] - pe)
        elif phase == "hover":
            target = wps[leg + 1] if leg >= 0 else wps[0]
            nxt = leg + 1
            if leg >= 0 and leg in refly and leg not in reflown:
                nxt = leg   # about to go back and fly it again
            if nxt < n_legs:
                du = wps[nxt + 1] - wps[nxt]
                psi_des = math.atan2(du[1], du[0])
            an_c = kv * (0.0 - vn) + kp * (target[0] - pn)
            ae_c = kv * (0.0 - ve) + kp * (target[1] - pe)
            vd_c = 0.5 * (target[2] - pd_)
            if t - phase_t >= (hover_s if leg >= 0 else 15.0):
                if nxt == leg:
                    reflown.add(leg)
                    phase, tr_a, tr_b = "transit", wps[leg + 1], wps[leg]
                    after_transit, leg = "hover", leg - 1
                elif nxt < n_legs:
                    phase, leg, phase_t = "leg", nxt, t
                    start_t.setdefault(leg, t)
                    if leg in dist and leg not in onset:
                        onset[leg] = t + onset_after_s
                elif home_ne_m is not None and after_transit != "land":
                    phase, tr_a, tr_b = "transit", wps[-1], np.array([home[0], home[1],
                                                                    wps[-1][2]])
                    after_transit = "land"
                else:
                    phase, phase_t = "land", t
        elif phase in ("leg", "transit"):
            a, b = (wps[leg], wps[leg + 1]) if phase == "leg" else (tr_a, tr_b)
            un, ue = b[0] - a[0], b[1] - a[1]
            length = math.hypot(un, ue)
            un, ue = un / length, ue / length
            psi_des = math.atan2(ue, un)
            rn, re_ = pn - a[0], pe - a[1]
            along = rn * un + re_ * ue
            cn, ce = rn - along * un, re_ - along * ue
            rem = length - along
            vref = max(-speed_m_s, min(speed_m_s, 0.8 * rem))
            an_c = kd * vn + kv * (vref * un - vn) - kp * cn
            ae_c = kd * ve + kv * (vref * ue - ve) - kp * ce
            vd_c = 0.5 * (a[2] + min(max(along / length, 0.0), 1.0) * (b[2] - a[2]) - pd_)
            if (abs(rem) < 0.3 and math.hypot(vn, ve) < 0.3) or (
                    phase == "leg" and wp_radius_m > 0 and rem < wp_radius_m):
                phase, phase_t = ("hover" if phase == "leg" else after_transit), t
        else:  # land
            land_n, land_e = (home if home_ne_m is not None else (wps[-1][0], wps[-1][1]))
            vd_c = 1.0 if pd_ < height_m - 1.0 else 0.3
            an_c = kv * (0.0 - vn) + kp * (land_n - pn)
            ae_c = kv * (0.0 - ve) + kp * (land_e - pe)
            if pd_ >= height_m:
                if ground_s <= 0:
                    break
                phase, landed_t = "ground", t
                flights_done += 1
        # ---------------------------------------------------------------- disturbance
        if phase == "leg" and leg in onset and onset[leg] <= t < onset[leg] + hold_s:
            rate = (FAST_RATE_G_S if dist[leg] == "fast" else SLOW_RATE_G_S) * 1e5
            delta = min(rate * (t - onset[leg]), ceiling_g * 1e5)
        else:
            delta = 0.0
        # ---------------------------------------------------------------- dynamics
        if phase == "ground" and ground_ne is None:
            ground_ne = (pn, pe)
        elif phase != "ground":
            ground_ne = None
        dpsi = _wrap_rad(psi - psi_est)
        cd, sd = math.cos(dpsi), math.sin(dpsi)
        an = cd * an_c - sd * ae_c
        ae = sd * an_c + cd * ae_c
        amax = 4.0
        s = math.hypot(an, ae)
        if s > amax:
            an, ae = an * amax / s, ae * amax / s
        # thrust tilt from the horizontal thrust acceleration (body axes, true heading)
        cps, sps = math.cos(psi), math.sin(psi)
        abx = cps * an + sps * ae
        aby = -sps * an + cps * ae
        theta = -math.atan2(abx, g)
        phi = math.atan2(aby * math.cos(theta), g)
        wn = gust_a * wn + gust_b * white[i, 0]
        we = gust_a * we + gust_b * white[i, 1]
        vn += (an - kd * (vn - wn) - kd * 0.0) * dt
        ve += (ae - kd * (ve - we)) * dt
        vd += (2.0 * (vd_c - vd)) * dt
        # drag feed-forward: the commanded kd*v cancels drag; the residual is gusts
        pn += vn * dt
        pe += ve * dt
        pd_ += vd * dt
        if phase == "ground":   # on the ground: still, level, no yaw
            pn, pe, pd_ = ground_ne[0], ground_ne[1], height_m
            vn, ve, vd, theta, phi = 0.0, 0.0, 0.0, 0.0, 0.0
        elif phase == "carry":   # carried by hand: walking pace, held level, a bob
            # the walker strays up to CARRY_WANDER_M either side of the straight line
            wander = CARRY_WANDER_M * math.sin(2.0 * math.pi * (t - carry_t) / 60.0)
            pn = carry_from[0] + s_c * u_c[0] - wander * u_c[1]
            pe = carry_from[1] + s_c * u_c[1] + wander * u_c[0]
            pd_ = height_m - CARRY_HEIGHT_M - CARRY_BOB_M * math.sin(2.0 * math.pi * 1.8 * t)
            vn, ve, vd, theta, phi = 0.0, 0.0, 0.0, 0.0, 0.0
        # yaw loop on the estimated heading; gyro is perfect
        rate_cmd = max(-0.5, min(0.5, 1.0 * _wrap_rad(psi_des - psi_est)))
        if phase in ("ground", "carry"):
            rate_cmd = 0.0
        psi = _wrap_rad(psi + rate_cmd * dt)
        # ---------------------------------------------------------------- magnetometer
        cth, sth, cph, sph = math.cos(theta), math.sin(theta), math.cos(phi), math.sin(phi)
        cps, sps = math.cos(psi), math.sin(psi)
        bx = cth * cps * bn + cth * sps * be - sth * bd
        by = ((sph * sth * cps - cph * sps) * bn + (sph * sth * sps + cph * cps) * be
              + sph * cth * bd)
        bz = ((cph * sth * cps + sph * sps) * bn + (cph * sth * sps - sph * cps) * be
              + cph * cth * bd)
        fx, fy, fz = bx + fnoise[i, 0], by + delta + fnoise[i, 1], bz + fnoise[i, 2]
        xh = fx * cth + (fy * sph + fz * cph) * sth
        yh = fy * cph - fz * sph
        psi_mag = math.atan2(-yh, xh) + dec
        psi_est = _wrap_rad(psi_est + rate_cmd * dt + _wrap_rad(psi_mag - psi_est) * dt / tau_s)
        # ---------------------------------------------------------------- truth
        xt = math.nan
        rec[i] = (t, pn, pe, pd_, math.degrees(psi_est) % 360.0, math.degrees(theta),
                  math.degrees(phi), fx, fy, fz, xt, leg if phase == "leg" else -1,
                  math.degrees(psi) % 360.0, math.degrees(_wrap_rad(psi - psi_est)), delta,
                  math.degrees(psi_mag) % 360.0, _PHASES.index(phase))
    rec = rec[: i + 1]
    rec = rec[np.isfinite(rec[:, 0])]
    n = len(rec)
    true_leg = rec[:, 11].astype(int)
    for k in np.unique(true_leg[true_leg >= 0]):
        m = true_leg == k
        ab = wps[k + 1] - wps[k]
        rel = rec[m, 1:4] - wps[k]
        rec[m, 10] = np.linalg.norm(np.cross(rel, ab), axis=1) / np.linalg.norm(ab)
    noisy = rec[:, 1:4] + rng.normal(0.0, rtk_noise_m, (n, 3))
    geo = ned_to_geodetic(noisy, origin)
    plan_geo = ned_to_geodetic(wps, origin)
    df = pd.DataFrame({
        "time": np.round(rec[:, 0], 6),
        "lat": geo[:, 0], "lon": geo[:, 1], "alt": geo[:, 2],
        "heading": rec[:, 4], "pitch": rec[:, 5], "roll": rec[:, 6],
        "flux_x": rec[:, 7], "flux_y": rec[:, 8], "flux_z": rec[:, 9],
        **_body_rates(rec, dt, gyro_noise_rad_s, seed),
        "truth_xtrack_m": rec[:, 10], "truth_leg": rec[:, 11].astype(int),
        "truth_heading": rec[:, 12], "truth_dpsi_deg": rec[:, 13],
        "truth_disturbance_nT": rec[:, 14], "truth_mag_heading": rec[:, 15],
    })
    if extended:
        df["truth_phase"] = np.asarray(_PHASES, dtype=object)[rec[:, 16].astype(int)]
    if armed_column:
        df["armed"] = _armed(rec[:, 16].astype(int), fs_hz)
    plan = pd.DataFrame({"lat": plan_geo[:, 0], "lon": plan_geo[:, 1], "alt": plan_geo[:, 2]})
    legs = []
    for k in range(n_legs):
        kind = dist.get(k)
        legs.append({
            "leg": k,
            "disturbance": kind,
            "rate_G_s": (FAST_RATE_G_S if kind == "fast" else SLOW_RATE_G_S) if kind else None,
            "onset_time": onset.get(k),
            "start_time": start_t.get(k),
        })
    truth = {
        "legs": legs, "seed": seed, "origin": list(origin), "fs_hz": fs_hz,
        "earth_field_G": earth_field_g, "inclination_deg": inclination_deg,
        "declination_deg": declination_deg, "tau_s": tau_s, "ceiling_G": ceiling_g,
        "rtk_noise_m": rtk_noise_m, "flux_noise_nT": flux_noise_nT, "gust_m_s": gust_m_s,
    }
    return df, plan, truth
