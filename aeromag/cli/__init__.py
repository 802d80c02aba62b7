"""The ``aeromag`` command line (typer).  Entry point: :func:`main`."""

from __future__ import annotations

import importlib

from ._app import app

# Each module registers its command(s) on ``app`` when imported.
_COMMAND_MODULES = ("compensate", "simulate", "track", "batch", "report", "compass", "detect",
                    "navigate", "grid", "level")
for _name in _COMMAND_MODULES:
    try:
        importlib.import_module(f"{__name__}.{_name}")
    except ModuleNotFoundError as _exc:  # pragma: no cover - during development only
        if _exc.name != f"{__name__}.{_name}":
            raise


def main() -> None:
    """Run the ``aeromag`` command line."""
    app()


__all__ = ["app", "main"]
