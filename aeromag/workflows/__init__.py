"""File in, files out: what each command runs.  The only layer (with ``cli``) that uses ``io``.

Each ``*_file`` function reads its input file(s) and writes its outputs atomically (all files or
none); the in-memory functions they wrap are the top-level ``am.compensate``, ``am.level``, ...
Names are imported on first use (``aeromag.workflows.compensate_file``), so a command imports
only its own workflow.
"""

from __future__ import annotations

from aeromag._core.lazy import lazy_names

#: Public name -> module that defines it.
_API: dict[str, str] = {
    "compensate_file": "aeromag.workflows.compensate",
    "calibrate_file": "aeromag.workflows.compensate",
    "apply_model_chunked": "aeromag.workflows.chunked",
    "compensate_online_file": "aeromag.workflows.online_compensate",
    "report_file": "aeromag.workflows.report",
    "load_compensated": "aeromag.workflows.report",
    "run_batch": "aeromag.workflows.batch",
    "track_file": "aeromag.workflows.track",
    "detect_file": "aeromag.workflows.detect",
    "compass_file": "aeromag.workflows.compass",
    "navigate_file": "aeromag.workflows.navigate",
    "level_file": "aeromag.workflows.level",
    "grid_file": "aeromag.workflows.grid",
    "write_survey_report": "aeromag.workflows.survey_report",
    "write_simulation": "aeromag.workflows.simulate",
    "write_level_simulation": "aeromag.workflows.simulate_level",
    "write_online_simulation": "aeromag.workflows.simulate_online",
    "write_mission_files": "aeromag.workflows.mission",
    "write_quadrotor_files": "aeromag.workflows.quadrotor",
}

__all__ = sorted(_API)

__getattr__, __dir__ = lazy_names(__name__, _API)
