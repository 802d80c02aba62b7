"""Start-up of :class:`aeromag.nav.NavFilter`: initial state and covariance, gates, datums.

A mixin kept apart from the filter's predict/update loop so each file reads in one sitting.
"""

from __future__ import annotations

import logging

import numpy as np
from scipy.stats import chi2

from .._core.sequential import InnovationStats
from .inputs import tilt_from_accel
from .models import level_heading
from .ukf import UnscentedKalmanFilter

log = logging.getLogger(__name__)

#: Indices of the attitude angles in the state (roll, pitch, yaw; wrapped by the filter).
ANGLES = (6, 7, 8)  # the magnetometer heading bias is small: not wrapped


class StartupMixin:
    """Initial state, covariance, gates and datums of :class:`aeromag.nav.NavFilter`."""

    def start(self, t0: float, acc_mean: np.ndarray, flux_mean: np.ndarray | None = None,
              heading_deg: float | None = None, vel_ned: np.ndarray | None = None,
              imu_dt_s: float = 0.004, pos_std_m: tuple[float, float] | None = None) -> None:
        """Initialise: level from the mean specific force, heading from the magnetometer.

        Parameters
        ----------
        t0 : float
            Start time, s.
        acc_mean : ndarray, shape (3,)
            Mean specific force over the start window, m/s².
        flux_mean : ndarray, shape (3,), optional
            Mean magnetometer vector over the window, nT (heading).
        heading_deg : float, optional
            Heading to use when there is no magnetometer, degrees true.
        vel_ned : ndarray, shape (3,), optional
            Initial velocity, m/s (default 0).
        imu_dt_s : float
            Typical IMU interval, s (turns per-sample noise into densities).
        pos_std_m : (float, float), optional
            Initial horizontal and vertical position sigma, m (default
            ``init_pos_std_m``; ``run`` gives the GNSS accuracy when the local frame's origin
            is a GNSS fix, whose own error is then the vehicle's position error).
        """
        c = self.config
        self._dt_imu = float(imu_dt_s)
        roll, pitch = tilt_from_accel(np.asarray(acc_mean, dtype=np.float64))
        yaw_std = np.deg2rad(c.init_yaw_std_deg)
        if flux_mean is not None and np.all(np.isfinite(flux_mean)) and self.mag_ref is not None:
            decl = self._declination()
            yaw = float(level_heading(np.array([roll]), np.array([pitch]), flux_mean, decl)[0])
        elif heading_deg is not None and np.isfinite(heading_deg):
            yaw = float(np.deg2rad(heading_deg))
        else:
            yaw, yaw_std = 0.0, np.deg2rad(60.0)
            self._warn("no magnetometer or heading to start from: initial yaw 0 with 60° "
                       "uncertainty")
        x0 = np.zeros(self.n)
        x0[6:9] = roll, pitch, np.mod(yaw + np.pi, 2 * np.pi) - np.pi
        if vel_ned is not None and np.all(np.isfinite(vel_ned)):
            x0[3:6] = vel_ned
        sd = np.zeros(self.n)
        sd[0:3] = c.init_pos_std_m
        if pos_std_m is not None:
            sd[0:2], sd[2] = pos_std_m
        sd[3:6] = c.init_vel_std_ms
        sd[6:8] = np.deg2rad(c.init_tilt_std_deg)
        sd[8] = yaw_std
        sd[9:12] = np.deg2rad(c.gyro_bias_init_dps)
        if c.accel_bias:
            sd[12:15] = c.accel_bias_init_ms2
        if self.imb is not None:
            sd[self.imb] = np.deg2rad(c.mag_bias_init_deg)
        sd[self.ig] = 1.0  # set from the first valid range (see _init_ground)
        sd[self.ib] = 1.0  # set from the first barometer sample (see _init_baro)
        self._ground_set = False
        self.baro_offset = None
        self.ukf = UnscentedKalmanFilter(x0, np.diag(np.maximum(sd, 1e-9) ** 2),
                                         alpha=c.alpha, beta=c.beta, kappa=c.kappa,
                                         angle_idx=ANGLES, state_names=self.names)
        self.ukf.time_s = float(t0)
        self._qrate = self._noise_rates()
        self._last_grav = None
        self._rejections: dict[str, int] = {}
        self._reject_since: dict[str, float] = {}
        self.noise_scale: dict[str, float] = dict.fromkeys(self.sensors, 1.0)
        self.innovations: dict[str, InnovationStats] = {
            s: InnovationStats(dof={"gps_pos": 3, "gps_vel": 3, "range": 1, "flow": 2,
                                    "baro": 1, "gravity": 3, "mag": 1}[s])
            for s in self.sensors}

    def _gross_gate(self, dof: int) -> float:
        """NIS beyond which a measurement is a gross fault (cached per dimension).

        The chi-square quantile of the probability of ``gross_gate_sigma`` for one degree
        of freedom (8 sigma: a consistent filter refuses about one sample in 1e15).
        """
        g = self._gates.get(("gross", dof))
        if g is None:
            p = float(chi2.cdf(self.config.gross_gate_sigma ** 2, 1))
            g = self._gates[("gross", dof)] = float(chi2.isf(1.0 - p, dof))
        return g

    def _huber_bound(self, dof: int) -> float:
        """NIS beyond which a measurement is down-weighted (chi-square ``huber_p`` quantile)."""
        g = self._gates.get(("huber", dof))
        if g is None:
            g = self._gates[("huber", dof)] = float(chi2.ppf(self.config.huber_p, dof))
        return g

    def _init_ground(self, height_m: float) -> None:
        """Set the ground level from the first valid range.

        ``d_ground = p_d + h``, correlated with ``p_d`` exactly as that sum is (so the datum
        error stays in the covariance).
        """
        ukf, ig = self.ukf, self.ig
        ukf.x[ig] = ukf.x[2] + height_m
        P = ukf.P
        P[ig, :] = P[2, :]
        P[:, ig] = P[:, 2]
        P[ig, ig] = P[2, 2] + self.config.range_noise_m ** 2
        ukf.P = P
        self._ground_set = True

    def _init_baro(self, baro_alt_m: float) -> None:
        """Set the barometer datum from its first sample used.

        ``offset = baro_alt + p_d``, correlated with ``p_d`` as that sum is, so the height's
        uncertainty at that moment (e.g. the first GNSS fix's vertical error) stays in the
        covariance instead of being frozen into the datum; the datum is then a random walk
        (``baro_walk_m_rt_s``: a barometer drifts with the weather and the temperature).
        """
        ukf, ib = self.ukf, self.ib
        ukf.x[ib] = baro_alt_m + ukf.x[2]
        P = ukf.P
        P[ib, :] = P[2, :]
        P[:, ib] = P[:, 2]
        P[ib, ib] = P[2, 2] + self.config.baro_noise_m ** 2
        ukf.P = P
        self.baro_offset = float(ukf.x[ib])

    def _declination(self) -> float:
        if self.mag_ref is None or not np.all(np.isfinite(self.mag_ref)):
            return 0.0
        return float(np.arctan2(self.mag_ref[1], self.mag_ref[0]))
