"""The compensation pipeline: per-segment TL fits, PCA screening, refit, apply, filter.

Python API used by the command line and by notebooks::

    import aeromag as am
    res = am.calibrate(cal_df)               # fit + screening -> res.model, res.report
    out = am.compensate(survey_df, model=res.model)
    out.data[["mag", "mag_tl", "mag_comp"]]

Steps (patent M1, see ``shared/methods.md``):

1. direction cosines and ``|B|`` from the fluxgate; the measured total field is ``mag`` (or
   ``|B|`` when the log has no ``mag``);
2. continuous stretches (time gaps and long NaN gaps split them; short NaN gaps are
   interpolated) and segments (the ``line`` column, or fixed windows);
3. the TL design matrix with derivatives against real time within each stretch; the target and
   every column band-passed (zero-phase Butterworth) per stretch, filter edges trimmed;
4. per-segment normal equations; a pooled fit; per-segment fits shrunk toward the pool;
5. PCA screening of the per-segment coefficients (:mod:`aeromag.screening`), repeated with the
   pool of the kept set until the kept set is stable;
6. one refit on all kept segments; ``mag_tl = A @ coef`` (unfiltered, never re-centred: it is a
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import logging
from typing import Any

import numpy as np
import pandas as pd

from .. import __version__
from .apply import _apply, _check_plausible
from .config import CompensationConfig, _config_dict, _resolve_gap
from .fit import fit_model
from .model import TLModel
from .prepare import Prepared, prepare
from .result import CompensationResult
from .segments import segment_counts

log = logging.getLogger(__name__)


def compensate(
    df: pd.DataFrame, cfg: CompensationConfig | None = None, *, model: TLModel | None = None,
    source: str | None = None,
) -> CompensationResult:
    """Compensate a log: fit on the log itself (with screening) or apply a saved ``model``.

    Parameters
    ----------
    df : DataFrame
        Log with canonical columns.
    cfg : CompensationConfig, optional
        Options.
    model : TLModel, optional
        A saved model (``aeromag calibrate``); when given nothing is fitted and every segment
        counts as kept.
    source : str, optional
        File name for messages and the report.

    Returns
    -------
    CompensationResult
        ``data`` holds the output table, ``report`` the JSON report.
    """
    cfg = _resolve_gap(cfg or CompensationConfig(), df)
    prep = prepare(df, cfg, source=source)
    if model is None:
        fit = fit_model(df, cfg, prep=prep)
        kept_ids = np.array([s["id"] for s in fit.report["segments"] if s["kept"]], dtype=np.int64)
        data, metrics, comp_bp = _apply(df, fit.model, cfg, prep=prep, kept_segments=kept_ids,
                                        source=source, release_flux=True)
        _check_plausible(data, metrics, prep, cfg, fitted=True)
        report = dict(fit.report)
        report["metrics"] = metrics
        report["model_source"] = "fitted"
        report["qc"] = _qc_block(data, report, cfg, comp_bp, prep)
        fit.model.meta["metrics"] = metrics
        return CompensationResult(data, fit.model, report, fit.screen, fit.segment_table)
    data, metrics, comp_bp = _apply(df, model, cfg, prep=prep, kept_segments=None,
                                    source=source, release_flux=True)
    _check_plausible(data, metrics, prep, cfg, fitted=False)
    seg_ids, counts = segment_counts(prep.segment)
    report = {
        "aeromag_version": __version__,
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "source": prep.source,
        "terms": list(model.terms),
        "coef": [float(c) for c in model.coef],
        "scale_nT": model.scale_nT,
        "model_source": str(model.meta.get("path", "given")),
        "band_hz": list(cfg.band_hz),
        "sampling_rate_hz": prep.fs,
        "segments": [
            {"id": int(s), "n": int(c), "kept": True, "scores": None, "residual_std": None}
            for s, c in zip(seg_ids, counts, strict=True)
        ],
        "screening": {"enabled": False, "notes": ["a saved model was applied: nothing fitted"]},
        "metrics": metrics,
        "config": _config_dict(cfg),
    }
    report["qc"] = _qc_block(data, report, cfg, comp_bp, prep)
    by_seg = report["qc"].get("residual_std_by_segment_nT") or {}
    for e in report["segments"]:
        e["residual_std"] = by_seg.get(str(e["id"]))
    return CompensationResult(data, model, report, None, None)



def _qc_block(data: pd.DataFrame, report: dict[str, Any], cfg: CompensationConfig,
              comp_bp: np.ndarray | None = None, prep: Prepared | None = None) -> dict:
    """The ``qc`` block of a report (FOM only when ``cfg.fom``; fit diagnostics are in
    ``report["fit"]`` already, computed from the fit's own statistics).  ``comp_bp`` is the
    band-passed ``mag_comp`` of the metrics, reused rather than filtered again."""
    from ..qc import quality_metrics  # qc builds on this module: import here

    extra: dict[str, Any] = {}
    if comp_bp is not None and prep is not None:
        extra = {"comp_bp": comp_bp, "segment": prep.segment, "fs_hz": prep.fs}
    return quality_metrics(data, report, cfg, fit=False, detect=bool(cfg.fom),
                           base_metrics=report.get("metrics"), **extra)



def calibrate(
    df: pd.DataFrame, cfg: CompensationConfig | None = None, *, source: str | None = None,
) -> CompensationResult:
    """Fit and screen the model on a calibration log (what ``aeromag calibrate`` runs).

    The same as :func:`compensate` without a model, with the Figure of Merit on unless
    ``cfg.fom`` says otherwise.

    Parameters
    ----------
    df : DataFrame
        Calibration log with canonical columns.
    cfg : CompensationConfig, optional
        Options.
    source : str, optional
        File name for messages and the report.

    Returns
    -------
    CompensationResult
        ``model`` is the fitted model (its ``meta`` is the report), ``data`` the calibration
        log with the model applied.
    """
    cfg = cfg or CompensationConfig()
    if cfg.fom is None:
        cfg = dataclasses.replace(cfg, fom=True)
    return compensate(df, cfg, source=source)
