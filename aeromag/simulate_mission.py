"""Deprecated: the mission simulator moved.

It is :mod:`aeromag.synthetic.mission` and its files :mod:`aeromag.workflows.mission`; this path
works for one release.
"""

from __future__ import annotations

import warnings

from ._core.geodesy import ned_to_geodetic
from .synthetic.mission import (
    DEFAULT_DISTURBANCES,
    FAST_RATE_G_S,
    SLOW_RATE_G_S,
    plan_waypoints_ned,
    simulate_mission,
)
from .workflows.mission import write_mission_files

__all__ = ["DEFAULT_DISTURBANCES", "FAST_RATE_G_S", "SLOW_RATE_G_S", "ned_to_geodetic",
           "plan_waypoints_ned", "simulate_mission", "write_mission_files"]

warnings.warn("aeromag.simulate_mission is deprecated: use aeromag.synthetic.mission "
              "(simulate_mission) and aeromag.workflows.mission (write_mission_files)",
              DeprecationWarning, stacklevel=2)
