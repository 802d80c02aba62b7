"""The one builder of the compensation report (``OUT.json``, ``MODEL.json``) from typed results.

Three runs make a report: a fit (:func:`fit_report`, from a
:class:`~aeromag.compensation.result.FitOutcome`), and a saved model applied in memory or chunk by
chunk (:func:`applied_report`, from an :class:`AppliedRun`).  They return a
:class:`~aeromag.compensation.report_types.CompensationReport`; the workflows that write a file
turn it into JSON (:meth:`~aeromag.compensation.report_types.CompensationReport.to_dict`).
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import logging
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import __version__
from .._core.angles import circular_mean_rad
from ..conventions import EPOCH_DISPLAY_S
from .config import CompensationConfig
from .config_record import ConfigRecord
from .model import TLModel
from .report_types import (
    ChunkSettings,
    CompensationMetrics,
    CompensationReport,
    FitSummary,
    ResidualScreen,
    ScreeningSummary,
    SegmentRow,
)
from .screening import RULE
from .segments import segment_counts

if TYPE_CHECKING:
    from .result import FitOutcome

log = logging.getLogger(__name__)

__all__ = ["AppliedRun", "applied_report", "dropped_summary", "fit_report",
           "flag_residual_outliers", "format_time",
           "is_epoch", "name_segments", "segment_name", "time_span"]


#: Residual screen of an applied model: a segment is flagged when its band-passed residual
#: std is above median + RESIDUAL_FLAG_MADS * MAD (the MAD scaled by 1.4826 to a normal
#: sigma) of the segments' residuals and above RESIDUAL_FLAG_RATIO times their median.
RESIDUAL_FLAG_MADS = 5.0
RESIDUAL_FLAG_RATIO = 3.0
#: Fewest segments with a residual for the screen to run (a median of two means nothing).
RESIDUAL_FLAG_MIN_SEGMENTS = 3


def flag_residual_outliers(report: CompensationReport) -> list[int]:
    """Flag the segments of an applied model whose residual is far above the others'.

    A saved model is applied, never refitted, so every segment stays ``kept`` (interface.md:
    ``segment_kept`` is all true when a saved model is applied); but a faulty line (a
    drifting sensor, an interference the calibration did not see) leaves a residual far above
    the rest.  Each segment gets ``residual_flagged`` (bool), the report a ``residual_screen``
    block (rule, median, MAD, threshold [nT], flagged ids), and a warning names the segments.
    The rule is robust (median and MAD, see :data:`RESIDUAL_FLAG_MADS`), so one bad line
    cannot hide itself by raising the threshold.

    Parameters
    ----------
    report : CompensationReport
        An applied report whose ``segments`` hold ``residual_std`` [nT] (None when unknown).
        Changed in place.

    Returns
    -------
    list of int
        Ids of the flagged segments.
    """
    segs = report.segments
    r = np.array([np.nan if e.residual_std is None else float(e.residual_std) for e in segs],
                 dtype=np.float64)
    ok = np.isfinite(r)
    block = ResidualScreen(
        rule=f"residual_std > median + {RESIDUAL_FLAG_MADS:g} * 1.4826 * MAD and >"
             f" {RESIDUAL_FLAG_RATIO:g} * median, over the segments")
    for e in segs:
        e.residual_flagged = False
    report.residual_screen = block
    if ok.sum() < RESIDUAL_FLAG_MIN_SEGMENTS:
        block.note = (f"fewer than {RESIDUAL_FLAG_MIN_SEGMENTS} segments with a residual:"
                      " not screened")
        return []
    med = float(np.median(r[ok]))
    mad = 1.4826 * float(np.median(np.abs(r[ok] - med)))
    thr = max(med + RESIDUAL_FLAG_MADS * mad, RESIDUAL_FLAG_RATIO * med)
    block.median_nT, block.mad_nT, block.threshold_nT = med, mad, thr
    flagged = [j for j in np.flatnonzero(ok & (r > thr)).tolist()]
    for j in flagged:
        segs[j].residual_flagged = True
    block.flagged = [int(segs[j].id) for j in flagged]
    if flagged:
        what = ", ".join(f"{segment_name(segs[j])}: {r[j]:.3g} nT" for j in flagged)
        log.warning(
            "%s: %d of %d segments have a residual far above the others' (%s; median %.3g nT,"
            " threshold %.3g nT = median + %g MAD): a faulty sensor or an interference the"
            " model does not hold there; check those segments (flagged in the report's"
            " segments and residual_screen; segment_kept stays true: a saved model is applied,"
            " not refitted)", report.source, len(flagged), int(ok.sum()),
            what, med, thr, RESIDUAL_FLAG_MADS)
    return block.flagged


def _header(source: str) -> dict[str, Any]:
    return {"aeromag_version": __version__,
            "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
            "source": source}


@dataclass
class AppliedRun:
    """A saved model applied to a log (in memory or chunked).

    Attributes
    ----------
    source : str
        The log.
    model : TLModel
        The model applied.
    cfg : CompensationConfig
        Options.
    fs_hz : float
        Sampling rate [Hz].
    segment_n : dict of int to int
        Samples per segment id.
    metrics : CompensationMetrics
        :mod:`aeromag.compensation.metrics` of the run.
    residual_by_segment : dict of int to float
        Band-passed residual std per segment [nT] (None where unknown).
    qc : object or None
        The ``qc`` block (:class:`aeromag.qc.QCMetrics`).
    n_rows : int or None
        Rows of a chunked run.
    chunked : ChunkSettings or None
        A chunked run's chunk and overlap rows.
    """

    source: str
    model: TLModel
    cfg: CompensationConfig
    fs_hz: float
    segment_n: dict[int, int]
    metrics: CompensationMetrics
    residual_by_segment: dict[int, float | None] = field(default_factory=dict)
    qc: Any = None
    n_rows: int | None = None
    chunked: ChunkSettings | None = None


def applied_report(run: AppliedRun) -> CompensationReport:
    """The report of a saved model applied to a log (every segment counts as kept).

    Parameters
    ----------
    run : AppliedRun
        What was applied and measured.

    Returns
    -------
    CompensationReport
        interface.md keys (``terms``, ``coef``, ``segments``, ``metrics``) and more.
    """
    model, cfg = run.model, run.cfg
    report = CompensationReport(
        **_header(run.source),
        terms=list(model.terms),
        coef=[float(c) for c in model.coef],
        scale_nT=model.scale_nT,
        model_source=str(model.meta.path or "given"),
        band_hz=list(cfg.band_hz),
        sampling_rate_hz=run.fs_hz,
        segments=[SegmentRow(int(i), int(run.segment_n[i]), True, None,
                             run.residual_by_segment.get(i)) for i in sorted(run.segment_n)],
        screening=ScreeningSummary(False, ["a saved model was applied: nothing fitted"]),
        metrics=run.metrics,
        # What the application used: the fit-only options played no part (the model's terms
        # are ``terms`` above).
        config=ConfigRecord.from_config(cfg, applied=True),
        qc=run.qc, n_rows=run.n_rows, chunked=run.chunked,
    )
    if any(v is not None for v in run.residual_by_segment.values()):
        flag_residual_outliers(report)  # in memory: once the qc has the residuals
    return report


def _segment_entries(fit: FitOutcome) -> list[SegmentRow]:
    """One entry per segment: fitted ones with their scores and guards, too-short ones."""
    stats, out, prep = fit.stats, fit.screening, fit.prep
    screen = out.screen
    # "n" counts the segment's samples in the log (as when a saved model is applied);
    # "n_fit" those its fit used (valid, filterable, filter edges trimmed).
    all_ids, all_n = segment_counts(prep.segment)
    n_of = dict(zip(all_ids.tolist(), all_n.tolist(), strict=True))
    segments = []
    for j, sid in enumerate(stats.ids):
        entry = SegmentRow(
            id=int(sid),
            n=int(n_of.get(int(sid), 0)),
            n_fit=int(stats.n[j]),
            kept=bool(out.kept[j]),
            scores=screen.scores[j].tolist() if screen is not None else None,
            residual_std=float(fit.residual[j]),
            cv_residual_std=float(fit.cv_residual[j]),
            condition_number=float(fit.segment_condition[j]),
            coef=[float(c) for c in out.seg_coef[j]],
        )
        if screen is not None:
            entry.robust_distance = float(screen.distance[j])
            entry.pca_outlier = bool(not screen.kept[j])
            entry.residual_excess = float(out.excess[j])
            entry.own_fit_excess = float(out.own_ratio[j])
            entry.readmitted = bool(out.readmitted[j])
        if out.residual_pool_nT is not None:
            # Under the pooled fit of the screening's last round: the median of these over the
            # segments it kept (kept and not readmitted) is what residual_excess divides by.
            entry.pool_residual_nT = float(out.residual_pool_nT[j])
        segments.append(entry)
    for sid, cnt in sorted(stats.too_short.items()):
        segments.append(SegmentRow(
            id=sid, n=int(n_of.get(int(sid), 0)), n_fit=cnt, kept=False, scores=None,
            residual_std=None, too_short=True, min_samples=int(stats.min_samples),
            reason=_too_short_reason(cnt, int(n_of.get(int(sid), 0)), int(stats.min_samples),
                                     fit.decimation),
            nulls=frozenset({"condition_number"})))
    segments.sort(key=lambda e: e.id)
    if prep.line_of_segment:
        for e in segments:
            e.set("line", prep.line_of_segment.get(e.id))
    _explain_dropped(fit, segments)
    return segments


def _too_short_reason(n_fit: int, n: int, need: int, decimation: int) -> str:
    """Why a segment was not fitted, with its numbers."""
    what = "usable samples" + (f" (decimated by {decimation})" if decimation > 1 else "")
    return (f"too short to fit: {n_fit} {what} of its {n} (band-passed, filter edges trimmed),"
            f" needs \u2265 {need}")


def _explain_dropped(fit: FitOutcome, segments: list[SegmentRow]) -> None:
    """Add to each dropped segment why (words and numbers), its time span, heading and name.

    A screened-out segment's reason gives its pooled-fit residual [nT] and the median it is
    compared with: the median pooled-fit residual of the segments the screening kept (each
    segment's ``pool_residual_nT``, under the pooled fit of the screening's last round, over
    the entries ``kept`` and not ``readmitted``), so that ``residual_excess =
    pool_residual_nT / pool_median_nT``.
    """
    from .normal import segment_residual_std
    from .screening import own_fit_excess

    stats, out, prep = fit.stats, fit.screening, fit.prep
    row = {int(s): j for j, s in enumerate(stats.ids)}
    own = None
    if out.residual_pool_nT is not None:
        own = own_fit_excess(out.residual_pool_nT, segment_residual_std(stats, out.seg_coef))
    for e in segments:
        if e.kept:
            continue
        if prep.from_line and e.line is None and "line" not in e.nulls:
            e.line = e.id  # integer line numbers are the segment ids
        j = row.get(e.id)
        if j is not None and out.screen is not None and out.residual_pool_nT is not None:
            r, ex = float(out.residual_pool_nT[j]), float(out.excess[j])
            med = r / ex if ex > 0 else None
            e.set("pool_median_nT", med)
            vs = (f"the median pooled-fit residual of the kept segments ({med:.3g} nT)"
                  if med is not None else "the median pooled-fit residual of the kept segments")
            if not out.screen.kept[j]:
                e.reason = (f"PCA outlier: robust distance\u00b2 {out.screen.distance[j]:.4g} >"
                               f" {out.screen.cutoff:.3g}; pooled-fit residual {r:.3g} nT ="
                               f" {ex:.3g}x {vs}")
            else:
                oj, oratio = float(own[j]), float(out.own_ratio[j])
                omed = oj / oratio if oratio > 0 else None
                e.own_excess_nT = oj
                e.set("own_excess_median_nT", omed)
                otail = f" ({omed:.3g} nT)" if omed is not None else ""
                e.reason = (f"faulty although inside the PCA cluster: pooled-fit residual"
                               f" {r:.3g} nT = {ex:.3g}x {vs}; own-fit excess {oj:.3g} nT ="
                               f" {oratio:.3g}x the kept segments' median{otail}")
        sel = prep.segment == e.id
        if sel.any():
            t = prep.time[sel]
            e.start_time, e.end_time = float(t[0]), float(t[-1])
            if prep.heading_deg is not None:
                h = prep.heading_deg[sel]
                h = h[np.isfinite(h)]
                e.set("heading_deg",
                      float(np.rad2deg(circular_mean_rad(np.deg2rad(h))) % 360.0)
                      if h.size else None)
    name_segments(segments, lines=prep.from_line)


def segment_name(entry: SegmentRow, *, lines: bool = True) -> str:
    """How the summary, the reports and the HTML name a segment.

    Parameters
    ----------
    entry : SegmentRow
        A report's segment (``id``; ``line``, ``start_time``, ``end_time`` [s] when
        known).
    lines : bool
        Whether the segments are the log's flight lines (its ``line`` column).  Segments cut
        from time windows or from detected heading legs / maneuvers are no lines.

    Returns
    -------
    str
        ``line 2`` for a flight line; otherwise ``segment 9 (120.0–185.3 s)`` (the span
        in the log's time, when known; ``segment 4 (22:15:19–22:15:49 UTC)`` when the time is
        epoch seconds, :func:`time_span`), never ``line 9``.
    """
    if lines and entry.line is not None:
        return f"line {entry.line:g}"
    name = f"segment {entry.id}"
    t0, t1 = entry.start_time, entry.end_time
    if t0 is not None and t1 is not None:
        name += f" ({time_span(t0, t1)})"
    return name


def is_epoch(t: float) -> bool:
    """Whether a time [s] reads as Unix epoch seconds (2001-09-09 to 2099-12-04).

    Parameters
    ----------
    t : float
        A time of the log [s].

    Returns
    -------
    bool
    """
    return bool(np.isfinite(t) and EPOCH_DISPLAY_S[0] <= t < EPOCH_DISPLAY_S[1])


def format_time(t: float) -> str:
    """A log time for people: ``HH:MM:SS`` (UTC) for epoch seconds, else ``123.4`` [s].

    The summary, the report's segment names and the HTML tables write times this way.

    Parameters
    ----------
    t : float
        A time of the log [s].

    Returns
    -------
    str
    """
    if is_epoch(t):
        return _dt.datetime.fromtimestamp(t, _dt.UTC).strftime("%H:%M:%S")
    return f"{t:.1f}"


def time_span(t0: float, t1: float) -> str:
    """``22:15:19–22:15:49 UTC`` for epoch seconds, else ``120.0–185.3 s`` (log time)."""
    unit = " UTC" if is_epoch(t0) and is_epoch(t1) else " s"
    if unit == " s":
        return f"{t0:.1f}–{t1:.1f} s"
    return f"{format_time(t0)}–{format_time(t1)}{unit}"


def name_segments(segments: list[SegmentRow], *, lines: bool) -> None:
    """Give every segment that was not kept its ``name`` (:func:`segment_name`), in place.

    With ``lines`` False (the segments are time windows, or heading legs / maneuvers that a
    detector found in a log without a ``line`` column) no entry keeps a ``line`` key: a
    segment id is no flight line.

    Parameters
    ----------
    segments : list of SegmentRow
        A report's ``segments``.
    lines : bool
        Whether the segments are the log's flight lines.
    """
    for e in segments:
        if not lines:
            e.drop("line")
        if not e.kept:
            e.name = segment_name(e, lines=lines)


def _too_short(entry: SegmentRow) -> bool:
    return bool(entry.too_short) or str(entry.reason or "").startswith("too short")


def _plural(n: int) -> str:
    return f"{n} segment{'s' if n != 1 else ''}"


def dropped_summary(report: CompensationReport) -> str:
    """What the fit left out, for the command line's one-line summary; empty when nothing.

    Segments the screening dropped and segments too short to fit are told apart:
    ``dropped 1 segment: line 2; 1 segment not fitted (too short): line 7``; segments that
    are no flight lines are named ``segment 9 (120.0–185.3 s)`` (:func:`segment_name`).

    Parameters
    ----------
    report : CompensationReport
        A report with ``segments``.

    Returns
    -------
    str
        The phrase for the command line's one-line summary.
    """
    gone = [e for e in report.segments if not e.kept]

    def names(entries: list[SegmentRow]) -> str:
        return ", ".join(e.name or segment_name(e) for e in entries)

    screened = [e for e in gone if not _too_short(e)]
    short = [e for e in gone if _too_short(e)]
    parts = []
    if screened:
        parts.append(f"dropped {_plural(len(screened))}: {names(screened)}")
    if short:
        parts.append(f"{_plural(len(short))} not fitted (too short): {names(short)}")
    return "; ".join(parts)


def _screening_block(fit: FitOutcome) -> ScreeningSummary:
    cfg, stats, out = fit.cfg, fit.stats, fit.screening
    screen = out.screen
    block = ScreeningSummary(
        enabled=out.screened,
        requested=bool(cfg.screen),
        method="pca+mcd",
        rule=RULE,
        pca_variance_threshold=cfg.pca_variance,
        quantile=cfg.screen_quantile,
        shrink=cfg.shrink,
        min_excess=cfg.min_excess,
        min_excess_nT=cfg.min_excess_nT,
        iterations=out.iterations,
        n_segments=len(stats.ids),
        n_kept=int(out.kept.sum()),
        dropped=[int(s) for s in stats.ids[~out.kept]],
        readmitted=[int(s) for s in stats.ids[out.readmitted]],
        notes=out.notes + (screen.notes if screen is not None else []),
    )
    if screen is not None:
        pca = screen.to_dict()
        pca.pop("notes")
        block = dataclasses.replace(block, **pca)
    return block


def fit_report(fit: FitOutcome) -> CompensationReport:
    """The report of a fit (``MODEL.json``; ``OUT.json`` adds the metrics and ``qc``).

    Parameters
    ----------
    fit : FitOutcome
        What the fit decided and measured.

    Returns
    -------
    CompensationReport
        ``terms``, ``coef``, ``fit``, ``segments``, ``screening``, ``config`` and more.
    """
    cfg, prep, stats, diag = fit.cfg, fit.prep, fit.stats, fit.diagnostics
    n_fit = int(stats.n[fit.screening.kept].sum())
    return CompensationReport(
        **_header(prep.source),
        terms=list(fit.terms),
        coef=[float(c) for c in fit.coef],
        scale_nT=50000.0,
        band_hz=list(cfg.band_hz),
        filter_order=cfg.order,
        sampling_rate_hz=prep.fs,
        mag_from_fluxgate=prep.mag_from_flux,
        fit=FitSummary(
            n_samples=n_fit,
            decimation_factor=fit.decimation,
            n_segments_fitted=int(fit.screening.kept.sum()),
            condition_number=fit.cond,
            condition_number_scaled=fit.cond_scaled,
            ridge=cfg.ridge,
            residual_std_nT=float(np.sqrt(max(fit.sse, 0.0) / max(n_fit, 1))),
            vif=diag.vif,
            max_vif=diag.max_vif,
            cv_residual_std_nT=diag.cv_residual_std_nT,
            cv_ratio=diag.cv_ratio,
        ),
        segments=_segment_entries(fit),
        screening=_screening_block(fit),
        config=ConfigRecord.from_config(cfg),
    )
