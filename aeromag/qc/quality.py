"""All quality-control metrics of a compensated log: :func:`compute_qc`.

Every number is computed from a :class:`aeromag.compensate.CompensationResult` (the output of
``aeromag compensate``: ``mag``, ``mag_tl``, ``mag_comp``, ``segment``, ``segment_kept``, its
configuration and report).  See ``docs/qc.md`` for the definitions.

* **FOM** (Figure of Merit, :mod:`aeromag.qc.fom`): the sum over the 12 manoeuvres of a
  calibration box of the peak-to-peak amplitude of the band-passed signal within the manoeuvre.
* **Improvement ratio** and **residual std**, per segment and per heading.
* **Noise** (:mod:`aeromag.qc.noise`): band-limited std before/after and the fourth-difference
  noise estimate.
* **Fit diagnostics** (:mod:`aeromag.qc.diagnostics`): condition numbers, variance inflation
  factors and leave-one-segment-out CV from the per-segment normal equations.
"""

from __future__ import annotations

import dataclasses
import logging
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from .._core.filters import sampling_rate
from .._core.fit_diagnostics import FitDiagnostics
from .._core.stretches import find_stretches
from ..compensation.apply import isolate_dropped
from ..compensation.config import CompensationConfig
from ..compensation.metrics import compensation_metrics
from ..compensation.report_types import CompensationMetrics, CompensationReport, HeadlineCheck
from ..compensation.terms import TERMS_16
from ..errors import AeromagError, InputError
from .diagnostics import fit_diagnostics
from .fom import fom_not_applicable, fom_rows, fom_summary, fom_table
from .fom_types import FomSummary
from .labels import kept_mask, segment_labels
from .maneuvers import CARDINALS, ManeuverResult, detect_maneuvers
from .noise import fourth_difference_noise, grouped_std
from .residuals import PieceResiduals, piece_residuals
from .summaries import (
    ManeuverSummary,
    NoiseSummary,
    PerPieceRms,
    PieceRms,
    QCSegmentRow,
    RmsSummary,
)
from .total_field import fluxgate_is_total_field, prepared_total_field

__all__ = ["QCMetrics", "QCResult", "compute_qc", "headline_metrics", "quality_metrics"]

log = logging.getLogger(__name__)

QC_SKIPPED_NOTE = "manoeuvre detection skipped (no FOM): run 'aeromag report' or --fom"
QC_SKIPPED_FOM = ("not computed for this run (FOM is for calibration flights: `aeromag"
                  " calibrate`, --fom, or `aeromag report`)")


def residual_definition(trim_s: float) -> str:
    """What the per-piece rms figures are (the ``qc.per_piece_rms.definition`` text).

    Parameters
    ----------
    trim_s : float
        Edge trimmed at each end of every segment piece [s].

    Returns
    -------
    str
    """
    return ("rms of mag and of mag - mag_tl band-passed in band_hz (zero-phase Butterworth),"
            " each segment piece (one segment within one continuous stretch) filtered on its"
            f" own, {trim_s:g} s trimmed at its ends; 'kept' over the kept segments, 'all' over"
            " every piece. A diagnostic beside the headline, not the improvement ratio")


def headline_metrics(comp_metrics: CompensationMetrics, per_piece_kept: RmsSummary,
                     per_piece_all: RmsSummary, trim_s: float) -> dict[str, Any]:
    """The QC headline: the contract's metrics, with the per-piece rms figures beside them.

    Parameters
    ----------
    comp_metrics : CompensationMetrics
        :func:`aeromag.compensation.metrics.compensation_metrics` of the log (the same block
        as OUT.json ``metrics``).
    per_piece_kept, per_piece_all : RmsSummary
        Per-piece rms figures (:class:`aeromag.qc.residuals.PieceResiduals` ``kept``/``all``:
        ``improvement_ratio``, ``residual_std_nT``, ``std_before_nT`` [nT], ``n_samples``).
    trim_s : float
        Edge trimmed at each end of every segment piece for those [s].

    Returns
    -------
    dict
        The keyword arguments of :class:`QCMetrics`: ``definition``, ``improvement_ratio``,
        ``residual_std_nT``, ``std_before_nT`` [nT],
        ``n_samples`` (over the kept segments, exactly the ``metrics`` block's), ``all_data``
        (:class:`~aeromag.qc.summaries.RmsSummary`, the same over all segments) and
        ``per_piece_rms`` (:class:`~aeromag.qc.summaries.PerPieceRms`: ``definition``,
        ``kept``, ``all`` with ``per_piece_rms_ratio``, ``per_piece_rms_after_nT``,
        ``per_piece_rms_before_nT`` [nT], ``n_samples``).
    """
    cm = comp_metrics
    return {
        "definition": cm.definition,
        "improvement_ratio": cm.improvement_ratio, "residual_std_nT": cm.residual_std_nT,
        "std_before_nT": cm.std_before_nT, "n_samples": cm.n_samples,
        "all_data": RmsSummary(cm.all_improvement_ratio, cm.all_residual_std_nT,
                               cm.all_std_before_nT, cm.all_n_samples),
        "per_piece_rms": PerPieceRms(residual_definition(trim_s), PieceRms.of(per_piece_kept),
                                     PieceRms.of(per_piece_all)),
    }


def contract_metrics(t: np.ndarray, mag: np.ndarray, tl: np.ndarray, seg: np.ndarray,
                     kept: np.ndarray, cfg: CompensationConfig) -> CompensationMetrics:
    """OUT.json's ``metrics`` recomputed from a compensated log (compensation.metrics).

    Band-passes ``mag`` and ``mag - mag_tl`` once per continuous stretch of finite samples,
    each dropped segment on its own, as :func:`aeromag.compensation.apply_model` does.

    Parameters
    ----------
    t : ndarray
        Times [s].
    mag, tl : ndarray
        Total field and the model's interference ``mag_tl`` [nT].
    seg : ndarray of int
        Segment per sample (-1: none).
    kept : ndarray of bool
        Samples of kept segments.
    cfg : CompensationConfig
        Band, order, trim and gap.

    Returns
    -------
    CompensationMetrics
        :func:`aeromag.compensation.metrics.compensation_metrics`.
    """
    after = mag - tl
    st = find_stretches(t, np.isfinite(after), cfg.max_gap_s)
    st = isolate_dropped(st, seg, kept)
    return compensation_metrics(mag, after, t, st, cfg, kept=kept)


#: Keys of ``qc.json`` / the report's ``qc`` block written even when None.
_QC_ALWAYS = frozenset({"band_hz", "definition", "improvement_ratio", "residual_std_nT",
                        "std_before_nT", "n_samples", "all_data", "per_piece_rms",
                        "residual_std_by_segment_nT", "noise", "fom", "notes"})


@dataclass
class QCMetrics:
    """The quality-control figures of one compensated log (``qc.json``, the report's ``qc``).

    Its blocks are typed (:mod:`aeromag.qc.summaries`, :mod:`aeromag.qc.fom_types`,
    :class:`~aeromag._core.fit_diagnostics.FitDiagnostics`); the per-segment and per-heading
    residuals and ``figures_skipped`` are mappings (their keys are segment ids, headings and
    figure names).

    Attributes
    ----------
    band_hz : list of float
        The fitting band [Hz].
    definition : str
        How the headline is computed (the compensation metrics' definition).
    improvement_ratio : float
        Band-passed std of ``mag`` over that of ``mag - mag_tl``, kept segments [-].
    residual_std_nT, std_before_nT : float
        Band-passed std of ``mag - mag_tl`` and of ``mag``, kept segments [nT].
    n_samples : int
        Samples of the kept segments the headline is taken over.
    all_data : RmsSummary or None
        The same over all segments (``improvement_ratio``, ``residual_std_nT``,
        ``std_before_nT`` [nT], ``n_samples``).
    per_piece_rms : PerPieceRms or None
        The per-piece rms diagnostic (``definition``, ``kept``, ``all``; see
        :func:`headline_metrics`).
    compensation_metrics : CompensationMetrics or None
        The compensation's own ``metrics`` block, as recorded.
    residual_std_by_segment_nT : dict of str to float
        Band-passed residual std per segment id [nT].
    noise : NoiseSummary or None
        Band-limited std before/after and fourth-difference noise before/after [nT].
    residual_std_by_heading_nT : dict or None
        Band-passed residual std per cardinal heading [nT] (when manoeuvres were detected).
    maneuvers : ManeuverSummary or None
        Detection summary (method, legs, manoeuvres, complete boxes, heading offset [deg]).
    fom : FomSummary or None
        Figure of Merit block (:func:`aeromag.qc.fom.fom_summary`), or why not applicable.
    fit : FitDiagnostics or None
        Fit diagnostics (condition numbers, VIF, leave-one-segment-out CV [nT]).
    notes : list of str
        Why something could not be computed.
    headline_check : HeadlineCheck or None
        ``aeromag report``'s comparison of the recomputed headline with the recorded one.
    figures : list of str or None
        Figures the report wrote.
    figures_skipped : dict or None
        Figures it could not draw, and why.
    segments : list of QCSegmentRow or None
        The report's per-segment rows (:func:`aeromag.workflows.report.segment_rows`).
    warnings : list or None
        What the run warned (filled when ``qc.json`` is written).
    extra : dict
        Other keys (written after the others).
    """

    band_hz: list[float]
    definition: str | None = None
    improvement_ratio: float | None = None
    residual_std_nT: float | None = None
    std_before_nT: float | None = None
    n_samples: int | None = None
    all_data: RmsSummary | None = None
    per_piece_rms: PerPieceRms | None = None
    compensation_metrics: CompensationMetrics | None = None
    residual_std_by_segment_nT: dict[str, float] = field(default_factory=dict)
    noise: NoiseSummary | None = None
    residual_std_by_heading_nT: dict[str, float] | None = None
    maneuvers: ManeuverSummary | None = None
    fom: FomSummary | None = None
    fit: FitDiagnostics | None = None
    notes: list[str] = field(default_factory=list)
    headline_check: HeadlineCheck | None = None
    figures: list[str] | None = None
    figures_skipped: dict[str, str] | None = None
    segments: list[QCSegmentRow] | None = None
    warnings: list[Any] | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The JSON block (optional parts only when present).

        Returns
        -------
        dict
        """
        d: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            if f.name == "extra":
                continue
            v = getattr(self, f.name)
            if v is not None or f.name in _QC_ALWAYS:
                d[f.name] = v.to_dict() if hasattr(v, "to_dict") else v
        d["band_hz"] = list(self.band_hz)
        if self.segments is not None:
            d["segments"] = [s.to_dict() for s in self.segments]
        d.update(self.extra)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> QCMetrics:
        """A ``qc`` block read from a file.

        Parameters
        ----------
        d : dict

        Returns
        -------
        QCMetrics
        """
        names = {f.name for f in dataclasses.fields(cls)} - {"extra"}
        kw = {k: v for k, v in d.items() if k in names}
        kw["band_hz"] = list(kw.get("band_hz") or [])
        kw["compensation_metrics"] = CompensationMetrics.from_dict(
            kw.get("compensation_metrics"))
        for key, typ in _BLOCKS.items():
            if kw.get(key) is not None:
                kw[key] = typ.from_dict(kw[key])
        if kw.get("segments") is not None:
            kw["segments"] = [QCSegmentRow.from_dict(s) for s in kw["segments"]]
        return cls(**kw, extra={k: v for k, v in d.items() if k not in names})


#: The typed blocks of :class:`QCMetrics` (key -> class read by ``from_dict``).
_BLOCKS: dict[str, Any] = {"all_data": RmsSummary, "per_piece_rms": PerPieceRms,
                           "noise": NoiseSummary, "maneuvers": ManeuverSummary,
                           "fom": FomSummary, "fit": FitDiagnostics,
                           "headline_check": HeadlineCheck}


@dataclass
class QCResult:
    """Quality-control results of one compensated log.

    Attributes
    ----------
    metrics : QCMetrics
        The figures (see :func:`compute_qc`; ``metrics.to_dict()`` is ``qc.json``).
    fom : DataFrame or None
        Per-manoeuvre peak-to-peak table (:func:`aeromag.qc.fom_table`), None when no FOM.
    maneuvers : ManeuverResult or None
        Detected legs and manoeuvres.
    segments : DataFrame
        Per-segment residual std, kept flag and cross-validated residual.
    notes : list of str
        Why something could not be computed.
    residuals : PieceResiduals or None
        The band-passed fields the residual metrics used (per segment piece).
    """

    metrics: QCMetrics
    fom: pd.DataFrame | None
    maneuvers: ManeuverResult | None
    segments: pd.DataFrame
    notes: list[str] = field(default_factory=list)
    residuals: PieceResiduals | None = field(default=None, repr=False)


def compute_qc(
    result: Any,
    *legacy: Any,
    config: CompensationConfig | None = None,
    maneuvers: ManeuverResult | None = None,
    maneuver_column: str | None = None,
    fit: bool = True,
    fom: bool = True,
) -> QCResult:
    """All quality-control metrics of a compensated log.

    Parameters
    ----------
    result : CompensationResult
        What :func:`aeromag.compensate.compensate` returned (or the report workflow loaded from
        ``OUT.csv``/``OUT.json``): ``data`` (``time``, ``mag`` or the fluxgate, ``mag_comp``,
        ``mag_tl``, ``segment``, ``segment_kept``; attitude when available), ``report``, and the
        configuration it was compensated with (``config``).
    config : CompensationConfig, optional
        The configuration (default: ``result.config``).
    maneuvers : ManeuverResult, optional
        Already detected manoeuvres.
    maneuver_column : str, optional
        Column naming the manoeuvre of each sample (instead of detection).
    fit : bool
        Fit diagnostics (VIF, condition number, CV): those the fit measured when the model
        was fitted on this log (the report's ``fit`` block), else rebuilt from the log.
    fom : bool
        Detect manoeuvres and compute the FOM (a calibration flight); False skips it unless
        ``maneuvers`` or ``maneuver_column`` is given.

    Returns
    -------
    QCResult
        ``metrics`` holds ``improvement_ratio``, ``residual_std_nT``, ``std_before_nT``,
        ``fom`` (box FOM before/after [nT], per-box and per-manoeuvre tables, or None),
        ``residual_std_by_segment_nT``, ``residual_std_by_heading_nT``, ``noise``, ``fit``
        (condition numbers, VIF, leave-one-segment-out CV), ``maneuvers``, ``notes``.
    """
    if isinstance(result, pd.DataFrame):  # the old compute_qc(data, report, cfg) call
        warnings.warn("compute_qc(data, report, cfg) is deprecated: pass the CompensationResult",
                      DeprecationWarning, stacklevel=2)
        rep = _as_report(legacy[0] if legacy else None)
        cfg = config or (legacy[1] if len(legacy) > 1 else None) or config_of(rep)
        return _compute(result, rep, cfg, maneuvers=maneuvers, maneuver_column=maneuver_column,
                        fit=fit, fom_on=fom)
    if legacy:
        raise TypeError("compute_qc(result): too many positional arguments")
    cfg = config if config is not None else getattr(result, "config", None)
    report = _as_report(getattr(result, "report", None))
    if cfg is None:
        cfg = config_of(report)
    data = result.data
    if data is None:
        raise InputError("this result holds no compensated data (use compensate())")
    return _compute(data, report, cfg, maneuvers=maneuvers, maneuver_column=maneuver_column,
                    fit=fit, fom_on=fom)


def _noise_pair(mag: np.ndarray, tl: np.ndarray | None, comp: np.ndarray, t: np.ndarray,
                max_gap_s: float | None) -> tuple[float, float]:
    """Fourth-difference noise [nT] of ``mag`` and of ``mag - tl`` (``comp`` without ``tl``).

    ``mag - tl`` is taken a block at a time (no full-length copy: 16 MB at 2e6 rows).
    """
    after = (fourth_difference_noise(mag, t, max_gap_s, minus=tl) if tl is not None
             else fourth_difference_noise(comp, t, max_gap_s))
    return fourth_difference_noise(mag, t, max_gap_s), after


def _compute(
    data: pd.DataFrame, report: CompensationReport, cfg: CompensationConfig, *,
    maneuvers: ManeuverResult | None, maneuver_column: str | None, fit: bool, fom_on: bool,
) -> QCResult:
    terms = tuple(report.terms or TERMS_16)
    base_metrics = report.metrics
    notes: list[str] = []
    t = data["time"].to_numpy(dtype=np.float64)
    if "mag_comp" not in data.columns:
        raise InputError("the log has no 'mag_comp' column; run `aeromag compensate` first")
    flux_total = fluxgate_is_total_field(data, report)
    if flux_total:
        # The compensation's total field (OUT.json mag_from_fluxgate): not the log's 'mag',
        # which the compensation did not use.
        mag = prepared_total_field(data, report, cfg)
    else:
        mag = data["mag"].to_numpy(dtype=np.float64)
    comp = data["mag_comp"].to_numpy(dtype=np.float64)
    band = cfg.band_hz
    seg = segment_labels(data, copy=False)  # read only here; the fit gets its own copy
    has_tl = "mag_tl" in data.columns
    tl = data["mag_tl"].to_numpy(dtype=np.float64) if has_tl else mag - comp
    if not has_tl:
        notes.append("no mag_tl column: residuals are band-passed mag_comp (low-passed)")
    fs = sampling_rate(t)  # once: a median over 1e6 steps costs 10-20 ms
    # One step after the other, each freeing its full-length temporaries before the next,
    # the largest first while little else is held: the fit diagnostics (~190 MB of
    # temporaries at 2e6 rows), the noise, the manoeuvres and their FOM table, then the
    # band-passed pieces (kept to the end).  The pieces and the noise used to run on the
    # filter pool beside the detection, and the diagnostics last, on top of everything the
    # QC keeps: `aeromag report` on 2e6 rows peaked at 756 MB, 678 MB now (the concurrency
    # saved 0.1-0.3 s of wall time).  The metrics are assembled below in their usual order.
    fitted = report.fit
    rebuild_fit = bool(fit and not (fitted is not None and fitted.vif)
                       and {"flux_x", "flux_y", "flux_z"} <= set(data.columns))
    fit_out: tuple[FitDiagnostics, pd.DataFrame] | None = None
    fit_error: AeromagError | None = None
    if rebuild_fit:
        try:
            fit_out = fit_diagnostics(data, cfg, terms, seg=seg.copy())
        except AeromagError as exc:
            fit_error = exc
    noise_before, noise_after = _noise_pair(mag, tl if has_tl else None, comp, t,
                                            cfg.max_gap_s)
    detect_error: AeromagError | None = None
    detected = maneuvers is None and (fom_on or maneuver_column is not None)
    if detected:
        try:
            maneuvers = detect_maneuvers(data, maneuver_column=maneuver_column,
                                         max_gap_s=cfg.max_gap_s, fs_hz=fs)
        except AeromagError as exc:
            detect_error = exc
    fom_tab = None
    if maneuvers is not None and len(maneuvers.table):
        fom_tab = fom_table(data, maneuvers, band_hz=band, order=cfg.order,
                            max_gap_s=cfg.max_gap_s, fs_hz=fs,
                            total_field=mag if flux_total else None)
    heading_leg = None
    if maneuvers is not None:
        heading_leg = maneuvers.labels["heading_leg"].to_numpy()
    kept = kept_mask(data)
    pieces = piece_residuals(t, mag, tl, seg, kept, band, cfg.order, trim_s=cfg.trim_s,
                             max_gap_s=cfg.max_gap_s, fs_hz=fs)
    # The headline is the compensation's own metrics of this log (OUT.json metrics, computed on
    # its prepared arrays: gaps interpolated, stretches as fitted); recomputed only without them.
    cm = (base_metrics if base_metrics is not None and base_metrics.all_improvement_ratio
          is not None else contract_metrics(t, mag, tl, seg, kept, cfg))
    metrics = QCMetrics(list(band), **headline_metrics(cm, pieces.kept, pieces.all,
                                                       pieces.trim_s))
    if base_metrics is not None:
        metrics.compensation_metrics = base_metrics
    seg_std = pieces.by_segment
    resid_bp = pieces.after_bp
    band_before = cm.all_std_before_nT
    band_after = cm.all_residual_std_nT
    metrics.residual_std_by_segment_nT = {str(k): v for k, v in seg_std.items()}
    metrics.noise = NoiseSummary(list(band), band_before, band_after, noise_before,
                                 noise_after)
    # Manoeuvres, heading legs, FOM (detected above).
    if maneuvers is None and not fom_on and maneuver_column is None:
        notes.append(QC_SKIPPED_NOTE)
    elif detect_error is not None:
        notes.append(f"manoeuvre detection failed: {detect_error}")
    fom_block: FomSummary | None = fom_not_applicable(QC_SKIPPED_FOM)
    if maneuvers is not None:
        # over the kept segments, like the headline
        hl = np.where(kept, heading_leg, -1)
        metrics.residual_std_by_heading_nT = {
            CARDINALS[k]: v for k, v in grouped_std(resid_bp, hl).items()}
        del hl
        metrics.maneuvers = ManeuverSummary(
            maneuvers.method, len(maneuvers.legs), len(maneuvers.table),
            maneuvers.complete_boxes, maneuvers.heading_offset_deg, maneuvers.notes)
        if fom_tab is not None:
            fom_block = fom_summary(fom_tab)
            fom_block.table = fom_rows(fom_tab)
            if not fom_block.applicable:
                notes.append(fom_block.reason)
            elif fom_block.kept_reason:  # a box with dropped manoeuvres: no kept FOM
                notes.append(fom_block.kept_reason)
        else:
            why = "no pitch/roll/yaw manoeuvre found (not a calibration flight?)"
            notes.append("no pitch/roll/yaw manoeuvre found: no FOM (not a calibration flight?)")
            fom_block = fom_not_applicable(why)
    elif fom_on:
        fom_block = fom_not_applicable("the manoeuvres could not be detected")
    metrics.fom = fom_block
    segs = pd.DataFrame({"segment": list(seg_std), "residual_std_nT": list(seg_std.values())})
    segs["n"] = [pieces.n_by_segment[s] for s in seg_std]
    del t, mag, comp, tl, resid_bp, kept
    if fit and fitted is not None and fitted.vif:  # the fit measured them on its own data
        metrics.fit = FitDiagnostics(
            source="the fit (model file)", condition_number=fitted.condition_number,
            condition_number_scaled=fitted.condition_number_scaled, vif=fitted.vif,
            max_vif=fitted.max_vif, cv_residual_std_nT=fitted.cv_residual_std_nT,
            cv_ratio=fitted.cv_ratio, fit_residual_std_nT=fitted.residual_std_nT,
            n_segments_kept=fitted.n_segments_fitted)
    elif fit_out is not None:
        diag, cv = fit_out
        metrics.fit = diag
        cv = cv.drop(columns=["n"])
        segs = cv.merge(segs, on="segment", how="outer")
    elif fit_error is not None:
        notes.append(f"fit diagnostics failed: {fit_error}")
    metrics.notes = notes
    for n in notes:
        log.info("qc: %s", n)
    return QCResult(metrics, fom_tab, maneuvers, segs, notes, pieces)


def quality_metrics(
    data: pd.DataFrame, report: CompensationReport | dict[str, Any] | None = None,
    cfg: CompensationConfig | None = None, *, detect: bool = True, fit: bool = True,
    maneuver_column: str | None = None, maneuvers: ManeuverResult | None = None,
) -> QCMetrics:
    """QC metrics of a compensated log given as a table and its report.

    Prefer :func:`compute_qc` on the :class:`~aeromag.compensate.CompensationResult`.

    Parameters
    ----------
    data : DataFrame
        Compensated log.
    report : CompensationReport or dict, optional
        Its report (a dict is read as a report file, :meth:`CompensationReport.from_dict`).
    cfg : CompensationConfig, optional
        Configuration (default: the report's ``config`` block).
    detect, fit : bool
        Manoeuvres/FOM and fit diagnostics (see :func:`compute_qc`'s ``fom`` and ``fit``).
    maneuver_column : str, optional
        Column naming each sample's manoeuvre.
    maneuvers : ManeuverResult, optional
        Already detected manoeuvres.

    Returns
    -------
    QCMetrics
        See :func:`compute_qc`.
    """
    rep = _as_report(report)
    cfg = cfg if cfg is not None else config_of(rep)
    return _compute(data, rep, cfg, maneuvers=maneuvers, maneuver_column=maneuver_column,
                    fit=fit, fom_on=detect).metrics


def _as_report(report: CompensationReport | dict[str, Any] | None) -> CompensationReport:
    """``report``, or a report read from its JSON dict (an empty one for None)."""
    if isinstance(report, CompensationReport):
        return report
    return CompensationReport.from_dict(report or {})


def config_of(report: CompensationReport) -> CompensationConfig:
    """The configuration recorded in a report (defaults for what it lacks).

    Parameters
    ----------
    report : CompensationReport
        A report (its ``config`` and ``band_hz``).

    Returns
    -------
    CompensationConfig
    """
    names = {f.name for f in dataclasses.fields(CompensationConfig)}
    kw = {k: v for k, v in (report.config.options() if report.config else {}).items()
          if k in names}
    if "band_hz" not in kw and report.band_hz:
        kw["band_hz"] = report.band_hz
    return CompensationConfig(**kw)
