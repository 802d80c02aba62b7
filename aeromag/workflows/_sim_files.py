"""Writing a simulator's logs and truth as one set (all files or none)."""

from __future__ import annotations

import os
from contextlib import ExitStack
from pathlib import Path
from typing import Any

import pandas as pd

from ..errors import InputError
from ..io import atomic_path, write_csv, write_json


def sim_folder(out_dir: str | os.PathLike[str]) -> Path:
    """The output folder of a simulator, checked (not created) before anything is simulated.

    Parameters
    ----------
    out_dir : path-like
        Output folder.

    Returns
    -------
    Path
        ``out_dir``.

    Raises
    ------
    InputError
        When ``out_dir`` exists and is not a folder.
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a folder; give -o a folder")
    return out


def write_sim_set(out: Path, files: dict[str, tuple[str, pd.DataFrame | dict[str, Any]]]
                  ) -> dict[str, Path]:
    """Write tables as CSV and truth dicts as JSON into ``out``, atomically as one set.

    Parameters
    ----------
    out : Path
        Output folder (created when missing).
    files : dict
        ``key -> (file name, DataFrame or dict)``; a DataFrame goes through
        :func:`aeromag.io.write_csv`, a dict through :func:`aeromag.io.write_json`.

    Returns
    -------
    dict of str to Path
        ``key -> written path``, in the order of ``files``.
    """
    out.mkdir(parents=True, exist_ok=True)
    paths = {key: out / name for key, (name, _) in files.items()}
    with ExitStack() as stack:
        for key, (_, obj) in files.items():
            tmp = stack.enter_context(atomic_path(paths[key]))
            if isinstance(obj, pd.DataFrame):
                write_csv(obj, tmp)
            else:
                write_json(obj, tmp)
    return paths
