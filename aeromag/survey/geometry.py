"""Survey geometry: projected coordinates, line pieces, lines and ties, straight parts.

A survey's samples carry a ``line`` number (tie lines included).  Here they get projected
coordinates (pyproj, through :mod:`aeromag._core.geodesy`), are split into *pieces* (a line
flown in several runs keeps its number; each run is a piece with its own levelling unknowns),
classified as lines or ties, and the turns and run-ins at the ends of each piece are marked
off the straight part (crossings and the lag estimate use the straight part only).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._core.geodesy import project, utm_epsg
from ..errors import InputError

log = logging.getLogger(__name__)

__all__ = ["SurveyGeometry", "angle_difference_deg", "build_geometry", "line_direction_deg",
           "position_noise_m"]

#: A direction more than this far from the dominant line direction makes a tie (direction rule).
TIE_ANGLE_DEG = 45.0
#: A sample whose local track direction is more than this from its piece's is off the straight.
STRAIGHT_TOLERANCE_DEG = 15.0


@dataclass
class SurveyGeometry:
    """Where each sample is and which line piece it belongs to.

    Attributes
    ----------
    crs : int
        EPSG code of the projected coordinates.
    x_m, y_m : ndarray, shape (n,)
        Easting and northing [m].
    line : ndarray, shape (n,)
        Line number of each sample (NaN: no line).
    piece : ndarray of int, shape (n,)
        Piece index of each sample (-1: no line); a piece is one contiguous run of a line.
    piece_line : ndarray, shape (n_pieces,)
        Line number of each piece.
    piece_is_tie : ndarray of bool, shape (n_pieces,)
        Whether the piece belongs to a tie line.
    piece_direction_deg : ndarray, shape (n_pieces,)
        Direction of each piece's straight part, degrees east of grid north in [0, 180).
    straight : ndarray of bool, shape (n,)
        Sample on the straight part of its piece (turns and run-ins trimmed).
    along_m : ndarray, shape (n,)
        Distance along the piece's direction from the piece's first straight sample [m].
    line_spacing_m : float
        Median distance between adjacent (non-tie) lines [m] (NaN with fewer than two lines).
    tie_source : str
        How the ties were chosen: ``"line_type"``, ``"list"`` or ``"direction"``.
    """

    crs: int
    x_m: np.ndarray
    y_m: np.ndarray
    line: np.ndarray
    piece: np.ndarray
    piece_line: np.ndarray
    piece_is_tie: np.ndarray
    piece_direction_deg: np.ndarray
    straight: np.ndarray
    along_m: np.ndarray
    line_spacing_m: float
    tie_source: str

    @property
    def is_tie(self) -> np.ndarray:
        """Per sample: on a tie line (False for samples without a line)."""
        out = np.zeros(self.piece.shape, dtype=bool)
        ok = self.piece >= 0
        out[ok] = self.piece_is_tie[self.piece[ok]]
        return out

    @property
    def lines_direction_deg(self) -> float:
        """Dominant direction of the (non-tie) lines, degrees east of grid north in [0, 180).

        The sample-weighted mean of the doubled angles: lines flown north-south have
        directions near both 0 and 180 degrees, whose plain median is anything between.
        """
        lines = ~self.piece_is_tie
        if not lines.any():
            return float("nan")
        n = np.bincount(self.piece[self.piece >= 0], minlength=self.n_pieces).astype(float)
        return _dominant(self.piece_direction_deg[lines], n[lines])

    @property
    def n_pieces(self) -> int:
        """Number of line pieces."""
        return int(self.piece_line.size)


def angle_difference_deg(a: np.ndarray | float, b: np.ndarray | float) -> np.ndarray:
    """Smallest difference of two undirected directions (mod 180), degrees in [0, 90].

    Parameters
    ----------
    a, b : array_like
        Directions [deg].

    Returns
    -------
    ndarray
        |a - b| folded to [0, 90] [deg].
    """
    d = np.abs((np.asarray(a, dtype=float) - np.asarray(b, dtype=float)) % 180.0)
    return np.minimum(d, 180.0 - d)


def line_direction_deg(x: np.ndarray, y: np.ndarray) -> float:
    """Principal direction of a set of points (the axis of largest spread).

    Parameters
    ----------
    x, y : ndarray
        Coordinates [m].

    Returns
    -------
    float
        Direction, degrees east of grid north, in [0, 180) (NaN for fewer than 2 points).
    """
    if x.size < 2:
        return float("nan")
    c = np.cov(np.vstack([x - x.mean(), y - y.mean()]))
    w, v = np.linalg.eigh(c)
    ex, ny = v[0, -1], v[1, -1]
    return float(np.rad2deg(np.arctan2(ex, ny)) % 180.0)


def _pieces(line: np.ndarray, x: np.ndarray, y: np.ndarray, gap_m: float | None
            ) -> tuple[np.ndarray, np.ndarray]:
    """Piece index per sample and the start of each piece (runs of one line, split at gaps)."""
    n = line.size
    ok = np.isfinite(line) & np.isfinite(x) & np.isfinite(y)
    step = np.hypot(np.diff(x), np.diff(y))
    same = (line[1:] == line[:-1]) & ok[1:] & ok[:-1]
    if gap_m is None:
        st = step[same & np.isfinite(step)]
        gap_m = max(10.0 * float(np.median(st)), 100.0) if st.size else np.inf
    new = np.ones(n, dtype=bool)
    new[1:] = ~(same & (step <= gap_m))
    new &= ok
    pid = np.cumsum(new) - 1
    pid[~ok] = -1
    return pid.astype(np.int64), np.flatnonzero(new)


def position_noise_m(x: np.ndarray, y: np.ndarray) -> float:
    """White noise of a track's positions, per axis, from their second differences [m].

    The median of the second differences' horizontal length is Rayleigh-distributed with
    scale ``sigma sqrt(6)`` for white noise of ``sigma`` per axis on a uniform straight track
    (its median is ``1.1774`` times the scale); a slow wander (a GNSS random walk) and the
    track's own curvature hardly contribute.

    Parameters
    ----------
    x, y : ndarray
        Positions in time order [m].

    Returns
    -------
    float
        Noise standard deviation per axis [m] (0 for fewer than 3 samples).
    """
    if x.size < 3:
        return 0.0
    d2 = np.hypot(np.diff(x, 2), np.diff(y, 2))
    d2 = d2[np.isfinite(d2)]
    return float(np.median(d2)) / (np.sqrt(6.0) * 1.1774) if d2.size else 0.0


def _straight_and_along(x: np.ndarray, y: np.ndarray, direction: float, window: int
                        ) -> tuple[np.ndarray, np.ndarray]:
    """Straight-part mask and along-direction distance of one piece.

    The local direction of sample i is that of the chord from i - k to i + k, with k at least
    ``window`` and doubled until the median chord is 10 times the positions' noise (a slow
    multirotor logging 0.2-0.5 m steps with 0.5-2 m of GNSS noise: over a few samples the
    direction is the noise's).  The straight part runs from the first to the last run of k
    samples within the tolerance, so that a sample of a turn whose noisy direction
    happens to fall near the line's does not pull the straight part into the turn.  A run is k
    consecutive samples most of which are within the tolerance (each first and last good
    sample of the first and last run bound the straight part).
    """
    th = np.deg2rad(direction)
    ux, uy = np.sin(th), np.cos(th)
    s = (x - x[0]) * ux + (y - y[0]) * uy
    n = x.size
    if n < 3:
        return np.ones(n, dtype=bool), s
    k = max(1, min(window, n // 4))
    sigma = position_noise_m(x, y)
    while (2 * k <= n // 4 and
           float(np.median(np.hypot(x[2 * k:] - x[:-2 * k], y[2 * k:] - y[:-2 * k])))
           < 10.0 * sigma):
        k *= 2
    i0 = np.clip(np.arange(n) - k, 0, n - 1)
    i1 = np.clip(np.arange(n) + k, 0, n - 1)
    hd = np.rad2deg(np.arctan2(x[i1] - x[i0], y[i1] - y[i0])) % 180.0
    good = angle_difference_deg(hd, direction) <= STRAIGHT_TOLERANCE_DEG
    # Trim only at the ends: the straight part runs from the first to the last good run.
    straight = np.zeros(n, dtype=bool)
    run = min(k, n)
    c = np.r_[0, np.cumsum(good)]
    full = np.flatnonzero(4 * (c[run:] - c[:-run]) >= 3 * run)  # 3/4 of good[i:i + run]
    if full.size:
        first = full[0] + int(np.argmax(good[full[0]:]))
        last = full[-1] + run - 1 - int(np.argmax(good[full[-1]:full[-1] + run][::-1]))
        straight[first:last + 1] = True
    s0 = s[straight].min() if straight.any() else 0.0
    return straight, s - s0


def _line_spacing(piece_line: np.ndarray, is_tie: np.ndarray, centre_across: np.ndarray
                  ) -> float:
    lines = ~is_tie
    if lines.sum() < 2:
        return float("nan")
    # One across-position per line number (pieces of a line share it).
    nums, inv = np.unique(piece_line[lines], return_inverse=True)
    pos = np.bincount(inv, weights=centre_across[lines]) / np.bincount(inv)
    d = np.diff(np.sort(pos))
    d = d[d > 1e-6]
    return float(np.median(d)) if d.size else float("nan")


def build_geometry(lat: np.ndarray | None, lon: np.ndarray | None, line: np.ndarray, *,
                   x_m: np.ndarray | None = None, y_m: np.ndarray | None = None,
                   crs: int | None = None, line_type: Sequence[str] | np.ndarray | None = None,
                   ties: Sequence[float] | None = None, gap_m: float | None = None,
                   window: int = 5, source: str = "<survey>") -> SurveyGeometry:
    """Project a survey, split it into line pieces, classify ties, trim turns.

    Parameters
    ----------
    lat, lon : ndarray or None
        WGS84 latitude and longitude [deg] (None when ``x_m``, ``y_m`` and ``crs`` are given).
    line : ndarray
        Line number per sample (NaN: none).
    x_m, y_m : ndarray, optional
        Projected coordinates [m] already known (then ``crs`` is their EPSG code).
    crs : int, optional
        EPSG code of the projection (default: the UTM zone of the survey's centre).
    line_type : sequence of str, optional
        ``line``/``tie`` per sample, any case (takes precedence over ``ties``).
    ties : sequence of float, optional
        Numbers of the tie lines (else the direction rule: lines more than 45 degrees from
        the dominant direction).
    gap_m : float, optional
        A step longer than this inside a line starts a new piece [m] (default 10 times the
        median step, at least 100 m).
    window : int
        Half-width, samples, of the local track direction that finds the turns.
    source : str
        Name for messages.

    Returns
    -------
    SurveyGeometry

    Raises
    ------
    InputError
        No line number at all, an unknown ``line_type`` value, or a tie number not in the
        survey.
    """
    line = np.asarray(line, dtype=np.float64)
    if not np.isfinite(line).any():
        raise InputError(f"{source}: column line holds no line number; the levelling needs "
                         "the flight-line number of each sample (map it with --col "
                         "line=NAME)")
    if x_m is None or y_m is None:
        if lat is None or lon is None:
            raise InputError(f"{source}: no lat/lon columns to project")
        lat = np.asarray(lat, dtype=np.float64)
        lon = np.asarray(lon, dtype=np.float64)
        ok = np.isfinite(lat) & np.isfinite(lon)
        if not ok.any():
            raise InputError(f"{source}: columns lat, lon hold no position")
        if crs is None:
            crs = utm_epsg(lat[ok], lon[ok])
        x_m, y_m = project(lat, lon, crs)
    elif crs is None:
        raise InputError(f"{source}: projected coordinates need their EPSG code (crs=)")
    x = np.asarray(x_m, dtype=np.float64)
    y = np.asarray(y_m, dtype=np.float64)
    piece, starts = _pieces(line, x, y, gap_m)
    ends = np.r_[starts[1:], line.size]
    # A piece ends where the next starts or at the first sample without a line.
    npc = starts.size
    piece_line = line[starts]
    direction = np.empty(npc)
    straight = np.zeros(line.size, dtype=bool)
    along = np.full(line.size, np.nan)
    bounds = []
    for k in range(npc):
        a = starts[k]
        b = a + int(np.count_nonzero(piece[a:ends[k]] == k))
        bounds.append((a, b))
        direction[k] = line_direction_deg(x[a:b], y[a:b])
    for k, (a, b) in enumerate(bounds):
        if b - a >= 2:
            straight[a:b], along[a:b] = _straight_and_along(x[a:b], y[a:b], direction[k], window)
    is_tie, tie_source = _classify(piece, piece_line, direction, bounds, line_type, ties, source)
    sizes = np.array([b - a for a, b in bounds], dtype=float)
    dom = _dominant(direction[~is_tie], sizes[~is_tie])
    th = np.deg2rad(dom + 90.0)
    centre = np.array([np.nanmean(x[a:b]) * np.sin(th) + np.nanmean(y[a:b]) * np.cos(th)
                       for a, b in bounds])
    spacing = _line_spacing(piece_line, is_tie, centre)
    return SurveyGeometry(int(crs), x, y, line, piece, piece_line, is_tie, direction, straight,
                          along, spacing, tie_source)


def _dominant(d: np.ndarray, n: np.ndarray) -> float:
    """Sample-weighted dominant direction (doubled-angle mean) [deg]."""
    ok = np.isfinite(d)
    if not ok.any():
        return 0.0
    c = np.sum(n[ok] * np.cos(np.deg2rad(2 * d[ok])))
    s = np.sum(n[ok] * np.sin(np.deg2rad(2 * d[ok])))
    return float(np.rad2deg(np.arctan2(s, c)) / 2.0 % 180.0)


def _classify(piece: np.ndarray, piece_line: np.ndarray, direction: np.ndarray,
              bounds: list[tuple[int, int]], line_type: Sequence[str] | np.ndarray | None,
              ties: Sequence[float] | None, source: str) -> tuple[np.ndarray, str]:
    if line_type is not None:
        lt = np.asarray(line_type, dtype=object)
        low = np.array([str(v).strip().lower() for v in lt[[a for a, _ in bounds]]])
        bad = sorted(set(low) - {"line", "tie"})
        if bad:
            raise InputError(f"{source}: column line_type holds {bad[0]!r}; expected 'line' or "
                             "'tie' (any case)")
        return low == "tie", "line_type"
    if ties is not None:
        want = np.asarray(list(ties), dtype=float)
        missing = [t for t in want if not np.any(piece_line == t)]
        if missing:
            raise InputError(f"{source}: --ties {missing[0]:g} is not a line number of the "
                             "survey")
        return np.isin(piece_line, want), "list"
    dom = _dominant(direction, np.array([b - a for a, b in bounds], dtype=float))
    # A whole line is a tie when its samples (over its pieces) run across the dominant way.
    is_tie = angle_difference_deg(direction, dom) > TIE_ANGLE_DEG
    nums = np.unique(piece_line)
    for num in nums:
        m = piece_line == num
        n = np.array([bounds[k][1] - bounds[k][0] for k in np.flatnonzero(m)])
        is_tie[m] = n[is_tie[m]].sum() > n[~is_tie[m]].sum()
    return is_tie, "direction"
