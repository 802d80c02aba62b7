"""Helpers shared by every command (the typer application object lives in ``_typer``).

The CLI is a thin shell over the Python API: each command parses options, calls one API
function, and turns :class:`~aeromag.errors.AeromagError` into a one-line message on stderr
with exit status 1 (no traceback for a user's mistake).
"""

from __future__ import annotations

import contextlib
import errno
import logging
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Annotated

import typer

from ..errors import AeromagError
from ._typer import app

log = logging.getLogger(__name__)


def _version(value: bool) -> None:
    """``--version``: print ``aeromag X.Y.Z`` and exit."""
    if value:
        from .. import __version__

        typer.echo(f"aeromag {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    version: Annotated[bool, typer.Option("--version", callback=_version, is_eager=True,
                                          help="Print the aeromag version and exit.")] = False,
) -> None:
    """Options before the command (``--version``); the group's help is ``app``'s."""


#: Exit status for a user's mistake (bad file, bad option value).
EXIT_USER_ERROR = 1


@contextlib.contextmanager
def user_errors() -> Iterator[None]:
    """Turn :class:`AeromagError` into ``error: ...`` on stderr and exit status 1.

    An operating-system error (an output folder that cannot be written, a full disk, a path
    that is a directory) is the user's to fix too: one line naming the path, no traceback.
    Every command runs its library calls in here, so this is where the library's words become
    the command line's: errors and warnings that name a parameter (``units={'time': 'ms'}``,
    ``band_hz``) name its flag instead (``--units time=ms``, ``--band``; see
    :func:`~aeromag.cli._options.config_errors` and
    :func:`~aeromag.cli._options.flag_messages`).
    """
    from ..io.messages import clean
    from ..io.outputs import output_set
    from ._options import config_errors, flag_message, flag_messages

    try:
        # all outputs of the command appear together, or none does
        with output_set(rewrite=flag_message), flag_messages(), config_errors():
            yield
    except AeromagError as exc:
        typer.echo(f"error: {clean(exc)}", err=True)
        raise typer.Exit(EXIT_USER_ERROR) from None
    except OSError as exc:
        typer.echo(f"error: {clean(os_error_message(exc))}", err=True)
        raise typer.Exit(EXIT_USER_ERROR) from None
    except StrictWarning as exc:
        typer.echo(f"error: {clean(str(exc))}", err=True)
        raise typer.Exit(EXIT_USER_ERROR) from None


class StrictWarning(Exception):  # noqa: N818 - a warning raised as an error, by --strict
    """A library warning raised as an error by ``--strict``.

    Not an :class:`AeromagError`, so that no library code that tolerates a failed step (and
    notes why) swallows it.
    """


class _RaiseWarnings(logging.Handler):
    """Raise :class:`StrictWarning` on a warning (a handler's filter runs in the caller)."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.addFilter(self._raise)

    @staticmethod
    def _raise(record: logging.LogRecord) -> bool:
        if record.levelno >= logging.WARNING:
            raise StrictWarning(f"{record.getMessage()} (--strict: warnings are errors)")
        return True

    def emit(self, record: logging.LogRecord) -> None:  # never reached: the filter raises
        pass


@contextlib.contextmanager
def strict_warnings(enabled: bool) -> Iterator[None]:
    """With ``enabled``, every warning of aeromag's loggers ends the command as an error.

    The first warning raises :class:`StrictWarning` where it is logged, so nothing after it
    runs and no output is written (:func:`user_errors` reports it on one line).

    Parameters
    ----------
    enabled : bool
        ``--strict``.
    """
    if not enabled:
        yield
        return
    handler = _RaiseWarnings()
    lg = logging.getLogger("aeromag")
    lg.addHandler(handler)
    try:
        yield
    finally:
        lg.removeHandler(handler)


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


def column_options(
    col: list[str] | None, map_file: Path | None, units: list[str] | None
) -> tuple[dict[str, str] | None, dict[str, str] | None]:
    """Merge ``--col``, ``--map`` and ``--units`` options into (columns, units) dicts.

    A map entry ``NAME=SOURCE`` renames the file's column ``SOURCE`` to ``NAME``; a ``NAME``
    that is not a canonical column (``time``, ``lat``, ..., ``leg``) is almost always a mistake
    (``--col foo=mag`` renames ``mag`` away and the pipeline falls back to the fluxgate
    magnitude), so it draws one warning line (see :func:`warn_non_canonical`).

    Parameters
    ----------
    col : list of str or None
        ``--col NAME=SOURCE`` options.
    map_file : Path or None
        ``--map`` TOML file (``[columns]``, ``[units]``).
    units : list of str or None
        ``--units NAME=UNIT`` options.

    Returns
    -------
    columns, units : dict or None, dict or None
        ``{canonical: source}`` and ``{column_or_group: unit}``, None when empty.
    """
    from ..io import parse_column_map, read_map_file

    columns: dict[str, str] = {}
    unit_map: dict[str, str] = {}
    if map_file is not None:
        c, u = read_map_file(map_file)
        warn_non_canonical(c, f"--map {map_file}:")
        columns.update(c)
        unit_map.update(u)
    c = parse_column_map(col or [], option="--col")
    warn_non_canonical(c, "--col")
    columns.update(c)
    unit_map.update(parse_column_map(units or [], option="--units"))
    return columns or None, unit_map or None


def warn_non_canonical(columns: Mapping[str, str], option: str = "--col") -> list[str]:
    """Warn (one line each) about map entries whose target name is not canonical.

    Parameters
    ----------
    columns : mapping
        Column map ``{NAME: SOURCE}`` (NAME the canonical name, SOURCE the file's column).
    option : str
        Option quoted in the warning.

    Returns
    -------
    list of str
        The non-canonical NAMEs.
    """
    from ..io import CANONICAL_COLUMNS

    canon = ", ".join(CANONICAL_COLUMNS)
    bad = [name for name in columns if name not in CANONICAL_COLUMNS]
    for name in bad:
        src = columns[name]
        if src in CANONICAL_COLUMNS:
            effect = f"renames the log's column {src!r} to {name!r}, so it is not used as {src}"
            if src == "mag":
                effect += (" (the log then has no scalar magnetometer: compensation refuses it,"
                           " as the renamed column still looks like one, unless"
                           " --mag-from-fluxgate)")
        else:
            effect = f"{name!r} is not a canonical column, so column {src!r} is not used"
        log.warning("%s %s=%s %s; write NAME=SOURCE with NAME one of %s", option, name, src,
                    effect, canon)
    return bad


def setup_logging(verbose: bool, quiet: bool = False) -> None:
    """Configure library logging for the command line (warnings by default).

    Parameters
    ----------
    verbose : bool
        Debug messages of aeromag's own loggers, with timestamps [ms] (other libraries stay at
        warnings: matplotlib's or numba's debug output is not aeromag's progress).
    quiet : bool
        Library warnings off (errors only); the command line's own warnings about its options
        (``aeromag.cli``) are still shown.
    """
    root = logging.ERROR if quiet and not verbose else logging.WARNING
    fmt = "%(relativeCreated)6.0f ms %(levelname)s: %(message)s" if verbose else \
        "%(levelname)s: %(message)s"
    logging.basicConfig(level=root, format=fmt, force=True)
    logging.getLogger("aeromag").setLevel(logging.DEBUG if verbose else logging.NOTSET)
    logging.getLogger(__package__).setLevel(
        logging.WARNING if quiet and not verbose else logging.NOTSET)
