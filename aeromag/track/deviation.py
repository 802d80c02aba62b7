"""Track-deviation alarms and the per-leg summary of every detector."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from ..detection.alarms import Alarms
from .report import LegSummary, PassSummary

__all__ = ["first_detector", "leg_summary", "track_alarm"]


def _sample_dt(t: np.ndarray) -> np.ndarray:
    """Duration represented by each sample (forward difference; median for the last), s."""
    if len(t) < 2:
        return np.zeros(len(t))
    dt = np.diff(t)
    return np.r_[dt, np.median(dt)]


def track_alarm(
    xtrack: np.ndarray,
    labels: np.ndarray,
    time: np.ndarray,
    *,
    threshold_m: float = 1.0,
    min_duration_s: float = 0.0,
) -> np.ndarray:
    """Track-deviation alarm per sample.

    A sample alarms when it is on a leg and ``xtrack`` is strictly above ``threshold_m``; with
    ``min_duration_s > 0`` only once the exceedance has lasted that long (time since the first
    sample of the current run of exceedances on the same leg >= ``min_duration_s``).

    Parameters
    ----------
    xtrack : ndarray
        Cross-track distance, m (NaN off-leg).
    labels : ndarray of int
        Leg per sample, -1 for none.
    time : ndarray
        Sample time, s.
    threshold_m : float
        Alarm threshold, m.
    min_duration_s : float
        Minimum duration of an exceedance before it alarms, s.

    Returns
    -------
    ndarray of bool
    """
    with np.errstate(invalid="ignore"):
        above = (labels >= 0) & (np.asarray(xtrack) > threshold_m)
    if min_duration_s <= 0 or not above.any():
        return above
    # Runs of consecutive exceedances on the same leg.
    brk = np.r_[True, (~above[:-1]) | (labels[1:] != labels[:-1])]
    run_id = np.cumsum(brk)
    t = np.asarray(time, dtype=np.float64)
    run_start_t = pd.Series(t).groupby(run_id).transform("first").to_numpy()
    return above & (t - run_start_t >= min_duration_s)


def _first_time(t: np.ndarray, mask: np.ndarray) -> float | None:
    idx = np.flatnonzero(mask)
    return float(t[idx[0]]) if idx.size else None


def first_detector(first_times: Mapping[str, float | None]) -> str | None:
    """Which detector fired first.

    Parameters
    ----------
    first_times : mapping
        Detector name -> time of its first alarm, s (None when it did not fire).

    Returns
    -------
    str or None
        The name of the earliest detector; on a tie ``"both"`` for two detectors and the names
        joined by ``+`` for more; None when none fired.
    """
    fired = {k: v for k, v in first_times.items() if v is not None}
    if not fired:
        return None
    t0 = min(fired.values())
    names = [k for k, v in fired.items() if v == t0]
    if len(names) == 1:
        return names[0]
    return "both" if len(names) == 2 else "+".join(names)


def _alarm_array(a: Alarms | np.ndarray) -> np.ndarray:
    return np.asarray(a.alarm if isinstance(a, Alarms) else a, dtype=bool)


def _span(t: np.ndarray, dt: np.ndarray, m: np.ndarray, cols: dict[str, np.ndarray],
          det: dict[str, np.ndarray | None], threshold_m: float) -> dict[str, Any]:
    """Fields of the :class:`~aeromag.track.report.SpanSummary` of the samples ``m``.

    ``m``: a leg or one pass over it.
    """
    x, h, v, al = cols["x"], cols["h"], cols["v"], cols["alarm"]
    if not m.any():
        # a leg without samples was not checked: "flagged": false then means nothing
        return {"n_samples": 0, "checked": False,
                "first_alarm_times": dict.fromkeys(det)}
    tt = t[m]
    with np.errstate(invalid="ignore"):
        above = x[m] > threshold_m
    firsts = {name: (None if a is None else _first_time(tt, a[m])) for name, a in det.items()}

    def peak(a: np.ndarray) -> float | None:
        return float(np.nanmax(a[m])) if np.isfinite(a[m]).any() else None

    return {"n_samples": int(m.sum()), "checked": True, "t_start": float(tt[0]),
            "t_end": float(tt[-1]), "max_xtrack_m": peak(x), "max_abs_xtrack_h_m": peak(h),
            "max_abs_xtrack_v_m": peak(v), "first_alarm_time": _first_time(tt, al[m]),
            "first_alarm_times": firsts,
            "time_above_threshold_s": float(dt[m][above].sum()), "flagged": bool(al[m].any()),
            "first_detector": first_detector(firsts)}


def leg_summary(
    data: pd.DataFrame,
    n_legs: int,
    threshold_m: float,
    detectors: Mapping[str, Alarms | np.ndarray | None],
    pass_id: np.ndarray | None = None,
) -> list[LegSummary]:
    """Per-leg summary of a checked log, with every pass, for any number of detectors.

    Parameters
    ----------
    data : DataFrame
        Output of :func:`~aeromag.track.check_track` (``time``, ``leg``, ``xtrack_*``,
        ``alarm``).
    n_legs : int
        Number of legs in the plan (every leg gets a row, flown or not).
    threshold_m : float
        Track threshold, m (for ``time_above_threshold_s``).
    detectors : mapping
        Detector name -> its :class:`~aeromag.detection.Alarms` (or per-sample alarm array),
        in report order, or None when the detector did not run (its first-alarm time is then
        null).  Each gets its ``first_alarm_times`` entry and may be ``first_detector``.
    pass_id : ndarray of int, optional
        Pass of each sample (-1 for none, see :func:`aeromag.track.legs.leg_passes`); when
        given each leg lists its passes under ``passes`` with their own start and end.

    Returns
    -------
    list of LegSummary
        One per leg (its JSON keys are listed in ``docs/track.md``); times in s, distances in
        m.
    """
    t = data["time"].to_numpy(dtype=np.float64)
    dt = _sample_dt(t)
    lab = data["leg"].fillna(-1).to_numpy(dtype=np.int64)
    cols = {"x": data["xtrack_m"].to_numpy(dtype=np.float64),
            "h": np.abs(data["xtrack_h_m"].to_numpy(dtype=np.float64)),
            "v": np.abs(data["xtrack_v_m"].to_numpy(dtype=np.float64)),
            "alarm": data["alarm"].to_numpy(dtype=bool)}
    det = {name: (None if a is None else _alarm_array(a)) for name, a in detectors.items()}
    out: list[LegSummary] = []
    for k in range(n_legs):
        m = lab == k
        row = LegSummary(leg=k, **_span(t, dt, m, cols, det, threshold_m))
        if pass_id is not None:
            ids = np.unique(pass_id[m & (pass_id >= 0)])
            row.n_passes = int(ids.size)
            # pass_number: this leg's pass number (1, 2, ...); session_pass: the session-wide
            # index of the pass (0-based, time order over all legs)
            row.passes = [PassSummary(pass_number=j + 1, session_pass=int(p),
                                      **_span(t, dt, pass_id == p, cols, det, threshold_m))
                          for j, p in enumerate(ids)]
        out.append(row)
    return out
