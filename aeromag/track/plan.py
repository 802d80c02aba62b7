"""Validation of a mission plan given as a table of waypoints (from any file or built in Python)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..errors import InputError
from .geometry import plan_ned

__all__ = ["MIN_LEG_LENGTH_M", "PLAN_NEEDS", "validate_plan"]

#: Largest plan altitude accepted, m (above 100 km is not a flight plan).
MAX_ABS_ALT_M = 1.0e5

#: Shortest leg accepted in a plan, m.
MIN_LEG_LENGTH_M = 0.01

#: What a plan file must hold (quoted in errors; ``--col`` does not apply to plans).
PLAN_NEEDS = ("a plan is a CSV with a header row and columns lat, lon (degrees, WGS84) and alt"
              " (m above the WGS84 ellipsoid), one row per waypoint in flight order; rename the"
              " plan's columns to these names")


def validate_plan(plan: pd.DataFrame, source: str = "<plan>") -> pd.DataFrame:
    """Check a mission plan and return it with float ``lat``, ``lon``, ``alt``.

    Parameters
    ----------
    plan : DataFrame
        Waypoints in flight order with ``lat``, ``lon`` [deg] and ``alt`` [m, ellipsoidal].
    source : str
        File name quoted in errors.

    Returns
    -------
    DataFrame
        ``lat``, ``lon``, ``alt`` as float64 (other columns kept), index reset.

    Notes
    -----
    Errors name the file line of the waypoint: ``plan.attrs["lines"]`` when the reader gave
    them (ground-station mission files), otherwise row + 2 (a CSV with its header on line 1).
    """
    lines = plan.attrs.get("lines")

    def line(i: int) -> int:
        return int(lines[i]) if lines is not None and i < len(lines) else i + 2

    missing = [c for c in ("lat", "lon", "alt") if c not in plan.columns]
    if missing:
        avail = ", ".join(map(str, plan.columns[:20])) or "(none)"
        raise InputError(
            f"{source}: plan is missing column(s) {', '.join(missing)}; columns are: {avail};"
            f" {PLAN_NEEDS}"
        )
    out = plan.reset_index(drop=True).copy()
    for c in ("lat", "lon", "alt"):
        conv = pd.to_numeric(out[c], errors="coerce")
        bad = ~np.isfinite(conv.to_numpy(dtype=np.float64))
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raw = out[c].iloc[i]
            what = ("is empty" if pd.isna(raw) or not str(raw).strip()
                    else f"value {str(raw)!r} is not a finite number")
            raise InputError(f"{source}: column {c!r}, line {line(i)}: {what}; fix the waypoint")
        out[c] = conv.astype(np.float64)
    if len(out) < 2:
        raise InputError(
            f"{source}: the plan has {len(out)} waypoint(s); a plan needs at least 2 (one leg)"
        )
    lat = out["lat"].to_numpy()
    bad = np.abs(lat) > 90
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        where = (f"column 'lat', line {line(i)}" if lines is None
                 else f"navigation waypoint {i + 1} of the mission (the item at line {line(i)})")
        fix = "check the column order" if lines is None else "fix the mission item"
        raise InputError(f"{source}: {where}: latitude {lat[i]:g} outside [-90, 90] degrees;"
                         f" {fix}")
    alt = out["alt"].to_numpy()
    bad = np.abs(alt) > MAX_ABS_ALT_M
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"{source}: column 'alt', line {line(i)}: altitude {alt[i]:g} m is not"
                         f" a height near the Earth (|alt| <= {MAX_ABS_ALT_M:g} m); check the"
                         " column and its unit")
    lon = out["lon"].to_numpy()
    bad = np.abs(lon) > 360
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"{source}: column 'lon', line {line(i)}: longitude {lon[i]:g} outside"
                         " [-180, 360] degrees; check the column order and units")
    ned = plan_ned(out)
    lengths = np.linalg.norm(np.diff(ned, axis=0), axis=1)
    short = lengths < MIN_LEG_LENGTH_M
    if short.any():
        k = int(np.flatnonzero(short)[0])
        raise InputError(
            f"{source}: lines {line(k)} and {line(k + 1)}: repeated waypoint makes leg {k}"
            f" zero-length ({lengths[k]:.3g} m); remove the duplicate waypoint"
        )
    return out
