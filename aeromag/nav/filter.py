"""The navigation filter: a 12-state (15 with accelerometer biases) unscented Kalman filter.

State (SI units, angles in rad)::

    0..2   position, local north-east-down, m
    3..5   velocity NED, m/s
    6..8   roll, pitch, yaw (Z-Y-X Euler angles of the body in NED)
    9..11  gyro biases, rad/s (random walk)
    12..14 accelerometer biases, m/s² (``NavConfig.accel_bias``; random walk)
    last   ground level: the down coordinate of the flat ground under the vehicle, m (set
           from the first valid range, correlated with the height as that sum is, so the
           rangefinder's datum error stays in the covariance; a slow random walk)

The study's filter has the first twelve; the ground level is the one state added, because a
flat-ground datum fixed once would make the vertical covariance (and the GNSS height
innovations) inconsistent.

The process is the strapdown mechanisation of :mod:`aeromag.nav.mechanization` driven by
the gyro and accelerometer at the IMU rate; the accelerometer error is white (as in the
study) unless its biases are estimated.  Measurements are fused at their own rates with the
models of :mod:`aeromag.nav.models`: optical flow, rangefinder, barometer, the gravity
vector, magnetic north and GNSS position and velocity.

How a run is organised (the speed of a Python filter is the number of numpy calls):

* all ``2n + 1`` sigma points are propagated at once, and all IMU samples between two
  measurement epochs in one call (:func:`aeromag.nav.mechanization.propagate`): the
  unscented *predict* (sigma points -> mean and covariance, plus the process noise of the
  whole interval) runs once per epoch, not once per IMU sample;
* every measurement of one epoch (row) is fused in one joint update (block-diagonal noise;
  each sensor gated on its own normalised innovation squared first).

A measurement on a row between two IMU samples is fused at the state of the last IMU
sample at or before it (at most one IMU interval early: 4 ms at 250 Hz).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence

import numpy as np

from .._core.sequential import InnovationStats, SequentialResult, Step
from .config import NavConfig
from .fusion import _RANGE_RECENT_S, FusionMixin
from .inputs import (
    Epoch,
    NavInputs,
    decimate_rows,
    flow_to_interval_end,
    imu_noise_from_data,
    magnetic_reference_from_log,
)
from .mechanization import GRAVITY, propagate
from .startup import StartupMixin
from .ukf import UnscentedKalmanFilter

log = logging.getLogger(__name__)

__all__ = ["ALL_SENSORS", "NavFilter", "NavInputs", "magnetic_reference_from_log"]

STATE_NAMES = ("n_m", "e_m", "d_m", "vn_ms", "ve_ms", "vd_ms", "roll_rad", "pitch_rad",
               "yaw_rad", "bgx_rads", "bgy_rads", "bgz_rads")
ACCEL_BIAS_NAMES = ("bax_ms2", "bay_ms2", "baz_ms2")
#: Measurement models the filter knows (``NavFilter(sensors=...)``).
ALL_SENSORS = ("gps_pos", "gps_vel", "range", "flow", "baro", "gravity", "mag")
_MAX_BATCH = 512  # IMU samples per propagation call at most


class NavFilter(StartupMixin, FusionMixin):
    """Inertial navigation aided by flow, range, barometer, gravity, magnetic north and GNSS.

    Parameters
    ----------
    config : NavConfig, optional
        Noise, gates, rates (defaults: the study's sensor table).
    mag_reference_ned_nT : array_like, shape (3,), optional
        Earth field in NED, nT (from IGRF or explicit); its direction gives the declination.
        When absent, :func:`magnetic_reference_from_log` derives strength and inclination
        from the log (declination 0: yaw magnetic).
    sensors : sequence of str, optional
        Measurement models to use (default :data:`ALL_SENSORS`); ``()`` runs the IMU alone.
    declination_deg : float, optional
        Magnetic declination, ° east, used with the strength and inclination found in the
        log when ``mag_reference_ned_nT`` is absent (an uncalibrated magnetometer's field
        strength differs from IGRF's; its heading does not).

    Notes
    -----
    The package's sequential convention (:mod:`aeromag._core.sequential`): ``run``
    processes a whole log (fast path) -> ``SequentialResult``; ``step(y, u)`` processes one
    row online -> ``Step`` and gives the same estimates to within rounding of the
    process-noise timing (tested; the IMU noise is then the configured one, not sized from
    the log).
    """

    def __init__(self, config: NavConfig | None = None,
                 mag_reference_ned_nT: np.ndarray | None = None,
                 sensors: Sequence[str] | None = None,
                 declination_deg: float | None = None) -> None:
        self.config = config or NavConfig()
        self.declination_deg = None if declination_deg is None else float(declination_deg)
        self.sensors = tuple(ALL_SENSORS if sensors is None else sensors)
        unknown = set(self.sensors) - set(ALL_SENSORS)
        if unknown:
            raise ValueError(f"unknown sensors {sorted(unknown)}; known: {ALL_SENSORS}")
        self.mag_ref = (None if mag_reference_ned_nT is None
                        else np.asarray(mag_reference_ned_nT, dtype=np.float64))
        self._layout(mag_bias=False)
        self.ukf: UnscentedKalmanFilter | None = None
        self.baro_offset: float | None = None
        self.warnings: list[str] = []
        self._dt_imu = 0.004
        self._last_range_t = -np.inf
        self._last_grav: tuple[float, np.ndarray] | None = None
        self._online: dict = {}
        self._gates: dict[tuple[str, int], float] = {}
        self.gyro_noise_dps = self.config.gyro_noise_dps
        self._pos_walk = 0.0
        self.accel_noise_g = self.config.accel_noise_g

    # ------------------------------------------------------------------ set-up
    def _layout(self, mag_bias: bool) -> None:
        """State layout: the study's 12 (15), the magnetometer heading bias, ground, datum."""
        base = 15 if self.config.accel_bias else 12
        self.imb = base if mag_bias else None   # magnetometer heading bias, rad
        self.n = base + (1 if mag_bias else 0) + 2
        self.ig = self.n - 2  # ground level (down coordinate of the flat ground), m
        self.ib = self.n - 1  # barometer datum: baro_alt + p_d, m (a random walk: drift)
        self.names = (STATE_NAMES + (ACCEL_BIAS_NAMES if self.config.accel_bias else ())
                      + (("mag_bias_rad",) if mag_bias else ())
                      + ("ground_d_m", "baro_offset_m"))

    def _noise_rates(self) -> np.ndarray:
        """Diagonal process noise per second of flight."""
        c = self.config
        q = np.zeros(self.n)
        q[3:6] = (self.accel_noise_g * GRAVITY) ** 2 * self._dt_imu
        q[6:9] = np.deg2rad(self.gyro_noise_dps) ** 2 * self._dt_imu
        q[9:12] = np.deg2rad(c.gyro_bias_walk_dps_rt_s) ** 2
        if c.accel_bias:
            q[12:15] = c.accel_bias_walk_ms2_rt_s ** 2
        q[0:2] = self._pos_walk ** 2
        if self.imb is not None:
            q[self.imb] = np.deg2rad(c.mag_bias_walk_deg_rt_s) ** 2
        q[self.ig] = c.ground_walk_m_rt_s ** 2
        q[self.ib] = c.baro_walk_m_rt_s ** 2
        return q

    def _warn(self, msg: str) -> None:
        if msg not in self.warnings:
            self.warnings.append(msg)
            log.warning("%s", msg)

    # ------------------------------------------------------------------ predict
    def _propagate(self, gyro: np.ndarray, acc: np.ndarray, dt: np.ndarray,
                   keep_path: bool) -> tuple[np.ndarray, np.ndarray] | None:
        """Propagate through IMU samples; return per-sample (mean, std) when asked.

        Between epochs the position and velocity sigma come from the sigma points; the other
        states carry the last epoch's sigma plus their process noise.
        """
        ukf = self.ukf
        X, Wm, Wc = ukf.sigma_points()
        P0 = np.diag(ukf.P).copy()
        Xe, mom = propagate(X, gyro, acc, dt, self.config.accel_bias,
                            (Wm, Wc) if keep_path else None)
        T = float(dt.sum())
        out = None
        if mom is not None:
            m, var6 = mom
            grow = np.cumsum(dt)[:, None] * self._qrate[None, :]
            var = P0[None, :] + grow
            var[:, 0:6] = var6 + grow[:, 0:6]
            out = (m, np.sqrt(np.clip(var, 0.0, None)))
        ukf.set_from_sigma(Xe, Wm, Wc, np.diag(self._qrate * T))
        ukf.time_s += T
        return out

    # ------------------------------------------------------------------ online
    def step(self, y: Mapping[str, object], u: Sequence[np.ndarray] | None = None) -> Step:
        """Process one row of the log: the sequential convention's ``step(y, u)``.

        Parameters
        ----------
        y : mapping
            The row's time and measurements: ``time`` (s, required) and any of ``flow``
            (rad/s, 2), ``flow_quality``, ``range_m`` (m), ``baro_alt`` (m), ``flux`` (nT, 3),
            ``gps_ned`` (m, 3), ``gps_vel`` (m/s, 3); missing or None: no sample.
        u : (gyro, acc), optional
            The row's IMU sample: body rate (rad/s) and specific force (m/s²).

        Returns
        -------
        Step
            State and one-sigma after the row (``used``: a measurement was fused).

        Notes
        -----
        The filter must have been started (:meth:`start`), or it starts itself on the first
        IMU sample (level from that one sample).
        """
        t = float(y["time"])
        gyro, acc = (None, None) if u is None else u
        flow, flow_quality = y.get("flow"), y.get("flow_quality")
        range_m, baro_alt, flux = y.get("range_m"), y.get("baro_alt"), y.get("flux")
        gps_ned, gps_vel = y.get("gps_ned"), y.get("gps_vel")
        fused_before = sum(s.n_fused for s in getattr(self, "innovations", {}).values())
        on = self._online
        imu = (gyro is not None and acc is not None and np.all(np.isfinite(gyro))
               and np.all(np.isfinite(acc)))
        if self.ukf is None:
            if not imu:
                raise ValueError("the first row given to step must carry the IMU, or call "
                                 "start() first")
            self.start(t, np.asarray(acc, float), None if flux is None else np.asarray(flux))
            on.clear()
            on.update(t_imu=t, cum_ang=np.zeros(3), cum_acc=np.zeros(3), t_flow=None,
                      ang_flow=np.zeros(3), t_grav=t, acc_grav=np.zeros(3),
                      ang_grav=np.zeros(3), t_mag=-np.inf, t_baro=-np.inf, cum_v=np.zeros(3),
                      v_flow=np.zeros(3))
            return self._step_out(False)
        if not on:
            t0 = self.ukf.time_s
            on.update(t_imu=t0, cum_ang=np.zeros(3), cum_acc=np.zeros(3), t_flow=None,
                      ang_flow=np.zeros(3), t_grav=t0, acc_grav=np.zeros(3),
                      ang_grav=np.zeros(3), t_mag=-np.inf, t_baro=-np.inf, cum_v=np.zeros(3),
                      v_flow=np.zeros(3))
        c = self.config
        if imu:
            dt = t - on["t_imu"]
            if dt > 0:
                g, a = np.asarray(gyro, float), np.asarray(acc, float)
                self._propagate(g[None], a[None], np.array([dt]), keep_path=False)
                on["t_imu"] = t
                on["cum_ang"] = on["cum_ang"] + g * dt
                on["cum_acc"] = on["cum_acc"] + a * dt
                on["cum_v"] = on["cum_v"] + self.ukf.x[3:6] * dt
        e = Epoch()
        if gps_ned is not None and np.all(np.isfinite(gps_ned)):
            e.gps_pos = np.asarray(gps_ned, float)
        if gps_vel is not None and np.all(np.isfinite(gps_vel)):
            e.gps_vel = np.asarray(gps_vel, float)
        if range_m is not None and np.isfinite(range_m):
            e.range_m = float(range_m)
        if flow is not None and np.all(np.isfinite(flow)):
            t_prev = on["t_flow"]
            q_ok = flow_quality is None or (np.isfinite(flow_quality)
                                            and flow_quality >= max(c.flow_min_quality, 1))
            if t_prev is not None and q_ok:
                T = on["t_imu"] - t_prev
                e.flow_interval_s = max(t - t_prev, 1e-6)
                e.flow_gyro = ((on["cum_ang"] - on["ang_flow"]) / T if T > 0
                               else np.asarray(gyro if gyro is not None else np.zeros(3), float))
                e.flow = np.asarray(flow, float)
                if T > 0:
                    e.flow_vel_lag = self.ukf.x[3:6] - (on["cum_v"] - on["v_flow"]) / T
            elif not q_ok and "flow" in self.innovations:
                self.innovations["flow"].n_gated += 1
            on["t_flow"], on["ang_flow"] = on["t_imu"], on["cum_ang"].copy()
            on["v_flow"] = on["cum_v"].copy()
        if baro_alt is not None and np.isfinite(baro_alt) and t - on["t_baro"] >= (
                c.baro_interval_s - 1e-9):
            e.baro, on["t_baro"] = float(baro_alt), t
        if flux is not None and np.all(np.isfinite(flux)) and t - on["t_mag"] >= (
                c.mag_interval_s - 1e-9):
            e.flux, on["t_mag"] = np.asarray(flux, float), t
        if imu and on["t_imu"] - on["t_grav"] >= c.gravity_interval_s - 1e-9:
            T = on["t_imu"] - on["t_grav"]
            e.grav_acc = (on["cum_acc"] - on["acc_grav"]) / T
            e.grav_rate = (on["cum_ang"] - on["ang_grav"]) / T
            e.grav_interval_s = T
            on["t_grav"], on["acc_grav"], on["ang_grav"] = (
                on["t_imu"], on["cum_acc"].copy(), on["cum_ang"].copy())
        self._fuse(t, e)
        self._check(t)
        return self._step_out(sum(s.n_fused for s in self.innovations.values()) > fused_before)

    def _step_out(self, used: bool) -> Step:
        return Step(state=self.ukf.x.copy(), std=np.sqrt(np.clip(np.diag(self.ukf.P), 0, None)),
                    innovation=np.zeros(0), used=used)

    # ------------------------------------------------------------------ batch
    def run(self, inputs: NavInputs, keep_cov: bool = False) -> SequentialResult:
        """Run the filter over a whole multi-rate log.

        Parameters
        ----------
        inputs : NavInputs
            The sensor arrays on the log's rows.
        keep_cov : bool
            Keep the full covariance after every measurement epoch (``info["cov"]``, at the
            rows ``info["cov_index"]``).

        Returns
        -------
        SequentialResult
            Estimate and one-sigma at every row (rows before the first IMU sample carry the
            initial state), per-sensor innovation statistics, and ``info`` (ground level,
            barometer offset, reference field, noise used, warnings).

        Raises
        ------
        ValueError
            Fewer than two IMU samples.
        DivergenceError
            The estimate stopped being finite or plausible (one line, with the time).
        """
        c = self.config
        t = np.asarray(inputs.time_s, dtype=np.float64)
        N = t.size
        gyro = np.asarray(inputs.gyro, dtype=np.float64)
        acc = np.asarray(inputs.acc, dtype=np.float64)
        imu = np.isfinite(gyro).all(axis=1) & np.isfinite(acc).all(axis=1)
        imu_rows = np.flatnonzero(imu)
        if imu_rows.size < 2:
            raise ValueError("fewer than two IMU samples (gyro_x..z and acc_x..z on a row)")
        dt = np.zeros(N)
        dt[imu_rows[1:]] = np.diff(t[imu_rows])
        dt_med = float(np.median(np.diff(t[imu_rows])))
        if c.imu_noise_from_data:
            g_dps, a_g = imu_noise_from_data(gyro[imu_rows], acc[imu_rows])
            self.gyro_noise_dps = max(c.gyro_noise_dps, g_dps)
            self.accel_noise_g = max(c.accel_noise_g, a_g)
        i0 = int(imu_rows[0])
        dt[i0] = dt_med
        # Cumulative delta angle and delta velocity at the IMU rows (for interval means).
        cum_ang = np.cumsum(np.where(imu[:, None], gyro, 0.0) * dt[:, None], axis=0)
        cum_acc = np.cumsum(np.where(imu[:, None], acc, 0.0) * dt[:, None], axis=0)
        last_imu = np.maximum.accumulate(np.where(imu, np.arange(N), -1))

        flux = None if inputs.flux is None else np.asarray(inputs.flux, dtype=np.float64)
        if flux is not None and self.mag_ref is None:   # also to align the yaw at the start
            ref, n_used = magnetic_reference_from_log(t, acc, gyro, flux)
            if n_used and self.declination_deg is not None:
                d = np.deg2rad(self.declination_deg)
                self.mag_ref = np.array([ref[0] * np.cos(d), ref[0] * np.sin(d), ref[2]])
                log.info("reference field: strength and inclination from the log's first"
                         " minute (%d calm samples), declination %.2f° given", n_used,
                         self.declination_deg)
            elif n_used:
                self.mag_ref = ref
                self._warn("no reference field given: strength and inclination from the log's"
                           f" first minute ({n_used} calm samples), declination unknown (yaw"
                           " is magnetic); give date='YYYY-MM-DD' or earth_field=(F, I, D)"
                           " for a true yaw")
            else:
                self._warn("no calm samples in the first minute to find the Earth field: the"
                           " magnetometer is not used; give date='YYYY-MM-DD' or"
                           " earth_field=(F, I, D)")
        win = imu_rows[t[imu_rows] <= t[i0] + c.init_seconds]
        acc0 = acc[win].mean(axis=0)
        flux0 = None
        if flux is not None:
            fr = np.flatnonzero(np.isfinite(flux).all(axis=1) & (t <= t[i0] + c.init_seconds))
            if fr.size:
                flux0 = flux[fr].mean(axis=0)
        head0 = None
        if inputs.heading_deg is not None:
            hh = np.asarray(inputs.heading_deg, float)
            fin = np.flatnonzero(np.isfinite(hh))
            head0 = float(hh[fin[0]]) if fin.size else None
        vel0 = None
        if inputs.gps_vel is not None:
            gv = np.asarray(inputs.gps_vel, float)
            use0 = (np.ones(N, bool) if inputs.gps_use is None else
                    np.asarray(inputs.gps_use, bool))
            fin = np.flatnonzero(np.isfinite(gv).all(axis=1) & use0 & (t <= t[i0] + 1.0))
            vel0 = gv[fin[0]] if fin.size and "gps_vel" in self.sensors else None
        has_fix = inputs.gps_ned is not None and bool(
            np.isfinite(np.asarray(inputs.gps_ned, float)).all(axis=1).any())
        pos_std = (c.gps_cep_m / 1.1774, c.gps_vert_noise_m) if has_fix else None
        n_fix_used = 0
        if has_fix and "gps_pos" in self.sensors:
            gu = np.ones(N, bool) if inputs.gps_use is None else np.asarray(inputs.gps_use, bool)
            n_fix_used = int((np.isfinite(np.asarray(inputs.gps_ned, float)).all(axis=1)
                              & gu).sum())
        self._pos_walk = c.gps_walk_m_rt_s if n_fix_used > 1 else 0.0
        n_vel_used = 0
        if inputs.gps_vel is not None and "gps_vel" in self.sensors and "mag" in self.sensors:
            gu = np.ones(N, bool) if inputs.gps_use is None else np.asarray(inputs.gps_use, bool)
            n_vel_used = int((np.isfinite(np.asarray(inputs.gps_vel, float)).all(axis=1)
                              & gu).sum())
        self._layout(mag_bias=c.mag_bias_init_deg > 0 and n_vel_used > 10)
        self.start(t[i0], acc0, flux0, head0, vel0, imu_dt_s=dt_med, pos_std_m=pos_std)

        # Measurement rows, per sensor.
        def rows_of(arr: np.ndarray | None, ncol: int) -> np.ndarray:
            if arr is None:
                return np.zeros(0, dtype=np.intp)
            a = np.asarray(arr, dtype=np.float64).reshape(N, ncol)
            return np.flatnonzero(np.isfinite(a).all(axis=1) & (np.arange(N) > i0))

        gps_use = (np.ones(N, bool) if inputs.gps_use is None
                   else np.asarray(inputs.gps_use, bool))
        r_gpsp = rows_of(inputs.gps_ned, 3)
        r_gpsp = r_gpsp[gps_use[r_gpsp]]
        if has_fix:
            # The local frame's origin is a fix (position 0, its accuracy the initial sigma):
            # fusing that fix again would count its information twice (sigma / sqrt 2).
            gn = np.asarray(inputs.gps_ned, float)
            first = np.flatnonzero(np.isfinite(gn).all(axis=1) & gps_use)
            if first.size and np.all(np.abs(gn[first[0]]) < 1e-6):
                r_gpsp = r_gpsp[r_gpsp != first[0]]
        r_gpsv = rows_of(inputs.gps_vel, 3)
        r_gpsv = r_gpsv[gps_use[r_gpsv]]
        r_range = rows_of(inputs.range_m, 1)
        flow_in, fq_in = inputs.flow, inputs.flow_quality
        if flow_in is not None and c.flow_stamp == "middle":
            flow_in, fq_in = flow_to_interval_end(t, np.asarray(flow_in, float).reshape(N, 2),
                                                  fq_in)
        r_flow_all = rows_of(flow_in, 2)
        if fq_in is not None and r_flow_all.size:
            q = np.asarray(fq_in, float)[r_flow_all]
            qok = np.isfinite(q) & (q >= max(c.flow_min_quality, 1))
        else:
            qok = np.ones(r_flow_all.size, bool)
        r_baro = decimate_rows(t, rows_of(inputs.baro_alt, 1), c.baro_interval_s)
        if not c.baro_with_range and r_range.size and r_baro.size and "range" in self.sensors:
            # Barometer samples while the rangefinder is valid are not fused: no epoch for them.
            rv = np.asarray(inputs.range_m, float)[r_range]
            t_ok = t[r_range[(rv >= c.range_min_m) & (rv < c.range_max_m)]]
            k = np.searchsorted(t_ok, t[r_baro], side="right") - 1
            recent = (k >= 0) & (t[r_baro] - t_ok[np.maximum(k, 0)] < _RANGE_RECENT_S)
            if "baro" in self.innovations:
                self.innovations["baro"].n_gated += int(recent.sum())
            r_baro = r_baro[~recent]
        r_mag = decimate_rows(t, rows_of(flux, 3), c.mag_interval_s)
        # Flow: body rate averaged over the interval since the previous flow sample.
        flow_gyro = np.zeros((r_flow_all.size, 3))
        flow_T = np.full(r_flow_all.size, 0.1)
        if r_flow_all.size:
            li = last_imu[r_flow_all]
            prev_li = np.r_[li[0], li[:-1]]
            T = t[li] - t[prev_li]
            ang = cum_ang[li] - cum_ang[prev_li]
            good = T > 0
            flow_gyro[good] = ang[good] / T[good, None]
            flow_gyro[~good] = gyro[li[~good]]
            flow_T = np.r_[0.1, np.diff(t[r_flow_all])]
            qok[0] = False  # the first sample has no known interval
        self.innovations.get("flow", InnovationStats(2)).n_gated += int((~qok).sum())
        flow_prev = np.r_[i0, r_flow_all[:-1]][qok] if r_flow_all.size else r_flow_all
        r_flow = r_flow_all[qok]
        flow_gyro, flow_T = flow_gyro[qok], flow_T[qok]
        r_mag, flux_fused = self._mag_epochs(t, flux, r_mag, np.unique(np.concatenate(
            [r_flow, r_range, r_gpsp])), imu_rows, last_imu, gyro, cum_ang)
        # Gravity: mean specific force and rate over the interval since the previous epoch.
        # Gravity epochs ride on the other sensors' epochs when there are any (one update
        # instead of two), else on IMU rows; the interval means end at the last IMU sample.
        others = np.unique(np.concatenate([r_gpsp, r_gpsv, r_range, r_flow, r_baro, r_mag]))
        r_grav = decimate_rows(t, others if others.size else imu_rows[imu_rows > i0],
                                c.gravity_interval_s)
        li_g = last_imu[r_grav]
        prev_g = np.r_[i0, li_g[:-1]]
        Tg = t[li_g] - t[prev_g]
        ok_g = Tg > 0
        r_grav, li_g, prev_g, Tg = r_grav[ok_g], li_g[ok_g], prev_g[ok_g], Tg[ok_g]
        grav_acc = (cum_acc[li_g] - cum_acc[prev_g]) / Tg[:, None]
        grav_rate = (cum_ang[li_g] - cum_ang[prev_g]) / Tg[:, None]

        use = set(self.sensors)
        per: dict[str, np.ndarray] = {
            "gps_pos": r_gpsp if "gps_pos" in use else r_gpsp[:0],
            "gps_vel": r_gpsv if "gps_vel" in use else r_gpsv[:0],
            "range": r_range if "range" in use else r_range[:0],
            "flow": r_flow if "flow" in use else r_flow[:0],
            "baro": r_baro if "baro" in use else r_baro[:0],
            "gravity": r_grav if "gravity" in use else r_grav[:0],
            "mag": r_mag if "mag" in use and self.mag_ref is not None else r_mag[:0],
        }
        epochs = np.unique(np.concatenate(list(per.values()) + [np.zeros(0, np.intp)]))
        lookup = {k: {int(r): j for j, r in enumerate(v)} for k, v in per.items()}
        flow_arr = None if flow_in is None else np.asarray(flow_in, float)
        gps_ned = None if inputs.gps_ned is None else np.asarray(inputs.gps_ned, float)
        gps_vel = None if inputs.gps_vel is None else np.asarray(inputs.gps_vel, float)
        rng = None if inputs.range_m is None else np.asarray(inputs.range_m, float)
        baro = None if inputs.baro_alt is None else np.asarray(inputs.baro_alt, float)

        xs = np.full((N, self.n), np.nan)
        sds = np.full((N, self.n), np.nan)
        recorded = np.zeros(N, dtype=bool)
        xs[i0], sds[i0], recorded[i0] = self.ukf.x, np.sqrt(np.diag(self.ukf.P)), True
        covs: list[np.ndarray] = []
        cov_rows: list[int] = []
        pos = 1  # next IMU row (index into imu_rows) to propagate
        step_n = max(1, int(round(c.max_imu_step_s / dt_med))) if c.max_imu_step_s > 0 else 1

        def advance(upto_row: int) -> None:
            nonlocal pos
            hi = int(np.searchsorted(imu_rows, upto_row, side="right"))
            if hi <= pos:
                return
            if hi - pos > _MAX_BATCH:   # bounded memory on long stretches without epochs
                advance(int(imu_rows[pos + _MAX_BATCH - 1]))
                advance(upto_row)
                return
            rows = imu_rows[pos:hi]
            pos = hi
            if step_n > 1 and rows.size > 1:
                groups = np.arange(rows.size) // step_n
                ends = np.r_[np.flatnonzero(np.diff(groups)), rows.size - 1]
                starts = np.r_[0, ends[:-1] + 1]
                dtg = np.add.reduceat(dt[rows], starts)
                g = np.add.reduceat(gyro[rows] * dt[rows, None], starts) / dtg[:, None]
                a = np.add.reduceat(acc[rows] * dt[rows, None], starts) / dtg[:, None]
                m, s = self._propagate(g, a, dtg, keep_path=True)
                xs[rows], sds[rows] = m[groups], s[groups]
            else:
                m, s = self._propagate(gyro[rows], acc[rows], dt[rows], keep_path=True)
                xs[rows], sds[rows] = m, s
            recorded[rows] = True

        for r in epochs.tolist():
            advance(r)
            te = t[r]
            e = Epoch()
            j = lookup["gps_pos"].get(r)
            if j is not None:
                e.gps_pos = gps_ned[r]
            if lookup["gps_vel"].get(r) is not None:
                e.gps_vel = gps_vel[r]
            if lookup["range"].get(r) is not None:
                e.range_m = float(rng[r])
            j = lookup["flow"].get(r)
            if j is not None:
                e.flow, e.flow_gyro, e.flow_interval_s = flow_arr[r], flow_gyro[j], flow_T[j]
                lo = int(np.searchsorted(imu_rows, flow_prev[j], side="right"))
                hi = int(np.searchsorted(imu_rows, r, side="right"))
                if hi > lo:
                    e.flow_vel_lag = self.ukf.x[3:6] - xs[imu_rows[lo:hi], 3:6].mean(axis=0)
            if lookup["baro"].get(r) is not None:
                e.baro = float(baro[r])
            j = lookup["gravity"].get(r)
            if j is not None:
                e.grav_acc, e.grav_rate, e.grav_interval_s = grav_acc[j], grav_rate[j], Tg[j]
            j = lookup["mag"].get(r)
            if j is not None:
                e.flux = flux_fused[j]
            self._fuse(te, e)
            self._check(te, r)
            xs[r], sds[r], recorded[r] = self.ukf.x, np.sqrt(np.clip(np.diag(self.ukf.P), 0,
                                                                      None)), True
            if keep_cov:
                covs.append(self.ukf.P.copy())
                cov_rows.append(r)
        advance(N - 1)
        self._check(t[-1], N - 1)
        # Rows without their own estimate take the last one before them (or the first).
        src = np.maximum.accumulate(np.where(recorded, np.arange(N), -1))
        src = np.where(src < 0, i0, src)
        xs, sds = xs[src], sds[src]
        info = {"d_ground_m": float(self.ukf.x[self.ig]) if self._ground_set else None,
                "mag_bias_deg": (None if self.imb is None else
                                 [float(np.rad2deg(self.ukf.x[self.imb])),
                                  float(np.rad2deg(np.sqrt(self.ukf.P[self.imb,
                                                                      self.imb])))]),
                "baro_offset_m": (float(self.ukf.x[self.ib]) if self.baro_offset is not None
                                  else None),
                "mag_reference_ned_nT": None if self.mag_ref is None else self.mag_ref.tolist(),
                "declination_deg": float(np.rad2deg(self._declination())),
                "imu_interval_s": dt_med, "warnings": list(self.warnings),
                "start_time_s": float(t[i0]), "sensors": list(self.sensors),
                "gps_rows": per["gps_pos"]}
        info["noise"] = self.noise_used()
        if keep_cov:
            info["cov"] = np.array(covs)
            info["cov_index"] = np.array(cov_rows, dtype=np.intp)
        return SequentialResult(time_s=t, state=xs, std=sds, state_names=self.names,
                                loglik=np.full(N, np.nan),
                                innovations=dict(self.innovations), info=info)
