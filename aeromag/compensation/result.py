"""What the compensation returns: :class:`CompensationResult`, and the fit's :class:`FitOutcome`."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .._core.fit_diagnostics import FitDiagnostics
from .._core.summary import summary_line, summary_table
from .config import CompensationConfig
from .model import TLModel
from .normal import SegmentStats
from .prepare import Prepared
from .report_types import CompensationMetrics, CompensationReport
from .screening import ScreeningOutcome, ScreenResult


@dataclass
class FitOutcome:
    """Everything the fit decided and measured (the report is built from it).

    Attributes
    ----------
    prep : Prepared
        The arrays the fit used.
    cfg : CompensationConfig
        Its options.
    terms, fit_terms : tuple of str
        All terms, and those fitted in the band (no ``bias``).
    coef : ndarray
        Coefficients of ``terms``.
    stats : SegmentStats
        Per-segment normal equations.
    screening : ScreeningOutcome
        What the screening loop kept.
    cond, cond_scaled : float
        Condition numbers of the final fit.
    diagnostics : FitDiagnostics
        VIF and leave-one-segment-out CV (:mod:`aeromag._core.fit_diagnostics`).
    cv_residual, residual, segment_condition : ndarray
        Per segment: CV residual, in-sample residual [nT], scaled condition number.
    sse : float
        Band-passed residual sum of squares of the kept segments [nT^2].
    decimation : int
        Factor by which the log was decimated for the fit (1 = none;
        :func:`aeromag.compensation.decimation.fit_arrays`); ``stats`` count decimated samples.
    """

    prep: Prepared
    cfg: CompensationConfig
    terms: tuple[str, ...]
    fit_terms: tuple[str, ...]
    coef: np.ndarray
    stats: SegmentStats
    screening: ScreeningOutcome
    cond: float
    cond_scaled: float
    diagnostics: FitDiagnostics
    cv_residual: np.ndarray
    residual: np.ndarray
    segment_condition: np.ndarray
    sse: float
    decimation: int = 1


@dataclass
class CompensationResult:
    """What the pipeline returns.

    Attributes
    ----------
    data : DataFrame
        The input log plus ``mag_tl``, ``mag_comp``, ``segment``, ``segment_kept``.
    model : TLModel
        The model applied (fitted here or loaded).
    report : CompensationReport
        The report (``report.to_dict()`` is the JSON of interface.md).
    screen : ScreenResult or None
        The last PCA screening (None when not screened).
    segment_table : DataFrame or None
        The report's ``segments`` as a table, one column per JSON key (fits only).
    fit : FitOutcome or None
        Everything the fit decided and measured (None when a saved model was applied).
    config : CompensationConfig or None
        The configuration the log was compensated with.
    comp_bp_nT : ndarray or None
        ``mag_comp`` band-passed in the fitting band, as the metrics used it (NaN on filter
        edges and gaps) [nT]: quality control reuses it instead of filtering again.
    segment : ndarray of int or None
        Segment id per sample (-1: none).
    fs_hz : float or None
        Sampling rate [Hz].
    """

    data: pd.DataFrame | None
    model: TLModel
    report: CompensationReport
    screen: ScreenResult | None = None
    segment_table: pd.DataFrame | None = field(default=None, repr=False)
    fit: FitOutcome | None = field(default=None, repr=False)
    config: CompensationConfig | None = None
    comp_bp_nT: np.ndarray | None = field(default=None, repr=False)
    segment: np.ndarray | None = field(default=None, repr=False)
    fs_hz: float | None = None

    def __post_init__(self) -> None:
        """A report given as the dict of a JSON file is read as one (:meth:`from_dict`)."""
        if isinstance(self.report, dict):
            self.report = CompensationReport.from_dict(self.report)

    def _summary(self) -> list[tuple[str, str]]:
        """(label, value) pairs of the short description (``repr`` and notebooks)."""
        rep = self.report
        segs = rep.segments
        kept = sum(1 for s in segs if s.kept)
        m = self.metrics
        rows = [("source", str(rep.source)),
                ("rows", "?" if self.data is None else str(len(self.data))),
                ("model", "fitted on this log" if self.fit is not None
                 else str(rep.model_source or "given")),
                ("terms", str(len(self.model.terms))),
                ("kept", f"{kept}/{len(segs)} segments")]
        for key in ("improvement_ratio", "residual_std_nT"):
            if m is not None and getattr(m, key) is not None:
                rows.append((key, f"{getattr(m, key):.4g}"))
        for w in rep.warnings or []:
            rows.append(("warning", str(w.get("message", w)) if isinstance(w, dict) else str(w)))
        return rows

    def __repr__(self) -> str:
        """One line: the summary's rows, warnings counted."""
        return summary_line(type(self).__name__, self._summary())

    def _repr_html_(self) -> str:
        """A small HTML table of the same summary (Jupyter)."""
        return summary_table(type(self).__name__, self._summary())

    @property
    def metrics(self) -> CompensationMetrics | None:
        """The report's headline metrics (None for a fit without data)."""
        return self.report.metrics
