"""Measurement models of the navigation filter, vectorised over sigma points.

Every model takes sigma points ``X`` of shape ``(S, n)`` (state layout of
:mod:`aeromag.nav.filter`: position NED, velocity NED, roll, pitch, yaw, gyro biases,
optionally accelerometer biases) and returns the predicted measurement ``(S, m)``.

* Optical flow (``flow_x``, ``flow_y``, rad/s; MAVLink ``OPTICAL_FLOW_RAD`` convention, body
  rotation included): ``flow_x = w_x - v_y / r``, ``flow_y = w_y + v_x / r`` with ``v`` the
  velocity in body axes, ``w`` the body rate averaged over the flow sample's interval (IMU gyro
  minus the bias state) and ``r`` the distance from the sensor to flat ground along the body
  z axis, ``(d_ground - p_d) / (cos roll cos pitch)``.
* Rangefinder: the same distance ``r`` (flat ground; its level ``d_ground`` is a state).
* Barometer: ``baro_alt = offset - p_d`` (its datum ``offset`` is a state).
* Gravity vector: specific force at rest or in uniform motion ``f_b = -C_nb^T g_n (+ b_a)``.
* Magnetic north: the magnetometer vector rotated to the level frame with each sigma point's
  own roll and pitch gives a magnetic heading; the model returns ``yaw - heading_mag``
  (wrapped), measured as 0.
* GNSS: position and velocity in the local NED frame.
"""

from __future__ import annotations

import numpy as np

from .._core.rotations import dcm_body_to_ned
from .mechanization import GRAVITY

__all__ = ["ground_distance", "h_baro", "h_flow", "h_gnss_pos", "h_gnss_vel", "h_gravity",
           "h_mag_heading", "h_range", "level_heading"]


def _dcm(X: np.ndarray) -> np.ndarray:
    return dcm_body_to_ned(X[:, 6], X[:, 7], X[:, 8])


def ground_distance(X: np.ndarray, ground_idx: int) -> np.ndarray:
    """Distance from the sensor to flat ground along body z, m, per sigma point.

    ``X[:, ground_idx]`` is the ground level (its down coordinate in the local frame).
    """
    cz = np.cos(X[:, 6]) * np.cos(X[:, 7])
    return (X[:, ground_idx] - X[:, 2]) / np.where(np.abs(cz) > 1e-6, cz, 1e-6)


def h_flow(X: np.ndarray, gyro_mean: np.ndarray, ground_idx: int,
           vel_lag: np.ndarray | None = None) -> np.ndarray:
    """Predicted optical flow (rad/s), shape (S, 2).

    ``vel_lag`` (m/s, NED) is the current velocity minus the mean velocity over the flow
    sample's interval (from the filter's own trajectory): the sensor averages the image motion
    over its interval, so under acceleration it lags the current velocity by ``a T / 2``.
    """
    C = _dcm(X)
    v = X[:, 3:6] if vel_lag is None else X[:, 3:6] - vel_lag[None, :]
    vb = np.einsum("sji,sj->si", C, v)
    r = ground_distance(X, ground_idx)
    r = np.where(r > 1e-3, r, 1e-3)
    w = gyro_mean[None, :2] - X[:, 9:11]
    return np.stack([w[:, 0] - vb[:, 1] / r, w[:, 1] + vb[:, 0] / r], axis=1)


def h_range(X: np.ndarray, ground_idx: int) -> np.ndarray:
    """Predicted rangefinder distance (m), shape (S, 1)."""
    return ground_distance(X, ground_idx)[:, None]


def h_baro(X: np.ndarray, offset_idx: int) -> np.ndarray:
    """Predicted barometric altitude (m), shape (S, 1).

    ``X[:, offset_idx]`` is the barometer's datum (``baro_alt + p_d``, a state).
    """
    return (X[:, offset_idx] - X[:, 2])[:, None]


def h_gravity(X: np.ndarray, accel_bias: bool = False) -> np.ndarray:
    """Predicted specific force at rest (m/s², body axes), shape (S, 3)."""
    r, p = X[:, 6], X[:, 7]
    f = -GRAVITY * np.stack([-np.sin(p), np.sin(r) * np.cos(p), np.cos(r) * np.cos(p)], axis=1)
    if accel_bias:
        f = f + X[:, 12:15]
    return f


def level_heading(roll: np.ndarray, pitch: np.ndarray, flux_b: np.ndarray,
                  declination_rad: float) -> np.ndarray:
    """True heading (rad) from a body-frame field vector tilt-compensated with roll, pitch.

    Parameters
    ----------
    roll, pitch : ndarray, shape (S,)
        Attitude, rad.
    flux_b : ndarray, shape (3,) or (S, 3)
        Field in body axes, any unit.
    declination_rad : float
        Magnetic declination, rad (east positive).
    """
    C = dcm_body_to_ned(roll, pitch, 0.0)
    f = np.broadcast_to(np.asarray(flux_b, dtype=np.float64), C.shape[:-1])
    ml = np.einsum("sij,sj->si", C, f)
    return declination_rad - np.arctan2(ml[:, 1], ml[:, 0])


def h_mag_heading(X: np.ndarray, flux_b: np.ndarray, declination_rad: float,
                  bias_idx: int | None = None) -> np.ndarray:
    """``yaw - heading from the magnetometer`` (rad, wrapped), shape (S, 1); measured as 0.

    ``X[:, bias_idx]`` (when given) is the magnetometer's heading bias, rad: the magnetic
    heading plus it is the true heading (a declination error, an uncalibrated sensor).
    """
    d = X[:, 8] - level_heading(X[:, 6], X[:, 7], flux_b, declination_rad)
    if bias_idx is not None:
        d = d - X[:, bias_idx]
    return (np.mod(d + np.pi, 2.0 * np.pi) - np.pi)[:, None]


def h_gnss_pos(X: np.ndarray) -> np.ndarray:
    """Predicted GNSS position, local NED (m), shape (S, 3)."""
    return X[:, 0:3]


def h_gnss_vel(X: np.ndarray) -> np.ndarray:
    """Predicted GNSS velocity, NED (m/s), shape (S, 3)."""
    return X[:, 3:6]
