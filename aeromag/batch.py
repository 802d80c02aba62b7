"""Deprecated location of :mod:`aeromag.workflows.batch` (kept for one release)."""

import warnings

from .workflows.batch import *  # noqa: F403
from .workflows.batch import (  # noqa: F401 - names callers imported from here
    LOG_EXTENSIONS,
    expand_inputs,
    run_batch,
)

warnings.warn("aeromag.batch moved to aeromag.workflows.batch; import it from there",
              DeprecationWarning, stacklevel=2)
