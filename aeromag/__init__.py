"""aeromag: post-processing of aeromagnetic surveys flown by aircraft and multirotor UAVs."""

from __future__ import annotations

from .errors import AeromagError, FitError, InputError

__version__ = "0.1.0"

__all__ = ["AeromagError", "FitError", "InputError", "__version__"]
