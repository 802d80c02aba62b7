"""Deprecated: moved to :mod:`aeromag.synthetic` (kept for one release)."""

from ._deprecated import forward

__getattr__, __dir__ = forward(__name__, (
    "aeromag.synthetic",
    "aeromag.synthetic.physics",
    "aeromag.synthetic.faults",
    "aeromag.workflows.simulate",
))
