"""Deprecated: moved to :mod:`aeromag._core.filters` (kept for one release)."""

from ._deprecated import forward

__getattr__, __dir__ = forward(__name__, (
    "aeromag._core.filters",
    "aeromag._core.parallel",
    "aeromag._core.runs",
))
