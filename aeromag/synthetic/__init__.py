"""Simulators with ground truth: true oracles, they import no fitting or filtering code.

Modules: ``physics`` (Earth field, attitude, the TL interference written independently of
:mod:`aeromag.compensation`, dipoles, local geodesy), ``faults``, ``calibration``
(:func:`simulate_calibration`), ``survey`` (:func:`simulate_survey`, :func:`survey_plan`),
``mission`` (:func:`simulate_mission`), ``compass`` (:func:`simulate_compass`), ``online_tl``
(:func:`simulate_online_tl`), ``quadrotor`` (:func:`simulate_quadrotor`), ``level_survey``
(:func:`simulate_level_survey`) and ``benchmarks`` (the filtering benchmarks:
:func:`simulate_growth`, the univariate growth model, and :func:`simulate_cstr`, the stirred-tank
reactor).  Writing the files is :func:`aeromag.workflows.write_simulation` (and its siblings).
"""

from __future__ import annotations

from .benchmarks import simulate_cstr, simulate_growth
from .calibration import simulate_calibration
from .compass import simulate_compass
from .currents import add_current_interference, current_channels
from .level_survey import level_survey_anomaly, simulate_level_survey
from .mission import simulate_mission
from .online_tl import simulate_online_tl
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
from .quadrotor import simulate_quadrotor
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
    "simulate_compass",
    "simulate_cstr",
    "simulate_growth",
    "level_survey_anomaly",
    "simulate_level_survey",
    "simulate_mission",
    "simulate_online_tl",
    "simulate_quadrotor",
    "simulate_survey",
    "stretch_ids",
    "survey_plan",
    "tl_interference",
    "tl_terms",
    "ROUNDING",
    "MANOEUVRE_AMPLITUDE_DEG",
]
