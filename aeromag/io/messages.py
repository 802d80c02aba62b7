"""Text echoed back to the user: file and column names without control characters."""

from __future__ import annotations

import re

#: Terminal escape sequences (CSI, OSC ...) and the remaining C0 / C1 control characters.
_ESCAPES = re.compile(r"\x1b\[[0-?]*[ -/]*[@-~]|\x1b\][^\x07\x1b]*(?:\x07|\x1b\\)?|\x1b.?")
_CONTROLS = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f]")


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
    if not _CONTROLS.search(s) and "\n" not in s and "\x1b" not in s:
        return s
    s = _ESCAPES.sub("?", s).replace("\n", " ")
    return _CONTROLS.sub("?", s)
