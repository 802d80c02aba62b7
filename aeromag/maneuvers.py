"""Deprecated: moved to :mod:`aeromag.qc.maneuvers` (this path works for one more release)."""

from ._deprecated import forward

__getattr__, __dir__ = forward(__name__, ("aeromag.qc.maneuvers",))
