"""Compensation quality control: noise, manoeuvres, Figure of Merit, fit diagnostics.

Modules (see ``docs/qc.md``):

* :mod:`~aeromag.qc.noise` - band-passed series, fourth-difference noise, grouped std;
* :mod:`~aeromag.qc.maneuvers` - heading legs and pitch/roll/yaw manoeuvres;
* :mod:`~aeromag.qc.fom` - the Figure of Merit per manoeuvre and per box;
* :mod:`~aeromag.qc.diagnostics` - condition numbers, VIF, leave-one-segment-out CV;
* :mod:`~aeromag.qc.quality` - :func:`compute_qc`, everything for one compensated log;
* :mod:`~aeromag.qc.summaries`, :mod:`~aeromag.qc.fom_types` - the typed blocks of its
  :class:`QCMetrics` (``to_dict``/``from_dict`` at the JSON edge).

``qc`` builds on :mod:`aeromag.compensate` (never the reverse).
"""

from __future__ import annotations

from .diagnostics import (
    FitDiagnostics,
    diagnostics_from_stats,
    fit_diagnostics,
    loso_cv,
    variance_inflation,
)
from .fom import fom_summary, fom_table
from .fom_types import FomBox, FomManeuver, FomSummary, FomTableRow
from .labels import kept_mask, segment_labels
from .maneuvers import CARDINALS, MANEUVERS, ManeuverResult, detect_heading_legs, detect_maneuvers
from .noise import FOURTH_DIFF_NORM, band_passed, fourth_difference_noise, grouped_std
from .quality import QCMetrics, QCResult, compute_qc, quality_metrics
from .summaries import (
    ManeuverSummary,
    NoiseSummary,
    PerPieceRms,
    PieceRms,
    QCSegmentRow,
    RmsSummary,
)

__all__ = [
    "CARDINALS",
    "FOURTH_DIFF_NORM",
    "MANEUVERS",
    "FitDiagnostics",
    "FomBox",
    "FomManeuver",
    "FomSummary",
    "FomTableRow",
    "ManeuverResult",
    "ManeuverSummary",
    "NoiseSummary",
    "PerPieceRms",
    "PieceRms",
    "QCMetrics",
    "QCResult",
    "QCSegmentRow",
    "RmsSummary",
    "band_passed",
    "compute_qc",
    "detect_heading_legs",
    "detect_maneuvers",
    "diagnostics_from_stats",
    "fit_diagnostics",
    "fom_summary",
    "fom_table",
    "fourth_difference_noise",
    "grouped_std",
    "kept_mask",
    "loso_cv",
    "quality_metrics",
    "segment_labels",
    "variance_inflation",
]
