"""The one figure style of :mod:`aeromag.plot`: figures, saving, time axes, display decimation.

Every plot function has the form ``fig = plot_xxx(..., ax=None, path=None)``: it draws into
``ax`` when given (and returns its figure), otherwise into a new :class:`QCFigure` on the Agg
canvas (no pyplot state, no window, never ``matplotlib.use``), and saves a PNG atomically when
``path`` is given.  A :class:`QCFigure` displays itself in Jupyter (``_repr_png_``), with or
without ``%matplotlib inline``.

Long lines are drawn as their min/max envelope per pixel column (:func:`envelope`); the
report's figures compute it block by block of rows (:class:`_EnvelopeStream`, the same points)
so that no full-length abscissa, label or key array exists.  Time axes are UTC for epoch
seconds, else seconds since the start of the log (:func:`time_axis`).
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
from ..compensation.report_types import CompensationReport
from ..conventions import EPOCH_DISPLAY_S
from ..errors import InputError

__all__ = ["DISPLAY_COLUMNS", "DPI", "QCFigure", "envelope", "figure_png", "new_figure",
           "plain_log_ticks", "save_figure", "time_axis"]

log = logging.getLogger(__name__)

#: Resolution of saved PNGs [dots per inch].
DPI = 150
PathLike = str | os.PathLike[str]

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


def target(ax: Axes | None, figsize: tuple[float, float]) -> tuple[Figure, Axes]:
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


def save_figure(fig: Figure, path: PathLike, dpi: int = DPI) -> Path:
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


def finish(fig: Figure, path: PathLike | None) -> Figure:
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
    ax = TimeAxis(t)
    return ax(t), ax.label, ax.is_date


class TimeAxis:
    """The abscissa of :func:`time_axis` as a function of a block of times (no full copy).

    ``TimeAxis(t)(t[a:b])`` is ``time_axis(t)[0][a:b]``, value for value.
    """

    def __init__(self, t: np.ndarray) -> None:
        fin = np.isfinite(t)
        i = int(np.argmax(fin)) if len(t) else 0
        has = bool(len(t)) and bool(fin[i])
        del fin
        self.t0 = float(t[i]) if has else 0.0  # the first finite time [s]
        self.is_date = has and EPOCH_DISPLAY_S[0] <= self.t0 < EPOCH_DISPLAY_S[1]
        if self.is_date:
            start = _dt.datetime.fromtimestamp(self.t0, _dt.UTC).strftime("%Y-%m-%d")
            self.label = f"time (UTC, {start})"
        else:
            self.label = "time since start of log (s)"

    def __call__(self, t: np.ndarray) -> np.ndarray:
        """Axis values [days since 1970 UTC, or s since the first sample] of times ``t`` [s]."""
        return t / 86400.0 if self.is_date else t - self.t0


def median_step(time_s: np.ndarray) -> float:
    """``np.median(np.diff(t))`` [s] (the same value) without the copy ``np.median`` makes.

    The step :func:`aeromag._core.filters.sampling_rate` and :func:`find_stretches`'s default
    gap are derived from; 16 MB transient at 2e6 rows instead of 32.  NaN when ``t`` has
    fewer than 2 samples.
    """
    t = np.asarray(time_s, dtype=np.float64)
    if len(t) < 2:
        return float("nan")
    return float(np.median(np.diff(t), overwrite_input=True))


def stretch_gap_s(time_s: np.ndarray) -> float:
    """The largest step inside a stretch that :func:`find_stretches` uses by default [s]."""
    med = median_step(time_s) if len(time_s) >= 2 else 1.0
    return 5.0 * med


def new_stretch(t: np.ndarray, a: int, b: int, gap_s: float) -> np.ndarray:
    """Where ``find_stretches(t)`` (no validity mask, gap ``gap_s``) starts a stretch in [a, b).

    True at the first sample of the log and after every step that is not ``<= gap_s``
    (NaN times included), exactly as :func:`find_stretches` decides it.
    """
    d = np.diff(t[max(a - 1, 0):b])
    new = np.empty(b - a, dtype=bool)
    if a == 0:
        new[0] = True
        np.less_equal(d, gap_s, out=new[1:])
        np.logical_not(new[1:], out=new[1:])
    else:
        np.less_equal(d, gap_s, out=new)
        np.logical_not(new, out=new)
    return new


def format_time(ax: Axes, is_date: bool, label: str) -> None:
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


#: Rows per block of :class:`_EnvelopeStream` (a few MB of temporaries per line).
ENVELOPE_BLOCK = 1 << 17


class _EnvelopeStream:
    """``envelope(x, y, breaks=_valid_runs(y, st))`` of a long line, given block by block.

    The figure's lines used to be enveloped whole: the abscissa, the stretch labels, the run
    labels and the column keys were each a full-length array (16 MB apiece at 2e6 rows).
    Here consecutive blocks of rows are added in order (:meth:`add`) and only the runs of one
    pixel column and one stretch are kept (a run cut by a block end is joined to its rest), so
    :meth:`result` returns the very points :func:`envelope` returns for a line of more than
    ``4 * columns`` samples, value for value (same columns, same runs, same extremes).

    Parameters
    ----------
    lo, hi : float
        Least and greatest abscissa of the drawable samples (finite ``x`` and ``y``) of the
        whole line: the pixel columns are ``(hi - lo) / columns`` wide.  Samples outside are
        clipped to the first or last column, as by :func:`envelope`; :attr:`seen` gives the
        bounds actually met, so a caller that guessed them can check.
    columns : int
        Pixel columns across the x range.

    Notes
    -----
    The stretches are given as a flag per sample, True where ``find_stretches(t)`` (no
    validity mask: every sample is in a stretch) starts a new one; see :func:`new_stretch`.
    """

    def __init__(self, lo: float, hi: float, columns: int = DISPLAY_COLUMNS) -> None:
        self.lo, self.columns = float(lo), int(columns)
        self.width = (hi - lo) / columns if hi > lo else 1.0
        self._parts: list[tuple[np.ndarray, ...]] = []  # (x0, x1, ymin, ymax, seg) per block
        self._last: tuple[int, int, int] | None = None  # (stop, seg, col) of the last run
        self._prev_good = False  # the previous block's last sample was finite
        self._count = 0  # run labels issued so far (the cumsum of _valid_runs)
        self.seen = (np.inf, -np.inf)

    def add(self, x: np.ndarray, y: np.ndarray, new: np.ndarray, offset: int) -> None:
        """Add the rows ``[offset, offset + len(x))``: abscissae, ordinates, stretch starts."""
        m = len(x)
        if m == 0:
            return
        good = np.isfinite(y)
        # _valid_runs: a new run after every missing sample and at every new stretch.
        start = good.copy()
        start[1:] &= ~good[:-1]
        start[0] &= not self._prev_good
        start |= new
        runs = np.cumsum(start, dtype=np.int64)
        del start
        runs += self._count
        self._count = int(runs[-1])
        self._prev_good = bool(good[-1])
        good &= np.isfinite(x)
        if not good.any():
            return
        xg = x[good]
        self.seen = (min(self.seen[0], float(np.min(xg))), max(self.seen[1], float(np.max(xg))))
        del xg
        c = x - self.lo
        c /= self.width
        col = c.astype(np.int64)
        del c
        np.clip(col, 0, self.columns - 1, out=col)
        key = runs - runs[0]
        key *= self.columns
        key += col
        key[~good] = -1
        a, b, _ = run_bounds(key)
        del key
        ymin = np.minimum.reduceat(np.where(good, y, np.inf), a)
        ymax = np.maximum.reduceat(np.where(good, y, -np.inf), a)
        x0, x1, seg, cola = x[a], x[b - 1], runs[a], col[a]
        if self._last is not None and self._last == (offset + int(a[0]), int(seg[0]),
                                                     int(cola[0])):
            p = self._parts[-1]  # the run goes on from the previous block: join it
            p[1][-1] = x1[0]
            p[2][-1] = min(p[2][-1], ymin[0])
            p[3][-1] = max(p[3][-1], ymax[0])
            x0, x1, ymin, ymax, seg = x0[1:], x1[1:], ymin[1:], ymax[1:], seg[1:]
        self._last = (offset + int(b[-1]), int(runs[b[-1] - 1]), int(col[b[-1] - 1]))
        if len(x0):
            self._parts.append((x0.copy(), x1.copy(), ymin, ymax, seg.copy()))

    def result(self) -> tuple[np.ndarray, np.ndarray]:
        """The points to draw (NaN between stretches), as :func:`envelope` returns them."""
        if not self._parts:
            return np.zeros(0), np.zeros(0)
        x0, x1, ymin, ymax, seg = (np.concatenate(v) for v in zip(*self._parts, strict=True))
        px = np.column_stack([x0, x1]).ravel()
        py = np.column_stack([ymin, ymax]).ravel()
        brk = _subpixel_breaks_merged(x0, x1, seg, self.width)
        return np.insert(px, brk, np.nan), np.insert(py, brk, np.nan)


def _drawable_bounds(lines: list[tuple[float, float]], x: np.ndarray,
                     ys: list[np.ndarray]) -> None:
    """Widen each line's ``(lo, hi)`` in place by the block's finite ``(x, y)`` samples."""
    fx = np.isfinite(x)
    for i, y in enumerate(ys):
        g = np.isfinite(y)
        g &= fx
        if g.any():
            xg = x[g]
            lo, hi = lines[i]
            lines[i] = (min(lo, float(np.min(xg))), max(hi, float(np.max(xg))))


def streamed_envelopes(
    n: int, blocks: Any, n_lines: int, bounds: list[tuple[float, float]] | None = None,
    columns: int = DISPLAY_COLUMNS,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """The envelopes of ``n_lines`` lines of ``n`` samples that are produced block by block.

    Equal, point for point, to ``envelope(x, y, breaks=_valid_runs(y, find_stretches(t)))``
    for each line: what :func:`_line` draws.

    Parameters
    ----------
    n : int
        Samples per line.
    blocks : callable
        ``blocks()`` yields ``(offset, x, new, ys)`` for consecutive blocks of rows covering
        ``[0, n)`` in order: abscissae, stretch starts (:func:`new_stretch`) and the list
        of the lines' ordinates.  Called once or twice (or three times, see ``bounds``).
    n_lines : int
        Number of lines.
    bounds : list of (float, float), optional
        A guess of each line's drawable x range (when its ordinates are costly to make: one
        pass); checked against the range met and, where it was wrong, the lines are made
        again.  Default: one cheap pass finds them first.
    columns : int
        Pixel columns.

    Returns
    -------
    list of (x, y)
        The points to draw for each line.
    """
    if n <= 4 * columns:  # a short line is drawn as it is: the whole-array path
        parts = list(blocks())
        x = np.concatenate([p[1] for p in parts])
        st = np.cumsum(np.concatenate([p[2] for p in parts])) - 1
        return [envelope(x, y, columns, breaks=_valid_runs(y, st))
                for y in (np.concatenate([p[3][i] for p in parts]) for i in range(n_lines))]
    if bounds is None:
        bounds = [(np.inf, -np.inf)] * n_lines
        for _, x, _, ys in blocks():
            _drawable_bounds(bounds, x, ys)
    for _ in range(2):
        streams = [_EnvelopeStream(lo, hi, columns) for lo, hi in bounds]
        for off, x, new, ys in blocks():
            for s, y in zip(streams, ys, strict=True):
                s.add(x, y, new, off)
        seen = [s.seen for s in streams]
        if all(g == b or g[0] > g[1] for g, b in zip(seen, bounds, strict=True)):
            break
        log.debug("envelope bounds guessed %s, met %s: drawn again", bounds, seen)
        bounds = seen
    return [s.result() for s in streams]


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


def _report(obj: Any) -> CompensationReport:
    """The report of a :class:`~aeromag.compensation.result.CompensationResult`, or ``obj``.

    A dict (a report or model file as read from JSON) is read with
    :meth:`CompensationReport.from_dict`; anything else gives an empty report.
    """
    rep = getattr(obj, "report", obj)
    if isinstance(rep, CompensationReport):
        return rep
    return CompensationReport.from_dict(rep if isinstance(rep, dict) else {})


def _data(obj: Any) -> pd.DataFrame:
    """The compensated log of a result, or ``obj`` itself (a DataFrame)."""
    if isinstance(obj, pd.DataFrame):
        return obj
    data = getattr(obj, "data", None)
    if data is None:
        raise InputError("this result holds no compensated data (use am.compensate())")
    return data
