"""The compensation report as typed objects: :class:`CompensationReport` and its parts.

Its parts: :class:`~aeromag.compensation.metrics.CompensationMetrics` (the headline),
:class:`~aeromag.compensation.segments.SegmentRow` (one per segment), :class:`FitSummary`,
:class:`ScreeningSummary`, :class:`ResidualScreen`.

The fit and the application of a saved model build these dataclasses
(:mod:`aeromag.compensation.report`); every layer above (quality control, plots, the command
line, the HTML report) reads their attributes.  JSON exists only where a file is written or
read: :meth:`CompensationReport.to_dict` gives the ``OUT.json`` / ``MODEL.json`` document
(interface.md keys, in the order the files have always had), :meth:`CompensationReport.from_dict`
reads one back.  Keys a reader does not know (another tool's, a later version's) are kept in
``extra`` and written back after the known ones.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

from .config import ConfigRecord
from .metrics import CompensationMetrics, block_dict, block_from_dict, split_fields
from .segments import SegmentRow

__all__ = ["CalibrationCheck", "ChunkSettings", "CompensationReport", "ExtendedSummary",
           "FitSummary", "HeadlineCheck", "HeldOut", "MagCompCheck", "ResidualScreen",
           "ScreeningSummary", "Segmentation"]


_known = split_fields


def _set_dict(obj: Any, always: frozenset[str] = frozenset()) -> dict[str, Any]:
    """A JSON block from a dataclass: its fields but the None ones (bar ``always``), ``extra``.

    A field in ``always`` or in the object's ``nulls`` is written as ``null`` when None.
    """
    keep = always | getattr(obj, "nulls", frozenset())
    d: dict[str, Any] = {}
    for f in dataclasses.fields(obj):
        if f.name in ("extra", "nulls"):
            continue
        v = getattr(obj, f.name)
        if v is not None or f.name in keep:
            d[f.name] = v.to_dict() if hasattr(v, "to_dict") else v
    d.update(obj.extra)
    return d


def _set_from_dict(cls: type, d: dict[str, Any], always: frozenset[str] = frozenset(),
                   **convert: Any) -> Any:
    """:func:`_set_dict` read back; ``convert`` maps a field to the function that reads it."""
    kw, extra = _known(cls, d)
    for name, read in convert.items():
        if kw.get(name) is not None:
            kw[name] = read(kw[name])
    if any(f.name == "nulls" for f in dataclasses.fields(cls)):
        kw["nulls"] = frozenset(k for k, v in kw.items() if v is None) - always
    return cls(**kw, extra=extra)


@dataclass
class Segmentation:
    """How a calibration log without a ``line`` column was segmented (``segmentation``).

    Attributes
    ----------
    method : str
        ``detected maneuvers``, ``detected heading legs`` or ``time windows``.
    detector : str or None
        The detector's method (:func:`aeromag.qc.detect_maneuvers`), when one found them.
    n_segments : int or None
        Segments it found.
    segment_seconds : float or None
        Window length of the time windows [s].
    reason : str or None
        Why time windows were used.
    extra : dict
        Keys this class does not know (written after the others).
    """

    method: str = ""
    detector: str | None = None
    n_segments: int | None = None
    segment_seconds: float | None = None
    reason: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The JSON block (the keys that are set).

        Returns
        -------
        dict
        """
        return _set_dict(self, frozenset({"method"}))

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> Segmentation | None:
        """The block read from a file (None for none).

        Parameters
        ----------
        d : dict or None

        Returns
        -------
        Segmentation or None
        """
        return None if d is None else _set_from_dict(cls, d)


@dataclass
class CalibrationCheck:
    """Whether a log holds a calibration box (``calibration_box``, ``self_calibration``).

    ``calibrate`` records it as ``calibration_box``; a log fitted on itself
    (``compensate`` without a model) as ``self_calibration``, with ``metrics`` saying that
    its figures are in-sample.

    Attributes
    ----------
    calibration_box : bool
        At least four heading legs with pitch, roll and yaw maneuvers.
    headings : list of str
        Heading legs found (``N``, ``E``...).
    maneuvers : list of str
        Maneuver kinds found.
    metrics : str or None
        What the metrics of a log fitted on itself mean (``self_calibration`` only).
    extra : dict
        Keys this class does not know (written after the others).
    """

    calibration_box: bool = False
    headings: list[str] = field(default_factory=list)
    maneuvers: list[str] = field(default_factory=list)
    metrics: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The JSON block (``metrics`` first when set).

        Returns
        -------
        dict
        """
        d: dict[str, Any] = {} if self.metrics is None else {"metrics": self.metrics}
        d.update(calibration_box=self.calibration_box, headings=list(self.headings),
                 maneuvers=list(self.maneuvers))
        d.update(self.extra)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> CalibrationCheck | None:
        """The block read from a file (None for none).

        Parameters
        ----------
        d : dict or None

        Returns
        -------
        CalibrationCheck or None
        """
        if d is None:
            return None
        kw, extra = _known(cls, d)
        kw["calibration_box"] = bool(kw.get("calibration_box", False))
        kw["headings"] = list(kw.get("headings") or [])
        kw["maneuvers"] = list(kw.get("maneuvers") or [])
        return cls(**kw, extra=extra)

@dataclass
class ChunkSettings:
    """The chunks of a chunked run (``chunked``).

    Attributes
    ----------
    chunk_rows : int
        Rows written per chunk.
    overlap_rows : int
        Rows of context read on each side of a chunk.
    extra : dict
        Keys this class does not know (written after the others).
    """

    chunk_rows: int = 0
    overlap_rows: int = 0
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The JSON block.

        Returns
        -------
        dict
        """
        return block_dict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> ChunkSettings | None:
        """The block read from a file (None for none).

        Parameters
        ----------
        d : dict or None

        Returns
        -------
        ChunkSettings or None
        """
        return block_from_dict(cls, d)


@dataclass
class HeldOut:
    """The extended fit's held-out errors (``extended.held_out``).

    Attributes
    ----------
    method : str
        How they were measured, in words.
    residual_std_nT : float
        Held-out residual std of the fit with every regressor [nT].
    tl_only_residual_std_nT : float
        The same with the TL terms only [nT].
    tl_only_param : float
        The regularisation of the TL-only fit.
    contributions : list of dict
        Per extra: ``name``, ``held_out_std_without_nT``, ``increase_nT`` [nT],
        ``increase_pct`` [%].
    extra : dict
        Keys this class does not know (written after the others).
    """

    method: str | None = None
    residual_std_nT: float | None = None
    tl_only_residual_std_nT: float | None = None
    tl_only_param: float | None = None
    contributions: list[dict[str, Any]] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The JSON block.

        Returns
        -------
        dict
        """
        return block_dict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> HeldOut | None:
        """The block read from a file (None for none).

        Parameters
        ----------
        d : dict or None

        Returns
        -------
        HeldOut or None
        """
        return block_from_dict(cls, d)


#: Keys of the extended block that describe the saved model (the others are the fit's record).
_EXTENDED_MODEL_KEYS = ("reference", "estimator", "param", "intercept_nT", "extras", "mlp")


@dataclass
class ExtendedSummary:
    """The extended fit's block (``extended``; :meth:`ExtendedModel.summary`).

    Attributes
    ----------
    reference : str or None
        Reference column the model was fitted against (None: band-passed self-fit).
    rows_left_out : int or None
        Rows without a value in an extra or the reference.
    dropped_extras : list of str or None
        Extras dropped (constant or empty).
    mlp_training : dict or None
        How the network was trained and judged (``kept``, ``linear_std_nT``,
        ``mlp_std_nT`` [nT], ``epochs``, ``split``, ``hidden``, ``seed``).
    held_out : HeldOut or None
        Held-out errors.
    n_fit_samples : int or None
        Samples of the fit.
    estimator : str or None
        ``ridge``, ``pls`` or ``mlp``.
    param : float or None
        The regularisation chosen (relative ridge, or PLS components).
    intercept_nT : float or None
        Constant of the model [nT].
    extras : list of dict
        Per extra: ``name``, ``coef_nT_per_unit`` [nT per unit], ``center``, ``scale``
        (units of the column).
    mlp : dict or None
        The network's weights, when kept.
    fitted : bool
        The block of a fit (``reference`` written first); False for a saved model's block,
        which writes the fit's record before the model's keys.
    extra : dict
        Keys this class does not know (written with the fit's record).
    """

    reference: str | None = None
    rows_left_out: int | None = None
    dropped_extras: list[str] | None = None
    mlp_training: dict[str, Any] | None = None
    held_out: HeldOut | None = None
    n_fit_samples: int | None = None
    estimator: str | None = None
    param: float | None = None
    intercept_nT: float | None = None
    extras: list[dict[str, Any]] = field(default_factory=list)
    mlp: dict[str, Any] | None = None
    fitted: bool = True
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The JSON block, in the order of its origin (a fit's, or a saved model's).

        Returns
        -------
        dict
        """
        d: dict[str, Any] = {"reference": self.reference} if self.fitted else {}
        for key in ("rows_left_out", "dropped_extras", "mlp_training", "held_out",
                    "n_fit_samples"):
            v = getattr(self, key)
            if v is not None:
                d[key] = v.to_dict() if hasattr(v, "to_dict") else v
        d.update(self.extra)
        d.update(reference=self.reference, estimator=self.estimator, param=self.param,
                 intercept_nT=self.intercept_nT, extras=list(self.extras), mlp=self.mlp)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> ExtendedSummary | None:
        """The block read from a file (None for none).

        Parameters
        ----------
        d : dict or None

        Returns
        -------
        ExtendedSummary or None
        """
        if d is None:
            return None
        kw, extra = _known(cls, d)
        kw.pop("fitted", None)
        kw["held_out"] = HeldOut.from_dict(kw.get("held_out"))
        kw["extras"] = list(kw.get("extras") or [])
        return cls(**kw, fitted=next(iter(d), None) == "reference", extra=extra)


@dataclass
class MagCompCheck:
    """``aeromag report``'s check of a log's ``mag_comp`` (``headline_check.mag_comp``).

    Attributes
    ----------
    compared : int
        Rows compared.
    max_abs_difference_nT : float or None
        Largest difference [nT].
    tolerance_nT : float
        Largest difference allowed [nT].
    first_row : int or None
        0-based data row of the first difference beyond the tolerance.
    filtered : bool
        Whether the expected ``mag_comp`` was low-passed.
    filter_recorded : bool
        Whether the report records the filter setting (an online report does not).
    warning : str or None
        The one-line warning.
    note : str or None
        Why the low-passed field was not compared.
    extra : dict
        Keys this class does not know (written after the others).
    """

    compared: int = 0
    max_abs_difference_nT: float | None = None
    tolerance_nT: float | None = None
    first_row: int | None = None
    filtered: bool | None = None
    filter_recorded: bool | None = None
    warning: str | None = None
    note: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    _ALWAYS = frozenset({"compared", "max_abs_difference_nT", "tolerance_nT", "first_row",
                         "filtered", "filter_recorded", "warning"})

    def to_dict(self) -> dict[str, Any]:
        """The JSON block (``note`` only when set).

        Returns
        -------
        dict
        """
        return _set_dict(self, self._ALWAYS)

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> MagCompCheck | None:
        """The block read from a file (None for none).

        Parameters
        ----------
        d : dict or None

        Returns
        -------
        MagCompCheck or None
        """
        return None if d is None else _set_from_dict(cls, d)


@dataclass
class HeadlineCheck:
    """``aeromag report``'s comparison of the recomputed headline with the recorded one.

    The report's and ``qc.json``'s ``headline_check``
    (:func:`aeromag.workflows.report_check.compare_headline`).

    Attributes
    ----------
    compared : bool
        Whether the recorded metrics could be compared.
    agree : bool or None
        Whether they agree within the tolerance (None when not compared).
    relative_tolerance : float
        Tolerance of the figures [-].
    counts : str
        ``equal``: sample counts compare exactly.
    recorded_in : str
        The report file.
    warning : str or None
        The one-line warning of a disagreement.
    definition : str
        What is compared, in words.
    note : str or None
        Why nothing was compared.
    max_relative_difference : float or None
        The largest relative difference [-].
    differences : dict or None
        Per figure: ``computed``, ``recorded``, ``relative``.
    mag_comp : MagCompCheck or None
        The check of the log's ``mag_comp``.
    extra : dict
        Keys this class does not know (written after the others).
    """

    compared: bool = False
    agree: bool | None = None
    relative_tolerance: float | None = None
    counts: str | None = None
    recorded_in: str | None = None
    warning: str | None = None
    definition: str | None = None
    note: str | None = None
    max_relative_difference: float | None = None
    differences: dict[str, dict[str, Any]] | None = None
    mag_comp: MagCompCheck | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    _ALWAYS = frozenset({"compared", "agree", "relative_tolerance", "counts", "recorded_in",
                         "warning", "definition"})

    def to_dict(self) -> dict[str, Any]:
        """The JSON block (``note``, the differences and ``mag_comp`` only when set).

        Returns
        -------
        dict
        """
        return _set_dict(self, self._ALWAYS)

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> HeadlineCheck | None:
        """The block read from a file (None for none).

        Parameters
        ----------
        d : dict or None

        Returns
        -------
        HeadlineCheck or None
        """
        return None if d is None else _set_from_dict(cls, d, mag_comp=MagCompCheck.from_dict)


@dataclass
class FitSummary:
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

    def to_dict(self) -> dict[str, Any]:
        """The JSON ``fit`` block.

        Returns
        -------
        dict
        """
        return block_dict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> FitSummary | None:
        """A ``fit`` block read from a file (None for none).

        Parameters
        ----------
        d : dict or None

        Returns
        -------
        FitSummary or None
        """
        return block_from_dict(cls, d)


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
