"""``aeromag compensate`` and ``aeromag calibrate`` as functions: file in, files out.

:func:`compensate` and :func:`calibrate` (``am.compensate``, ``am.calibrate``) are the
in-memory runs: the compensation of :mod:`aeromag.compensation.pipeline` plus the report's
``qc`` block from :mod:`aeromag.qc` (quality control builds on the compensation, so the two
meet here, above both).
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import os
import time
from dataclasses import dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeAlias

import numpy as np
import pandas as pd

from ..compensation import pipeline as _pipeline
from ..compensation.config import CompensationConfig
from ..compensation.model import TLModel
from ..compensation.report import flag_residual_outliers
from ..compensation.report_types import CalibrationCheck, CompensationReport, Segmentation
from ..compensation.result import CompensationResult
from ..conventions import FLUX_COLUMNS
from ..errors import AeromagError, InputError
from ..io import (
    atomic_path,
    check_outputs,
    json_path_for,
    read_log,
    write_csv_passthrough,
    write_json,
)
from ..io.formats import output_format, write_table
from ..io.outputs import output_set

if TYPE_CHECKING:
    from ..qc.maneuver_result import ManeuverResult

log = logging.getLogger(__name__)


__all__ = ["CompensationRun", "calibrate", "calibrate_file", "check_outputs", "compensate",
           "compensate_file", "write_outputs", "write_report_json"]


def compensate(
    df: pd.DataFrame, cfg: CompensationConfig | None = None, *, model: TLModel | None = None,
    source: str | None = None,
) -> CompensationRun:
    """Compensate a log in memory, report ``qc`` block included (``am.compensate``).

    Parameters
    ----------
    df, cfg, model, source
        As in :func:`aeromag.compensation.pipeline.run_compensation` (log, options, saved model to
        apply instead of fitting, file name for messages).

    Returns
    -------
    CompensationRun
        The pipeline's result with the report's ``qc`` block added.
    """
    with _one_blas_thread():
        res = _run(_pipeline.run_compensation(df, cfg, model=model, source=source))
        _add_qc(res)
    return res


def _one_blas_thread() -> contextlib.AbstractContextManager[Any]:
    """BLAS (OpenBLAS, MKL) on one thread for a run's fit and QC; threadpoolctl's public API.

    The run's arrays are small for BLAS (the screening's 1667 x 16 coefficient matrix, 17 x 17
    normal equations, dot products of 65,536 samples) and its parallel work already runs on the
    filter pool (:mod:`aeromag._core.parallel`).  A threaded OpenBLAS there only waits for its
    own threads: on this 2-core machine under load, scikit-learn's PCA of 1667 segments (one
    SVD of 1667 x 16) took 0.3 s wall and 0.17-0.19 s CPU on two BLAS threads and 0.0005 s on
    one.  Results are bitwise the same but for threaded dot products' last bit.  No-op when
    threadpoolctl (a scikit-learn dependency) is missing.
    """
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - scikit-learn requires it
        return contextlib.nullcontext()
    return threadpool_limits(limits=1, user_api="blas")


#: Heading legs and maneuver kinds that make a calibration box (docs/compensation.md).
_BOX_HEADINGS, _BOX_MANEUVERS = 4, frozenset({"pitch", "roll", "yaw"})


#: What :func:`_detect` found: the manoeuvres, or the error that stopped their detection.
_Detected: TypeAlias = "tuple[ManeuverResult | None, AeromagError | None]"


def _detect(df: pd.DataFrame, cfg: CompensationConfig | None, source: str) -> _Detected:
    """The manoeuvres and heading legs of a log, detected once for every use of one run.

    :func:`aeromag.qc.detect_maneuvers` (about 0.1 s per 1e6 rows) serves the segmentation of a
    log without lines, the calibration-box check and the QC's FOM; ``calibrate`` ran it three
    times on the same rows with the same options.
    """
    from ..qc import detect_maneuvers

    try:
        return detect_maneuvers(df, max_gap_s=cfg.max_gap_s if cfg else None, source=source), None
    except AeromagError as exc:
        return None, exc


def _self_calibration(df: pd.DataFrame, cfg: CompensationConfig | None,
                      source: str, *, calibrating: bool = False,
                      detected: _Detected | None = None) -> CalibrationCheck:
    """Whether a log fitted on itself holds a calibration box; warn when it does not.

    A survey's few headings and gusts separate the TL terms only in the band: the
    heading-dependent level of ``mag_tl`` is not determined (the fit is blind to what does
    not vary in the band), yet its in-sample metrics look excellent.  A box is at least
    ``_BOX_HEADINGS`` heading legs with pitch, roll and yaw maneuvers
    (:func:`aeromag.qc.detect_maneuvers`; ``detected``: already run on ``df``).
    """
    out: dict[str, Any] = {"metrics": "in-sample: fitted and measured on the same log, in the"
                           " band; they say nothing about the level outside it"}
    man, exc = detected if detected is not None else _detect(df, cfg, source)
    if man is None:
        headings, kinds, why = [], [], f"no maneuvers could be detected ({exc})"
    else:
        headings = sorted(set(man.legs["heading"].astype(str))) if len(man.legs) else []
        kinds = sorted(set(man.table["maneuver"].astype(str))) if len(man.table) else []
        why = (f"{len(headings)} heading(s) ({', '.join(headings) or 'none'}) and maneuvers"
               f" {', '.join(kinds) or 'none'}")
    box = len(headings) >= _BOX_HEADINGS and _BOX_MANEUVERS <= set(kinds)
    out.update(calibration_box=bool(box), headings=headings, maneuvers=kinds)
    if not box and calibrating:  # 'aeromag calibrate' on a log that is no calibration flight
        log.warning("%s: not a calibration flight: no calibration box (%s), so the model's"
                    " heading-dependent level is not determined and its Figure of Merit not"
                    " applicable; calibrate on a box (four headings, each with pitch, roll and"
                    " yaw maneuvers)", source, why)
    elif not box:
        log.warning("%s: fitted on itself without a calibration box (%s): the heading-dependent"
                    " level of mag_tl is not determined, and the improvement ratio is in-sample"
                    " and flattering; fly a box, run 'aeromag calibrate' on it and apply it with"
                    " model=MODEL", source, why)
    return CalibrationCheck(**out)


def calibrate(
    df: pd.DataFrame, cfg: CompensationConfig | None = None, *, source: str | None = None,
) -> CompensationRun:
    """Fit and screen the model on a calibration log in memory (``am.calibrate``).

    Parameters
    ----------
    df : DataFrame
        Calibration log with canonical columns.
    cfg : CompensationConfig, optional
        Options (the Figure of Merit is on unless ``cfg.fom`` is False).
    source : str, optional
        File name for messages and the report.

    Returns
    -------
    CompensationResult

    Without a ``line`` column the segments are the maneuvers that
    :func:`aeromag.qc.detect_maneuvers` finds (fixed time windows would cut across maneuvers
    and mix a faulty one with clean ones); when none is found, the time windows are used with a
    warning.  The report's ``segmentation`` says which.
    """
    segmentation = None
    detected = _detect(df, cfg, source or str(df.attrs.get("source", "<log>")))
    if "line" not in df.columns:
        df, segmentation = _segments_from_maneuvers(df, cfg, source, detected)
    with _one_blas_thread():
        res = _run(_pipeline.calibrate(df, cfg, source=source))
        if segmentation is not None:
            res.report.segmentation = segmentation  # the model's too (its meta is the report)
        _add_qc(res, maneuvers=_for_qc(detected[0], df, res))
    # As compensate warns when it fits a log without a box: the same check, the same warning.
    box = _self_calibration(df, cfg, source or "<log>", calibrating=True, detected=detected)
    box.metrics = None  # the in-sample note is compensate's (a log fitted on itself)
    res.report.calibration_box = box
    if segmentation is not None and res.data is not None and "line" in res.data.columns:
        # The detected legs were the fit's 'line' column, but they are no flight lines:
        # segments are named by id and time span, never "line 9" (issue 15).
        from ..compensation.report import name_segments

        name_segments(res.report.segments, lines=False)  # the model's report's rows too
        res.data = res.data.drop(columns="line")
    return res


def _segments_from_maneuvers(df: pd.DataFrame, cfg: CompensationConfig | None,
                             source: str | None, detected: _Detected,
                             ) -> tuple[pd.DataFrame, Segmentation]:
    """A ``line`` column from the detected maneuvers (or heading legs) of a calibration log."""
    src = source or str(df.attrs.get("source", "<log>"))
    seconds = (cfg or CompensationConfig()).segment_seconds
    man, exc = detected
    why = str(exc) if man is None else "no maneuver or heading leg was found"
    if man is not None and len(man.table):
        line, what = man.labels["maneuver_id"].to_numpy(dtype=float), "detected maneuvers"
    elif man is not None and len(man.legs):
        line, what = man.labels["leg_id"].to_numpy(dtype=float), "detected heading legs"
    else:
        log.warning("%s: the log has no 'line' column and %s: fitting %g-s time windows, which"
                    " cut across maneuvers (a faulty maneuver then spoils clean ones); give the"
                    " flight's lines with columns={'line': 'SOURCE'}", src, why, seconds)
        return df, Segmentation("time windows", segment_seconds=seconds, reason=why)
    line[line < 0] = np.nan
    n = int(np.unique(line[np.isfinite(line)]).size)
    log.info("%s: no 'line' column: %d %s are the segments", src, n, what)
    return df.assign(line=line), Segmentation(what, detector=man.method, n_segments=n)


#: Columns :func:`aeromag.qc.detect_maneuvers` reads (besides ``df.attrs["source"]``).
@dataclass(repr=False)  # CompensationResult's short repr, not every field
class CompensationRun(CompensationResult):
    """A :class:`~aeromag.compensation.result.CompensationResult` with figures, QC and report.

    What :func:`compensate` and :func:`calibrate` (``am.compensate``, ``am.calibrate``) return:
    the result plus methods that draw its figures (:mod:`aeromag.plot.compensation`), compute
    its quality control (:mod:`aeromag.qc`) and write the HTML report; they live here, above
    the compensation, plot and QC packages they join.
    """

    # Figures (matplotlib Figure objects, headless; see aeromag.plot.compensation).
    def plot_pca_scores(self, **kw: Any) -> Any:
        """The PCA score plot (PC1 vs PC2): kept/dropped segments, decision boundary."""
        from ..plot import compensation as pc

        return pc.plot_pca_scores(self.report, **kw)

    def plot_explained_variance(self, **kw: Any) -> Any:
        """Explained-variance bars of the screening PCA."""
        from ..plot import compensation as pc

        return pc.plot_explained_variance(self.report, **kw)

    def plot_timeseries(self, **kw: Any) -> Any:
        """Uncompensated vs compensated total field against time."""
        from ..plot import compensation as pc

        return pc.plot_timeseries(self._data(), **kw)

    def plot_psd(self, **kw: Any) -> Any:
        """Power spectral density before and after compensation."""
        from ..plot import compensation as pc

        kw.setdefault("band_hz", tuple(self.report.band_hz))
        return pc.plot_psd(self._data(), **kw)

    def plot_term_contributions(self, **kw: Any) -> Any:
        """Permanent / induced / eddy contributions to ``mag_tl``."""
        from ..plot import compensation as pc

        return pc.plot_term_contributions(self._data(), self.report, **kw)

    def plot_fom(self, **kw: Any) -> Any:
        """FOM bars per heading and maneuver (calibration flights)."""
        from ..plot import compensation as pc
        from ..qc import fom_table

        table = fom_table(self._data(), band_hz=tuple(self.report.band_hz))
        return pc.plot_fom(table, **kw)

    def plot_map(self, **kw: Any) -> Any:
        """Map of the flight coloured by the compensated field (needs lat/lon)."""
        from ..plot import compensation as pc

        return pc.plot_map(self._data(), **kw)

    def qc(self, **kw: Any) -> Any:
        """All quality-control metrics (:func:`aeromag.qc.compute_qc`)."""
        from ..qc import compute_qc

        return compute_qc(self, **kw)

    def write_report(self, out_dir: str | os.PathLike[str]) -> Path:
        """Write the figures, ``qc.json`` and ``report.html`` into ``out_dir``."""
        from .report import write_report

        return write_report(self, out_dir)

    def _data(self) -> pd.DataFrame:
        if self.data is None:
            raise InputError("this result holds no compensated data (use compensate())")
        return self.data



def _run(res: CompensationResult) -> CompensationRun:
    return CompensationRun(**{f.name: getattr(res, f.name) for f in fields(CompensationResult)})


def _for_qc(man: ManeuverResult | None, df: pd.DataFrame,
            res: CompensationResult) -> ManeuverResult | None:
    """``man`` (detected on ``df``) for the QC of ``res``, or None to let the QC detect.

    The QC detects the manoeuvres itself only for the FOM (``cfg.fom``), and on the run's own
    rows: the detection is handed on only then, and only when those rows are ``df``'s.
    """
    data = res.data
    if (man is None or not res.config.fom or data is None or len(data) != len(df)
            or not np.array_equal(data["time"].to_numpy(), df["time"].to_numpy())):
        return None
    return man


def _add_qc(res: CompensationResult, maneuvers: Any = None) -> None:
    """Add the ``qc`` block and, for an applied model, each segment's residual.

    :func:`aeromag.qc.compute_qc` (band-passed ``mag - mag_tl`` per segment piece, as the
    report computes it); the FOM only when ``cfg.fom``; the fit diagnostics are in
    ``report.fit`` already.  ``maneuvers``: already detected on this log.
    """
    from ..qc import compute_qc

    res.report.qc = compute_qc(res, fit=False, fom=bool(res.config.fom),
                               maneuvers=maneuvers).metrics
    if res.fit is None:
        by_seg = res.report.qc.residual_std_by_segment_nT or {}
        for e in res.report.segments:
            e.residual_std = by_seg.get(str(e.id))
        flag_residual_outliers(res.report)


# --------------------------------------------------------------------------- files
def compensate_file(
    path: str | os.PathLike[str], out_path: str | os.PathLike[str],
    cfg: CompensationConfig | None = None, *, model: TLModel | str | os.PathLike[str] | None = None,
    columns: dict[str, str] | None = None, units: dict[str, str] | None = None,
    fmt: str | None = None, self_check: bool = True,
) -> CompensationResult:
    """Read a log, compensate it and write ``OUT.csv`` and ``OUT.json`` atomically.

    Parameters
    ----------
    path : path-like
        Input log.
    out_path : path-like
        Output CSV; the report goes to the same name with ``.json``.
    cfg : CompensationConfig, optional
        Options.
    model : TLModel or path-like, optional
        Saved model to apply instead of fitting.
    columns, units : dict, optional
        Column map and unit conversions.
    fmt : str, optional
        Input format (default from the extension).
    self_check : bool
        When fitting on the log itself (no ``model``), check it for a calibration box and
        warn without one: the heading-dependent level is then undetermined and the in-sample
        improvement ratio flattering (the report's ``self_calibration``).  On by default, as
        ``aeromag compensate`` and ``aeromag batch`` (each log fitted on itself) do; with
        ``model`` nothing is fitted and nothing is checked.  False skips the check (e.g. a
        log known to be a box, to save the maneuver detection).

    Returns
    -------
    CompensationResult
    """
    with output_set():  # the run's warnings go to OUT.json, from Python as from the CLI
        cfg = cfg or CompensationConfig()
        check_outputs(path, out_path, json_path_for(Path(out_path)))
        output_format(out_path)
        if model is not None and not isinstance(model, TLModel):
            mpath = Path(model)
            model = TLModel.load(mpath)
            model.meta.path = str(mpath)
        t0 = time.perf_counter()
        df = read_log(path, columns=columns, units=units, required=("time", *FLUX_COLUMNS), fmt=fmt)
        t1 = time.perf_counter()
        log.info("%s: read %d rows in %.2f s", path, len(df), t1 - t0)
        res = compensate(df, cfg, model=model, source=str(path))
        if model is None and self_check:
            res.report.self_calibration = _self_calibration(df, cfg, str(path))
        t2 = time.perf_counter()
        log.info("%s: %s in %.2f s", path, "model applied" if model is not None else
                 "fitted, screened and applied", t2 - t1)
        out = Path(out_path)
        write_outputs(res.data, res.report, out, passthrough=df.attrs.get("passthrough_csv"))
        log.info("%s: wrote %s in %.2f s", path, out, time.perf_counter() - t2)
        return res


def write_outputs(data: pd.DataFrame, report: CompensationReport, out_csv: Path, *,
                  passthrough: dict[str, Any] | None = None) -> None:
    """Write the output log and its JSON report; both appear or neither does.

    The report's ``warnings`` are those the run logged (:func:`write_report_json`).

    ``passthrough`` (``{"path", "columns"}``, set by :func:`aeromag.io.read_log` on a plain
    CSV) says that ``data`` starts with that file's columns, unchanged: their lines are then
    copied verbatim and only the added columns are formatted
    (:func:`aeromag.io.write_csv_passthrough`).
    """
    out_json = json_path_for(out_csv)
    fmt = output_format(out_csv)  # -o OUT.parquet / OUT.xyz write that format (issue 15, 2)
    with atomic_path(out_csv) as tmp_csv:
        done = False
        if passthrough and fmt == "csv":
            cols = list(passthrough["columns"])
            if list(data.columns[: len(cols)]) == cols and len(data.columns) > len(cols):
                done = write_csv_passthrough(passthrough["path"], cols,
                                             data.iloc[:, len(cols):], tmp_csv)
                if not done:
                    log.info("%s: not a plain CSV, output written column by column",
                             passthrough["path"])
        if not done:
            write_table(data, tmp_csv, fmt)
        write_report_json(report, out_json)


def write_report_json(report: CompensationReport, path: str | os.PathLike[str]) -> Path:
    """Write a compensation report as JSON (:meth:`CompensationReport.to_dict`), atomically.

    The JSON's ``warnings`` list (what the command logged, :func:`aeromag.io.write_json`) is
    recorded in ``report.warnings`` too.

    Parameters
    ----------
    report : CompensationReport
        The report.
    path : path-like
        Destination.

    Returns
    -------
    Path
        The written path.
    """
    doc = report.to_dict()
    out = write_json(doc, path)
    report.warnings = doc.get("warnings")
    return out


def calibrate_file(
    path: str | os.PathLike[str], model_path: str | os.PathLike[str],
    cfg: CompensationConfig | None = None, *, columns: dict[str, str] | None = None,
    units: dict[str, str] | None = None, fmt: str | None = None,
) -> CompensationResult:
    """Fit and screen on a calibration log; write the model JSON atomically.

    Parameters
    ----------
    path : path-like
        Calibration log.
    model_path : path-like
        Output model file (JSON with ``terms``, ``coef``, ``segments``, ``metrics``...).
    cfg : CompensationConfig, optional
        Options.
    columns, units : dict, optional
        Column map and unit conversions.
    fmt : str, optional
        Input format.

    Returns
    -------
    CompensationResult
        ``data`` is the calibration log with the model applied (not written).
    """
    with output_set():  # the fit's warnings go to the model file, from Python as from the CLI
        cfg = cfg or CompensationConfig()
        check_outputs(path, model_path)
        if Path(model_path).suffix.lower() != ".json":
            raise InputError(f"-o {model_path}: the model is written as JSON; give it a .json name,"
                             f" e.g. -o {Path(model_path).with_suffix('.json').name}")
        if cfg.fom is None:
            cfg = dataclasses.replace(cfg, fom=True)
        df = read_log(path, columns=columns, units=units, required=("time", *FLUX_COLUMNS), fmt=fmt)
        res = calibrate(df, cfg, source=str(path))
        write_report_json(res.report, model_path)
        return res
