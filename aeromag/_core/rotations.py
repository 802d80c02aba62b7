"""Attitude: yaw-pitch-roll (Z-Y-X) Euler angles of the body in north-east-down, as rotations.

Frames follow the interface: body axes x forward, y right, z down; navigation frame NED.
``C_nb`` (``dcm_body_to_ned``) maps a body-frame vector to NED: ``v_n = C_nb @ v_b``.  Angles
are radians here; callers convert degrees at their edge.  Everything is vectorised: inputs of
shape (n,) give matrices of shape (n, 3, 3).
"""

from __future__ import annotations

import numpy as np

__all__ = ["dcm_body_to_ned", "euler_from_dcm", "rotate_ned_to_body", "rotate_body_to_ned"]


def dcm_body_to_ned(roll_rad: np.ndarray | float, pitch_rad: np.ndarray | float,
                    yaw_rad: np.ndarray | float) -> np.ndarray:
    """Direction-cosine matrix body -> NED from Z-Y-X Euler angles.

    Parameters
    ----------
    roll_rad, pitch_rad, yaw_rad : array_like, shape (n,) or scalar
        Roll (about x), pitch (about y) and yaw (about z, from north towards east), rad.

    Returns
    -------
    ndarray, shape (..., 3, 3)
        ``C_nb = Rz(yaw) @ Ry(pitch) @ Rx(roll)``.
    """
    r, p, y = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64)
                                    for a in (roll_rad, pitch_rad, yaw_rad)))
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    c = np.empty(r.shape + (3, 3))
    c[..., 0, 0] = cp * cy
    c[..., 0, 1] = sr * sp * cy - cr * sy
    c[..., 0, 2] = cr * sp * cy + sr * sy
    c[..., 1, 0] = cp * sy
    c[..., 1, 1] = sr * sp * sy + cr * cy
    c[..., 1, 2] = cr * sp * sy - sr * cy
    c[..., 2, 0] = -sp
    c[..., 2, 1] = sr * cp
    c[..., 2, 2] = cr * cp
    return c


def euler_from_dcm(c_nb: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Z-Y-X Euler angles from a body -> NED direction-cosine matrix.

    Parameters
    ----------
    c_nb : ndarray, shape (..., 3, 3)

    Returns
    -------
    roll_rad, pitch_rad, yaw_rad : ndarray
        Roll and yaw in [-pi, pi], pitch in [-pi/2, pi/2], rad.
    """
    c = np.asarray(c_nb, dtype=np.float64)
    roll = np.arctan2(c[..., 2, 1], c[..., 2, 2])
    pitch = -np.arcsin(np.clip(c[..., 2, 0], -1.0, 1.0))
    yaw = np.arctan2(c[..., 1, 0], c[..., 0, 0])
    return roll, pitch, yaw


def rotate_ned_to_body(v_ned: np.ndarray, roll_rad: np.ndarray, pitch_rad: np.ndarray,
                       yaw_rad: np.ndarray) -> np.ndarray:
    """Express NED vectors in body axes: ``v_b = C_nb.T @ v_n``.

    Parameters
    ----------
    v_ned : ndarray, shape (3,) or (n, 3)
        Vector(s) in NED, any unit.
    roll_rad, pitch_rad, yaw_rad : array_like, shape (n,) or scalar
        Attitude, rad.

    Returns
    -------
    ndarray, shape (n, 3)
        The vectors in body axes, same unit.
    """
    c = dcm_body_to_ned(roll_rad, pitch_rad, yaw_rad)
    return np.einsum("...ji,...j->...i", c, np.asarray(v_ned, dtype=np.float64))


def rotate_body_to_ned(v_body: np.ndarray, roll_rad: np.ndarray, pitch_rad: np.ndarray,
                       yaw_rad: np.ndarray) -> np.ndarray:
    """Express body-frame vectors in NED: ``v_n = C_nb @ v_b``.

    Parameters
    ----------
    v_body : ndarray, shape (3,) or (n, 3)
        Vector(s) in body axes, any unit.
    roll_rad, pitch_rad, yaw_rad : array_like, shape (n,) or scalar
        Attitude, rad.

    Returns
    -------
    ndarray, shape (n, 3)
        The vectors in NED, same unit.
    """
    c = dcm_body_to_ned(roll_rad, pitch_rad, yaw_rad)
    return np.einsum("...ij,...j->...i", c, np.asarray(v_body, dtype=np.float64))
