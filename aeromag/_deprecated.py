"""Old import paths kept for one release: modules that forward to the new layout and warn.

``aeromag/compensate.py`` and the other old flat modules hold two lines each: a call of
:func:`forward` naming the modules that now define their names.  Importing one warns once
(``DeprecationWarning``, naming the new home); every name, private ones included, is looked up
in the new modules on first use, so code written against the old paths keeps working.
"""

from __future__ import annotations

import importlib
import sys
import warnings
from collections.abc import Callable, Sequence
from typing import Any

__all__ = ["OLD_PATHS", "forward"]

#: Old module -> where its names live now (the first is the one named in the warning).
OLD_PATHS: dict[str, tuple[str, ...]] = {}


def forward(old: str, new: Sequence[str]) -> tuple[Callable[[str], Any], Callable[[], list]]:
    """Turn module ``old`` into a forwarder to the modules ``new``.

    Parameters
    ----------
    old : str
        The deprecated module (``__name__`` of the caller).
    new : sequence of str
        Modules that define its names now, searched in order.

    Returns
    -------
    getattr, dir : callable
        The module-level ``__getattr__`` and ``__dir__`` for ``old``.
    """
    new = tuple(new)
    OLD_PATHS[old] = new
    warnings.warn(f"{old} is deprecated and will be removed in the next release; import from"
                  f" {new[0]} (or the flat API: import aeromag as am)", DeprecationWarning,
                  stacklevel=3)

    def __getattr__(name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        for mod in new:
            m = importlib.import_module(mod)
            if hasattr(m, name):
                value = getattr(m, name)
                setattr(sys.modules[old], name, value)
                return value
        raise AttributeError(f"module {old!r} has no attribute {name!r} (see {new[0]})")

    def __dir__() -> list[str]:
        names: set[str] = set()
        for mod in new:
            names.update(dir(importlib.import_module(mod)))
        return sorted(names)

    return __getattr__, __dir__
