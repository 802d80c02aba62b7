"""Typed results of the track check: the per-leg (and per-pass) summary and the report.

:func:`~aeromag.track.check_track` builds them; the command line, the plots and the batch read
their attributes.  ``to_dict()`` gives the JSON that ``aeromag track`` writes to OUT.json
(keys, order and values as documented in ``docs/track.md``); ``from_dict()`` reads it back.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any

__all__ = ["LegSummary", "PassSummary", "SpanSummary", "TrackReport"]

#: JSON key of a detector's first alarm time: ``first_<name>_alarm_time``.
_FIRST_KEY = re.compile(r"^first_(.+)_alarm_time$")


@dataclass(kw_only=True)
class SpanSummary:
    """Track statistics of the samples of one leg or of one pass over it.

    Attributes
    ----------
    n_samples : int
        Samples on the leg (or pass).
    checked : bool
        Whether any sample was checked (``flagged=False`` means nothing otherwise).
    t_start, t_end : float or None
        Time of the first and last sample, s (None when not checked).
    max_xtrack_m, max_abs_xtrack_h_m, max_abs_xtrack_v_m : float or None
        Largest cross-track distance, horizontal and vertical deviation, m.
    first_alarm_time : float or None
        Time of the first combined alarm, s.
    first_alarm_times : dict
        Detector name -> time of its first alarm, s (None when it did not fire or run), in
        report order; JSON ``first_<name>_alarm_time``.
    time_above_threshold_s : float
        Time spent above the track threshold, s.
    flagged : bool
        Any combined alarm.
    first_detector : str or None
        Which detector fired first (see :func:`aeromag.track.deviation.first_detector`).
    """

    n_samples: int
    checked: bool
    t_start: float | None = None
    t_end: float | None = None
    max_xtrack_m: float | None = None
    max_abs_xtrack_h_m: float | None = None
    max_abs_xtrack_v_m: float | None = None
    first_alarm_time: float | None = None
    first_alarm_times: dict[str, float | None] = field(default_factory=dict)
    time_above_threshold_s: float = 0.0
    flagged: bool = False
    first_detector: str | None = None

    def _span_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "n_samples": self.n_samples, "checked": self.checked, "t_start": self.t_start,
            "t_end": self.t_end, "max_xtrack_m": self.max_xtrack_m,
            "max_abs_xtrack_h_m": self.max_abs_xtrack_h_m,
            "max_abs_xtrack_v_m": self.max_abs_xtrack_v_m,
            "first_alarm_time": self.first_alarm_time}
        out.update({f"first_{name}_alarm_time": v for name, v in self.first_alarm_times.items()})
        out.update(time_above_threshold_s=self.time_above_threshold_s, flagged=self.flagged,
                   first_detector=self.first_detector)
        return out

    @staticmethod
    def _span_kwargs(d: dict[str, Any]) -> dict[str, Any]:
        firsts = {}
        for key, value in d.items():
            m = _FIRST_KEY.match(key)
            if m:
                firsts[m.group(1)] = value
        return {"n_samples": d["n_samples"], "checked": d["checked"],
                "t_start": d["t_start"], "t_end": d["t_end"], "max_xtrack_m": d["max_xtrack_m"],
                "max_abs_xtrack_h_m": d["max_abs_xtrack_h_m"],
                "max_abs_xtrack_v_m": d["max_abs_xtrack_v_m"],
                "first_alarm_time": d["first_alarm_time"], "first_alarm_times": firsts,
                "time_above_threshold_s": d["time_above_threshold_s"],
                "flagged": d["flagged"], "first_detector": d["first_detector"]}


@dataclass(kw_only=True)
class PassSummary(SpanSummary):
    """One pass over a leg (the statistics of :class:`SpanSummary` over its samples).

    Attributes
    ----------
    pass_number : int
        This leg's pass number (1, 2, ...); JSON ``pass``.
    session_pass : int
        Session-wide index of the pass (0-based, time order over all legs).
    """

    pass_number: int
    session_pass: int

    def to_dict(self) -> dict[str, Any]:
        """The pass as it appears in OUT.json (``legs[].passes[]``)."""
        return {"pass": self.pass_number, "session_pass": self.session_pass,
                **self._span_dict()}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> PassSummary:
        """Read a pass written by :meth:`to_dict`."""
        return cls(pass_number=d["pass"], session_pass=d["session_pass"],
                   **cls._span_kwargs(d))


@dataclass(kw_only=True)
class LegSummary(SpanSummary):
    """Summary of one leg of the plan (flown or not).

    Attributes
    ----------
    leg : int
        Leg index (0-based, from waypoint ``leg`` to ``leg + 1``).
    n_passes : int or None
        Passes over the leg (None when the passes were not counted).
    passes : list of PassSummary or None
        Each pass with its own start and end (None when not counted).
    """

    leg: int
    n_passes: int | None = None
    passes: list[PassSummary] | None = None

    def to_dict(self) -> dict[str, Any]:
        """The leg as it appears in OUT.json (``legs[]``)."""
        out = {"leg": self.leg, **self._span_dict()}
        if self.passes is not None:
            out["n_passes"] = self.n_passes
            out["passes"] = [p.to_dict() for p in self.passes]
        return out

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> LegSummary:
        """Read a leg written by :meth:`to_dict`."""
        passes = d.get("passes")
        return cls(leg=d["leg"], n_passes=d.get("n_passes"),
                   passes=None if passes is None else [PassSummary.from_dict(p)
                                                       for p in passes],
                   **cls._span_kwargs(d))


#: Keys of OUT.json held by :class:`TrackReport` fields, in the file's order.
_KEYS = ("legs", "n_legs", "n_flagged", "flagged_legs", "threshold_m", "min_duration_s",
         "combine", "distance", "leg_source", "leg_model", "n_passes", "altitude_offset",
         "ground", "origin", "position_input", "velocity", "heading_detector", "detectors",
         "n_samples", "n_on_leg", "n_legs_checked", "plan_check", "warnings")
#: Keys the track workflow adds (written after the others when set).
_FILE_KEYS = ("navigation", "input", "plan", "plan_format", "plots")
#: Keys derived from ``legs`` (properties, not fields).
_DERIVED = ("n_flagged", "flagged_legs", "n_legs_checked")


@dataclass(kw_only=True)
class TrackReport:
    """The report of a track check (OUT.json of ``aeromag track``).

    Attributes
    ----------
    legs : list of LegSummary
        One per leg of the plan.
    n_legs : int
        Legs in the plan.
    threshold_m, min_duration_s : float
        Track threshold, m, and minimum duration of an exceedance, s.
    combine : {"or", "and"}
        How the detectors make the verdict.
    distance : {"3d", "horizontal"}
        Which distance the track alarm uses.
    leg_source : {"assigned", "log column"}
        Where the legs came from.
    leg_model : dict or None
        Parameters of the leg assignment (``LegModel.to_dict()``; None for a log column).
    n_passes : int
        Passes over all legs.
    altitude_offset, ground, velocity, plan_check : dict
        The diagnoses' JSON blocks (see ``docs/track.md``).
    origin : dict
        ``lat``, ``lon`` [deg], ``alt`` [m] of the NED origin (the first waypoint).
    position_input : {"log", "given"}
        Whose positions were checked.
    heading_detector : dict
        The heading detector's settings and calm statistics (``available``: whether it ran).
    detectors : list of dict
        ``detector``, ``ran``, ``n_alarms`` of each detector, in order.
    n_samples, n_on_leg : int
        Rows of the log, and rows on a leg.
    warnings : list of str
        The check's warnings.
    navigation : dict or None
        The navigation filter's block (``--navigate``; set by the workflow).
    input, plan, plan_format : str or None
        The files checked (set by the workflow).
    plots : list of str or None
        Figures written (set by the workflow).
    extra : dict
        Keys of a read report that no field holds (written back after the known ones).
    """

    legs: list[LegSummary] = field(default_factory=list)
    n_legs: int = 0
    threshold_m: float = 1.0
    min_duration_s: float = 0.0
    combine: str = "or"
    distance: str = "3d"
    leg_source: str = "assigned"
    leg_model: dict[str, Any] | None = None
    n_passes: int = 0
    altitude_offset: dict[str, Any] = field(default_factory=dict)
    ground: dict[str, Any] = field(default_factory=dict)
    origin: dict[str, float] = field(default_factory=dict)
    position_input: str = "log"
    velocity: dict[str, Any] = field(default_factory=dict)
    heading_detector: dict[str, Any] = field(default_factory=lambda: {"available": False})
    detectors: list[dict[str, Any]] = field(default_factory=list)
    n_samples: int = 0
    n_on_leg: int = 0
    plan_check: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    navigation: dict[str, Any] | None = None
    input: str | None = None
    plan: str | None = None
    plan_format: str | None = None
    plots: list[str] | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def flagged_legs(self) -> list[int]:
        """Legs with an alarm."""
        return [row.leg for row in self.legs if row.flagged]

    @property
    def n_flagged(self) -> int:
        """Number of legs with an alarm."""
        return len(self.flagged_legs)

    @property
    def n_legs_checked(self) -> int:
        """Number of legs with a checked sample."""
        return sum(1 for row in self.legs if row.checked)

    def to_dict(self) -> dict[str, Any]:
        """The report as OUT.json holds it."""
        out: dict[str, Any] = {}
        for key in _KEYS:
            value = getattr(self, key)
            out[key] = [row.to_dict() for row in value] if key == "legs" else value
        for key in _FILE_KEYS:
            if getattr(self, key) is not None:
                out[key] = getattr(self, key)
        out.update(self.extra)
        return out

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> TrackReport:
        """Read a report written by :meth:`to_dict` (an OUT.json of ``aeromag track``)."""
        known = [k for k in (*_KEYS, *_FILE_KEYS) if k not in _DERIVED]
        kw = {k: d[k] for k in known if k in d}
        kw["legs"] = [LegSummary.from_dict(row) for row in d.get("legs", [])]
        extra = {k: v for k, v in d.items() if k not in _KEYS and k not in _FILE_KEYS}
        return cls(**kw, extra=extra)
