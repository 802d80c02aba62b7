"""Deprecated: moved to :mod:`aeromag.compensation` (kept for one release)."""

from ._deprecated import forward

__getattr__, __dir__ = forward(__name__, (
    "aeromag.workflows.compensate",
    "aeromag.compensation",
    "aeromag.compensation.pipeline",
    "aeromag.compensation.config",
    "aeromag.compensation.prepare",
    "aeromag.compensation.normal",
    "aeromag.compensation.fit",
    "aeromag.compensation.apply",
    "aeromag.compensation.metrics",
    "aeromag.compensation.result",
    "aeromag.compensation.segments",
    "aeromag.compensation.screening",
    "aeromag.compensation.report",
    "aeromag._core.moments",
))
