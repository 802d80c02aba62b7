"""Compensation diagnostics plots (matplotlib, headless: Agg canvas, never ``plt.show``).

One function per figure; each has the form ``fig = plot_xxx(..., ax=None, path=None)``: it
draws into ``ax`` when given (and returns its figure), otherwise into a new figure, and saves a
PNG atomically when ``path`` is given.  Figures are created with :class:`matplotlib.figure.Figure`
directly on the Agg canvas (no pyplot state, no global backend switch), so they work headless,
in threads, scripts and notebooks alike.

* :func:`plot_pca_scores` - PCA score plot (PC1 vs PC2) of the segment coefficient vectors,
  kept / dropped segments and the screening decision boundary;
* :func:`plot_explained_variance` - explained-variance bars with the cumulative curve;
* :func:`plot_timeseries` - uncompensated vs compensated total field;
* :func:`plot_psd` - power spectral density before / after;
* :func:`plot_term_contributions` - permanent / induced / eddy parts of ``mag_tl``;
* :func:`plot_fom` - FOM peak-to-peak bars per heading and manoeuvre, before / after;
* :func:`plot_map` - the flight path coloured by the compensated field.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Ellipse
from scipy import signal

from ..errors import InputError
from ..filters import run_bounds, sampling_rate
from ..io import atomic_path
from ..segments import find_stretches
from ..tolles_lawson import EDDY_9, INDUCED_6, PERMANENT, design_matrix

log = logging.getLogger(__name__)

#: Resolution of saved PNGs [dots per inch].
DPI = 150
_PathLike = str | os.PathLike[str]


def new_figure(figsize: tuple[float, float] = (7.0, 4.5)) -> tuple[Figure, Axes]:
    """A new figure with one axes on an Agg canvas (no pyplot, no window).

    Parameters
    ----------
    figsize : (float, float)
        Size [inch].

    Returns
    -------
    fig : Figure
    ax : Axes
    """
    fig = Figure(figsize=figsize, layout="constrained")
    FigureCanvasAgg(fig)
    return fig, fig.add_subplot(1, 1, 1)


def _target(ax: Axes | None, figsize: tuple[float, float]) -> tuple[Figure, Axes]:
    if ax is None:
        return new_figure(figsize)
    return ax.figure, ax  # type: ignore[return-value]


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
    if fig.canvas is None or not isinstance(fig.canvas, FigureCanvasAgg):
        FigureCanvasAgg(fig)
    with atomic_path(p) as tmp:
        fig.savefig(tmp, format="png", dpi=dpi)
    log.info("wrote %s", p)
    return p


def _finish(fig: Figure, path: _PathLike | None) -> Figure:
    if path is not None:
        save_figure(fig, path)
    return fig


def _segments_frame(report: dict[str, Any]) -> pd.DataFrame:
    segs = [s for s in report.get("segments", []) if s.get("scores") is not None]
    if not segs:
        raise InputError("the report has no PCA scores (screening was off or a saved model was"
                         " applied): no score plot")
    return pd.DataFrame(segs)


# --------------------------------------------------------------------------- PCA
def plot_pca_scores(
    report: dict[str, Any], *, ax: Axes | None = None, path: _PathLike | None = None,
    annotate: bool = True,
) -> Figure:
    """PCA score plot: each segment's scores on PC1 (x) and PC2 (y), kept vs dropped.

    The decision boundary is the projection on the PC1-PC2 plane of the screening ellipsoid
    ``(s - location)' covariance^-1 (s - location) = cutoff`` (robust location and covariance
    of the retained components, chi-square cut-off); with one retained component it is a pair
    of vertical lines.  Segments outside the boundary but kept (their residual was not
    materially worse, see :mod:`aeromag.screening`) are drawn hollow.

    Parameters
    ----------
    report : dict
        Compensation report with ``segments[*].scores``/``kept`` and ``screening``.
    ax : Axes, optional
        Where to draw.
    path : path-like, optional
        Save the figure there (PNG).
    annotate : bool
        Label dropped and outlying segments with their id.

    Returns
    -------
    Figure
    """
    seg = _segments_frame(report)
    scr = report.get("screening") or {}
    fig, ax = _target(ax, (6.0, 5.0))
    sc = np.array([np.r_[s, 0.0][:2] if len(s) < 2 else s[:2] for s in seg["scores"]],
                  dtype=float)
    kept = seg["kept"].to_numpy(dtype=bool)
    outl = seg["pca_outlier"].fillna(False).to_numpy(dtype=bool) if "pca_outlier" in seg \
        else ~kept
    ax.scatter(sc[kept & ~outl, 0], sc[kept & ~outl, 1], s=28, c="C0", label="kept",
               zorder=3)
    if (kept & outl).any():
        ax.scatter(sc[kept & outl, 0], sc[kept & outl, 1], s=36, facecolors="none",
                   edgecolors="C0", label="outside, kept (not material)", zorder=3)
    if (~kept).any():
        ax.scatter(sc[~kept, 0], sc[~kept, 1], s=46, c="C3", marker="X", label="dropped",
                   zorder=4)
    if annotate:
        for i in np.flatnonzero(~kept | outl):
            ax.annotate(str(seg["id"].iloc[i]), sc[i], textcoords="offset points",
                        xytext=(4, 4), fontsize=8)
    loc = np.asarray(scr.get("location") or [], dtype=float)
    cov = np.asarray(scr.get("covariance") or [], dtype=float)
    cut = scr.get("cutoff")
    if loc.size and cut is not None:
        if loc.size >= 2:
            c2 = cov[:2, :2]
            w, v = np.linalg.eigh(c2)
            ang = np.degrees(np.arctan2(v[1, 1], v[0, 1]))
            width, height = 2 * np.sqrt(cut * np.maximum(w[::-1], 0))
            ax.add_patch(Ellipse(loc[:2], width, height, angle=ang, fill=False, ls="--",
                                 color="k", lw=1.2, label="decision boundary"))
            ax.plot(*loc[:2], "k+", ms=10, label="robust centre")
        else:
            half = np.sqrt(cut * float(cov.ravel()[0]))
            for j, x in enumerate((loc[0] - half, loc[0] + half)):
                ax.axvline(x, color="k", ls="--", lw=1.2,
                           label="decision boundary" if j == 0 else None)
    evr = scr.get("explained_variance_ratio") or []
    lab = [f"PC{i + 1}" + (f" ({100 * evr[i]:.0f} %)" if i < len(evr) else "") for i in (0, 1)]
    ax.set_xlabel(lab[0])
    ax.set_ylabel(lab[1])
    nd = int((~kept).sum())
    ax.set_title(f"PCA score plot: {len(seg)} segments, {nd} dropped")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.autoscale_view()
    return _finish(fig, path)


def plot_explained_variance(
    report: dict[str, Any], *, ax: Axes | None = None, path: _PathLike | None = None,
) -> Figure:
    """Explained-variance ratio per principal component (bars) and cumulative (line).

    Parameters
    ----------
    report : dict
        Compensation report with ``screening.explained_variance_ratio``.
    ax : Axes, optional
        Where to draw.
    path : path-like, optional
        Save the figure there (PNG).

    Returns
    -------
    Figure
    """
    scr = report.get("screening") or {}
    evr = np.asarray(scr.get("explained_variance_ratio") or [], dtype=float)
    if evr.size == 0:
        raise InputError("the report has no explained-variance ratios (no PCA screening)")
    fig, ax = _target(ax, (6.0, 4.0))
    x = np.arange(1, evr.size + 1)
    ncomp = int(scr.get("n_components", 0))
    colors = ["C0" if i < ncomp else "0.7" for i in range(evr.size)]
    ax.bar(x, 100 * evr, color=colors, label="per component")
    ax.plot(x, 100 * np.cumsum(evr), "k.-", label="cumulative")
    thr = scr.get("pca_variance_threshold")
    if thr is not None:
        ax.axhline(100 * thr, color="C3", ls="--", lw=1, label=f"threshold {100 * thr:.0f} %")
    ax.set_xlabel("principal component")
    ax.set_ylabel("explained variance (%)")
    ax.set_xticks(x)
    ax.set_ylim(0, 105)
    ax.set_title(f"Explained variance ({ncomp} component(s) retained)")
    ax.legend(loc="center right", fontsize=8)
    ax.grid(axis="y", alpha=0.3)
    return _finish(fig, path)


# --------------------------------------------------------------------------- time series
def _field_before(data: pd.DataFrame) -> np.ndarray:
    if "mag" in data.columns:
        return data["mag"].to_numpy(dtype=np.float64)
    return np.linalg.norm(data[["flux_x", "flux_y", "flux_z"]].to_numpy(dtype=np.float64), axis=1)


def _with_gaps(t: np.ndarray, *ys: np.ndarray) -> tuple[np.ndarray, ...]:
    """Insert NaN at time gaps so lines are not drawn across them."""
    st = find_stretches(t)
    brk = np.flatnonzero(st[1:] != st[:-1]) + 1
    return tuple(np.insert(np.asarray(a, dtype=float), brk, np.nan) for a in (t, *ys))


def plot_timeseries(
    data: pd.DataFrame, *, ax: Axes | None = None, path: _PathLike | None = None,
) -> Figure:
    """Uncompensated (``mag``) and compensated (``mag_comp``) total field against time.

    Parameters
    ----------
    data : DataFrame
        Compensated log (``time`` [s], ``mag`` [nT] or the fluxgate, ``mag_comp`` [nT]).
    ax : Axes, optional
        Where to draw.
    path : path-like, optional
        Save the figure there (PNG).

    Returns
    -------
    Figure
    """
    fig, ax = _target(ax, (9.0, 4.0))
    t, b, a = _with_gaps(data["time"].to_numpy(dtype=np.float64), _field_before(data),
                         data["mag_comp"].to_numpy(dtype=np.float64))
    ax.plot(t, b, color="0.55", lw=0.8, label="uncompensated (mag)")
    ax.plot(t, a, color="C0", lw=0.9, label="compensated (mag_comp)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("total field (nT)")
    ax.set_title("Uncompensated vs compensated total field")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    return _finish(fig, path)


def _welch(x: np.ndarray, t: np.ndarray, nperseg: int) -> tuple[np.ndarray, np.ndarray]:
    """Welch PSD averaged over continuous stretches (weighted by their length)."""
    fs = sampling_rate(t)
    st = find_stretches(t, np.isfinite(x))
    starts, stops, _ = run_bounds(st)
    nps = min(nperseg, int(max(stops - starts)))
    acc = None
    wsum = 0.0
    for a, b in zip(starts, stops, strict=True):
        if b - a < nps:
            continue
        f, p = signal.welch(x[a:b], fs=fs, nperseg=nps, detrend="linear")
        acc = p * (b - a) if acc is None else acc + p * (b - a)
        wsum += b - a
    if acc is None:
        raise InputError("no continuous stretch long enough for a spectrum")
    return f, acc / wsum


def plot_psd(
    data: pd.DataFrame, *, band_hz: tuple[float, float] | None = None, nperseg: int = 512,
    ax: Axes | None = None, path: _PathLike | None = None,
) -> Figure:
    """Power spectral density (Welch, per stretch) of the field before and after compensation.

    Parameters
    ----------
    data : DataFrame
        Compensated log.
    band_hz : (float, float), optional
        Fitting band to shade [Hz].
    nperseg : int
        Welch segment length [samples] (shortened to the longest stretch).
    ax : Axes, optional
        Where to draw.
    path : path-like, optional
        Save the figure there (PNG).

    Returns
    -------
    Figure
        PSD in nT^2/Hz against frequency [Hz], log-log.
    """
    fig, ax = _target(ax, (7.0, 4.5))
    t = data["time"].to_numpy(dtype=np.float64)
    f, pb = _welch(_field_before(data), t, nperseg)
    f2, pa = _welch(data["mag_comp"].to_numpy(dtype=np.float64), t, nperseg)
    ax.loglog(f[1:], pb[1:], color="0.55", lw=1, label="uncompensated (mag)")
    ax.loglog(f2[1:], pa[1:], color="C0", lw=1, label="compensated (mag_comp)")
    if "mag_tl" in data.columns:
        f3, pt = _welch(data["mag_tl"].to_numpy(dtype=np.float64), t, nperseg)
        ax.loglog(f3[1:], pt[1:], color="C1", lw=0.8, ls=":", label="model (mag_tl)")
    if band_hz is not None:
        ax.axvspan(band_hz[0], band_hz[1], color="C2", alpha=0.08, label="fitting band")
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("PSD (nT²/Hz)")
    ax.set_title("Power spectral density before / after")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3, which="both")
    return _finish(fig, path)


def term_contributions(data: pd.DataFrame, terms: Any, coef: Any) -> pd.DataFrame:
    """Permanent, induced and eddy parts of the modelled interference.

    Parameters
    ----------
    data : DataFrame
        Log with ``time`` [s] and ``flux_x/y/z`` [nT].
    terms : sequence of str
        Term names of the model.
    coef : array_like
        Coefficients [nT; eddy nT*s].

    Returns
    -------
    DataFrame
        ``permanent``, ``induced``, ``eddy`` (and ``bias``) [nT] per sample; their sum is
        ``mag_tl``.
    """
    terms = tuple(terms)
    c = np.asarray(coef, dtype=np.float64)
    t = data["time"].to_numpy(dtype=np.float64)
    flux = data[["flux_x", "flux_y", "flux_z"]].to_numpy(dtype=np.float64)
    ok = np.all(np.isfinite(flux), axis=1)
    st = find_stretches(t, ok)
    A = np.full((len(t), len(terms)), np.nan)
    A[ok] = design_matrix(flux[ok], t[ok], terms, stretch=st[ok])
    groups = {"permanent": PERMANENT, "induced": INDUCED_6, "eddy": EDDY_9, "bias": ("bias",)}
    out = {}
    for name, members in groups.items():
        idx = [j for j, x in enumerate(terms) if x in members]
        if idx:
            out[name] = A[:, idx] @ c[idx]
    return pd.DataFrame(out, index=data.index)


def plot_term_contributions(
    data: pd.DataFrame, report: dict[str, Any], *, ax: Axes | None = None,
    path: _PathLike | None = None,
) -> Figure:
    """Permanent, induced and eddy contributions to ``mag_tl`` against time.

    Parameters
    ----------
    data : DataFrame
        Log with ``time`` and the fluxgate.
    report : dict
        Report or model dictionary with ``terms`` and ``coef``.
    ax : Axes, optional
        Where to draw.
    path : path-like, optional
        Save the figure there (PNG).

    Returns
    -------
    Figure
    """
    parts = term_contributions(data, report["terms"], report["coef"])
    fig, ax = _target(ax, (9.0, 4.0))
    t = data["time"].to_numpy(dtype=np.float64)
    for j, name in enumerate(parts.columns):
        tt, y = _with_gaps(t, parts[name].to_numpy())
        ax.plot(tt, y, lw=0.9, color=f"C{j}", label=f"{name} (std {np.nanstd(y):.2f} nT)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("interference (nT)")
    ax.set_title("Term contributions to the modelled interference")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    return _finish(fig, path)


# --------------------------------------------------------------------------- FOM
def plot_fom(
    fom: pd.DataFrame, *, ax: Axes | None = None, path: _PathLike | None = None,
) -> Figure:
    """FOM bar chart: peak-to-peak per heading and manoeuvre, before and after compensation.

    Bars are the mean over boxes of each (heading, manoeuvre) peak-to-peak; the title gives
    the box FOM (sum of the 12) before and after.

    Parameters
    ----------
    fom : DataFrame
        Output of :func:`aeromag.qc.fom_table`.
    ax : Axes, optional
        Where to draw.
    path : path-like, optional
        Save the figure there (PNG).

    Returns
    -------
    Figure
    """
    from ..maneuvers import CARDINALS, MANEUVERS

    if fom is None or len(fom) == 0:
        raise InputError("no manoeuvres: no FOM chart")
    fig, ax = _target(ax, (9.0, 4.5))
    agg = fom.groupby(["heading_leg", "maneuver"])[["ptp_before_nT", "ptp_after_nT"]].mean()
    labels, before, after = [], [], []
    for h in range(4):
        for m in MANEUVERS:
            if (h, m) in agg.index:
                labels.append(f"{CARDINALS[h]} {m}")
                before.append(agg.loc[(h, m), "ptp_before_nT"])
                after.append(agg.loc[(h, m), "ptp_after_nT"])
    x = np.arange(len(labels))
    ax.bar(x - 0.2, before, 0.4, color="0.6", label=f"before (sum {np.sum(before):.2f} nT)")
    ax.bar(x + 0.2, after, 0.4, color="C0", label=f"after (sum {np.sum(after):.3f} nT)")
    ax.set_xticks(x)
    ax.set_xticklabels(labels, rotation=45, ha="right", fontsize=8)
    ax.set_ylabel("peak-to-peak (nT)")
    ax.set_yscale("log")
    ax.set_title(f"Figure of Merit: {np.sum(before):.2f} nT before, {np.sum(after):.3f} nT after")
    ax.legend(loc="best", fontsize=8)
    ax.grid(axis="y", alpha=0.3, which="both")
    return _finish(fig, path)


# --------------------------------------------------------------------------- map
def plot_map(
    data: pd.DataFrame, *, column: str = "mag_comp", ax: Axes | None = None,
    path: _PathLike | None = None,
) -> Figure:
    """Flight path (longitude, latitude) coloured by the compensated field.

    Parameters
    ----------
    data : DataFrame
        Log with ``lat``, ``lon`` [deg] and ``column`` [nT].
    column : str
        Column used for the colour (default ``mag_comp``).
    ax : Axes, optional
        Where to draw.
    path : path-like, optional
        Save the figure there (PNG).

    Returns
    -------
    Figure
    """
    if not {"lat", "lon", column} <= set(data.columns):
        raise InputError(f"the map needs columns lat, lon and {column}")
    fig, ax = _target(ax, (6.5, 6.0))
    lat = data["lat"].to_numpy(dtype=np.float64)
    lon = data["lon"].to_numpy(dtype=np.float64)
    v = data[column].to_numpy(dtype=np.float64)
    ok = np.isfinite(lat) & np.isfinite(lon) & np.isfinite(v)
    if not ok.any():
        raise InputError("no sample with a position and a compensated field to map")
    lo, hi = np.percentile(v[ok], [2, 98])
    sc = ax.scatter(lon[ok], lat[ok], c=v[ok], s=4, cmap="viridis", vmin=lo, vmax=hi)
    fig.colorbar(sc, ax=ax, label=f"{column} (nT)")
    ax.set_xlabel("longitude (°)")
    ax.set_ylabel("latitude (°)")
    ax.set_aspect(1.0 / max(np.cos(np.deg2rad(np.nanmean(lat[ok]))), 1e-3))
    ax.ticklabel_format(useOffset=False)
    ax.set_title(f"Flight coloured by {column}")
    ax.grid(alpha=0.3)
    return _finish(fig, path)
