"""Atomic output files, written as a set.

Every output file is written to a temporary file beside its target (``.NAME.aeromag-PID-XXXX.tmp``,
the writer's process id in the name), then renamed onto the target.  Inside an
:func:`output_set` (the command line opens one around every command) the renames wait until the
whole set is written, and happen then one after the other: all the files of a command appear
together, or none does (a failure, Ctrl-C or SIGTERM removes every temporary file; the targets
keep their old contents).  Nested :func:`atomic_path` blocks join the set of the outer one.

A temporary file left by a process that was killed outright (SIGKILL, power loss) is removed by
the next write of the same output once its process is gone (:func:`remove_stale_temporaries`).

Inside an output set, the inputs of the command (:func:`register_input`: logs, models, plans,
column maps) are never written over: an output that is an input is refused, whatever the
command.  An output must be a regular file path: a device (``/dev/null``), a FIFO or a socket
is refused (renaming a file onto it would replace it).
"""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import re
import secrets
import signal
import stat
import threading
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import InputError
from .messages import clean

log = logging.getLogger(__name__)


def _current_umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


_UMASK = _current_umask()

#: Marker in the names of temporary files (``.NAME.aeromag-PID-XXXXXXXX.tmp``).
TEMP_MARK = "aeromag"
_TEMP_NAME = re.compile(r"^\.(?P<name>.+)\." + TEMP_MARK + r"-(?P<pid>\d+)-[0-9a-f]+\.tmp$")


@dataclass
class _OutputSet:
    """Files of one command: temporaries waiting to be renamed, and the inputs."""

    pending: list[tuple[Path, Path]] = field(default_factory=list)
    inputs: dict[Path, str] = field(default_factory=dict)
    depth: int = 0
    warnings: list[str] = field(default_factory=list)
    #: How the set's reports spell their own ``warnings`` (the CLI: with flags, like the log).
    rewrite: Callable[[str], str] | None = None


class _WarningCapture(logging.Handler):
    """Collects the warnings of aeromag's loggers for the reports of the set, and passes
    every record on as the logger would have (same levels, same handlers)."""

    def __init__(self, sink: list[str], forward_level: int) -> None:
        super().__init__(logging.DEBUG)
        self.sink = sink
        self.stack = _stack()  # the sets of the thread that opened the capture
        self.forward_level = forward_level

    def _level_of(self, name: str) -> int:
        """The effective level the record's logger had before the capture began."""
        lg: logging.Logger | None = logging.getLogger(name)
        while lg is not None:
            lvl = self.forward_level if lg.name == "aeromag" else lg.level
            if lvl:
                return lvl
            lg = lg.parent  # type: ignore[assignment]
        return logging.WARNING

    def emit(self, record: logging.LogRecord) -> None:
        if record.levelno >= logging.WARNING:
            try:
                msg = clean(record.getMessage())
            except Exception:  # noqa: BLE001 - a bad format string must not break a run
                msg = clean(str(record.msg))
            sink = self.stack[-1].warnings if self.stack else self.sink  # innermost set
            if msg not in sink:
                sink.append(msg)
        if record.levelno < self._level_of(record.name):
            return
        try:  # names from files echoed without their control characters
            record.msg, record.args = clean(record.getMessage()), None
        except Exception:  # noqa: BLE001
            pass
        root = logging.getLogger()
        if root.handlers:
            for h in root.handlers:
                if record.levelno >= h.level:
                    h.handle(record)
        elif logging.lastResort is not None and record.levelno >= logging.lastResort.level:
            logging.lastResort.handle(record)


@contextlib.contextmanager
def _capture_warnings(sink: list[str]) -> Iterator[None]:
    lg = logging.getLogger("aeromag")
    if any(isinstance(h, _WarningCapture) for h in lg.handlers):
        yield  # an enclosing set captures already (into its own list)
        return
    level, propagate = lg.level, lg.propagate
    # forward_level: the level set on "aeromag" itself (0: inherited from the root)
    h = _WarningCapture(sink, level or logging.getLogger().getEffectiveLevel())
    lg.setLevel(min(lg.getEffectiveLevel(), logging.WARNING))
    lg.propagate = False
    lg.addHandler(h)
    try:
        yield
    finally:
        lg.removeHandler(h)
        lg.setLevel(level)
        lg.propagate = propagate


def recorded_warnings() -> list[str]:
    """The warnings logged so far in the current output set (empty outside one)."""
    s = _active()
    return list(s.warnings) if s is not None else []


def report_warnings(own: Sequence[str]) -> list[str]:
    """A report's ``warnings``: its own, then those logged in the set that it does not hold.

    A report lists the warnings its code found (in the library's words) and the set records
    every warning logged while it ran, some of them the same message.  Inside a set opened
    with ``rewrite`` (the command line names flags where the library names parameters,
    :func:`output_set`), the report's own are spelt the same way first, so that one warning
    is listed once.

    Parameters
    ----------
    own : sequence of str
        The report's own warnings.

    Returns
    -------
    list of str
    """
    s = _active()
    if s is None:
        return list(own)
    mine = [s.rewrite(w) for w in own] if s.rewrite is not None else list(own)
    return [*mine, *(w for w in s.warnings if w not in mine)]


_state = threading.local()


def _stack() -> list[_OutputSet]:
    st = getattr(_state, "stack", None)
    if st is None:
        st = _state.stack = []
    return st


def _active() -> _OutputSet | None:
    st = _stack()
    return st[-1] if st else None


def temp_path_for(target: Path) -> Path:
    """A fresh temporary name beside ``target`` that names this process."""
    return target.parent / f".{target.name}.{TEMP_MARK}-{os.getpid()}-{secrets.token_hex(4)}.tmp"


def _pid_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # somebody else's live process
        return True
    except OSError:
        return True
    return True


def remove_stale_temporaries(target: str | os.PathLike[str]) -> list[Path]:
    """Remove the temporary files of ``target`` whose writing process is gone.

    Parameters
    ----------
    target : path-like
        An output file.

    Returns
    -------
    list of Path
        The temporaries removed.
    """
    t = Path(target)
    removed = []
    try:
        entries = list(os.scandir(t.parent if str(t.parent) else "."))
    except OSError:
        return removed
    for e in entries:
        m = _TEMP_NAME.match(e.name)
        if not m or m.group("name") != t.name or _pid_alive(int(m.group("pid"))):
            continue
        with contextlib.suppress(OSError):
            os.unlink(e.path)
            removed.append(Path(e.path))
            log.info("removed %s, left by an interrupted run", e.path)
    return removed


def display_path(path: str | os.PathLike[str]) -> Path:
    """The output a path stands for in messages: the target of a temporary, else itself.

    Writers called on another writer's temporary (``write_table(df, tmp)``) name the real
    output in their errors, never the hidden temporary.
    """
    p = Path(path)
    for _ in range(8):
        s = _active()
        target = next((t for tmp, t in (s.pending if s else []) if tmp == p), None)
        if target is None:
            return p
        p = target
    return p


def _same_file(a: Path, b: Path) -> bool:
    try:
        if a.resolve() == b.resolve():
            return True
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except (OSError, RuntimeError):  # RuntimeError: a symbolic-link loop (Python < 3.13)
        return False


def register_input(path: str | os.PathLike[str], kind: str = "input log") -> None:
    """Note that the running command reads ``path``: no output of it may overwrite that file.

    Does nothing outside an :func:`output_set`.

    Parameters
    ----------
    path : path-like
        An input file.
    kind : str
        What it is, for the message (``"input log"``, ``"model"``, ``"plan"`` ...).
    """
    s = _active()
    if s is not None:
        s.inputs.setdefault(Path(path), kind)


def check_output_path(target: str | os.PathLike[str]) -> None:
    """Refuse an output that is not a regular file path, or that is an input of the command.

    Parameters
    ----------
    target : path-like
        The output file.

    Raises
    ------
    InputError
        When ``target`` is a folder, a device, a FIFO or a socket, or an input registered
        with :func:`register_input`.
    """
    t = Path(target)
    try:
        st = os.stat(t)
    except FileNotFoundError:
        st = None
    except OSError:
        st = None
    if st is not None and stat.S_ISDIR(st.st_mode):
        raise InputError(f"-o {clean(str(t))}: is a folder; give a file name, e.g."
                         f" -o {clean(str(t / 'out.csv'))}")
    if st is not None and not stat.S_ISREG(st.st_mode):
        what = ("a FIFO" if stat.S_ISFIFO(st.st_mode) else "a socket" if stat.S_ISSOCK(
            st.st_mode) else "a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(
            st.st_mode) else "not a regular file")
        raise InputError(f"-o {clean(str(t))}: is {what}, not a regular file; aeromag writes"
                         " its outputs as files (written whole, then renamed into place):"
                         " give a file path")
    s = _active()
    if s is not None:
        for src, kind in s.inputs.items():
            if _same_file(t, src):
                raise InputError(f"{clean(str(src))}: -o {clean(str(t))} would overwrite the"
                                 f" {kind}; choose another -o")


def _named(exc: OSError, target: Path) -> OSError:
    """The same error, naming the output instead of its temporary file."""
    out = OSError(exc.errno, exc.strerror or str(exc), str(target))
    return out


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success.

    On any exception (Ctrl-C and SIGTERM included) the temporary file is removed and ``path``
    is left untouched, so no partial output is ever left behind.  Inside an
    :func:`output_set` (or another ``atomic_path``) the rename waits for the end of the set.
    An error of the file system (disk full, read-only) names ``path``, not the temporary.

    Parameters
    ----------
    path : path-like
        Final destination (a regular file path; see :func:`check_output_path`).
    """
    target = Path(path)
    check_output_path(target)
    with output_set() as s:
        try:
            if str(target.parent) and not target.parent.exists():
                target.parent.mkdir(parents=True, exist_ok=True)
            remove_stale_temporaries(target)
            tmp = temp_path_for(target)
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666 & ~_UMASK)
            os.close(fd)
        except OSError as exc:
            raise _named(exc, target) from None
        # A writer that writes into another writer's temporary renames first.
        at = next((i for i, (t, _) in enumerate(s.pending) if t == target), len(s.pending))
        s.pending.insert(at, (tmp, target))
        try:
            yield tmp
        except OSError as exc:
            if exc.filename is not None and Path(exc.filename) == tmp:
                raise _named(exc, target) from None
            if exc.filename is None and exc.errno in (errno.ENOSPC, errno.EROFS, errno.EDQUOT,
                                                      errno.EFBIG, errno.EIO):
                raise _named(exc, target) from None
            raise


def _install_signal_handlers() -> dict[int, object] | None:
    """SIGTERM (and SIGHUP) raise SystemExit in the main thread, so that clean-up runs."""
    if threading.current_thread() is not threading.main_thread():
        return None
    old: dict[int, object] = {}

    def handler(signum: int, frame: object) -> None:
        raise SystemExit(128 + signum)

    for sig in (signal.SIGTERM, getattr(signal, "SIGHUP", None)):
        if sig is None:
            continue
        try:
            prev = signal.getsignal(sig)
            if prev is signal.SIG_IGN:  # e.g. nohup: keep ignoring
                continue
            signal.signal(sig, handler)
            old[sig] = prev
        except (ValueError, OSError):  # pragma: no cover - not in the main thread
            continue
    return old


def _restore_signal_handlers(old: dict[int, object] | None) -> None:
    for sig, prev in (old or {}).items():
        with contextlib.suppress(ValueError, OSError, TypeError):
            signal.signal(sig, prev)  # type: ignore[arg-type]


@contextlib.contextmanager
def output_set(*, separate: bool = False,
               rewrite: Callable[[str], str] | None = None) -> Iterator[_OutputSet]:
    """Write every output of the block as one set: all appear together, or none does.

    Files written with :func:`atomic_path` inside the block go to temporary names; at the
    end of the outermost block they are renamed onto their targets in the order they were
    written.  On an exception (Ctrl-C, SIGTERM: a handler turns it into ``SystemExit`` while
    a set is open) every temporary is removed.  Blocks nest: an inner block joins the outer
    set, unless ``separate`` (one set per file of a batch) makes it a set of its own.

    Parameters
    ----------
    separate : bool
        Commit this block's files at its end even inside another set (its inputs are
        those of the enclosing set, plus its own).
    rewrite : callable, optional
        How the reports written in the set spell their own warnings (:func:`report_warnings`);
        the command line passes the function that names its flags.  An inner set inherits
        the outer one's.

    Yields
    ------
    the set (internal)
    """
    stack = _stack()
    outer = not stack or separate
    handlers = None
    if outer:
        s = _OutputSet(inputs=dict(stack[-1].inputs) if stack else {},
                       rewrite=rewrite or (stack[-1].rewrite if stack else None))
        if not stack:
            handlers = _install_signal_handlers()
        stack.append(s)
    else:
        s = stack[-1]
    s.depth += 1
    try:
        with _capture_warnings(s.warnings) if outer else contextlib.nullcontext():
            yield s
        if outer:
            _commit(s)
    except BaseException as exc:
        if outer:
            if _clean_exit(exc):
                _commit(s)
            else:
                _discard(s)
        raise
    finally:
        s.depth -= 1
        if outer:
            stack.pop()
            _restore_signal_handlers(handlers)


def _clean_exit(exc: BaseException) -> bool:
    """A successful early exit (``SystemExit(0)``, ``typer.Exit(0)``): the outputs stand."""
    if isinstance(exc, SystemExit):
        return exc.code in (0, None)
    code = getattr(exc, "exit_code", None)
    return code == 0 and type(exc).__name__ == "Exit"


def _commit(s: _OutputSet) -> None:
    """Rename the set's temporaries onto their targets, in order."""
    while s.pending:
        tmp, target = s.pending[0]
        if not tmp.exists():  # renamed by a nested writer onto another temporary
            s.pending.pop(0)
            continue
        try:
            os.replace(tmp, target)
        except OSError as exc:
            raise _named(exc, target) from None
        s.pending.pop(0)


def _discard(s: _OutputSet) -> None:
    for tmp, _ in s.pending:
        with contextlib.suppress(OSError):
            tmp.unlink()
    s.pending.clear()


#: Output names whose report is the name with its suffix replaced (interface.md: "OUT.json
#: is OUT.csv with the suffix .json"); every other output keeps its suffix in the report's.
CSV_SUFFIXES = (".csv", ".txt")


def json_path_for(csv_path: str | os.PathLike[str]) -> Path:
    """Return the report path of an output log: ``OUT.json`` for ``OUT.csv``.

    A CSV output (``.csv``, ``.txt``) has its suffix replaced, as interface.md says; any other
    output is named in full, ``OUT.parquet.json`` and ``OUT.xyz.json``, so that ``-o
    d/survey.parquet`` and ``-o d/survey.xyz`` (or ``d/survey.csv``) never write the same
    report.  A name without a suffix gets ``.json`` added.
    """
    p = Path(csv_path)
    if p.suffix.lower() in CSV_SUFFIXES or not p.suffix or p.suffix.lower() == ".json":
        return p.with_suffix(".json")
    return p.with_name(p.name + ".json")


def check_report_owner(json_path: str | os.PathLike[str],
                       output_path: str | os.PathLike[str]) -> None:
    """Refuse to replace a JSON report that describes another output.

    A report records the file it describes in its ``output`` key (a file name beside the
    report): ``aeromag level -o lev.csv`` and ``aeromag grid lev.csv -o lev.nc`` would both
    write ``lev.json``, and the second would silently replace the first (which the grid step
    reads for the CRS).  A report without ``output``, unreadable, or describing this very
    output may be replaced.

    Parameters
    ----------
    json_path : path-like
        The report about to be written.
    output_path : path-like
        The output that report describes.

    Raises
    ------
    InputError
        When ``json_path`` exists and records another ``output``.
    """
    import json

    jp, out = Path(json_path), Path(output_path)
    if not jp.is_file():
        return
    try:
        owner = json.loads(jp.read_text(encoding="utf-8")).get("output")
    except (OSError, ValueError, AttributeError):
        return
    if isinstance(owner, str) and owner and Path(owner).name != out.name:
        raise InputError(f"-o {clean(str(out))}: its report {clean(str(jp))} is the report of"
                         f" {clean(Path(owner).name)} and would be replaced; give another -o"
                         f" name, e.g. -o {clean(out.stem + '_grid' + out.suffix)}")


def check_outputs(source: str | os.PathLike[str] | None, *outputs: str | os.PathLike[str],
                  kind: str = "input log",
                  inputs: Sequence[tuple[str | os.PathLike[str], str]] = ()) -> None:
    """Refuse outputs that would overwrite an input (the log, a plan, a model) or are no files.

    Parameters
    ----------
    source : path-like or None
        The input file.
    *outputs : path-like
        Files about to be written (e.g. OUT.csv and its report OUT.json).
    kind : str
        What ``source`` is, for the message.
    inputs : sequence of (path-like, str)
        Other inputs and what they are (``"model"``, ``"plan"``).

    Raises
    ------
    InputError
        When an output is one of the inputs (or an input registered with
        :func:`register_input`), is not a regular file path, or when the first of several
        outputs (the data, when its report is the second) ends in ``.json`` so that the
        report would replace it.
    """
    if outputs and len(outputs) > 1 and json_path_for(Path(outputs[0])) == Path(outputs[0]):
        raise InputError(f"-o {clean(str(outputs[0]))}: the report goes to OUT.json, so OUT"
                         " must not end in .json; give the output another name, e.g."
                         " -o survey_comp.csv")
    if len(outputs) > 1 and Path(outputs[1]) == json_path_for(Path(outputs[0])):
        check_report_owner(outputs[1], outputs[0])
    pairs = ([(source, kind)] if source is not None else []) + list(inputs)
    for out in outputs:
        o = Path(out)
        check_output_path(o)
        for src, what in pairs:
            if src is not None and _same_file(o, Path(src)):
                raise InputError(f"{clean(str(src))}: -o {clean(str(o))} would overwrite the"
                                 f" {what}; choose another -o")
