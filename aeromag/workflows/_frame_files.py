"""File in, files out around a frame function: the preamble the online commands share."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

import pandas as pd

from .._core.rls import check_forgetting
from ..io import atomic_path, json_path_for, read_log, write_csv, write_json
from .compensate import check_outputs


class JSONReport(Protocol):
    """A typed report: its JSON is ``to_dict()``; ``warnings`` gets the logged ones."""

    warnings: list[str]

    def to_dict(self) -> dict[str, Any]: ...


def frame_to_files(log_path: str | os.PathLike, out_path: str | os.PathLike, forgetting: float,
                   frame: Callable[[pd.DataFrame],
                                   tuple[pd.DataFrame, JSONReport, Any]], *,
                   columns: dict[str, str] | None = None,
                   units: dict[str, str] | None = None,
                   fmt: str | None = None) -> JSONReport:
    """Check the paths and lambda, read the log, run ``frame``, write OUT.csv and OUT.json.

    Parameters
    ----------
    log_path, out_path : path-like
        Input log and output CSV (the report goes to OUT.json; both are written or neither).
    forgetting : float
        Forgetting factor lambda (checked before the log is read).
    frame : callable
        ``frame(df) -> (data, report, extra)``; ``extra`` is ignored.  ``report`` is a typed
        report (:class:`JSONReport`: OUT.json is its ``to_dict()``, and the warnings the
        command logged are recorded in its ``warnings``).
    columns, units, fmt
        Passed to :func:`aeromag.io.read_log` (``time`` is required).

    Returns
    -------
    JSONReport
        The report ``frame`` returned, its ``warnings`` as written.
    """
    out = Path(out_path)
    out_json = json_path_for(out)
    check_outputs(log_path, out, out_json)
    check_forgetting(forgetting)
    df = read_log(log_path, columns=columns, units=units, required=("time",), fmt=fmt)
    data, report, _ = frame(df)
    doc = report.to_dict()
    with atomic_path(out) as tmp_csv, atomic_path(out_json) as tmp_json:
        write_csv(data, tmp_csv)
        write_json(doc, tmp_json)
    report.warnings = doc.get("warnings")  # with those the command logged, as in the file
    return report
