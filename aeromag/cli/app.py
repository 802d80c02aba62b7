"""The typer application object and helpers shared by every command.

The CLI is a thin shell over the Python API: each command parses options, calls one API
function, and turns :class:`~aeromag.errors.AeromagError` into a one-line message on stderr
with exit status 1 (no traceback for a user's mistake).
"""

from __future__ import annotations

import contextlib
import errno
import logging
from collections.abc import Iterator
from pathlib import Path

import typer

from ..errors import AeromagError

app = typer.Typer(
    name="aeromag",
    help="Aeromagnetic survey post-processing: Tolles-Lawson compensation with PCA screening "
    "of segments, DGPS track-deviation checks, batch processing.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

#: Exit status for a user's mistake (bad file, bad option value).
EXIT_USER_ERROR = 1


@contextlib.contextmanager
def user_errors() -> Iterator[None]:
    """Turn :class:`AeromagError` into ``error: ...`` on stderr and exit status 1.

    An operating-system error (an output folder that cannot be written, a full disk, a path
    that is a directory) is the user's to fix too: one line naming the path, no traceback.
    """
    try:
        yield
    except AeromagError as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(EXIT_USER_ERROR) from None
    except OSError as exc:
        typer.echo(f"error: {os_error_message(exc)}", err=True)
        raise typer.Exit(EXIT_USER_ERROR) from None


def os_error_message(exc: OSError) -> str:
    """One line for an :class:`OSError`: the path, the system's reason and what to do."""
    where = exc.filename if exc.filename is not None else "<file>"
    why = exc.strerror or str(exc)
    what = {
        errno.EACCES: "check its permissions or choose another -o",
        errno.EPERM: "check its permissions or choose another -o",
        errno.EROFS: "the file system is read-only: choose another -o",
        errno.ENOSPC: "free disk space or choose another -o",
        errno.EISDIR: "it is a folder: give a file name",
        errno.ENOTDIR: "a part of the path is a file, not a folder: fix the path",
        errno.ENOENT: "check the path",
    }.get(exc.errno or -1, "check the path")
    return " ".join(f"{where}: {why}; {what}".split())


def column_options(col: list[str] | None, map_file: Path | None, units: list[str] | None):
    """Merge ``--col``, ``--map`` and ``--units`` options into (columns, units) dicts."""
    from ..io import parse_column_map, read_map_file

    columns: dict[str, str] = {}
    unit_map: dict[str, str] = {}
    if map_file is not None:
        c, u = read_map_file(map_file)
        columns.update(c)
        unit_map.update(u)
    columns.update(parse_column_map(col or [], option="--col"))
    unit_map.update(parse_column_map(units or [], option="--units"))
    return columns or None, unit_map or None


def setup_logging(verbose: bool, quiet: bool = False) -> None:
    """Configure library logging for the command line (warnings by default)."""
    level = logging.DEBUG if verbose else (logging.ERROR if quiet else logging.WARNING)
    fmt = "%(relativeCreated)6.0f ms %(levelname)s: %(message)s" if verbose else \
        "%(levelname)s: %(message)s"
    logging.basicConfig(level=level, format=fmt, force=True)
