"""Inputs of ``aeromag batch``: files, globs and folders; output names; fingerprints.

The fingerprint tells whether a file's outputs are up to date.
"""

from __future__ import annotations

import dataclasses
import glob
import hashlib
import json
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

#: Extensions picked up when an input is a folder.
LOG_EXTENSIONS: tuple[str, ...] = (".csv", ".txt", ".parquet", ".pq", ".xyz", ".h5", ".hdf5")

#: Suffix of the per-file fingerprint written beside the outputs (``.NAME.batch.json``).
FINGERPRINT_SUFFIX = ".batch.json"


# --------------------------------------------------------------------------- inputs
def expand_inputs(inputs: Iterable[str | os.PathLike[str]]) -> tuple[list[Path], list[str]]:
    """Expand files, globs and folders into a sorted list of log files.

    Parameters
    ----------
    inputs : iterable of path-like
        Files, glob patterns (``logs/*.csv``) or folders (their log files, not recursive).

    Returns
    -------
    files : list of Path
        Distinct files, in the order given (folders and globs sorted).
    unmatched : list of str
        Inputs that matched nothing.
    """
    files: list[Path] = []
    unmatched: list[str] = []
    seen: set[Path] = set()

    def add(p: Path) -> None:
        key = p.resolve()
        if key not in seen:
            seen.add(key)
            files.append(p)

    for item in inputs:
        s = str(item)
        p = Path(s)
        if p.is_dir():
            found = sorted(q for q in p.iterdir()
                           if q.is_file() and q.suffix.lower() in LOG_EXTENSIONS
                           and not q.name.startswith("."))
            if not found:
                unmatched.append(s)
            for q in found:
                add(q)
        elif p.exists():
            add(p)
        elif glob.has_magic(s):
            found = sorted(Path(g) for g in glob.glob(s) if Path(g).is_file())
            if not found:
                unmatched.append(s)
            for q in found:
                add(q)
        else:
            unmatched.append(s)
    return files, unmatched


def unmatched_reason(item: str) -> str:
    """One-line reason why an input matched no log file, and what to do.

    Parameters
    ----------
    item : str
        An input of :func:`expand_inputs` that it returned as unmatched.

    Returns
    -------
    str
        ``"ITEM: ..."``.
    """
    p = Path(item)
    if p.is_dir():
        exts = ", ".join(f"*{e}" for e in LOG_EXTENSIONS)
        return (f"{item}: the folder holds no log files (looked for {exts}, not in"
                " sub-folders); give the log files themselves or another folder")
    if glob.has_magic(item):
        return f"{item}: no file matches this pattern; check the folder and the pattern"
    return f"{item}: no such file or folder; check the path"


def output_names(inp: Path, out_dir: Path) -> dict[str, Path]:
    """Output paths of one input.

    Parameters
    ----------
    inp : Path
        Input log ``NAME.ext``.
    out_dir : Path
        Output folder.

    Returns
    -------
    dict
        ``comp`` (NAME_comp.csv), ``track`` (NAME_track.csv) and ``fingerprint``
        (.NAME.batch.json).
    """
    return {"comp": out_dir / f"{inp.stem}_comp.csv", "track": out_dir / f"{inp.stem}_track.csv",
            "fingerprint": out_dir / f".{inp.stem}{FINGERPRINT_SUFFIX}"}


def up_to_date(outputs: Sequence[Path], sources: Sequence[Path]) -> bool:
    """True when every output exists and is newer than every source (modification times)."""
    try:
        oldest_out = min(p.stat().st_mtime for p in outputs)
        newest_in = max(p.stat().st_mtime for p in sources)
    except (FileNotFoundError, ValueError):
        return False
    return oldest_out > newest_in


def file_sha256(path: str | os.PathLike[str]) -> str:
    """SHA-256 of a file's contents (hex), read in 1 MiB blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def batch_fingerprint(
    *,
    cfg: Any,
    model: str | os.PathLike[str] | None = None,
    plan: str | os.PathLike[str] | None = None,
    columns: dict[str, str] | None = None,
    units: dict[str, str] | None = None,
    fmt: str | None = None,
    chunk_rows: int | None = None,
    track_options: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """What a file's outputs depend on besides the file itself, and its digest.

    Parameters
    ----------
    cfg : CompensationConfig
        Effective pipeline options.
    model, plan : path-like, optional
        Model and plan files (their contents are hashed, not their names or times).
    columns, units : dict, optional
        Column map and unit conversions.
    fmt : str, optional
        Input format.
    chunk_rows : int, optional
        Chunk size of the model application (counts only with a model).
    track_options : dict, optional
        Keyword arguments of :func:`aeromag.track.track_file` (count only with a plan).

    Returns
    -------
    dict
        ``fingerprint`` (SHA-256 hex of the other entries, as sorted JSON) and the entries:
        ``aeromag`` (version), ``config``, ``model_sha256``, ``plan_sha256``, ``columns``,
        ``units``, ``format``, ``chunk_rows``, ``track``.
    """
    from .. import __version__
    from ..compensation.config import CompensationConfig, config_dict

    config = (config_dict(cfg) if isinstance(cfg, CompensationConfig)
              else dataclasses.asdict(cfg) if dataclasses.is_dataclass(cfg) else repr(cfg))
    parts: dict[str, Any] = {
        "aeromag": __version__,
        "config": config,
        "model_sha256": None if model is None else file_sha256(model),
        "plan_sha256": None if plan is None else file_sha256(plan),
        "columns": dict(sorted(columns.items())) if columns else None,
        "units": dict(sorted(units.items())) if units else None,
        "format": fmt,
        "chunk_rows": chunk_rows if model is not None else None,
        "track": (dict(sorted((track_options or {}).items())) if plan is not None else None),
    }
    text = json.dumps(parts, sort_keys=True, default=str)
    parts = json.loads(text)  # the stored form: tuples as lists, objects as text
    return {"fingerprint": hashlib.sha256(text.encode()).hexdigest(), **parts}


def stored_fingerprint(path: Path) -> str | None:
    """The fingerprint stored by a file's last successful run, or None."""
    try:
        return str(json.loads(path.read_text(encoding="utf-8"))["fingerprint"])
    except (OSError, ValueError, KeyError, TypeError):
        return None
