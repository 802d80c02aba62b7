"""The flight map of a compensation: east/north in metres, coloured by the compensated field.

Same style as :mod:`aeromag.plot.compensation` (:mod:`aeromag.plot._style`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from ..errors import InputError
from ._style import PathLike, _data, finish, target

__all__ = ["plot_map"]


def plot_map(
    data: Any, *, column: str = "mag_comp", ax: Axes | None = None,
    path: PathLike | None = None, max_points: int = 20_000,
) -> Figure:
    """The flight in metres (east, north of its first fix), coloured by the compensated field.

    Positions go through the one geodesy module (:mod:`aeromag._core.geodesy`, exact WGS84);
    samples of segments the screening dropped are drawn as grey crosses and labelled with their
    line (or segment) number.

    Parameters
    ----------
    data : DataFrame or CompensationResult
        Log with ``lat``, ``lon`` [deg] (``alt`` [m] when present) and ``column`` [nT];
        ``segment``/``segment_kept`` (and ``line``) mark the dropped segments.
    column : str
        Column used for the colour (default ``mag_comp``).
    ax : Axes, optional
        Where to draw.
    path : path-like, optional
        Save the figure there (PNG).
    max_points : int
        Most points drawn (a regular subsample beyond).

    Returns
    -------
    Figure
    """
    from .._core.geodesy import geodetic_to_ned
    from ..qc.labels import kept_mask, segment_labels

    data = _data(data)
    if not {"lat", "lon", column} <= set(data.columns):
        raise InputError(f"the map needs columns lat, lon and {column}")
    # Columns as stored (the report holds positions in single precision): only the drawn
    # samples are converted to float64, not three full-length copies.
    lat_s, lon_s = data["lat"].to_numpy(), data["lon"].to_numpy()
    v_s = data[column].to_numpy()
    ok = np.isfinite(lat_s)
    ok &= np.isfinite(lon_s)
    ok &= np.isfinite(v_s)
    n_ok = int(np.count_nonzero(ok))
    if not n_ok:
        raise InputError("no sample with a position and a compensated field to map")
    step = max(1, -(-n_ok // max_points))
    idx = _every_nth(ok, step)  # np.flatnonzero(ok)[::step], without the full index array
    del ok
    lat, lon, v = (np.asarray(a[idx], dtype=np.float64) for a in (lat_s, lon_s, v_s))
    alt = np.asarray(data["alt"].to_numpy()[idx], dtype=np.float64) \
        if "alt" in data.columns else np.zeros(len(idx))
    alt = np.where(np.isfinite(alt), alt, 0.0)
    ned = geodetic_to_ned(lat, lon, alt, (float(lat[0]), float(lon[0]), float(alt[0])))
    north, east = ned[:, 0], ned[:, 1]
    # The drawn rows only: the segment labels and kept flags of every row are not needed
    # (a full-length int64 copy, 16 MB at 2e6 rows); both are decided row by row.
    drawn = data.iloc[idx]
    kept = kept_mask(drawn)
    fig, ax = target(ax, (6.5, 6.0))
    vk = v[kept]
    lo, hi = np.percentile(vk if vk.size else v, [2, 98])
    sc = ax.scatter(east[kept], north[kept], c=vk, s=4, cmap="viridis", vmin=lo, vmax=hi,
                    rasterized=True)
    cb = fig.colorbar(sc, ax=ax, label=f"{column} (nT)")
    cb.formatter.set_useOffset(False)  # the field itself, not "+4.9999e4"
    cb.update_ticks()
    if (~kept).any():
        ax.scatter(east[~kept], north[~kept], s=6, c="0.5", marker="x", lw=0.6,
                   label="dropped segments")
        seg = segment_labels(drawn)
        name = drawn["line"].to_numpy() if "line" in data.columns else seg
        for sid in np.unique(seg[~kept]):
            j = np.flatnonzero((seg == sid) & ~kept)
            mid = j[len(j) // 2]
            ax.annotate(f"line {_line_name(name[mid])}" if "line" in data.columns
                        else f"segment {sid}",
                        (east[mid], north[mid]), fontsize=8, color="C3",
                        textcoords="offset points", xytext=(4, 4))
        ax.legend(loc="upper right", fontsize=8)
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.ticklabel_format(useOffset=False, style="plain")
    ax.set_title(f"Flight coloured by {column} (origin: first fix)")
    ax.grid(alpha=0.3)
    return finish(fig, path)


def _every_nth(mask: np.ndarray, step: int, block: int = 1 << 18) -> np.ndarray:
    """``np.flatnonzero(mask)[::step]``, block by block (int64 indices).

    Parameters
    ----------
    mask : ndarray of bool, shape (n,)
    step : int
        Keep every ``step``-th True sample, from the first.

    Returns
    -------
    ndarray of int64
    """
    out, seen = [], 0
    for a in range(0, len(mask), block):
        f = np.flatnonzero(mask[a:a + block])
        out.append(f[(-seen) % step::step] + a)
        seen += len(f)
    return np.concatenate(out) if out else np.zeros(0, dtype=np.int64)


def _line_name(value: object) -> str:
    """A line id as a surveyor writes it: ``4`` for 4.0 (float columns), text as it is."""
    try:
        f = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return str(value)
    return f"{f:g}" if np.isfinite(f) else str(value)
