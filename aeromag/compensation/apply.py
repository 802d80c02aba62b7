"""Apply a TL model to a log: add ``mag_tl``, ``mag_comp``, ``segment``, ``segment_kept``."""

from __future__ import annotations

import copy
import logging
from typing import Any

import numpy as np
import pandas as pd

from .._core.filters import butter_sos, filter_stretches, lowpass_stretches
from .._core.parallel import submit
from .._core.stretches import find_stretches
from ..conventions import FLUX_COLUMNS
from .checks import check_metrics
from .config import CompensationConfig
from .fit import check_interference
from .metrics import band_metrics
from .model import TLModel
from .prepare import Prepared, prepare
from .report_types import CompensationMetrics

log = logging.getLogger(__name__)


# --------------------------------------------------------------------------- applying
def apply_model(
    df: pd.DataFrame, model: TLModel, cfg: CompensationConfig | None = None, *,
    kept_segments: np.ndarray | None = None, source: str | None = None,
) -> tuple[pd.DataFrame, CompensationMetrics]:
    """Apply a TL model: add ``mag_tl``, ``mag_comp``, ``segment``, ``segment_kept``.

    ``mag_tl`` is the model on the unfiltered design matrix (never re-centred, so it does not
    depend on what else is in the file); ``mag_comp = mag - mag_tl``, low-pass filtered per
    stretch unless ``cfg.filter_output`` is False.

    Parameters
    ----------
    df : DataFrame
        Log with canonical columns.
    model : TLModel
        Model to apply.
    cfg : CompensationConfig, optional
        Options.
    kept_segments : ndarray of int, optional
        Segment ids kept by screening (default: all segments kept).
    source : str, optional
        File name for messages.

    Returns
    -------
    data : DataFrame
        A copy of ``df`` with the four added columns.
    metrics : CompensationMetrics
        ``improvement_ratio``, ``residual_std_nT`` and friends (band-passed, see interface.md).
    """
    out, metrics, _ = _apply(df, model, cfg or CompensationConfig(), prep=None,
                             kept_segments=kept_segments, source=source)
    return out, metrics


def _apply(
    df: pd.DataFrame, model: TLModel, cfg: CompensationConfig, *, prep: Prepared | None,
    kept_segments: np.ndarray | None, source: str | None, release_flux: bool = False,
) -> tuple[pd.DataFrame, CompensationMetrics, np.ndarray]:
    """:func:`apply_model`, also returning the band-passed ``mag_comp`` the metrics used.

    The band-passed ``mag_comp`` (edges trimmed to NaN) is reused by the per-segment residuals
    and the QC block.  ``release_flux`` drops ``prep.flux`` once the model is evaluated
    (``compensate`` owns its ``prep``; at 1e7 samples that frees 240 MB before the filters
    run).
    """
    prep = prep or prepare(df, cfg, source=source)
    t = prep.time
    ok = prep.flux_ok
    if ok.all():
        st_all = prep.stretch if prep.valid.all() else find_stretches(t, None, cfg.max_gap_s)
        mag_tl = model.predict(prep.flux, t, st_all)
    else:
        fstretch = find_stretches(t, ok, cfg.max_gap_s)
        mag_tl = np.full(len(t), np.nan)
        mag_tl[ok] = model.predict(prep.flux[ok], t[ok], fstretch[ok])
    if model.extended is not None:
        mag_tl = mag_tl + extended_part(df, model, prep, cfg)
    if release_flux:
        prep.flux = None  # type: ignore[assignment]
    comp = np.subtract(prep.mag, mag_tl)
    seg = prep.segment
    if kept_segments is None:
        kept = np.ones(len(seg), dtype=bool)  # a saved model: every sample counts as kept
    else:
        kept = np.isin(seg, kept_segments) & (seg >= 0)
    # The metrics band-pass mag and mag - mag_tl (unfiltered: the final low-pass would flatter
    # them) once, over the stretches where mag - mag_tl is finite, each dropped segment on its
    # own so that a fault does not ring into its kept neighbours' figures; mag is filtered on
    # a pool thread while mag - mag_tl is filtered here.
    valid_st = prep.stretch >= 0
    fin = np.isfinite(comp)
    st_m = prep.stretch if fin[valid_st].all() else find_stretches(t, fin & valid_st,
                                                                    cfg.max_gap_s)
    del fin, valid_st
    st_m = isolate_dropped(st_m, seg, kept)
    sos_band = butter_sos("bandpass", cfg.band_hz, prep.fs, cfg.order)
    mag_bp_future = submit(
        lambda: filter_stretches(np.asarray(prep.mag, dtype=np.float64)[None, :], st_m,
                                 sos_band, axis=1)[0])
    metrics, comp_bp = band_metrics(prep.mag, comp, t, prep.stretch, cfg, kept=kept,
                                     fs_hz=prep.fs, stretch_bp=st_m,
                                     mag_bp=mag_bp_future.result(), source=prep.source)
    if cfg.filter_output:
        cut = cfg.lowpass_hz if cfg.lowpass_hz is not None else cfg.band_hz[1]
        # Low-pass per stretch, but each dropped segment on its own: a fault (a source
        # switching on, a drift step) must not ring through the filter into good data.
        lab = isolate_dropped(prep.stretch, seg, kept)
        comp_out = lowpass_stretches(comp, t, lab, cut, cfg.order, fs_hz=prep.fs)
        del comp  # the unfiltered copy is not kept (mag - mag_tl, for whoever needs it)
    else:
        comp_out = comp
    no_mag = missing_total_field(df, prep.mag_from_flux)
    if no_mag is not None:
        # Short gaps of mag were interpolated for the filters; a row without a measured total
        # field has no compensated one (mag_comp = mag - mag_tl).
        comp_out = np.array(comp_out, dtype=np.float64, copy=True)
        comp_out[no_mag] = np.nan
    metrics.n_rows_without_mag = 0 if no_mag is None else int(no_mag.sum())
    missing = seg < 0
    added = {"mag_tl": mag_tl, "mag_comp": comp_out,
             "segment": pd.arrays.IntegerArray(np.where(missing, 0, seg) if missing.any()
                                               else seg, missing),
             "segment_kept": kept}
    return _with_columns(df, added), metrics, comp_bp


def extended_part(df: pd.DataFrame, model: TLModel, prep: Prepared,
                  cfg: CompensationConfig) -> np.ndarray:
    """The model's interference beyond ``A @ coef``: extras, intercept, network [nT].

    Parameters
    ----------
    df : DataFrame
        The log (rows as ``prep``'s).
    model : TLModel
        A model with ``extended``.
    prep : Prepared
        Its arrays (``flux`` still held).
    cfg : CompensationConfig
        Options (the gap that splits stretches).

    Returns
    -------
    ndarray, shape (n,)
        NaN where an extra has no value.
    """
    from .terms import design_matrix

    fit_terms = tuple(t for t in model.terms if t != "bias")

    def tl_design() -> np.ndarray:
        st = find_stretches(prep.time, prep.flux_ok, cfg.max_gap_s)
        return design_matrix(prep.flux, prep.time, fit_terms, stretch=st)

    return model.extended.predict(df, tl_design, prep.source)


def missing_total_field(df: pd.DataFrame, mag_from_flux: bool) -> np.ndarray | None:
    """Rows of ``df`` without a measured total field (None when every row has one).

    Parameters
    ----------
    df : DataFrame
        The log as read (``mag`` [nT], or the fluxgate columns [nT] when they are the total
        field).
    mag_from_flux : bool
        Whether the fluxgate magnitude is the total field (no ``mag`` column, or
        ``mag_from_fluxgate``).

    Returns
    -------
    ndarray of bool or None
        True where ``mag`` (or a fluxgate component) is missing or not finite; ``mag_comp``
        is left empty there.
    """
    if mag_from_flux:
        cols = [c for c in FLUX_COLUMNS if c in df.columns]
        if not cols:
            return None
        bad = ~np.isfinite(df[cols].to_numpy(dtype=np.float64)).all(axis=1)
    elif "mag" in df.columns:
        bad = ~np.isfinite(df["mag"].to_numpy(dtype=np.float64))
    else:
        return None
    return bad if bad.any() else None


def _with_columns(df: pd.DataFrame, added: dict[str, Any]) -> pd.DataFrame:
    """``df`` with ``added``'s columns set (replaced in place, or appended), nothing copied.

    ``out[name] = array`` copies every array it is given (pandas' copy-on-write): four
    columns, 25 MB per 1e6 rows, allocated and written once more for nothing.  One frame
    built from the caller's columns and the new arrays shares them all; copy-on-write still
    keeps the caller's frame untouched.  The same columns, order, index and ``attrs`` as
    ``df.copy(deep=False)`` with the columns set one by one.
    """
    if not df.columns.is_unique or any(not isinstance(c, str) for c in added):
        out = df.copy(deep=False)
        for name, values in added.items():
            out[name] = values
        return out
    cols = {c: df[c] for c in df.columns}
    cols.update(added)
    out = pd.DataFrame(cols, index=df.index, copy=False)
    out.attrs = copy.deepcopy(df.attrs)  # as df.copy() does
    return out



def isolate_dropped(stretch: np.ndarray, segment: np.ndarray, kept: np.ndarray) -> np.ndarray:
    """Stretch labels in which every dropped segment is a stretch of its own.

    Filters run per label, so a dropped segment's fault never rings into its neighbours.

    Parameters
    ----------
    stretch : ndarray of int, shape (n,)
        Stretch labels (-1: invalid sample).
    segment : ndarray of int, shape (n,)
        Segment id per sample (-1: none).
    kept : ndarray of bool, shape (n,)
        Samples of kept segments.

    Returns
    -------
    ndarray of int, shape (n,)
        ``stretch`` itself when no segment is dropped, otherwise new labels (-1 kept).
    """
    has = segment >= 0
    if kept[has].all():
        return stretch
    dropped = np.where(has & ~kept, segment, -1)
    st = stretch
    lab = np.cumsum(np.r_[True, (st[1:] != st[:-1]) | (dropped[1:] != dropped[:-1])]) - 1
    return np.where(st >= 0, lab, -1)


def check_plausible(data: pd.DataFrame, metrics: CompensationMetrics, prep: Prepared,
                     cfg: CompensationConfig, *, fitted: bool) -> None:
    """Refuse (fitted) or warn about (saved model) a non-physical compensation.

    No aircraft's interference approaches the Earth field itself (``cfg.max_interference``,
    :func:`aeromag.compensation.fit.check_interference`); a compensation that makes the
    band-passed field worse, or leaves an implausible residual, is a warning
    (:func:`aeromag.compensation.checks.check_metrics`, the checks ``aeromag batch`` makes).
    """
    check_interference(data["mag_tl"].to_numpy(), prep.field_nT, cfg.max_interference,
                       source=prep.source, fitted=fitted)
    check_metrics(metrics, source=prep.source, fitted=fitted)
