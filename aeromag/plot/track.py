"""Track-check plots: planned vs flown track, deviation and heading-difference time series."""

from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from .._core.geodesy import geodetic_to_ned
from ..io import atomic_path

if TYPE_CHECKING:  # pragma: no cover
    from ..track import TrackResult

log = logging.getLogger(__name__)


def plot_track(result: TrackResult, plan: pd.DataFrame, out_dir: str | os.PathLike[str], *,
               threshold_m: float = 1.0) -> list[Path]:
    """Write the track plots (PNG, matplotlib Agg) of a checked log.

    ``track_map.png``: planned lines and flown track (east vs north, m, NED at the first
    waypoint) with alarmed stretches highlighted.  ``track_timeseries.png``: ``xtrack_m`` [m]
    with the threshold, and ``heading_diff_deg`` [deg] when available, with alarm markers.

    Parameters
    ----------
    result : TrackResult
        Output of :func:`aeromag.track.check_track`.
    plan : DataFrame
        The plan (``lat``, ``lon`` [deg], ``alt`` [m]).
    out_dir : path-like
        Output folder (created when missing).
    threshold_m : float
        Track threshold drawn on the deviation plot, m.

    Returns
    -------
    list of Path
        The written files.
    """
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    d = result.data
    lat0, lon0, alt0 = (float(plan[c].iloc[0]) for c in ("lat", "lon", "alt"))
    wps = geodetic_to_ned(plan["lat"], plan["lon"], plan["alt"], (lat0, lon0, alt0))
    pos = np.full((len(d), 3), np.nan)
    ok = d[["lat", "lon", "alt"]].notna().all(axis=1).to_numpy()
    if ok.any():
        pos[ok] = geodetic_to_ned(d["lat"][ok], d["lon"][ok], d["alt"][ok], (lat0, lon0, alt0))
    alarm = d["alarm"].to_numpy(dtype=bool)
    t = d["time"].to_numpy(dtype=np.float64)
    paths: list[Path] = []

    fig, ax = plt.subplots(figsize=(7, 7))
    ax.plot(wps[:, 1], wps[:, 0], "k--", lw=1, label="plan")
    ax.plot(wps[:, 1], wps[:, 0], "ko", ms=3)
    ax.plot(pos[:, 1], pos[:, 0], "C0-", lw=0.8, label="flown")
    if alarm.any():
        ax.plot(np.where(alarm, pos[:, 1], np.nan), np.where(alarm, pos[:, 0], np.nan), "r-",
                lw=2.5, label="alarm")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(loc="best")
    ax.set_title("Planned vs flown track")
    paths.append(_save(fig, out / "track_map.png"))
    plt.close(fig)

    has_hd = "heading_diff_deg" in d.columns
    fig, axes = plt.subplots(2 if has_hd else 1, 1, figsize=(10, 6 if has_hd else 3.5),
                             sharex=True, squeeze=False)
    ax = axes[0, 0]
    ax.plot(t, d["xtrack_m"], "C0-", lw=0.8, label="xtrack_m")
    ax.axhline(threshold_m, color="r", ls="--", lw=1, label=f"threshold {threshold_m:g} m")
    ta = d["track_alarm"].to_numpy(dtype=bool)
    if ta.any():
        ax.plot(t[ta], d["xtrack_m"].to_numpy()[ta], "r.", ms=2, label="track alarm")
    ax.set_ylabel("cross-track (m)")
    ax.legend(loc="upper right")
    if has_hd:
        ax = axes[1, 0]
        hd = d["heading_diff_deg"].to_numpy(dtype=np.float64)
        ax.plot(t, hd, "C1-", lw=0.6, label="heading_diff_deg")
        ha = d["heading_alarm"].to_numpy(dtype=bool)
        if ha.any():
            ax.plot(t[ha], hd[ha], "r.", ms=2, label="heading alarm")
        ax.set_ylabel("heading diff (deg)")
        ax.legend(loc="upper right")
    axes[-1, 0].set_xlabel("time (s)")
    paths.append(_save(fig, out / "track_timeseries.png"))
    plt.close(fig)
    log.info("wrote %s", ", ".join(map(str, paths)))
    return paths


def _save(fig, path: Path) -> Path:
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight")
    return path
