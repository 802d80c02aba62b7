"""Vector-magnetometer calibration (12 parameters: soft-iron matrix and hard-iron offset)
against the expected Earth field, online by recursive least squares with forgetting.

Modules: ``reference`` (the Earth field: IGRF-14 via ``ppigrf``, or explicit), ``calibration``
(:class:`CompassCalibration`, the tilt-compensated heading, the excitation indicator),
``heading_stats`` (the heading error's statistics) and ``report`` (:class:`CompassReport`, what
``aeromag compass`` writes).
"""

from __future__ import annotations

from .calibration import (
    EXCITATION_THRESHOLD,
    CompassCalibration,
    CompassResult,
    ExcitationWindow,
    attitude_at_samples,
    calibrate_compass,
    compass_heading,
    convergence_time,
    excitation_windows,
    reference_in_body,
)
from .heading_stats import HeadingErrorStats, heading_error_stats
from .reference import IGRF_RANGE, ReferenceField, explicit_field, igrf_field
from .report import CompassHistory, CompassMetrics, CompassReport, ExcitationSummary

__all__ = ["EXCITATION_THRESHOLD", "IGRF_RANGE", "CompassCalibration", "CompassHistory",
           "CompassMetrics", "CompassReport", "CompassResult", "ExcitationSummary",
           "ExcitationWindow", "HeadingErrorStats", "ReferenceField", "attitude_at_samples",
           "calibrate_compass", "compass_heading", "convergence_time", "excitation_windows",
           "explicit_field", "heading_error_stats", "igrf_field", "reference_in_body"]
