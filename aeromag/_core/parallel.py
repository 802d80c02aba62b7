"""The package's one parallel configuration: one thread pool, one setting.

Domain functions never take threads as arguments; they call :func:`parallel_map` and
:func:`submit` (or the filters that do).  The pool's size is :data:`THREADS`, set by the one
environment variable ``AEROMAG_THREADS`` (1 runs everything on the calling thread); BLAS
threads are set with threadpoolctl where a command needs it (``workflows.compensate``).  The
batch command's process pool (one process per log) is the batch feature, not this.
"""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

log = logging.getLogger(__name__)


#: Threads of the package's pool (work that releases the GIL: scipy's filters, numpy on
#: large arrays).  The environment variable ``AEROMAG_THREADS`` overrides it (1: no threads).
THREADS = max(1, int(os.environ.get("AEROMAG_THREADS", min(4, os.cpu_count() or 1))))
#: Values in an array below which splitting it over threads does not pay.
THREADED_MIN_SAMPLES = 1_000_000


def signal_module() -> Any:
    """``scipy.signal``, imported on first use, on the calling thread.

    Never imported by two pool threads at once.  It takes most of a second to import;
    deferring it keeps ``aeromag --help`` and the reading of a log from waiting for it.
    """
    from scipy import signal

    return signal


_POOL: ThreadPoolExecutor | None = None
_WORKER = threading.local()


def _pool() -> ThreadPoolExecutor:
    """The package's thread pool (created once; threads are started on first use)."""
    global _POOL
    if _POOL is None:
        _POOL = ThreadPoolExecutor(THREADS, thread_name_prefix="aeromag",
                                   initializer=_mark_worker)
    return _POOL


def _mark_worker() -> None:
    _WORKER.busy = True


def _reset_pool() -> None:  # a forked child has none of the parent's threads
    global _POOL
    _POOL = None


os.register_at_fork(after_in_child=_reset_pool)


def parallel_map(fn: Callable[[Any], Any], items: Sequence[Any]) -> list[Any]:
    """``[fn(i) for i in items]`` on the package's thread pool (in order).

    Work that releases the GIL (scipy's filter kernel, numpy on large arrays, BLAS) runs on
    :data:`THREADS` threads.  Called from inside a pool thread (nested), or with one
    thread configured, it runs serially, so a pool thread never waits on its own pool.
    """
    if THREADS < 2 or len(items) < 2 or getattr(_WORKER, "busy", False):
        return [fn(i) for i in items]
    signal_module()  # scipy.signal imported here, never by two pool threads at once
    return list(_pool().map(fn, items))


def submit(fn: Callable[..., Any], *args: Any) -> Future:
    """Run ``fn(*args)`` on the package's thread pool and return its future.

    Runs it at once on the calling thread (and returns a finished future) when threads are
    off or when called from a pool thread, so a pool thread never waits on its own pool.
    """
    if THREADS < 2 or getattr(_WORKER, "busy", False):
        fut: Future = Future()
        try:
            fut.set_result(fn(*args))
        except BaseException as exc:  # noqa: BLE001 - handed to whoever takes the result
            fut.set_exception(exc)
        return fut
    signal_module()
    return _pool().submit(fn, *args)

