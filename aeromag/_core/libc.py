"""The C library through :mod:`ctypes`: the one loader of the package.

Used for what Python does not expose: glibc's allocator settings (``mallopt``,
``malloc_trim``, by the report) and ``prctl`` (the batch workers' parent-death signal).
"""

from __future__ import annotations

import sys
from typing import Any

__all__ = ["libc", "trim_heap"]

_LIBC: Any = None


def libc() -> Any:
    """The C library loaded once (``libc.so.6``, errno kept), or None off Linux/glibc.

    ``malloc_trim`` and ``mallopt`` get their argument types when the library has them
    (musl has neither; callers check with ``hasattr``).

    Returns
    -------
    ctypes.CDLL or None
        The library, or None where it cannot be loaded.
    """
    global _LIBC
    if _LIBC is None:
        _LIBC = False
        if sys.platform.startswith("linux"):
            import ctypes

            try:
                lib = ctypes.CDLL("libc.so.6", use_errno=True)
            except OSError:
                try:
                    lib = ctypes.CDLL(None, use_errno=True)
                except OSError:
                    lib = None
            if lib is not None:
                for name, args in (("malloc_trim", [ctypes.c_size_t]),
                                   ("mallopt", [ctypes.c_int, ctypes.c_int])):
                    fn = getattr(lib, name, None)
                    if fn is not None:
                        fn.argtypes = args
                        fn.restype = ctypes.c_int
                _LIBC = lib
    return _LIBC or None


def trim_heap() -> None:
    """Give the C heap's free pages back to the system (glibc ``malloc_trim``; else nothing).

    Between the steps of a long computation: glibc keeps freed blocks resident, and the next
    step's temporaries then come on top of them.
    """
    lib = libc()
    if lib is not None and hasattr(lib, "malloc_trim"):
        lib.malloc_trim(0)
