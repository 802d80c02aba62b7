"""Deprecated location of :mod:`aeromag.io.warm` (kept for one release)."""

import warnings

from .io.warm import *  # noqa: F403
from .io.warm import (  # noqa: F401 - names callers imported from here
    COLUMNS_MIN_BYTES,
    READ_BLOCK_BYTES,
    prefetch_csv,
    read_csv_columns,
    read_csv_table,
    take_prefetched,
)

warnings.warn("aeromag.warm moved to aeromag.io.warm; import it from there",
              DeprecationWarning, stacklevel=2)
