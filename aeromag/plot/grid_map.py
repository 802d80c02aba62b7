"""The anomaly map of a grid: colour with shaded relief, the flight lines, a colour bar in nT.

Same style as the other plots (:mod:`aeromag.plot._style`: ``ax=``, ``path=``, Agg only when
drawing a new figure; a new figure shows itself in Jupyter).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.cm import ScalarMappable
from matplotlib.colors import LightSource, Normalize
from matplotlib.figure import Figure

from ..errors import InputError
from ._style import PathLike, figure_png, finish, target

__all__ = ["figure_png", "plot_grid_map"]


def _grid_array(grid: Any) -> Any:
    """The DataArray of a GridResult, a Dataset (its first variable) or a DataArray."""
    ds = getattr(grid, "dataset", grid)
    if hasattr(ds, "data_vars"):
        names = list(ds.data_vars)
        if not names:
            raise InputError("the grid has no data variable to map")
        return ds[names[0]]
    return ds


def plot_grid_map(
    grid: Any, *, lines: tuple[np.ndarray, np.ndarray] | None = None,
    line_id: np.ndarray | None = None, ax: Axes | None = None, path: PathLike | None = None,
    cmap: str = "RdYlBu_r", azimuth_deg: float = 315.0, elevation_deg: float = 45.0,
    max_line_points: int = 200_000, title: str | None = None,
) -> Figure:
    """Map a grid in colour with shaded relief, the flight lines on top and a colour bar.

    Parameters
    ----------
    grid : GridResult, xarray.Dataset or xarray.DataArray
        The grid (dims ``y``, ``x`` in metres), NaN where blank.
    lines : (ndarray, ndarray), optional
        Sample positions (x, y) [m] of the flight lines, drawn as thin black lines.
    line_id : ndarray, optional
        Line number of each sample (breaks the drawn line between lines).
    ax : Axes, optional
        Where to draw.
    path : path-like, optional
        Save the figure there (PNG).
    cmap : str
        Colour map.
    azimuth_deg, elevation_deg : float
        Direction of the light (from north, clockwise) and its height [deg].
    max_line_points : int
        Most flight-line samples drawn (every n-th beyond).
    title : str, optional
        Axes title (default: the variable's name and units).

    Returns
    -------
    Figure
    """
    da = _grid_array(grid)
    z = np.asarray(da.values, dtype=float)
    x, y = np.asarray(da["x"].values, float), np.asarray(da["y"].values, float)
    blank = ~np.isfinite(z)
    if blank.all():
        raise InputError("the grid is blank everywhere: nothing to map")
    units = str(da.attrs.get("units", "nT"))
    lo, hi = np.nanpercentile(z, [2, 98])
    norm = Normalize(vmin=lo, vmax=hi if hi > lo else lo + 1.0)
    filled = np.where(blank, np.nanmedian(z), z)
    h = float(x[1] - x[0]) if x.size > 1 else 1.0
    gy, gx = np.gradient(filled, h)
    slope = np.hypot(gx, gy)[~blank]
    exag = 1.0 / max(float(np.percentile(slope, 90)), 1e-12) if slope.size else 1.0
    ls = LightSource(azdeg=azimuth_deg, altdeg=elevation_deg)
    import matplotlib as mpl

    # rows as stored (y ascending): drawn with origin="lower"
    rgb = ls.shade(filled, cmap=mpl.colormaps[cmap], norm=norm, blend_mode="soft",
                   vert_exag=exag, dx=h, dy=h)
    rgb[..., 3] = np.where(blank, 0.0, 1.0)
    fig, ax = target(ax, (7.0, 7.0))
    ext = (x[0] - h / 2, x[-1] + h / 2, y[0] - h / 2, y[-1] + h / 2)
    ax.imshow(rgb, origin="lower", extent=ext, interpolation="nearest")
    if lines is not None:
        lx, ly = (np.asarray(a, float) for a in lines)
        step = max(1, -(-lx.size // max_line_points))
        lx, ly = lx[::step].copy(), ly[::step].copy()
        if line_id is not None:
            lid = np.asarray(line_id)[::step]
            brk = np.flatnonzero(np.diff(lid) != 0) + 1
            lx, ly = np.insert(lx, brk, np.nan), np.insert(ly, brk, np.nan)
        ax.plot(lx, ly, color="k", lw=0.2, alpha=0.5, label="flight lines")
    sm = ScalarMappable(norm=norm, cmap=cmap)
    cb = fig.colorbar(sm, ax=ax, label=f"{da.name} ({units})", shrink=0.8)
    cb.formatter.set_useOffset(False)
    cb.update_ticks()
    ax.set_xlim(ext[0], ext[1])
    ax.set_ylim(ext[2], ext[3])
    ax.set_aspect("equal")
    ax.ticklabel_format(useOffset=False, style="plain")
    crs = da.attrs.get("crs")
    where = f" (EPSG:{crs})" if crs is not None else ""
    ax.set_xlabel(f"easting (m){where}")
    ax.set_ylabel("northing (m)")
    ax.set_title(title or f"{da.name}: shaded relief, light from {azimuth_deg:g} deg")
    return finish(fig, path)
