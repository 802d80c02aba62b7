"""The one figure style of :mod:`aeromag.plot`: figures, saving, time axes, display decimation.

Every plot function has the form ``fig = plot_xxx(..., ax=None, path=None)``: it draws into
``ax`` when given (and returns its figure), otherwise into a new :class:`QCFigure` on the Agg
canvas (no pyplot state, no window, never ``matplotlib.use``), and saves a PNG atomically when
``path`` is given.  A :class:`QCFigure` displays itself in Jupyter (``_repr_png_``), with or
without ``%matplotlib inline``.

Long lines are drawn as their min/max envelope per pixel column (:func:`envelope`); time axes
are UTC for epoch seconds, else seconds since the start of the log (:func:`time_axis`).
"""

from __future__ import annotations

import datetime as _dt
import io as _io
import logging
import os
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib import rc_context
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from .._core.runs import run_bounds
from ..conventions import EPOCH_DISPLAY_S
from ..errors import InputError

__all__ = ["DISPLAY_COLUMNS", "DPI", "QCFigure", "envelope", "figure_png", "new_figure",
           "plain_log_ticks", "save_figure", "time_axis"]

log = logging.getLogger(__name__)

#: Resolution of saved PNGs [dots per inch].
DPI = 150
_PathLike = str | os.PathLike[str]

#: Pixel columns a line is reduced to for display (min and max per column).
DISPLAY_COLUMNS = 2000

#: Vertices Agg rasterises at a time (``agg.path.chunksize``) when saving a PNG.  A min/max
#: envelope zigzags across the whole plot height in every column, and Agg keeps a cell per
#: pixel crossed until the path is drawn: 165 MB for the residual figure of a 2e6-row log in
#: one piece, 22 MB in pieces of 2000 (and 0.5 s less); at most a few tens of antialiased
#: pixels differ where the pieces join.
AGG_CHUNK = 2000


class QCFigure(Figure):
    """A matplotlib figure that displays itself in Jupyter (``_repr_png_``), on any backend."""

    def _repr_png_(self) -> bytes:
        return figure_png(self, dpi=100)


def plain_log_ticks(ax: Axes) -> None:
    r"""Label the log-scaled axes of ``ax`` in plain text ("0.01", "1e+03"), not mathtext.

    matplotlib labels a log axis ``$\\mathdefault{10^{-2}}$`` by default: every PSD figure
    then starts the mathtext parser, which looks up the Computer Modern and "DejaVu Sans
    Display" fonts and, where the font cache does not list them, logs a ``findfont``
    warning per font that reached the user of ``aeromag report`` at default verbosity.

    Parameters
    ----------
    ax : Axes
        Axes whose x and/or y scale is ``"log"``.
    """
    from matplotlib.ticker import LogFormatter

    for axis in (ax.xaxis, ax.yaxis):
        if axis.get_scale() == "log":
            axis.set_major_formatter(LogFormatter(base=10.0))
            axis.set_minor_formatter(LogFormatter(base=10.0, labelOnlyBase=False))


def new_figure(figsize: tuple[float, float] = (7.0, 4.5)) -> tuple[Figure, Axes]:
    """A new figure with one axes on an Agg canvas (no pyplot, no window).

    Parameters
    ----------
    figsize : (float, float)
        Size [inch].

    Returns
    -------
    fig : QCFigure
    ax : Axes
    """
    fig = QCFigure(figsize=figsize, layout="constrained")
    FigureCanvasAgg(fig)
    return fig, fig.add_subplot(1, 1, 1)


def _target(ax: Axes | None, figsize: tuple[float, float]) -> tuple[Figure, Axes]:
    if ax is None:
        return new_figure(figsize)
    return ax.figure, ax  # type: ignore[return-value]


def figure_png(fig: Figure, dpi: int = DPI) -> bytes:
    """A figure as PNG bytes.

    Parameters
    ----------
    fig : Figure
        The figure.
    dpi : int
        Resolution [dots per inch].

    Returns
    -------
    bytes
    """
    if fig.canvas is None or not isinstance(fig.canvas, FigureCanvasAgg):
        FigureCanvasAgg(fig)
    buf = _io.BytesIO()
    with rc_context({"agg.path.chunksize": AGG_CHUNK}):
        fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def save_figure(fig: Figure, path: _PathLike, dpi: int = DPI) -> Path:
    """Write a figure as PNG atomically (a partial file never appears).

    Parameters
    ----------
    fig : Figure
        The figure.
    path : path-like
        Output file.
    dpi : int
        Resolution [dots per inch].

    Returns
    -------
    Path
    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    data = figure_png(fig, dpi)
    tmp = p.with_name(f".{p.name}.{os.getpid()}.tmp")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, p)
    finally:
        tmp.unlink(missing_ok=True)
    log.info("wrote %s", p)
    return p


def _finish(fig: Figure, path: _PathLike | None) -> Figure:
    if path is not None:
        save_figure(fig, path)
    return fig


# --------------------------------------------------------------------------- display helpers
def time_axis(time_s: np.ndarray) -> tuple[np.ndarray, str, bool]:
    """Times for an axis: UTC dates for epoch seconds, else seconds since the start.

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Times [s]; values from 2001-09-09 (1e9 s) on are taken as UNIX epoch seconds (UTC).

    Returns
    -------
    x : ndarray of float
        matplotlib date numbers (days since 1970-01-01 UTC) or seconds since the first sample.
    label : str
        Axis label.
    is_date : bool
    """
    t = np.asarray(time_s, dtype=np.float64)
    fin = t[np.isfinite(t)]
    t0 = float(fin[0]) if fin.size else 0.0
    if fin.size and EPOCH_DISPLAY_S[0] <= t0 < EPOCH_DISPLAY_S[1]:
        start = _dt.datetime.fromtimestamp(t0, _dt.UTC).strftime("%Y-%m-%d")
        return t / 86400.0, f"time (UTC, {start})", True
    return t - t0, "time since start of log (s)", False


def _format_time(ax: Axes, is_date: bool, label: str) -> None:
    ax.set_xlabel(label)
    if is_date:
        import matplotlib.dates as mdates

        ax.xaxis_date(tz=_dt.UTC)
        loc = mdates.AutoDateLocator(tz=_dt.UTC)
        ax.xaxis.set_major_locator(loc)
        ax.xaxis.set_major_formatter(mdates.ConciseDateFormatter(loc, tz=_dt.UTC))
    else:
        ax.ticklabel_format(axis="x", useOffset=False, style="plain")


def envelope(x: np.ndarray, y: np.ndarray, columns: int = DISPLAY_COLUMNS,
             breaks: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Min/max envelope of a line for display: two points per pixel column and per stretch.

    Parameters
    ----------
    x : ndarray, shape (n,)
        Abscissae, increasing.
    y : ndarray, shape (n,)
        Ordinates; NaN breaks the line.
    columns : int
        Pixel columns across the x range; a line of at most ``4 * columns`` points is kept.
    breaks : ndarray of int, optional
        Stretch label per sample: the line is not drawn across a change of label (on a
        long line, except across a sub-pixel gap next to a sub-pixel stretch, see
        :func:`_subpixel_breaks_merged`).

    Returns
    -------
    x, y : ndarray
        The points to draw (NaN between stretches).
    """
    xf = np.asarray(x, dtype=np.float64)
    yv = np.asarray(y, dtype=np.float64)
    good = np.isfinite(yv)
    good &= np.isfinite(xf)
    all_good = bool(good.all())
    if breaks is None:
        lab = None
    else:
        lab = np.asarray(breaks)
        good &= lab >= 0
        all_good = all_good and bool(good.all())
    if not good.any():
        return np.zeros(0), np.zeros(0)
    if len(yv) > 4 * columns:
        # The column of every sample, computed in place (a few full-length passes, no more):
        # the key of a sample is its column and stretch; runs of one key are reduced to
        # their minimum and maximum.  Invalid samples get the key -1 (they belong to no run).
        xg = xf if all_good else xf[good]
        lo, hi = float(np.min(xg)), float(np.max(xg))
        del xg
        width = (hi - lo) / columns if hi > lo else 1.0
        c = xf - lo
        c /= width
        key = c.astype(np.int64)
        del c
        np.clip(key, 0, columns - 1, out=key)
        if lab is not None:
            lmin = int(lab[good].min()) if not all_good else int(lab.min())
            key += columns * (lab - lmin)
        if not all_good:
            key[~good] = -1
        a, b, _ = run_bounds(key)
        seg_of = (np.zeros(len(a), dtype=np.int64) if lab is None else lab[a])
        del key
        px = np.column_stack([xf[a], xf[b - 1]]).ravel()
        if all_good:  # runs tile the samples: no masking copy
            ymin, ymax = np.minimum.reduceat(yv, a), np.maximum.reduceat(yv, a)
        else:
            ymin = np.minimum.reduceat(np.where(good, yv, np.inf), a)
            ymax = np.maximum.reduceat(np.where(good, yv, -np.inf), a)
        py = np.column_stack([ymin, ymax]).ravel()
        brk = _subpixel_breaks_merged(xf[a], xf[b - 1], seg_of, width)
        return np.insert(px, brk, np.nan), np.insert(py, brk, np.nan)
    labv = np.zeros(len(yv), dtype=np.int64) if lab is None else lab
    px, py, seg = xf[good], yv[good], labv[good]
    brk = np.flatnonzero(seg[1:] != seg[:-1]) + 1
    return np.insert(px, brk, np.nan), np.insert(py, brk, np.nan)


def _subpixel_breaks_merged(x0: np.ndarray, x1: np.ndarray, seg: np.ndarray,
                            width: float) -> np.ndarray:
    """Where to break the envelope line (indices into its points, two per run).

    A change of stretch breaks the line, except where the gap before the next stretch is
    narrower than a pixel column and one of the two stretches is too: thousands of
    stretches shorter than a pixel (a calibration cut at every turn) would otherwise make a
    line of thousands of pieces, invisible at that scale and slow to draw.  A gap wider than
    a column, or between two stretches at least a column wide, always breaks the line.
    """
    change = np.flatnonzero(seg[1:] != seg[:-1])
    if not change.size:
        return change
    ids, inv = np.unique(seg, return_inverse=True)
    first = np.full(len(ids), np.inf)
    last = np.full(len(ids), -np.inf)
    np.minimum.at(first, inv, x0)
    np.maximum.at(last, inv, x1)
    narrow = (last - first) < width
    gap = x0[change + 1] - x1[change]
    keep = (gap >= width) | ~(narrow[inv[change]] | narrow[inv[change + 1]])
    return 2 * (change[keep] + 1)


def _line(ax: Axes, x: np.ndarray, y: np.ndarray, st: np.ndarray | None = None,
          **kw: Any) -> None:
    ex, ey = envelope(x, y, breaks=_valid_runs(y, st))
    ax.plot(ex, ey, **kw)


def _valid_runs(y: np.ndarray, st: np.ndarray | None) -> np.ndarray:
    """A label per sample that changes at every new stretch and after every missing sample.

    A masked series (the dropped segments' residual, NaN on the kept ones) must not be drawn
    as a straight line across the samples it leaves out; -1 (no line) outside stretches.
    """
    good = np.isfinite(np.asarray(y, dtype=np.float64))
    start = good & ~np.r_[False, good[:-1]]
    if st is not None:
        lab = np.asarray(st)
        start |= np.r_[True, lab[1:] != lab[:-1]]
    runs = np.cumsum(start)
    if st is not None:
        runs[np.asarray(st) < 0] = -1
    return runs


def _report(obj: Any) -> dict[str, Any]:
    """The report of a :class:`~aeromag.compensation.result.CompensationResult`, or ``obj``."""
    rep = getattr(obj, "report", obj)
    return rep if isinstance(rep, dict) else {}


def _data(obj: Any) -> pd.DataFrame:
    """The compensated log of a result, or ``obj`` itself (a DataFrame)."""
    if isinstance(obj, pd.DataFrame):
        return obj
    data = getattr(obj, "data", None)
    if data is None:
        raise InputError("this result holds no compensated data (use am.compensate())")
    return data
