"""The compensation report as typed objects: :class:`CompensationReport` and its parts.

Its parts: :class:`~aeromag.compensation.metrics.CompensationMetrics` (the headline),
:class:`~aeromag.compensation.segments.SegmentRow` (one per segment), :class:`FitSummary`,
:class:`ScreeningSummary`, :class:`ResidualScreen`, the recorded options
(:class:`~aeromag.compensation.config_record.ConfigRecord`) and the smaller blocks of
:mod:`aeromag.compensation.report_blocks` (re-exported here).

The fit and the application of a saved model build these dataclasses
(:mod:`aeromag.compensation.report`); every layer above (quality control, plots, the command
line, the HTML report) reads their attributes.  JSON exists only where a file is written or
read: :meth:`CompensationReport.to_dict` gives the ``OUT.json`` / ``MODEL.json`` document
(interface.md keys, in the order the files have always had), :meth:`CompensationReport.from_dict`
reads one back.  Keys a reader does not know (another tool's, a later version's) are kept in
``extra`` and written back after the known ones.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from .config_record import ConfigRecord
from .metrics import CompensationMetrics, FlatBlock, split_fields
from .report_blocks import (
    CalibrationCheck,
    ChunkSettings,
    ExtendedSummary,
    HeadlineCheck,
    HeadlineDifference,
    HeldOut,
    MagCompCheck,
    Segmentation,
)
from .segments import SegmentRow

__all__ = ["CalibrationCheck", "ChunkSettings", "CompensationReport", "ConfigRecord",
           "ExtendedSummary", "FitSummary", "HeadlineCheck", "HeadlineDifference", "HeldOut",
           "MagCompCheck", "ResidualScreen", "ScreeningSummary", "Segmentation"]


_known = split_fields


@dataclass
class FitSummary(FlatBlock):
    """What the fit measured (the report's ``fit`` block).

    Attributes
    ----------
    n_samples : int
        Band-passed samples of the kept segments the final fit used (decimated).
    decimation_factor : int
        Factor the log was decimated by for the fit (1: none).
    n_segments_fitted : int
        Segments kept and fitted.
    condition_number, condition_number_scaled : float
        Condition numbers of the normal equations, raw and with unit-norm columns [-].
    ridge : float
        Ridge parameter of the fit [-].
    residual_std_nT : float
        In-sample band-passed residual std of the kept segments [nT].
    vif : dict
        Variance inflation factor per term [-].
    max_vif : float
        The largest VIF [-].
    cv_residual_std_nT : float
        Leave-one-segment-out cross-validated residual std [nT].
    cv_ratio : float
        ``cv_residual_std_nT / residual_std_nT`` [-].
    extra : dict
        Keys this class does not know (written after the others).
    """

    n_samples: int | None = None
    decimation_factor: int | None = None
    n_segments_fitted: int | None = None
    condition_number: float | None = None
    condition_number_scaled: float | None = None
    ridge: float | None = None
    residual_std_nT: float | None = None
    vif: Any = None
    max_vif: float | None = None
    cv_residual_std_nT: float | None = None
    cv_ratio: float | None = None
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass
class ScreeningSummary:
    """How the segments were screened (the report's ``screening`` block).

    Attributes
    ----------
    enabled : bool
        Whether the screening ran.
    notes : list of str
        What it noticed (and why it did not run).
    requested : bool or None
        Whether it was asked for (fits only; None when a saved model was applied).
    method, rule : str or None
        ``pca+mcd`` and the decision rule in words.
    pca_variance_threshold, quantile, shrink, min_excess, min_excess_nT : float or None
        Its settings (variance kept [-], chi-square quantile [-], shrinkage [-], smallest
        residual excess ratio [-] and excess [nT] that drop a segment).
    iterations : int or None
        Rounds until the kept set was stable.
    n_segments, n_kept : int or None
        Segments screened and kept.
    dropped, readmitted : list of int or None
        Ids dropped, and PCA outliers kept.
    explained_variance_ratio : list of float or None
        Per principal component [-] (PCA part: None when no PCA ran).
    n_components : int or None
        Components retained.
    cutoff : float or None
        Chi-square cut-off of the robust distance [-].
    location, covariance : list or None
        Robust (MCD) location and covariance of the retained scores.
    column_mean, column_scale, components : list or None
        Standardisation and basis of the PCA.
    extra : dict
        Keys this class does not know (written after the others).
    """

    enabled: bool = False
    notes: list[str] = field(default_factory=list)
    requested: bool | None = None
    method: str | None = None
    rule: str | None = None
    pca_variance_threshold: float | None = None
    quantile: float | None = None
    shrink: float | None = None
    min_excess: float | None = None
    min_excess_nT: float | None = None
    iterations: int | None = None
    n_segments: int | None = None
    n_kept: int | None = None
    dropped: list[int] | None = None
    readmitted: list[int] | None = None
    explained_variance_ratio: list[float] | None = None
    n_components: int | None = None
    cutoff: float | None = None
    location: list[float] | None = None
    covariance: list[list[float]] | None = None
    column_mean: list[float] | None = None
    column_scale: list[float] | None = None
    components: list[list[float]] | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    _FIT = ("requested", "method", "rule", "pca_variance_threshold", "quantile", "shrink",
            "min_excess", "min_excess_nT", "iterations", "n_segments", "n_kept", "dropped",
            "readmitted")
    _PCA = ("explained_variance_ratio", "n_components", "cutoff", "location", "covariance",
            "column_mean", "column_scale", "components")

    def to_dict(self) -> dict[str, Any]:
        """The JSON ``screening`` block (the fit's settings and the PCA part when they exist).

        Returns
        -------
        dict
        """
        d: dict[str, Any] = {"enabled": self.enabled}
        if self.requested is not None:
            d.update({k: getattr(self, k) for k in self._FIT})
        d["notes"] = list(self.notes)
        if self.explained_variance_ratio is not None:
            d.update({k: getattr(self, k) for k in self._PCA})
        d.update(self.extra)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> ScreeningSummary:
        """A ``screening`` block read from a file.

        Parameters
        ----------
        d : dict or None

        Returns
        -------
        ScreeningSummary
        """
        kw, extra = _known(cls, d or {})
        kw["enabled"] = bool(kw.get("enabled", False))
        kw["notes"] = list(kw.get("notes") or [])
        return cls(**kw, extra=extra)


@dataclass
class ResidualScreen:
    """The residual screen of an applied model (the report's ``residual_screen`` block).

    Attributes
    ----------
    rule : str
        The rule in words.
    median_nT, mad_nT, threshold_nT : float or None
        Median and scaled MAD of the segments' residuals, and the threshold [nT] (None when
        not screened).
    flagged : list of int
        Ids of the flagged segments.
    note : str or None
        Why it did not run.
    """

    rule: str
    median_nT: float | None = None
    mad_nT: float | None = None
    threshold_nT: float | None = None
    flagged: list[int] = field(default_factory=list)
    note: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """The JSON block.

        Returns
        -------
        dict
        """
        d: dict[str, Any] = {"rule": self.rule, "median_nT": self.median_nT,
                             "mad_nT": self.mad_nT, "threshold_nT": self.threshold_nT,
                             "flagged": list(self.flagged)}
        if self.note is not None:
            d["note"] = self.note
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> ResidualScreen | None:
        """The block read from a file (None for none).

        Parameters
        ----------
        d : dict or None

        Returns
        -------
        ResidualScreen or None
        """
        if not d:
            return None
        kw, _ = _known(cls, d)
        kw.setdefault("rule", "")
        return cls(**kw)


def _as_dict(v: Any) -> Any:
    return v.to_dict() if hasattr(v, "to_dict") else v


@dataclass
class CompensationReport:
    """The report of a compensation: what ``OUT.json`` and ``MODEL.json`` hold, typed.

    Attributes
    ----------
    source : str
        The log.
    aeromag_version, created : str
        Provenance (version, UTC ISO time of the report).
    terms : list of str
        Model terms.
    coef : list of float
        Their coefficients [nT; eddy terms nT·s].
    scale_nT : float
        Field scale of the induced and eddy terms [nT].
    band_hz : list of float
        Fitting band [Hz].
    sampling_rate_hz : float or None
        Sampling rate [Hz].
    segments : list of SegmentRow
        One row per segment.
    screening : ScreeningSummary
        How segments were screened.
    config : ConfigRecord or None
        The options recorded (:meth:`ConfigRecord.from_config`).
    model_source : str or None
        ``fitted``, or the saved model's path (``given`` without one).
    filter_order : int or None
        Butterworth order (fits).
    mag_from_fluxgate : bool or None
        Whether the total field was the fluxgate's magnitude (fits).
    fit : FitSummary or None
        What the fit measured (None when a saved model was applied).
    metrics : CompensationMetrics or None
        Headline metrics (None for a fit without data).
    extended : ExtendedSummary or None
        The extended model's block (:meth:`ExtendedModel.summary`).
    segmentation : Segmentation or None
        How a calibration log without lines was segmented.
    qc : object or None
        The quality-control block (:attr:`aeromag.qc.QCResult.metrics`; as read, a dict, from
        a file: quality control builds on this package, not the other way).
    calibration_box, self_calibration : CalibrationCheck or None
        Whether the log holds a calibration box (calibrate; a log fitted on itself).
    n_rows : int or None
        Rows of a chunked run.
    chunked : ChunkSettings or None
        Chunk settings of a chunked run.
    residual_screen : ResidualScreen or None
        The applied model's residual screen.
    warnings : list or None
        What the run warned (filled when the report is written).
    recorded_metrics : CompensationMetrics or None
        The metrics a report file recorded, when ``aeromag report`` recomputed them
        (:func:`aeromag.workflows.report_check.headline_from_data`).
    headline_check : HeadlineCheck or None
        That comparison.
    extra : dict
        Keys of a report file this class does not know (written after the others).
    """

    source: str = "<log>"
    aeromag_version: str | None = None
    created: str | None = None
    terms: list[str] = field(default_factory=list)
    coef: list[float] = field(default_factory=list)
    scale_nT: float | None = None
    band_hz: list[float] | None = None
    sampling_rate_hz: float | None = None
    segments: list[SegmentRow] = field(default_factory=list)
    screening: ScreeningSummary = field(default_factory=ScreeningSummary)
    config: ConfigRecord | None = None
    model_source: str | None = None
    filter_order: int | None = None
    mag_from_fluxgate: bool | None = None
    fit: FitSummary | None = None
    metrics: CompensationMetrics | None = None
    extended: ExtendedSummary | None = None
    segmentation: Segmentation | None = None
    qc: Any = None
    calibration_box: CalibrationCheck | None = None
    self_calibration: CalibrationCheck | None = None
    n_rows: int | None = None
    chunked: ChunkSettings | None = None
    residual_screen: ResidualScreen | None = None
    warnings: list[Any] | None = None
    recorded_metrics: CompensationMetrics | None = field(default=None, repr=False)
    headline_check: HeadlineCheck | None = field(default=None, repr=False)
    extra: dict[str, Any] = field(default_factory=dict)

    def kept_ids(self) -> list[int]:
        """Ids of the kept segments.

        Returns
        -------
        list of int
        """
        return [s.id for s in self.segments if s.kept]

    def segment(self, sid: int) -> SegmentRow | None:
        """The row of segment ``sid`` (None when the report has none).

        Parameters
        ----------
        sid : int
            Segment id.

        Returns
        -------
        SegmentRow or None
        """
        for s in self.segments:
            if s.id == sid:
                return s
        return None

    def to_dict(self) -> dict[str, Any]:
        """The JSON document (``OUT.json``, ``MODEL.json``), keys in the files' order.

        A fit writes its model, ``fit``, ``segments``, ``screening`` and ``config`` before the
        metrics; an applied model writes ``model_source`` after ``scale_nT`` and the metrics
        before ``config`` (the order the reports have always had).

        Returns
        -------
        dict
        """
        fitted = self.fit is not None or self.filter_order is not None
        d: dict[str, Any] = {}

        def put(key: str, value: Any) -> None:
            if value is not None:
                d[key] = _as_dict(value)

        put("aeromag_version", self.aeromag_version)
        put("created", self.created)
        d["source"] = self.source
        d["terms"] = list(self.terms)
        d["coef"] = list(self.coef)
        put("scale_nT", self.scale_nT)
        if not fitted:
            put("model_source", self.model_source)
        put("band_hz", None if self.band_hz is None else list(self.band_hz))
        put("filter_order", self.filter_order)
        put("sampling_rate_hz", self.sampling_rate_hz)
        put("mag_from_fluxgate", self.mag_from_fluxgate)
        put("fit", self.fit)
        d["segments"] = [s.to_dict() for s in self.segments]
        d["screening"] = self.screening.to_dict()
        if not fitted:
            put("metrics", self.metrics)
        put("config", self.config)
        put("extended", self.extended)
        if fitted:
            put("metrics", self.metrics)
            put("model_source", self.model_source)
        for key in ("segmentation", "qc", "calibration_box", "self_calibration", "n_rows",
                    "chunked", "residual_screen", "warnings", "recorded_metrics",
                    "headline_check"):
            put(key, getattr(self, key))
        d.update(self.extra)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> CompensationReport:
        """A report read from a JSON file (``OUT.json``, ``MODEL.json``, another run's).

        Parameters
        ----------
        d : dict
            The document; keys this class does not know go to ``extra``.

        Returns
        -------
        CompensationReport
        """
        kw, extra = _known(cls, d)
        kw["source"] = str(kw.get("source", "<log>"))
        kw["terms"] = list(kw.get("terms") or [])
        kw["coef"] = list(kw.get("coef") or [])
        kw["segments"] = [SegmentRow.from_dict(s) for s in kw.get("segments") or []
                          if isinstance(s, dict)]
        kw["screening"] = ScreeningSummary.from_dict(kw.get("screening"))
        kw["fit"] = FitSummary.from_dict(kw.get("fit"))
        kw["metrics"] = CompensationMetrics.from_dict(kw.get("metrics"))
        kw["recorded_metrics"] = CompensationMetrics.from_dict(kw.get("recorded_metrics"))
        kw["residual_screen"] = ResidualScreen.from_dict(kw.get("residual_screen"))
        kw["config"] = ConfigRecord.from_dict(kw.get("config"))
        kw["extended"] = ExtendedSummary.from_dict(kw.get("extended"))
        kw["segmentation"] = Segmentation.from_dict(kw.get("segmentation"))
        kw["calibration_box"] = CalibrationCheck.from_dict(kw.get("calibration_box"))
        kw["self_calibration"] = CalibrationCheck.from_dict(kw.get("self_calibration"))
        kw["chunked"] = ChunkSettings.from_dict(kw.get("chunked"))
        kw["headline_check"] = HeadlineCheck.from_dict(kw.get("headline_check"))
        return cls(**kw, extra=extra)
