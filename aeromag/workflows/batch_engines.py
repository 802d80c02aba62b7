"""Engines of ``aeromag batch``: a local process pool, or a Dask cluster.

The local workers die with the batch process.  A worker installs a SIGTERM handler that raises
``SystemExit`` (so the file being written loses only its temporaries), asks the kernel for
SIGTERM when its parent dies (Linux ``PR_SET_PDEATHSIG``) and runs a watchdog thread that
terminates it within about :data:`WORKER_GRACE_S` + :data:`WATCHDOG_S` seconds of the batch
process's death.  Ctrl-C (or SIGTERM) in the batch process cancels the queue and terminates
the workers instead of draining the queue.
"""

from __future__ import annotations

import contextlib
import logging
import os
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context
from pathlib import Path
from typing import Any

from ..errors import InputError
from .batch_jobs import BatchJob, FileResult


# --------------------------------------------------------------------------- engines
def run_local(jobs: list[BatchJob], workers: int, fn: Callable[[BatchJob], FileResult],
              done: Callable[[FileResult], None]) -> None:
    """Run ``fn(job)`` for every job on a local process pool, ``done`` with each result.

    One worker runs in this process; otherwise the workers die with this process and Ctrl-C
    stops them at once.
    """
    if workers <= 1 or len(jobs) <= 1:
        for j in jobs:
            done(fn(j))
        return
    ctx = get_context("forkserver") if "forkserver" in _start_methods() else None
    ex = ProcessPoolExecutor(max_workers=min(workers, len(jobs)), mp_context=ctx,
                             initializer=_worker_init, initargs=(os.getpid(),))
    try:
        futs = {ex.submit(fn, j): j for j in jobs}
        for f in as_completed(futs):
            try:
                done(f.result())
            except Exception as exc:  # noqa: BLE001 - a worker died (e.g. out of memory)
                j = futs[f]
                done(FileResult.failure(
                    j, f"{j.input}: worker failed ({type(exc).__name__}: {exc})"))
    except BaseException:
        # Ctrl-C / SIGTERM: drop the queue and stop the workers now (each removes its
        # temporary files on SIGTERM), instead of draining the queue.
        _stop_workers(ex)
        raise
    ex.shutdown(wait=True)


def _stop_workers(ex: ProcessPoolExecutor, grace_s: float = 5.0) -> None:
    """Cancel what has not started and terminate the running workers (SIGTERM, then KILL)."""
    procs = list(getattr(ex, "_processes", {}).values())
    ex.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        with contextlib.suppress(Exception):
            p.terminate()
    deadline = time.monotonic() + grace_s
    for p in procs:
        with contextlib.suppress(Exception):
            p.join(max(0.0, deadline - time.monotonic()))
            if p.is_alive():
                p.kill()


#: Seconds between a worker's checks that the batch process is still alive.
WATCHDOG_S = 0.25
#: Seconds a worker whose batch process died gets to remove its temporary files.
WORKER_GRACE_S = 2.0


def _worker_init(parent_pid: int) -> None:
    """In each worker: die with the batch process, and clean up on SIGTERM like on Ctrl-C.

    On Linux the kernel sends SIGTERM when the worker's parent dies (``PR_SET_PDEATHSIG``);
    everywhere a watchdog thread checks every :data:`WATCHDOG_S` that the batch process is
    alive (killed by ``timeout`` or the out-of-memory killer, it cannot stop its workers
    itself), then terminates the worker: SIGTERM raises ``SystemExit`` in its main thread, so
    the file being written loses only its temporaries.
    """
    import signal
    import threading

    # Warnings reach the user through the summary (each file's 'warnings'), not as stray
    # lines from the workers; errors still show.
    logging.basicConfig(level=logging.ERROR)

    def on_term(signum: int, frame: object) -> None:
        raise SystemExit(128 + signum)

    signal.signal(signal.SIGTERM, on_term)

    def watch() -> None:
        while True:
            time.sleep(WATCHDOG_S)
            try:
                os.kill(parent_pid, 0)
            except ProcessLookupError:
                break
            except OSError:
                continue
        os.kill(os.getpid(), signal.SIGTERM)
        # Clean-up time (SystemExit unwinds the file being written); then go, whatever the
        # main thread does (the executor catches SystemExit and would wait for more work).
        time.sleep(WORKER_GRACE_S)
        os._exit(1)

    threading.Thread(target=watch, name="aeromag-watchdog", daemon=True).start()


def _start_methods() -> list[str]:
    import multiprocessing

    return multiprocessing.get_all_start_methods()


def run_dask(jobs: list[BatchJob], scheduler: Any, fn: Callable[[BatchJob], FileResult],
             done: Callable[[FileResult], None]) -> None:
    """Run ``fn(job)`` for every job on a Dask cluster (``scheduler``: address or client)."""
    try:
        from distributed import Client
        from distributed import as_completed as dask_completed
    except ImportError:
        raise InputError(
            "scheduler=ADDRESS needs Dask distributed: pip install 'aeromag[dask]'") from None
    own = not isinstance(scheduler, Client)
    try:
        client = Client(scheduler) if own else scheduler
    except (OSError, TimeoutError, ValueError) as exc:
        raise InputError(f"scheduler={scheduler!r}: cannot connect ({exc}); is the Dask"
                         " scheduler running at that address?") from None
    try:
        futs = client.map(fn, jobs, pure=False, key=[
            f"aeromag-{i}-{Path(j.input).name}" for i, j in enumerate(jobs)])
        index = {f.key: j for f, j in zip(futs, jobs, strict=True)}
        for f in dask_completed(futs):
            try:
                done(f.result())
            except Exception as exc:  # noqa: BLE001 - a worker was lost
                j = index[f.key]
                done(FileResult.failure(
                    j, f"{j.input}: Dask task failed ({type(exc).__name__}: {exc})"))
    finally:
        if own:
            client.close()
