"""Particle-filter detector helpers: the latch's reference, the gyro unit, the calm bias.

See :mod:`aeromag.detection.particle`.
"""

from __future__ import annotations

import logging

import numpy as np

log = logging.getLogger("aeromag.detection.particle")

__all__ = ["calm_bias", "check_gyro_unit", "gyro_reference"]


def gyro_reference(t: np.ndarray, ang: np.ndarray, mean: np.ndarray, j0: int,
                    t_min: float = -np.inf, max_rms: float = np.inf, span_s: float = 60.0,
                    guard_s: float = 2.0) -> tuple[float, float, float, int] | None:
    """The filter's heading before a disturbance, carried on by the bias-corrected gyro.

    Fits ``mean - ang = c + b t`` (``b``: the gyro bias the filter followed, rad/s) over the
    compass samples from ``span_s`` to ``guard_s`` seconds before row ``j0`` (the first
    sample far from the filter), so that ``c + b t + ang(t)`` is the heading the compass
    should read without the disturbance.

    Parameters
    ----------
    t, ang, mean : ndarray
        Row times (s), gyro heading (rad) and filter heading (rad, NaN off compass rows) of
        the stretch.
    j0 : int
        Row where the compass left the filter.
    t_min : float
        Only samples after this time are fitted (the end of the previous latch: the filter
        followed the disturbed compass until then), s.
    max_rms : float
        Largest rms of the fit's residual, rad: a filter that was already following a slow
        disturbance before ``j0`` bends the fitted track (a kink, not a line), so it gives
        no trustworthy reference.
    span_s, guard_s : float
        Fit window before ``t[j0]``, s.

    Returns
    -------
    (c, b, sd_b, j0) or None
        Intercept (rad), bias (rad/s), its standard error (rad/s); None with fewer than 10
        compass samples before ``j0`` or a residual rms above ``max_rms`` (no reference: no
        latch).
    """
    ok = np.isfinite(mean) & (t > t_min)
    sel = np.flatnonzero((t >= t[j0] - span_s) & (t <= t[j0] - guard_s) & ok)
    if sel.size < 10:
        sel = np.flatnonzero((t < t[j0]) & ok)
        if sel.size < 10:
            return None
    x = t[sel] - t[j0]
    d = np.unwrap(mean[sel] - ang[sel])
    b, c0 = np.polyfit(x, d, 1)
    res = d - (c0 + b * x)
    if float(np.sqrt(np.mean(res**2))) > max_rms:
        return None
    sxx = float(np.sum((x - x.mean()) ** 2))
    sd_b = float(np.sqrt(np.sum(res**2) / max(sel.size - 2, 1) / max(sxx, 1e-12)))
    # floor: the filter's heading is correlated in time, so the formal error is optimistic
    sd_b = max(sd_b, float(np.deg2rad(0.01)))
    return float(c0 - b * t[j0]), float(b), sd_b, int(j0)


def check_gyro_unit(t: np.ndarray, ang: np.ndarray, mh_deg: np.ndarray | None,
                     source: str) -> None:
    """Warn when the gyro's heading changes some 57 times more than the compass's (deg/s).

    Compares, over 1 s blocks, the median absolute change of the integrated gyro angle with
    that of the unwrapped compass heading (rad both); a ratio above 10 means the gyro is
    most likely logged in deg/s.
    """
    if mh_deg is None:
        return
    ok = np.isfinite(mh_deg)
    if ok.sum() < 10 or t[-1] - t[0] < 2.0:
        return
    tc = t[ok]
    yc = np.unwrap(np.deg2rad(mh_deg[ok]))
    grid = np.arange(tc[0], tc[-1], 1.0)
    dc = np.abs(np.diff(np.interp(grid, tc, yc)))
    dg = np.abs(np.diff(np.interp(grid, t, ang)))
    mc, mg = float(np.median(dc)), float(np.median(dg))
    if mg > 10.0 * max(mc, np.deg2rad(0.05)):
        log.warning("%s: the gyro turns the heading %.0f times more than the compass does "
                    "(median per second %.3g rad against %.3g rad): is the gyro in deg/s? "
                    "The interface wants rad/s; convert with units={'gyro': 'deg/s'}",
                    source, mg / max(mc, 1e-12), mg, mc)


def calm_bias(time_s: np.ndarray, y_rad: np.ndarray, dpsi_rad: np.ndarray,
              segment: np.ndarray, calm: np.ndarray) -> tuple[float, float] | None:
    """Gyro bias from the calm window: minus the slope of compass minus gyro heading.

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Times [s].
    y_rad : ndarray, shape (n,)
        Compass heading [rad] (NaN where none).
    dpsi_rad : ndarray, shape (n,)
        Gyro heading increment per row [rad].
    segment : ndarray of int, shape (n,)
        Continuous stretch of each row.
    calm : ndarray of bool, shape (n,)
        Rows of the calm window.

    Returns
    -------
    (float, float) or None
        ``(b, sd_b)`` [rad/s] from the stretch with the most calm compass samples; None
        with fewer than 10 compass samples in every stretch of the calm window.
    """
    best = None
    for s in np.unique(segment):
        rows = segment == s
        ang = np.cumsum(dpsi_rad[rows])
        m = (calm & np.isfinite(y_rad))[rows]
        if m.sum() < 10:
            continue
        tt = time_s[rows][m]
        d = np.unwrap(y_rad[rows][m] - ang[m])
        x = tt - tt.mean()
        slope, c0 = np.polyfit(x, d, 1)
        res = d - (c0 + slope * x)
        sxx = float(np.sum(x * x))
        sd = float(np.sqrt(np.sum(res**2) / max(m.sum() - 2, 1) / max(sxx, 1e-12)))
        if best is None or m.sum() > best[2]:
            best = (-float(slope), sd, int(m.sum()))
    return None if best is None else (best[0], best[1])
