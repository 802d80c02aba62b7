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
from ..compensation.metrics import band_metrics, compensation_metrics
from ..compensation.online import LATENCY_SAMPLES, OnlineTL, OnlineTLResult
from ..compensation.prepare import prepare
from ..errors import FitError, InputError
from ..io.outputs import output_set
from ._frame_files import frame_to_files

log = logging.getLogger(__name__)

__all__ = ["compensate_online_file", "compensate_online_frame", "online_metrics",
           "DEFAULT_FORGETTING", "COVERAGE"]

#: Default forgetting factor of the online TL fit (memory about 1000 samples: 100 s at 10 Hz).
DEFAULT_FORGETTING = 0.999
#: Rows of the coefficient history kept in OUT.json.
HISTORY_POINTS = 200

#: What the online headline covers (OUT.json ``metrics.coverage``).
COVERAGE = ("every sample of the flight, the RLS warm-up included (no screening online: every"
            " segment is kept, so kept_* = all_*); metrics.after_warmup gives the same figures"
            " without the first warmup_s seconds (one memory, 1 / (1 - forgetting) samples)")


def online_metrics(time_s: np.ndarray, mag: np.ndarray, mag_tl: np.ndarray,
                   segment: np.ndarray, cfg: CompensationConfig, forgetting: float,
                   source: str = "<log>") -> tuple[dict[str, Any], list[dict[str, Any]]]:
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

    Returns
    -------
    metrics : dict
        :func:`aeromag.compensation.metrics.compensation_metrics` (all samples kept) plus
        ``coverage`` (:data:`COVERAGE`) and ``after_warmup`` (``warmup_s`` [s],
        ``n_samples``, ``std_before_nT``, ``residual_std_nT``, ``improvement_ratio``; None
        when no band-passed sample is left after the warm-up).
    segments : list of dict
        Per segment: ``id``, ``n``, ``kept`` (True), ``scores`` (None), ``residual_std``
        (std of the headline's band-passed ``mag - mag_tl`` over the segment [nT]).
    """
    t = np.asarray(time_s, dtype=np.float64)
    after = np.asarray(mag, dtype=np.float64) - np.asarray(mag_tl, dtype=np.float64)
    st = find_stretches(t, np.isfinite(after), cfg.max_gap_s)  # as contract_metrics
    kept = np.ones(len(t), dtype=bool)
    metrics, comp_bp = band_metrics(mag, after, t, st, cfg, kept=kept, source=source)
    metrics["coverage"] = COVERAGE
    fin_t = t[np.isfinite(after)]
    warmup_s = round(1.0 / (1.0 - forgetting) / sampling_rate(t), 6) if forgetting < 1 else 0.0
    post = t >= fin_t[0] + warmup_s  # (metrics were measured: some sample is finite)
    block = None
    if (post & np.isfinite(comp_bp)).any():
        w = compensation_metrics(mag, after, t, st, cfg, kept=post)
        block = {"warmup_s": warmup_s, "definition": "the headline's band-passed fields, std"
                 f" over the samples after the first {warmup_s:g} s",
                 **{k: w[f"kept_{k}"] for k in ("std_before_nT", "residual_std_nT",
                                                "improvement_ratio")},
                 "n_samples": w["n_samples"]}
    metrics["after_warmup"] = block
    segments = []
    for s in np.unique(segment[segment >= 0]):
        m = (segment == s) & np.isfinite(comp_bp)
        segments.append({"id": int(s), "n": int((segment == s).sum()), "kept": True,
                         "scores": None,
                         "residual_std": float(np.std(comp_bp[m])) if m.sum() > 1 else None})
    return metrics, segments


def compensate_online_frame(df: pd.DataFrame, cfg: CompensationConfig | None = None, *,
                            forgetting: float = DEFAULT_FORGETTING,
                            derivative: str = "central", source: str | None = None,
                            ) -> tuple[pd.DataFrame, dict[str, Any], OnlineTLResult]:
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

    Returns
    -------
    data : DataFrame
        ``df`` plus ``mag_tl``, ``mag_comp``, ``segment``, ``segment_kept``.
    report : dict
        The OUT.json content.
    result : OnlineTLResult
    """
    cfg = cfg or CompensationConfig()
    src = source or str(df.attrs.get("source", "<log>"))
    lam = check_forgetting(forgetting)
    prep = prepare(df, cfg, source=src)
    est = OnlineTL(prep.fs, cfg.terms, forgetting=lam, band_hz=cfg.band_hz, order=cfg.order,
                   max_gap_s=cfg.max_gap_s, derivative=derivative)
    p = len(est.terms)
    if int(prep.valid.sum()) <= p:
        raise InputError(f"{src}: only {int(prep.valid.sum())} usable samples for {p} terms; "
                         "the online fit needs many more than the number of terms")
    mag = np.where(prep.valid, prep.mag, np.nan)
    res = est.run(prep.time, prep.flux, mag)
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
    out["mag_comp"] = comp_out
    seg = prep.segment
    missing = seg < 0
    out["segment"] = pd.arrays.IntegerArray(np.where(missing, 0, seg), missing)
    out["segment_kept"] = np.ones(len(seg), dtype=bool)
    metrics, segments = online_metrics(t, prep.mag, res.mag_tl, seg, cfg, lam, src)
    # The batch fit's checks, one implementation: warnings (OUT.json; an error with --strict).
    check_metrics(metrics, source=src, fitted=True, online=True)
    n = len(t)
    step = max(1, n // HISTORY_POINTS)
    idx = np.arange(0, n, step)
    if idx[-1] != n - 1:
        idx = np.r_[idx, n - 1]
    report: dict[str, Any] = {
        "aeromag_version": __version__,
        "input": src,
        "online": True,
        "terms": list(est.terms),
        "coef": res.coef.tolist(),
        "forgetting": lam,
        "derivative": derivative,
        "latency_samples": LATENCY_SAMPLES[derivative],
        "coef_lowpass_hz": est.coef_lowpass_hz,
        "band_hz": list(cfg.band_hz),
        "segments": segments,
        "metrics": {**metrics, "n_skipped": int(res.skipped.sum())},
        "history": {"time": t[idx].tolist(), "coef": res.coef_history[idx].tolist()},
    }
    return out, report, res


def compensate_online_file(log_path: str | os.PathLike[str], out_path: str | os.PathLike[str],
                           cfg: CompensationConfig | None = None, *,
                           forgetting: float = DEFAULT_FORGETTING, derivative: str = "central",
                           columns: dict[str, str] | None = None,
                           units: dict[str, str] | None = None, fmt: str | None = None,
                           ) -> dict[str, Any]:
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

    Returns
    -------
    dict
        The report; its ``warnings`` list every warning logged while the log was read and
        compensated (the metric checks' among them).
    """
    with output_set():  # the warnings of the whole run go to OUT.json, from Python too
        return frame_to_files(
            log_path, out_path, forgetting,
            lambda df: compensate_online_frame(df, cfg, forgetting=forgetting,
                                               derivative=derivative, source=str(log_path)),
            columns=columns, units=units, fmt=fmt)
