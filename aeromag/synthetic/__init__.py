"""Simulators with ground truth: true oracles, they import no fitting or filtering code.

Modules: ``physics`` (Earth field, attitude, the TL interference written independently of
:mod:`aeromag.compensation`, dipoles, local geodesy), ``faults``, ``calibration``
(:func:`simulate_calibration`), ``survey`` (:func:`simulate_survey`, :func:`survey_plan`).
Writing the files is :func:`aeromag.workflows.simulate.write_simulation`.
"""

from __future__ import annotations

from .calibration import simulate_calibration
from .currents import add_current_interference, current_channels
from .physics import (
    CAL_HEADINGS_DEG,
    DEFAULT_ORIGIN,
    FAULT_KINDS,
    FIELD_SCALE_NT,
    MANEUVER_AMPLITUDE_DEG,
    MANEUVERS,
    MANOEUVRE_AMPLITUDE_DEG,
    MANOEUVRES,
    TERM_NAMES,
    EarthField,
    band_noise,
    body_field,
    default_aircraft_coef,
    dipole_field_ned,
    geodetic_to_local,
    gradient_by_stretch,
    local_to_geodetic,
    local_transformer,
    ned_to_body_dcm,
    stretch_ids,
    tl_interference,
    tl_terms,
)
from .survey import ROUNDING, round_log, simulate_survey, survey_plan

__all__ = [
    "CAL_HEADINGS_DEG",
    "DEFAULT_ORIGIN",
    "FAULT_KINDS",
    "FIELD_SCALE_NT",
    "MANEUVERS",
    "MANEUVER_AMPLITUDE_DEG",
    "MANOEUVRES",
    "TERM_NAMES",
    "EarthField",
    "add_current_interference",
    "current_channels",
    "band_noise",
    "body_field",
    "default_aircraft_coef",
    "dipole_field_ned",
    "geodetic_to_local",
    "gradient_by_stretch",
    "local_to_geodetic",
    "local_transformer",
    "ned_to_body_dcm",
    "round_log",
    "simulate_calibration",
    "simulate_survey",
    "stretch_ids",
    "survey_plan",
    "tl_interference",
    "tl_terms",
    "ROUNDING",
    "MANOEUVRE_AMPLITUDE_DEG",
]
