"""The measurement update of the navigation filter: gates, models, one joint update per epoch.

A mixin of :class:`aeromag.nav.NavFilter`, kept apart to keep each file readable.
"""

from __future__ import annotations

import numpy as np

from .._core.rotations import dcm_body_to_ned
from .inputs import Epoch, decimate_rows
from .mechanization import GRAVITY, rotation_matrices
from .models import h_baro, h_flow, h_gnss_pos, h_gnss_vel, h_gravity, h_mag_heading, h_range
from .ukf import DivergenceError

__all__ = ["FusionMixin"]

_RANGE_RECENT_S = 1.0


class FusionMixin:
    """Measurement update of :class:`aeromag.nav.NavFilter`.

    ``_fuse`` checks the validity of every measurement of an epoch; ``_update_blocks`` makes
    one joint unscented update with block-diagonal noise.  Each block is weighted on its own
    normalised innovation squared (NIS): Huber (``NavConfig.robust``) beyond the
    ``huber_p`` chi-square quantile, refused only beyond the gross-fault gate; its noise
    level adapts to its innovations within bounds (``adaptive_noise``).
    """

    def noise_used(self) -> dict[str, float]:
        """The noise levels the filter ended with (after sizing from the data), SI units.

        ``gyro_noise_dps``, ``accel_noise_g`` (per IMU sample) and, per measurement, its
        one-sigma noise and the adaptive variance scale applied to the configured one.
        """
        c = self.config
        base = {"flow": ("flow_noise_ms", c.flow_noise_ms), "range": ("range_noise_m",
                c.range_noise_m), "baro": ("baro_noise_m", c.baro_noise_m),
                "mag": ("mag_heading_noise_deg", c.mag_heading_noise_deg),
                "gps_pos": ("gps_cep_m", c.gps_cep_m),
                "gps_vel": ("gps_vel_noise_ms", c.gps_vel_noise_ms),
                "gravity": ("gravity_noise_ms2", c.gravity_noise_ms2)}
        out: dict[str, float] = {"gyro_noise_dps": float(self.gyro_noise_dps),
                                 "accel_noise_g": float(self.accel_noise_g)}
        for name in self.sensors:
            key, v = base[name]
            sc = float(self.noise_scale.get(name, 1.0))
            out[key] = float(v * np.sqrt(sc))
            out[f"{name}_variance_scale"] = sc
        return out

    def _check(self, t: float, row: int | None = None) -> None:
        x, P = self.ukf.x, self.ukf.P
        where = f"t = {t:.3f} s" + ("" if row is None else f" (row {row})")
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(P))):
            raise DivergenceError(f"navigation filter diverged at {where}: the state is no "
                                  "longer finite; check the IMU units and noise settings")
        ps = float(np.sqrt(max(P[0, 0], P[1, 1], P[2, 2], 0.0)))
        if ps > self.config.max_position_std_m or np.linalg.norm(x[3:6]) > 500.0:
            raise DivergenceError(
                f"navigation filter diverged at {where}: position sigma {ps:.3g} m, speed "
                f"{np.linalg.norm(x[3:6]):.3g} m/s; check the IMU units (units=...) and the "
                "noise settings, or give GNSS")

    def _mag_epochs(self, t: np.ndarray, flux: np.ndarray | None, r_mag: np.ndarray,
                    hosts: np.ndarray, imu_rows: np.ndarray, last_imu: np.ndarray,
                    gyro: np.ndarray, cum_ang: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rows at which to fuse the magnetometer, and the field vector to fuse there.

        With ``mag_on_epochs``, each magnetometer update rides on an epoch the filter makes
        anyway (flow, range, GNSS; decimated to ``mag_interval_s``) with the magnetometer
        sample nearest to it, within half a magnetometer interval: one update instead of two.
        Either way the vector is rotated by the body rotation (gyro) from its own time to the
        time of the state it is fused with (the last IMU sample), so neither the shift nor the
        IMU interval biases the heading in a turn.
        """
        if flux is None:
            return r_mag, np.zeros((0, 3))
        c = self.config
        src = r_mag
        if c.mag_on_epochs and hosts.size:
            all_mag = np.flatnonzero(np.isfinite(flux).all(axis=1) & (last_imu >= 0))
            all_mag = all_mag[all_mag > imu_rows[0]]
            if all_mag.size > 1:
                half = 0.5 * float(np.median(np.diff(t[all_mag])))
                dec = decimate_rows(t, hosts, c.mag_interval_s)
                k = np.clip(np.searchsorted(t[all_mag], t[dec]), 1, all_mag.size - 1)
                left, right = all_mag[k - 1], all_mag[k]
                pick = np.where(np.abs(t[left] - t[dec]) <= np.abs(t[right] - t[dec]), left,
                                right)
                ok = np.abs(t[pick] - t[dec]) <= half + 1e-9
                r_mag, src = dec[ok], pick[ok]
        if r_mag.size == 0:
            return r_mag, np.zeros((0, 3))
        # Body angle at a time: the cumulative angle at the last IMU sample before it plus the
        # next sample's rate over the remainder.
        def angle_at(rows: np.ndarray) -> np.ndarray:
            li = last_imu[rows]
            nxt = imu_rows[np.minimum(np.searchsorted(imu_rows, li, side="right"),
                                      imu_rows.size - 1)]
            return cum_ang[li] + gyro[nxt] * (t[rows] - t[li])[:, None]

        dtheta = cum_ang[last_imu[r_mag]] - angle_at(src)       # from the sample to the state
        R = rotation_matrices(dtheta)
        fused = np.einsum("kji,kj->ki", R, flux[src])          # R^T m: the field at the state
        return r_mag, fused

    def _fuse(self, t: float, e: Epoch) -> None:
        """Gate and fuse every measurement of one epoch in one joint update."""
        c = self.config
        ukf = self.ukf
        x = ukf.x
        C = dcm_body_to_ned(x[6], x[7], x[8])
        cz = float(C[2, 2])
        tilt_ok = cz >= np.cos(np.deg2rad(c.max_tilt_deg))
        blocks: list[tuple[str, np.ndarray, object, np.ndarray, tuple[int, ...]]] = []
        use = self.sensors
        st = self.innovations
        sh = c.gps_cep_m / 1.1774
        if e.gps_pos is not None and "gps_pos" in use:
            blocks.append(("gps_pos", e.gps_pos, h_gnss_pos,
                           np.diag([sh**2, sh**2, c.gps_vert_noise_m**2]), ()))
        if e.gps_vel is not None and "gps_vel" in use:
            blocks.append(("gps_vel", e.gps_vel, h_gnss_vel,
                           np.eye(3) * c.gps_vel_noise_ms**2, ()))
        if e.range_m is not None and "range" in use:
            r = e.range_m
            if not (c.range_min_m <= r < c.range_max_m) or not tilt_ok:
                st["range"].n_gated += 1
            elif not self._ground_set:
                self._init_ground(r * cz)
                self._last_range_t = t
            else:
                self._last_range_t = t
                ig = self.ig
                blocks.append(("range", np.array([r]), lambda X, ig=ig: h_range(X, ig),
                               np.array([[c.range_noise_m**2]]), ()))
        if e.flow is not None and "flow" in use:
            dist = (x[self.ig] - x[2]) / max(cz, 1e-6) if self._ground_set else None
            if not tilt_ok or dist is None or dist < c.flow_min_distance_m:
                st["flow"].n_gated += 1
            else:
                dg, wm = self.ig, e.flow_gyro
                lag = np.zeros(3) if e.flow_vel_lag is None else e.flow_vel_lag
                var = ((c.flow_noise_ms / dist) ** 2
                       + np.deg2rad(self.gyro_noise_dps) ** 2 * self._dt_imu
                       / max(e.flow_interval_s, self._dt_imu))
                blocks.append(("flow", e.flow,
                               lambda X, dg=dg, wm=wm, lag=lag: h_flow(X, wm, dg, lag),
                               np.eye(2) * var, ()))
        if e.baro is not None and "baro" in use:
            if not c.baro_with_range and t - self._last_range_t < _RANGE_RECENT_S:
                st["baro"].n_gated += 1
            elif self.baro_offset is None:
                self._init_baro(float(e.baro))
            else:
                ib = self.ib
                blocks.append(("baro", np.array([e.baro]), lambda X, ib=ib: h_baro(X, ib),
                               np.array([[c.baro_noise_m**2]]), ()))
        if e.grav_acc is not None and "gravity" in use:
            v = x[3:6].copy()
            prev, self._last_grav = self._last_grav, (t, v)
            acc_est = (np.inf if prev is None or t <= prev[0]
                       else float(np.linalg.norm(v - prev[1]) / (t - prev[0])))
            if (abs(np.linalg.norm(e.grav_acc) - GRAVITY) > c.gravity_max_force_dev_ms2
                    or np.linalg.norm(e.grav_rate) > np.deg2rad(c.gravity_max_rate_dps)
                    or acc_est > c.gravity_max_accel_ms2):
                st["gravity"].n_gated += 1
            else:
                var = ((self.accel_noise_g * GRAVITY) ** 2 * self._dt_imu
                       / max(e.grav_interval_s, self._dt_imu) + c.gravity_noise_ms2**2)
                ab = c.accel_bias
                blocks.append(("gravity", e.grav_acc, lambda X, ab=ab: h_gravity(X, ab),
                               np.eye(3) * var, ()))
        if e.flux is not None and "mag" in use:
            ref = self.mag_ref
            mn = float(np.linalg.norm(e.flux))
            fref = float(np.linalg.norm(ref)) if ref is not None else np.nan
            ok = np.isfinite(fref) and abs(mn - fref) <= c.mag_field_tolerance * fref
            if ok:
                inc_ref = np.arcsin(ref[2] / fref)
                inc = np.arcsin(np.clip((C @ e.flux)[2] / mn, -1, 1))
                ok = abs(inc - inc_ref) <= np.deg2rad(c.mag_inclination_tolerance_deg)
            if not ok:
                st["mag"].n_gated += 1
            else:
                fl, decl = e.flux, self._declination()
                blocks.append(("mag", np.zeros(1),
                               lambda X, fl=fl, decl=decl, mb=self.imb:
                               h_mag_heading(X, fl, decl, mb),
                               np.array([[np.deg2rad(c.mag_heading_noise_deg) ** 2]]), (0,)))
        if blocks:
            self._update_blocks(blocks)

    def _update_blocks(self, blocks: list) -> None:
        ukf = self.ukf
        X, Wm, Wc = ukf.sigma_points()
        preds = [np.asarray(h(X), dtype=np.float64) for _, _, h, _, _ in blocks]
        keep = []
        for b, Z in zip(blocks, preds, strict=True):
            name, z, _, R, aidx = b
            zp = Wm @ Z
            dZ = Z - zp
            nu = z - zp
            if aidx:
                ia = list(aidx)
                zp[ia] = np.arctan2(Wm @ np.sin(Z[:, ia]), Wm @ np.cos(Z[:, ia]))
                dZ = np.mod(Z - zp + np.pi, 2 * np.pi) - np.pi
                nu = np.mod(z - zp + np.pi, 2 * np.pi) - np.pi
            Pzz = (Wc[:, None] * dZ).T @ dZ
            scale = self.noise_scale.get(name, 1.0)
            S = Pzz + scale * R
            nis = float(nu @ np.linalg.solve(S, nu))
            if not np.isfinite(nis):
                raise DivergenceError(f"filter diverged at t = {ukf.time_s:.3f} s: non-finite"
                                      f" innovation of {name}")
            stats = self.innovations[name]
            n_rej = self._rejections.get(name, 0)
            dof = z.size
            now = float(ukf.time_s)
            if n_rej == 0:
                self._reject_since[name] = now
            k2 = self._huber_bound(dof)
            # GNSS: a receiver's jump lasts seconds.  Once a fix was refused as a gross fault,
            # the following ones are refused beyond the Huber bound too, for up to
            # gps_relock_s: otherwise the position walk grows the covariance until the
            # jumped fixes pass the gross gate and, down-weighted but one after another, drag
            # the track onto the jump (a 20-m, 10-s jump at 5 Hz: 13 m off on the
            # independent simulator of tests/test_nav_independent.py; 2 m with this rule).
            wait = self.config.gps_relock_s if name.startswith("gps") else 0.0
            in_run = n_rej > 0 and now - self._reject_since.get(name, now) < wait
            if (nis > self._gross_gate(dof) or (in_run and nis > k2)) and (
                    n_rej < self.config.max_rejections or in_run):
                stats.n_rejected += 1        # a gross fault: not fused
                self._rejections[name] = n_rej + 1
                continue
            if n_rej >= self.config.max_rejections:
                self._warn(f"{name}: {n_rej} measurements in a row were gross outliers;"
                           " fused the next one (down-weighted) so the filter re-locks")
            self._rejections[name] = 0
            stats.n_fused += 1
            stats.nis_sum += nis
            R_eff = scale * R
            if self.config.robust == "huber" and nis > k2:
                # Huber weight w = k / d on the Mahalanobis distance d: the innovation
                # covariance is inflated to S / w (R absorbs the inflation).
                stats.n_downweighted += 1
                R_eff = S * np.sqrt(nis / k2) - Pzz
            if self.config.adaptive_noise:
                # Innovation-based adaptive estimation of the noise level, bounded: the
                # variance scale follows the mean of the (Huber-clipped) NIS per dof.
                r = min(nis, k2) / dof
                a = self.config.adaptive_rate
                self.noise_scale[name] = min(max(scale * (1.0 + a * (r - 1.0)), 1.0),
                                             self.config.adaptive_max_scale)
            keep.append((z, Z, R_eff, aidx))
        if not keep:
            return
        z = np.concatenate([k[0] for k in keep])
        Z = np.concatenate([k[1] for k in keep], axis=1)
        R = np.zeros((z.size, z.size))
        aidx: list[int] = []
        o = 0
        for zk, _, Rk, ak in keep:
            m = zk.size
            R[o:o + m, o:o + m] = Rk
            aidx += [o + a for a in ak]
            o += m
        ukf.update_from_sigma(z, X, Z, Wm, Wc, R, tuple(aidx), name="_joint", gate=None)
