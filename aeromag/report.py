"""Deprecated: moved to :mod:`aeromag.workflows.report` (this path works for one more release)."""

from ._deprecated import forward

__getattr__, __dir__ = forward(__name__, ("aeromag.workflows.report",))
