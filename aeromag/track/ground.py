"""Which rows of a log are on the ground: never on a leg, never evidence for a hypothesis.

A day's work in one log holds the vehicle on the ground between its flights: at rest after a
landing, disarmed, then carried by hand to the next take-off point, often along the line just
flown (walking pace, a metre above the ground, tens of metres below the plan).  Such rows move
along a leg (backwards, or forwards when carried the other way) and, once an altitude datum
is assumed, can look like a pass: a log of six forward passes at the plan's altitude and five
carries back along the line was read as a mission flown reversed 21 m below its plan, the leg
given to 179 ground rows and none of the passes (issue 30).  :func:`ground_rows` marks them:

* **From the log** when it says so: a column ``armed`` (false: on the ground; ArduPilot's
  ``EV`` arm/disarm events, PX4's ``vehicle_status.arming_state``) and/or ``landed`` (true:
  on the ground; PX4's ``vehicle_land_detected.landed``, ArduPilot's ``LAND_COMPLETE``).
  Empty cells of these state columns (a multi-rate log) take the state of the row before.
* **Inferred** otherwise, from the take-off height: the level of the rest (slower than
  :data:`REST_SPEED_M_S` horizontally and :data:`REST_VSPEED_M_S` vertically for at least
  :data:`REST_MIN_S`) at the log's start and at its end (a log starts at arming, on the
  ground, and ends after the last landing).  When the log rises at least
  :data:`MIN_CLIMB_M` above that level, a row is on the ground when it is within
  ``band = min(GROUND_BAND_M, GROUND_BAND_FRACTION * climb)`` of the take-off height *and* in
  a stretch of such rows that holds a rest on the ground (a landing, a wait): a carry back
  along the line is, a low pass that never stops there is not.  A log that never leaves its
  first height (or never rests at its start or end) has no inferred ground.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from .._core.runs import true_runs
from ..errors import InputError

__all__ = ["GROUND_BAND_FRACTION", "GROUND_BAND_M", "GROUND_COLUMNS", "MIN_CLIMB_M",
           "REST_MIN_S", "REST_SPEED_M_S", "REST_VSPEED_M_S", "ground_rows", "ground_spans"]

#: The log's state columns (name, value that means "on the ground").
GROUND_COLUMNS = (("armed", False), ("landed", True))

#: Horizontal speed below which a row is at rest, m/s.
REST_SPEED_M_S = 0.3

#: Vertical speed below which a row is at rest, m/s.
REST_VSPEED_M_S = 0.2

#: Shortest rest that makes a stretch at take-off height ground, s.
REST_MIN_S = 3.0

#: Smallest rise above the take-off height for ground to be inferred, m.
MIN_CLIMB_M = 4.0

#: Widest band about the take-off height that is ground, m (a vehicle carried by hand is
#: about 1 m above the ground; take-off points of one day differ by a metre or two).
GROUND_BAND_M = 3.0

#: The band is at most this fraction of the rise above the take-off height (a survey flown
#: low keeps its passes out of it).
GROUND_BAND_FRACTION = 0.25


def _state(log_df: pd.DataFrame, name: str, source: str) -> np.ndarray | None:
    """A boolean state column (True/False, 1/0, true/false), empty cells carried forward."""
    if name not in log_df.columns:
        return None
    col = log_df[name]
    if col.dtype == bool:
        return col.to_numpy(dtype=bool)
    text = col.astype("string").str.strip().str.lower()
    words = {"true": 1.0, "false": 0.0, "1": 1.0, "0": 0.0, "1.0": 1.0, "0.0": 0.0,
             "yes": 1.0, "no": 0.0}
    val = text.map(words, na_action="ignore")
    bad = text.notna() & (text != "") & val.isna()
    if bad.any():
        i = int(np.flatnonzero(bad.to_numpy())[0])
        raise InputError(f"{source}: column '{name}', line {i + 2}: {col.iloc[i]!r} is not a"
                         " state (true/false or 1/0); fix the value or drop the column")
    v = pd.to_numeric(val, errors="coerce").ffill().bfill()
    if v.isna().all():
        return None
    return v.to_numpy(dtype=np.float64) > 0.5


def ground_spans(time_s: np.ndarray, ground: np.ndarray) -> list[list[float]]:
    """Time spans ``[t_first, t_last]`` of the runs of ground rows, s."""
    t = np.asarray(time_s, dtype=np.float64)
    return [[float(t[a]), float(t[b - 1])] for a, b in zip(*true_runs(ground), strict=True)]


def ground_rows(time_s: np.ndarray, ned: np.ndarray, vel: np.ndarray,
                log_df: pd.DataFrame | None = None, source: str = "<log>"
                ) -> tuple[np.ndarray, dict[str, Any]]:
    """Rows on the ground (see the module docstring).

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Sample times, s (increasing).
    ned : ndarray, shape (n, 3)
        Positions, NED, m (NaN rows: not positioned, not ground by inference).
    vel : ndarray, shape (n, 3)
        Velocities, NED, m/s.
    log_df : DataFrame, optional
        The log, for its ``armed`` / ``landed`` columns.
    source : str
        Name of the log quoted in errors.

    Returns
    -------
    ground : ndarray of bool, shape (n,)
    info : dict
        ``source`` (the columns used, ``"inferred"`` or ``"none"``), ``n_rows``, ``spans``
        (time spans of the ground stretches, s) and, inferred, ``takeoff_down_m`` (the
        take-off heights, NED down, m), ``climb_m`` and ``band_m``.
    """
    t = np.asarray(time_s, dtype=np.float64)
    p = np.asarray(ned, dtype=np.float64)
    n = len(t)
    ground = np.zeros(n, dtype=bool)
    used = []
    if log_df is not None:
        for name, on_ground in GROUND_COLUMNS:
            st = _state(log_df, name, source)
            if st is not None:
                ground |= st == on_ground
                used.append(name)
    info: dict[str, Any] = {"source": "+".join(used) if used else "none"}
    if not used:
        inferred = _inferred(t, p, np.asarray(vel, dtype=np.float64))
        if inferred is not None:
            ground, extra = inferred
            info.update(source="inferred", **extra)
    info["n_rows"] = int(ground.sum())
    info["spans"] = ground_spans(t, ground)
    return ground, info


def _inferred(t: np.ndarray, p: np.ndarray, v: np.ndarray
              ) -> tuple[np.ndarray, dict[str, Any]] | None:
    """Ground from the take-off height and the rests at it (None: not inferable)."""
    fin = np.isfinite(p).all(axis=1) & np.isfinite(v).all(axis=1)
    if fin.sum() < 3:
        return None
    rest = fin & (np.hypot(v[:, 0], v[:, 1]) < REST_SPEED_M_S) & (np.abs(v[:, 2])
                                                                   < REST_VSPEED_M_S)
    starts, stops = true_runs(rest)
    long = [(a, b) for a, b in zip(starts, stops, strict=True)
            if t[b - 1] - t[a] >= REST_MIN_S - 1e-9]
    pos = np.flatnonzero(fin)
    levels = []
    for a, b in long:
        # the rest the log starts with, and the one it ends with: the take-off heights
        if a <= pos[0] or b - 1 >= pos[-1]:
            levels.append(float(np.median(p[a:b, 2])))
    if not levels:
        return None
    lev = np.asarray(levels)
    top = float(np.quantile(p[fin, 2], 0.01))       # down: the highest 1 % of the log
    climb = float(np.min(lev) - top)
    if climb < MIN_CLIMB_M:
        return None
    band = min(GROUND_BAND_M, GROUND_BAND_FRACTION * climb)
    near = fin.copy()
    near[fin] = np.min(np.abs(p[fin, 2][:, None] - lev[None, :]), axis=1) < band
    rest_near = np.zeros(len(t), dtype=bool)
    for a, b in long:
        if np.all(near[a:b]):
            rest_near[a:b] = True
    ground = np.zeros(len(t), dtype=bool)
    for a, b in zip(*true_runs(near), strict=True):
        if rest_near[a:b].any():
            ground[a:b] = True
    return ground, {"takeoff_down_m": [float(x) for x in np.unique(np.round(lev, 3))],
                    "climb_m": climb, "band_m": band}
