"""Deprecated: moved to :mod:`aeromag.compensation` (kept for one release)."""

from ._deprecated import forward

__getattr__, __dir__ = forward(__name__, (
    "aeromag.compensation.terms",
    "aeromag.compensation.model",
    "aeromag._core.lstsq",
    "aeromag.compensation.estimator",
))
