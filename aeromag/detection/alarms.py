"""One alarm result type shared by every detector (heading, track deviation, particle filter)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._core.runs import true_runs
from .._core.sequential import SequentialResult

__all__ = ["Alarms", "alarm_events"]


def alarm_events(time_s: np.ndarray, alarm: np.ndarray) -> list[dict[str, float]]:
    """Runs of consecutive alarms as events.

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Sample times, s.
    alarm : ndarray of bool, shape (n,)
        Alarm per sample.

    Returns
    -------
    list of dict
        One ``{"start_time": s, "end_time": s, "n": samples}`` per run of alarms, in time
        order (``end_time`` is the time of the run's last alarming sample).
    """
    t = np.asarray(time_s, dtype=np.float64)
    starts, stops = true_runs(alarm)
    return [{"start_time": float(t[a]), "end_time": float(t[b - 1]), "n": int(b - a)}
            for a, b in zip(starts, stops, strict=True)]


@dataclass
class Alarms:
    """What a detector says about a log, sample by sample.

    Attributes
    ----------
    name : str
        Detector name (``"heading"``, ``"track"``, ``"pf"``).
    time_s : ndarray, shape (n,)
        Sample times, s.
    stat : ndarray, shape (n,)
        The detector's statistic per sample (NaN where it could not be computed).
    alarm : ndarray of bool, shape (n,)
        Alarm per sample (never True where ``stat`` is NaN).
    threshold : float
        Threshold the statistic was compared with, in the statistic's units.
    info : dict
        Detector-specific settings and calibration (JSON-ready), e.g. the calm window.
    fit : SequentialResult or None
        The run of the detector's sequential filter, one row per sample, when it has one
        (the particle filter: heading and gyro bias, their std, ``log L_k``); None for the
        heading and track detectors.
    """

    name: str
    time_s: np.ndarray
    stat: np.ndarray
    alarm: np.ndarray
    threshold: float
    info: dict[str, Any] = field(default_factory=dict)
    fit: SequentialResult | None = None

    def __post_init__(self) -> None:
        self.time_s = np.asarray(self.time_s, dtype=np.float64)
        self.stat = np.asarray(self.stat, dtype=np.float64)
        self.alarm = np.asarray(self.alarm, dtype=bool) & np.isfinite(self.stat)

    @property
    def events(self) -> list[dict[str, float]]:
        """Runs of consecutive alarms (see :func:`alarm_events`)."""
        return alarm_events(self.time_s, self.alarm)

    @property
    def first_alarm_time(self) -> float | None:
        """Time of the first alarm, s, or None."""
        i = np.flatnonzero(self.alarm)
        return float(self.time_s[i[0]]) if i.size else None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary: name, threshold, number of alarms, events and info."""
        return {"detector": self.name, "threshold": float(self.threshold),
                "n_alarms": int(self.alarm.sum()), "events": self.events, **self.info}
