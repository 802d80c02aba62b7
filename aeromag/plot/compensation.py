"""Compensation diagnostics plots (matplotlib, headless: Agg canvas, never ``plt.show``).

One function per figure; each has the form ``fig = plot_xxx(..., ax=None, path=None)``: it
draws into ``ax`` when given (and returns its figure), otherwise into a new figure, and saves a
PNG atomically when ``path`` is given.  Figures are :class:`QCFigure` objects created directly
on the Agg canvas (no pyplot state, no global backend switch, never ``matplotlib.use``), so they
work headless, in threads, scripts and notebooks alike; in Jupyter a returned figure shows
itself inline (``_repr_png_``), with or without ``%matplotlib inline``.

Long logs are drawn decimated for display: each line is reduced to its minimum and maximum
per pixel column (:func:`envelope`), so a figure of 2e7 samples costs what one of a few
thousand does and looks the same.  Time axes are UTC when ``time`` holds epoch seconds, else
seconds since the start of the log.

* :func:`plot_pca_scores` - PCA score plot (PC1 vs PC2) of the segment coefficient vectors,
  kept / dropped segments and the screening decision boundary;
* :func:`plot_explained_variance` - explained-variance bars with the cumulative curve;
* :func:`plot_timeseries` - uncompensated vs compensated total field;
* :func:`plot_psd` - power spectral density before / after;
* :func:`plot_term_contributions` - permanent / induced / eddy parts of ``mag_tl``;
* :func:`plot_fom` - FOM peak-to-peak bars per heading and manoeuvre, before / after;
* :func:`plot_residuals` - band-passed field before / after (the QC residual);
* :func:`plot_map` - the flight in metres (east, north), coloured by the compensated field,
  dropped segments marked.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Ellipse

from ..compensation.report_types import CompensationReport
from ..errors import InputError
from ._series import (
    NanStd,
    _welch,
    field_before,
    field_before_rows,
    term_blocks,
    term_contributions,
    term_groups,
    time_blocks,
)
from ._style import (
    DPI,
    ENVELOPE_BLOCK,
    PathLike,
    QCFigure,
    TimeAxis,
    _data,
    _report,
    envelope,
    figure_png,
    finish,
    format_time,
    median_step,
    new_figure,
    new_stretch,
    plain_log_ticks,
    save_figure,
    streamed_envelopes,
    stretch_gap_s,
    target,
    time_axis,
)
from .maps import plot_map

__all__ = ["DPI", "QCFigure", "envelope", "figure_png", "new_figure", "plot_explained_variance",
           "plot_fom", "plot_map", "plot_pca_scores", "plot_psd", "plot_residuals",
           "plot_term_contributions", "plot_timeseries", "save_figure", "term_contributions",
           "time_axis"]

log = logging.getLogger(__name__)


def _segments_frame(report: CompensationReport) -> pd.DataFrame:
    segs = [s for s in report.segments if s.scores is not None]
    if not segs:
        raise InputError("the report has no PCA scores (screening was off or a saved model was"
                         " applied): no score plot")
    return pd.DataFrame({"id": [s.id for s in segs], "scores": [s.scores for s in segs],
                         "kept": [s.kept for s in segs],
                         "pca_outlier": [s.pca_outlier for s in segs]})


# --------------------------------------------------------------------------- PCA
def plot_pca_scores(
    report: Any, *, ax: Axes | None = None, path: PathLike | None = None,
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
    report : CompensationReport, CompensationResult or dict
        Compensation report (or the result holding it, or the report as read from its JSON
        file) with the segments' ``scores``/``kept`` and ``screening``.
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
    report = _report(report)
    seg = _segments_frame(report)
    scr = report.screening
    own = ax is None
    fig, ax = target(ax, (6.0, 5.0))
    sc = np.array([np.r_[s, 0.0][:2] if len(s) < 2 else s[:2] for s in seg["scores"]],
                  dtype=float)
    kept = seg["kept"].to_numpy(dtype=bool)
    outl = (seg["pca_outlier"].fillna(False).to_numpy(dtype=bool)
            if seg["pca_outlier"].notna().any() else ~kept)
    ax.scatter(sc[kept & ~outl, 0], sc[kept & ~outl, 1], s=28, c="C0", label="kept",
               zorder=3)
    if (kept & outl).any():
        ax.scatter(sc[kept & outl, 0], sc[kept & outl, 1], s=36, facecolors="none",
                   edgecolors="C0", label="outside, kept (not material)", zorder=3)
    if (~kept).any():
        ax.scatter(sc[~kept, 0], sc[~kept, 1], s=46, c="C3", marker="X", label="dropped",
                   zorder=4)
    if annotate:  # the dropped segments first, then the farthest outliers (at most 15)
        flag = np.flatnonzero(~kept | outl)
        dist = np.hypot(*(sc[flag] - np.median(sc, axis=0)).T)
        order = flag[np.lexsort((-dist, kept[flag]))][:15]
        for i in order:
            ax.annotate(str(seg["id"].iloc[i]), sc[i], textcoords="offset points",
                        xytext=(4, 4), fontsize=8)
    loc = np.asarray(scr.location or [], dtype=float)
    cov = np.asarray(scr.covariance or [], dtype=float)
    cut = scr.cutoff
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
    evr = scr.explained_variance_ratio or []
    lab = [f"PC{i + 1}" + (f" ({100 * evr[i]:.0f} %)" if i < len(evr) else "") for i in (0, 1)]
    ax.set_xlabel(lab[0])
    ax.set_ylabel(lab[1])
    nd = int((~kept).sum())
    ax.set_title(f"PCA score plot: {len(seg)} segments, {nd} dropped")
    ax.grid(alpha=0.3)
    # Below the axes, outside them: inside, any corner can hide a kept segment's point (issue
    # 30); "best" costs seconds with many segments.
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=3, fontsize=8,
              frameon=False)
    ax.autoscale_view()
    if own and fig.get_layout_engine() is None:
        fig.subplots_adjust(bottom=0.22)  # room for the legend (a caller's ax is left alone)
    return finish(fig, path)


def plot_explained_variance(
    report: Any, *, ax: Axes | None = None, path: PathLike | None = None,
) -> Figure:
    """Explained-variance ratio per principal component (bars) and cumulative (line).

    Parameters
    ----------
    report : CompensationReport, CompensationResult or dict
        Compensation report (or the result holding it, or the report as read from its JSON
        file) with ``screening.explained_variance_ratio``.
    ax : Axes, optional
        Where to draw.
    path : path-like, optional
        Save the figure there (PNG).

    Returns
    -------
    Figure
    """
    scr = _report(report).screening
    evr = np.asarray(scr.explained_variance_ratio or [], dtype=float)
    if evr.size == 0:
        raise InputError("the report has no explained-variance ratios (no PCA screening)")
    fig, ax = target(ax, (6.0, 4.0))
    x = np.arange(1, evr.size + 1)
    ncomp = int(scr.n_components or 0)
    colors = ["C0" if i < ncomp else "0.7" for i in range(evr.size)]
    ax.bar(x, 100 * evr, color=colors, label="per component")
    ax.plot(x, 100 * np.cumsum(evr), "k.-", label="cumulative")
    thr = scr.pca_variance_threshold
    if thr is not None:
        ax.axhline(100 * thr, color="C3", ls="--", lw=1, label=f"threshold {100 * thr:.0f} %")
    ax.set_xlabel("principal component")
    ax.set_ylabel("explained variance (%)")
    ax.set_xticks(x)
    ax.set_ylim(0, 105)
    ax.set_title(f"Explained variance ({ncomp} component(s) retained)")
    ax.legend(loc="center right", fontsize=8)
    ax.grid(axis="y", alpha=0.3)
    return finish(fig, path)


# --------------------------------------------------------------------------- time series
def plot_timeseries(
    data: Any, *, ax: Axes | None = None, path: PathLike | None = None,
) -> Figure:
    """Uncompensated (``mag``) and compensated (``mag_comp``) total field against time.

    Parameters
    ----------
    data : DataFrame or CompensationResult
        Compensated log (``time`` [s], ``mag`` [nT] or the fluxgate, ``mag_comp`` [nT]).
    ax : Axes, optional
        Where to draw.
    path : path-like, optional
        Save the figure there (PNG).

    Returns
    -------
    Figure
    """
    data = _data(data)
    fig, ax = target(ax, (9.0, 4.0))
    t = data["time"].to_numpy(dtype=np.float64)
    before = field_before_rows(data)
    comp = data["mag_comp"].to_numpy()
    # Enveloped block by block: no full-length abscissa, labels or keys (issue 15).
    tax, blocks = time_blocks(
        t, lambda a, b: [before(a, b), np.asarray(comp[a:b], dtype=np.float64)])
    (xb, yb), (xc, yc) = streamed_envelopes(len(t), blocks, 2)
    ax.plot(xb, yb, color="0.55", lw=0.8, label="uncompensated (mag)")
    ax.plot(xc, yc, color="C0", lw=0.9, label="compensated (mag_comp)")
    format_time(ax, tax.is_date, tax.label)
    ax.ticklabel_format(axis="y", useOffset=False, style="plain")
    ax.set_ylabel("total field (nT)")
    ax.set_title("Uncompensated vs compensated total field")
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(alpha=0.3)
    return finish(fig, path)


def plot_residuals(
    time_s: Any, before_bp: np.ndarray | None = None, after_bp: np.ndarray | None = None, *,
    kept: np.ndarray | None = None, band_hz: tuple[float, float] | None = None,
    ax: Axes | None = None, path: PathLike | None = None,
) -> Figure:
    """Band-passed field before (``mag``) and after (``mag - mag_tl``) compensation.

    Both are filtered the same way (in the fitting band, each segment piece on its own, see
    :func:`aeromag.qc.residuals.piece_residuals`), so the figure compares like with like.
    Samples of dropped segments are drawn in red.

    Parameters
    ----------
    time_s : ndarray, shape (n,), or CompensationResult
        Times [s]; or a compensation, whose residuals are computed
        (:func:`aeromag.qc.compute_qc`).
    before_bp, after_bp : ndarray, shape (n,)
        Band-passed fields [nT] (NaN where not filtered).
    kept : ndarray of bool, shape (n,), optional
        Samples of kept segments.
    band_hz : (float, float), optional
        The band, for the title [Hz].
    ax : Axes, optional
        Where to draw.
    path : path-like, optional
        Save the figure there (PNG).

    Returns
    -------
    Figure
    """
    if before_bp is None or after_bp is None:
        from ..qc import compute_qc, kept_mask

        q = compute_qc(time_s, fit=False, fom=False)
        data = _data(time_s)
        before_bp, after_bp = q.residuals.before_bp, q.residuals.after_bp
        kept = kept_mask(data) if kept is None else kept
        band_hz = tuple(q.metrics.band_hz) if band_hz is None else band_hz
        time_s = data["time"].to_numpy()
    fig, ax = target(ax, (9.0, 4.0))
    t = np.asarray(time_s, dtype=np.float64)
    bp = np.asarray(before_bp)
    ap = np.asarray(after_bp)
    k = None if kept is None else np.asarray(kept, dtype=bool)
    dropped = k is not None and not bool(k.all())

    def lines(i: int, j: int) -> list[np.ndarray]:  # float64 rows [i, j) of each line
        b = np.asarray(bp[i:j], dtype=np.float64)
        a = np.asarray(ap[i:j], dtype=np.float64)
        if k is None:
            return [b, a]
        out = [b, np.where(k[i:j], a, np.nan)]
        if dropped:
            out.append(np.where(k[i:j], np.nan, a))
        return out

    # Enveloped block by block: no full-length abscissa, masked copies, labels or keys.
    tax, blocks = time_blocks(t, lines)
    env = streamed_envelopes(len(t), blocks, 3 if dropped else 2)
    ax.plot(*env[0], color="0.6", lw=0.7, label="before: mag")
    ax.plot(*env[1], color="C0", lw=0.8, label="after: mag - mag_tl (kept segments)")
    if dropped:
        ax.plot(*env[2], color="C3", lw=0.8, label="after (dropped segments)")
    format_time(ax, tax.is_date, tax.label)
    ax.set_ylabel("band-passed field (nT)")
    band = f" {band_hz[0]:g}-{band_hz[1]:g} Hz" if band_hz else ""
    ax.set_title(f"Band-passed{band} field before and after compensation")
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(alpha=0.3)
    return finish(fig, path)


def plot_psd(
    data: Any, *, band_hz: tuple[float, float] | None = None, nperseg: int = 512,
    ax: Axes | None = None, path: PathLike | None = None,
) -> Figure:
    """Power spectral density (Welch, per stretch) of the field before and after compensation.

    Parameters
    ----------
    data : DataFrame or CompensationResult
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
    if band_hz is None and _report(data).band_hz:
        band_hz = tuple(_report(data).band_hz)
    data = _data(data)
    fig, ax = target(ax, (7.0, 4.5))
    t = data["time"].to_numpy(dtype=np.float64)
    step = median_step(t)
    f, pb = _welch(field_before(data), t, nperseg, step)
    f2, pa = _welch(data["mag_comp"].to_numpy(dtype=np.float64), t, nperseg, step)
    ax.loglog(f[1:], pb[1:], color="0.55", lw=1, label="uncompensated (mag)")
    ax.loglog(f2[1:], pa[1:], color="C0", lw=1, label="compensated (mag_comp)")
    if "mag_tl" in data.columns:
        f3, pt = _welch(data["mag_tl"].to_numpy(dtype=np.float64), t, nperseg, step)
        ax.loglog(f3[1:], pt[1:], color="C1", lw=0.8, ls=":", label="model (mag_tl)")
    if band_hz is not None:
        ax.axvspan(band_hz[0], band_hz[1], color="C2", alpha=0.08, label="fitting band")
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("PSD (nT²/Hz)")
    ax.set_title("Power spectral density before / after")
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(alpha=0.3, which="both")
    plain_log_ticks(ax)
    return finish(fig, path)


def plot_term_contributions(
    data: Any, report: CompensationReport | dict[str, Any] | None = None, *,
    ax: Axes | None = None,
    path: PathLike | None = None,
) -> Figure:
    """Permanent, induced and eddy contributions to ``mag_tl`` against time.

    The contributions are computed and enveloped for display block by block
    (:func:`term_contributions`' blocks): the full-length groups never exist.

    Parameters
    ----------
    data : DataFrame or CompensationResult
        Log with ``time`` and the fluxgate.
    report : CompensationReport or dict, optional
        Report with ``terms`` and ``coef``, or a report or model file as read from JSON
        (default: the result's).
    ax : Axes, optional
        Where to draw.
    path : path-like, optional
        Save the figure there (PNG).

    Returns
    -------
    Figure
    """
    if report is None:
        report = _report(data)
    report = _report(report)
    data = _data(data)
    if not {"flux_x", "flux_y", "flux_z"} <= set(data.columns):
        raise InputError("the term contributions need flux_x, flux_y, flux_z")
    if not report.terms or not report.coef:
        raise InputError("the report has no model (terms, coef)")
    terms, coef = tuple(report.terms), report.coef
    names = list(term_groups(terms))
    fig, ax = target(ax, (9.0, 4.0))
    t = data["time"].to_numpy(dtype=np.float64)
    tax, gap, n = TimeAxis(t), stretch_gap_s(t), len(t)
    stats = {g: NanStd() for g in names}
    counted = [False]

    def blocks() -> Any:
        for a, b, parts in term_blocks(data, terms, coef):
            ys = [parts[g] for g in names]
            if not counted[0]:
                for g, y in zip(names, ys, strict=True):
                    stats[g].add(y)
            yield a, tax(t[a:b]), new_stretch(t, a, b, gap), ys
        counted[0] = True

    # Each line's drawable x range, guessed from the rows with a fluxgate sample (the groups
    # are finite there): checked by the envelopes, which redo the pass if it was wrong.
    fl = [data[k].to_numpy() for k in ("flux_x", "flux_y", "flux_z")]
    lo, hi = np.inf, -np.inf
    for a in range(0, n, ENVELOPE_BLOCK):
        x = tax(t[a:a + ENVELOPE_BLOCK])
        ok = np.isfinite(x)
        for f in fl:
            ok &= np.isfinite(f[a:a + ENVELOPE_BLOCK])
        if ok.any():
            lo, hi = min(lo, float(np.min(x[ok]))), max(hi, float(np.max(x[ok])))
    env = streamed_envelopes(n, blocks, len(names), [(lo, hi)] * len(names))
    exact = None
    for j, name in enumerate(names):
        sd = stats[name].text()
        if sd is None:  # near a rounding boundary: np.nanstd's own value (one more pass)
            if exact is None:
                exact = term_contributions(data, terms, coef)
            sd = f"{np.nanstd(exact[name].to_numpy()):.2f}"
        ax.plot(*env[j], lw=0.9, color=f"C{j}", label=f"{name} (std {sd} nT)")
    del exact
    format_time(ax, tax.is_date, tax.label)
    ax.set_ylabel("interference (nT)")
    ax.set_title("Term contributions to the modelled interference")
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(alpha=0.3)
    return finish(fig, path)


# --------------------------------------------------------------------------- FOM
def plot_fom(
    fom: Any, *, ax: Axes | None = None, path: PathLike | None = None,
) -> Figure:
    """FOM bar chart: peak-to-peak per heading and manoeuvre, before and after compensation.

    Bars are the mean over boxes of each (heading, manoeuvre) peak-to-peak; the title gives
    the box FOM (sum of the 12) before and after.

    Parameters
    ----------
    fom : DataFrame, FomSummary, QCResult or CompensationResult
        Output of :func:`aeromag.qc.fom_table`; the FOM block of a QC (its ``table``; a
        dict read from ``qc.json``'s ``fom`` is read through
        :meth:`~aeromag.qc.FomSummary.from_dict`); a QC result (:func:`aeromag.qc.compute_qc`);
        or a compensation of a calibration flight (its FOM is computed).  An error says why
        when there is no complete box.
    ax : Axes, optional
        Where to draw.
    path : path-like, optional
        Save the figure there (PNG).

    Returns
    -------
    Figure
    """
    from ..qc import FomSummary, QCResult, compute_qc
    from ..qc.maneuvers import CARDINALS, MANEUVERS

    if isinstance(fom, dict):  # qc.json's fom block: typed at the edge
        fom = FomSummary.from_dict(fom)
    if isinstance(fom, FomSummary):
        if not fom.applicable:
            raise InputError(fom.reason or "no FOM")
        fom = pd.DataFrame([r.to_dict() for r in fom.table or []])
    elif not isinstance(fom, pd.DataFrame) and fom is not None:
        q = fom if isinstance(fom, QCResult) else compute_qc(fom, fit=False)
        if q.metrics.fom is None or not q.metrics.fom.applicable:
            raise InputError(q.metrics.fom.reason if q.metrics.fom is not None else "no FOM")
        fom = q.fom
    if fom is None or len(fom) == 0:
        raise InputError("no manoeuvres: no FOM chart")
    fig, ax = target(ax, (9.0, 4.5))
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
    plain_log_ticks(ax)  # no mathtext: it looks up fonts and warns where they are missing
    ax.set_title(f"Figure of Merit: {np.sum(before):.2f} nT before, {np.sum(after):.3f} nT after")
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(axis="y", alpha=0.3, which="both")
    return finish(fig, path)
