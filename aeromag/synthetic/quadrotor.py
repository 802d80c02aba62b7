"""A quadrotor with the sensors of the navigation study, with ground truth (an oracle).

Scenarios (methods.md M4): a 60 s hover at 2 m, and a 60 s rectangle (20 m x 10 m) flown at
1.5 m/s and 2 m, the vehicle yawing to face each leg while stopped at the corners.  The truth
is built on a 2 kHz grid: a smooth position, the attitude a quadrotor needs to produce that
acceleration (thrust along -body z) with the scenario's yaw, and from them the mean body rate
and mean specific force over each IMU interval (the interface's convention).

Sensors (one multi-rate table: a sensor's columns are empty on rows where it has no sample):

=============  ========  =================================================================
sensor         rate      errors
=============  ========  =================================================================
IMU            250 Hz    MPU-6000 class: gyro white 0.05 °/s rms, bias N(0, 0.3 °/s) +
                         random walk 0.002 °/s/sqrt(s); accelerometer white 0.05 g rms,
                         bias ±0.05 m/s² per axis (random sign)
magnetometer   50 Hz     HMC5983 class: white 150 nT per axis (about 0.5° of heading)
flow           10 Hz     PX4Flow class: mean over its interval of the OPTICAL_FLOW_RAD
                         rates (stamped at the interval's middle), white 1 cm/s over
                         the distance; quality 150..255, 2 % of samples invalid
                         (quality 0, garbage rates)
rangefinder    10 Hz     HRLV-EZ4 class: distance along body z to flat ground, 0.01 m
barometer      10 Hz     0.3 m white plus a 0.02 m/sqrt(s) random walk, offset datum
GNSS           5 Hz      u-blox LEA-6H class: 2.5 m CEP horizontal, 4 m vertical, 0.1 m/s
=============  ========  =================================================================

The Earth field is IGRF-14 at the default site and date (constants here: the simulator imports
no model code).  This module never imports filtering code.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .._core.geodesy import ned_to_geodetic
from .._core.rotations import dcm_body_to_ned, euler_from_dcm

__all__ = ["QuadrotorFlight", "QuadrotorSensors", "simulate_quadrotor", "SCENARIOS"]

GRAVITY = 9.80665
#: Default site (Oslo), ground height above the ellipsoid, flight date.
SITE = (59.90, 10.75, 100.0)
DATE = "2024-06-01"
#: IGRF-14 main field at SITE (0.1 km) on DATE, NED, nT (ppigrf 2024-06-01).
FIELD_NED_NT = (15091.5, 1230.1, 49221.5)
SCENARIOS = ("hover", "rectangle")


@dataclass
class QuadrotorSensors:
    """Sensor rates (Hz) and error figures (units in the names)."""

    imu_hz: float = 250.0
    mag_hz: float = 50.0
    flow_hz: float = 10.0
    range_hz: float = 10.0
    baro_hz: float = 10.0
    gps_hz: float = 5.0
    gyro_noise_dps: float = 0.05
    gyro_bias_dps: float = 0.3
    gyro_bias_walk_dps_rt_s: float = 0.002
    accel_noise_g: float = 0.05
    accel_bias_ms2: float = 0.05
    mag_noise_nT: float = 150.0
    flow_noise_ms: float = 0.01
    flow_invalid_fraction: float = 0.02
    range_noise_m: float = 0.01
    baro_noise_m: float = 0.3
    baro_walk_m_rt_s: float = 0.02
    gps_cep_m: float = 2.5
    gps_vert_noise_m: float = 4.0
    gps_vel_noise_ms: float = 0.1


@dataclass
class QuadrotorFlight:
    """A simulated flight.

    Attributes
    ----------
    log : DataFrame
        Canonical multi-rate log (``time``, ``gyro_*``, ``acc_*``, ``flux_*``, ``flow_x``,
        ``flow_y``, ``flow_quality``, ``range_m``, ``baro_alt``, ``lat``, ``lon``, ``alt``,
        ``vel_n``, ``vel_e``, ``vel_d``).
    truth : DataFrame
        At every row of ``log``: ``time``, ``n_m``, ``e_m``, ``d_m`` (NED from the take-off
        point on the ground), ``vn_ms``, ``ve_ms``, ``vd_ms``, ``roll_deg``, ``pitch_deg``,
        ``yaw_deg`` ([0, 360)), ``lat``, ``lon``, ``alt``.
    info : dict
        Scenario, seed, site, date, field, the true sensor biases.
    """

    log: pd.DataFrame
    truth: pd.DataFrame
    info: dict = field(default_factory=dict)


def _smooth_step(u: np.ndarray) -> np.ndarray:
    """0 -> 1 with zero first and second derivatives at both ends (quintic)."""
    u = np.clip(u, 0.0, 1.0)
    return u**3 * (10 - 15 * u + 6 * u**2)


def _hover(t: np.ndarray, rng: np.random.Generator, height_m: float
           ) -> tuple[np.ndarray, np.ndarray]:
    pos = np.zeros((t.size, 3))
    pos[:, 2] = -height_m
    for axis, amp in ((0, 0.12), (1, 0.12), (2, 0.04)):
        for _ in range(3):
            period = rng.uniform(6.0, 25.0)
            pos[:, axis] += amp / 3 * np.sin(2 * np.pi * t / period + rng.uniform(0, 2 * np.pi))
    yaw0 = rng.uniform(0, 2 * np.pi)
    yaw = yaw0 + np.deg2rad(3.0) * np.sin(2 * np.pi * t / rng.uniform(10, 30))
    return pos, yaw


def _rectangle(t: np.ndarray, speed: float, height_m: float, size_m: tuple[float, float]
               ) -> tuple[np.ndarray, np.ndarray]:
    """Legs N, E, S, W; smooth 2 s speed ramps; 2 s yaw turns at the corners."""
    ramp, hold = 2.0, 2.0
    legs = [(0.0, size_m[0]), (np.pi / 2, size_m[1]), (np.pi, size_m[0]),
            (1.5 * np.pi, size_m[1])]
    vel = np.zeros((t.size, 3))
    yaw = np.zeros(t.size)
    t_start = 2.0
    yaw_prev = 0.0
    for k, (heading, length) in enumerate(legs):
        if k > 0:  # turn at the corner
            u = (t - t_start) / hold
            yaw += (heading - yaw_prev) * _smooth_step(u) * (t >= t_start)
            t_start += hold
        cruise = (length - speed * ramp) / speed       # ramps cover speed*ramp in total
        t1, t2, t3 = t_start + ramp, t_start + ramp + cruise, t_start + 2 * ramp + cruise
        sp = speed * (_smooth_step((t - t_start) / ramp) * (t < t2)
                      + (t >= t2) * (1 - _smooth_step((t - t2) / ramp)))
        sp = np.where((t >= t_start) & (t <= t3), sp, 0.0)
        vel[:, 0] += sp * np.cos(heading)
        vel[:, 1] += sp * np.sin(heading)
        yaw_prev = heading
        t_start = t3
        del t1
    dt = np.diff(t, prepend=t[0])
    pos = np.cumsum(0.5 * (vel + np.vstack([vel[:1], vel[:-1]])) * dt[:, None], axis=0)
    pos[:, 2] = -height_m
    return pos, yaw


def simulate_quadrotor(scenario: str = "hover", duration_s: float = 60.0, seed: int = 0,
                       sensors: QuadrotorSensors | None = None, height_m: float = 2.0,
                       speed_ms: float = 1.5, size_m: tuple[float, float] = (20.0, 10.0),
                       site: tuple[float, float, float] = SITE,
                       field_ned_nT: tuple[float, float, float] = FIELD_NED_NT,
                       fine_hz: float = 2000.0) -> QuadrotorFlight:
    """Simulate a quadrotor flight with its sensors and the truth.

    Parameters
    ----------
    scenario : {"hover", "rectangle"}
        Hover at ``height_m`` with a small wander, or the rectangle at ``speed_ms``.
    duration_s : float
        Length of the flight, s.
    seed : int
        Random seed (trajectory details and every sensor error).
    sensors : QuadrotorSensors, optional
        Rates and error figures.
    height_m : float
        Flight height above flat ground, m.
    speed_ms : float
        Cruise speed of the rectangle, m/s.
    size_m : (float, float)
        Rectangle north and east side lengths, m.
    site : (float, float, float)
        Take-off point: latitude, longitude (degrees), ground height above the ellipsoid (m).
    field_ned_nT : (float, float, float)
        Earth field in NED, nT.
    fine_hz : float
        Rate of the truth grid, Hz.

    Returns
    -------
    QuadrotorFlight
    """
    if scenario not in SCENARIOS:
        raise ValueError(f"scenario must be one of {SCENARIOS}, got {scenario!r}")
    s = sensors or QuadrotorSensors()
    rng = np.random.default_rng(seed)
    tf = np.arange(0.0, duration_s + 1e-9, 1.0 / fine_hz)
    if scenario == "hover":
        pos, yaw = _hover(tf, rng, height_m)
    else:
        pos, yaw = _rectangle(tf, speed_ms, height_m, size_m)
    vel = np.gradient(pos, tf, axis=0)
    accn = np.gradient(vel, tf, axis=0)
    # Attitude: body z along minus the specific force; yaw as given.
    fn = accn - np.array([0.0, 0.0, GRAVITY])
    zb = -fn / np.linalg.norm(fn, axis=1)[:, None]
    cy, sy = np.cos(yaw), np.sin(yaw)
    zx = cy * zb[:, 0] + sy * zb[:, 1]          # Rz(yaw)^T zb
    zy = -sy * zb[:, 0] + cy * zb[:, 1]
    zz = zb[:, 2]
    roll = np.arctan2(-zy, np.hypot(zx, zz))
    pitch = np.arctan2(zx, zz)
    C = dcm_body_to_ned(roll, pitch, yaw)                                    # (F, 3, 3)
    fb = np.einsum("kji,kj->ki", C, fn)                                      # specific force
    dR = np.einsum("kji,kjl->kil", C[:-1], C[1:])                            # C_(k-1)^T C_k
    rotvec = 0.5 * np.stack([dR[:, 2, 1] - dR[:, 1, 2], dR[:, 0, 2] - dR[:, 2, 0],
                             dR[:, 1, 0] - dR[:, 0, 1]], axis=1)
    cum_ang = np.vstack([np.zeros(3), np.cumsum(rotvec, axis=0)])           # at fine times
    fb_mid = 0.5 * (fb[:-1] + fb[1:])
    cum_dv = np.vstack([np.zeros(3), np.cumsum(fb_mid / fine_hz, axis=0)])
    vb = np.einsum("kji,kj->ki", C, vel)
    rng_dist = -pos[:, 2] / (np.cos(roll) * np.cos(pitch))
    flow_true = np.stack([-vb[:, 1] / rng_dist, vb[:, 0] / rng_dist], axis=1)
    cum_flow_trans = np.vstack([np.zeros(2), np.cumsum(0.5 * (flow_true[:-1] + flow_true[1:])
                                                        / fine_hz, axis=0)])

    def interp(times: np.ndarray, arr: np.ndarray) -> np.ndarray:
        return np.stack([np.interp(times, tf, arr[:, j]) for j in range(arr.shape[1])], axis=1)

    def sample_times(rate: float, offset: float) -> np.ndarray:
        return np.round(np.arange(offset, duration_s - 1e-9, 1.0 / rate), 6)

    t_imu = sample_times(s.imu_hz, 1.0 / s.imu_hz)
    t_mag = sample_times(s.mag_hz, 0.0011)
    t_flow = sample_times(s.flow_hz, 0.0537)
    t_rng = sample_times(s.range_hz, 0.0263)
    t_baro = sample_times(s.baro_hz, 0.0071)
    t_gps = sample_times(s.gps_hz, 0.0)

    # IMU: mean rate and specific force over each interval.
    t_prev = np.r_[0.0, t_imu[:-1]]
    dt = t_imu - t_prev
    gyro_true = (interp(t_imu, cum_ang) - interp(t_prev, cum_ang)) / dt[:, None]
    acc_true = (interp(t_imu, cum_dv) - interp(t_prev, cum_dv)) / dt[:, None]
    bg0 = rng.normal(0.0, np.deg2rad(s.gyro_bias_dps), 3)
    walk = np.cumsum(rng.normal(0.0, np.deg2rad(s.gyro_bias_walk_dps_rt_s) * np.sqrt(dt)[:, None],
                                (t_imu.size, 3)), axis=0)
    bg = bg0 + walk
    ba = s.accel_bias_ms2 * rng.choice([-1.0, 1.0], 3)
    gyro = gyro_true + bg + rng.normal(0.0, np.deg2rad(s.gyro_noise_dps), (t_imu.size, 3))
    acc = acc_true + ba + rng.normal(0.0, s.accel_noise_g * GRAVITY, (t_imu.size, 3))

    # Magnetometer.
    Cm = dcm_body_to_ned(np.interp(t_mag, tf, roll), np.interp(t_mag, tf, pitch),
                         np.interp(t_mag, tf, np.unwrap(yaw)))
    flux = np.einsum("kji,j->ki", Cm, np.asarray(field_ned_nT)) + rng.normal(
        0.0, s.mag_noise_nT, (t_mag.size, 3))

    # Flow: means over each sample's interval (rotation plus translation), noise in m/s / r.
    tfp = np.r_[t_flow[0] - 1.0 / s.flow_hz, t_flow[:-1]]
    Tf = (t_flow - tfp)[:, None]
    flow = ((interp(t_flow, cum_ang)[:, :2] - interp(tfp, cum_ang)[:, :2])
            + (interp(t_flow, cum_flow_trans) - interp(tfp, cum_flow_trans))) / Tf
    r_flow = np.interp(t_flow, tf, rng_dist)
    flow += rng.normal(0.0, 1.0, flow.shape) * (s.flow_noise_ms / r_flow)[:, None]
    quality = rng.integers(150, 256, t_flow.size).astype(np.float64)
    bad = rng.random(t_flow.size) < s.flow_invalid_fraction
    quality[bad] = 0.0
    flow[bad] = rng.uniform(-1.0, 1.0, (int(bad.sum()), 2))

    rng_m = np.interp(t_rng, tf, rng_dist) + rng.normal(0.0, s.range_noise_m, t_rng.size)
    alt_true_baro = site[2] - np.interp(t_baro, tf, pos[:, 2])
    baro = (alt_true_baro + 37.0 + rng.normal(0.0, s.baro_noise_m, t_baro.size)
            + np.cumsum(rng.normal(0.0, s.baro_walk_m_rt_s / np.sqrt(s.baro_hz), t_baro.size)))

    sh = s.gps_cep_m / 1.1774
    gps_ned = interp(t_gps, pos) + rng.normal(0.0, 1.0, (t_gps.size, 3)) * np.array(
        [sh, sh, s.gps_vert_noise_m])
    gps_llh = ned_to_geodetic(gps_ned, site)
    gps_vel = interp(t_gps, vel) + rng.normal(0.0, s.gps_vel_noise_ms, (t_gps.size, 3))

    # One multi-rate table.
    # Flow is stamped at the middle of its integration interval (shared/interface.md).
    t_flow_stamp = 0.5 * (tfp + t_flow)
    times = np.unique(np.concatenate([t_imu, t_mag, t_flow_stamp, t_rng, t_baro, t_gps]))
    n = times.size
    log = pd.DataFrame({"time": times})

    def put(cols: list[str], t_s: np.ndarray, vals: np.ndarray) -> None:
        idx = np.searchsorted(times, t_s)
        vals = np.asarray(vals, dtype=np.float64).reshape(t_s.size, -1)
        for j, c in enumerate(cols):
            col = np.full(n, np.nan)
            col[idx] = vals[:, j]
            log[c] = col

    put(["gyro_x", "gyro_y", "gyro_z"], t_imu, gyro)
    put(["acc_x", "acc_y", "acc_z"], t_imu, acc)
    put(["flux_x", "flux_y", "flux_z"], t_mag, flux)
    put(["flow_x", "flow_y"], t_flow_stamp, flow)
    put(["flow_quality"], t_flow_stamp, quality)
    put(["range_m"], t_rng, rng_m)
    put(["baro_alt"], t_baro, baro)
    put(["lat", "lon", "alt"], t_gps, gps_llh)
    put(["vel_n", "vel_e", "vel_d"], t_gps, gps_vel)

    p_t = interp(times, pos)
    v_t = interp(times, vel)
    Ct = dcm_body_to_ned(np.interp(times, tf, roll), np.interp(times, tf, pitch),
                         np.interp(times, tf, np.unwrap(yaw)))
    r_t, p_t_, y_t = euler_from_dcm(Ct)
    llh = ned_to_geodetic(p_t, site)
    truth = pd.DataFrame({
        "time": times, "n_m": p_t[:, 0], "e_m": p_t[:, 1], "d_m": p_t[:, 2],
        "vn_ms": v_t[:, 0], "ve_ms": v_t[:, 1], "vd_ms": v_t[:, 2],
        "roll_deg": np.rad2deg(r_t), "pitch_deg": np.rad2deg(p_t_),
        "yaw_deg": np.mod(np.rad2deg(y_t), 360.0),
        "lat": llh[:, 0], "lon": llh[:, 1], "alt": llh[:, 2]})
    info = {"scenario": scenario, "seed": seed, "duration_s": duration_s, "site": list(site),
            "date": DATE, "field_ned_nT": list(field_ned_nT), "height_m": height_m,
            "speed_ms": speed_ms if scenario == "rectangle" else 0.0,
            "gyro_bias_rads": bg0.tolist(), "accel_bias_ms2": ba.tolist(),
            "sensors": s.__dict__.copy()}
    return QuadrotorFlight(log=log, truth=truth, info=info)
