"""Mission plans from files: a CSV of waypoints, QGroundControl ``.plan``, Mission Planner
``.waypoints``."""

from __future__ import annotations

import os
from pathlib import Path

import pandas as pd

from ..errors import InputError
from ..track.plan import PLAN_NEEDS, validate_plan
from .log import read_log

__all__ = ["read_plan"]


def _blank_file(path: Path, most: int = 1 << 16) -> bool:
    """True when a file holds nothing but white space (and a UTF-8 byte-order mark)."""
    try:
        if path.stat().st_size > most:
            return False
        data = path.read_bytes()
    except OSError:
        return False  # read_log reports it
    return not data.removeprefix(b"\xef\xbb\xbf").strip()


def read_plan(path: str | os.PathLike[str]) -> pd.DataFrame:
    """Read and validate a mission plan CSV.

    Parameters
    ----------
    path : path-like
        CSV of waypoints in flight order with ``lat``, ``lon`` [deg] and ``alt`` [m].

    Returns
    -------
    DataFrame
        The validated plan (see :func:`validate_plan`).
    """
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{p}: plan file not found (or not a file); check the --plan path")
    if _blank_file(p):
        raise InputError(f"{p}: the plan is empty; {PLAN_NEEDS}")
    # No required columns here: validate_plan says what a plan needs (--col is for logs).
    df = read_log(p, required=(), min_rows=0)
    return validate_plan(df, str(p))
