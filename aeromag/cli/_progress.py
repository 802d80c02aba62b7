"""The one progress facility of the command line: a rich progress bar on stderr.

Library code never prints; it reports progress through an optional callback
``progress(done, total, step)`` (e.g. :func:`aeromag.workflows.report.write_report`).  A
command wraps its work in :func:`progress_bar` and passes the callback it yields::

    with progress_bar("report") as progress:
        report_file(..., progress=progress)

The bar is drawn only when stderr is a terminal (pipes, logs and tests get nothing), and
disappears when the command ends, so the command's one-line summary stays the last line.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Callable, Iterator

__all__ = ["ProgressCallback", "progress_bar"]

#: ``progress(done, total, step)``.
ProgressCallback = Callable[[int, int, str], None]


@contextlib.contextmanager
def progress_bar(label: str, *, enabled: bool | None = None) -> Iterator[ProgressCallback]:
    """A progress callback that draws a rich bar on stderr.

    Parameters
    ----------
    label : str
        What is in progress (the command).
    enabled : bool, optional
        Draw the bar (default: when stderr is a terminal and ``NO_COLOR`` is unset).

    Yields
    ------
    callable
        ``progress(done, total, step)``.
    """
    if enabled is None:
        enabled = sys.stderr.isatty() and "NO_COLOR" not in os.environ
    if not enabled:
        yield lambda done, total, step: None
        return
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    with Progress(TextColumn("[bold]{task.description}"), BarColumn(),
                  TextColumn("{task.completed}/{task.total}"), TextColumn("{task.fields[step]}"),
                  TimeElapsedColumn(), console=Console(stderr=True), transient=True) as bar:
        task = bar.add_task(label, total=None, step="")

        def update(done: int, total: int, step: str) -> None:
            bar.update(task, completed=done, total=total, step=step)

        yield update
