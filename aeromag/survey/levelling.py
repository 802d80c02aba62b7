"""Tie-line levelling: one least-squares network adjustment over all crossings.

Every piece (a run of a line or of a tie) gets a correction ``c(s)`` along its own distance
``s``: piecewise linear in ``s`` with knots ("hat" basis), so one knot is a shift, two knots
(the ends of the piece's crossings) a linear trend, and more knots a smooth correction.  The
mistie after levelling at a crossing is ``(v_line + c_line(s_line)) - (v_tie + c_tie(s_tie))``;
all knot values are solved at once (Yarger et al., 1978; GMT's x2sys_solve), weighted:

* each crossing's weight is ``1 / (sigma0^2 + (g d_xy)^2 + (g dh)^2)``: ``g`` the horizontal
  gradient there, ``d_xy`` a positioning uncertainty, ``dh`` the height difference of line
  and tie (a crossing on a steep gradient or between different heights is weighted down, as
  Oasis's XLEVEL limits do, without a hard cut);
* robust: iteratively reweighted (Huber passes, then Tukey bisquare passes, scale from the
  median absolute deviation of the weighted residuals); a crossing given no weight by the
  bisquare counts as rejected;
* one datum fixed per connected network (pieces linked through crossings; two blocks flown
  with their own ties are two networks): the mean correction over the network's samples is
  zero (each piece weighted by its samples, its correction by the mean of its knots), so the
  survey keeps its level and only the relative levels of lines and ties change; a small
  damping of the slopes (differences of adjacent knots) removes the tilt a
  crossing network cannot see (all lines tilted alike, ties shifted to match), choosing the
  least-tilted solution.

Pieces with fewer than ``trend_min`` crossings get a shift only; with ``method="smooth"``
knots are placed every ``knot_m`` metres along lines with enough crossings (at least three
crossings per knot).  Samples beyond a piece's first or last crossing take the correction at
that end (never extrapolated).  Each pass's mistie std is reported.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.sparse.linalg import splu, spsolve

from ..errors import InputError
from .crossings import Crossings

log = logging.getLogger(__name__)

__all__ = ["LevellingPass", "LevellingResult", "METHODS", "level_network", "robust_std"]

#: Levelling methods (``--level``).
METHODS = ("none", "shift", "trend", "smooth")


def robust_std(r: np.ndarray) -> float:
    """1.4826 times the median absolute deviation from the median (NaN-safe).

    Parameters
    ----------
    r : ndarray
        Values.

    Returns
    -------
    float
        Robust standard deviation (NaN when empty).
    """
    r = np.asarray(r, dtype=float)
    r = r[np.isfinite(r)]
    if r.size == 0:
        return float("nan")
    return float(1.4826 * np.median(np.abs(r - np.median(r))))


@dataclass
class LevellingPass:
    """One pass of the robust adjustment.

    Attributes
    ----------
    kind : str
        ``"weighted"`` (first), ``"huber"`` or ``"bisquare"``.
    mistie_std_nT, mistie_robust_std_nT : float
        Std and robust std of the misties after this pass [nT].
    n_rejected : int
        Crossings given (almost) no weight by this pass.
    """

    kind: str
    mistie_std_nT: float
    mistie_robust_std_nT: float
    n_rejected: int

    def to_dict(self) -> dict:
        """JSON-ready form."""
        return {"kind": self.kind, "mistie_std_nT": self.mistie_std_nT,
                "mistie_robust_std_nT": self.mistie_robust_std_nT,
                "n_rejected": self.n_rejected}


@dataclass
class LevellingResult:
    """The solved network.

    Attributes
    ----------
    method : str
        Levelling method.
    knots_m : list of ndarray
        Knot positions (along-piece distance, m) of each piece (empty: not levelled).
    values_nT : list of ndarray
        Correction at each knot [nT].
    mistie_lev_nT : ndarray
        Misties after levelling, per crossing [nT].
    weight : ndarray
        Final weight of each crossing (relative, 0-1 after the robust passes).
    passes : list of LevellingPass
        The passes.
    n_unlevelled : int
        Pieces without a crossing (no correction).
    n_networks : int
        Connected networks of pieces (each with its own datum).
    n_parameters_effective : float
        Effective number of fitted parameters (trace of the hat matrix of the last pass, the
        datum constraints and the trend prior included): what the corrections can absorb.
    dof : float
        Crossings with weight minus ``n_parameters_effective``. When it is small, the
        levelled misties show how well the corrections fit the crossings, not the level
        error that is left.
    """

    method: str
    knots_m: list[np.ndarray]
    values_nT: list[np.ndarray]
    mistie_lev_nT: np.ndarray
    weight: np.ndarray
    passes: list[LevellingPass] = field(default_factory=list)
    n_unlevelled: int = 0
    n_networks: int = 1
    n_parameters_effective: float = float("nan")
    dof: float = float("nan")

    def correction(self, piece: np.ndarray, along_m: np.ndarray) -> np.ndarray:
        """The correction at samples (0 where the piece was not levelled).

        Parameters
        ----------
        piece : ndarray of int
            Piece index per sample (-1: none; NaN correction).
        along_m : ndarray
            Along-piece distance per sample [m].

        Returns
        -------
        ndarray
            Correction [nT] (constant beyond the end knots).
        """
        out = np.full(piece.size, np.nan)
        if piece.size == 0:
            return out
        # Runs of one piece (a piece is one run in a survey's geometry): slices, no sort
        # and no index arrays of every sample.
        cuts = np.flatnonzero(np.diff(piece)) + 1
        starts, ends = np.r_[0, cuts], np.r_[cuts, piece.size]
        for a, b in zip(starts.tolist(), ends.tolist(), strict=True):
            k = int(piece[a])
            if k < 0:
                continue
            kn, val = self.knots_m[k], self.values_nT[k]
            if kn.size == 0:
                out[a:b] = 0.0
            elif kn.size == 1:
                out[a:b] = val[0]
            else:
                out[a:b] = np.interp(along_m[a:b], kn, val)
        return out


def _hat_rows(s: np.ndarray, knots: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Indices (left knot) and weights (left, right) of the hat basis at s."""
    if knots.size == 1:
        return np.zeros(s.size, dtype=np.int64), np.ones(s.size)
    sc = np.clip(s, knots[0], knots[-1])
    j = np.clip(np.searchsorted(knots, sc, side="right") - 1, 0, knots.size - 2)
    w = (sc - knots[j]) / (knots[j + 1] - knots[j])
    return j, 1.0 - w


def _knots(s: np.ndarray, n_knots: int) -> np.ndarray:
    lo, hi = float(s.min()), float(s.max())
    if n_knots <= 1 or hi - lo < 1.0:
        return np.array([0.5 * (lo + hi)])
    return np.linspace(lo, hi, n_knots)


def _plan_knots(cx: Crossings, n_pieces: int, is_tie: np.ndarray, method: str, trend_min: int,
                knot_m: float, tie_trend: bool) -> list[np.ndarray]:
    knots: list[np.ndarray] = []
    s_all = [[] for _ in range(n_pieces)]
    for p, s in zip(cx.line_piece, cx.line_along_m, strict=True):
        s_all[p].append(s)
    for p, s in zip(cx.tie_piece, cx.tie_along_m, strict=True):
        s_all[p].append(s)
    for k in range(n_pieces):
        s = np.asarray(s_all[k], dtype=float)
        if s.size == 0:
            knots.append(np.array([]))
            continue
        n = 1
        allow = method in ("trend", "smooth") and (not is_tie[k] or tie_trend)
        if allow and s.size >= trend_min:
            n = 2
            if method == "smooth":
                n = int(np.clip(np.ceil((s.max() - s.min()) / knot_m) + 1, 2,
                                max(2, s.size // 3)))
        knots.append(_knots(s, n))
    return knots


def _leverage(N: sp.spmatrix, A: sp.csr_matrix, weights: np.ndarray, block: int = 2048
              ) -> np.ndarray:
    """Diagonal of the hat matrix ``A N^-1 A^T W`` (one leverage per crossing, 0-1).

    ``N`` is factorised once and solved for blocks of crossings, so memory stays at
    ``n_par x block`` whatever the number of crossings.
    """
    lu = splu(sp.csc_matrix(N))
    At = sp.csc_matrix(A.T)
    h = np.empty(A.shape[0])
    for i in range(0, A.shape[0], block):
        cols = At[:, i:i + block].toarray()
        h[i:i + block] = weights[i:i + block] * np.einsum("ij,ij->j", cols, lu.solve(cols))
    return np.clip(h, 0.0, 1.0)


def level_network(cx: Crossings, n_pieces: int, is_tie: np.ndarray, *, method: str = "trend",
                  sigma0_nT: float = 1.0, position_m: float = 5.0, trend_min: int = 3,
                  knot_m: float = 5000.0, tie_trend: bool = False, passes: int = 6,
                  huber_k: float = 1.5, bisquare_c: float = 4.685, damping: float = 1e-3,
                  piece_samples: np.ndarray | None = None, trend_prior_nT: float = 20.0,
                  source: str = "<survey>"
                  ) -> LevellingResult:
    """Solve the corrections of all pieces from the crossings' misties.

    Parameters
    ----------
    cx : Crossings
        The crossings (``mistie_nT``, gradient and height difference).
    n_pieces : int
        Number of pieces of the survey.
    is_tie : ndarray of bool, shape (n_pieces,)
        Tie pieces.
    method : {"shift", "trend", "smooth"}
        Correction shape per line piece (ties: a shift unless ``tie_trend``).
    sigma0_nT : float
        Mistie noise of a crossing on a flat field [nT].
    position_m : float
        Positioning uncertainty multiplying the gradient [m].
    trend_min : int
        Fewest crossings for more than a shift.
    knot_m : float
        Knot spacing of ``smooth`` [m].
    tie_trend : bool
        Ties get the same shape as lines (else a shift).
    passes : int
        Total passes (1 weighted, then Huber, then the last two bisquare).
    huber_k, bisquare_c : float
        Robust tuning constants (in robust standard deviations).
    damping : float
        Weight of the slope damping relative to the median crossing weight.
    piece_samples : ndarray, optional
        Samples per piece: the datum's weights (default: equal).
    trend_prior_nT : float
        Prior std of the change of a correction between adjacent knots (a line's
        end-to-end trend) [nT]: a trend is fitted as far as the crossings' noise allows,
        never more (a line with three crossings on steep gradients keeps a small trend).
    source : str
        Name for messages.

    Returns
    -------
    LevellingResult

    Raises
    ------
    InputError
        An unknown method, or no crossing at all.
    """
    if method not in METHODS or method == "none":
        raise InputError(f"{source}: --level {method}: use one of "
                         f"{', '.join(m for m in METHODS)}")
    if cx.n == 0:
        raise InputError(f"{source}: no line crosses a tie line: the survey cannot be "
                         "tie-line levelled; give the tie lines (--ties ID,... or a line_type "
                         "column), or skip the levelling with --level none")
    knots = _plan_knots(cx, n_pieces, is_tie, method, trend_min, knot_m, tie_trend)
    offs = np.cumsum([0] + [k.size for k in knots])
    n_par = int(offs[-1])
    rows, cols, vals = [], [], []
    m = cx.n
    r_idx = np.arange(m)
    for piece, s, sign in ((cx.line_piece, cx.line_along_m, 1.0),
                           (cx.tie_piece, cx.tie_along_m, -1.0)):
        for k in np.unique(piece):
            sel = piece == k
            j, wl = _hat_rows(s[sel], knots[k])
            base = offs[k]
            rows += [r_idx[sel], r_idx[sel]]
            cols += [base + j, base + np.minimum(j + 1, knots[k].size - 1)]
            vals += [sign * wl, sign * (1.0 - wl)]
    A = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(m, n_par))
    b = -cx.mistie_nT
    g = np.nan_to_num(cx.gradient_nT_m)
    dh = np.nan_to_num(cx.dh_m)
    w0 = 1.0 / (sigma0_nT ** 2 + (g * position_m) ** 2 + (g * dh) ** 2)
    # Constraints: one datum per connected network (sample-weighted mean correction = 0),
    # slope damping, a tiny ridge.
    link = sp.coo_matrix((np.ones(m), (cx.line_piece, cx.tie_piece)), shape=(n_pieces,) * 2)
    n_net, net = connected_components(link, directed=False)
    wpiece = (np.ones(n_pieces) if piece_samples is None
              else np.asarray(piece_samples, dtype=float))
    c_r, c_c, c_v = [], [], []
    used = np.zeros(n_net, dtype=bool)
    for k in range(n_pieces):
        if knots[k].size:
            used[net[k]] = True
    net_row = np.cumsum(used) - 1
    tot = np.bincount(net, weights=wpiece * np.array([k.size > 0 for k in knots]),
                      minlength=n_net)
    for k in range(n_pieces):
        nk = knots[k].size
        if nk:
            c_r += [net_row[net[k]]] * nk
            c_c += list(range(offs[k], offs[k + 1]))
            c_v += [wpiece[k] / tot[net[k]] / nk] * nk
    wref = float(np.median(w0))
    C_rows = [sp.csr_matrix((c_v, (c_r, c_c)), shape=(int(used.sum()), n_par))]
    d_r, d_c, d_v = [], [], []
    nr = 0
    for k in range(n_pieces):
        kn = knots[k]
        for i in range(kn.size - 1):
            d_r += [nr, nr]
            d_c += [offs[k] + i, offs[k] + i + 1]
            d_v += [1.0, -1.0]
            nr += 1
    D = sp.csr_matrix((d_v, (d_r, d_c)), shape=(nr, n_par))
    C = sp.vstack(C_rows)
    CC = C.T @ C
    DD = D.T @ D
    ridge = sp.identity(n_par)
    weights = w0.copy()
    res_passes: list[LevellingPass] = []
    robust_w = np.ones(m)
    x = np.zeros(n_par)
    for p in range(max(1, passes)):
        if p == 0:
            kind = "weighted"
        else:
            z = (b - A @ x) * np.sqrt(w0)
            scale = robust_std(z)
            if not np.isfinite(scale) or scale <= 0:
                break
            u = np.abs(z - np.median(z)) / scale
            if p >= passes - 2 and passes >= 3:
                kind = "bisquare"
                robust_w = np.where(u < bisquare_c, (1 - (u / bisquare_c) ** 2) ** 2, 0.0)
            else:
                kind = "huber"
                robust_w = np.where(u <= huber_k, 1.0, huber_k / np.maximum(u, 1e-12))
            # Weights in 1/nT^2: the crossings' noise scale is the robust std of the
            # normalised residuals, so the prior on the slopes keeps its meaning in nT.
            weights = w0 * robust_w / max(scale, 1e-6) ** 2
        wmed = float(np.median(weights[weights > 0])) if np.any(weights > 0) else wref
        reg = (1e6 * wmed * m) * CC + (damping * wmed + 1.0 / trend_prior_nT ** 2) * DD \
            + 1e-9 * wmed * ridge
        W = sp.diags(weights)
        N = (A.T @ W @ A + reg).tocsc()
        x = spsolve(N, A.T @ (weights * b))
        lev = cx.mistie_nT + A @ x
        res_passes.append(LevellingPass(kind, float(np.std(lev)), robust_std(lev),
                                        int(np.count_nonzero(robust_w < 1e-3))))
        log.debug("%s: levelling pass %d (%s): mistie std %.3f nT, robust %.3f nT", source, p,
                  kind, res_passes[-1].mistie_std_nT, res_passes[-1].mistie_robust_std_nT)
    values = [x[offs[k]:offs[k + 1]] for k in range(n_pieces)]
    n_unlev = sum(1 for k in knots if k.size == 0)
    n_eff = float(_leverage(N, A, weights).sum())  # effective parameters: trace of the hat
    n_used = int(np.count_nonzero(weights > 1e-3 * float(weights.max())))
    return LevellingResult(method, knots, values, cx.mistie_nT + A @ x,
                           weights / max(float(weights.max()), 1e-300), res_passes, n_unlev,
                           int(used.sum()), n_eff, n_used - n_eff)
