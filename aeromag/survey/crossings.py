"""Line-tie crossings: found through a spatial index, values interpolated at the crossing.

The straight part of every piece is a polyline of segments between consecutive samples.
Candidate (line segment, tie segment) pairs come from a k-d tree of the tie segments'
midpoints queried with the line segments' midpoints within half the two longest segments'
lengths (``scipy.spatial.cKDTree.sparse_distance_matrix``): about one candidate per true
crossing, never all pairs.  Only the line segments in cells (of that radius) next to a tie
segment's go into the tree: a few per crossing, not the whole survey.  Each candidate is
tested exactly (segment intersection); at a crossing the value, the height and the
along-track gradient of each of the two lines are interpolated linearly along its segment.
A (line piece, tie piece) pair crossing more than once (a wiggle) keeps one crossing, the
one nearest to the middle of the crossings.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from .geometry import SurveyGeometry

__all__ = ["BLOCK_SAMPLES", "Crossings", "MistieStd", "along_gradient", "find_crossings"]


@dataclass(frozen=True)
class MistieStd:
    """Spread of the crossing misties before and after a correction.

    Attributes
    ----------
    before, after : float or None
        Std (or robust std) of the misties before and after [nT]; None without crossings.
    """

    before: float | None = None
    after: float | None = None

    def to_dict(self) -> dict[str, float | None]:
        """JSON-ready dict: ``{"before": ..., "after": ...}``."""
        return {"before": self.before, "after": self.after}

    @classmethod
    def from_dict(cls, d: dict[str, float | None]) -> MistieStd:
        """Read a pair written by :meth:`to_dict`."""
        return cls(before=d["before"], after=d["after"])


@dataclass
class Crossings:
    """Line-tie intersections.

    Attributes
    ----------
    line_piece, tie_piece : ndarray of int
        Piece indices of the line and the tie.
    line, tie : ndarray
        Their line numbers.
    x_m, y_m : ndarray
        Position of the crossing [m].
    line_along_m, tie_along_m : ndarray
        Along-piece distance of the crossing on the line and on the tie [m].
    line_value, tie_value : ndarray
        Values interpolated at the crossing [nT].
    mistie_nT : ndarray
        ``line_value - tie_value`` [nT].
    dh_m : ndarray
        Height of the line minus height of the tie at the crossing [m] (NaN: no height).
    gradient_nT_m : ndarray
        Horizontal gradient magnitude at the crossing from the two along-track gradients
        [nT/m].
    line_index, tie_index : ndarray of int
        First sample of the segment holding the crossing on the line and on the tie.
    line_frac, tie_frac : ndarray
        Fraction along that segment.
    """

    line_piece: np.ndarray
    tie_piece: np.ndarray
    line: np.ndarray
    tie: np.ndarray
    x_m: np.ndarray
    y_m: np.ndarray
    line_along_m: np.ndarray
    tie_along_m: np.ndarray
    line_value: np.ndarray
    tie_value: np.ndarray
    mistie_nT: np.ndarray
    dh_m: np.ndarray
    gradient_nT_m: np.ndarray
    line_index: np.ndarray
    tie_index: np.ndarray
    line_frac: np.ndarray
    tie_frac: np.ndarray

    @property
    def n(self) -> int:
        """Number of crossings."""
        return int(self.mistie_nT.size)

    def values_at(self, value: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Another column interpolated at the crossings (line side, tie side).

        Parameters
        ----------
        value : ndarray, shape (n_samples,)
            Per-sample values.

        Returns
        -------
        line_value, tie_value : ndarray
        """
        a, f = self.line_index, self.line_frac
        b, g = self.tie_index, self.tie_frac
        return (value[a] + f * (value[a + 1] - value[a]),
                value[b] + g * (value[b + 1] - value[b]))


def along_gradient(geom: SurveyGeometry, value: np.ndarray, half_width: int = 3,
                   index: np.ndarray | None = None) -> np.ndarray:
    """Along-track derivative of a value inside each piece [value unit per m].

    A central difference over ``2 half_width`` samples, shortened at the piece's ends.

    Parameters
    ----------
    geom : SurveyGeometry
        Geometry.
    value : ndarray
        Per-sample values.
    half_width : int
        Samples each side.
    index : ndarray of int, optional
        Only at these samples (default: every sample); the values are those of the whole
        array at the same samples.

    Returns
    -------
    ndarray
        Per sample (or per ``index``); NaN where no two samples of the piece are available.
    """
    n = value.size
    i = np.arange(n) if index is None else np.asarray(index, dtype=np.int64)
    p = geom.piece
    pi = p[i]
    out = np.full(i.size, np.nan)
    lo = np.clip(i - half_width, 0, n - 1)
    hi = np.clip(i + half_width, 0, n - 1)
    # Pull each end back inside the sample's piece.
    for _ in range(half_width):
        bad = p[lo] != pi
        lo[bad] += 1
        bad = p[hi] != pi
        hi[bad] -= 1
    ds = np.hypot(geom.x_m[hi] - geom.x_m[lo], geom.y_m[hi] - geom.y_m[lo])
    ok = (hi > lo) & (pi >= 0) & (ds > 0)
    out[ok] = (value[hi[ok]] - value[lo[ok]]) / ds[ok]
    return out


def _segments(geom: SurveyGeometry, tie: bool, valid: np.ndarray) -> np.ndarray:
    """First sample of each segment of straight parts of the line (or tie) pieces."""
    p = geom.piece
    ok = (p[:-1] >= 0) & (p[:-1] == p[1:]) & geom.straight[:-1] & geom.straight[1:]
    ok &= valid[:-1] & valid[1:]
    tie_s = np.zeros(p.size - 1, dtype=bool)
    tie_s[ok] = geom.piece_is_tie[p[:-1][ok]]
    ok &= tie_s == tie
    return np.flatnonzero(ok)


#: Line segments screened against the ties' cells at a time.
BLOCK_SAMPLES = 1_000_000


def _seg_len(x: np.ndarray, y: np.ndarray, s: np.ndarray) -> float:
    """Longest of the segments starting at the samples ``s`` [m], in blocks."""
    blocks = (s[a:a + BLOCK_SAMPLES] for a in range(0, s.size, BLOCK_SAMPLES))
    return max(float(np.max(np.hypot(x[k + 1] - x[k], y[k + 1] - y[k]))) for k in blocks)


def _near_ties(x: np.ndarray, y: np.ndarray, ls: np.ndarray, ts: np.ndarray, radius: float
               ) -> np.ndarray:
    """The line segments whose midpoint may lie within ``radius`` of a tie segment's.

    Cells of ``radius``: a midpoint within ``radius`` of another lies in the same cell or a
    neighbouring one, so the line segments outside the cells next to a tie's never make a
    candidate pair; the rest (a few per crossing) go to the k-d tree.
    """
    size = 2.0 * (radius * 1.001 if radius > 0 else 1.0)  # twice the cell: of x[k] + x[k+1]

    def cells(k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return (np.floor((x[k] + x[k + 1]) / size).astype(np.int64),
                np.floor((y[k] + y[k + 1]) / size).astype(np.int64))

    tx, ty = cells(ts)
    x0, y0 = int(tx.min()) - 2, int(ty.min()) - 2
    width = int(tx.max()) - x0 + 3
    near = np.unique(np.concatenate([(ty - y0 + dy) * width + (tx - x0 + dx)
                                     for dx in (-1, 0, 1) for dy in (-1, 0, 1)]))
    keep = []
    for a in range(0, ls.size, BLOCK_SAMPLES):
        k = ls[a:a + BLOCK_SAMPLES]
        cx, cy = cells(k)
        inside = (cx >= x0) & (cx < x0 + width) & (cy >= y0)
        key = (cy - y0) * width + (cx - x0)
        j = np.clip(np.searchsorted(near, key), 0, near.size - 1)
        keep.append(k[inside & (near[j] == key)])
    return np.concatenate(keep)


def find_crossings(geom: SurveyGeometry, value: np.ndarray, height_m: np.ndarray | None = None
                   ) -> Crossings:
    """Every intersection of a line piece with a tie piece.

    Parameters
    ----------
    geom : SurveyGeometry
        Geometry (straight parts only are used).
    value : ndarray, shape (n,)
        The values compared at the crossings [nT] (samples with NaN make no segment).
    height_m : ndarray, optional
        Height per sample [m] for the height difference.

    Returns
    -------
    Crossings
    """
    x, y = geom.x_m, geom.y_m
    valid = np.isfinite(value) & np.isfinite(x) & np.isfinite(y)
    ls = _segments(geom, False, valid)
    ts = _segments(geom, True, valid)
    empty = np.array([], dtype=float)
    ei = np.array([], dtype=np.int64)
    none = Crossings(ei, ei, empty, empty, empty, empty, empty, empty, empty, empty, empty,
                     empty, empty, ei, ei, empty, empty)
    if ls.size == 0 or ts.size == 0:
        return none
    radius = 0.5 * (_seg_len(x, y, ls) + _seg_len(x, y, ts)) * 1.0001
    ls = _near_ties(x, y, ls, ts, radius)
    if ls.size == 0:
        return none
    lm = np.column_stack([(x[ls] + x[ls + 1]) / 2, (y[ls] + y[ls + 1]) / 2])
    tm = np.column_stack([(x[ts] + x[ts + 1]) / 2, (y[ts] + y[ts + 1]) / 2])
    tt = cKDTree(tm)
    near = cKDTree(lm).sparse_distance_matrix(tt, radius, output_type="ndarray")
    # in a fixed order (the trees' order depends on which segments they hold)
    near = near[np.lexsort((near["j"], near["i"]))]
    ai = near["i"].astype(np.int64)
    bi = near["j"].astype(np.int64)
    a, b = ls[ai], ts[bi]
    px, py = x[a], y[a]
    rx, ry = x[a + 1] - px, y[a + 1] - py
    qx, qy = x[b], y[b]
    sx, sy = x[b + 1] - qx, y[b + 1] - qy
    den = rx * sy - ry * sx
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((qx - px) * sy - (qy - py) * sx) / den
        u = ((qx - px) * ry - (qy - py) * rx) / den
    # Closed intervals with a rounding margin: a crossing on a shared vertex must not fall
    # between two segments (t = 1 - eps on one, -eps on the next); duplicates of one
    # crossing are reduced to one per (line piece, tie piece) below.
    eps = 1e-9
    hit = (den != 0) & (t >= -eps) & (t <= 1 + eps) & (u >= -eps) & (u <= 1 + eps)
    a, b = a[hit], b[hit]
    t, u = np.clip(t[hit], 0.0, 1.0), np.clip(u[hit], 0.0, 1.0)
    # One crossing per (line piece, tie piece).
    lp, tp = geom.piece[a], geom.piece[b]
    key = lp * (geom.n_pieces + 1) + tp
    order = np.lexsort((geom.along_m[a] + t, key))
    key_s = key[order]
    first = np.r_[True, key_s[1:] != key_s[:-1]]
    starts = np.flatnonzero(first)
    counts = np.diff(np.r_[starts, key_s.size])
    pick = order[starts + counts // 2]
    a, b, t, u = a[pick], b[pick], t[pick], u[pick]
    lp, tp = geom.piece[a], geom.piece[b]
    cx = x[a] + t * (x[a + 1] - x[a])
    cy = y[a] + t * (y[a + 1] - y[a])
    lv = value[a] + t * (value[a + 1] - value[a])
    tv = value[b] + u * (value[b + 1] - value[b])
    ga, ga1, gb, gb1 = (along_gradient(geom, value, index=k) for k in (a, a + 1, b, b + 1))
    gl = ga + t * (ga1 - ga)
    gt = gb + u * (gb1 - gb)
    g = np.hypot(np.nan_to_num(gl), np.nan_to_num(gt))
    if height_m is not None:
        h = np.asarray(height_m, dtype=float)
        dh = (h[a] + t * (h[a + 1] - h[a])) - (h[b] + u * (h[b + 1] - h[b]))
    else:
        dh = np.full(a.size, np.nan)
    la = geom.along_m[a] + t * (geom.along_m[a + 1] - geom.along_m[a])
    ta = geom.along_m[b] + u * (geom.along_m[b + 1] - geom.along_m[b])
    order = np.lexsort((tp, lp))
    sel = [arr[order] for arr in (lp, tp, cx, cy, la, ta, lv, tv, dh, g, a, b, t, u)]
    lp, tp, cx, cy, la, ta, lv, tv, dh, g, a, b, t, u = sel
    return Crossings(lp, tp, geom.piece_line[lp], geom.piece_line[tp], cx, cy, la, ta, lv, tv,
                     lv - tv, dh, g, a, b, t, u)
