"""One file of ``aeromag batch``: the job a worker runs and the result it sends back.

Both are plain dataclasses (picklable for the process pool and Dask); the engines
(:mod:`aeromag.workflows.batch_engines`) pass them between ``run_batch`` and
``process_file`` (:mod:`aeromag.workflows.batch`), reading only a job's ``input``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

__all__ = ["BatchJob", "FileResult"]


@dataclass(kw_only=True)
class BatchJob:
    """What a worker needs to process one log.

    Attributes
    ----------
    input : str
        The input log.
    out_dir : str
        Output folder.
    model : str or None
        Saved model applied to the log (None: self-calibrated).
    plan : str or None
        Mission plan: also run the track check.
    cfg : CompensationConfig
        Pipeline options.
    columns, units : dict or None
        Column map and unit conversions.
    fmt : str or None
        Log format (default from the extension).
    chunk_rows : int or None
        With a model: apply it in chunks of this many rows.
    track : dict or None
        Keyword arguments of :func:`aeromag.workflows.track.track_file` (``threshold_m`` [m],
        ...): an open set of options.
    fingerprint : dict or None
        From :func:`~aeromag.workflows.batch_inputs.batch_fingerprint`: written to
        ``.NAME.batch.json`` when the file succeeds (the old one is removed first).
    strict : bool
        Warnings are this file's errors.
    """

    input: str
    out_dir: str
    model: str | None = None
    plan: str | None = None
    cfg: Any = None
    columns: dict[str, str] | None = None
    units: dict[str, str] | None = None
    fmt: str | None = None
    chunk_rows: int | None = None
    track: dict[str, Any] | None = None
    fingerprint: dict[str, Any] | None = None
    strict: bool = False


@dataclass
class FileResult:
    """Outcome of one input log.

    Attributes
    ----------
    input : str
        The input path.
    status : {"ok", "warn", "skipped", "failed"}
        What happened: ``warn`` is a success whose results need a look (a warning recorded in
        the file's report, an improvement ratio below 1, an implausible residual).
    outputs : list of str
        Files written (or found up to date when skipped).
    error : str or None
        One-line reason of the failure.
    seconds : float
        Wall time of this file [s].
    n_rows : int or None
        Rows of the output log.
    improvement_ratio, residual_std_nT : float or None
        Compensation metrics of the report (interface.md).
    flagged_legs : int or None
        Legs with an alarm (with a plan).
    warnings : list of str
        The warnings of this file (those recorded in its reports, and the batch's own checks).
    """

    input: str
    status: str
    outputs: list[str] = field(default_factory=list)
    error: str | None = None
    seconds: float = 0.0
    n_rows: int | None = None
    improvement_ratio: float | None = None
    residual_std_nT: float | None = None
    flagged_legs: int | None = None
    warnings: list[str] = field(default_factory=list)

    @classmethod
    def failure(cls, job: BatchJob, error: str) -> FileResult:
        """The result of a job whose worker failed (``error``: the one-line reason)."""
        return cls(job.input, "failed", error=error)
