"""The report's headline, computed from the compensated log it shows, checked against OUT.json.

``aeromag report OUT.csv`` once took its improvement ratio and residual from OUT.json (the
sidecar of ``compensate``/``calibrate``) without looking at the CSV: a CSV whose ``mag_tl`` had
been zeroed, or with lines cut out, still showed OUT.json's numbers.  Here the headline is
recomputed from the log's own columns with the library's one implementation
(:func:`aeromag.qc.quality.contract_metrics`, i.e.
:func:`aeromag.compensation.metrics.compensation_metrics` of ``mag - mag_tl``), after the same
preparation of the total field as the compensation did
(:func:`aeromag.qc.total_field.prepared_total_field`: short gaps interpolated, or the fluxgate
magnitude), so that an unmodified output reproduces
OUT.json's figures; the recorded figures are shown beside it and a disagreement beyond
:data:`REL_TOL` (:data:`REL_TOL_ONLINE` for ``--online`` outputs,
:data:`REL_TOL_FLUXGATE` when the fluxgate magnitude is the total field) or any difference in the
sample counts is a one-line warning.  See ``docs/qc.md`` for the measured differences the
tolerances rest on.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from .._core.filters import lowpass_stretches, sampling_rate
from ..compensation.apply import missing_total_field
from ..compensation.config import CompensationConfig
from ..compensation.metrics import residual_metrics, run_blocks, stretch_runs
from ..compensation.report_types import (
    CompensationMetrics,
    CompensationReport,
    HeadlineCheck,
    HeadlineDifference,
    MagCompCheck,
)
from ..compensation.result import CompensationResult
from ..errors import InputError
from ..qc import kept_mask, segment_labels
from ..qc.quality import config_of
from ..qc.total_field import prepared_total_field

__all__ = ["MAG_COMP_TOL_NT", "MAG_COMP_TOL_FLUXGATE_NT", "REL_TOL", "REL_TOL_FLUXGATE",
           "REL_TOL_ONLINE", "HeadlineRecord", "check_mag_comp", "compare_headline",
           "headline_from_data", "headline_record", "log_kind"]

log = logging.getLogger(__name__)

#: Relative tolerance between the headline computed from the log and OUT.json's (batch
#: outputs).  Measured on every shipped sample and simulator log, in memory, chunked, CSV,
#: XYZ and Parquet, with NaN gaps, dropped rows and truncated rows: at most 5.2e-15.
REL_TOL = 1e-6

#: The same for ``compensate --online`` outputs: their OUT.json headline is the batch
#: definition on ``mag - mag_tl`` over every sample (the RLS warm-up included, like the
#: report's recomputation); measured 0 (exactly equal) on the shipped calibration and survey,
#: two hand-made flights and a simulator log, filtered and ``--no-filter`` (before, when it
#: was of the low-passed ``mag_comp``: 5.5e-4 to 7.4e-2, tolerance 0.15).
REL_TOL_ONLINE = 1e-6

#: The same when the fluxgate magnitude is the total field: the report reads the fluxgate
#: columns in single precision (``_report_read``); measured 5.8e-5 to 1.1e-4.
REL_TOL_FLUXGATE = 1e-3

#: The float figures compared (kept segments, then all data).
_COMPARED = ("improvement_ratio", "residual_std_nT", "std_before_nT",
             "all_improvement_ratio", "all_residual_std_nT", "all_std_before_nT")

#: The sample counts compared (equal on every unmodified output measured).
_COUNTS = ("n_samples", "all_n_samples")

#: What a disagreement most likely means (``{kind}``: :func:`log_kind` of the file).
LIKELY_CAUSE = "{kind} was changed after compensation, or OUT.json belongs to another run"

#: Largest difference [nT] allowed between a log's ``mag_comp`` and the one the compensation
#: writes from the log's own ``mag`` and ``mag_tl`` with OUT.json's filter settings
#: (:func:`check_mag_comp`); see ``docs/qc.md`` for the differences measured on unmodified
#: outputs.
MAG_COMP_TOL_NT = 1e-3

#: The same when the fluxgate magnitude is the total field (read in single precision).
MAG_COMP_TOL_FLUXGATE_NT = 0.02


def log_kind(source: str) -> str:
    """The kind of a log file in words, for a warning ("the CSV", "the Parquet file" ...).

    Parameters
    ----------
    source : str
        File name.

    Returns
    -------
    str
        ``"the CSV"``, ``"the Parquet file"``, ``"the XYZ file"``, ``"the HDF5 file"`` or
        ``"the log"``.
    """
    suffix = source.rsplit(".", 1)[-1].lower() if "." in source else ""
    return {"csv": "the CSV", "parquet": "the Parquet file", "pq": "the Parquet file",
            "xyz": "the XYZ file", "h5": "the HDF5 file", "hdf5": "the HDF5 file"
            }.get(suffix, "the log")


def compare_headline(computed: CompensationMetrics, recorded: CompensationMetrics | None, *,
                     online: bool = False, fluxgate: bool = False, source: str = "OUT.csv",
                     recorded_in: str = "OUT.json") -> HeadlineCheck:
    """Compare the headline computed from the log with the one recorded in its report.

    Parameters
    ----------
    computed : CompensationMetrics
        Metrics computed from the log (``compensation_metrics``).
    recorded : CompensationMetrics or None
        The report's ``metrics`` (None or without ``all_*``: nothing to compare).
    online : bool
        The report is of ``compensate --online`` (tolerance :data:`REL_TOL_ONLINE`).
    fluxgate : bool
        The fluxgate magnitude is the total field (tolerance :data:`REL_TOL_FLUXGATE`).
    source, recorded_in : str
        File names for the warning.

    Returns
    -------
    HeadlineCheck
        ``compared``, ``agree`` (None when not compared), ``relative_tolerance``,
        ``max_relative_difference``, ``differences`` (per figure: ``computed``,
        ``recorded``, ``relative``), ``warning`` (one line, or None), ``recorded_in``.
    """
    tol = REL_TOL_ONLINE if online else REL_TOL_FLUXGATE if fluxgate else REL_TOL
    out = HeadlineCheck(compared=False, agree=None, relative_tolerance=tol, counts="equal",
                        recorded_in=recorded_in, warning=None,
                        definition="the headline is computed from the log's columns; the"
                        " recorded figures are the report's metrics block")
    if recorded is None or any(getattr(recorded, k) is None for k in _COMPARED + _COUNTS):
        out.note = f"{recorded_in} has no metrics to compare"
        return out
    diffs: dict[str, HeadlineDifference] = {}
    worst = 0.0
    bad: list[str] = []
    for k in _COMPARED:
        a, b = getattr(computed, k), getattr(recorded, k)
        rel = _rel(a, b)
        diffs[k] = HeadlineDifference(computed=a, recorded=b, relative=rel)
        worst = max(worst, rel)
        if rel > tol:
            bad.append(k)
    for k in _COUNTS:
        a, b = getattr(computed, k), getattr(recorded, k)
        diffs[k] = HeadlineDifference(computed=a, recorded=b, relative=_rel(a, b))
        if a != b:
            bad.append(k)
    out.compared, out.agree = True, not bad
    out.max_relative_difference, out.differences = worst, diffs
    if bad:
        out.warning = (
            f"{source}: the headline computed from this log (improvement ratio"
            f" {_g(computed.improvement_ratio)}, residual {_g(computed.residual_std_nT)}"
            f" nT, {computed.n_samples} samples) disagrees with {recorded_in}"
            f" ({_g(recorded.improvement_ratio)}, {_g(recorded.residual_std_nT)} nT,"
            f" {recorded.n_samples} samples; differing: {', '.join(bad)}; tolerance {tol:g}"
            f" relative, sample counts exact): {LIKELY_CAUSE.format(kind=log_kind(source))}")
    return out


def _rel(a: Any, b: Any) -> float:
    """|a - b| / |b| (0 for equal values, inf when one is missing or not finite)."""
    if a is None or b is None:
        return 0.0 if a is None and b is None else math.inf
    a, b = float(a), float(b)
    if a == b or (math.isnan(a) and math.isnan(b)):
        return 0.0
    if not (math.isfinite(a) and math.isfinite(b)):
        return math.inf
    return abs(a - b) / abs(b) if b != 0 else math.inf


def _g(v: Any) -> str:
    return "–" if v is None else f"{float(v):.4g}"


class _MagCompCheck:
    """:func:`check_mag_comp`'s comparison, accumulated over blocks of whole stretches.

    Called as ``check(a, b, comp, labels)`` for rows ``a:b`` (``comp = mag - mag_tl`` there,
    ``labels`` the block's stretch labels); :meth:`result` then gives the check's record.
    Each filter choice keeps its rows compared, largest difference and first row beyond the
    tolerance, so no full-length expected or difference array exists.
    """

    def __init__(self, data: pd.DataFrame, report: CompensationReport,
                 cfg: CompensationConfig, time_s: np.ndarray, fs_hz: float, source: str,
                 recorded_in: str) -> None:
        fluxgate = bool(report.mag_from_fluxgate) or "mag" not in data.columns
        self.tol = MAG_COMP_TOL_FLUXGATE_NT if fluxgate else MAG_COMP_TOL_NT
        # An --online OUT.json records no configuration: whether mag_comp was low-passed
        # (--no-filter) is then not known, and mag_comp may match either.
        self.recorded = report.config is not None and report.config.filter_output is not None
        self.choices = (bool(cfg.filter_output),) if self.recorded else (False, True)
        self.t, self.fs, self.cfg = time_s, fs_hz, cfg
        self.cut = cfg.lowpass_hz if cfg.lowpass_hz is not None else cfg.band_hz[1]
        self.no_mag = missing_total_field(data, fluxgate)
        self.have = data["mag_comp"].to_numpy(dtype=np.float64)
        self.source, self.recorded_in = source, recorded_in
        self.n = dict.fromkeys(self.choices, 0)
        self.worst = dict.fromkeys(self.choices, 0.0)
        self.first: dict[bool, int | None] = dict.fromkeys(self.choices, None)
        self.error: dict[bool, InputError] = {}

    def __call__(self, a: int, b: int, comp: np.ndarray, labels: np.ndarray) -> None:
        have = self.have[a:b]
        for filt in self.choices:
            if filt in self.error:
                continue
            if filt:
                try:
                    diff = lowpass_stretches(comp, self.t[a:b], labels, self.cut,
                                             self.cfg.order, fs_hz=self.fs)
                except InputError as exc:
                    self.error[filt] = exc
                    continue
                np.subtract(have, diff, out=diff)
            else:
                diff = np.subtract(have, comp)
            np.abs(diff, out=diff)
            if self.no_mag is not None:
                diff[self.no_mag[a:b]] = np.nan
            fin = np.isfinite(diff)
            k = int(fin.sum())
            if k:
                self.n[filt] += k
                self.worst[filt] = max(self.worst[filt], float(diff[fin].max()))
                if self.first[filt] is None:
                    over = diff > self.tol
                    if over.any():
                        self.first[filt] = a + int(np.argmax(over))

    def result(self) -> MagCompCheck:
        """The check's record (see :func:`check_mag_comp`)."""
        tol, recorded = self.tol, self.recorded
        out = MagCompCheck(compared=0, tolerance_nT=tol, filtered=self.choices[0],
                           filter_recorded=recorded)
        best: tuple[float, bool, int | None] | None = None
        for filt in self.choices:  # the unfiltered field first when the file does not say
            if filt in self.error:
                out.note = f"mag_comp not checked against the low-pass: {self.error[filt]}"
                continue
            out.compared = self.n[filt]
            worst = self.worst[filt]
            if best is None or worst < best[0]:
                best = (worst, filt, self.first[filt])
            if worst <= tol:
                break
        if best is None or not out.compared:
            return out
        worst, filt, first = best
        out.max_abs_difference_nT, out.filtered = worst, filt
        if worst > tol:
            i = int(first or 0)
            out.first_row = i
            what = (f"mag - mag_tl low-passed at {self.cut:g} Hz" if filt and recorded
                    else "mag - mag_tl (unfiltered)" if recorded
                    else "mag - mag_tl, unfiltered or low-passed,")
            out.warning = (
                f"{self.source}: column 'mag_comp' differs from {what} as {self.recorded_in}"
                f" records it by up to {_g(worst)} nT (first at data row {i + 1}; tolerance"
                f" {tol:g} nT): {LIKELY_CAUSE.format(kind=log_kind(self.source))}; the"
                " compensated-field figures draw this column")
        return out


def check_mag_comp(data: pd.DataFrame, comp: np.ndarray, report: CompensationReport,
                   cfg: CompensationConfig, *, source: str = "OUT.csv",
                   recorded_in: str = "OUT.json") -> MagCompCheck:
    """Compare the log's ``mag_comp`` with what the compensation writes from its columns.

    The expected ``mag_comp`` is ``mag - mag_tl`` (``comp``, the total field prepared as the
    compensation did), low-passed per stretch with each dropped segment on its own
    (:func:`aeromag.compensation.apply.isolate_dropped`, the same filter and cut-off as
    :func:`aeromag.compensation.apply.apply_model`) unless ``cfg.filter_output`` is False,
    and empty where the log has no measured total field.  Only rows where both are finite
    are compared.  The work is done in blocks of whole stretches
    (:func:`aeromag.compensation.metrics.run_blocks`); :func:`headline_from_data` makes the
    same check inside the headline's own pass over the blocks.

    Parameters
    ----------
    data : DataFrame
        The compensated log (``time`` [s], ``mag_comp`` [nT], ``segment``, ``segment_kept``).
    comp : ndarray
        ``mag - mag_tl`` per row [nT] (not changed).
    report : CompensationReport
        Its report (``mag_from_fluxgate``).
    cfg : CompensationConfig
        Filter settings recorded in the report (``filter_output``, ``lowpass_hz``,
        ``band_hz``, ``order``, ``max_gap_s``).
    source, recorded_in : str
        File names for the warning.

    Returns
    -------
    MagCompCheck
        ``compared`` (rows compared), ``max_abs_difference_nT``, ``tolerance_nT``,
        ``first_row`` (0-based data row of the first difference beyond the tolerance, or
        None), ``filtered`` and ``warning`` (one line, or None).
    """
    t = data["time"].to_numpy(dtype=np.float64)
    comp = np.asarray(comp, dtype=np.float64)
    check = _MagCompCheck(data, report, cfg, t, sampling_rate(t), source, recorded_in)
    starts, stops = stretch_runs(t, comp, np.broadcast_to(0.0, comp.shape), _segments(data),
                                 kept_mask(data), cfg.max_gap_s)
    for a, b, lab in run_blocks(starts, stops):
        check(a, b, comp[a:b], lab)
    return check.result()


def _segments(data: pd.DataFrame) -> np.ndarray:
    """:func:`aeromag.qc.segment_labels`'s values, without its int64 copy.

    The column itself when it is a plain integer column (the report's reader gives int32).
    """
    col = data["segment"] if "segment" in data.columns else None
    if col is not None and isinstance(col.dtype, np.dtype) and col.dtype.kind == "i":
        return col.to_numpy()
    return segment_labels(data)


def _float_column(data: pd.DataFrame, name: str) -> np.ndarray:
    """A float column as stored (float32 or float64, no copy), else as float64.

    ``mag - col`` is the same in both: numpy widens float32 to float64 exactly.
    """
    v = data[name].to_numpy()
    return v if v.dtype in (np.float32, np.float64) else data[name].to_numpy(dtype=np.float64)


def headline_from_data(result: CompensationResult,
                       config: CompensationConfig | None = None) -> CompensationResult:
    """The result with its headline metrics computed from its data, OUT.json's kept beside.

    The metrics are :func:`aeromag.qc.quality.contract_metrics`'s, bit for bit, computed by
    :func:`aeromag.compensation.metrics.residual_metrics` in blocks of whole stretches
    (one pass, which also makes the ``mag_comp`` check, :func:`check_mag_comp`), so that
    no full-length temporary is made beyond the prepared total field and one packed array.

    Parameters
    ----------
    result : CompensationResult
        A compensation (in memory, or read back by
        :func:`aeromag.workflows.report.load_compensated`).
    config : CompensationConfig, optional
        Its configuration (default: the result's, else the report's).

    Returns
    -------
    CompensationResult
        A copy whose report's ``metrics`` are computed from ``data`` (``mag`` and
        ``mag - mag_tl`` band-passed once, kept segments first), with the report's own block
        as ``recorded_metrics`` and the comparison (:func:`compare_headline`) as
        ``headline_check``; the caller's result is not changed.  A disagreement is logged
        as one warning.

    Raises
    ------
    InputError
        The log has no ``mag_tl`` (the headline is of ``mag - mag_tl``), or is too short
        to measure.
    """
    data, report = result.data, result.report
    src = str(data.attrs.get("source") or report.source or "<log>")
    if "mag_tl" not in data.columns:
        raise InputError(f"{src}: no mag_tl column: the headline metrics are of mag - mag_tl,"
                         " so this log must be the output of `aeromag compensate` as written;"
                         f" run `aeromag compensate LOG -o {src}` first")
    cfg = config or result.config or config_of(report)
    rj = str(data.attrs.get("report_json") or "OUT.json")
    t = data["time"].to_numpy(dtype=np.float64)
    fs_error: InputError | None = None
    try:  # first: its median's temporaries come before the full-length arrays
        fs = sampling_rate(t)
    except InputError as exc:
        fs, fs_error = math.nan, exc
    mag = prepared_total_field(data, report, cfg)  # ours: residual_metrics overwrites it
    tl = _float_column(data, "mag_tl")
    check = (_MagCompCheck(data, report, cfg, t, fs, src, rj)
             if "mag_comp" in data.columns and fs_error is None else None)
    try:
        if fs_error is not None:
            raise fs_error
        kept = kept_mask(data)
        starts, stops = stretch_runs(t, mag, tl, _segments(data), kept, cfg.max_gap_s)
        computed = residual_metrics(t, mag, tl, starts, stops, cfg, kept, fs_hz=fs,
                                    visit=check)
    except InputError as exc:
        raise InputError(str(exc).replace("<log>", src, 1)) from None
    finally:
        del mag
    comp_check = check.result() if check is not None else None
    del t, tl, kept, starts, stops, check
    recorded = report.metrics
    fluxgate = bool(report.mag_from_fluxgate) or "mag" not in data.columns
    check_ = compare_headline(computed, recorded, online=bool(report.extra.get("online")),
                              fluxgate=fluxgate, source=src, recorded_in=rj)
    if check_.warning:
        log.warning("%s", check_.warning)
    if comp_check is not None:
        check_.mag_comp = comp_check
        if comp_check.warning:
            log.warning("%s", comp_check.warning)
    report = dataclasses.replace(report, metrics=computed, headline_check=check_,
                                 recorded_metrics=recorded or report.recorded_metrics)
    return dataclasses.replace(result, report=report)


@dataclass
class HeadlineRecord:
    """What :func:`headline_from_data` adds to ``qc.json`` (:func:`headline_record`).

    Attributes
    ----------
    headline_check : HeadlineCheck or None
        The comparison of the recomputed headline with the recorded one.
    compensation_metrics : CompensationMetrics or None
        OUT.json's metrics block, as the compensation computed it (None when the report
        recorded none).
    """

    headline_check: HeadlineCheck | None = None
    compensation_metrics: CompensationMetrics | None = None

    def to_dict(self) -> dict[str, Any]:
        """The keys it adds to ``qc.json`` (those that are set).

        Returns
        -------
        dict
        """
        return {k: v.to_dict() for k, v in (("headline_check", self.headline_check),
                                            ("compensation_metrics", self.compensation_metrics))
                if v is not None}


def headline_record(report: CompensationReport) -> HeadlineRecord:
    """What :func:`headline_from_data` adds to ``qc.json`` (nothing for other reports).

    Parameters
    ----------
    report : CompensationReport
        A report returned in :func:`headline_from_data`'s result.

    Returns
    -------
    HeadlineRecord
        ``headline_check`` and, when the report recorded metrics, ``compensation_metrics``
        (OUT.json's block, as the compensation computed it).
    """
    return HeadlineRecord(report.headline_check, report.recorded_metrics)
