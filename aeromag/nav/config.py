"""Settings of the navigation filter: noise, gates, rates and initial uncertainties.

The noise defaults are the sensor table of the study reproduced (methods.md M4): MPU-6000
IMU (gyro 0.05 °/s, accelerometer 0.05 g), HMC5983 magnetometer (1° heading), HRLV-EZ4 sonar
(0.01 m), PX4Flow (1 cm/s), u-blox LEA-6H GPS (2.5 m CEP).  The IMU figures are taken as the
white-noise rms of one sample at the log's IMU rate (the filter turns them into noise
densities with the median IMU interval); the flow figure is a velocity, turned into rad/s by
the height at each sample.  Everything is an option; see ``docs/navigate.md``.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

__all__ = ["NavConfig"]


@dataclass
class NavConfig:
    """Navigation filter settings (units in the names).

    Attributes
    ----------
    gyro_noise_dps : float
        Gyro white noise, rms of one sample, °/s (MPU-6000: 0.05).
    accel_noise_g : float
        Accelerometer white noise, rms of one sample, g (MPU-6000: 0.05).
    gyro_bias_init_dps : float
        Initial one-sigma gyro bias, °/s.
    gyro_bias_walk_dps_rt_s : float
        Gyro bias random walk, °/s/sqrt(s).
    accel_bias : bool
        Estimate accelerometer biases (15 states instead of the study's 12; default, because
        a real MEMS accelerometer always has a bias and the 12-state filter then believes its
        tilt too well: see ``docs/navigate.md``).
    accel_bias_init_ms2 : float
        Initial one-sigma accelerometer bias, m/s².
    accel_bias_walk_ms2_rt_s : float
        Accelerometer bias random walk, m/s²/sqrt(s).
    flow_noise_ms : float
        Optical-flow noise as a ground velocity, m/s (PX4Flow: 0.01).
    flow_stamp : str
        Where a flow sample is stamped in its integration interval: ``"middle"`` (the
        interface's convention; ``run`` moves it to the interval's end) or ``"end"``.
        ``step`` (online) takes flow as stamped at the end.
    flow_min_quality : int
        Flow samples with a lower ``flow_quality`` are not used (0 is invalid).
    flow_min_distance_m : float
        No flow below this distance to the ground (the image is out of focus).
    range_noise_m : float
        Rangefinder noise, m (HRLV-EZ4: 0.01).
    range_min_m, range_max_m : float
        Valid rangefinder readings, m: at least MIN and below MAX (a reading at MAX is a
        saturated sensor; HRLV-EZ4: 0.3 to 5 m).
    gps_walk_m_rt_s : float
        Random walk of the horizontal position beyond what the velocity explains, m/sqrt(s),
        applied when a run fuses GNSS positions: a real receiver's position error is
        correlated over tens of seconds and the aided velocity has slowly varying errors
        (scale, heading), so a filter that trusts the integrated velocity fully stops
        following the fixes (the real PX4 flight: 12 m rms against GNSS without it, 3 m with
        0.3).
    ground_walk_m_rt_s : float
        Random walk of the ground level (the flat-ground state), m/sqrt(s).
    max_tilt_deg : float
        Flow and range are not used beyond this tilt (flat-ground model).
    baro_noise_m : float
        Barometer noise, m.
    baro_walk_m_rt_s : float
        Random walk of the barometer's datum (drift with weather and temperature), m/sqrt(s).
    baro_with_range : bool
        Fuse the barometer also while the rangefinder is valid (default: only without it).
    baro_interval_s, mag_interval_s, gravity_interval_s : float
        Shortest interval between two fused samples of these sensors, s.
    mag_on_epochs : bool
        Fuse the magnetometer sample nearest to an epoch the filter makes anyway (flow,
        range, GNSS), rotated by the gyro to that epoch's time: one update instead of two.
    mag_heading_noise_deg : float
        Magnetometer heading noise, ° (HMC5983: 1).
    mag_bias_init_deg : float
        Initial one-sigma of the magnetometer heading bias, ° (a state when GNSS velocity
        is fused: against it, with the flow's body velocity, the yaw is observable while the
        vehicle moves); 0: no such state.
    mag_bias_walk_deg_rt_s : float
        Random walk of that bias, °/sqrt(s).
    mag_field_tolerance : float
        Relative tolerance of the field strength against the reference (gate).
    mag_inclination_tolerance_deg : float
        Tolerance of the inclination against the reference, ° (gate).
    gravity_noise_ms2 : float
        Extra noise of the gravity-vector measurement (vibration, unmodelled acceleration),
        m/s², added to the averaged accelerometer noise.
    gravity_max_accel_ms2 : float
        No gravity update while the filter's own acceleration estimate exceeds this, m/s².
    gravity_max_force_dev_ms2 : float
        No gravity update while abs(norm of the specific force - g) exceeds this, m/s².
    gravity_max_rate_dps : float
        No gravity update while the body rate exceeds this, °/s.
    gps_cep_m : float
        GNSS horizontal accuracy, CEP (m); the per-axis sigma is CEP / 1.1774.
    gps_vert_noise_m : float
        GNSS vertical one-sigma, m.
    gps_vel_noise_ms : float
        GNSS velocity one-sigma per axis, m/s.
    init_seconds : float
        Length of the window at the start used to level (accelerometer) and to find the
        heading (magnetometer), s.
    init_pos_std_m, init_vel_std_ms, init_tilt_std_deg, init_yaw_std_deg : float
        Initial one-sigma uncertainties.
    robust : str
        ``"huber"`` (default): a measurement whose normalised innovation squared (NIS)
        exceeds the chi-square quantile ``huber_p`` is fused with the Huber weight ``k / d``
        (``d`` its Mahalanobis distance, ``k`` the bound's), i.e. its innovation covariance
        inflated by ``d / k``, instead of being thrown away; ``"none"``: plain updates.
    huber_p : float
        Probability of the chi-square quantile where the Huber weighting starts.
    gross_gate_sigma : float
        Only a measurement beyond this many sigma (as a NIS quantile of its dimension) is
        refused as a gross fault; after ``max_rejections`` in a row from one sensor the next
        one is fused (down-weighted) so the filter re-locks instead of ignoring it forever.
    max_rejections : int
        See ``gross_gate_sigma``.
    gps_relock_s : float
        GNSS only: after a fix refused as a gross fault, the following fixes are refused
        beyond the Huber bound too (not down-weighted and fused) for up to this many seconds,
        so that a receiver's jump does not drag the track while the position walk grows the
        covariance; then the next fix is fused to re-lock.  0: the ``max_rejections`` rule
        alone (PX4 EKF2 resets to GNSS after about 7 s of rejections).
    adaptive_noise : bool
        Size each measurement's noise from its innovations (bounded innovation-based
        adaptive estimation): a variance scale per sensor that follows the mean NIS per
        degree of freedom (Huber-clipped), between 1 (the configured noise is the floor) and
        ``adaptive_max_scale``.
    adaptive_rate : float
        Step of the adaptive variance scale per measurement (about ``1 / rate`` samples of
        memory).
    adaptive_max_scale : float
        Largest variance scale (1e4: a noise up to 100 times the configured one).
    imu_noise_from_data : bool
        Size the gyro and accelerometer white noise from the log (robust scale of the
        first differences of the IMU samples, vibration included), never below
        ``gyro_noise_dps`` and ``accel_noise_g``.
    max_imu_step_s : float
        Combine consecutive IMU samples into steps of at most this length (delta angles and
        delta velocities summed; coning neglected); 0 propagates every sample.
    alpha, beta, kappa : float
        Sigma-point scaling.
    max_position_std_m : float
        The run ends with an error when the position uncertainty exceeds this (diverged).
    """

    gyro_noise_dps: float = 0.05
    accel_noise_g: float = 0.05
    gyro_bias_init_dps: float = 0.5
    gyro_bias_walk_dps_rt_s: float = 0.002
    accel_bias: bool = True
    accel_bias_init_ms2: float = 0.1
    accel_bias_walk_ms2_rt_s: float = 1e-4
    flow_noise_ms: float = 0.01
    flow_stamp: str = "middle"
    flow_min_quality: int = 1
    flow_min_distance_m: float = 0.3
    range_noise_m: float = 0.01
    range_min_m: float = 0.3
    range_max_m: float = 5.0
    gps_walk_m_rt_s: float = 0.3
    ground_walk_m_rt_s: float = 0.001
    max_tilt_deg: float = 30.0
    baro_noise_m: float = 0.5
    baro_walk_m_rt_s: float = 0.01
    baro_with_range: bool = False
    baro_interval_s: float = 0.1
    mag_interval_s: float = 0.1
    gravity_interval_s: float = 0.1
    mag_on_epochs: bool = True
    mag_heading_noise_deg: float = 1.0
    mag_bias_init_deg: float = 10.0
    mag_bias_walk_deg_rt_s: float = 0.01
    mag_field_tolerance: float = 0.15
    mag_inclination_tolerance_deg: float = 5.0
    gravity_noise_ms2: float = 0.1
    gravity_max_accel_ms2: float = 0.5
    gravity_max_force_dev_ms2: float = 0.5
    gravity_max_rate_dps: float = 30.0
    gps_cep_m: float = 2.5
    gps_vert_noise_m: float = 4.0
    gps_vel_noise_ms: float = 0.1
    init_seconds: float = 1.0
    init_pos_std_m: float = 0.01
    init_vel_std_ms: float = 0.3
    init_tilt_std_deg: float = 2.0
    init_yaw_std_deg: float = 5.0
    robust: str = "huber"
    huber_p: float = 0.99
    gross_gate_sigma: float = 8.0
    max_rejections: int = 25
    gps_relock_s: float = 15.0
    adaptive_noise: bool = True
    adaptive_rate: float = 0.02
    adaptive_max_scale: float = 1e4
    imu_noise_from_data: bool = True
    max_imu_step_s: float = 0.0
    alpha: float = 1.0
    beta: float = 2.0
    kappa: float = 0.0
    max_position_std_m: float = 1e5

    def __post_init__(self) -> None:
        if self.flow_stamp not in ("middle", "end"):
            raise ValueError(f"flow_stamp must be 'middle' or 'end', got {self.flow_stamp!r}")
        if self.robust not in ("huber", "none"):
            raise ValueError(f"robust must be 'huber' or 'none', got {self.robust!r}")
        for name, value in asdict(self).items():
            if isinstance(value, bool | str):
                continue
            if not (isinstance(value, int | float) and value == value and abs(value) < 1e300):
                raise ValueError(f"{name} must be a finite number, got {value!r}")
            if value < 0:
                raise ValueError(f"{name} must not be negative, got {value!r}")
        if not 0 < self.huber_p < 1:
            raise ValueError("huber_p must be in (0, 1)")
        if not 0 < self.adaptive_rate <= 1 or self.adaptive_max_scale < 1:
            raise ValueError("adaptive_rate must be in (0, 1] and adaptive_max_scale >= 1")
        if self.range_max_m <= self.range_min_m:
            raise ValueError("range_max_m must exceed range_min_m")

    def as_dict(self) -> dict[str, float | int | bool]:
        """Plain dictionary for reports."""
        return asdict(self)
