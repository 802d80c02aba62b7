"""``aeromag compensate --online``: the Tolles-Lawson model estimated sample by sample.

File in, files out, with the same columns as ``compensate`` (``mag_tl``, ``mag_comp``,
``segment``, ``segment_kept``) and the same report keys (``terms``, ``coef``, ``segments``,
``metrics``), plus the coefficient history at a coarse step.  No screening: every segment is
kept (an online estimator has no second pass).  The metrics are the batch fit's
(:func:`online_metrics`: ``mag - mag_tl`` band-passed once, over every sample, the warm-up
included, which is what ``aeromag report`` recomputes from OUT.csv; ``after_warmup`` beside
it, without the first memory of the estimate).  The headline metrics get the batch fit's
checks (:func:`aeromag.compensation.checks.check_metrics`: an improvement ratio below 1, an
implausible residual), logged as warnings, so that OUT.json records them and ``--strict``
refuses the log before anything is written.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from .. import __version__
from .._core.filters import lowpass_stretches, sampling_rate
from .._core.rls import check_forgetting
from .._core.stretches import find_stretches
from ..compensation.checks import check_metrics
from ..compensation.config import CompensationConfig
from ..compensation.fit import check_interference
from ..compensation.metrics import band_metrics, compensation_metrics, split_fields
from ..compensation.online import LATENCY_SAMPLES, NIS_THRESHOLD, OnlineTL, OnlineTLResult
from ..compensation.online_convergence import UnconvergedSpan
from ..compensation.prepare import prepare
from ..compensation.report_types import CompensationMetrics
from ..compensation.segments import SegmentRow
from ..errors import FitError, InputError
from ..io.outputs import output_set
from ._frame_files import frame_to_files

log = logging.getLogger(__name__)

__all__ = ["ConvergenceSummary", "OnlineHistory", "OnlineReport", "compensate_online_file",
           "compensate_online_frame", "convergence_summary", "online_metrics",
           "DEFAULT_FORGETTING", "COVERAGE"]

#: Default forgetting factor of the online TL fit (memory about 1000 samples: 100 s at 10 Hz).
DEFAULT_FORGETTING = 0.999
#: Rows of the coefficient history kept in OUT.json.
HISTORY_POINTS = 200

#: What the online headline covers (OUT.json ``metrics.coverage``).
COVERAGE = ("every sample of the flight, the RLS warm-up included (no screening online: every"
            " segment is kept, so kept_* = all_*); metrics.after_warmup gives the same figures"
            " without the first warmup_s seconds (one memory, 1 / (1 - forgetting) samples)")
#: ``metrics.coverage`` with ``--mark-unconverged``.
COVERAGE_MARKED = ("all_*: every sample of the flight; kept_*: the rows written with"
                   " segment_kept true, the rows issued before the online fit converged"
                   " (convergence.spans) marked false (mark_unconverged)")


@dataclass
class ConvergenceSummary:
    """Whether the online fit had converged where it issued its output (``convergence``).

    Attributes
    ----------
    definition : str
        The convergence check in words.
    threshold : float
        Windowed NIS ratio above which the fit is not converged [-].
    window_s, memory_s : float
        Window of the NIS and memory of the estimate [s].
    n_unconverged : int
        Rows issued before convergence.
    marked : bool
        Whether those rows were written with ``segment_kept`` false (``--mark-unconverged``).
    spans : list of UnconvergedSpan
        The stretches issued before convergence.
    mag_tl_std_nT : dict
        ``converged_median``, ``converged_p95``, ``unconverged_median``, ``unconverged_p95``
        of the fit's own ``mag_tl`` uncertainty [nT] (None without such rows).
    extra : dict
        Keys this class does not know (written after the others).
    """

    definition: str = ""
    threshold: float | None = None
    window_s: float | None = None
    memory_s: float | None = None
    n_unconverged: int = 0
    marked: bool = False
    spans: list[UnconvergedSpan] = field(default_factory=list)
    mag_tl_std_nT: dict[str, float | None] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The JSON block.

        Returns
        -------
        dict
        """
        d = {"definition": self.definition, "threshold": self.threshold,
             "window_s": self.window_s, "memory_s": self.memory_s,
             "n_unconverged": self.n_unconverged, "marked": self.marked,
             "spans": [s.to_dict() for s in self.spans],
             "mag_tl_std_nT": dict(self.mag_tl_std_nT)}
        d.update(self.extra)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> ConvergenceSummary | None:
        """The block read from a file (None for none).

        Parameters
        ----------
        d : dict or None

        Returns
        -------
        ConvergenceSummary or None
        """
        if d is None:
            return None
        kw, extra = split_fields(cls, d)
        kw["spans"] = [UnconvergedSpan(**s) for s in kw.get("spans") or []]
        kw["mag_tl_std_nT"] = dict(kw.get("mag_tl_std_nT") or {})
        return cls(**kw, extra=extra)


@dataclass
class OnlineHistory:
    """The coefficients of the online fit at a coarse step (``history``).

    Attributes
    ----------
    time : list of float
        Times [s] (at most :data:`HISTORY_POINTS` + 1, the last row included).
    coef : list of list of float
        The coefficients at those times, one list per time [nT; eddy terms nT·s].
    """

    time: list[float] = field(default_factory=list)
    coef: list[list[float]] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        """The JSON block.

        Returns
        -------
        dict
        """
        return {"time": list(self.time), "coef": list(self.coef)}

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> OnlineHistory | None:
        """The block read from a file (None for none).

        Parameters
        ----------
        d : dict or None

        Returns
        -------
        OnlineHistory or None
        """
        if d is None:
            return None
        return cls(list(d.get("time") or []), list(d.get("coef") or []))


@dataclass
class OnlineReport:
    """The report of ``compensate --online`` (its ``OUT.json``).

    Attributes
    ----------
    aeromag_version : str or None
        Version that wrote it.
    input : str
        The log.
    online : bool
        True: the report of an online fit.
    terms : list of str
        Model terms.
    coef : list of float
        The coefficients at the end of the log [nT; eddy terms nT·s].
    forgetting : float
        lambda of the estimate.
    derivative : str
        How the eddy terms' derivatives were taken (``central``, ``midpoint``, ``backward``).
    latency_samples : int
        Samples the output lags the input.
    coef_lowpass_hz : float or None
        Cut-off of the coefficients' low-pass [Hz].
    band_hz : list of float
        Fitting band [Hz].
    segments : list of SegmentRow
        Per segment: ``id``, ``n``, ``kept`` (True), ``scores`` (None), ``residual_std``
        [nT].
    metrics : CompensationMetrics
        Headline metrics (:func:`online_metrics`; ``coverage``, ``after_warmup`` and
        ``n_skipped`` in its ``extra``).
    convergence : ConvergenceSummary
        Where the fit had converged.
    history : OnlineHistory
        The coefficients at a coarse step.
    warnings : list or None
        What the run warned (filled when the report is written).
    extra : dict
        Keys this class does not know (written after the others).
    """

    aeromag_version: str | None = None
    input: str = "<log>"
    online: bool = True
    terms: list[str] = field(default_factory=list)
    coef: list[float] = field(default_factory=list)
    forgetting: float | None = None
    derivative: str | None = None
    latency_samples: int | None = None
    coef_lowpass_hz: float | None = None
    band_hz: list[float] = field(default_factory=list)
    segments: list[SegmentRow] = field(default_factory=list)
    metrics: CompensationMetrics = field(default_factory=CompensationMetrics)
    convergence: ConvergenceSummary = field(default_factory=ConvergenceSummary)
    history: OnlineHistory = field(default_factory=OnlineHistory)
    warnings: list[Any] | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The JSON document (``OUT.json``), keys in the files' order.

        Returns
        -------
        dict
        """
        d: dict[str, Any] = {} if self.aeromag_version is None else {
            "aeromag_version": self.aeromag_version}
        d.update(input=self.input, online=self.online, terms=list(self.terms),
                 coef=list(self.coef), forgetting=self.forgetting, derivative=self.derivative,
                 latency_samples=self.latency_samples, coef_lowpass_hz=self.coef_lowpass_hz,
                 band_hz=list(self.band_hz), segments=[s.to_dict() for s in self.segments],
                 metrics=self.metrics.to_dict(), convergence=self.convergence.to_dict(),
                 history=self.history.to_dict())
        if self.warnings is not None:
            d["warnings"] = self.warnings
        d.update(self.extra)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> OnlineReport:
        """An online ``OUT.json`` read back.

        Parameters
        ----------
        d : dict

        Returns
        -------
        OnlineReport
        """
        kw, extra = split_fields(cls, d)
        kw["segments"] = [SegmentRow.from_dict(s) for s in kw.get("segments") or []]
        kw["metrics"] = CompensationMetrics.from_dict(kw.get("metrics")) or CompensationMetrics()
        kw["convergence"] = (ConvergenceSummary.from_dict(kw.get("convergence"))
                             or ConvergenceSummary())
        kw["history"] = OnlineHistory.from_dict(kw.get("history")) or OnlineHistory()
        return cls(**kw, extra=extra)


def online_metrics(time_s: np.ndarray, mag: np.ndarray, mag_tl: np.ndarray,
                   segment: np.ndarray, cfg: CompensationConfig, forgetting: float,
                   source: str = "<log>", kept: np.ndarray | None = None,
                   ) -> tuple[CompensationMetrics, list[SegmentRow]]:
    """The online fit's metrics: the batch definition, on ``mag - mag_tl`` as written.

    The headline is exactly what ``aeromag report`` recomputes from OUT.csv
    (:func:`aeromag.qc.quality.contract_metrics`): ``mag`` and ``mag - mag_tl``
    (unfiltered, not the low-passed ``mag_comp``) band-passed once per continuous stretch in
    ``cfg.band_hz``, filter edges trimmed, over every sample (no segment is dropped online,
    so the warm-up of the recursive estimate is included).  Beside it, ``after_warmup``: the
    same band-passed fields, their standard deviations over the samples after the first
    memory of the estimate (``1 / (1 - forgetting)`` samples from the first sample).

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Times [s].
    mag, mag_tl : ndarray, shape (n,)
        Total field as compensated and the online interference [nT].
    segment : ndarray of int, shape (n,)
        Segment per sample (-1: none).
    cfg : CompensationConfig
        Band, order, trim, gap.
    forgetting : float
        lambda of the estimate (its memory sets the warm-up).
    source : str
        File name for messages.
    kept : ndarray of bool, shape (n,), optional
        The rows written with ``segment_kept`` true (all when omitted; ``--mark-unconverged``
        sets the unconverged rows false), for the ``kept_*`` figures, as the report reads
        them from OUT.csv.

    Returns
    -------
    metrics : CompensationMetrics
        :func:`aeromag.compensation.metrics.compensation_metrics` (``kept`` rows) plus, in
        its ``extra``, ``coverage`` (:data:`COVERAGE`) and ``after_warmup`` (``warmup_s`` [s],
        ``n_samples``, ``std_before_nT``, ``residual_std_nT``, ``improvement_ratio``; None
        when no band-passed sample is left after the warm-up).
    segments : list of SegmentRow
        Per segment: ``id``, ``n``, ``kept`` (True), ``scores`` (None), ``residual_std``
        (std of the headline's band-passed ``mag - mag_tl`` over the segment [nT]).
    """
    t = np.asarray(time_s, dtype=np.float64)
    after = np.asarray(mag, dtype=np.float64) - np.asarray(mag_tl, dtype=np.float64)
    st = find_stretches(t, np.isfinite(after), cfg.max_gap_s)  # as contract_metrics
    marked = kept is not None and not np.all(kept)
    kept = np.ones(len(t), dtype=bool) if kept is None else np.asarray(kept, dtype=bool)
    metrics, comp_bp = band_metrics(mag, after, t, st, cfg, kept=kept, source=source)
    metrics.extra["coverage"] = COVERAGE_MARKED if marked else COVERAGE
    fin_t = t[np.isfinite(after)]
    warmup_s = round(1.0 / (1.0 - forgetting) / sampling_rate(t), 6) if forgetting < 1 else 0.0
    post = t >= fin_t[0] + warmup_s  # (metrics were measured: some sample is finite)
    block = None
    if (post & np.isfinite(comp_bp)).any():
        w = compensation_metrics(mag, after, t, st, cfg, kept=post)
        block = {"warmup_s": warmup_s, "definition": "the headline's band-passed fields, std"
                 f" over the samples after the first {warmup_s:g} s",
                 **{k: getattr(w, f"kept_{k}") for k in ("std_before_nT", "residual_std_nT",
                                                         "improvement_ratio")},
                 "n_samples": w.n_samples}
    metrics.extra["after_warmup"] = block
    segments = []
    for s in np.unique(segment[segment >= 0]):
        m = (segment == s) & np.isfinite(comp_bp)
        segments.append(SegmentRow(int(s), int((segment == s).sum()), True, None,
                                   float(np.std(comp_bp[m])) if m.sum() > 1 else None))
    return metrics, segments


def convergence_summary(res: OnlineTLResult, time_s: np.ndarray, forgetting: float,
                        source: str, marked: bool) -> ConvergenceSummary:
    """OUT.json ``convergence``, and a warning for each change the fit had to re-converge from.

    Parameters
    ----------
    res : OnlineTLResult
        The online fit with its convergence check.
    time_s : ndarray, shape (n,)
        Times [s].
    forgetting : float
        lambda.
    source : str
        File name for messages.
    marked : bool
        Whether ``--mark-unconverged`` marked the rows.

    Returns
    -------
    ConvergenceSummary
        ``definition``, ``threshold``, ``window_s``, ``memory_s``, ``n_unconverged``,
        ``marked``, ``spans`` (``start_s``, ``end_s``, ``kind``, ``peak_nis_ratio``,
        ``n_samples``) and the median and 95th percentile of ``mag_tl_std`` over the
        converged and the unconverged rows [nT].
    """
    fs = sampling_rate(time_s)
    memory = 1.0 / (1.0 - forgetting) if forgetting < 1 else float(len(time_s))
    std = res.mag_tl_std

    def pct(mask: np.ndarray, q: float) -> float | None:
        v = std[mask & np.isfinite(std)]
        return round(float(np.percentile(v, q)), 6) if v.size else None

    changes = [s for s in res.spans if s.kind == "change"]
    for s in changes:
        log.warning("%s: the interference changed at %.1f s and the online fit re-converged "
                    "only at %.1f s: mag_tl and mag_comp over %.1f-%.1f s were issued before "
                    "convergence (a-priori residual up to %.0fx the log's level); %s", source,
                    s.start_s, s.end_s, s.start_s, s.end_s, np.sqrt(s.peak_nis_ratio),
                    "those rows have segment_kept false" if marked else
                    "mark_unconverged=True sets segment_kept false on them")
    return ConvergenceSummary(
        definition="windowed NIS of the band-passed a-priori residuals (their mean square,"
                   " standardised by the RLS prior variance, over window_s) divided by its"
                   " median over the log; above threshold the fit is not converged, and"
                   " neither is it for one memory after; the first memory is the warm-up",
        threshold=NIS_THRESHOLD, window_s=round(max(20, round(memory) // 10) / fs, 6),
        memory_s=round(memory / fs, 6), n_unconverged=int((~res.converged).sum()),
        marked=marked, spans=list(res.spans),
        mag_tl_std_nT={"converged_median": pct(res.converged, 50),
                       "converged_p95": pct(res.converged, 95),
                       "unconverged_median": pct(~res.converged, 50),
                       "unconverged_p95": pct(~res.converged, 95)},
    )


def compensate_online_frame(df: pd.DataFrame, cfg: CompensationConfig | None = None, *,
                            forgetting: float = DEFAULT_FORGETTING,
                            derivative: str = "central", source: str | None = None,
                            mark_unconverged: bool = False,
                            ) -> tuple[pd.DataFrame, OnlineReport, OnlineTLResult]:
    """Compensate a log in memory with the online TL fit.

    Parameters
    ----------
    df : DataFrame
        Log with ``time``, ``flux_x/y/z`` [nT] and ``mag`` [nT] (the fluxgate magnitude when
        absent).
    cfg : CompensationConfig, optional
        Band, terms, order, final low-pass, gap handling (screening options are not used).
    forgetting : float
        lambda, 0 < lambda <= 1.
    derivative : {"central", "midpoint", "backward"}
        See :class:`aeromag.compensation.online.OnlineTL`.
    source : str, optional
        File name for messages.
    mark_unconverged : bool
        Write ``segment_kept`` false on the rows issued before the fit converged (the
        warm-up and after a change of the interference: ``convergence.spans`` of the
        report); the ``kept_*`` metrics then leave them out.

    Returns
    -------
    data : DataFrame
        ``df`` plus ``mag_tl``, ``mag_tl_std`` (the fit's own one-sigma uncertainty of
        ``mag_tl``), ``tl_converged``, ``mag_comp``, ``segment``, ``segment_kept``.
    report : OnlineReport
        The OUT.json content (:meth:`OnlineReport.to_dict`).
    result : OnlineTLResult
    """
    cfg = cfg or CompensationConfig()
    src = source or str(df.attrs.get("source", "<log>"))
    lam = check_forgetting(forgetting)
    prep = prepare(df, cfg, source=src)
    est = OnlineTL(prep.fs, cfg.terms, forgetting=lam, band_hz=cfg.band_hz, order=cfg.order,
                   max_gap_s=cfg.max_gap_s, derivative=derivative,
                   coef_std=False)  # OUT.* carry mag_tl_std, not the coefficients' std
    p = len(est.terms)
    if int(prep.valid.sum()) <= p:
        raise InputError(f"{src}: only {int(prep.valid.sum())} usable samples for {p} terms; "
                         "the online fit needs many more than the number of terms")
    mag = np.where(prep.valid, prep.mag, np.nan)
    res = est.compensate(prep.time, prep.flux, mag)
    try:  # the batch fit's plausibility limit (cfg.max_interference of the Earth field)
        check_interference(res.mag_tl, prep.field_nT, cfg.max_interference, source=src,
                           fitted=True)
    except FitError as exc:
        head = str(exc).split(": this flight")[0]
        raise FitError(f"{head}: the online fit is not determined by this flight (too few "
                       "headings or manoeuvres within its memory); give a longer memory "
                       f"(a forgetting factor closer to 1 than forgetting={lam:g}), or "
                       "calibrate on a box flight and apply that model (model=MODEL; limit: "
                       "max_interference)") from None
    t = prep.time
    comp = prep.mag - res.mag_tl
    if cfg.filter_output:
        cut = cfg.lowpass_hz if cfg.lowpass_hz is not None else cfg.band_hz[1]
        comp_out = lowpass_stretches(comp, t, prep.stretch, cut, cfg.order, fs_hz=prep.fs)
    else:
        comp_out = comp
    out = df.copy(deep=False)
    out["mag_tl"] = res.mag_tl
    out["mag_tl_std"] = res.mag_tl_std
    out["tl_converged"] = res.converged
    out["mag_comp"] = comp_out
    seg = prep.segment
    missing = seg < 0
    out["segment"] = pd.arrays.IntegerArray(np.where(missing, 0, seg), missing)
    kept = res.converged.copy() if mark_unconverged else np.ones(len(seg), dtype=bool)
    out["segment_kept"] = kept
    metrics, segments = online_metrics(t, prep.mag, res.mag_tl, seg, cfg, lam, src,
                                       kept=kept if mark_unconverged else None)
    convergence = convergence_summary(res, t, lam, src, mark_unconverged)
    # The batch fit's checks, one implementation: warnings (OUT.json; an error with --strict).
    check_metrics(metrics, source=src, fitted=True, online=True)
    n = len(t)
    step = max(1, n // HISTORY_POINTS)
    idx = np.arange(0, n, step)
    if idx[-1] != n - 1:
        idx = np.r_[idx, n - 1]
    metrics.extra["n_skipped"] = int(res.skipped.sum())
    report = OnlineReport(
        aeromag_version=__version__, input=src, online=True, terms=list(est.terms),
        coef=res.coef.tolist(), forgetting=lam, derivative=derivative,
        latency_samples=LATENCY_SAMPLES[derivative], coef_lowpass_hz=est.coef_lowpass_hz,
        band_hz=list(cfg.band_hz), segments=segments, metrics=metrics,
        convergence=convergence,
        history=OnlineHistory(t[idx].tolist(), res.coef_history[idx].tolist()))
    return out, report, res


def compensate_online_file(log_path: str | os.PathLike[str], out_path: str | os.PathLike[str],
                           cfg: CompensationConfig | None = None, *,
                           forgetting: float = DEFAULT_FORGETTING, derivative: str = "central",
                           columns: dict[str, str] | None = None,
                           units: dict[str, str] | None = None, fmt: str | None = None,
                           mark_unconverged: bool = False) -> OnlineReport:
    """Read a log, compensate it online, write OUT.csv and OUT.json (both or neither).

    Parameters
    ----------
    log_path, out_path : path-like
        Input log and output CSV (the report goes to OUT.json).
    cfg : CompensationConfig, optional
        Band, terms, filter options.
    forgetting, derivative
        See :func:`compensate_online_frame`.
    columns, units : dict, optional
        Column map and unit conversions.
    fmt : str, optional
        Log format.
    mark_unconverged : bool
        See :func:`compensate_online_frame`.

    Returns
    -------
    OnlineReport
        The report; its ``warnings`` list every warning logged while the log was read and
        compensated (the metric checks' among them).
    """
    with output_set():  # the warnings of the whole run go to OUT.json, from Python too
        return frame_to_files(
            log_path, out_path, forgetting,
            lambda df: compensate_online_frame(df, cfg, forgetting=forgetting,
                                               derivative=derivative, source=str(log_path),
                                               mark_unconverged=mark_unconverged),
            columns=columns, units=units, fmt=fmt)
