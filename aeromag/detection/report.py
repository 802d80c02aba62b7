"""The report of a particle-filter detector run (OUT.json of ``aeromag detect``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .alarms import Alarms

__all__ = ["EVENTS_NOTE", "DetectReport"]

#: What an event of ``aeromag detect`` means (written to OUT.json as ``events_note``).
EVENTS_NOTE = (
    "one event per run of pf_alarm: S_k above the threshold (a change of the compass "
    "against the gyro: onset or removal of a disturbance) or a latch (the compass held "
    "more than 5 sigma_y off the bias-corrected gyro heading carried from before the "
    "filter restarted). A slow disturbance the filter followed without a restart "
    "(about 1 deg/s or slower) alarms only near its onset and removal.")


@dataclass(kw_only=True)
class DetectReport:
    """What ``aeromag detect`` found in a log.

    Attributes
    ----------
    input : str
        The log's file name.
    threshold : float
        Threshold on the statistic ``S_k``.
    window : int
        ``M``: compass samples in the statistic's window.
    particles : int
        Particles of the filter.
    events : list of dict
        Runs of alarms, ``start_time`` and ``end_time`` [s] and ``n`` (samples), in time order
        (:attr:`aeromag.detection.Alarms.events`).
    events_note : str
        What an event means.
    n_alarms : int
        Alarming samples.
    n_samples : int
        Samples of the log.
    n_stat : int
        Samples with a finite statistic.
    settings : dict
        Everything else the detector measured and used (its ``info``: ``threshold_source``,
        the calm window, ...); an open mapping, JSON-ready.
    warnings : list of str
        The warnings the command logged (recorded when the file is written).
    """

    input: str
    threshold: float
    window: int
    particles: int
    events: list[dict[str, float]] = field(default_factory=list)
    events_note: str = EVENTS_NOTE
    n_alarms: int = 0
    n_samples: int = 0
    n_stat: int = 0
    settings: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    @classmethod
    def from_alarms(cls, res: Alarms, source: str) -> DetectReport:
        """The report of a particle-filter run.

        Parameters
        ----------
        res : Alarms
            Output of :func:`aeromag.detection.particle.particle_detector` (its ``info``
            holds ``window`` and ``particles``).
        source : str
            Input file name.

        Returns
        -------
        DetectReport
        """
        info = dict(res.info)
        return cls(input=source, threshold=float(res.threshold),
                   window=int(info.pop("window")), particles=int(info.pop("particles")),
                   events=res.events, n_alarms=int(res.alarm.sum()),
                   n_samples=int(res.stat.size), n_stat=int(np.isfinite(res.stat).sum()),
                   settings=info)

    @property
    def threshold_source(self) -> str | None:
        """Where the threshold came from (``"calm"``, ``"given"``...), from ``settings``."""
        return self.settings.get("threshold_source")

    def to_dict(self) -> dict[str, Any]:
        """The report as OUT.json holds it."""
        return {"input": self.input, "threshold": self.threshold, "window": self.window,
                "particles": self.particles, "events": self.events,
                "events_note": self.events_note, "n_alarms": self.n_alarms,
                "n_samples": self.n_samples, "n_stat": self.n_stat, "settings": self.settings,
                "warnings": self.warnings}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> DetectReport:
        """Read a report written by :meth:`to_dict`."""
        return cls(**{k: d[k] for k in ("input", "threshold", "window", "particles", "events",
                                         "events_note", "n_alarms", "n_samples", "n_stat",
                                         "settings")}, warnings=list(d.get("warnings", [])))
