"""A plain error-state EKF and the real-flight metrics: the yardstick of ``aeromag.nav``.

Written independently of :mod:`aeromag.nav` (it imports nothing from it): nominal state
position, velocity (NED), body-to-NED quaternion, gyro and accelerometer biases, ground
level; a 16-dimensional error state; first-order covariance propagation at every IMU sample;
numerical measurement Jacobians; PX4 EKF2's default noise figures (gyro 0.015 rad/s,
accelerometer 0.35 m/s², flow 0.15 rad/s, range 0.1 m, heading 0.3 rad, GNSS 2.5 m / 0.5 m/s)
and a fixed chi-square gate (p = 0.9999, no re-lock).  Flow is modelled at the middle of its
integration interval (the interface's stamping): the body rate averaged over
``[t - T/2, t + T/2]``.  It exists for tests and ``benchmarks/nav_real_flight.py`` only.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.stats import chi2

G = 9.80665


def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def _qrot(phi: np.ndarray) -> np.ndarray:
    a = float(np.linalg.norm(phi))
    if a < 1e-12:
        return np.array([1.0, *(0.5 * phi)])
    return np.array([np.cos(a / 2), *(np.sin(a / 2) * phi / a)])


def _dcm(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _euler_q(roll: float, pitch: float, yaw: float) -> np.ndarray:
    cr, sr, cp, sp = np.cos(roll / 2), np.sin(roll / 2), np.cos(pitch / 2), np.sin(pitch / 2)
    cy, sy = np.cos(yaw / 2), np.sin(yaw / 2)
    return np.array([cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                     cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy])


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


@dataclass
class RefStats:
    """Fused and rejected counts and the NIS sum of one sensor."""

    dof: int
    fused: int = 0
    rejected: int = 0
    nis: float = 0.0

    @property
    def nis_per_dof(self) -> float:
        return self.nis / max(self.fused, 1) / self.dof


@dataclass
class RefResult:
    time_s: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    yaw: np.ndarray
    stats: dict[str, RefStats] = field(default_factory=dict)


def _mag_heading(q: np.ndarray, m_b: np.ndarray, decl: float) -> float:
    C = _dcm(q)
    roll = np.arctan2(C[2, 1], C[2, 2])
    pitch = -np.arcsin(np.clip(C[2, 0], -1, 1))
    cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    mx = cp * m_b[0] + sp * sr * m_b[1] + sp * cr * m_b[2]
    my = cr * m_b[1] - sr * m_b[2]
    return decl - np.arctan2(my, mx)


def reference_ekf(df: pd.DataFrame, gps_use: np.ndarray, declination_rad: float,
                  *, gps_pos_m: float = 2.5, gps_vel_ms: float = 0.5,
                  flow_rads: float = 0.15, range_m: float = 0.1,
                  heading_rad: float = 0.3) -> RefResult:
    """Run the plain error-state EKF on a canonical log.

    ``gps_use`` (bool per row) says which GNSS rows are fused (position in a local NED frame
    at the first fix, velocity); the first fix starts the filter either way.
    """
    from pyproj import Transformer

    t = df["time"].to_numpy(float)
    N = t.size

    def col(*names):
        return np.column_stack([df[c].to_numpy(float) if c in df else np.full(N, np.nan)
                                for c in names])

    gyro, acc = col("gyro_x", "gyro_y", "gyro_z"), col("acc_x", "acc_y", "acc_z")
    flow, fq = col("flow_x", "flow_y"), col("flow_quality")[:, 0]
    rng, flux = col("range_m")[:, 0], col("flux_x", "flux_y", "flux_z")
    llh, vel = col("lat", "lon", "alt"), col("vel_n", "vel_e", "vel_d")
    fix = np.isfinite(llh).all(axis=1)
    i0 = int(np.flatnonzero(fix)[0])
    ecef = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
    x, y, z = ecef.transform(llh[fix, 1], llh[fix, 0], llh[fix, 2])
    la, lo = np.deg2rad(llh[i0, 0]), np.deg2rad(llh[i0, 1])
    Rn = np.array([[-np.sin(la) * np.cos(lo), -np.sin(la) * np.sin(lo), np.cos(la)],
                   [-np.sin(lo), np.cos(lo), 0.0],
                   [-np.cos(la) * np.cos(lo), -np.cos(la) * np.sin(lo), -np.sin(la)]])
    d = np.column_stack([x, y, z])
    ned = np.full((N, 3), np.nan)
    ned[fix] = (d - d[np.flatnonzero(fix) == i0][0]) @ Rn.T
    imu = np.flatnonzero(np.isfinite(gyro).all(axis=1) & np.isfinite(acc).all(axis=1))
    # cumulative gyro angle on a time axis (interval means ending at each IMU row)
    ti = t[imu]
    dti = np.diff(ti, prepend=ti[0] - np.median(np.diff(ti)))
    cum = np.vstack([np.zeros(3), np.cumsum(gyro[imu] * dti[:, None], axis=0)])
    tcum = np.r_[ti[0] - dti[0], ti]

    def gyro_mean(a: float, b: float) -> np.ndarray:
        return np.array([(np.interp(b, tcum, cum[:, k]) - np.interp(a, tcum, cum[:, k]))
                         for k in range(3)]) / (b - a)

    # start: level from the first second, heading from the magnetometer
    w0 = imu[ti <= ti[0] + 1.0]
    f0 = acc[w0].mean(axis=0)
    roll0, pitch0 = np.arctan2(-f0[1], -f0[2]), np.arctan2(f0[0], np.hypot(f0[1], f0[2]))
    m0 = flux[np.isfinite(flux).all(axis=1) & (t <= ti[0] + 1.0)].mean(axis=0)
    q = _euler_q(roll0, pitch0, 0.0)
    q = _euler_q(roll0, pitch0, _mag_heading(q, m0, declination_rad))
    p, v = np.zeros(3), np.where(np.isfinite(vel[i0]), vel[i0], 0.0)
    bg, ba = np.zeros(3), np.zeros(3)
    ground = np.nan
    P = np.diag(np.r_[[2.5**2] * 2, 5.0**2, [0.5**2] * 3, [0.05**2] * 2, 0.2**2,
                      [np.deg2rad(0.5) ** 2] * 3, [0.2**2] * 3, 1.0])
    qg, qa, qbg, qba = 0.015**2, 0.35**2, 1e-3**2, 3e-3**2
    st = {k: RefStats(dof) for k, dof in (("flow", 2), ("range", 1), ("mag", 1),
                                          ("gps_pos", 3), ("gps_vel", 3))}
    pos, velo, yaw = np.full((N, 3), np.nan), np.full((N, 3), np.nan), np.full(N, np.nan)
    last_flow_t, last_mag_t, t_prev = None, -np.inf, None

    def state():
        return p, v, q, bg, ba, ground

    def inject(dx, s):
        p_, v_, q_, bg_, ba_, g_ = s
        q2 = _qmul(_qrot(dx[6:9]), q_)
        return (p_ + dx[0:3], v_ + dx[3:6], q2 / np.linalg.norm(q2), bg_ + dx[9:12],
                ba_ + dx[12:15], g_ + dx[15])

    def update(name, zres_fn, R):
        """zres_fn(state) -> innovation vector (measured - predicted); numerical Jacobian."""
        nonlocal p, v, q, bg, ba, ground, P
        s = state()
        r0 = zres_fn(s)
        H = np.zeros((r0.size, 16))
        for k in range(16):
            dx = np.zeros(16)
            dx[k] = 1e-6
            H[:, k] = -(zres_fn(inject(dx, s)) - r0) / 1e-6
        S = H @ P @ H.T + R
        nis = float(r0 @ np.linalg.solve(S, r0))
        if nis > chi2.ppf(0.9999, r0.size):
            st[name].rejected += 1
            return
        st[name].fused += 1
        st[name].nis += nis
        K = P @ H.T @ np.linalg.inv(S)
        p, v, q, bg, ba, ground = inject(K @ r0, s)
        IKH = np.eye(16) - K @ H
        P = IKH @ P @ IKH.T + K @ R @ K.T

    flow_rows = np.flatnonzero(np.isfinite(flow).all(axis=1))
    flow_T = dict(zip(flow_rows.tolist(), np.r_[np.nan, np.diff(t[flow_rows])].tolist(),
                      strict=True))
    for r in range(i0, N):
        tr = t[r]
        if np.isfinite(gyro[r]).all() and np.isfinite(acc[r]).all():
            if t_prev is not None:
                dt = tr - t_prev
                w = gyro[r] - bg
                f = acc[r] - ba
                C = _dcm(q)
                a_n = C @ f + np.array([0, 0, G])
                p = p + v * dt + 0.5 * a_n * dt * dt
                v = v + a_n * dt
                q = _qmul(q, _qrot(w * dt))
                q /= np.linalg.norm(q)
                F = np.eye(16)
                F[0:3, 3:6] = np.eye(3) * dt
                F[3:6, 6:9] = -_skew(C @ f) * dt
                F[3:6, 12:15] = -C * dt
                F[6:9, 9:12] = -C * dt
                Qd = np.zeros(16)
                Qd[3:6], Qd[6:9] = qa * dt, qg * dt
                Qd[9:12], Qd[12:15], Qd[15] = qbg * dt, qba * dt, 1e-4 * dt
                P = F @ P @ F.T + np.diag(Qd)
            t_prev = tr
        if t_prev is None:
            continue
        if np.isfinite(rng[r]) and 0.3 <= rng[r] <= 5.0:
            C = _dcm(q)
            if not np.isfinite(ground):
                ground = p[2] + rng[r] * C[2, 2]
            else:
                zr = rng[r]
                update("range", lambda s, zr=zr: np.array(
                    [zr - (s[5] - s[0][2]) / _dcm(s[2])[2, 2]]), np.array([[range_m**2]]))
        T = flow_T.get(r)
        if (T is not None and np.isfinite(T) and fq[r] > 0 and np.isfinite(ground)
                and T < 0.5):
            wm = gyro_mean(tr - T / 2, tr + T / 2)
            zf = flow[r]

            def fres(s, zf=zf, wm=wm):
                C = _dcm(s[2])
                h = (s[5] - s[0][2]) / C[2, 2]
                vb = C.T @ s[1]
                w = wm - s[3]
                return zf - np.array([w[0] - vb[1] / h, w[1] + vb[0] / h])

            update("flow", fres, np.eye(2) * flow_rads**2)
            last_flow_t = tr
        if np.isfinite(flux[r]).all() and tr - last_mag_t >= 0.1:
            last_mag_t = tr
            mb = flux[r]

            def mres(s, mb=mb):
                C = _dcm(s[2])
                return np.array([_wrap(_mag_heading(s[2], mb, declination_rad)
                                       - np.arctan2(C[1, 0], C[0, 0]))])

            update("mag", mres, np.array([[heading_rad**2]]))
        if fix[r] and gps_use[r] and r != i0:
            zp = ned[r]
            update("gps_pos", lambda s, zp=zp: zp - s[0],
                   np.diag([gps_pos_m**2, gps_pos_m**2, (2 * gps_pos_m) ** 2]))
            if np.isfinite(vel[r]).all():
                zv = vel[r]
                update("gps_vel", lambda s, zv=zv: zv - s[1], np.eye(3) * gps_vel_ms**2)
        pos[r], velo[r] = p, v
        C = _dcm(q)
        yaw[r] = np.arctan2(C[1, 0], C[0, 0])
    del last_flow_t
    return RefResult(time_s=t, pos=pos, vel=velo, yaw=yaw, stats=st)


# ---------------------------------------------------------------------------- metrics
def gnss_truth(df: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """GNSS rows, their local NED position (origin: first fix) and velocity."""
    from pyproj import Transformer

    llh = df[["lat", "lon", "alt"]].to_numpy(float)
    rows = np.flatnonzero(np.isfinite(llh).all(axis=1))
    o = llh[rows[0]]
    tr = Transformer.from_pipeline(
        f"+proj=pipeline +step +proj=cart +ellps=WGS84 +step +proj=topocentric "
        f"+ellps=WGS84 +lat_0={o[0]} +lon_0={o[1]} +h_0={o[2]}")
    e, n, u = tr.transform(llh[rows, 1], llh[rows, 0], llh[rows, 2])
    ned = np.column_stack([n, e, -np.asarray(u)])
    v = df[["vel_n", "vel_e", "vel_d"]].to_numpy(float)[rows]
    return rows, df["time"].to_numpy(float)[rows], ned, v


def _smooth(t: np.ndarray, x: np.ndarray, width_s: float) -> np.ndarray:
    out = np.empty_like(x)
    lo = np.searchsorted(t, t - width_s / 2)
    hi = np.searchsorted(t, t + width_s / 2, side="right")
    c = np.vstack([np.zeros(x.shape[1]), np.cumsum(x, axis=0)])
    out[:] = (c[hi] - c[lo]) / (hi - lo)[:, None]
    return out


def flight_metrics(df: pd.DataFrame, pos: np.ndarray, vel: np.ndarray,
                   outage: tuple[float, float] | None = (247.6, 277.6)) -> dict[str, float]:
    """Errors of a navigated log against its own GNSS (horizontal, metres and m/s).

    ``vel_rms``: rms of the horizontal difference between the estimate and the GNSS velocity,
    both smoothed by a 1-s moving mean, at the GNSS rows; ``pos_rms``: rms horizontal distance
    to the GNSS fixes; ``disp10_rms``: rms error of the 10-s horizontal displacement (windows
    starting at every fix, GNSS smoothed over 1 s); ``outage_end``: horizontal distance at the
    last fix of the outage to the GNSS position smoothed over 1 s.
    """
    rows, t, gp, gv = gnss_truth(df)
    ok = np.isfinite(pos[rows]).all(axis=1) & np.isfinite(gv).all(axis=1)
    rows, t, gp, gv = rows[ok], t[ok], gp[ok], gv[ok]
    ep, ev = pos[rows], vel[rows]
    out = {}
    sv = _smooth(t, gv[:, :2], 1.0) - _smooth(t, ev[:, :2], 1.0)
    out["vel_rms"] = float(np.sqrt(np.mean(np.sum(sv**2, axis=1))))
    dp = ep[:, :2] - gp[:, :2]
    out["pos_rms"] = float(np.sqrt(np.mean(np.sum(dp**2, axis=1))))
    gs = _smooth(t, gp[:, :2], 1.0)
    es = _smooth(t, ep[:, :2], 1.0)
    j = np.searchsorted(t, t + 10.0)
    k = np.flatnonzero(j < t.size)
    err = (es[j[k]] - es[k]) - (gs[j[k]] - gs[k])
    out["disp10_rms"] = float(np.sqrt(np.mean(np.sum(err**2, axis=1))))
    if outage is not None:
        i = int(np.searchsorted(t, outage[1]) - 1)
        out["outage_end"] = float(np.linalg.norm(es[i] - gs[i]))
    return out
