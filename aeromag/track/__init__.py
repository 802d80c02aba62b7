"""Mission-track check (methods M2): plan geometry, leg assignment, deviation, per-leg summary.

``check_track(log_df, plan_df, ...)`` runs it on tables; :func:`aeromag.workflows.track.track_file`
reads the files and writes OUT.csv and OUT.json; :func:`aeromag.io.plans.read_plan` reads a plan
(CSV, QGroundControl ``.plan``, Mission Planner ``.waypoints``).
"""

from __future__ import annotations

from .assign import assign_legs
from .check import ADDED_COLUMNS, TrackResult, check_track
from .deviation import leg_summary, track_alarm
from .geometry import cross_track, plan_ned
from .plan import MIN_LEG_LENGTH_M, PLAN_NEEDS, validate_plan
from .report import LegSummary, PassSummary, SpanSummary, TrackReport

__all__ = ["ADDED_COLUMNS", "MIN_LEG_LENGTH_M", "PLAN_NEEDS", "LegSummary", "PassSummary",
           "SpanSummary", "TrackReport", "TrackResult", "assign_legs", "check_track",
           "cross_track", "leg_summary", "plan_ned", "track_alarm", "validate_plan"]
