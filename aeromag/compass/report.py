"""The report of an online compass calibration (OUT.json of ``aeromag compass``).

:func:`aeromag.workflows.compass.compass_frame` builds a :class:`CompassReport`; the command
line reads its attributes, and ``to_dict()`` is the JSON the command writes (``from_dict()``
reads it back).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from .calibration import ExcitationWindow
from .heading_stats import HeadingErrorStats

__all__ = ["CompassHistory", "CompassMetrics", "CompassReport", "ExcitationSummary"]


@dataclass(kw_only=True)
class CompassMetrics(HeadingErrorStats):
    """Heading error of the calibrated compass and the samples behind it.

    Attributes
    ----------
    rms_deg, mean_deg, max_abs_deg : float or None
        Heading error statistics [deg] (:class:`~aeromag.compass.HeadingErrorStats`).
    n_samples : int
        Rows of the log.
    n_skipped : int
        Rows the filter skipped (no complete field and attitude).
    n_attitude_interpolated : int
        Magnetometer rows whose attitude was interpolated (a multi-rate log).
    """

    n_samples: int = 0
    n_skipped: int = 0
    n_attitude_interpolated: int = 0

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (the report's ``metrics``)."""
        return {**super().to_dict(), "n_samples": self.n_samples, "n_skipped": self.n_skipped,
                "n_attitude_interpolated": self.n_attitude_interpolated}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> CompassMetrics:
        """Read a ``metrics`` block written by :meth:`to_dict`."""
        h = HeadingErrorStats.from_dict(d)
        return cls(rms_deg=h.rms_deg, mean_deg=h.mean_deg, max_abs_deg=h.max_abs_deg,
                   n_samples=d["n_samples"], n_skipped=d["n_skipped"],
                   n_attitude_interpolated=d["n_attitude_interpolated"])


@dataclass(kw_only=True)
class ExcitationSummary:
    """How well the manoeuvres excited the 12 parameters, window by window.

    Attributes
    ----------
    window_s : float
        Window length [s].
    windows : list of ExcitationWindow
        Every window, in time order.
    """

    window_s: float
    windows: list[ExcitationWindow] = field(default_factory=list)

    @property
    def n_windows(self) -> int:
        """Number of windows."""
        return len(self.windows)

    @property
    def n_insufficient(self) -> int:
        """Windows that did not excite enough to trust the estimate."""
        return sum(1 for w in self.windows if not w.sufficient)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (the report's ``excitation``)."""
        return {"window_s": self.window_s, "n_windows": self.n_windows,
                "n_insufficient": self.n_insufficient,
                "windows": [w.to_dict() for w in self.windows]}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> ExcitationSummary:
        """Read an ``excitation`` block written by :meth:`to_dict`."""
        return cls(window_s=d["window_s"],
                   windows=[ExcitationWindow.from_dict(w) for w in d["windows"]])


@dataclass(kw_only=True)
class CompassHistory:
    """The estimate along the flight, on a coarse step.

    Attributes
    ----------
    time : list of float
        Sample times [s].
    matrix : list
        Soft-iron matrix ``D`` (3 x 3) at each time.
    offset_nT : list
        Hard-iron offset ``e`` (3) at each time [nT].
    """

    time: list[float] = field(default_factory=list)
    matrix: list[list[list[float]]] = field(default_factory=list)
    offset_nT: list[list[float]] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (the report's ``history``)."""
        return {"time": self.time, "matrix": self.matrix, "offset_nT": self.offset_nT}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> CompassHistory:
        """Read a ``history`` block written by :meth:`to_dict`."""
        return cls(time=d["time"], matrix=d["matrix"], offset_nT=d["offset_nT"])


@dataclass(kw_only=True)
class CompassReport:
    """What ``aeromag compass`` estimated.

    Attributes
    ----------
    input : str
        The log's file name.
    matrix : list of list of float
        Final soft-iron matrix ``D`` (3 x 3, dimensionless).
    offset_nT : list of float
        Final hard-iron offset ``e`` [nT].
    forgetting : float
        Forgetting factor lambda.
    alpha : float
        Prior covariance scale.
    reference : dict
        The reference field's description (:attr:`aeromag.compass.ReferenceField.info`).
    metrics : CompassMetrics
        Heading error and sample counts.
    excitation : ExcitationSummary
        Excitation per window.
    history : CompassHistory
        The estimate along the flight.
    warnings : list of str
        The warnings the command logged (recorded when the file is written).
    """

    input: str
    matrix: list[list[float]]
    offset_nT: list[float]
    forgetting: float
    alpha: float
    reference: dict[str, Any]
    metrics: CompassMetrics
    excitation: ExcitationSummary
    history: CompassHistory
    warnings: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        """The report as OUT.json holds it."""
        return {"input": self.input, "matrix": self.matrix, "offset_nT": self.offset_nT,
                "forgetting": self.forgetting, "alpha": self.alpha,
                "reference": self.reference, "metrics": self.metrics.to_dict(),
                "excitation": self.excitation.to_dict(), "history": self.history.to_dict(),
                "warnings": self.warnings}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> CompassReport:
        """Read a report written by :meth:`to_dict` (an OUT.json of ``aeromag compass``)."""
        return cls(input=d["input"], matrix=d["matrix"], offset_nT=d["offset_nT"],
                   forgetting=d["forgetting"], alpha=d["alpha"], reference=d["reference"],
                   metrics=CompassMetrics.from_dict(d["metrics"]),
                   excitation=ExcitationSummary.from_dict(d["excitation"]),
                   history=CompassHistory.from_dict(d["history"]),
                   warnings=list(d.get("warnings", [])))
