"""Diagnostics of a least-squares fit from per-segment normal equations (pure numerics).

Given per-segment Gram matrices ``G_j = A_j' A_j``, right-hand sides ``b_j = A_j' y_j``,
``yy_j = y_j' y_j`` and sizes ``n_j`` (any object with the attributes ``ids``, ``n``, ``gram``,
``rhs``, ``yy``, e.g. :class:`aeromag.compensate.SegmentStats`):

* :func:`variance_inflation` - VIF per column, ``diag(R^-1)`` of the unit-diagonal Gram matrix;
* :func:`loso_cv` - leave-one-segment-out residuals, ``c_j = (G - G_j)^-1 (b - b_j)``;
* :func:`diagnostics_from_stats` - condition numbers, VIF and pooled CV in one call, as a
  :class:`FitDiagnostics`.

Used by the compensation fit (its report's ``fit`` block) and by :mod:`aeromag.qc`, so both give
the same numbers.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

__all__ = ["FitDiagnostics", "diagnostics_from_stats", "loso_cv", "variance_inflation"]

#: Keys of the diagnostics rebuilt from normal equations, in the order the QC writes them.
_REBUILT_ORDER = ("terms", "condition_number", "condition_number_scaled", "vif", "max_vif",
                  "n_segments_kept", "fit_residual_std_nT", "cv_residual_std_nT", "cv_ratio")
#: ... and of those a fit measured (from its report's ``fit`` block, with their ``source``).
_RECORDED_ORDER = ("source", "condition_number", "condition_number_scaled", "vif", "max_vif",
                   "cv_residual_std_nT", "cv_ratio", "fit_residual_std_nT", "n_segments_kept")


@dataclass
class FitDiagnostics:
    """Condition numbers, VIF and leave-one-segment-out CV of a fit (the QC's ``fit`` block).

    Two kinds, which write their keys in different orders (the order the files have always
    had): rebuilt from the normal equations (:func:`diagnostics_from_stats`: ``terms`` set,
    ``source`` None) or as the fit measured them (``source`` names where from, e.g. ``"the
    fit (model file)"``).  ``vif`` is a mapping with one entry per fitted term.

    Attributes
    ----------
    terms : list of str or None
        The fitted terms (rebuilt diagnostics).
    condition_number, condition_number_scaled : float or None
        Condition numbers of the normal equations, raw and with unit-norm columns [-].
    vif : dict of str to float or None
        Variance inflation factor per term [-].
    max_vif : float or None
        The largest VIF [-].
    n_segments_kept : int or None
        Segments the fit used.
    fit_residual_std_nT : float or None
        In-sample band-passed residual std of the kept segments [nT].
    cv_residual_std_nT : float or None
        Leave-one-segment-out residual std [nT].
    cv_ratio : float or None
        ``cv_residual_std_nT / fit_residual_std_nT`` [-].
    source : str or None
        Where recorded diagnostics come from (None: rebuilt here).
    extra : dict
        Keys this class does not know (written after the others).
    """

    terms: list[str] | None = None
    condition_number: float | None = None
    condition_number_scaled: float | None = None
    vif: dict[str, float] | None = None
    max_vif: float | None = None
    n_segments_kept: int | None = None
    fit_residual_std_nT: float | None = None
    cv_residual_std_nT: float | None = None
    cv_ratio: float | None = None
    source: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The JSON block, in its kind's order (the other kind's ``terms``/``source`` last).

        Returns
        -------
        dict
        """
        order = _RECORDED_ORDER if self.source is not None else _REBUILT_ORDER
        d = {k: getattr(self, k) for k in order}
        for k in ("terms", "source"):
            if k not in d and getattr(self, k) is not None:
                d[k] = getattr(self, k)
        d.update(self.extra)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> FitDiagnostics | None:
        """A block read from a file (None for none).

        Parameters
        ----------
        d : dict or None

        Returns
        -------
        FitDiagnostics or None
        """
        if not d:
            return None
        names = set(_REBUILT_ORDER) | {"source"}
        return cls(**{k: v for k, v in d.items() if k in names},
                   extra={k: v for k, v in d.items() if k not in names})


def variance_inflation(gram: np.ndarray) -> np.ndarray:
    """Variance inflation factors of the columns of a (zero-mean) design matrix.

    ``VIF_j = [R^-1]_jj`` with ``R`` the correlation matrix, here the Gram matrix scaled to
    unit diagonal (band-passed columns have zero mean).

    Parameters
    ----------
    gram : ndarray, shape (k, k)
        ``A.T @ A``.

    Returns
    -------
    ndarray, shape (k,)
        VIF per column (1 = orthogonal to the others; above 10 = strongly collinear).
    """
    d = np.sqrt(np.maximum(np.diag(gram), 1e-300))
    r = gram / d[:, None] / d[None, :]
    try:
        return np.diag(np.linalg.inv(r)).copy()
    except np.linalg.LinAlgError:
        return np.full(len(d), np.inf)


def loso_cv(stats: Any, kept: np.ndarray, ridge: float = 0.0) -> pd.DataFrame:
    """Leave-one-segment-out residuals from per-segment normal equations.

    For each kept segment ``j`` the model is refitted on the other kept segments,
    ``c_j = (G - G_j)^-1 (b - b_j)``, and its band-passed residual is
    ``sqrt((yy_j - 2 c_j.b_j + c_j.G_j.c_j) / n_j)``.  Dropped segments get the residual under
    the model fitted on all kept segments (they were left out anyway).

    Parameters
    ----------
    stats : SegmentStats-like
        Per-segment Gram matrices, right-hand sides, ``yy`` and sizes.
    kept : ndarray of bool, shape (m,)
        Segments used in the fit.
    ridge : float
        Relative ridge parameter of the fit.

    Returns
    -------
    DataFrame
        ``segment``, ``n``, ``kept``, ``fit_residual_std_nT`` (in-sample) and
        ``cv_residual_std_nT`` (out of sample).
    """
    G = stats.gram[kept].sum(axis=0)
    b = stats.rhs[kept].sum(axis=0)
    k = G.shape[0]

    def solve(g: np.ndarray, r: np.ndarray, pinv: bool = False) -> np.ndarray:
        d = np.sqrt(np.maximum(np.diagonal(g, axis1=-2, axis2=-1), 1e-300))
        gs = g / d[..., :, None] / d[..., None, :] + ridge * np.eye(k)
        rhs = (r / d)[..., None]
        if pinv:
            return (np.linalg.pinv(gs) @ rhs)[..., 0] / d
        return np.linalg.solve(gs, rhs)[..., 0] / d

    def solve_or_pinv(g: np.ndarray, r: np.ndarray) -> np.ndarray:
        try:
            return solve(g, r)
        except np.linalg.LinAlgError:
            return solve(g, r, pinv=True)

    c_all = solve_or_pinv(G, b)

    def loso(pinv: bool) -> np.ndarray:
        # The leave-one-out systems, a block of segments at a time: the (m, k, k) matrices
        # G - G_j and their scaled copies never exist whole (each is 16 MB at 8000
        # segments); every system is solved on its own, so the values are the same.
        out = np.empty(stats.rhs.shape)
        for a in range(0, len(kept), _LOSO_BLOCK):
            sl = slice(a, a + _LOSO_BLOCK)
            gi = np.where(kept[sl, None, None], G - stats.gram[sl], G)
            bi = np.where(kept[sl, None], b - stats.rhs[sl], b)
            out[sl] = solve(gi, bi, pinv)
        return out

    try:
        c_cv = loso(False)
    except np.linalg.LinAlgError:
        # As for the whole stack at once: one singular system sends all to the pseudo-inverse.
        c_cv = loso(True)

    def resid(c: np.ndarray) -> np.ndarray:
        c = np.broadcast_to(c, stats.rhs.shape)
        sse = stats.yy - 2 * np.einsum("mk,mk->m", c, stats.rhs) + np.einsum(
            "mk,mkj,mj->m", c, stats.gram, c)
        return np.sqrt(np.maximum(sse, 0.0) / stats.n)

    return pd.DataFrame({"segment": stats.ids.astype(int), "n": stats.n.astype(int),
                         "kept": kept, "fit_residual_std_nT": resid(c_all),
                         "cv_residual_std_nT": resid(c_cv)})


#: Segments per block of leave-one-out systems in :func:`loso_cv`.
_LOSO_BLOCK = 512


def diagnostics_from_stats(
    stats: Any, kept: np.ndarray, fit_terms: tuple[str, ...], ridge: float = 0.0,
) -> tuple[FitDiagnostics, pd.DataFrame]:
    """Condition numbers, VIF and leave-one-segment-out CV from per-segment normal equations.

    Parameters
    ----------
    stats : SegmentStats-like
        Per-segment band-passed normal equations.
    kept : ndarray of bool, shape (m,)
        Segments used in the fit.
    fit_terms : tuple of str
        Names of the fitted terms.
    ridge : float
        Relative ridge parameter of the fit.

    Returns
    -------
    diagnostics : FitDiagnostics
        ``terms``, ``condition_number``, ``condition_number_scaled``, ``vif`` (term -> VIF),
        ``max_vif``, ``n_segments_kept``, ``fit_residual_std_nT``, ``cv_residual_std_nT``
        [nT] and ``cv_ratio`` (CV / in-sample, None without an in-sample residual).
    segments : DataFrame
        Output of :func:`loso_cv`.
    """
    G = stats.gram[kept].sum(axis=0)
    ev = np.linalg.eigvalsh(G)
    d = np.sqrt(np.maximum(np.diag(G), 1e-300))
    evs = np.linalg.eigvalsh(G / d[:, None] / d[None, :])
    vif = variance_inflation(G)
    segs = loso_cv(stats, kept, ridge)
    nk = segs.loc[segs["kept"], "n"].to_numpy()

    def pooled(col: str) -> float:
        v = segs.loc[segs["kept"], col].to_numpy()
        return float(np.sqrt(np.sum(v**2 * nk) / max(nk.sum(), 1)))

    cv = pooled("cv_residual_std_nT")
    fit = pooled("fit_residual_std_nT")
    diag = FitDiagnostics(
        terms=list(fit_terms),
        condition_number=float(np.sqrt(ev[-1] / ev[0])) if ev[0] > 0 else float("inf"),
        condition_number_scaled=float(np.sqrt(evs[-1] / evs[0])) if evs[0] > 0
        else float("inf"),
        vif={t: float(v) for t, v in zip(fit_terms, vif, strict=True)},
        max_vif=float(np.max(vif)),
        n_segments_kept=int(kept.sum()),
        fit_residual_std_nT=fit,
        cv_residual_std_nT=cv,
        cv_ratio=cv / fit if fit > 0 else None,
    )
    return diag, segs
