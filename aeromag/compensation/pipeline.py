"""The compensation pipeline: per-segment TL fits, PCA screening, refit, apply, filter.

Python API used by the command line and by notebooks::

    import aeromag as am
    res = am.calibrate(cal_df)               # fit + screening -> res.model, res.report
    out = am.compensate(survey_df, model=res.model)   # run_compensation + the qc block
    out.data[["mag", "mag_tl", "mag_comp"]]

Steps (patent M1, see ``shared/methods.md``):

1. direction cosines and ``|B|`` from the fluxgate; the measured total field is ``mag`` (or
   ``|B|`` when the log has no ``mag``, with a warning, or with ``--mag-from-fluxgate``);
2. continuous stretches (time gaps and long NaN gaps split them; short NaN gaps are
   interpolated) and segments (the ``line`` column, or fixed windows);
3. the TL design matrix with derivatives against real time within each stretch; the target and
   every column band-passed (zero-phase Butterworth) per stretch, filter edges trimmed;
4. per-segment normal equations; a pooled fit; per-segment fits shrunk toward the pool;
5. PCA screening of the per-segment coefficients (:mod:`aeromag.compensation.screening`),
   repeated with the pool of the kept set until the kept set is stable;
6. one refit on all kept segments; ``mag_tl = A @ coef`` (unfiltered, never re-centred: it is a
   property of the aircraft); ``mag_comp = mag - mag_tl``, low-pass filtered (level kept).

The functions here return the report without its ``qc`` block: quality control builds on the
compensation (:mod:`aeromag.qc`), and :func:`aeromag.compensate` (the public function, in
:mod:`aeromag.workflows.compensate`) adds it.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from .apply import _apply, check_plausible
from .config import CompensationConfig, refuse_unused_options, resolve_gap
from .extended_fit import extended_inputs_for, extended_result
from .fit import fit_result
from .model import TLModel
from .prepare import check_total_field, prepare
from .report import AppliedRun, applied_report
from .result import CompensationResult
from .segments import segment_counts

__all__ = ["calibrate", "run_compensation"]


def run_compensation(
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
        ``data`` holds the output table, ``report`` the report (without ``qc``).

    Raises
    ------
    InputError
        When ``cfg`` changes a setting this run cannot use, as the command line refuses it
        (:func:`~aeromag.compensation.config.unused_options`): a fit-only one (``ridge``,
        ``terms``, the screening's) with ``model``, a screening threshold (``noise_factor``...)
        with ``screen=False``, ``lowpass_hz`` with ``filter_output=False``.
    """
    cfg = cfg or CompensationConfig()
    refuse_unused_options(cfg, model=model is not None)  # as the command line does
    cfg = resolve_gap(cfg, df)
    prep = prepare(df, cfg, source=source)
    if model is None:
        inputs = extended_inputs_for(df, cfg, prep.source)
        fit = fit_result(prep, cfg) if inputs is None else extended_result(prep, cfg, inputs)
        kept_ids = np.array(fit.report.kept_ids(), dtype=np.int64)
        data, metrics, comp_bp = _apply(df, fit.model, cfg, prep=prep, kept_segments=kept_ids,
                                        source=source, release_flux=True)
        check_plausible(data, metrics, prep, cfg, fitted=True)
        report = dataclasses.replace(fit.report, metrics=metrics, model_source="fitted")
        fit.model.meta.report = report  # the model file is this report
        return CompensationResult(data, fit.model, report, fit.screen, fit.segment_table,
                                  fit=fit.fit, config=cfg, comp_bp_nT=comp_bp,
                                  segment=prep.segment, fs_hz=prep.fs)
    check_total_field(model, prep.mag_from_flux, prep.source)
    if model.extended is not None:  # the columns the model needs, before anything is computed
        from .extended import require_columns

        require_columns(df, model.extended.extras, prep.source,
                        "extras the model was fitted with: the log must log them too")
    data, metrics, comp_bp = _apply(df, model, cfg, prep=prep, kept_segments=None,
                                    source=source, release_flux=True)
    check_plausible(data, metrics, prep, cfg, fitted=False)
    seg_ids, counts = segment_counts(prep.segment)
    report = applied_report(AppliedRun(prep.source, model, cfg, prep.fs,
                                       dict(zip(seg_ids.tolist(), counts.tolist(), strict=True)),
                                       metrics))
    if model.extended is not None:
        report.extended = model.extended.summary()
    return CompensationResult(data, model, report, None, None, config=cfg, comp_bp_nT=comp_bp,
                              segment=prep.segment, fs_hz=prep.fs)


def calibrate(
    df: pd.DataFrame, cfg: CompensationConfig | None = None, *, source: str | None = None,
) -> CompensationResult:
    """Fit and screen the model on a calibration log (what ``aeromag calibrate`` runs).

    The same as :func:`run_compensation` without a model, with the Figure of Merit on unless
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
        ``model`` is the fitted model (its ``meta.report`` is the report), ``data`` the calibration
        log with the model applied.
    """
    cfg = cfg or CompensationConfig()
    if cfg.fom is None:
        cfg = dataclasses.replace(cfg, fom=True)
    return run_compensation(df, cfg, source=source)
