"""Heading-difference detector of magnetic interference (methods M2).

The classic detector (methods M2) compares the attitude heading of the INS/AHRS with the heading
measured by the magnetometer (compass).  In calm conditions their difference is a constant
(mounting misalignment, declination error) plus noise; a magnetic disturbance makes it move.
The mean ``m`` and standard deviation ``sigma`` of the difference are measured over a calm
reference window (by default the first 30 s of the log) and a sample alarms when
``abs(wrap(diff - m)) > k * sigma`` (``k = 5`` by default).

When the log has no ``mag_heading`` column it is derived from the body-frame fluxgate
(``flux_x/y/z``) with tilt compensation from ``pitch``/``roll`` and a declination
(:func:`mag_heading_from_flux`).

Everything here is vectorised over samples.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .._core.angles import wrap_deg
from ..errors import InputError
from .alarms import Alarms

__all__ = ["CalmWindow", "DEFAULT_CALM_SECONDS", "DEFAULT_SIGMA_FLOOR_DEG", "HeadingResult",
           "MIN_CALM_SAMPLES", "SIGMA_FLOOR_DEG", "calm_mask", "heading_columns_available",
           "heading_detector", "heading_difference", "mag_heading_from_flux",
           "parse_calm_window"]

log = logging.getLogger(__name__)

#: Default length of the calm reference window, s (from the start of the log).
DEFAULT_CALM_SECONDS = 30.0

#: Smallest sigma used whatever the options, degrees (a perfectly noise-free reference would
#: otherwise alarm on rounding errors).
SIGMA_FLOOR_DEG = 1e-3

#: Default floor of the calm-window sigma, degrees (``--heading-sigma-floor``).  A calm window
#: can be quieter than the compass really is over a flight (a short window, a vehicle at rest,
#: a smoothed or quantised heading): a sigma of 0.005 deg made a clean survey line raise 173
#: alarms.  0.5 deg is the heading noise of a good MEMS compass in flight (0.1-0.3 deg rms at
#: rest, more with motor currents) and half the 1 deg accuracy of the HMC5983 of methods M4, so
#: with k = 5 nothing below 2.5 deg alarms; the study's disturbances bend the heading by tens
#: of degrees.
DEFAULT_SIGMA_FLOOR_DEG = 0.5

#: Fewest finite samples accepted in the calm window.
MIN_CALM_SAMPLES = 5

CalmWindow = float | tuple[float, float] | str | None


def mag_heading_from_flux(
    flux_x: np.ndarray,
    flux_y: np.ndarray,
    flux_z: np.ndarray,
    pitch_deg: np.ndarray,
    roll_deg: np.ndarray,
    declination_deg: float = 0.0,
) -> np.ndarray:
    """Tilt-compensated magnetometer heading from a body-frame fluxgate.

    The body frame is forward-right-down with aerospace Z-Y-X (yaw, pitch, roll) angles.  The
    field is levelled by undoing roll then pitch,
    ``Xh = bx cos(theta) + (by sin(phi) + bz cos(phi)) sin(theta)``,
    ``Yh = by cos(phi) - bz sin(phi)``, and the magnetic heading is ``atan2(-Yh, Xh)``; the
    declination (east positive) is added to give a true heading.

    Parameters
    ----------
    flux_x, flux_y, flux_z : array_like
        Body-frame field components, nT (any common unit works).
    pitch_deg, roll_deg : array_like
        Attitude, degrees.
    declination_deg : float
        Magnetic declination, degrees east of true north.

    Returns
    -------
    ndarray
        Heading, degrees in [0, 360).
    """
    bx, by, bz = (np.asarray(c, dtype=np.float64) for c in (flux_x, flux_y, flux_z))
    th = np.deg2rad(np.asarray(pitch_deg, dtype=np.float64))
    ph = np.deg2rad(np.asarray(roll_deg, dtype=np.float64))
    xh = bx * np.cos(th) + (by * np.sin(ph) + bz * np.cos(ph)) * np.sin(th)
    yh = by * np.cos(ph) - bz * np.sin(ph)
    psi = np.rad2deg(np.arctan2(-yh, xh)) + float(declination_deg)
    return np.mod(psi, 360.0)


def heading_difference(heading_deg: np.ndarray, mag_heading_deg: np.ndarray) -> np.ndarray:
    """Attitude heading minus magnetometer heading, wrapped to [-180, 180).

    Parameters
    ----------
    heading_deg, mag_heading_deg : array_like
        Headings, degrees.

    Returns
    -------
    ndarray
        Difference, degrees in [-180, 180).
    """
    return wrap_deg(np.asarray(heading_deg, dtype=np.float64)
                    - np.asarray(mag_heading_deg, dtype=np.float64))


def parse_calm_window(spec: CalmWindow) -> float | tuple[float, float]:
    """Parse a calm-window specification.

    Parameters
    ----------
    spec : float, (float, float), str or None
        ``None`` (the default 30 s), a number of seconds from the start of the log (``30`` or
        ``"30"``), or an absolute time range ``(t0, t1)`` / ``"t0:t1"`` in the log's time
        unit, s.

    Returns
    -------
    float or (float, float)
        Seconds from the start, or an absolute time range, s.
    """
    if spec is None:
        return DEFAULT_CALM_SECONDS
    if isinstance(spec, str):
        text = spec.strip()
        try:
            if ":" in text:
                a, _, b = text.partition(":")
                rng = (float(a), float(b))
            else:
                rng = None
                sec = float(text)
        except ValueError:
            raise InputError(
                f"calm_window={spec!r}: expected seconds (e.g. 30) or a time range T0:T1"
            ) from None
        if rng is None:
            return parse_calm_window(sec)
        return parse_calm_window(rng)
    if isinstance(spec, Sequence):
        if len(spec) != 2:
            raise InputError(f"calm_window={tuple(spec)!r}: a time range needs two values T0:T1")
        t0, t1 = float(spec[0]), float(spec[1])
        if not (np.isfinite(t0) and np.isfinite(t1)) or t1 <= t0:
            raise InputError(f"calm_window=({t0:g}, {t1:g}): the end must be after the start")
        return (t0, t1)
    sec = float(spec)
    if not np.isfinite(sec) or sec <= 0:
        raise InputError(f"calm_window={spec!r}: the window length must be positive seconds")
    return sec


def calm_mask(time: np.ndarray, spec: CalmWindow) -> np.ndarray:
    """Boolean mask of the calm reference window.

    Parameters
    ----------
    time : ndarray
        Sample times, s.
    spec : float, (float, float), str or None
        See :func:`parse_calm_window`.

    Returns
    -------
    ndarray of bool
    """
    t = np.asarray(time, dtype=np.float64)
    win = parse_calm_window(spec)
    if isinstance(win, tuple):
        return (t >= win[0]) & (t <= win[1])
    return t <= t[0] + win


@dataclass
class HeadingResult(Alarms):
    """Output of :func:`heading_detector`: the shared ``Alarms`` with the detector's fields.

    ``stat`` is ``abs(wrap(diff - mean))`` [deg] and ``threshold`` is ``k * sigma`` [deg].

    Attributes
    ----------
    diff_deg : ndarray
        Attitude heading minus magnetometer heading, degrees in [-180, 180).
    mean_deg, sigma_deg : float
        Statistics of the calm window, degrees (``sigma_deg`` after the floor).
    sigma_raw_deg : float
        Standard deviation of the calm window before the floor, degrees.
    sigma_floor_deg : float
        The floor applied, degrees.
    n_calm : int
        Samples in the calm window.
    source : str
        ``"mag_heading"`` or ``"flux"`` (where the magnetometer heading came from).
    """

    diff_deg: np.ndarray = field(default_factory=lambda: np.zeros(0))
    mean_deg: float = 0.0
    sigma_deg: float = 0.0
    sigma_raw_deg: float = 0.0
    sigma_floor_deg: float = 0.0
    n_calm: int = 0
    source: str = ""


def heading_columns_available(df: pd.DataFrame) -> str | None:
    """Say whether the heading detector can run on ``df``.

    Parameters
    ----------
    df : DataFrame
        Log with canonical columns.

    Returns
    -------
    str or None
        ``"mag_heading"`` when ``heading`` and ``mag_heading`` exist, ``"flux"`` when
        ``heading``, ``flux_x/y/z``, ``pitch`` and ``roll`` exist, else ``None``.
    """
    if "heading" not in df.columns:
        return None
    if "mag_heading" in df.columns:
        return "mag_heading"
    if all(c in df.columns for c in ("flux_x", "flux_y", "flux_z", "pitch", "roll")):
        return "flux"
    return None


def heading_detector(
    df: pd.DataFrame,
    *,
    calm_window: CalmWindow = None,
    sigmas: float = 5.0,
    declination_deg: float = 0.0,
    sigma_floor_deg: float = DEFAULT_SIGMA_FLOOR_DEG,
    source: str = "<log>",
) -> HeadingResult:
    """Run the heading-difference detector on a log.

    Parameters
    ----------
    df : DataFrame
        Log with ``time`` [s], ``heading`` [deg] and either ``mag_heading`` [deg] or
        ``flux_x/y/z`` [nT] with ``pitch``/``roll`` [deg].
    calm_window : float, (float, float), str or None
        Calm reference window (see :func:`parse_calm_window`); default the first 30 s.
    sigmas : float
        Alarm factor ``k`` (alarm when the deviation from the calm mean exceeds ``k`` sigma).
    declination_deg : float
        Declination added to a fluxgate-derived heading, degrees east.
    sigma_floor_deg : float
        Floor of the calm-window sigma, degrees (see :data:`DEFAULT_SIGMA_FLOOR_DEG`).
    source : str
        File name quoted in errors.

    Returns
    -------
    HeadingResult
    """
    if not np.isfinite(sigmas) or sigmas <= 0:
        raise InputError(f"sigmas={sigmas!r}: must be a positive number")
    if not np.isfinite(sigma_floor_deg) or sigma_floor_deg < 0:
        raise InputError(f"sigma_floor_deg={sigma_floor_deg!r}: must be >= 0 degrees")
    kind = heading_columns_available(df)
    if kind is None:
        raise InputError(
            f"{source}: the heading detector needs 'heading' and 'mag_heading' (or flux_x/y/z,"
            " pitch and roll); map them with columns={'NAME': 'SOURCE'}"
        )
    if kind == "mag_heading":
        mh = df["mag_heading"].to_numpy(dtype=np.float64)
    else:
        mh = mag_heading_from_flux(df["flux_x"], df["flux_y"], df["flux_z"], df["pitch"],
                                   df["roll"], declination_deg)
    diff = heading_difference(df["heading"].to_numpy(dtype=np.float64), mh)
    t = df["time"].to_numpy(dtype=np.float64)
    calm = calm_mask(t, calm_window) & np.isfinite(diff)
    n_calm = int(calm.sum())
    if n_calm < MIN_CALM_SAMPLES:
        raise InputError(
            f"{source}: only {n_calm} usable sample(s) in the calm window {calm_window!r}"
            f" (need {MIN_CALM_SAMPLES}); choose another calm_window"
        )
    ref = diff[calm]
    # Circular-safe mean: centre on the median before averaging, so a reference near +-180
    # does not average to 0.
    centre = float(np.median(ref))
    dev = wrap_deg(ref - centre)
    mean = float(wrap_deg(centre + dev.mean()))
    sigma_raw = float(dev.std(ddof=1))
    sigma = max(sigma_raw, float(sigma_floor_deg), SIGMA_FLOOR_DEG)
    if sigma_raw < sigma_floor_deg:
        log.info("%s: calm-window heading sigma %.4f deg is below the floor; using %.3f deg",
                 source, sigma_raw, sigma)
    excess = np.abs(wrap_deg(diff - mean))
    with np.errstate(invalid="ignore"):
        alarm = excess > sigmas * sigma
    alarm &= np.isfinite(diff)
    log.debug("%s: heading detector from %s: calm mean %.3f deg, sigma %.3f deg (%d samples)",
              source, kind, mean, sigma, n_calm)
    return HeadingResult(name="heading", time_s=t, stat=excess, alarm=alarm,
                         threshold=sigmas * sigma, diff_deg=diff, mean_deg=mean,
                         sigma_deg=sigma, sigma_raw_deg=sigma_raw,
                         sigma_floor_deg=float(sigma_floor_deg), n_calm=n_calm, source=kind)
