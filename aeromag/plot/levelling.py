"""Levelling QC figures: mistie histograms before and after, stacked line profiles.

Same style as every :mod:`aeromag.plot` figure: ``fig = plot_xxx(..., ax=None, path=None)``
draws on the Agg canvas (or into ``ax``), saves a PNG atomically with ``path``, and shows
itself inline in Jupyter.
"""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from ..errors import InputError
from ..survey.chain import LevelResult
from ..survey.levelling import robust_std
from ._style import PathLike, finish, target

__all__ = ["plot_mistie_histogram", "plot_stacked_profiles"]

def plot_mistie_histogram(result: LevelResult, *, bins: int = 60, ax: Axes | None = None,
                          path: PathLike | None = None) -> Figure:
    """Histogram of the crossings' misties before and after tie-line levelling.

    Parameters
    ----------
    result : LevelResult
        A levelled survey with crossings.
    bins : int
        Histogram bins.
    ax : Axes, optional
        Where to draw.
    path : path-like, optional
        Save the figure there (PNG).

    Returns
    -------
    Figure
    """
    cx = result.crossings
    if cx is None or cx.n == 0:
        raise InputError("the levelled survey has no crossings to plot")
    before = cx.mistie_nT
    after = result.levelling.mistie_lev_nT if result.levelling is not None else before
    fig, ax = target(ax, (6.5, 4.0))
    lim = np.nanpercentile(np.abs(before), 99) or 1.0
    edges = np.linspace(-lim, lim, bins + 1)
    for v, name, c in ((before, "before", "0.6"), (after, "after", "C0")):
        ax.hist(np.clip(v, -lim, lim), bins=edges, color=c, alpha=0.8,
                label=f"{name}: std {np.std(v):.2f} nT, robust {robust_std(v):.2f} nT")
    ax.set_xlabel("mistie, line minus tie (nT)")
    ax.set_ylabel("crossings")
    ax.set_title(f"Misties at {cx.n} crossings")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return finish(fig, path)


def plot_stacked_profiles(result: LevelResult, *, column: str = "tmi_lev", n_lines: int = 12,
                          offset_nT: float | None = None, ax: Axes | None = None,
                          path: PathLike | None = None) -> Figure:
    """Profiles of adjacent lines stacked with an offset (levelled vs unlevelled).

    Parameters
    ----------
    result : LevelResult
        A levelled survey.
    column : str
        Column drawn (``tmi_lev``, ``tmi_mlev`` or ``tmi``); ``tmi`` is drawn grey beneath.
    n_lines : int
        Lines shown (the middle ones of the survey).
    offset_nT : float, optional
        Vertical offset between lines (default: the robust std of the column).
    ax : Axes, optional
        Where to draw.
    path : path-like, optional
        Save the figure there (PNG).

    Returns
    -------
    Figure
    """
    g = result.geometry
    d = result.data
    if column not in d.columns:
        raise InputError(f"no column {column} in the levelled survey")
    lines = np.flatnonzero(~g.piece_is_tie)
    if lines.size == 0:
        raise InputError("the survey has no flight lines to plot")
    th = np.deg2rad(g.lines_direction_deg)
    u = g.x_m * np.sin(th) + g.y_m * np.cos(th)
    u = u - np.nanmin(u[g.piece >= 0])  # from the survey's edge, not the projection's origin
    v = g.x_m * np.cos(th) - g.y_m * np.sin(th)
    across = np.array([np.nanmean(v[g.piece == k]) for k in lines])
    lo = np.array([np.nanmin(u[g.piece == k]) for k in lines])
    hi = np.array([np.nanmax(u[g.piece == k]) for k in lines])
    # adjacent lines of one block: the pieces overlapping (over half the shorter) the piece
    # at the middle across the survey, then the n_lines nearest it across (a survey of two
    # blocks side by side along the lines must not stack lines of both)
    centre = int(np.argsort(across)[lines.size // 2])
    overlap = np.minimum(hi, hi[centre]) - np.maximum(lo, lo[centre])
    same = overlap > 0.5 * np.minimum(hi - lo, hi[centre] - lo[centre])
    near = np.flatnonzero(same)[np.argsort(np.abs(across[same] - across[centre]))][:n_lines]
    show = lines[near[np.argsort(across[near])]]
    y = d[column].to_numpy(float)
    raw = d["tmi"].to_numpy(float)
    off = offset_nT or max(3.0 * robust_std(y), 1.0)
    fig, ax = target(ax, (7.0, 6.0))
    for i, k in enumerate(show):
        sel = (g.piece == k) & g.straight
        o = np.argsort(u[sel])
        ref = np.nanmedian(y[sel])
        ax.plot(u[sel][o] / 1000.0, raw[sel][o] - ref + i * off, color="0.7", lw=0.8)
        ax.plot(u[sel][o] / 1000.0, y[sel][o] - ref + i * off, color="C0", lw=0.9)
        ax.text(u[sel][o][-1] / 1000.0, i * off, f" {g.piece_line[k]:g}", fontsize=7,
                va="center")
    ax.set_xlabel("distance along the lines (km)")
    ax.set_ylabel(f"{column} (nT), offset {off:.1f} nT per line")
    ax.set_title(f"Stacked profiles: {column} (blue) over tmi (grey)")
    ax.grid(alpha=0.3)
    return finish(fig, path)
