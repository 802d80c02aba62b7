"""JSON documents (reports, models) written atomically, NaN and inf as ``null``."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from .outputs import atomic_path, report_warnings


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return _clean_float(float(obj))
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def _clean_float(x: float) -> float | None:
    return None if (math.isnan(x) or math.isinf(x)) else x


def _jsonable(obj: Any) -> Any:
    """Replace NaN/inf by None recursively (JSON has no NaN)."""
    if isinstance(obj, float):
        return _clean_float(obj)
    if isinstance(obj, np.floating):
        return _clean_float(float(obj))
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    return obj


#: Keys that mark a JSON document as a command's report (it gets the recorded warnings).
REPORT_KEYS = frozenset({"source", "input", "warnings"})


def write_json(obj: Any, path: str | os.PathLike[str]) -> Path:
    """Write a JSON document atomically (NaN and inf written as ``null``).

    A report (a dict with a ``source``, ``input`` or ``warnings`` key) written inside an
    output set (every command) gets the warnings logged so far by the command in a
    ``warnings`` list (added to ``obj`` too; ``[]`` when there were none): what a user was told
    on the terminal is recorded beside the results.

    Parameters
    ----------
    obj : object
        JSON-serialisable data (numpy scalars and arrays are converted).
    path : path-like
        Destination file.

    Returns
    -------
    Path
        The written path.
    """
    target = Path(path)
    if isinstance(obj, dict) and REPORT_KEYS & obj.keys():
        # Always a list, empty when nothing was said: one shape for every command's report.
        obj["warnings"] = report_warnings(obj.get("warnings") or [])
    text = dumps_readable(_jsonable(obj))
    with atomic_path(target) as tmp:
        tmp.write_text(text + "\n", encoding="utf-8")
    return target


_ENCODER = json.JSONEncoder(allow_nan=False, default=_json_default, separators=(", ", ": "))


def dumps_readable(obj: Any, indent: int = 2) -> str:
    """JSON text with dicts indented and each element of a list of containers on one line.

    ``json.dumps(indent=...)`` runs the pure-Python encoder over every value (0.1 s for a
    3 MB model file of 1,667 segments); here only the dicts outside lists are walked in
    Python, and every list is written by the C encoder: a list of numbers on one line, a list
    of dicts or lists (segments, table rows) one element per line.  The file stays readable
    and parses to the same document.

    Parameters
    ----------
    obj : object
        JSON-ready data (NaN and inf already replaced; numpy scalars are converted).
    indent : int
        Spaces per level of dict nesting.

    Returns
    -------
    str
        The JSON text (no trailing newline).
    """
    out: list[str] = []
    _write(obj, out, " " * indent, 0)
    return "".join(out)


def _write(obj: Any, out: list[str], ind: str, level: int) -> None:
    enc = _ENCODER.encode
    if isinstance(obj, dict) and obj:
        pad = ind * (level + 1)
        out.append("{")
        sep = "\n"
        for k, v in obj.items():
            out.append(f"{sep}{pad}{enc(str(k) if not isinstance(k, str) else k)}: ")
            _write(v, out, ind, level + 1)
            sep = ",\n"
        out.append(f"\n{ind * level}}}")
    elif isinstance(obj, list | tuple) and obj and any(
            isinstance(v, dict | list | tuple) for v in obj):
        pad = ind * (level + 1)
        out.append("[\n" + ",\n".join(pad + enc(v) for v in obj) + f"\n{ind * level}]")
    else:
        out.append(enc(obj))
