"""Stable import path of the CLI's shared objects (defined in :mod:`aeromag.cli._app`).

New command modules import ``app``, ``setup_logging``, ``user_errors``, ``column_options`` and
``EXIT_USER_ERROR`` from here.
"""

from __future__ import annotations

from ._app import (
    EXIT_USER_ERROR,
    app,
    column_options,
    os_error_message,
    setup_logging,
    user_errors,
    warn_non_canonical,
)

__all__ = ["EXIT_USER_ERROR", "app", "column_options", "os_error_message", "setup_logging",
           "user_errors", "warn_non_canonical"]
