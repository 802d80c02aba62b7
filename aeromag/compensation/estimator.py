"""The Tolles-Lawson compensator as a scikit-learn estimator (``fit`` / ``predict`` /
``get_params``), so it can sit in a ``Pipeline``.

Kept apart from :mod:`aeromag.compensation.model` so that applying a saved model never imports
scikit-learn.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin

from .._core.lstsq import solve_normal
from ..errors import InputError
from .model import TLModel
from .terms import design_matrix, parse_terms

__all__ = ["TollesLawson"]


class TollesLawson(RegressorMixin, BaseEstimator):
    """Tolles-Lawson compensator with the scikit-learn estimator API.

    ``X`` has four columns: time [s], flux_x, flux_y, flux_z [nT] (an array or a DataFrame with
    columns ``time, flux_x, flux_y, flux_z``); ``y`` is the scalar magnetometer [nT].
    :meth:`predict` returns the modelled aircraft interference (``mag_tl``) [nT], so
    ``y - predict(X)`` is the compensated field.

    Parameters
    ----------
    terms : str or sequence of str
        Term set (see :func:`parse_terms`), default ``"16"``.
    band : tuple of float
        Band-pass edges applied to the target and every term before least squares [Hz].
    ridge : float
        Relative ridge parameter (0 = plain least squares).
    order : int
        Butterworth filter order.
    max_gap_s : float or None
        A time step longer than this starts a new stretch [s]; default 5 sample intervals.

    Attributes
    ----------
    coef_ : ndarray
        Coefficients [nT; eddy nT*s].
    terms_ : tuple of str
        Term names.
    condition_number_ : float
        Condition number of the band-passed design matrix (unit-norm columns).
    n_samples_fit_ : int
        Samples used in the fit (after edge trimming).
    model_ : TLModel
        The fitted model.
    """

    def __init__(
        self,
        terms: str | Sequence[str] = "16",
        band: tuple[float, float] = (0.1, 0.9),
        ridge: float = 0.0,
        order: int = 4,
        max_gap_s: float | None = None,
    ) -> None:
        self.terms = terms
        self.band = band
        self.ridge = ridge
        self.order = order
        self.max_gap_s = max_gap_s

    @staticmethod
    def _split_X(X: Any) -> tuple[np.ndarray, np.ndarray]:
        if hasattr(X, "columns") and {"time", "flux_x", "flux_y", "flux_z"} <= set(X.columns):
            arr = X[["time", "flux_x", "flux_y", "flux_z"]].to_numpy(dtype=np.float64)
        else:
            arr = np.asarray(X, dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] != 4:
            raise InputError("X must have 4 columns: time [s], flux_x, flux_y, flux_z [nT]")
        return arr[:, 0], arr[:, 1:4]

    def fit(self, X: Any, y: Any) -> TollesLawson:
        """Fit the coefficients by band-passed least squares; returns ``self``."""
        from .._core.filters import bandpass_pieces
        from .._core.stretches import find_stretches

        t, flux = self._split_X(X)
        yv = np.asarray(y, dtype=np.float64).ravel()
        if len(yv) != len(t):
            raise InputError(f"X has {len(t)} rows but y has {len(yv)}")
        terms = parse_terms(self.terms)
        fit_terms = tuple(x for x in terms if x != "bias")
        stretch = find_stretches(t, np.isfinite(yv) & np.all(np.isfinite(flux), axis=1),
                                 self.max_gap_s)
        ok = stretch >= 0
        A = design_matrix(flux[ok], t[ok], fit_terms, stretch=stretch[ok])
        gram, rhs, _, n = bandpass_pieces(A, yv[ok], t[ok], stretch[ok], self.band, self.order)
        coef, _cond, cond_s = solve_normal(gram, rhs, self.ridge)
        full = np.zeros(len(terms))
        idx = [terms.index(x) for x in fit_terms]
        full[idx] = coef
        if "bias" in terms:
            resid = yv[ok] - A @ coef
            full[terms.index("bias")] = float(np.mean(resid))
        self.terms_ = terms
        self.coef_ = full
        self.condition_number_ = cond_s
        self.n_samples_fit_ = int(n)
        self.model_ = TLModel(terms, full)
        return self

    def predict(self, X: Any) -> np.ndarray:
        """Modelled aircraft interference ``mag_tl`` [nT] for each row of ``X``."""
        from .._core.stretches import find_stretches

        if not hasattr(self, "model_"):
            from sklearn.exceptions import NotFittedError

            raise NotFittedError("call fit() first")
        t, flux = self._split_X(X)
        stretch = find_stretches(t, np.all(np.isfinite(flux), axis=1), self.max_gap_s)
        return self.model_.predict(flux, t, stretch)

    def score(self, X: Any, y: Any, sample_weight: Any = None) -> float:
        """Improvement ratio: std of band-passed ``y`` over std of band-passed ``y - predict``."""
        from .._core.filters import bandpass_stretches
        from .._core.stretches import find_stretches

        t, _ = self._split_X(X)
        yv = np.asarray(y, dtype=np.float64).ravel()
        stretch = find_stretches(t, np.isfinite(yv), self.max_gap_s)
        before = bandpass_stretches(yv, t, stretch, self.band, self.order)
        after = bandpass_stretches(yv - self.predict(X), t, stretch, self.band, self.order)
        return float(np.nanstd(before) / np.nanstd(after))
