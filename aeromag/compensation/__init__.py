"""Tolles-Lawson compensation: configuration, terms, model, segments, screening, fit, apply.

Modules, in pipeline order: ``config`` (:class:`CompensationConfig` and its option groups),
``terms`` (term sets and the design matrix), ``model`` (:class:`TLModel`), ``segments``,
``prepare`` (arrays of a log), ``normal`` (per-segment normal equations), ``screening`` (the
whole PCA screening loop), ``fit`` (the one fit kernel, shared with the scikit-learn
estimator), ``apply``, ``metrics``, ``report`` (the builders) and ``report_types``
(:class:`CompensationReport`, whose ``to_dict`` is the JSON), ``result``, ``pipeline``
(:func:`run_compensation`, :func:`calibrate`), ``estimator`` (:class:`TollesLawsonRegressor`,
imported on first use: applying a model never imports scikit-learn).
"""

from __future__ import annotations

from typing import Any

from .apply import apply_model
from .config import CompensationConfig
from .fit import fit_model
from .metrics import CompensationMetrics, compensation_metrics
from .model import TLModel, predict_interference
from .pipeline import run_compensation
from .prepare import Prepared, prepare
from .report_types import CompensationReport, FitSummary, ScreeningSummary
from .result import CompensationResult
from .screening import ScreenResult, pca_screen
from .segments import SegmentRow, assign_segments, segment_counts
from .terms import TERMS_16, design_matrix, direction_cosines, parse_terms

__all__ = [
    "TERMS_16",
    "CompensationConfig",
    "CompensationMetrics",
    "CompensationReport",
    "CompensationResult",
    "FitSummary",
    "Prepared",
    "ScreenResult",
    "ScreeningSummary",
    "SegmentRow",
    "TLModel",
    "TollesLawsonRegressor",
    "apply_model",
    "assign_segments",
    "run_compensation",
    "compensation_metrics",
    "design_matrix",
    "direction_cosines",
    "fit_model",
    "parse_terms",
    "pca_screen",
    "predict_interference",
    "prepare",
    "segment_counts",
]


def __getattr__(name: str) -> Any:
    if name == "TollesLawsonRegressor":  # scikit-learn only when the estimator is used
        from .estimator import TollesLawsonRegressor

        return TollesLawsonRegressor
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
