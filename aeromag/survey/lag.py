"""Magnetometer lag: shifting values against positions, and estimating the lag.

Convention (``interface.md``): the lag is positive when the reading at time t is the field at
the position of time t - lag.  The corrected value at the position of time t is therefore the
reading at t + lag, interpolated in time inside each line piece (never across pieces; a sample
whose t + lag falls outside its piece gets NaN, never an extrapolation).

``estimate_lag`` uses adjacent lines flown in opposite directions: a lag moves each line's
profile by lag x speed along its own direction, so a pair of opposite lines shows twice that
(the herring-bone).  The lag that best aligns all such pairs (least squares over their common
stretch, each pair's level difference removed) is the estimate; its uncertainty is the
jackknife over the pairs.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .geometry import SurveyGeometry

log = logging.getLogger(__name__)

__all__ = ["FLAT_HALF_WIDTH_S", "LagEstimate", "apply_lag", "estimate_lag"]

#: ``--lag auto`` refuses when the lags fitting within 10 % of the best span more than twice
#: this [s] (a UAV survey whose lines are too far apart for its shallow sources: 2 s wide).
FLAT_HALF_WIDTH_S = 0.5


@dataclass
class LagEstimate:
    """A lag estimated from opposite-direction line pairs.

    Attributes
    ----------
    lag_s : float
        Estimated lag [s].
    std_s : float
        Jackknife standard error over the pairs [s].
    n_pairs : int
        Groups of adjacent lines flown in opposite directions used (a line between two
        neighbours flown the other way, or else pairs).
    search_s : tuple of float
        Range searched [s].
    """

    lag_s: float
    std_s: float
    n_pairs: int
    search_s: tuple[float, float]

    def to_dict(self) -> dict[str, float | int | list[float]]:
        """JSON-ready form."""
        return {"lag_s": self.lag_s, "std_s": self.std_s, "n_pairs": self.n_pairs,
                "search_s": list(self.search_s)}


def apply_lag(time_s: np.ndarray, value: np.ndarray, piece: np.ndarray, lag_s: float
              ) -> np.ndarray:
    """Move values onto the positions: value at t becomes the reading at t + lag.

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Sample times [s], increasing inside each piece.
    value : ndarray, shape (n,)
        Readings [nT].
    piece : ndarray of int, shape (n,)
        Piece index per sample (-1: none; such samples are shifted against their neighbours
        of the same run of -1 as well, which is what a turn needs).
    lag_s : float
        Lag [s].

    Returns
    -------
    ndarray
        Lag-corrected values [nT] (NaN where t + lag leaves the piece).
    """
    v = np.asarray(value, dtype=np.float64)
    if lag_s == 0:
        return v.copy()
    t = np.asarray(time_s, dtype=np.float64)
    out = np.full(v.shape, np.nan)
    change = np.flatnonzero(np.diff(piece) != 0) + 1
    starts = np.r_[0, change]
    ends = np.r_[change, v.size]
    for a, b in zip(starts, ends, strict=True):
        tt, vv = t[a:b], v[a:b]
        ok = np.isfinite(vv) & np.isfinite(tt)
        if ok.sum() < 2:
            continue
        q = tt + lag_s
        inside = (q >= tt[ok][0]) & (q <= tt[ok][-1])
        out[a:b][inside] = np.interp(q[inside], tt[ok], vv[ok])
    return out


def _profiles(geom: SurveyGeometry, time_s: np.ndarray, value: np.ndarray
              ) -> list[tuple[float, float, int, np.ndarray, np.ndarray, np.ndarray]]:
    """Per non-tie piece: (across position, direction sign, piece, u, t, v) on its straight."""
    lines = np.flatnonzero(~geom.piece_is_tie)
    if lines.size == 0:
        return []
    th = np.deg2rad(geom.lines_direction_deg)
    ux, uy = np.sin(th), np.cos(th)
    out = []
    sel = geom.straight & (geom.piece >= 0)
    idx = np.flatnonzero(sel)
    pid = geom.piece[idx]
    order = np.argsort(pid, kind="stable")
    idx = idx[order]
    bounds = np.flatnonzero(np.diff(geom.piece[idx])) + 1
    for grp in np.split(idx, bounds):
        k = int(geom.piece[grp[0]])
        if geom.piece_is_tie[k] or grp.size < 10:
            continue
        u = geom.x_m[grp] * ux + geom.y_m[grp] * uy
        across = float(np.mean(geom.x_m[grp] * uy - geom.y_m[grp] * ux))
        sign = 1.0 if u[-1] > u[0] else -1.0
        out.append((across, sign, k, u, time_s[grp], value[grp]))
    return out


def _lagged_on(p: tuple, grid: np.ndarray, lag: float) -> np.ndarray:
    """A profile's lag-corrected values on a grid of along positions."""
    u, t, v = p[3], p[4], p[5]
    w = np.interp(t + lag, t, v)  # the reading at t + lag belongs to the position of t
    o = np.argsort(u)
    return np.interp(grid, u[o], w[o])


def _misfit(group: list[tuple], lags: np.ndarray, n_grid: int = 400) -> np.ndarray:
    """Mean squared misfit per trial lag of a line against its opposite neighbour(s).

    Two profiles: their difference.  Three (a line between two flown the other way): the
    middle one minus the mean of its neighbours, which cancels the change of the geology
    from line to line to first order (an oblique strike would otherwise mimic a lag).
    The level difference is removed.
    """
    lo = max(p[3].min() for p in group)
    hi = min(p[3].max() for p in group)
    if hi - lo <= 0:
        return np.full(lags.size, np.nan)
    grid = np.linspace(lo + 0.05 * (hi - lo), hi - 0.05 * (hi - lo), n_grid)
    out = np.empty(lags.size)
    for i, lag in enumerate(lags):
        prof = [_lagged_on(p, grid, lag) for p in group]
        d = prof[0] - prof[1] if len(prof) == 2 else prof[1] - 0.5 * (prof[0] + prof[2])
        out[i] = np.mean((d - d.mean()) ** 2)
    return out


def estimate_lag(geom: SurveyGeometry, time_s: np.ndarray, value: np.ndarray, *,
                 max_lag_s: float = 2.0, step_s: float = 0.02, source: str = "<survey>"
                 ) -> LagEstimate:
    """Estimate the lag from adjacent lines flown in opposite directions.

    Parameters
    ----------
    geom : SurveyGeometry
        The survey's geometry.
    time_s : ndarray
        Sample times [s].
    value : ndarray
        Total field or anomaly [nT] (a constant or slowly varying offset does not matter).
    max_lag_s : float
        Largest |lag| searched [s].
    step_s : float
        Search step [s] (refined by a parabola through the best three).
    source : str
        Name for messages.

    Returns
    -------
    LagEstimate

    Raises
    ------
    InputError
        No pair of adjacent lines flown in opposite directions (``--lag auto`` needs them).
    """
    prof = sorted(_profiles(geom, time_s, value), key=lambda p: p[0])
    triples = [list(prof[i - 1:i + 2]) for i in range(1, len(prof) - 1)
               if prof[i - 1][1] != prof[i][1] and prof[i + 1][1] != prof[i][1]]
    pairs = triples or [[a, b] for a, b in zip(prof[:-1], prof[1:], strict=True)
                        if a[1] != b[1]]
    if not pairs:
        raise InputError(f"{source}: --lag auto needs adjacent lines flown in opposite "
                         "directions and the survey has none; give the lag in seconds "
                         "(--lag S)")
    lags = np.arange(-max_lag_s, max_lag_s + step_s / 2, step_s)
    curves = []
    for group in pairs:
        m = _misfit(group, lags)
        if np.all(np.isfinite(m)) and m.max() > 0:
            curves.append(m / np.median(m))
    if not curves:
        raise InputError(f"{source}: --lag auto: the opposite-direction lines do not overlap; "
                         "give the lag in seconds (--lag S)")
    c = np.array(curves)

    def best(total: np.ndarray) -> float:
        i = int(np.argmin(total))
        if 0 < i < total.size - 1:
            y0, y1, y2 = total[i - 1], total[i], total[i + 1]
            den = y0 - 2 * y1 + y2
            off = 0.5 * (y0 - y2) / den if den > 0 else 0.0
            return float(lags[i] + off * step_s)
        return float(lags[i])

    total = c.sum(axis=0)
    lag = best(total)
    # How well the lag is determined: the lags whose misfit is within 10 % of the best.  Lines
    # too far apart for their fields to match (shallow sources under a slow UAV's 20-30 m
    # lines) give a flat curve whose minimum is anywhere: refused, not applied.
    i = int(np.argmin(total))
    near = total <= 1.1 * total[i]
    lo = i - int(np.argmin(near[i::-1])) if not near[:i + 1].all() else -1  # last one out
    hi = i + int(np.argmin(near[i:])) if not near[i:].all() else lags.size
    width = (hi - lo - 2) * step_s
    if width > 2.0 * FLAT_HALF_WIDTH_S:
        raise InputError(f"{source}: --lag auto: the opposite-direction lines do not "
                         f"determine the lag (every lag from {lags[lo + 1]:.2f} to "
                         f"{lags[hi - 1]:.2f} s fits within 10 %: the field changes more from "
                         "line to line than a lag moves it); give the lag in seconds (--lag S)")
    n = c.shape[0]
    if n >= 3:
        jack = np.array([best(c.sum(axis=0) - c[i]) for i in range(n)])
        std = float(np.sqrt((n - 1) / n * np.sum((jack - jack.mean()) ** 2)))
    else:
        std = float("nan")
    if abs(lag) >= max_lag_s - step_s:
        log.warning("%s: the estimated lag %.2f s is at the edge of the search (+-%g s)",
                    source, lag, max_lag_s)
    return LagEstimate(lag, std, n, (-max_lag_s, max_lag_s))
