"""``aeromag level``: a survey log in, the levelled anomaly (OUT.csv) and OUT.json out.

:func:`level` is the Python entry point (``am.level``): a table or a file, a base record as a
file, several files, a ``BaseRecord`` or a ``time,mag`` table; :func:`level_file` reads, runs
the chain (:func:`aeromag.survey.chain.level_survey`) and writes OUT (``.csv``, ``.parquet``
or ``.xyz``: Geosoft XYZ with a ``Line``/``Tie`` header per line, so the result opens in
Oasis montaj with its line structure) and OUT.json, both or neither.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..errors import InputError
from ..io import atomic_path, json_path_for, read_log, write_json
from ..io.base import read_base
from ..io.formats import output_format, write_table
from ..io.outputs import check_outputs, output_set
from ..survey.chain import LevelResult, level_survey
from ..survey.diurnal import BaseRecord

log = logging.getLogger(__name__)

__all__ = ["level", "level_file", "base_record"]

PathLike = str | os.PathLike[str]


def base_record(base: PathLike | Sequence[PathLike] | BaseRecord | pd.DataFrame | None,
                date: str | None = None) -> BaseRecord | None:
    """A base-station record from a file, files, a ``time,mag`` table or a record.

    Parameters
    ----------
    base : path-like, sequence of path-like, BaseRecord, DataFrame or None
        The record.
    date : str, optional
        ``YYYY-MM-DD``, for a base dump without its date (G-856: the year).

    Returns
    -------
    BaseRecord or None
    """
    if base is None or isinstance(base, BaseRecord):
        return base
    if isinstance(base, pd.DataFrame):
        missing = [c for c in ("time", "mag") if c not in base.columns]
        if missing:
            raise InputError(f"base table: missing column(s) {', '.join(missing)}")
        return BaseRecord(base["time"].to_numpy(float), base["mag"].to_numpy(float),
                          str(base.attrs.get("source", "<base>")))
    t, v, src, notes = read_base(base, date=date)
    return BaseRecord(t, v, src, tuple(notes))


def _parse_ties(ties: str | Sequence[float]) -> str | list[float]:
    if not isinstance(ties, str):
        return [float(v) for v in ties]
    if ties.strip().lower() == "auto":
        return "auto"
    try:
        return [float(v) for v in ties.split(",") if v.strip()]
    except ValueError:
        raise InputError(f"--ties {ties}: give auto or tie-line numbers ID,ID,...") from None


def level(survey: pd.DataFrame | PathLike, *,
          base: PathLike | Sequence[PathLike] | BaseRecord | pd.DataFrame | None = None,
          value: str | None = None, date: str | None = None, lag: float | str = 0.0,
          igrf: bool = True, ties: str | Sequence[float] = "auto", method: str = "trend",
          decorrugate: bool = False, crs: int | None = None,
          base_datum_nT: float | None = None, allow_base_gaps: bool = False,
          columns: dict[str, str] | None = None, units: dict[str, str] | None = None,
          fmt: str | None = None,
          progress: Callable[[int, int, str], None] | None = None) -> LevelResult:
    """Level a survey: lag, diurnal, IGRF removal, tie-line levelling, micro-levelling.

    Parameters
    ----------
    survey : DataFrame or path-like
        The survey (``time``, ``lat``, ``lon``, ``alt``, ``line``, a total field).
    base : path-like, list of path-like, BaseRecord or DataFrame, optional
        Base-station record(s): CSV ``time,mag``, IAGA-2002 ``.min``/``.sec``, a GEM GSM-19
        base file or a Geometrics G-856 dump (``date`` gives a G-856 dump its year).
    value : str, optional
        Column to level (default ``mag_comp``, else ``mag``).
    date : str, optional
        ``YYYY-MM-DD`` of a ``time`` in seconds since midnight UTC.
    lag : float or "auto"
        Magnetometer lag [s] (positive: the reading at t is the field at the position of
        t - lag).
    igrf : bool
        Remove the IGRF-14 total intensity (False: the value is an anomaly already).
    ties : "auto", "ID,ID,..." or sequence of float
        Tie lines.
    method : {"trend", "shift", "smooth", "none"}
        Levelling: a shift per tie, a shift and a linear trend (``trend``) or a smooth
        piecewise-linear correction (``smooth``) per line.
    decorrugate : bool
        Micro-level (``tmi_mlev``).
    crs : int, optional
        EPSG code (default: the UTM zone of the centre).
    base_datum_nT : float, optional
        Base datum [nT] (default: the base's mean over the survey).
    allow_base_gaps : bool
        Leave the diurnal empty (warning) where the base does not cover, instead of an error.
    columns, units, fmt
        How to read a survey file (see :func:`aeromag.io.read_log`).
    progress : callable, optional
        ``progress(done, total, step)``.

    Returns
    -------
    LevelResult
        ``.data`` (the table with ``x_m``, ``y_m``, ``line_type``, ``igrf``, ``diurnal``,
        ``tmi``, ``tmi_lev``, ``tmi_mlev``), each step's result and ``.to_report()``.
    """
    if isinstance(survey, pd.DataFrame):
        df, src = survey, str(survey.attrs.get("source", "<survey>"))
        if columns:
            df = df.rename(columns={v: k for k, v in columns.items()})
    else:
        src = str(survey)
        df = read_log(survey, columns=columns, units=units, required=(), fmt=fmt)
    return level_survey(df, value=value, base=base_record(base, date), date=date, lag=lag,
                        igrf=igrf, ties=_parse_ties(ties), method=method,
                        decorrugate_lines=decorrugate, crs=crs, base_datum_nT=base_datum_nT,
                        allow_base_gaps=allow_base_gaps, progress=progress, source=src)


def level_file(survey_path: PathLike, out_path: PathLike, *, plot_dir: PathLike | None = None,
               **kw: Any) -> LevelResult:
    """Read a survey, level it, write OUT and OUT.json (both or neither).

    Parameters
    ----------
    survey_path : path-like
        The survey log.
    out_path : path-like
        ``.csv``, ``.parquet`` or ``.xyz`` (Geosoft XYZ with Line/Tie headers); the report
        goes to OUT.json.
    plot_dir : path-like, optional
        Also write the QC page there (:func:`aeromag.workflows.survey_report.
        write_survey_report`: the anomaly map, mistie histograms, stacked profiles and
        ``report.html``).
    **kw
        Options of :func:`level`.

    Returns
    -------
    LevelResult
    """
    out = Path(out_path)
    out_json = json_path_for(out)
    with output_set():
        check_outputs(survey_path, out, out_json)  # and check_report_owner(out_json, out)
        fmt_out = output_format(out)
        base = kw.get("base")
        if base is not None and not isinstance(base, (BaseRecord, pd.DataFrame)):
            paths = [base] if isinstance(base, (str, os.PathLike)) else list(base)
            check_outputs(None, out, out_json, inputs=[(p, "base record") for p in paths])
        res = level(survey_path, **kw)
        report = {"input": str(survey_path), "output": out.name, **res.to_report()}
        data = res.data
        if fmt_out == "xyz":
            data = data.copy()
            data["line_type"] = np.where(data["line_type"] == "", "line", data["line_type"])
        with atomic_path(out) as tmp:
            write_table(data, tmp, fmt_out)
        if plot_dir is not None:
            from .survey_report import write_survey_report

            report["figures"] = [str(p) for p in write_survey_report(res, plot_dir,
                                                                     report=report)]
        write_json(report, out_json)
    return res
