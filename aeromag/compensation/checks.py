"""Checks of a compensation's headline metrics: one implementation for every command.

``aeromag compensate`` and ``aeromag calibrate`` (in memory or chunked, and
``compensate --online``) log each finding as a warning, so that it is recorded in the
report's ``warnings`` and ``--strict`` makes it an error; ``aeromag batch`` gives a file with
a finding the status ``warn`` from the same words (:func:`metric_warnings`).
"""

from __future__ import annotations

import logging
import math
from typing import Any

from .report_types import CompensationMetrics

log = logging.getLogger(__name__)

__all__ = ["IMPLAUSIBLE_RESIDUAL_NT", "check_metrics", "metric_warnings"]

#: Band-passed residual [nT] above which a compensated log is implausible (a survey's is
#: well under 1 nT; tens of nT mean a wrong model, unit or column).
IMPLAUSIBLE_RESIDUAL_NT = 50.0


def metric_warnings(metrics: CompensationMetrics, *, source: str | None = None,
                    fitted: bool = False, online: bool = False) -> list[str]:
    """What is wrong with a compensation's headline metrics (empty when nothing).

    Parameters
    ----------
    metrics : CompensationMetrics
        The report's ``metrics`` (``improvement_ratio`` [-], ``residual_std_nT`` [nT]).
    source : str, optional
        File name that starts every message.
    fitted : bool
        Whether the model was fitted on this very log (else a saved model was applied): only
        the advice of the improvement-ratio message differs.
    online : bool
        The metrics are the online (recursive) fit's: its advice is the estimate's memory and
        terms, not a calibration box.

    Returns
    -------
    list of str
        An improvement ratio below 1 (the compensation adds variation), or a residual that is
        missing, zero, or above :data:`IMPLAUSIBLE_RESIDUAL_NT`.
    """
    out = []
    ratio, resid = metrics.improvement_ratio, metrics.residual_std_nT
    if _finite(ratio) and ratio < 1.0:
        shown = _below_one(float(ratio))
        if online:
            out.append(f"the online fit leaves more band-passed variation than it removes"
                       f" (improvement ratio {shown} < 1): the recursive estimate chases"
                       " noise when the interference is small against the sensor noise or"
                       " the memory too short; try a longer memory (forgetting=0.9999),"
                       " fewer terms (terms=9), or the batch fit of the whole log")
        elif fitted:
            out.append(f"the fitted model leaves more band-passed variation than it removes"
                       f" (improvement ratio {shown} < 1): the fit is unreliable; calibrate"
                       " on a flight with maneuvers and apply that model")
        else:
            out.append(f"the model leaves more band-passed variation than it removes"
                       f" (improvement ratio {shown} < 1): it adds interference to this"
                       " log; check that the model is this aircraft's and the columns")
    if not _finite(resid):
        out.append("no residual could be computed (too few band-passed samples?)")
    elif resid <= 1e-6:
        out.append(f"residual std {resid:.3g} nT is implausibly small (a log too short for"
                   " the band-pass filter?)")
    elif resid > IMPLAUSIBLE_RESIDUAL_NT:
        out.append(f"residual std {resid:.4g} nT is implausible for a compensated survey"
                   f" (> {IMPLAUSIBLE_RESIDUAL_NT:g} nT): check the units of mag and of the"
                   " fluxgate, and the column map")
    if source:
        out = [f"{source}: {w}" for w in out]
    return out


def check_metrics(metrics: CompensationMetrics, *, source: str | None = None,
                  fitted: bool = False, online: bool = False) -> list[str]:
    """Log every finding of :func:`metric_warnings` as a warning; return them.

    Parameters
    ----------
    metrics, source, fitted, online
        As in :func:`metric_warnings`.

    Returns
    -------
    list of str
        The warnings logged.
    """
    found = metric_warnings(metrics, source=source, fitted=fitted, online=online)
    for w in found:
        log.warning("%s", w)
    return found


def _below_one(ratio: float) -> str:
    """``ratio`` (< 1) with the fewest significant digits (3 at least) that still read < 1."""
    for digits in range(3, 16):
        text = f"{ratio:.{digits}g}"
        if float(text) < 1.0:
            return text
    return repr(ratio)


def _finite(x: Any) -> bool:
    try:
        return x is not None and math.isfinite(float(x))
    except (TypeError, ValueError):
        return False
