"""The typer application object, alone: every CLI module registers on it.

It has a module of its own so that the option table (``_options``, which registers commands on
it) and the shared helpers (``_app``, which map library messages through the option table)
import it without importing each other.
"""

from __future__ import annotations

import typer

app = typer.Typer(
    name="aeromag",
    help="Aeromagnetic survey post-processing: Tolles-Lawson compensation with PCA screening "
    "of segments (offline or online), DGPS track-deviation checks, compass calibration, "
    "UKF navigation, particle-filter fault detection, survey levelling (lag, diurnal, IGRF, "
    "tie lines) and minimum-curvature gridding, QC reports, batch processing.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    # Plain click help: help strings are shown as written (rich markup would eat "[columns]"
    # and "'aeromag[dask]'"), flags get no "<bool>" type as if they took a value, and a usage
    # error is three plain lines instead of a box.
    rich_markup_mode=None,
)
