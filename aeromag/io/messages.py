"""Text echoed back to the user: file and column names without control characters."""

from __future__ import annotations

import re

#: Terminal escape sequences (CSI, OSC ...) and the remaining C0 / C1 control characters.
_ESCAPES = re.compile(r"\x1b\[[0-?]*[ -/]*[@-~]|\x1b\][^\x07\x1b]*(?:\x07|\x1b\\)?|\x1b.?")
_CONTROLS = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f]")
#: Longest run of non-blank characters echoed whole (a longer one is an echoed cell or line:
#: a 10 MB row must not become a 10 MB message).
MAX_ECHO_CHARS = 400
_LONG_RUN = re.compile(rf"\S{{{MAX_ECHO_CHARS + 1},}}")


def _shorten(m: re.Match[str]) -> str:
    run = m.group(0)
    return f"{run[:60]}...[{len(run) - 80} characters]...{run[-20:]}"


def clean(text: object) -> str:
    """``text`` without terminal escape sequences and control characters.

    Each control character (bell, backspace, carriage return, escape ...) becomes ``?``, so
    that a name from a file can never move the cursor, recolour or retitle the terminal, or
    hide part of a message.  Tabs are kept; a newline becomes a blank (one-line messages).

    Parameters
    ----------
    text : object
        A message, a file name or a column name.

    Returns
    -------
    str
    """
    s = str(text)
    if len(s) > MAX_ECHO_CHARS:
        s = _LONG_RUN.sub(_shorten, s)
    if not _CONTROLS.search(s) and "\n" not in s and "\x1b" not in s:
        return s
    s = _ESCAPES.sub("?", s).replace("\n", " ")
    return _CONTROLS.sub("?", s)


def check_input_file(path: object, what: str = "log file") -> None:
    """Refuse an input path that is not a readable regular file, with a one-line reason.

    Checked before the file is opened, so that a FIFO or a device never blocks or streams
    without end, and a symbolic-link loop, a folder or a missing file is named as such.

    Parameters
    ----------
    path : path-like
        The input.
    what : str
        What it should be, for the message.

    Raises
    ------
    InputError
        When ``path`` is missing, a folder, a FIFO, socket or device, a symbolic-link loop, or
        cannot be examined.
    """
    import errno
    import os
    import stat

    from ..errors import InputError

    name = clean(path)
    try:
        st = os.stat(path)  # follows links
    except FileNotFoundError:
        if os.path.islink(path):  # type: ignore[arg-type]
            raise InputError(f"{name}: a symbolic link to a file that does not exist; give"
                             f" the {what} itself") from None
        raise InputError(f"{name}: file not found; check the path") from None
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise InputError(f"{name}: a loop of symbolic links, not a {what}; give the"
                             f" {what} itself") from None
        raise InputError(f"{name}: cannot read ({exc.strerror or exc}); check the path and"
                         " its permissions") from None
    if stat.S_ISDIR(st.st_mode):
        raise InputError(f"{name}: is a folder, not a {what}; give the {what} itself")
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"{name}: not a regular file (a FIFO, socket or device), not a"
                         f" {what}; give a {what} on disk")
    if not os.access(path, os.R_OK):  # type: ignore[arg-type]
        raise InputError(f"{name}: permission denied; make the {what} readable (chmod +r)")
