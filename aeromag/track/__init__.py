"""Mission-track check (methods M2): plan geometry, leg assignment, deviation, per-leg summary.

``check_track(log_df, plan_df, ...)`` runs it on tables; :func:`aeromag.workflows.track.track_file`
reads the files and writes OUT.csv and OUT.json; :func:`aeromag.io.plans.read_plan` reads a plan
(CSV, QGroundControl ``.plan``, Mission Planner ``.waypoints``).
"""

from __future__ import annotations

import warnings
from typing import Any

from .._core import geodesy as _geodesy
from .assign import assign_legs
from .check import ADDED_COLUMNS, TrackResult, check_track
from .deviation import leg_summary, track_alarm
from .geometry import cross_track, plan_ned
from .legs import DEFAULT_WAYPOINT_RADIUS_M
from .plan import MIN_LEG_LENGTH_M, PLAN_NEEDS, validate_plan

__all__ = ["ADDED_COLUMNS", "DEFAULT_WAYPOINT_RADIUS_M", "MIN_LEG_LENGTH_M", "PLAN_NEEDS",
           "TrackResult", "assign_legs", "check_track", "cross_track", "leg_summary",
           "plan_ned", "track_alarm", "validate_plan"]

#: Names that lived in the old ``aeromag.track`` module and now live in the file layers.
_MOVED = {"track_file": ("aeromag.workflows.track", "track_file"),
          "read_plan": ("aeromag.io.plans", "read_plan")}

_GEODESY = ("geodetic_to_ecef", "geodetic_to_ned", "ecef_to_ned_matrix")


def __getattr__(name: str) -> Any:
    """Old names of the ``aeromag.track`` module, with a DeprecationWarning (one release)."""
    if name in _MOVED:
        import importlib

        mod, attr = _MOVED[name]
        warnings.warn(f"aeromag.track.{name} is deprecated: use {mod}.{attr}",
                      DeprecationWarning, stacklevel=2)
        return getattr(importlib.import_module(mod), attr)
    if name in _GEODESY:
        warnings.warn(f"aeromag.track.{name} is deprecated: use aeromag._core.geodesy.{name}",
                      DeprecationWarning, stacklevel=2)
        return getattr(_geodesy, name)
    raise AttributeError(f"module 'aeromag.track' has no attribute {name!r}")
