"""Deprecated: moved to :mod:`aeromag.compensation.estimator` (kept for one release)."""

from ._deprecated import forward

__getattr__, __dir__ = forward(__name__, (
    "aeromag.compensation.estimator",
))
