"""Micro-levelling (decorrugation): the line-parallel stripes tie-line levelling leaves.

After Minty (1991): the corrugation is what a grid of the levelled data holds at short
wavelengths *across* the lines (a high-pass at a few line spacings) and long wavelengths
*along* them (a low-pass).  Here the grid has cells of half a line spacing in the lines' own
frame (along and across the dominant line direction), filled from the lines' straight parts
at their true positions (each line resampled along, then each column interpolated across
the lines); the ties are left out (they are the datum).  Both directional filters are
Gaussian (normalised convolution, so the survey's edges and gaps are filtered over the data
there is); the filtered grid is sampled back onto each line's samples and subtracted.

Bounded so that it cannot remove geology, twice:

* a correction is clipped to ``limit_nT`` (by default three times the robust mistie std left
  by the tie-line levelling: the size of level error the crossings show is left), so a
  geological feature striking along the lines loses at most that much;
* the crossing check (given the crossings and their misties after levelling): the ties are
  the datum and are not corrected, so a correction ``c`` of a line changes its misties from
  ``m`` to ``m - c`` at its crossings.  A correction the misties do not support is not a
  level error the ties see but geology the directional filter took for one (after tie-line
  levelling ``m`` is only noise, and any ``c`` raises it).  Each line's correction is
  scaled by the least-squares factor ``a = clip(sum w m c / sum w c^2, 0, 1)``, which never
  raises the weighted mistie sum ``sum w (m - a c)^2``, and rejected (``a = 0``) unless
  that sum falls significantly: ``sum w m c / sqrt(sum w c^2) >= 2 sigma``, ``sigma`` the
  pooled robust std of the residuals ``sqrt(w) (m - a c)`` over the survey, corrected for
  the one factor fitted per line (a one-sided 2-sigma test of the regression of the
  misties on the correction; on 4 crossings of noise a bare least-squares factor keeps
  some geology by chance).  A line without
  a crossing keeps the clipped correction.

The std removed per line, the scale per line and the mistie std before and after are
reported.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import RegularGridInterpolator
from scipy.ndimage import gaussian_filter1d

from .crossings import Crossings, MistieStd
from .geometry import SurveyGeometry
from .levelling import robust_std

__all__ = ["DecorrugationResult", "decorrugate"]

#: Significance the crossing check asks of a line's correction: the lowering of its weighted
#: mistie sum, in units of the misties' robust scale, must be at least CHECK_T squared
#: (a one-sided 2-sigma test that the correction has the sign and shape of its misties).
CHECK_T = 2.0

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
    scale : dict
        Line number -> factor of the crossing check applied to its correction (1: kept,
        0: rejected; a line in pieces: the sample-weighted mean of its pieces'); empty
        without crossings.
    mistie_std_nT, mistie_robust_std_nT : MistieStd
        Std and robust std of the crossing misties before and after the micro-levelling [nT]
        (None without crossings).
    """

    correction_nT: np.ndarray
    limit_nT: float
    across_wavelength_m: float
    along_wavelength_m: float
    std_removed_nT: dict[float, float]
    fraction_clipped: float
    scale: dict[float, float] = field(default_factory=dict)
    mistie_std_nT: MistieStd = field(default_factory=MistieStd)
    mistie_robust_std_nT: MistieStd = field(default_factory=MistieStd)

    def to_dict(self) -> dict:
        """JSON-ready summary."""
        vals = np.array(list(self.std_removed_nT.values()) or [np.nan])
        sc = np.array(list(self.scale.values()) or [np.nan])
        with np.errstate(all="ignore"):
            return {"limit_nT": self.limit_nT,
                    "across_wavelength_m": self.across_wavelength_m,
                    "along_wavelength_m": self.along_wavelength_m,
                    "fraction_clipped": self.fraction_clipped,
                    "std_removed_median_nT": _nan_none(np.nanmedian(vals)),
                    "std_removed_max_nT": _nan_none(np.nanmax(vals)),
                    "crossing_check": bool(self.scale),
                    "n_lines_kept": int(np.sum(sc >= 1.0)),
                    "n_lines_scaled": int(np.sum((sc > 0.0) & (sc < 1.0))),
                    "n_lines_rejected": int(np.sum(sc <= 0.0)),
                    "n_lines_unchecked": (len(self.std_removed_nT) - len(self.scale)
                                          if self.scale else None),
                    "mistie_std_nT": self.mistie_std_nT.to_dict(),
                    "mistie_robust_std_nT": self.mistie_robust_std_nT.to_dict()}


def _nan_none(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None


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
                across_lines: float = 4.0, along_lines: float = 20.0,
                crossings: Crossings | None = None, mistie_nT: np.ndarray | None = None,
                crossing_weight: np.ndarray | None = None) -> DecorrugationResult:
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
    crossings : Crossings, optional
        The line-tie crossings of ``value``'s survey: enables the crossing check (each
        line's correction scaled so that it never raises the line's weighted mistie sum).
    mistie_nT : ndarray, optional
        Misties of ``value`` at the crossings [nT] (default ``crossings.mistie_nT``; after
        tie-line levelling give the levelled misties).
    crossing_weight : ndarray, optional
        Weight of each crossing in the check (default equal; the levelling's final weights
        discount steep gradients, height differences and rejected crossings).

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
    # the crossing check: each piece's clipped correction at its crossings against its misties
    piece_scale = np.ones(geom.n_pieces)
    checked = np.zeros(geom.n_pieces, dtype=bool)
    mist = c_at = w = None
    if crossings is not None and crossings.n > 0:
        mist = np.asarray(crossings.mistie_nT if mistie_nT is None else mistie_nT, float)
        w = (np.ones(crossings.n) if crossing_weight is None
             else np.asarray(crossing_weight, float))
        uc = crossings.x_m * np.sin(th) + crossings.y_m * np.cos(th)
        vc = crossings.x_m * np.cos(th) - crossings.y_m * np.sin(th)
        c_at = np.clip(at(np.column_stack([vc, uc])), -limit_nT, limit_nT)
        ok = np.isfinite(mist) & np.isfinite(w) & (w > 0)
        pc = crossings.line_piece[ok]
        m_, c_, w_ = mist[ok], c_at[ok], w[ok]
        n_p = geom.n_pieces
        smc = np.bincount(pc, weights=w_ * m_ * c_, minlength=n_p)
        scc = np.bincount(pc, weights=w_ * c_ * c_, minlength=n_p)
        checked = np.bincount(pc, minlength=n_p) > 0
        # the factor a minimising sum w (m - a c)^2 is smc / scc; it lowers the sum by
        # smc^2 / scc, which must exceed what the misties' noise gives (t >= 2), the noise
        # being the pooled robust scale of the residuals sqrt(w) (m - a c) (one factor fitted
        # per checked piece: dof-corrected)
        with np.errstate(invalid="ignore", divide="ignore"):
            best = np.clip(np.where(scc > 0, smc / scc, 0.0), 0.0, 1.0)
        resid = np.sqrt(w_) * (m_ - best[pc] * c_)
        n_used, n_fit = resid.size, int(checked.sum())
        sigma = robust_std(resid) * np.sqrt(n_used / max(n_used - n_fit, 1))
        sigma = max(sigma, 1e-6 * max(robust_std(np.sqrt(w_) * m_), 1e-9))
        with np.errstate(invalid="ignore", divide="ignore"):
            t = np.where(scc > 0, smc / (sigma * np.sqrt(scc)), 0.0)
        piece_scale = np.where(checked, np.where(t >= CHECK_T, best, 0.0), 1.0)
    removed: dict[float, float] = {}
    scale_n: dict[float, list[float]] = {}
    n_clip = n_tot = 0
    for g in groups:
        k = int(geom.piece[g[0]])
        c = at(np.column_stack([v[g], u[g]]))
        n_clip += int(np.count_nonzero(np.abs(c) > limit_nT))
        n_tot += c.size
        c = piece_scale[k] * np.clip(c, -limit_nT, limit_nT)
        corr[g] = c
        num = float(geom.piece_line[k])
        removed[num] = float(np.hypot(removed.get(num, 0.0), np.std(c)))
        if checked[k]:
            acc = scale_n.setdefault(num, [0.0, 0.0])
            acc[0] += piece_scale[k] * g.size
            acc[1] += g.size
    res = DecorrugationResult(corr, float(limit_nT), across_lines * spacing,
                              along_lines * spacing, removed, n_clip / max(n_tot, 1),
                              scale={num: a / n for num, (a, n) in scale_n.items()})
    if mist is not None and c_at is not None:
        after = mist - piece_scale[crossings.line_piece] * c_at
        fin = np.isfinite(mist)
        res.mistie_std_nT = MistieStd(before=float(np.std(mist[fin])),
                                      after=float(np.std(after[fin])))
        res.mistie_robust_std_nT = MistieStd(before=robust_std(mist), after=robust_std(after))
    return res
