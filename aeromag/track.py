"""DGPS track-deviation check per mission leg, combined with the heading detector.

Method (methods M2): a multirotor on RTK DGPS follows its planned lines to within tens of
centimetres.  When a magnetic disturbance bends the compass, the estimated heading drifts, the
commanded acceleration is rotated by the heading error and the track leaves the line.  For a
leg from waypoint ``A`` to ``B`` and an antenna position ``X``, all in a local north-east-down
(NED) frame with its origin at the first waypoint of the plan (the take-off point),

    d = |(X - A) x (B - A)| / |B - A|                                   (``xtrack_m``)

and the sample alarms when ``d`` is strictly above a threshold (1 m by default).

Geometry is exact: geodetic (WGS84 latitude, longitude, ellipsoidal height) -> ECEF with pyproj
(one Transformer, built once) -> NED by the rotation at the origin.  No degrees are ever used as
metres, so the result holds anywhere on Earth, across UTM zone boundaries and at high latitude.
The deviation is split into a horizontal part ``xtrack_h_m`` (signed, positive to the right of
the direction of travel) and a vertical part ``xtrack_v_m`` (signed, positive above the line),
with ``hypot(xtrack_h_m, xtrack_v_m) == xtrack_m``; ``along_m`` is the position along the leg
from ``A``.

Leg assignment
--------------
When the log has a ``leg`` column (the autopilot's own leg index) it is used as is (empty or
negative values mean "no leg").  Otherwise legs are assigned by this rule, with a waypoint
radius ``R`` (default 5 m, enlarged to 1.5 times the 95th percentile of the distance between
successive samples when the log is sparse):

1. *Leg start.*  Leg ``k`` (``A = W_k`` to ``B = W_k+1``) starts at the first sample at which
   the vehicle leaves the sphere of radius ``R`` around ``A`` towards ``B``: the previous sample
   was inside the sphere, this one is outside, and it lies within 45 degrees of the leg's
   direction (cross-track distance <= along-track distance).  A vehicle that has not reached
   ``A`` yet, is climbing to it, or is turning around inside it is therefore not on the leg.
2. *Leg end.*  The leg ends (exclusive) at the first later sample inside the sphere around
   ``B`` or past the plane through ``B`` perpendicular to the leg, or when the vehicle leaves
   ``A`` towards ``B`` again (the leg is being re-flown).
3. *Sequence.*  Starting from the beginning of the log, the next leg is the one whose start
   event comes first after the current leg's end; on a tie the next leg in the plan is
   preferred, then the same leg again (re-flown), then the nearest leg number.
4. Samples on no leg -- take-off, climb to the first waypoint, turns and hovering inside the
   waypoint spheres, transit back to re-fly a leg, landing -- get an empty ``leg``, no
   ``xtrack_*`` values and never alarm.

Turns therefore never count as deviations; the price is that the first and last ``R`` metres
of each leg are not checked.

Per-leg summary: ``leg``, ``n_samples``, ``t_start``/``t_end`` [s], ``max_xtrack_m``,
``max_abs_xtrack_h_m``, ``max_abs_xtrack_v_m``, ``first_alarm_time`` (combined verdict; null
when none), ``first_track_alarm_time``, ``first_heading_alarm_time``, ``time_above_threshold_s``,
``flagged`` and ``first_detector`` (``"track"``, ``"heading"``, ``"both"`` or null).
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ._core.geodesy import ecef_to_ned_matrix, geodetic_to_ecef, geodetic_to_ned  # noqa: F401
from .detect import CalmWindow, combine_alarms, heading_columns_available, heading_detector
from .errors import InputError
from .io import json_path_for, read_log, write_csv, write_json

log = logging.getLogger(__name__)

#: Default waypoint radius, m (see the leg-assignment rule).
DEFAULT_WAYPOINT_RADIUS_M = 5.0

#: Shortest leg accepted in a plan, m.
MIN_LEG_LENGTH_M = 0.01

#: What a plan file must hold (quoted in errors; ``--col`` does not apply to plans).
PLAN_NEEDS = ("a plan is a CSV with a header row and columns lat, lon (degrees, WGS84) and alt"
              " (m above the WGS84 ellipsoid), one row per waypoint in flight order; rename the"
              " plan's columns to these names")

#: Columns that ``track`` adds, in output order.
ADDED_COLUMNS = ("leg", "xtrack_m", "xtrack_h_m", "xtrack_v_m", "along_m", "track_alarm",
                 "heading_diff_deg", "heading_alarm", "alarm")


# --------------------------------------------------------------------------- geometry
def cross_track(
    x: np.ndarray, a: np.ndarray, b: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Distance from points to the line through ``a`` and ``b`` and its parts (NED frame).

    ``d = |(x - a) x (b - a)| / |b - a|``.  The perpendicular offset is split into a horizontal
    part along ``down x u`` (``u`` the unit leg direction; positive to the right of travel) and a
    vertical part along ``u x (down x u)`` reversed (positive above the line).  For a vertical
    leg the horizontal axis is east.

    Parameters
    ----------
    x : ndarray, shape (n, 3) or (3,)
        Points, NED, m.
    a, b : ndarray, shape (3,)
        Line start and end, NED, m (distinct).

    Returns
    -------
    d, h, v, along : ndarray, shape (n,)
        3-D distance to the line [m], signed horizontal part [m], signed vertical part [m]
        (``hypot(h, v) == d``), and position along the line from ``a`` [m].
    """
    x = np.atleast_2d(np.asarray(x, dtype=np.float64))
    a = np.asarray(a, dtype=np.float64)
    ab = np.asarray(b, dtype=np.float64) - a
    length = float(np.linalg.norm(ab))
    if not length > 0:
        raise ValueError("cross_track: a and b must be distinct")
    u = ab / length
    rel = x - a
    d = np.linalg.norm(np.cross(rel, ab), axis=1) / length
    along = rel @ u
    down = np.array([0.0, 0.0, 1.0])
    hdir = np.cross(down, u)
    hn = float(np.linalg.norm(hdir))
    hdir = hdir / hn if hn > 1e-12 else np.array([0.0, 1.0, 0.0])
    vdir = np.cross(hdir, u)  # up for a horizontal leg
    h = rel @ hdir
    v = rel @ vdir
    return d, h, v, along


# --------------------------------------------------------------------------- plans
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
    """
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
            raise InputError(
                f"{source}: column {c!r}, line {i + 2}: value {str(out[c].iloc[i])!r} is not a"
                " finite number; fix the waypoint"
            )
        out[c] = conv.astype(np.float64)
    if len(out) < 2:
        raise InputError(
            f"{source}: the plan has {len(out)} waypoint(s); a plan needs at least 2 (one leg)"
        )
    lat = out["lat"].to_numpy()
    bad = np.abs(lat) > 90
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"{source}: column 'lat', line {i + 2}: latitude {lat[i]:g} outside"
                         " [-90, 90] degrees; check the column order")
    ned = plan_ned(out)
    lengths = np.linalg.norm(np.diff(ned, axis=0), axis=1)
    short = lengths < MIN_LEG_LENGTH_M
    if short.any():
        k = int(np.flatnonzero(short)[0])
        raise InputError(
            f"{source}: lines {k + 2} and {k + 3}: repeated waypoint makes leg {k} zero-length"
            f" ({lengths[k]:.3g} m); remove the duplicate waypoint"
        )
    return out


def plan_ned(plan: pd.DataFrame) -> np.ndarray:
    """Waypoints of a plan in the NED frame at its first waypoint.

    Parameters
    ----------
    plan : DataFrame
        ``lat``, ``lon`` [deg], ``alt`` [m].

    Returns
    -------
    ndarray, shape (n_waypoints, 3)
        North, east, down, m.
    """
    lat, lon, alt = (plan[c].to_numpy(dtype=np.float64) for c in ("lat", "lon", "alt"))
    return geodetic_to_ned(lat, lon, alt, (lat[0], lon[0], alt[0]))


def _blank_file(path: Path, most: int = 1 << 16) -> bool:
    """True when a file holds nothing but white space (and a UTF-8 byte-order mark)."""
    try:
        if path.stat().st_size > most:
            return False
        data = path.read_bytes()
    except OSError:
        return False  # read_log reports it
    return not data.removeprefix(b"\xef\xbb\xbf").strip()


def read_plan(path: str | os.PathLike[str]) -> pd.DataFrame:
    """Read and validate a mission plan CSV.

    Parameters
    ----------
    path : path-like
        CSV of waypoints in flight order with ``lat``, ``lon`` [deg] and ``alt`` [m].

    Returns
    -------
    DataFrame
        The validated plan (see :func:`validate_plan`).
    """
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{p}: plan file not found (or not a file); check the --plan path")
    if _blank_file(p):
        raise InputError(f"{p}: the plan is empty; {PLAN_NEEDS}")
    # No required columns here: validate_plan says what a plan needs (--col is for logs).
    df = read_log(p, required=(), min_rows=0)
    return validate_plan(df, str(p))


# --------------------------------------------------------------------------- legs
def _effective_radius(ned: np.ndarray, radius: float) -> float:
    """Waypoint radius, enlarged when successive samples are far apart."""
    if len(ned) < 2:
        return radius
    steps = np.linalg.norm(np.diff(ned, axis=0), axis=1)
    steps = steps[np.isfinite(steps)]
    if steps.size == 0:
        return radius
    eff = max(radius, 1.5 * float(np.percentile(steps, 95)))
    if eff > radius:
        log.info("waypoint radius enlarged from %.2f m to %.2f m (sparse samples)", radius, eff)
    return eff


def assign_legs(
    ned: np.ndarray, waypoints: np.ndarray, *, waypoint_radius_m: float = DEFAULT_WAYPOINT_RADIUS_M
) -> np.ndarray:
    """Assign each sample to a mission leg (see the module docstring for the rule).

    Parameters
    ----------
    ned : ndarray, shape (n, 3)
        Antenna positions, NED, m.
    waypoints : ndarray, shape (m, 3)
        Plan waypoints, NED, m.
    waypoint_radius_m : float
        Radius of the sphere around each waypoint inside which the vehicle is turning, m.

    Returns
    -------
    ndarray of int, shape (n,)
        Leg index per sample, -1 for none.
    """
    n = len(ned)
    n_legs = len(waypoints) - 1
    labels = np.full(n, -1, dtype=np.int64)
    if n < 2 or n_legs < 1:
        return labels
    r = _effective_radius(ned, waypoint_radius_m)
    finite = np.isfinite(ned).all(axis=1)
    starts: list[np.ndarray] = []
    ends: list[np.ndarray] = []
    for k in range(n_legs):
        a, b = waypoints[k], waypoints[k + 1]
        d, _, _, along = cross_track(ned, a, b)
        length = float(np.linalg.norm(b - a))
        in_a = (np.linalg.norm(ned - a, axis=1) <= r) & finite
        in_b = (np.linalg.norm(ned - b, axis=1) <= r) & finite
        leave = np.r_[False, in_a[:-1] & ~in_a[1:]] & finite & (d <= along)
        starts.append(np.flatnonzero(leave))
        ends.append(np.flatnonzero(in_b | (along >= length)))
    pos, cur = 0, -1
    while True:
        best: tuple[int, int, int] | None = None
        for k in range(n_legs):
            j = int(np.searchsorted(starts[k], pos))
            if j == len(starts[k]):
                continue
            prio = 0 if k == cur + 1 else (1 if k == cur else 2 + abs(k - cur))
            cand = (int(starts[k][j]), prio, k)
            if best is None or cand < best:
                best = cand
        if best is None:
            break
        s, _, k = best
        j = int(np.searchsorted(ends[k], s + 1))
        e = int(ends[k][j]) if j < len(ends[k]) else n
        j = int(np.searchsorted(starts[k], s + 1))
        if j < len(starts[k]):
            e = min(e, int(starts[k][j]))
        labels[s:e] = k
        pos, cur = e, k
    return labels


def _labels_from_column(log_df: pd.DataFrame, n_legs: int, source: str) -> np.ndarray:
    """Leg labels from the log's own ``leg`` column (empty or negative: no leg)."""
    vals = pd.to_numeric(log_df["leg"], errors="coerce").to_numpy(dtype=np.float64)
    ok = np.isfinite(vals) & (vals >= 0)
    frac = ok & (vals != np.round(vals))
    if frac.any():
        i = int(np.flatnonzero(frac)[0])
        raise InputError(f"{source}: column 'leg', line {i + 2}: {vals[i]!r} is not an integer"
                         " leg index")
    over = ok & (vals >= n_legs)
    if over.any():
        i = int(np.flatnonzero(over)[0])
        raise InputError(
            f"{source}: column 'leg', line {i + 2}: leg {int(vals[i])} but the plan has only"
            f" {n_legs} leg(s) (0-{n_legs - 1}); use the matching plan or drop the leg column"
        )
    return np.where(ok, vals, -1).astype(np.int64)


# --------------------------------------------------------------------------- alarms
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


def leg_summary(
    data: pd.DataFrame, n_legs: int, threshold_m: float, heading: bool
) -> list[dict[str, Any]]:
    """Per-leg summary of a checked log.

    Parameters
    ----------
    data : DataFrame
        Output of :func:`check_track` (``time``, ``leg``, ``xtrack_*``, alarms).
    n_legs : int
        Number of legs in the plan (every leg gets a row, flown or not).
    threshold_m : float
        Track threshold, m (for ``time_above_threshold_s``).
    heading : bool
        Whether the heading detector ran.

    Returns
    -------
    list of dict
        One dict per leg (keys listed in the module docstring); times in s, distances in m.
    """
    t = data["time"].to_numpy(dtype=np.float64)
    dt = _sample_dt(t)
    lab = data["leg"].fillna(-1).to_numpy(dtype=np.int64)
    x = data["xtrack_m"].to_numpy(dtype=np.float64)
    h = np.abs(data["xtrack_h_m"].to_numpy(dtype=np.float64))
    v = np.abs(data["xtrack_v_m"].to_numpy(dtype=np.float64))
    ta = data["track_alarm"].to_numpy(dtype=bool)
    al = data["alarm"].to_numpy(dtype=bool)
    ha = data["heading_alarm"].to_numpy(dtype=bool) if heading else np.zeros(len(t), bool)
    out: list[dict[str, Any]] = []
    for k in range(n_legs):
        m = lab == k
        row: dict[str, Any] = {"leg": k, "n_samples": int(m.sum())}
        if not m.any():
            row.update(t_start=None, t_end=None, max_xtrack_m=None, max_abs_xtrack_h_m=None,
                       max_abs_xtrack_v_m=None, first_alarm_time=None,
                       first_track_alarm_time=None, first_heading_alarm_time=None,
                       time_above_threshold_s=0.0, flagged=False, first_detector=None)
            out.append(row)
            continue
        tt = t[m]
        with np.errstate(invalid="ignore"):
            above = x[m] > threshold_m
        ft = _first_time(tt, ta[m])
        fh = _first_time(tt, ha[m]) if heading else None
        first_det = None
        if ft is not None and (fh is None or ft < fh):
            first_det = "track"
        elif fh is not None and (ft is None or fh < ft):
            first_det = "heading"
        elif ft is not None and fh is not None:
            first_det = "both"
        row.update(
            t_start=float(tt[0]), t_end=float(tt[-1]),
            max_xtrack_m=float(np.nanmax(x[m])) if np.isfinite(x[m]).any() else None,
            max_abs_xtrack_h_m=float(np.nanmax(h[m])) if np.isfinite(h[m]).any() else None,
            max_abs_xtrack_v_m=float(np.nanmax(v[m])) if np.isfinite(v[m]).any() else None,
            first_alarm_time=_first_time(tt, al[m]),
            first_track_alarm_time=ft,
            first_heading_alarm_time=fh,
            time_above_threshold_s=float(dt[m][above].sum()),
            flagged=bool(al[m].any()),
            first_detector=first_det,
        )
        out.append(row)
    return out


# --------------------------------------------------------------------------- top level
@dataclass
class TrackResult:
    """Result of :func:`check_track`.

    Attributes
    ----------
    data : DataFrame
        The input log with the added columns (``leg``, ``xtrack_m``, ``xtrack_h_m``,
        ``xtrack_v_m``, ``along_m``, ``track_alarm``, and when possible ``heading_diff_deg``,
        ``heading_alarm``; always ``alarm``).
    legs : list of dict
        Per-leg summary (see :func:`leg_summary`).
    report : dict
        The JSON report: ``{"legs": legs, ...settings and heading statistics}``.
    """

    data: pd.DataFrame
    legs: list[dict[str, Any]] = field(default_factory=list)
    report: dict[str, Any] = field(default_factory=dict)


def check_track(
    log_df: pd.DataFrame,
    plan: pd.DataFrame,
    *,
    threshold_m: float = 1.0,
    min_duration_s: float = 0.0,
    calm_window: CalmWindow = None,
    heading_sigmas: float = 5.0,
    declination_deg: float = 0.0,
    combine: str = "or",
    waypoint_radius_m: float = DEFAULT_WAYPOINT_RADIUS_M,
    source: str | None = None,
) -> TrackResult:
    """Flag DGPS track deviations per leg, run the heading detector and combine them.

    Parameters
    ----------
    log_df : DataFrame
        Survey log with ``time`` [s], ``lat``/``lon`` [deg], ``alt`` [m]; optionally ``leg``,
        ``heading`` [deg] with ``mag_heading`` [deg] or ``flux_x/y/z`` [nT] + ``pitch``/``roll``
        [deg] for the heading detector.
    plan : DataFrame
        Waypoints with ``lat``, ``lon`` [deg], ``alt`` [m] (validated here).
    threshold_m : float
        Track alarm threshold, m (alarm when ``xtrack_m`` is strictly above it).
    min_duration_s : float
        Minimum duration of an exceedance before the track alarm fires, s.
    calm_window : float, (float, float), str or None
        Calm reference window of the heading detector: seconds from the start (default 30) or
        an absolute time range (``"t0:t1"``), s.
    heading_sigmas : float
        Heading alarm factor ``k`` (alarm above ``k`` sigma of the calm window).
    declination_deg : float
        Declination for a fluxgate-derived magnetometer heading, degrees east.
    combine : {"or", "and"}
        How the two detectors make the verdict ``alarm`` (see
        :func:`aeromag.detect.combine_alarms`).
    waypoint_radius_m : float
        Waypoint radius of the leg-assignment rule, m (unused when the log has ``leg``).
    source : str, optional
        Name of the log quoted in errors (default ``log_df.attrs["source"]``).

    Returns
    -------
    TrackResult
    """
    src = source or str(log_df.attrs.get("source", "<log>"))
    if not np.isfinite(threshold_m) or threshold_m <= 0:
        raise InputError(f"--threshold {threshold_m!r}: must be a positive number of metres")
    if not np.isfinite(min_duration_s) or min_duration_s < 0:
        raise InputError(f"--min-duration {min_duration_s!r}: must be >= 0 seconds")
    if not np.isfinite(waypoint_radius_m) or waypoint_radius_m <= 0:
        raise InputError(f"--waypoint-radius {waypoint_radius_m!r}: must be positive metres")
    if str(combine).lower() not in ("or", "and"):
        raise InputError(f"--combine {combine!r}: use 'or' or 'and'")
    missing = [c for c in ("time", "lat", "lon", "alt") if c not in log_df.columns]
    if missing:
        raise InputError(
            f"{src}: missing column(s) {', '.join(missing)}; the track check needs time, lat, lon"
            " and alt (DGPS position); map them with --col NAME=SOURCE"
        )
    plan = validate_plan(plan, str(plan.attrs.get("source", "<plan>")))
    wp_geo = plan[["lat", "lon", "alt"]].to_numpy(dtype=np.float64)
    origin = (float(wp_geo[0, 0]), float(wp_geo[0, 1]), float(wp_geo[0, 2]))
    wps = geodetic_to_ned(wp_geo[:, 0], wp_geo[:, 1], wp_geo[:, 2], origin)
    n_legs = len(wps) - 1

    data = log_df.copy()
    pos = data[["lat", "lon", "alt"]].apply(pd.to_numeric, errors="coerce")
    lat, lon, alt = (pos[c].to_numpy(dtype=np.float64) for c in ("lat", "lon", "alt"))
    ok = np.isfinite(lat) & np.isfinite(lon) & np.isfinite(alt)
    if not ok.any():
        raise InputError(f"{src}: no row has a finite lat, lon and alt; the track check needs"
                         " DGPS positions")
    ned = np.full((len(data), 3), np.nan)
    ned[ok] = geodetic_to_ned(lat[ok], lon[ok], alt[ok], origin)

    if "leg" in data.columns:
        labels = _labels_from_column(data, n_legs, src)
        how = "log column"
    else:
        labels = assign_legs(ned, wps, waypoint_radius_m=waypoint_radius_m)
        how = "assigned"
    labels[~ok] = -1

    n = len(data)
    xt, xh, xv, al = (np.full(n, np.nan) for _ in range(4))
    for k in np.unique(labels[labels >= 0]):
        m = labels == k
        d, h, v, a = cross_track(ned[m], wps[k], wps[k + 1])
        xt[m], xh[m], xv[m], al[m] = d, h, v, a
    t = data["time"].to_numpy(dtype=np.float64)
    tr = track_alarm(xt, labels, t, threshold_m=threshold_m, min_duration_s=min_duration_s)

    data["leg"] = pd.array(np.where(labels >= 0, labels, 0), dtype="Int64")
    data.loc[labels < 0, "leg"] = pd.NA
    data["xtrack_m"] = xt
    data["xtrack_h_m"] = xh
    data["xtrack_v_m"] = xv
    data["along_m"] = al
    data["track_alarm"] = tr

    heading_info: dict[str, Any] = {"available": False}
    hd_alarm = None
    if heading_columns_available(data) is not None:
        hres = heading_detector(data, calm_window=calm_window, sigmas=heading_sigmas,
                                declination_deg=declination_deg, source=src)
        hd_alarm = hres.alarm & (labels >= 0)
        data["heading_diff_deg"] = hres.diff_deg
        data["heading_alarm"] = hd_alarm
        heading_info = {"available": True, "source": hres.source, "mean_deg": hres.mean_deg,
                        "sigma_deg": hres.sigma_deg, "n_calm": hres.n_calm,
                        "sigmas": heading_sigmas, "declination_deg": declination_deg}
    else:
        log.info("%s: no heading columns; heading detector skipped", src)
    data["alarm"] = combine_alarms(tr, hd_alarm, labels, combine)

    legs = leg_summary(data, n_legs, threshold_m, hd_alarm is not None)
    report = {
        "legs": legs,
        "n_legs": n_legs,
        "n_flagged": sum(1 for row in legs if row["flagged"]),
        "flagged_legs": [row["leg"] for row in legs if row["flagged"]],
        "threshold_m": threshold_m,
        "min_duration_s": min_duration_s,
        "combine": str(combine).lower(),
        "leg_source": how,
        "waypoint_radius_m": waypoint_radius_m,
        "origin": {"lat": origin[0], "lon": origin[1], "alt": origin[2]},
        "heading_detector": heading_info,
        "n_samples": n,
        "n_on_leg": int((labels >= 0).sum()),
    }
    log.info("%s: %d/%d legs flagged", src, report["n_flagged"], n_legs)
    return TrackResult(data=data, legs=legs, report=report)


def track_file(
    log_path: str | os.PathLike[str],
    plan_path: str | os.PathLike[str],
    out_path: str | os.PathLike[str],
    *,
    threshold_m: float = 1.0,
    min_duration_s: float = 0.0,
    calm_window: CalmWindow = None,
    heading_sigmas: float = 5.0,
    declination_deg: float = 0.0,
    combine: str = "or",
    waypoint_radius_m: float = DEFAULT_WAYPOINT_RADIUS_M,
    columns: dict[str, str] | None = None,
    units: dict[str, str] | None = None,
    plot_dir: str | os.PathLike[str] | None = None,
    fmt: str | None = None,
) -> TrackResult:
    """Read a log and a plan, check the track, write OUT.csv and OUT.json atomically.

    Outputs that would overwrite the log or the plan are refused before anything is read.

    Parameters
    ----------
    log_path : path-like
        Survey log (needs ``time``, ``lat``, ``lon``, ``alt``).
    plan_path : path-like
        Mission plan CSV (``lat``, ``lon``, ``alt`` per waypoint).
    out_path : path-like
        Output CSV; the report goes to the same path with suffix ``.json``.
    threshold_m, min_duration_s, calm_window, heading_sigmas, declination_deg, combine,
    waypoint_radius_m
        See :func:`check_track` (m, s, s, -, degrees, -, m).
    columns : dict, optional
        Column map ``{canonical: source}``.
    units : dict, optional
        Unit conversions for field columns.
    plot_dir : path-like, optional
        Folder for the track plots (PNG); none when omitted.
    fmt : str, optional
        Log format (default from the extension).

    Returns
    -------
    TrackResult
    """
    from .compensate import check_outputs

    out = Path(out_path)
    out_json = json_path_for(out)
    check_outputs(log_path, out, out_json)  # not OUT.json, never over the log or the plan
    check_outputs(plan_path, out, out_json, kind="plan")
    plan = read_plan(plan_path)
    plan.attrs["source"] = str(plan_path)
    df = read_log(log_path, columns=columns, units=units,
                  required=("time", "lat", "lon", "alt"), fmt=fmt)
    res = check_track(df, plan, threshold_m=threshold_m, min_duration_s=min_duration_s,
                      calm_window=calm_window, heading_sigmas=heading_sigmas,
                      declination_deg=declination_deg, combine=combine,
                      waypoint_radius_m=waypoint_radius_m, source=str(log_path))
    res.report["input"] = str(log_path)
    res.report["plan"] = str(plan_path)
    write_csv(res.data, out)
    try:
        write_json(res.report, out_json)
    except BaseException:
        out.unlink(missing_ok=True)
        raise
    if plot_dir is not None:
        from .plot.track import plot_track

        res.report["plots"] = [str(p) for p in plot_track(res, plan, plot_dir,
                                                          threshold_m=threshold_m)]
    return res
