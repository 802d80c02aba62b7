"""Batch processing: many logs, on all local cores or on a Dask cluster.

Every input log is compensated exactly as ``aeromag compensate`` does it (self-calibrated, or
with the saved ``model``), and with a ``plan`` also checked by ``aeromag track``; each file runs
in its own task, so a bad file is reported without stopping the others::

    from aeromag.workflows.batch import run_batch
    summary = run_batch(["logs/"], "out/", model="aircraft.json", workers=8)
    summary.to_frame()           # one row per input: status, seconds, metrics, error
    summary.failed               # the failures, each with its one-line reason

Outputs: ``OUT/NAME_comp.csv`` + ``.json`` (and ``OUT/NAME_track.csv`` + ``.json``) per input
``NAME.ext``, and ``OUT/batch_summary.csv`` + ``.json``.  No output may be an input (a log, the
model or the plan): such a run is refused before it starts.

Strict (``strict=True``, ``aeromag batch --strict``): every warning of a file is its error,
as ``--strict`` makes it for ``compensate``: that file is ``failed`` with the warning as its
reason and none of its outputs is written; the other files go on.  Self-fitted logs are
checked for a calibration box as ``aeromag compensate`` checks them (without one: a warning).

Skipping: a file is skipped (unless ``force``) when its outputs are newer than it **and** were
made with the same fingerprint -- the effective pipeline options, column map, units, format,
chunking, track options, the SHA-256 of the model and plan files' contents and the aeromag
version (:func:`batch_fingerprint`).  The fingerprint of a file's last successful run is kept
in ``OUT/.NAME.batch.json``; it is removed when the file is processed again and written back
only when the file succeeds, so a failed or interrupted run is always redone.

Engines: a local process pool (default, ``workers`` processes), or Dask distributed when
``scheduler`` is given (an address such as ``tcp://host:8786``, or a
:class:`distributed.Client`); Dask is imported only then (``pip install 'aeromag[dask]'``).
"""

from __future__ import annotations

import contextlib
import logging
import os
import threading
import time
import traceback
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from ..compensation.checks import (  # noqa: F401 - importable from here too
    IMPLAUSIBLE_RESIDUAL_NT,
    metric_warnings,
)
from ..compensation.report_types import CompensationMetrics, CompensationReport
from ..errors import AeromagError, InputError
from .batch_engines import run_dask, run_local
from .batch_inputs import (  # noqa: F401 - FINGERPRINT_SUFFIX ... importable from here too
    FINGERPRINT_SUFFIX,
    LOG_EXTENSIONS,
    batch_fingerprint,
    expand_inputs,
    file_sha256,
    output_names,
    stored_fingerprint,
    unmatched_reason,
    up_to_date,
)
from .batch_jobs import BatchJob, FileResult

log = logging.getLogger(__name__)


SUMMARY_NAME = "batch_summary"


#: Summary columns holding counts, written as integers (empty when unknown).
INTEGER_COLUMNS: tuple[str, ...] = ("n_rows", "flagged_legs")


@dataclass
class BatchSummary:
    """Results of :func:`run_batch`, one :class:`FileResult` per input, in input order."""

    results: list[FileResult]
    out_dir: Path
    summary_csv: Path | None = None
    summary_json: Path | None = None
    seconds: float = 0.0

    @property
    def failed(self) -> list[FileResult]:
        """The inputs that failed."""
        return [r for r in self.results if r.status == "failed"]

    @property
    def warned(self) -> list[FileResult]:
        """The inputs that succeeded with warnings (status ``warn``)."""
        return [r for r in self.results if r.status == "warn"]

    @property
    def ok(self) -> bool:
        """True when no input failed."""
        return not self.failed

    def to_frame(self) -> pd.DataFrame:
        """One row per input: ``input, status, seconds, n_rows, improvement_ratio, ...``."""
        rows = []
        for r in self.results:
            d = asdict(r)
            d["outputs"] = ";".join(r.outputs)
            d["warnings"] = " | ".join(r.warnings)
            rows.append(d)
        cols = list(FileResult.__dataclass_fields__)
        frame = pd.DataFrame(rows, columns=cols)
        for c in INTEGER_COLUMNS:  # None makes a float column: 2010.0
            frame[c] = frame[c].astype("Int64")
        return frame


def _refuse_overwriting_inputs(sources: Sequence[tuple[Path, str]],
                               outputs: Sequence[Path]) -> None:
    """Raise :class:`InputError` when an output of the run is one of its inputs.

    Parameters
    ----------
    sources : sequence of (Path, str)
        Input files and what they are (``"log"``, ``"model"``, ``"plan"``).
    outputs : sequence of Path
        Every file the run may write.
    """
    from .compensate import check_outputs

    existing: dict[tuple[int, int], Path] = {}
    for o in outputs:
        try:
            st = o.stat()
        except OSError:
            continue  # not there yet: cannot be an existing input
        existing[(st.st_dev, st.st_ino)] = o
    for src, kind in sources:
        try:
            st = src.stat()
        except OSError:
            continue
        o = existing.get((st.st_dev, st.st_ino))
        if o is None:
            continue
        check_outputs(src, o, kind=kind)


# --------------------------------------------------------------------------- one file
def process_file(job: BatchJob) -> FileResult:
    """Compensate (and track-check) one log; never raises.

    Parameters
    ----------
    job : BatchJob
        The log, the output folder, the model or plan, the options and the fingerprint
        (written to ``.NAME.batch.json`` when the file succeeds; the old one is removed first).

    Returns
    -------
    FileResult
        What happened to the file.
    """
    from ..io import json_path_for, write_json
    from ..io.outputs import output_set

    t0 = time.perf_counter()
    inp = Path(job.input)
    names = output_names(inp, Path(job.out_dir))
    res = FileResult(str(inp), "ok")
    errors: list[str] = []
    # Outputs about to change: the old fingerprint no longer describes them.
    try:
        names["fingerprint"].unlink(missing_ok=True)
    except OSError as exc:
        log.debug("%s: %s", names["fingerprint"], exc)
    warnings: list[str] = []
    strict = job.strict
    try:
        # This file's CSV and JSON together, or neither (a strict warning discards both).
        with output_set(separate=True), strict_log_warnings(strict):
            report = _compensate_one(job, inp, names, res)
            m = report.metrics or CompensationMetrics()
            # The metric checks the single-file commands log (recorded in the report, so
            # the same words are found once); a report made without them is checked here.
            found = [str(w) for w in report.warnings or []] + metric_warnings(
                m, source=str(inp), fitted=report.model_source == "fitted")
            if strict and found:
                raise StrictWarningError(found[0])
        res.improvement_ratio = m.improvement_ratio
        res.residual_std_nT = m.residual_std_nT
        res.outputs += [str(names["comp"]), str(json_path_for(names["comp"]))]
        warnings += found
    except StrictWarningError as exc:
        errors.append(_strict_reason(inp, exc))
    except AeromagError as exc:
        errors.append(str(exc))
    except Exception as exc:  # noqa: BLE001 - isolate every file, whatever breaks
        log.debug("%s", traceback.format_exc())
        errors.append(f"{inp}: internal error {type(exc).__name__}: {exc}".splitlines()[0])
    if job.plan is not None:
        try:
            from .track import track_file

            with output_set(separate=True), strict_log_warnings(strict):
                tr = track_file(inp, job.plan, names["track"], columns=job.columns,
                                units=job.units, fmt=job.fmt, **(job.track or {}))
                tw = [str(w) for w in tr.report.warnings]
                if strict and tw:
                    raise StrictWarningError(tw[0])
            res.flagged_legs = tr.report.n_flagged
            res.outputs += [str(names["track"]), str(json_path_for(names["track"]))]
            warnings += [f"track: {w}" for w in tw]
        except StrictWarningError as exc:
            errors.append(f"track: {_strict_reason(inp, exc)}")
        except AeromagError as exc:
            errors.append(f"track: {exc}")
        except Exception as exc:  # noqa: BLE001
            errors.append(f"track: {inp}: internal error {type(exc).__name__}: {exc}"
                          .splitlines()[0])
    res.warnings = list(dict.fromkeys(warnings))
    if errors:
        res.status = "failed"
        res.error = " | ".join(errors)
    elif res.warnings:
        res.status = "warn"
    if not errors and job.fingerprint is not None:
        try:
            write_json(job.fingerprint, names["fingerprint"])
        except OSError as exc:  # the outputs are good; the next run just redoes this file
            log.warning("%s: cannot record the run's fingerprint (%s); the next batch run will"
                        " process this file again", names["fingerprint"], exc)
    res.seconds = time.perf_counter() - t0
    return res


def _compensate_one(job: BatchJob, inp: Path, names: dict[str, Path],
                    res: FileResult) -> CompensationReport:
    """Run the compensation of one file (chunked with a model when asked); its report."""
    from .compensate import compensate_file

    if job.chunk_rows and job.model is not None:
        from .chunked import apply_model_chunked

        report = apply_model_chunked(inp, names["comp"], job.model, job.cfg,
                                     chunk_rows=job.chunk_rows, columns=job.columns,
                                     units=job.units, fmt=job.fmt)
        res.n_rows = int(report.n_rows or 0) or None
        return report
    # self_check: a log fitted on itself is checked for a calibration box, as 'aeromag
    # compensate' does (without one its level is undetermined and its headline in-sample).
    out = compensate_file(inp, names["comp"], job.cfg, model=job.model,
                          columns=job.columns, units=job.units, fmt=job.fmt,
                          self_check=job.model is None)
    res.n_rows = len(out.data) if out.data is not None else None
    return out.report


class StrictWarningError(Exception):
    """A warning of one log, raised as that log's error by a strict batch.

    Not an :class:`~aeromag.errors.AeromagError`, so that no library code that tolerates a
    failed step (and notes why) swallows it.
    """


_STRICT = threading.local()  # .on: this thread runs a strict file
_STRICT_LOCK = threading.Lock()
_STRICT_USERS = [0]  # files running strict in this process (the handler is installed while >0)


class _StrictHandler(logging.Handler):
    """Raise :class:`StrictWarningError` on a warning logged by a thread running strict."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.addFilter(self._raise)

    @staticmethod
    def _raise(record: logging.LogRecord) -> bool:
        if record.levelno >= logging.WARNING and getattr(_STRICT, "on", False):
            from ..io.messages import clean

            raise StrictWarningError(clean(record.getMessage()))
        return False  # nothing to emit: the capture of the output set records warnings

    def emit(self, record: logging.LogRecord) -> None:  # never reached: the filter decides
        pass


_HANDLER = _StrictHandler()


@contextlib.contextmanager
def strict_log_warnings(enabled: bool) -> Iterator[None]:
    """With ``enabled``, a warning of aeromag's loggers in this thread ends the block.

    It raises :class:`StrictWarningError` where it is logged (so inside an output set
    nothing of the file is written).  Other threads (Dask's) are not affected unless they
    run strict too.

    Parameters
    ----------
    enabled : bool
        Whether warnings are errors (the batch's ``strict``).
    """
    if not enabled:
        yield
        return
    lg = logging.getLogger("aeromag")
    with _STRICT_LOCK:
        if _STRICT_USERS[0] == 0:
            lg.addHandler(_HANDLER)
        _STRICT_USERS[0] += 1
    before = getattr(_STRICT, "on", False)
    _STRICT.on = True
    try:
        yield
    finally:
        _STRICT.on = before
        with _STRICT_LOCK:
            _STRICT_USERS[0] -= 1
            if _STRICT_USERS[0] == 0:
                lg.removeHandler(_HANDLER)


def _strict_reason(inp: Path, exc: StrictWarningError) -> str:
    """The failure of a strict file: its warning, naming the file."""
    msg = str(exc)
    head = msg if str(inp) in msg or inp.name in msg else f"{inp}: {msg}"
    return f"{head} (strict: warnings are errors)"


# --------------------------------------------------------------------------- driver
def run_batch(
    inputs: Iterable[str | os.PathLike[str]],
    out_dir: str | os.PathLike[str],
    *,
    model: str | os.PathLike[str] | None = None,
    plan: str | os.PathLike[str] | None = None,
    cfg: Any = None,
    workers: int | None = None,
    scheduler: Any = None,
    force: bool = False,
    columns: dict[str, str] | None = None,
    units: dict[str, str] | None = None,
    fmt: str | None = None,
    progress: bool = True,
    chunk_rows: int | None = None,
    track_options: dict[str, Any] | None = None,
    strict: bool = False,
) -> BatchSummary:
    """Compensate (and with ``plan`` track-check) many logs in parallel.

    Parameters
    ----------
    inputs : iterable of path-like
        Files, glob patterns or folders.
    out_dir : path-like
        Output folder (created when missing).
    model : path-like, optional
        Saved model applied to every log; without it every log is self-calibrated exactly as
        ``aeromag compensate`` does.
    plan : path-like, optional
        Mission plan: also run :func:`aeromag.track.track_file` on every log.
    cfg : CompensationConfig, optional
        Pipeline options (default: the command line's defaults).
    workers : int, optional
        Local worker processes (default: all cores); 1 runs in this process.
    scheduler : str or distributed.Client, optional
        Dask scheduler address (``tcp://host:8786``) or client: run the files there instead.
    force : bool
        Re-process every file; otherwise a file is skipped when its outputs are newer than it
        and its stored fingerprint equals this run's (:func:`batch_fingerprint`).
    columns, units : dict, optional
        Column map and unit conversions, for every file.
    fmt : str, optional
        Input format for every file (default: from each extension).
    progress : bool
        Show a rich progress bar on stderr.
    chunk_rows : int, optional
        With ``model``: apply it in chunks of this many rows (bounded memory, see
        :mod:`aeromag.chunked`) instead of reading each log whole.
    track_options : dict, optional
        Keyword arguments of :func:`aeromag.track.track_file` (``threshold_m`` [m], ...).
    strict : bool
        Warnings are errors, per file: a log that draws a warning (a units warning, a log
        fitted on itself without a calibration box, an improvement ratio below 1, ...)
        is ``failed`` with the warning as its error and none of its outputs written; the
        others go on.

    Returns
    -------
    BatchSummary
        Per-file results; ``batch_summary.csv``/``.json`` are written to ``out_dir``.
    """
    from ..compensation.config import CompensationConfig
    from ..compensation.model import TLModel
    from ..io import write_csv, write_json

    t_start = time.perf_counter()
    cfg = cfg or CompensationConfig()
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a folder; give -o a folder")
    if model is not None:
        TLModel.load(model)  # a bad model is everyone's problem: fail before starting
    if plan is not None and not Path(plan).is_file():
        raise InputError(f"{plan}: plan file not found")
    files, unmatched = expand_inputs(inputs)
    if not files and not unmatched:
        raise InputError("no input logs given")
    stems: dict[str, Path] = {}
    for f in files:
        if f.stem in stems:
            raise InputError(f"{f} and {stems[f.stem]} would both write {f.stem}_comp.csv;"
                             " rename one or run them into different -o folders")
        stems[f.stem] = f
    from ..io import json_path_for

    per_file: dict[Path, list[Path]] = {}
    for f in files:
        names = output_names(f, out)
        outs = [names["comp"], json_path_for(names["comp"])]
        if plan is not None:
            outs += [names["track"], json_path_for(names["track"])]
        per_file[f] = outs
    _refuse_overwriting_inputs(
        [(f, "log") for f in files] + [(Path(p), k) for p, k in ((model, "model"),
                                                                 (plan, "plan")) if p is not None],
        [p for f in files for p in (*per_file[f], output_names(f, out)["fingerprint"])]
        + [out / f"{SUMMARY_NAME}.csv", out / f"{SUMMARY_NAME}.json"])
    fingerprint = batch_fingerprint(cfg=cfg, model=model, plan=plan, columns=columns,
                                    units=units, fmt=fmt, chunk_rows=chunk_rows,
                                    track_options=track_options)
    if strict:  # a strict run redoes files that passed only leniently (their warnings)
        import hashlib

        digest = hashlib.sha256(f"{fingerprint['fingerprint']}:strict".encode()).hexdigest()
        fingerprint = {**fingerprint, "fingerprint": digest, "strict": True}
    out.mkdir(parents=True, exist_ok=True)
    results: dict[str, FileResult] = {}
    order = [str(f) for f in files] + unmatched
    for s in unmatched:
        results[s] = FileResult(s, "failed", error=unmatched_reason(s))
    jobs: list[BatchJob] = []
    for f in files:
        outs = per_file[f]
        if (not force and up_to_date(outs, [f])
                and stored_fingerprint(output_names(f, out)["fingerprint"])
                == fingerprint["fingerprint"]):
            results[str(f)] = FileResult(str(f), "skipped", [str(p) for p in outs])
            continue
        jobs.append(BatchJob(input=str(f), out_dir=str(out),
                             model=None if model is None else str(model),
                             plan=None if plan is None else str(plan), cfg=cfg,
                             columns=columns, units=units, fmt=fmt, chunk_rows=chunk_rows,
                             track=track_options, fingerprint=fingerprint, strict=strict))
    log.info("%d file(s) to process, %d up to date, %d unmatched", len(jobs),
             sum(r.status == "skipped" for r in results.values()), len(unmatched))

    bar = _progress(progress, len(jobs))

    def done(r: FileResult) -> None:
        results[r.input] = r
        if r.status == "failed":
            log.warning("%s", r.error)
        if bar is not None:
            bar[0].advance(bar[1])

    try:
        if jobs:
            if scheduler is not None:
                run_dask(jobs, scheduler, process_file, done)
            else:
                run_local(jobs, workers or os.cpu_count() or 1, process_file, done)
    finally:
        if bar is not None:
            bar[0].stop()
    summary = BatchSummary([results[k] for k in order], out,
                           seconds=time.perf_counter() - t_start)
    frame = summary.to_frame()
    summary.summary_csv = write_csv(frame, out / f"{SUMMARY_NAME}.csv")
    summary.summary_json = write_json(
        {"out_dir": str(out), "model": None if model is None else str(model),
         "plan": None if plan is None else str(plan), "seconds": summary.seconds,
         "fingerprint": fingerprint,
         "n_ok": sum(r.status == "ok" for r in summary.results),
         "n_warn": len(summary.warned),
         "n_skipped": sum(r.status == "skipped" for r in summary.results),
         "n_failed": len(summary.failed),
         "files": [asdict(r) for r in summary.results],
         "warnings": []},  # the run's own (each file's are in "files"): always a list
        out / f"{SUMMARY_NAME}.json")
    return summary


def _progress(enabled: bool, total: int) -> tuple[Any, Any] | None:
    if not enabled or total == 0:
        return None
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn

    bar = Progress("[progress.description]{task.description}", BarColumn(),
                   MofNCompleteColumn(), TimeElapsedColumn(),
                   console=Console(stderr=True), transient=False)
    task = bar.add_task("aeromag batch", total=total)
    bar.start()
    return bar, task
