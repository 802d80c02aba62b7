"""Track-check figures: the planned and flown track with the alarms, and the time series.

The time series are the deviation and the heading difference.  Same style as
:mod:`aeromag.plot.compensation` (:mod:`aeromag.plot._style`): each function draws into ``ax``
when given, otherwise into a new figure on the Agg canvas that displays itself in
Jupyter, and saves a PNG atomically when ``path`` is given.  No pyplot, no backend switch.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from .._core.geodesy import geodetic_to_ned
from ._style import _line, finish, format_time, new_figure, save_figure, target, time_axis

if TYPE_CHECKING:  # pragma: no cover
    from ..track import TrackResult

__all__ = ["plot_track", "plot_track_map", "plot_track_timeseries"]

log = logging.getLogger(__name__)
_PathLike = str | os.PathLike[str]

#: Most points of the flown track drawn on the map (longer logs are thinned for display).
MAP_POINTS = 20000


def _plan_of(result: TrackResult, plan: pd.DataFrame | None) -> pd.DataFrame:
    p = plan if plan is not None else result.plan
    if p is None:
        raise ValueError("plot_track_map needs the plan (pass plan=...)")
    return p


def plot_track_map(result: TrackResult, plan: pd.DataFrame | None = None, *,
                   ax: Axes | None = None, path: _PathLike | None = None) -> Figure:
    """Planned lines and flown track (east against north, m), alarms in red.

    Parameters
    ----------
    result : TrackResult
        Output of :func:`aeromag.track.check_track`.
    plan : DataFrame, optional
        The plan (``lat``, ``lon`` [deg], ``alt`` [m]); default the one the result was checked
        against.
    ax : Axes, optional
        Draw here instead of a new figure.
    path : path-like, optional
        Save the figure as PNG.

    Returns
    -------
    Figure
    """
    p = _plan_of(result, plan)
    fig, ax = target(ax, (7.0, 7.0))
    d = result.data
    origin = tuple(float(p[c].iloc[0]) for c in ("lat", "lon", "alt"))
    wps = geodetic_to_ned(p["lat"], p["lon"], p["alt"], origin)
    pos = np.full((len(d), 3), np.nan)
    ll = d[["lat", "lon", "alt"]].apply(pd.to_numeric, errors="coerce")
    ok = ll.notna().all(axis=1).to_numpy()
    if ok.any():
        pos[ok] = geodetic_to_ned(ll["lat"][ok], ll["lon"][ok], ll["alt"][ok], origin)
    step = max(1, len(d) // MAP_POINTS)
    alarm = d["alarm"].to_numpy(dtype=bool)
    on = d["leg"].notna().to_numpy()
    ax.plot(pos[::step, 1], pos[::step, 0], "-", color="0.7", lw=0.7, label="flown (no leg)")
    ax.plot(np.where(on, pos[:, 1], np.nan)[::step], np.where(on, pos[:, 0], np.nan)[::step],
            "C0-", lw=0.9, label="flown on a leg")
    ax.plot(wps[:, 1], wps[:, 0], "k--", lw=1, label="plan")
    ax.plot(wps[:, 1], wps[:, 0], "ko", ms=3)
    for k in range(len(wps) - 1):
        mid = 0.5 * (wps[k] + wps[k + 1])
        ax.annotate(str(k), (mid[1], mid[0]), fontsize=7, color="k")
    if alarm.any():
        ax.plot(np.where(alarm, pos[:, 1], np.nan), np.where(alarm, pos[:, 0], np.nan), "r-",
                lw=2.5, label="alarm")
    ax.set_xlabel("east of the first waypoint (m)")
    ax.set_ylabel("north of the first waypoint (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(loc="best", fontsize=8)
    flagged = result.report.flagged_legs
    checked = result.report.n_legs_checked
    if checked == 0:   # no row on a leg: "none flagged" would read as a clean flight
        ax.set_title("Planned vs flown track: no leg checked (no sample on any leg)")
    else:
        ax.set_title(f"Planned vs flown track: legs flagged {flagged if flagged else 'none'}")
    return finish(fig, path)


def plot_track_timeseries(result: TrackResult, *, threshold_m: float | None = None,
                          ax: Axes | None = None, path: _PathLike | None = None) -> Figure:
    """Cross-track deviation [m] with the threshold, and the heading difference [deg].

    The heading difference is drawn when the heading detector ran; alarms are marked.

    Parameters
    ----------
    result : TrackResult
        Output of :func:`aeromag.track.check_track`.
    threshold_m : float, optional
        Threshold drawn, m (default the result's).
    ax : Axes, optional
        Draw the deviation here (the heading difference is then left out).
    path : path-like, optional
        Save the figure as PNG.

    Returns
    -------
    Figure
    """
    d = result.data
    thr = float(result.report.threshold_m if threshold_m is None else threshold_m)
    x, label, is_date = time_axis(d["time"].to_numpy(dtype=np.float64))
    has_hd = "heading_diff_deg" in d.columns and ax is None
    if ax is None:
        fig, ax0 = new_figure((10.0, 6.0 if has_hd else 3.5))
        if has_hd:
            fig.clear()
            ax0, ax1 = fig.subplots(2, 1, sharex=True)
    else:
        fig, ax0 = target(ax, (10.0, 3.5))
    xt = d["xtrack_m"].to_numpy(dtype=np.float64)
    legs = d["leg"].fillna(-1).to_numpy(dtype=np.int64)
    _line(ax0, x, xt, legs, color="C0", lw=0.8, label="xtrack_m")
    ax0.axhline(thr, color="r", ls="--", lw=1, label=f"threshold {thr:g} m")
    ta = d["track_alarm"].to_numpy(dtype=bool)
    if ta.any():
        ax0.plot(x[ta], xt[ta], "r.", ms=2, label="track alarm")
    ax0.set_ylabel("cross-track (m)")
    ax0.legend(loc="upper right", fontsize=8)
    if has_hd:
        hd = d["heading_diff_deg"].to_numpy(dtype=np.float64)
        _line(ax1, x, hd, None, color="C1", lw=0.6, label="heading_diff_deg")
        ha = d["heading_alarm"].to_numpy(dtype=bool)
        if ha.any():
            ax1.plot(x[ha], hd[ha], "r.", ms=2, label="heading alarm")
        ax1.set_ylabel("heading diff (deg)")
        ax1.legend(loc="upper right", fontsize=8)
        format_time(ax1, is_date, label)
    else:
        format_time(ax0, is_date, label)
    return finish(fig, path)


def plot_track(result: TrackResult, plan: pd.DataFrame | None, out_dir: _PathLike, *,
               threshold_m: float = 1.0) -> list[Path]:
    """Write ``track_map.png`` and ``track_timeseries.png`` of a checked log.

    Parameters
    ----------
    result : TrackResult
        Output of :func:`aeromag.track.check_track`.
    plan : DataFrame or None
        The plan (default the result's).
    out_dir : path-like
        Output folder (created when missing).
    threshold_m : float
        Track threshold drawn on the deviation plot, m.

    Returns
    -------
    list of Path
        The written files.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = [save_figure(plot_track_map(result, plan), out / "track_map.png", dpi=110),
             save_figure(plot_track_timeseries(result, threshold_m=threshold_m),
                         out / "track_timeseries.png", dpi=110)]
    log.info("wrote %s", ", ".join(map(str, paths)))
    return paths
