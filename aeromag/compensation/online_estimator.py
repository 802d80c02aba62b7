"""The online Tolles-Lawson fit as a scikit-learn estimator with a real ``partial_fit``.

Kept apart from :mod:`aeromag.compensation.online` so that the command line never imports
scikit-learn.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin

from .._core.filters import sampling_rate
from ..errors import InputError
from .estimator import split_X
from .online import OnlineTL
from .terms import design_matrix

__all__ = ["OnlineTollesLawsonRegressor"]


class OnlineTollesLawsonRegressor(RegressorMixin, BaseEstimator):
    """Online Tolles-Lawson compensator (RLS with forgetting) with the scikit-learn API.

    ``X`` has four columns: time [s], flux_x, flux_y, flux_z [nT] (array or DataFrame with
    those columns); ``y`` is the scalar magnetometer [nT].  :meth:`partial_fit` continues
    the estimate with the next piece of a log (filter states, derivative context and the
    estimator carried over); :meth:`fit` starts afresh.  :meth:`predict` returns the modelled
    interference with the current coefficients.

    Parameters
    ----------
    terms : str or sequence of str
        Term set, default ``"16"``.
    forgetting : float
        lambda, 0 < lambda <= 1.
    band : tuple of float
        Causal band-pass [Hz].
    order : int
        Butterworth order.
    alpha : float
        Prior covariance scale [nT^2].
    fs_hz : float or None
        Sampling rate [Hz]; from the first batch's times when None.
    derivative : {"central", "midpoint", "backward"}
        See :class:`aeromag.compensation.online.OnlineTL`.

    Attributes
    ----------
    coef_ : ndarray
        Current coefficients [nT; eddy nT*s].
    terms_ : tuple of str
    n_samples_seen_ : int
    mag_tl_ : ndarray
        Interference of the samples of the last ``fit``/``partial_fit`` call (causal) [nT].
    mag_tl_std_ : ndarray
        Its predicted one-sigma uncertainty [nT] (:meth:`OnlineTL.run`).
    """

    def __init__(self, terms: str | Sequence[str] = "16", forgetting: float = 0.999,
                 band: tuple[float, float] = (0.1, 0.9), order: int = 4, alpha: float = 1e4,
                 fs_hz: float | None = None, derivative: str = "central") -> None:
        self.terms = terms
        self.forgetting = forgetting
        self.band = band
        self.order = order
        self.alpha = alpha
        self.fs_hz = fs_hz
        self.derivative = derivative

    _split_X = staticmethod(split_X)

    def partial_fit(self, X: Any, y: Any) -> OnlineTollesLawsonRegressor:
        """Continue the estimate with more samples (in time order).

        Parameters
        ----------
        X : array_like, shape (n, 4)
            time [s], flux_x, flux_y, flux_z [nT].
        y : array_like, shape (n,)
            Scalar magnetometer [nT].

        Returns
        -------
        self
        """
        t, flux = self._split_X(X)
        mag = np.asarray(y, dtype=np.float64).reshape(-1)
        if len(mag) != len(t):
            raise InputError(f"X has {len(t)} rows but y has {len(mag)}")
        if not hasattr(self, "_est"):
            fs = self.fs_hz if self.fs_hz is not None else sampling_rate(t)
            self._est = OnlineTL(fs, self.terms, forgetting=self.forgetting, band_hz=self.band,
                                 order=self.order, alpha=self.alpha,
                                 derivative=self.derivative)
            self.n_samples_seen_ = 0
        res = self._est.run(mag, np.column_stack([t, flux]))
        self.mag_tl_ = res.info["mag_tl"]
        self.mag_tl_std_ = res.info["mag_tl_std"]
        self.coef_ = res.info["coef"]
        self.terms_ = self._est.terms
        self.n_samples_seen_ += int((~res.info["skipped"]).sum())
        return self

    def fit(self, X: Any, y: Any) -> OnlineTollesLawsonRegressor:
        """Start afresh and run over the whole log (``X`` and ``y`` as in :meth:`partial_fit`).

        Returns
        -------
        self
        """
        if hasattr(self, "_est"):
            del self._est
        return self.partial_fit(X, y)

    def predict(self, X: Any) -> np.ndarray:
        """Modelled interference with the current coefficients [nT].

        Parameters
        ----------
        X : array_like, shape (n, 4)
            time [s], flux_x, flux_y, flux_z [nT].

        Returns
        -------
        ndarray, shape (n,)
        """
        if not hasattr(self, "coef_"):
            from sklearn.exceptions import NotFittedError

            raise NotFittedError(
                "OnlineTollesLawsonRegressor is not fitted yet: call fit or partial_fit")
        t, flux = self._split_X(X)
        return design_matrix(flux, t, self.terms_) @ self.coef_
