"""aeromag: post-processing of aeromagnetic surveys flown by aircraft and multirotor UAVs.

The public API is flat::

    import aeromag as am
    df = am.read_log("survey.csv")
    res = am.compensate(df)                  # fit on the survey itself, screen, apply
    model = am.calibrate(am.read_log("calibration.csv")).model
    out = am.compensate(df, model=model)

Every public name is listed in ``__all__`` (``docs/api.md``); names are imported on first use,
so ``import aeromag`` (and ``aeromag --help``) stays fast.  Everything else lives in the
packages (``aeromag.compensation``, ``aeromag.io``, ...) or is private.
"""

from __future__ import annotations

import importlib
from typing import Any

from .errors import AeromagError, FitError, InputError

__version__ = "0.1.0"

#: Public name -> module that defines it.  Other families add their names here (one line each).
_API: dict[str, str] = {
    # reading and writing logs
    "read_log": "aeromag.io",
    "write_csv": "aeromag.io",
    # compensation
    "CompensationConfig": "aeromag.compensation.config",
    "CompensationResult": "aeromag.compensation.result",
    "TLModel": "aeromag.compensation.model",
    "TollesLawson": "aeromag.compensation.estimator",
    "compensate": "aeromag.workflows.compensate",
    "calibrate": "aeromag.workflows.compensate",
    "fit_model": "aeromag.compensation.fit",
    "apply_model": "aeromag.compensation.apply",
    "compensation_metrics": "aeromag.compensation.metrics",
    "design_matrix": "aeromag.compensation.terms",
    "parse_terms": "aeromag.compensation.terms",
    "TERMS_16": "aeromag.conventions",
    "compensate_file": "aeromag.workflows.compensate",
    "calibrate_file": "aeromag.workflows.compensate",
    "apply_model_chunked": "aeromag.workflows.chunked",
    # simulators
    "simulate_calibration": "aeromag.synthetic",
    "simulate_survey": "aeromag.synthetic",
    "survey_plan": "aeromag.synthetic",
    "write_simulation": "aeromag.workflows.simulate",
    # quality control
    "compute_qc": "aeromag.qc",
    "QCResult": "aeromag.qc",
    "detect_maneuvers": "aeromag.qc",
    "fom_table": "aeromag.qc",
    "plot_pca_scores": "aeromag.plot.compensation",
    "plot_explained_variance": "aeromag.plot.compensation",
    "plot_timeseries": "aeromag.plot.compensation",
    "plot_residuals": "aeromag.plot.compensation",
    "plot_psd": "aeromag.plot.compensation",
    "plot_term_contributions": "aeromag.plot.compensation",
    "plot_fom": "aeromag.plot.compensation",
    "plot_map": "aeromag.plot.compensation",
    "write_report": "aeromag.workflows.report",
    "build_report": "aeromag.workflows.report",
    "load_compensated": "aeromag.workflows.report",
    # track check
    "check_track": "aeromag.track",
    "TrackResult": "aeromag.track",
    "LegModel": "aeromag.track.leg_model",
    "read_plan": "aeromag.io.plans",
    "track_file": "aeromag.workflows.track",
    "plot_track_map": "aeromag.plot.track",
    "plot_track_timeseries": "aeromag.plot.track",
    "simulate_mission": "aeromag.synthetic.mission",
    # online estimation: recursive least squares with forgetting, compass calibration
    "RecursiveLeastSquares": "aeromag._core.rls",
    "CompassCalibration": "aeromag.compass",
    "calibrate_compass": "aeromag.compass",
    "igrf_field": "aeromag.compass",
    "compass_file": "aeromag.workflows.compass",
    "simulate_compass": "aeromag.synthetic.compass",
    "OnlineTL": "aeromag.compensation.online",
    "OnlineTollesLawson": "aeromag.compensation.online_estimator",
    "compensate_online_file": "aeromag.workflows.online_compensate",
    "simulate_online_tl": "aeromag.synthetic.online_tl",
    # particle filters and the particle-filter detector
    "ParticleFilter": "aeromag._core.particles",
    "StateSpaceModel": "aeromag._core.particles",
    "FilterBank": "aeromag._core.particles",
    "threshold_from_runs": "aeromag._core.particles",
    "particle_detector": "aeromag.detection.particle",
    "detect_file": "aeromag.workflows.detect",
    "simulate_growth": "aeromag.synthetic.benchmarks",
    "simulate_cstr": "aeromag.synthetic.benchmarks",
    # navigation: the unscented transform, the UKF and the 12-state navigation filter
    "sigma_points": "aeromag._core.unscented",
    "unscented_transform": "aeromag._core.unscented",
    "UnscentedKalmanFilter": "aeromag.nav",
    "NavConfig": "aeromag.nav",
    "NavFilter": "aeromag.nav",
    "NavInputs": "aeromag.nav",
    "navigate": "aeromag.nav",
    "navigate_file": "aeromag.workflows.navigate",
    "simulate_quadrotor": "aeromag.synthetic.quadrotor",
    # survey chain: gridding
    "grid": "aeromag.survey.grids",
    "GridResult": "aeromag.survey.grids",
    "GridSummary": "aeromag.survey.gridding",
    "minimum_curvature": "aeromag.survey.gridding",
    "grid_file": "aeromag.workflows.grid",
    "plot_grid_map": "aeromag.plot.grid_map",
    # the survey chain: levelling (lag, diurnal, IGRF, tie lines, micro-levelling)
    "level": "aeromag.workflows.level",
    "level_file": "aeromag.workflows.level",
    "LevelResult": "aeromag.survey.chain",
    "simulate_level_survey": "aeromag.synthetic.level_survey",
}

__all__ = ["AeromagError", "FitError", "InputError", "__version__", *sorted(_API)]


def __getattr__(name: str) -> Any:
    module = _API.get(name)
    if module is None:
        raise AttributeError(f"module 'aeromag' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_API))

