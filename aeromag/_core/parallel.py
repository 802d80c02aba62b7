"""Speed plumbing in one place: the thread pool and scipy's private filter kernel.

Domain functions never take these as arguments; they call :func:`parallel_map` and
:func:`submit` (or the filters that do).
"""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

log = logging.getLogger(__name__)


#: Threads used to filter many columns of a long stretch at once (scipy releases the GIL).
#: Override with the environment variable ``AEROMAG_FILTER_THREADS`` (1 disables threading).
FILTER_THREADS = max(1, int(os.environ.get("AEROMAG_FILTER_THREADS", min(4, os.cpu_count() or 1))))
_THREADED_MIN_SAMPLES = 1_000_000  # values in the array, below which threads do not pay


def _signal() -> Any:
    """``scipy.signal``, imported on first use.

    It takes most of a second to import; deferring it keeps ``aeromag --help`` and the
    reading of a log from waiting for it (see :mod:`aeromag.warm`).
    """
    from scipy import signal

    return signal



def _kernel() -> Any:
    """Scipy's in-place second-order-section kernel (``scipy.signal._sosfilt._sosfilt``).

    :func:`zero_phase_rows` calls it directly: scipy's public ``sosfiltfilt`` wraps the same
    kernel in copies and axis moves (about a quarter of its time on rows of 600-6000 samples).
    None when this scipy does not have it (the public function is then used).
    """
    global _KERNEL
    if _KERNEL is False:
        _signal()
        try:
            from scipy.signal._sosfilt import _sosfilt
        except ImportError:  # pragma: no cover - a scipy without the private kernel
            log.debug("scipy.signal._sosfilt not found: using scipy.signal.sosfiltfilt")
            _sosfilt = None
        _KERNEL = _sosfilt
    return _KERNEL


_KERNEL: Any = False
_POOL: ThreadPoolExecutor | None = None
_WORKER = threading.local()


def _pool() -> ThreadPoolExecutor:
    """The filter thread pool (created once; threads are started on first use)."""
    global _POOL
    if _POOL is None:
        _POOL = ThreadPoolExecutor(FILTER_THREADS, thread_name_prefix="aeromag-filter",
                                   initializer=_mark_worker)
    return _POOL


def _mark_worker() -> None:
    _WORKER.busy = True


def _reset_pool() -> None:  # a forked child has none of the parent's threads
    global _POOL
    _POOL = None


os.register_at_fork(after_in_child=_reset_pool)


def parallel_map(fn: Callable[[Any], Any], items: Sequence[Any]) -> list[Any]:
    """``[fn(i) for i in items]`` on the filter thread pool (in order).

    Work that releases the GIL (scipy's filter kernel, numpy on large arrays, BLAS) runs on
    :data:`FILTER_THREADS` threads.  Called from inside a pool thread (nested), or with one
    thread configured, it runs serially, so a pool thread never waits on its own pool.
    """
    if FILTER_THREADS < 2 or len(items) < 2 or getattr(_WORKER, "busy", False):
        return [fn(i) for i in items]
    _kernel()  # scipy.signal imported here, never by two pool threads at once
    return list(_pool().map(fn, items))


def submit(fn: Callable[..., Any], *args: Any) -> Future:
    """Run ``fn(*args)`` on the filter thread pool and return its future.

    Runs it at once on the calling thread (and returns a finished future) when threads are
    off or when called from a pool thread, so a pool thread never waits on its own pool.
    """
    if FILTER_THREADS < 2 or getattr(_WORKER, "busy", False):
        fut: Future = Future()
        try:
            fut.set_result(fn(*args))
        except BaseException as exc:  # noqa: BLE001 - handed to whoever takes the result
            fut.set_exception(exc)
        return fut
    _kernel()
    return _pool().submit(fn, *args)

