"""aeromag: post-processing of aeromagnetic surveys flown by aircraft and multirotor UAVs.

The public API is flat::

    import aeromag as am
    df = am.read_log("survey.csv")
    res = am.compensate(df)                  # fit on the survey itself, screen, apply
    model = am.calibrate(am.read_log("calibration.csv")).model
    out = am.compensate(df, model=model)

Every public name is listed in ``__all__`` (``docs/api.md``); names are imported on first use,
so ``import aeromag`` (and ``aeromag --help``) stays fast.  Four public subpackages hold the
rest: ``am.synthetic`` (simulators with ground truth), ``am.estimation`` (generic sequential
numerics: RLS, UKF, particle filters), ``am.plot`` (figures) and ``am.workflows`` (file in,
files out: the ``*_file`` functions each command runs).  Everything else lives in the domain
packages (``aeromag.compensation``, ``aeromag.io``, ...) or is private.
"""

from __future__ import annotations

import importlib
from typing import Any

from .errors import AeromagError, FitError, InputError

__version__ = "0.1.0"

#: Public name -> module that defines it, grouped by role (one line each; at most ~45 names in
#: ``__all__``, checked by tests/test_api.py).  Simulators, generic numerics, plots and the
#: file workflows are the subpackages ``am.synthetic``, ``am.estimation``, ``am.plot`` and
#: ``am.workflows``.
_API: dict[str, str] = {
    # reading and writing
    "read_log": "aeromag.io",
    "write_csv": "aeromag.io",
    "read_plan": "aeromag.io.plans",
    # compensation: the fitted model (TLModel) and the scikit-learn estimators (*Regressor)
    "CompensationConfig": "aeromag.compensation.config",
    "CompensationResult": "aeromag.compensation.result",
    "TLModel": "aeromag.compensation.model",
    "TollesLawsonRegressor": "aeromag.compensation.estimator",
    "OnlineTollesLawsonRegressor": "aeromag.compensation.online_estimator",
    "compensate": "aeromag.workflows.compensate",
    "calibrate": "aeromag.workflows.compensate",
    "fit_model": "aeromag.compensation.fit",
    "apply_model": "aeromag.compensation.apply",
    "compensation_metrics": "aeromag.compensation.metrics",
    "design_matrix": "aeromag.compensation.terms",
    "TERMS_16": "aeromag.conventions",
    # quality control and the report
    "compute_qc": "aeromag.qc",
    "QCResult": "aeromag.qc",
    "detect_maneuvers": "aeromag.qc",
    "fom_table": "aeromag.qc",
    "write_report": "aeromag.workflows.report",
    # track check and detection
    "check_track": "aeromag.track",
    "TrackResult": "aeromag.track",
    "particle_detector": "aeromag.detection.particle",
    # navigation and compass
    "NavConfig": "aeromag.nav",
    "NavFilter": "aeromag.nav",
    "NavInputs": "aeromag.nav",
    "NavigationResult": "aeromag.nav",
    "navigate": "aeromag.nav",
    "CompassCalibration": "aeromag.compass",
    "calibrate_compass": "aeromag.compass",
    "igrf_field": "aeromag.compass",
    # survey chain: levelling and gridding
    "level": "aeromag.workflows.level",
    "LevelResult": "aeromag.survey.chain",
    "grid": "aeromag.survey.grids",
    "GridResult": "aeromag.survey.grids",
}

#: Public subpackages, imported on first use like the names above.
_SUBPACKAGES = ("estimation", "plot", "synthetic", "workflows")

__all__ = ["AeromagError", "FitError", "InputError", "__version__", *sorted(_API),
           *_SUBPACKAGES]


def __getattr__(name: str) -> Any:
    if name in _SUBPACKAGES:
        value = importlib.import_module(f"aeromag.{name}")
        globals()[name] = value
        return value
    module = _API.get(name)
    if module is None:
        raise AttributeError(f"module 'aeromag' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_API) | set(_SUBPACKAGES))

