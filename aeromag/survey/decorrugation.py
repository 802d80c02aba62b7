"""Micro-levelling (decorrugation): the line-parallel stripes tie-line levelling leaves.

After Minty (1991): the corrugation is what a grid of the levelled data holds at short
wavelengths *across* the lines (a high-pass at a few line spacings) and long wavelengths
*along* them (a low-pass).  Here the grid has cells of half a line spacing in the lines' own
frame (along and across the dominant line direction), filled from the lines' straight parts
at their true positions (each line resampled along, then each column interpolated across
the lines); the ties are left out (they are the datum).  Both directional filters are
Gaussian (normalised convolution, so the survey's edges and gaps are filtered over the data
there is); the filtered grid is sampled back onto each line's samples and subtracted.

Bounded so that it cannot remove geology: a correction is clipped to ``limit_nT`` (by
default three times the robust mistie std left by the tie-line levelling: the size of level
error the crossings show is left), so a geological feature striking along the lines loses
at most that much; the std removed per line is reported.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import RegularGridInterpolator
from scipy.ndimage import gaussian_filter1d

from .geometry import SurveyGeometry

__all__ = ["DecorrugationResult", "decorrugate"]

#: Gaussian sigma per cut-off wavelength (half-power point of exp(-(2 pi sigma / L)^2 / 2)).
_SIGMA_PER_WAVELENGTH = np.sqrt(2.0 * np.log(2.0)) / (2.0 * np.pi)


@dataclass
class DecorrugationResult:
    """The micro-levelling correction.

    Attributes
    ----------
    correction_nT : ndarray
        Per sample, subtracted from ``tmi_lev`` [nT] (0 on ties and off the lines).
    limit_nT : float
        Clip applied to the correction [nT].
    across_wavelength_m, along_wavelength_m : float
        Cut-offs of the across-line high-pass and the along-line low-pass [m].
    std_removed_nT : dict
        Line number -> std of the correction applied to it [nT].
    fraction_clipped : float
        Share of the corrected samples whose correction was clipped.
    """

    correction_nT: np.ndarray
    limit_nT: float
    across_wavelength_m: float
    along_wavelength_m: float
    std_removed_nT: dict[float, float]
    fraction_clipped: float

    def to_dict(self) -> dict:
        """JSON-ready summary."""
        vals = np.array(list(self.std_removed_nT.values()) or [np.nan])
        return {"limit_nT": self.limit_nT, "across_wavelength_m": self.across_wavelength_m,
                "along_wavelength_m": self.along_wavelength_m,
                "fraction_clipped": self.fraction_clipped,
                "std_removed_median_nT": float(np.nanmedian(vals)),
                "std_removed_max_nT": float(np.nanmax(vals))}


def _smooth(g: np.ndarray, sigma: float, axis: int) -> np.ndarray:
    """Gaussian low-pass of a grid with NaNs (normalised convolution)."""
    mask = np.isfinite(g)
    num = gaussian_filter1d(np.where(mask, g, 0.0), sigma, axis=axis, mode="constant")
    den = gaussian_filter1d(mask.astype(float), sigma, axis=axis, mode="constant")
    with np.errstate(invalid="ignore", divide="ignore"):
        out = num / den
    out[~mask] = np.nan
    return out


def decorrugate(geom: SurveyGeometry, value: np.ndarray, *, limit_nT: float,
                across_lines: float = 4.0, along_lines: float = 20.0) -> DecorrugationResult:
    """Remove the line-parallel corrugation of levelled line data.

    Parameters
    ----------
    geom : SurveyGeometry
        Geometry (``line_spacing_m`` sets the scales).
    value : ndarray
        Levelled values [nT].
    limit_nT : float
        Largest correction [nT] (the bound).
    across_lines : float
        Cut-off wavelength of the across-line high-pass, in line spacings.
    along_lines : float
        Cut-off wavelength of the along-line low-pass, in line spacings.

    Returns
    -------
    DecorrugationResult
    """
    n = value.size
    corr = np.zeros(n)
    spacing = geom.line_spacing_m
    lines = np.flatnonzero(~geom.piece_is_tie)
    if not np.isfinite(spacing) or lines.size < 3:
        return DecorrugationResult(corr, limit_nT, np.nan, np.nan, {}, 0.0)
    th = np.deg2rad(geom.lines_direction_deg)  # not a median: N-S lines are at 0 and 180
    u = geom.x_m * np.sin(th) + geom.y_m * np.cos(th)
    v = geom.x_m * np.cos(th) - geom.y_m * np.sin(th)
    sel = (geom.piece >= 0) & ~geom.is_tie & geom.straight & np.isfinite(value)
    idx = np.flatnonzero(sel)
    order = np.argsort(geom.piece[idx], kind="stable")
    idx = idx[order]
    groups = np.split(idx, np.flatnonzero(np.diff(geom.piece[idx])) + 1)
    groups = [g for g in groups if g.size >= 2]
    if len(groups) < 3:
        return DecorrugationResult(corr, limit_nT, np.nan, np.nan, {}, 0.0)
    # The grid: cells of half a line spacing in the lines' frame (u along, v across).  Each
    # line is resampled at the u nodes (its value and its true across position v: a line's
    # wander off its nominal track is geology seen elsewhere, not corrugation), then each
    # column is interpolated linearly across the lines onto the v nodes (no bridging of a
    # gap wider than two line spacings).
    cell = spacing / 2.0
    u_nodes = np.arange(float(u[idx].min()), float(u[idx].max()) + cell, cell)
    v_nodes = np.arange(float(v[idx].min()), float(v[idx].max()) + cell, cell)
    lv = np.full((len(groups), u_nodes.size), np.nan)
    lval = np.full((len(groups), u_nodes.size), np.nan)
    for r, g in enumerate(groups):
        o = np.argsort(u[g])
        ug = u[g][o]
        inside = (u_nodes >= ug[0]) & (u_nodes <= ug[-1])
        lv[r, inside] = np.interp(u_nodes[inside], ug, v[g][o])
        lval[r, inside] = np.interp(u_nodes[inside], ug, value[g][o])
    grid = np.full((v_nodes.size, u_nodes.size), np.nan)
    for c in range(u_nodes.size):
        ok = np.isfinite(lv[:, c])
        if ok.sum() < 2:
            continue
        o = np.argsort(lv[ok, c])
        vs, zs = lv[ok, c][o], lval[ok, c][o]
        col = np.interp(v_nodes, vs, zs, left=np.nan, right=np.nan)
        j = np.clip(np.searchsorted(vs, v_nodes), 1, vs.size - 1)
        col[(vs[j] - vs[j - 1]) > 2.0 * spacing] = np.nan
        grid[:, c] = col
    sig_across = _SIGMA_PER_WAVELENGTH * across_lines * spacing / cell  # rows (v)
    sig_along = _SIGMA_PER_WAVELENGTH * along_lines * spacing / cell  # columns (u)
    high = grid - _smooth(grid, sig_across, axis=0)
    corrug = np.nan_to_num(_smooth(high, sig_along, axis=1))
    at = RegularGridInterpolator((v_nodes, u_nodes), corrug, bounds_error=False,
                                 fill_value=0.0)
    removed: dict[float, float] = {}
    n_clip = n_tot = 0
    for g in groups:
        c = at(np.column_stack([v[g], u[g]]))
        n_clip += int(np.count_nonzero(np.abs(c) > limit_nT))
        n_tot += c.size
        c = np.clip(c, -limit_nT, limit_nT)
        corr[g] = c
        num = float(geom.piece_line[geom.piece[g[0]]])
        removed[num] = float(np.hypot(removed.get(num, 0.0), np.std(c)))
    return DecorrugationResult(corr, float(limit_nT), across_lines * spacing,
                               along_lines * spacing, removed, n_clip / max(n_tot, 1))
