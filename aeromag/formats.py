"""Deprecated location of :mod:`aeromag.io.formats` (kept for one release)."""

import warnings

from .io.formats import *  # noqa: F403
from .io.formats import (  # noqa: F401 - names callers imported from here
    EXTENSIONS,
    FORMATS,
    MAGNAV_FLUXGATES,
    MAGNAV_PRESET,
    apply_preset,
    detect_format,
    read_magarrow,
    read_magdrone,
    read_table,
    read_table_rows,
    read_xyz,
    sniff_csv,
    write_table,
    write_xyz,
)

warnings.warn("aeromag.formats moved to aeromag.io.formats; import it from there",
              DeprecationWarning, stacklevel=2)
