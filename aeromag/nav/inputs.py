"""What the navigation filter reads.

The sensor arrays of a log, the start-up helpers, and the measurements of one epoch.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .mechanization import GRAVITY

__all__ = ["NavInputs", "decimate_rows", "flow_to_interval_end", "imu_noise_from_data",
           "magnetic_reference_from_log", "tilt_from_accel"]


@dataclass
class NavInputs:
    """Sensor arrays on the rows of one multi-rate log (NaN where a sensor has no sample).

    Attributes
    ----------
    time_s : ndarray, shape (N,)
        Strictly increasing time, s.
    gyro : ndarray, shape (N, 3)
        Body rate, mean over the interval ending at the row, rad/s.
    acc : ndarray, shape (N, 3)
        Specific force, body axes, m/s².
    flow : ndarray, shape (N, 2), optional
        Optical flow, rad/s (``OPTICAL_FLOW_RAD`` convention).
    flow_quality : ndarray, shape (N,), optional
        Flow quality 0..255 (0 invalid); all valid when absent.
    range_m : ndarray, shape (N,), optional
        Downward rangefinder distance, m.
    baro_alt : ndarray, shape (N,), optional
        Barometric altitude, m (any datum).
    flux : ndarray, shape (N, 3), optional
        Magnetometer, body axes, nT.
    gps_ned : ndarray, shape (N, 3), optional
        GNSS position in the local NED frame, m.
    gps_vel : ndarray, shape (N, 3), optional
        GNSS velocity NED, m/s.
    gps_use : ndarray of bool, shape (N,), optional
        Which GNSS rows may be fused (all when absent).
    heading_deg : ndarray, shape (N,), optional
        An INS heading, used only to start when there is no magnetometer.
    """

    time_s: np.ndarray
    gyro: np.ndarray
    acc: np.ndarray
    flow: np.ndarray | None = None
    flow_quality: np.ndarray | None = None
    range_m: np.ndarray | None = None
    baro_alt: np.ndarray | None = None
    flux: np.ndarray | None = None
    gps_ned: np.ndarray | None = None
    gps_vel: np.ndarray | None = None
    gps_use: np.ndarray | None = None
    heading_deg: np.ndarray | None = None


def imu_noise_from_data(gyro: np.ndarray, acc: np.ndarray) -> tuple[float, float]:
    """White noise of one IMU sample from the log: gyro in °/s, accelerometer in g.

    The robust scale (1.4826 MAD) of the first differences of consecutive samples over
    sqrt(2), per axis, the largest axis counted: the body's own motion is slow at the IMU
    rate, so the differences hold the sensor noise and the vibration the filter must treat
    as noise.

    Parameters
    ----------
    gyro : ndarray, shape (N, 3)
        Body rate, rad/s, at consecutive IMU samples.
    acc : ndarray, shape (N, 3)
        Specific force, m/s², at the same samples.
    """
    def scale(x: np.ndarray) -> float:
        d = np.diff(x, axis=0)
        if d.shape[0] < 10:
            return 0.0
        mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0)
        return float(np.max(1.4826 * mad / np.sqrt(2.0)))

    return float(np.rad2deg(scale(gyro))), scale(acc) / GRAVITY


def flow_to_interval_end(time_s: np.ndarray, flow: np.ndarray,
                         quality: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
    """Move mid-interval flow samples to the row at the end of their interval.

    A flow value is the mean over its integration interval, stamped at the middle of it
    (``shared/interface.md``); the interval is taken as the spacing to the previous sample.
    The filter models flow at the end of its interval (the body rate and velocity averaged
    over the interval that ends where it is fused), so each sample moves to the log row
    nearest ``t + T / 2``.  A sample that would land on a later sample's row, or past the
    log, stays on the row it would otherwise reach.

    Parameters
    ----------
    time_s : ndarray, shape (N,)
        Row times, s.
    flow : ndarray, shape (N, 2)
        Flow, rad/s (NaN on rows without a sample).
    quality : ndarray, shape (N,), optional
        ``flow_quality``, moved with the flow.
    """
    rows = np.flatnonzero(np.isfinite(flow).all(axis=1))
    if rows.size < 2:
        return flow, quality
    T = np.diff(time_s[rows])
    T = np.r_[T[0], T]
    k = np.clip(np.searchsorted(time_s, time_s[rows] + 0.5 * T), 1, time_s.size - 1)
    near = np.where(np.abs(time_s[k - 1] - (time_s[rows] + 0.5 * T))
                    <= np.abs(time_s[k] - (time_s[rows] + 0.5 * T)), k - 1, k)
    nxt = np.r_[rows[1:], time_s.size]
    dest = np.clip(near, rows, nxt - 1)          # never onto or past the next sample's row
    out = np.full_like(flow, np.nan)
    out[dest] = flow[rows]
    q_out = None
    if quality is not None:
        q_out = np.full(time_s.size, np.nan)
        q_out[dest] = np.asarray(quality, float)[rows]
    return out, q_out


def tilt_from_accel(f: np.ndarray) -> tuple[float, float]:
    """Roll and pitch (rad) of a body whose specific force is ``f`` (at rest: -g down)."""
    roll = float(np.arctan2(-f[1], -f[2]))
    pitch = float(np.arctan2(f[0], np.hypot(f[1], f[2])))
    return roll, pitch


def magnetic_reference_from_log(time_s: np.ndarray, acc: np.ndarray, gyro: np.ndarray,
                                flux: np.ndarray, window_s: float = 60.0
                                ) -> tuple[np.ndarray, int]:
    """The Earth field's strength and inclination from the log itself.

    Uses the rows of the first ``window_s`` seconds that have the IMU and the magnetometer
    and where the vehicle is close to rest or level uniform flight (norm of the specific force
    within 0.3 m/s² of g, body rate below 0.2 rad/s): the inclination is the angle between
    the field and the accelerometer's "down".  The declination is unknown (0: the yaw is then
    magnetic).

    Parameters
    ----------
    time_s : ndarray, shape (N,)
    acc, gyro, flux : ndarray, shape (N, 3)
        Specific force (m/s²), body rate (rad/s), field (nT); NaN rows are skipped.
    window_s : float
        Length of the window from the first row, s.

    Returns
    -------
    ned_nT : ndarray, shape (3,)
        Reference field ``F (cos I, 0, sin I)``, nT.
    n_used : int
        Rows used (0: none qualified; ``ned_nT`` is NaN).
    """
    t = np.asarray(time_s, dtype=np.float64)
    # The accelerometer and gyro at or before each row (forward fill).
    ok_imu = np.isfinite(acc).all(axis=1) & np.isfinite(gyro).all(axis=1)
    idx = np.maximum.accumulate(np.where(ok_imu, np.arange(len(t)), -1))
    ok = (np.isfinite(flux).all(axis=1) & (idx >= 0) & (t <= t[0] + window_s))
    rows = np.flatnonzero(ok)
    if rows.size == 0:
        return np.full(3, np.nan), 0
    f = acc[idx[rows]]
    w = gyro[idx[rows]]
    m = flux[rows]
    fn = np.linalg.norm(f, axis=1)
    calm = (np.abs(fn - GRAVITY) < 0.3) & (np.linalg.norm(w, axis=1) < 0.2)
    if calm.sum() < 5:
        return np.full(3, np.nan), 0
    f, m, fn = f[calm], m[calm], fn[calm]
    mn = np.linalg.norm(m, axis=1)
    sin_i = np.einsum("ij,ij->i", m, -f / fn[:, None]) / mn
    F = float(np.median(mn))
    inc = float(np.median(np.arcsin(np.clip(sin_i, -1, 1))))
    return F * np.array([np.cos(inc), 0.0, np.sin(inc)]), int(calm.sum())


def decimate_rows(t: np.ndarray, rows: np.ndarray, interval_s: float) -> np.ndarray:
    """The rows of ``rows`` kept when no two are closer than ``interval_s`` (greedy)."""
    if interval_s <= 0 or rows.size == 0:
        return rows
    keep = []
    last = -np.inf
    for r, tr in zip(rows.tolist(), t[rows].tolist(), strict=True):
        if tr - last >= interval_s - 1e-9:
            keep.append(r)
            last = tr
    return np.asarray(keep, dtype=np.intp)


@dataclass
class Epoch:
    """What one row brings to fuse (filled by ``run`` in bulk or ``step`` online)."""

    gps_pos: np.ndarray | None = None
    gps_vel: np.ndarray | None = None
    range_m: float | None = None
    flow: np.ndarray | None = None
    flow_gyro: np.ndarray | None = None
    flow_interval_s: float = 0.1
    flow_vel_lag: np.ndarray | None = None
    baro: float | None = None
    grav_acc: np.ndarray | None = None
    grav_rate: np.ndarray | None = None
    grav_interval_s: float = 0.1
    flux: np.ndarray | None = None
    extra: dict = field(default_factory=dict)
