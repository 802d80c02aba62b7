"""The Tolles-Lawson compensator as a scikit-learn estimator, so it can sit in a ``Pipeline``.

``fit``, ``predict``, ``transform``, ``score``, ``get_params``:
:meth:`TollesLawsonRegressor.fit` runs the pipeline's own fit
(:func:`aeromag.compensation.fit.fit_outcome`, one segment per stretch, no screening), so it
refuses what ``aeromag calibrate`` refuses: a scaled condition number above
``max_condition`` and an interference above ``max_interference`` of the Earth field.  Kept
apart from :mod:`aeromag.compensation.model` so that applying a saved model never imports
scikit-learn.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd
from sklearn.base import BaseEstimator, RegressorMixin

from .._core.stretches import find_stretches
from ..conventions import FLUX_COLUMNS
from ..errors import InputError
from .config import CompensationConfig, resolve_gap
from .fit import check_interference, fit_outcome
from .metrics import compensation_metrics
from .model import TLModel
from .prepare import prepare

__all__ = ["TollesLawsonRegressor"]

#: Segment length that makes every stretch one segment [s].
_WHOLE_STRETCH_S = 1e12


def split_X(X: Any) -> tuple[np.ndarray, np.ndarray]:
    """Time [s] and fluxgate [nT] of an estimator's ``X``.

    Parameters
    ----------
    X : DataFrame or array-like, shape (n, 4)
        Columns ``time, flux_x, flux_y, flux_z`` (a DataFrame may hold more; those are used).

    Returns
    -------
    t : ndarray, shape (n,)
    flux : ndarray, shape (n, 3)
    """
    arr = np.asarray(_four_columns(X), dtype=np.float64)
    _check_four(arr)
    return arr[:, 0], arr[:, 1:4]


def _four_columns(X: Any) -> Any:
    """``X`` itself, or a DataFrame's ``time, flux_x, flux_y, flux_z`` columns."""
    if hasattr(X, "columns") and {"time", *FLUX_COLUMNS} <= set(X.columns):
        return X[["time", *FLUX_COLUMNS]]
    return X


def _check_four(arr: np.ndarray) -> None:
    if arr.ndim != 2 or arr.shape[1] != 4:
        n = arr.shape[1] if arr.ndim == 2 else 0
        raise InputError("X must have 4 columns: time [s], flux_x, flux_y, flux_z [nT]; got"
                         f" {n} feature(s), shape {arr.shape}")


class TollesLawsonRegressor(RegressorMixin, BaseEstimator):
    """Tolles-Lawson compensator with the scikit-learn estimator API.

    ``X`` has four columns: time [s], flux_x, flux_y, flux_z [nT] (an array or a DataFrame with
    columns ``time, flux_x, flux_y, flux_z``); ``y`` is the scalar magnetometer [nT].
    :meth:`predict` returns the modelled aircraft interference (``mag_tl``) [nT] and
    :meth:`transform` the compensated field ``y - predict(X)`` [nT].

    Parameters
    ----------
    terms : str or sequence of str
        Term set (see :func:`aeromag.compensation.terms.parse_terms`), default ``"16"``.
    band : tuple of float
        Band-pass edges applied to the target and every term before least squares [Hz].
    ridge : float
        Relative ridge parameter (0 = plain least squares).
    order : int
        Butterworth filter order.
    max_gap_s : float or None
        A time step longer than this starts a new stretch [s]; default 5 sample intervals.
    max_condition : float
        Largest scaled condition number of an unregularised fit (as ``--max-condition``).
    max_interference : float
        Largest plausible ``|mag_tl|`` (99th percentile) as a fraction of the Earth field
        (as ``--max-interference``).

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
        max_condition: float = 1e5,
        max_interference: float = 0.25,
    ) -> None:
        self.terms = terms
        self.band = band
        self.ridge = ridge
        self.order = order
        self.max_gap_s = max_gap_s
        self.max_condition = max_condition
        self.max_interference = max_interference

    _split_X = staticmethod(split_X)

    def __sklearn_tags__(self) -> Any:
        """scikit-learn (>= 1.6) tags: a regressor that is also a transformer.

        ``transform`` gives ``y - predict(X)``, so it needs ``y``; ``X`` is float64, four
        columns.
        """
        from sklearn.utils import TransformerTags

        tags = super().__sklearn_tags__()
        tags.transformer_tags = TransformerTags(preserves_dtype=["float64"])
        tags.target_tags.required = True
        tags.input_tags.allow_nan = False
        return tags

    def _config(self) -> CompensationConfig:
        terms = self.terms if isinstance(self.terms, str) else ",".join(self.terms)
        return CompensationConfig(band_hz=self.band, terms=terms, ridge=self.ridge,
                                  order=self.order, max_gap_s=self.max_gap_s, screen=False,
                                  segment_seconds=_WHOLE_STRETCH_S,
                                  max_condition=self.max_condition,
                                  max_interference=self.max_interference)

    def fit(self, X: Any, y: Any) -> TollesLawsonRegressor:
        """Fit the coefficients by band-passed least squares (the pipeline's fit).

        Parameters
        ----------
        X : array-like, shape (n, 4)
            time [s], flux_x, flux_y, flux_z [nT].
        y : array-like, shape (n,)
            Scalar magnetometer [nT].

        Returns
        -------
        TollesLawsonRegressor
            ``self``.

        Raises
        ------
        FitError
            Ill-conditioned, or an interference no aircraft makes (as ``aeromag calibrate``).
        """
        from sklearn.utils.validation import validate_data

        # scikit-learn's own checks first (finite numbers, no sparse or complex data, y given
        # and 1-D, at least 2 samples; n_features_in_ and feature_names_in_ recorded).
        arr, yv = validate_data(self, _four_columns(X), y, dtype=np.float64, y_numeric=True,
                                ensure_min_samples=2)
        _check_four(arr)
        t, flux = arr[:, 0], arr[:, 1:4]
        df = pd.DataFrame({"time": t, "flux_x": flux[:, 0], "flux_y": flux[:, 1],
                           "flux_z": flux[:, 2], "mag": yv})
        cfg = resolve_gap(self._config(), df)
        prep = prepare(df, cfg, source="TollesLawsonRegressor.fit")
        fit = fit_outcome(prep, cfg)
        model = TLModel(fit.terms, fit.coef)
        ok = prep.flux_ok
        tl = model.predict(prep.flux[ok], prep.time[ok],
                           find_stretches(prep.time[ok], None, cfg.max_gap_s))
        check_interference(tl, prep.field_nT, self.max_interference,
                           source="TollesLawsonRegressor.fit", fitted=True)
        self.terms_ = fit.terms
        self.coef_ = fit.coef
        self.condition_number_ = fit.cond_scaled
        self.n_samples_fit_ = int(fit.stats.n[fit.screening.kept].sum())
        self.model_ = model
        return self

    def predict(self, X: Any) -> np.ndarray:
        """Modelled aircraft interference ``mag_tl`` [nT] for each row of ``X``."""
        if not hasattr(self, "model_"):
            from sklearn.exceptions import NotFittedError

            raise NotFittedError("call fit() first")
        t, flux = self._split_X(X)
        stretch = find_stretches(t, np.all(np.isfinite(flux), axis=1), self.max_gap_s)
        return self.model_.predict(flux, t, stretch)

    def transform(self, X: Any, y: Any = None) -> np.ndarray:
        """The compensated total field ``mag - mag_tl`` [nT] (unfiltered).

        Parameters
        ----------
        X : array-like or DataFrame
            As for :meth:`predict`; a DataFrame may carry the scalar as its ``mag`` column.
        y : array-like, shape (n,), optional
            Scalar magnetometer [nT] (default: ``X["mag"]``).

        Returns
        -------
        ndarray, shape (n,)
            Compensated field [nT].
        """
        if y is None:
            if not (hasattr(X, "columns") and "mag" in X.columns):
                raise InputError("transform needs the scalar magnetometer: pass y or a 'mag'"
                                 " column in X")
            y = X["mag"]
        return np.asarray(y, dtype=np.float64).ravel() - self.predict(X)

    def fit_transform(self, X: Any, y: Any) -> np.ndarray:
        """:meth:`fit`, then :meth:`transform` of the same data (``y - mag_tl``) [nT]."""
        return self.fit(X, y).transform(X, y)

    def score(self, X: Any, y: Any, sample_weight: Any = None) -> float:
        """Improvement ratio, as the pipeline's metrics compute it.

        Std of band-passed ``y`` over std of band-passed ``y - predict(X)``, in the fitting band
        applied once, filter edges trimmed
        (:func:`aeromag.compensation.metrics.compensation_metrics`).

        Parameters
        ----------
        X : array-like, shape (n, 4)
            time [s], flux_x, flux_y, flux_z [nT].
        y : array-like, shape (n,)
            Scalar magnetometer [nT].
        sample_weight : None
            Not supported (scikit-learn's signature).

        Returns
        -------
        float
            Improvement ratio (higher is better).
        """
        t, _ = self._split_X(X)
        yv = np.asarray(y, dtype=np.float64).ravel()
        cfg = self._config()
        stretch = find_stretches(t, np.isfinite(yv), cfg.max_gap_s)
        return float(compensation_metrics(yv, yv - self.predict(X), t, stretch,
                                          cfg).improvement_ratio)
