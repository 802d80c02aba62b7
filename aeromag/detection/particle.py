"""Particle-filter detector of magnetic interference: heading from the gyro vs the compass.

Model (two states: the magnetic heading ``psi`` in rad, kept unwrapped, and the gyro bias
``b`` in rad/s):

    psi_k = psi_{k-1} + dpsi_k - b_{k-1} dt_k + w_k,  w_k ~ N(0, sigma_w^2 dt)  (gyro)
    b_k   = b_{k-1} + e_k,                            e_k ~ N(0, sigma_b^2 dt)  (bias walk)
    y_k   = wrap(psi_k + v_k),                        v_k ~ N(0, sigma_y^2)     (compass)

``dpsi_k`` is the heading increment measured by the gyro over the interval ending at row
``k``: the Euler yaw rate ``(q sin(phi) + r cos(phi)) / cos(theta)`` from ``gyro_x/y/z`` and
the attitude ``pitch``/``roll``, or ``gyro_z`` alone (level), or, without a gyro, the change of
the attitude ``heading`` column (an AHRS heading partly follows the compass, so detection is
slower).  Multi-rate logs: the gyro's integrated angle is interpolated to every row; rows
without a compass sample are prediction-only.  The compass heading is ``mag_heading`` or the
tilt-compensated fluxgate heading (:func:`aeromag.detection.heading.mag_heading_from_flux`).

The bias prior is the calm window's ``-d(compass - gyro heading)/dt`` (least squares; prior
standard deviation three times its standard error, at least 0.05 deg/s; 2 deg/s without a calm
estimate).  With the bias a state of its own the heading noise ``sigma_w`` (default
0.1 deg/sqrt(s)) and the bias walk ``sigma_b`` (default 0.003 deg/s/sqrt(s)) are small: a
disturbance turning the compass at ~1 deg/s cannot be followed as "bias", the innovations
grow and the statistic ``S_k`` (sum over the last ``window`` compass samples of ``-ln`` of
the mean particle likelihood) crosses the threshold.  A restart keeps the bias learnt before
the compass left the filter.

Noise and threshold come from the log:

* ``sigma_y`` is the largest of a robust scale of the compass-minus-gyro residual (its
  deviation from a 2 s running median, 1.4826 MAD) over the whole log and over the calm
  window, and ``sigma_floor_deg``: a quiet stretch (a landed vehicle, motors off) cannot make
  the filter over-confident for the rest of the flight;
* the threshold is the calm window's largest ``S_k`` (but at least the model's own mean
  ``S_k`` and the log's median ``S_k``, so a calm window quieter than the flight cannot set
  a threshold the flight's noise alone exceeds) plus ``margin``, unless given.  The default
  margin is how far ``S_k`` of a correct model rises by chance -- half the excess of the
  ``chi^2_M`` quantile at 1e-6 over its mean -- times the ratio of the standard deviation of
  ``S_k`` (over the calm window, and robustly over the log) to the chi-square's
  ``sqrt(M/2)`` when above one (compass noise correlated in time makes ``S_k`` wander more
  than independent noise would).

Gaps longer than ``gap_s`` (default 1 s, or 20 median intervals if that is longer) restart the
filter: the statistic is NaN (no alarm) until the window is full again, so a gap never
produces an alarm storm and NaN never propagates.
"""

from __future__ import annotations

import logging
import time as _time
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import stats as _stats
from scipy.ndimage import median_filter

from .._core.angles import wrap_rad
from .._core.particles import ParticleFilter, StateSpaceModel, threshold_from_calm
from .._core.sequential import InnovationStats, SequentialResult
from ..errors import InputError
from .alarms import Alarms
from .heading import CalmWindow, calm_mask, mag_heading_from_flux
from .pf_latch import calm_bias
from .pf_latch import check_gyro_unit as _check_gyro_unit
from .pf_latch import gyro_reference as _gyro_reference

log = logging.getLogger(__name__)

__all__ = [
    "DEFAULT_PARTICLES",
    "DEFAULT_WINDOW",
    "PFDetectorInputs",
    "heading_model",
    "particle_detector",
    "pf_columns_available",
    "prepare_pf_inputs",
]

#: Default number of particles.
DEFAULT_PARTICLES = 500
#: Default window ``M`` of ``S_k``, compass samples.
DEFAULT_WINDOW = 20
#: Default heading process noise, deg / sqrt(s) (the gyro bias is a state of its own).
DEFAULT_WALK_DEG = 0.1
#: Default random walk of the gyro bias, deg/s / sqrt(s).
DEFAULT_BIAS_WALK_DEG = 0.003
#: Prior standard deviation of the gyro bias without a calm-window estimate, deg/s.
DEFAULT_BIAS_PRIOR_DEG = 2.0
#: Default floor of the compass noise, deg.
DEFAULT_SIGMA_FLOOR_DEG = 0.2
#: Fewest compass samples with a full window in the calm window.
MIN_CALM_STATS = 5
_LOG2PI = float(np.log(2.0 * np.pi))


def pf_columns_available(df: pd.DataFrame) -> tuple[str, str] | None:
    """Say whether the detector can run on ``df`` and from which columns.

    Parameters
    ----------
    df : DataFrame
        Log with canonical columns.

    Returns
    -------
    (str, str) or None
        ``(rate_source, compass_source)``: ``"gyro_xyz"``, ``"gyro_z"`` or ``"heading"``;
        ``"mag_heading"`` or ``"flux"``; None when either is missing.
    """
    cols = set(df.columns)
    tilt = {"pitch", "roll"} <= cols
    if {"gyro_x", "gyro_y", "gyro_z"} <= cols and tilt:
        rate = "gyro_xyz"
    elif "gyro_z" in cols:
        rate = "gyro_z"
    elif "heading" in cols:
        rate = "heading"
    else:
        return None
    if "mag_heading" in cols:
        comp = "mag_heading"
    elif {"flux_x", "flux_y", "flux_z"} <= cols and tilt:
        comp = "flux"
    else:
        return None
    return rate, comp


@dataclass
class PFDetectorInputs:
    """What the detector filters, per row of the log.

    Attributes
    ----------
    time_s : ndarray
        Row times, s.
    dpsi_rad : ndarray
        Gyro heading increment over the interval ending at the row, rad (finite).
    y_rad : ndarray
        Compass heading, rad in [-pi, pi) (NaN where the row has no compass sample).
    segment : ndarray of int
        Stretch id (a gap starts a new stretch).
    rate_source, compass_source : str
        Columns used (see :func:`pf_columns_available`).
    """

    time_s: np.ndarray
    dpsi_rad: np.ndarray
    y_rad: np.ndarray
    segment: np.ndarray
    rate_source: str
    compass_source: str


def _integrated_angle(t: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """Integral of a rate logged as interval means, interpolated to every row, rad."""
    ok = np.isfinite(rate)
    if ok.sum() < 2:
        return np.zeros_like(t)
    tg, rg = t[ok], rate[ok]
    ang = np.concatenate([[0.0], np.cumsum(rg[1:] * np.diff(tg))])
    return np.interp(t, tg, ang)


def prepare_pf_inputs(df: pd.DataFrame, *, declination_deg: float = 0.0,
                      gap_s: float | None = None, source: str = "<log>") -> PFDetectorInputs:
    """Gyro heading increments, compass headings and stretches of a log.

    Parameters
    ----------
    df : DataFrame
        Log with ``time`` [s], a rate source (``gyro_x/y/z`` [rad/s] with ``pitch``/``roll``
        [deg], or ``gyro_z``, or ``heading`` [deg]) and a compass (``mag_heading`` [deg] or
        ``flux_x/y/z`` [nT] with ``pitch``/``roll``).
    declination_deg : float
        Declination added to a fluxgate heading, degrees east (a constant offset: it does
        not change the statistic).
    gap_s : float, optional
        Time step that starts a new stretch, s (default ``max(1 s, 20 median steps)``).
    source : str
        File name quoted in errors.

    Returns
    -------
    PFDetectorInputs
    """
    kinds = pf_columns_available(df)
    if kinds is None:
        raise InputError(
            f"{source}: the particle-filter detector needs a gyro (gyro_z, or gyro_x/y/z with "
            "pitch and roll; or an attitude 'heading') and a compass ('mag_heading', or "
            "flux_x/y/z with pitch and roll); map them with columns={'NAME': 'SOURCE'}"
        )
    rate_src, comp_src = kinds
    t = df["time"].to_numpy(dtype=np.float64)
    if t.size < 3:
        raise InputError(f"{source}: only {t.size} row(s); the detector needs more samples")
    if np.any(np.diff(t) <= 0):
        i = int(np.flatnonzero(np.diff(t) <= 0)[0]) + 1
        raise InputError(f"{source}: column 'time' is not strictly increasing at data row {i}"
                         " (sort the log or remove duplicated rows)")
    col = {c: df[c].to_numpy(dtype=np.float64) for c in df.columns
           if c in ("gyro_x", "gyro_y", "gyro_z", "pitch", "roll", "heading", "mag_heading",
                    "flux_x", "flux_y", "flux_z")}
    if rate_src == "gyro_xyz":
        ph, th = np.deg2rad(col["roll"]), np.deg2rad(col["pitch"])
        # attitude columns may be on other rows than the gyro: interpolate them
        ph, th = (_fill_interp(t, a) for a in (ph, th))
        rate = (col["gyro_y"] * np.sin(ph) + col["gyro_z"] * np.cos(ph)) / np.maximum(
            np.cos(th), 0.1)
        ang = _integrated_angle(t, rate)
    elif rate_src == "gyro_z":
        ang = _integrated_angle(t, col["gyro_z"])
    else:
        hd = np.deg2rad(col["heading"])
        ok = np.isfinite(hd)
        if ok.sum() < 2:
            raise InputError(f"{source}: column 'heading' has fewer than 2 values")
        ang = np.interp(t, t[ok], np.unwrap(hd[ok]))
    dpsi = np.diff(ang, prepend=ang[0])
    if rate_src != "heading":
        _check_gyro_unit(t, ang, col.get("mag_heading"), source)
    if comp_src == "mag_heading":
        y = np.deg2rad(col["mag_heading"])
    else:
        y = np.deg2rad(mag_heading_from_flux(col["flux_x"], col["flux_y"], col["flux_z"],
                                             _fill_interp(t, col["pitch"]),
                                             _fill_interp(t, col["roll"]), declination_deg))
    y = np.where(np.isfinite(y), wrap_rad(np.where(np.isfinite(y), y, 0.0)), np.nan)
    if np.isfinite(y).sum() < 3:
        raise InputError(f"{source}: fewer than 3 compass headings ({comp_src}); check the "
                         "magnetometer columns")
    dt = np.diff(t)
    gap = max(1.0, 20.0 * float(np.median(dt))) if gap_s is None else float(gap_s)
    seg = np.concatenate([[0], np.cumsum(dt > gap)])
    dpsi[np.concatenate([[True], dt > gap])] = 0.0
    return PFDetectorInputs(time_s=t, dpsi_rad=dpsi, y_rad=y, segment=seg,
                            rate_source=rate_src, compass_source=comp_src)


def _fill_interp(t: np.ndarray, a: np.ndarray) -> np.ndarray:
    ok = np.isfinite(a)
    if ok.all() or not ok.any():
        return np.where(ok, a, 0.0)
    return np.interp(t, t[ok], a[ok])


def _robust_sigma(inp: PFDetectorInputs, mask: np.ndarray | None = None) -> float:
    """Robust scale of the compass-minus-gyro residual around a 2 s running median, rad."""
    scales = []
    for s in np.unique(inp.segment):
        m = (inp.segment == s) & np.isfinite(inp.y_rad)
        if mask is not None:
            m &= mask
        if m.sum() < 5:
            continue
        ang = np.cumsum(inp.dpsi_rad[inp.segment == s])
        sel = m[inp.segment == s]
        r = np.unwrap(inp.y_rad[m] - ang[sel])
        dt = np.median(np.diff(inp.time_s[m])) if m.sum() > 1 else 1.0
        width = int(max(3, min(len(r), round(2.0 / max(dt, 1e-6))) | 1))
        dev = r - median_filter(r, size=width, mode="nearest")
        scales.append((np.abs(dev - np.median(dev)), len(dev)))
    if not scales:
        return 0.0
    allv = np.concatenate([v for v, _ in scales])
    return float(1.4826 * np.median(allv))


def heading_model(sigma_y_rad: float, walk_rad: float, y0: float,
                  dt_s: float, *, bias_walk_rad: float = 0.0, b0: float = 0.0,
                  sd_b0: float = 0.0) -> StateSpaceModel:
    """The heading-and-gyro-bias model as a :class:`~aeromag._core.particles.StateSpaceModel`.

    State ``x = [psi, b]``: heading (rad, unwrapped) and gyro bias (rad/s).

    Parameters
    ----------
    sigma_y_rad : float
        Compass noise, rad.
    walk_rad : float
        Heading process noise (what the gyro's own noise adds), rad / sqrt(s).
    y0 : float
        First compass heading (the prior mean of ``psi``), rad.
    dt_s : float
        Typical step, s (the random walks' variances per step are ``walk^2 dt``).
    bias_walk_rad : float
        Random walk of the gyro bias, rad/s / sqrt(s).
    b0, sd_b0 : float
        Prior mean and standard deviation of the gyro bias, rad/s.

    Returns
    -------
    StateSpaceModel
        Control ``u = [dpsi, dt]`` (rad, s): ``psi_k = psi_{k-1} + dpsi - b dt``;
        measurement ``y = [heading]`` (rad, an angle).
    """
    r = float(sigma_y_rad) ** 2
    c = -0.5 * (np.log(r) + _LOG2PI)

    def f(x, k, u):
        psi = x[..., :1] + u[..., :1] - x[..., 1:2] * u[..., 1:2]
        return np.concatenate([psi, x[..., 1:2]], axis=-1)

    def h(x, k):
        return x[..., :1]

    def loglik(y, x, k):
        d = wrap_rad(y[..., 0] - x[..., 0])
        return c - 0.5 * d * d / r

    q = max(float(walk_rad) ** 2 * float(dt_s), 1e-14)
    qb = max(float(bias_walk_rad) ** 2 * float(dt_s), 1e-16)
    pb = max(float(sd_b0) ** 2, 1e-14)
    return StateSpaceModel(f=f, Q=[[q, 0.0], [0.0, qb]], loglik=loglik, x0=[y0, b0],
                           P0=[[4.0 * r, 0.0], [0.0, pb]], h=h, R=[[r]], angle_y=(0,))


def particle_detector(
    df: pd.DataFrame,
    *,
    n_particles: int = DEFAULT_PARTICLES,
    window: int = DEFAULT_WINDOW,
    threshold: float | None = None,
    calm_window: CalmWindow = None,
    margin: float | None = None,
    walk_deg: float = DEFAULT_WALK_DEG,
    bias_walk_deg: float = DEFAULT_BIAS_WALK_DEG,
    sigma_floor_deg: float = DEFAULT_SIGMA_FLOOR_DEG,
    proposal: str = "unscented",
    scheme: str = "genetic",
    declination_deg: float = 0.0,
    gap_s: float | None = None,
    reset_sigmas: float = 5.0,
    reset_after: int | None = None,
    seed: int = 0,
    source: str = "<log>",
) -> Alarms:
    """Run the particle-filter detector on a log.

    Parameters
    ----------
    df : DataFrame
        Log (see :func:`prepare_pf_inputs`).
    n_particles : int
        Number of particles.
    window : int
        ``M``: compass samples summed in ``S_k``.
    threshold : float, optional
        Threshold on ``S_k``; default from the calm window.
    calm_window : float, (float, float), str or None
        Calm reference window (see :func:`aeromag.detection.heading.parse_calm_window`);
        default the first 30 s.
    margin : float, optional
        Added to the calm window's largest ``S_k`` (default ``(chi2_M(1 - 1e-6) - M) / 2``
        times the calm spread ratio, see the module text).
    walk_deg : float
        Heading process noise, deg / sqrt(s).
    bias_walk_deg : float
        Random walk of the gyro bias, deg/s / sqrt(s).
    sigma_floor_deg : float
        Floor of the compass noise, deg.
    proposal, scheme : str
        Particle-filter proposal (``"unscented"`` or ``"bootstrap"``) and renewal
        (``"genetic"``, ``"systematic"``, ``"multinomial"``).
    declination_deg : float
        Declination for a fluxgate heading, degrees east.
    gap_s : float, optional
        Gap that restarts the filter, s.
    reset_sigmas, reset_after : float, int
        The filter restarts at the compass heading when the compass has stayed more than
        ``reset_sigmas`` compass sigmas from the filter's heading for ``reset_after``
        compass samples (default ``window``): after a disturbance has moved the compass
        for good (or has been removed) the filter re-locks instead of alarming for ever.
    seed : int
        Random seed (results are reproducible).
    source : str
        File name quoted in errors.

    Returns
    -------
    Alarms
        ``name="pf"``, ``stat`` = ``S_k`` per row (carried over rows without a compass sample;
        NaN until a stretch's window is full), ``info`` with the settings, the noise estimate
        and the threshold's origin.
    """
    t_start = _time.perf_counter()
    if int(n_particles) < 2:
        raise InputError(f"n_particles={n_particles!r}: need at least 2 particles")
    if int(window) < 1:
        raise InputError(f"window={window!r}: need at least 1 sample")
    if threshold is not None and not np.isfinite(threshold):
        raise InputError(f"threshold={threshold!r}: must be a finite number")
    if not (np.isfinite(walk_deg) and walk_deg > 0):
        raise InputError(f"walk_deg={walk_deg!r}: the heading random walk must be positive")
    if not (np.isfinite(bias_walk_deg) and bias_walk_deg >= 0):
        raise InputError(f"bias_walk_deg={bias_walk_deg!r}: must be zero or positive")
    inp = prepare_pf_inputs(df, declination_deg=declination_deg, gap_s=gap_s, source=source)
    t = inp.time_s
    calm = calm_mask(t, calm_window)
    sig_all = _robust_sigma(inp)
    sig_calm = _robust_sigma(inp, calm)
    sigma_y = max(sig_all, sig_calm, np.deg2rad(sigma_floor_deg))
    walk = np.deg2rad(walk_deg)
    bwalk = np.deg2rad(bias_walk_deg)
    cb = calm_bias(inp.time_s, inp.y_rad, inp.dpsi_rad, inp.segment, calm)
    if cb is None:
        b0, sd_b0 = 0.0, float(np.deg2rad(DEFAULT_BIAS_PRIOR_DEG))
    else:
        # the fit's formal error is optimistic (correlated compass noise): floor 0.05 deg/s
        b0, sd_b0 = cb[0], max(3.0 * cb[1], float(np.deg2rad(0.05)))
    dt = float(np.median(np.diff(t)))
    stat = np.full(t.size, np.nan)
    # the filter's own run, one row per log row (NaN where no step was taken)
    f_state = np.full((t.size, 2), np.nan)
    f_std = np.full((t.size, 2), np.nan)
    f_ll = np.full(t.size, np.nan)
    rng = np.random.default_rng(seed)
    n_steps = 0
    n_resets = 0
    n_latched = 0
    held = np.zeros(t.size, dtype=bool)
    reset_n = int(window) if reset_after is None else int(reset_after)
    lim = float(reset_sigmas) * sigma_y
    for s in np.unique(inp.segment):
        rows = np.flatnonzero(inp.segment == s)
        yy = inp.y_rad[rows]
        du = inp.dpsi_rad[rows]
        fin = np.isfinite(yy)
        if fin.sum() < int(window):
            continue
        md = heading_model(sigma_y, walk, float(yy[fin][0]), dt, bias_walk_rad=bwalk,
                           b0=b0, sd_b0=sd_b0)
        pf = ParticleFilter(md, int(n_particles), proposal=proposal, scheme=scheme,
                            window=int(window), seed=rng)
        out = np.full(rows.size, np.nan)
        tt = t[rows]
        uu = np.column_stack([du, np.diff(tt, prepend=tt[0])])   # [dpsi, dt] per row
        ang = np.cumsum(du)                 # gyro heading of the stretch, rad
        mean = np.full(rows.size, np.nan)   # filter heading at compass rows, rad
        far = 0
        far_start = 0
        b_last = b0
        last = np.nan
        ref: tuple[float, float, float, int] | None = None   # latch: (c, b, sd_b, j0)
        inside = 0
        restart: list[float] | None = None
        t_unlatch = -np.inf
        for j in range(rows.size):
            yj = yy[j]
            if not np.isfinite(yj):
                r = pf.step(None, uu[j])
                f_state[rows[j]], f_std[rows[j]] = r.state, r.std
                out[j] = last
                if ref is not None:
                    held[rows[j]] = True
                continue
            r = pf.step(yj, uu[j])
            f_state[rows[j]], f_std[rows[j]], f_ll[rows[j]] = r.state, r.std, r.loglik
            last = pf.last_stat
            if restart is not None:
                # After a restart, until the window is full again: the partial window's
                # sum scaled to M samples (an estimate of S_k, so the column has no hole).
                restart.append(-float(r.loglik))
                if np.isnan(last):
                    last = float(np.sum(restart)) * int(window) / len(restart)
                else:
                    restart = None
            out[j] = last
            mean[j] = r.state[0]
            if ref is None and far == 0:
                b_last = float(r.state[1])
            is_far = abs(wrap_rad(yj - r.state[0])) > lim
            if is_far and far == 0:
                far_start = j
            far = far + 1 if is_far else 0
            if ref is not None:
                # Latched: is the compass still off the gyro heading carried from before
                # the disturbance (bias-corrected, gate widened by the bias's uncertainty)?
                c, b, sd_b, j0 = ref
                d = wrap_rad(yj - (c + b * tt[j] + ang[j]))
                gate = lim + 3.0 * sd_b * (tt[j] - tt[j0])
                inside = inside + 1 if abs(d) <= gate else 0
                if inside >= reset_n:
                    ref = None
                    t_unlatch = tt[j]
                    held[rows[j - reset_n + 1:j + 1]] = False
                else:
                    held[rows[j]] = True
            if far >= reset_n:
                # The compass has left the filter for good (a disturbance that holds, or
                # its removal): start again at the compass heading; S_k is NaN until the
                # window is full again, and the alarm stays latched (below) until the
                # compass is back on the gyro's heading.
                if ref is None:
                    ref = _gyro_reference(tt, ang, mean, far_start, t_unlatch,
                                          max_rms=0.5 * lim)
                    if ref is not None:
                        held[rows[far_start:j + 1]] = True
                        inside = 0
                        n_latched += 1
                # keep the bias learnt so far (a disturbance does not change the gyro)
                md.x0 = np.array([yj, b_last])
                pf.reset()
                far, restart = 0, []
                n_resets += 1
        stat[rows] = out
        n_steps += rows.size
    calm_ok = calm & np.isfinite(stat)
    info: dict = {
        "particles": int(n_particles), "window": int(window), "proposal": proposal,
        "scheme": scheme, "rate_source": inp.rate_source, "compass_source": inp.compass_source,
        "sigma_y_deg": float(np.rad2deg(sigma_y)),
        "sigma_y_log_deg": float(np.rad2deg(sig_all)),
        "sigma_y_calm_deg": float(np.rad2deg(sig_calm)), "walk_deg_sqrt_s": float(walk_deg),
        "bias_walk_deg_s_sqrt_s": float(bias_walk_deg),
        "gyro_bias_prior_deg_s": float(np.rad2deg(b0)),
        "gyro_bias_prior_sd_deg_s": float(np.rad2deg(sd_b0)),
        "n_stretches": int(np.unique(inp.segment).size), "n_resets": int(n_resets),
        "seed": int(seed),
    }
    if threshold is None:
        if calm_ok.sum() < MIN_CALM_STATS:
            raise InputError(
                f"{source}: only {int(calm_ok.sum())} sample(s) with a full window in the calm"
                f" window {calm_window!r} (need {MIN_CALM_STATS}; the window is {window} compass"
                " samples); choose a longer calm_window or give threshold=X"
            )
        w = int(window)
        fin = np.isfinite(stat)
        med_all = float(np.median(stat[fin]))
        if margin is None:
            # How far S_k of a correct model rises by chance (chi-square excess at 1e-6),
            # inflated by the spread of S_k over the chi-square's sqrt(M/2) when larger
            # (compass noise correlated in time makes S_k wander more), measured over the
            # calm window and, robustly, over the whole log (a quiet calm window, e.g. a
            # landed vehicle, would under-state the flight's spread).
            base = 0.5 * (float(_stats.chi2.ppf(1.0 - 1e-6, w)) - w)
            sd_chi = np.sqrt(0.5 * w)
            spread_calm = float(np.std(stat[calm_ok])) / sd_chi
            mad = float(np.median(np.abs(stat[fin] - med_all)))
            spread_log = 1.4826 * mad / sd_chi
            info["calm_spread_ratio"] = spread_calm
            info["log_spread_ratio"] = spread_log
            margin = base * max(1.0, spread_calm, spread_log)
        th = threshold_from_calm(stat, calm_ok, percentile=100.0, margin=float(margin))
        # The level the margin is added to: the calm window's largest S_k, but never below
        # the mean S_k of the model itself or the log's median S_k (a calm window quieter
        # than the flight must not set a threshold the flight's noise alone exceeds).
        expected = 0.5 * w * (np.log(2.0 * np.pi * sigma_y**2) + 1.0)
        level = max(th.info["calm_percentile_value"], expected, med_all)
        th.value = level + float(margin)
        info["expected_stat"] = float(expected)
        info["log_median_stat"] = med_all
        thr = th.value
        info["threshold_source"] = "calm"
        info["calm_window"] = calm_window if calm_window is None else str(calm_window)
        info["calm_samples"] = th.n
        info["calm_max_stat"] = th.info["calm_percentile_value"]
        info["margin"] = float(margin)
        info["calm_false_alarm_rate"] = float(np.mean(stat[calm_ok] > th.value))
    else:
        thr = float(threshold)
        info["threshold_source"] = "given"
    with np.errstate(invalid="ignore"):
        alarm = (stat > thr) | held
    info["n_latched"] = int(n_latched)
    info["latched_s"] = float(np.sum(np.diff(t, append=t[-1])[held]))
    # Carry S_k over rows without a compass sample (already done by window_sum within a
    # stretch); rows of a stretch too short for a window stay NaN and never alarm.
    info["elapsed_s"] = float(_time.perf_counter() - t_start)
    info["particle_steps_per_s"] = float(n_steps * int(n_particles) /
                                         max(info["elapsed_s"], 1e-9))
    log.debug("%s: pf detector sigma_y %.3f deg, threshold %.2f, %d alarms",
              source, info["sigma_y_deg"], thr, int(np.sum(alarm)))
    fit = SequentialResult(
        time_s=t, state=f_state, std=f_std, state_names=("heading_rad", "gyro_bias_rad_s"),
        loglik=f_ll, innovations={"heading": InnovationStats(
            dof=1, n_fused=int(np.isfinite(f_ll).sum()),
            n_gated=int(np.isfinite(f_state[:, 0]).sum() - np.isfinite(f_ll).sum()))},
        info={"n_resets": int(n_resets)})
    return Alarms(name="pf", time_s=t, stat=stat, alarm=alarm, threshold=float(thr), info=info,
                  fit=fit)
