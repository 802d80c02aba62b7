"""Flight segments: the unit of the per-segment fit and of PCA screening.

A *segment* is a flight line (the ``line`` column) or, without one, a fixed window of
``segment_seconds`` inside a stretch (:mod:`aeromag._core.stretches`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import InputError
from .metrics import NullableBlock, split_fields

log = logging.getLogger(__name__)


def assign_segments(
    time_s: np.ndarray,
    stretch: np.ndarray,
    line: np.ndarray | None = None,
    segment_seconds: float = 60.0,
) -> np.ndarray:
    """Segment id per sample.

    With a ``line`` column the segment is the line number (a line interrupted by a gap stays
    one segment; each continuous piece is filtered on its own; a negative line number marks a
    turn or transit and belongs to no segment, with a warning); non-integer line numbers
    (e.g. ``1002.02``) are numbered 0, 1, ... in sorted order (see :func:`line_labels`).
    Without it, every stretch is cut into ``round(duration / segment_seconds)`` (at least
    one) windows of equal duration, numbered consecutively over the flight.

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Times [s].
    stretch : ndarray of int, shape (n,)
        Stretch labels (-1 = invalid sample).
    line : ndarray, shape (n,), optional
        Line numbers (NaN = no line).
    segment_seconds : float
        Window length without a line column [s].

    Returns
    -------
    ndarray of int64, shape (n,)
        Segment id, -1 for samples in no segment.
    """
    st = np.asarray(stretch)
    if line is not None:
        ln = np.asarray(line, dtype=np.float64)
        ok = np.isfinite(ln) & (st >= 0)
        seg = np.full(len(st), -1, dtype=np.int64)
        vals = ln[ok]
        if np.array_equal(vals, np.rint(vals)):
            seg[ok] = vals.astype(np.int64)
            neg = int((vals < 0).sum())
            if neg:
                log.warning("%d sample(s) have a negative line number (turns, by convention):"
                            " they belong to no segment and are not fitted", neg)
        else:
            # Line numbers such as 1002.02 / 1002.20 (SGL): number them 0, 1, ... in sorted
            # order so that distinct lines never merge; line_labels() gives the originals.
            _, codes = np.unique(vals, return_inverse=True)
            seg[ok] = codes
            log.info("non-integer line numbers: segments numbered 0..%d in line order",
                     int(codes.max()))
        return seg
    if segment_seconds <= 0:

        raise InputError(f"segment_seconds={segment_seconds}: must be positive")
    t = np.asarray(time_s, dtype=np.float64)
    seg = np.full(len(st), -1, dtype=np.int64)
    ok = st >= 0
    if not ok.any():
        return seg
    sid = st[ok]
    tt = t[ok]
    nst = int(sid.max()) + 1
    t0 = np.full(nst, np.inf)
    t1 = np.full(nst, -np.inf)
    np.minimum.at(t0, sid, tt)
    np.maximum.at(t1, sid, tt)
    dur = np.maximum(t1 - t0, 0.0)
    nwin = np.maximum(1, np.round(dur / segment_seconds)).astype(np.int64)
    width = np.where(dur > 0, dur / nwin, 1.0)
    win = np.minimum(((tt - t0[sid]) / width[sid]).astype(np.int64), nwin[sid] - 1)
    offset = np.r_[0, np.cumsum(nwin)[:-1]]
    seg[ok] = offset[sid] + win
    return seg


def line_labels(line: np.ndarray | None) -> dict[int, float] | None:
    """Map segment ids back to the original line numbers when those are not integers.

    Parameters
    ----------
    line : ndarray or None
        The ``line`` column.

    Returns
    -------
    dict or None
        ``{segment_id: line_number}``, or None when line numbers are integers (segment id =
        line number) or absent.
    """
    if line is None:
        return None
    ln = np.asarray(line, dtype=np.float64)
    fin = ln[np.isfinite(ln)]
    if fin.size == 0 or np.array_equal(fin, np.rint(fin)):  # integers: no sort needed
        return None
    vals = np.unique(fin)
    return {i: float(v) for i, v in enumerate(vals)}


def segment_counts(segment: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Segment ids present (ascending) and their sample counts (-1 = no segment).

    Parameters
    ----------
    segment : ndarray of int, shape (n,)
        Segment id per sample.

    Returns
    -------
    ids, counts : ndarray of int64
    """
    seg = np.asarray(segment)
    good = seg[seg >= 0]
    if good.size == 0:
        e = np.zeros(0, dtype=np.int64)
        return e, e
    top = int(good.max())
    if top <= 4 * good.size + 1024:  # small ids: a histogram, no sort
        counts = np.bincount(good, minlength=top + 1)
        ids = np.flatnonzero(counts)
        return ids.astype(np.int64), counts[ids].astype(np.int64)
    ids, counts = np.unique(good, return_counts=True)
    return ids.astype(np.int64), counts.astype(np.int64)


#: Optional keys of a segment row, in the order the JSON writes them (``reason`` moves before
#: ``robust_distance`` on a too-short segment, where the fit records it first).
_SEGMENT_ORDER = ("id", "n", "n_fit", "kept", "scores", "residual_std", "cv_residual_std",
                  "condition_number", "coef", "too_short", "min_samples", "robust_distance",
                  "pca_outlier", "residual_excess", "own_fit_excess", "readmitted",
                  "pool_residual_nT", "line", "pool_median_nT", "own_excess_nT",
                  "own_excess_median_nT", "reason", "start_time", "end_time", "heading_deg",
                  "residual_flagged", "name")
#: Keys every segment row writes, None or not.
_SEGMENT_ALWAYS = frozenset({"id", "n", "kept", "scores", "residual_std"})


@dataclass
class SegmentRow(NullableBlock):
    """One segment of a compensation (an entry of the report's ``segments``).

    Attributes
    ----------
    id : int
        Segment id (the ``segment`` column).
    n : int
        Samples of the segment in the log.
    kept : bool
        Whether the fit kept it (always True when a saved model is applied).
    scores : list of float or None
        Its PCA scores (None when not screened or not fitted).
    residual_std : float or None
        Band-passed residual std of the segment [nT]: in-sample under the final fit, or
        (saved model) of ``mag - mag_tl`` per segment piece; None when unknown.
    n_fit : int or None
        Samples its fit used (band-passed, filter edges trimmed, decimated); fits only.
    cv_residual_std : float or None
        Leave-this-segment-out residual std [nT].
    condition_number : float or None
        Scaled condition number of its own normal equations [-].
    coef : list of float or None
        Its own (shrunk) coefficients.
    too_short : bool or None
        True for a segment too short to fit (then ``min_samples`` and ``reason``).
    min_samples : int or None
        Samples a segment needs to be fitted.
    robust_distance : float or None
        Robust (MCD) squared distance of its PCA scores [-].
    pca_outlier : bool or None
        Outside the screening's chi-square cut-off.
    residual_excess, own_fit_excess : float or None
        Its pooled-fit residual over the kept segments' median, and its own-fit excess ratio
        [-].
    readmitted : bool or None
        A PCA outlier kept because its residual is not materially worse.
    pool_residual_nT : float or None
        Its residual under the pooled fit of the screening's last round [nT].
    line : float or None
        The flight line (when the segments are the log's lines).
    pool_median_nT : float or None
        The median ``pool_residual_nT`` a dropped segment is compared with [nT].
    own_excess_nT, own_excess_median_nT : float or None
        Its own-fit excess and the kept segments' median of it [nT].
    reason : str or None
        Why it was dropped or not fitted, with numbers.
    start_time, end_time : float or None
        Time span of a dropped segment [s, the log's time].
    heading_deg : float or None
        Its circular-mean heading [deg].
    residual_flagged : bool or None
        Flagged by the residual screen of an applied model
        (:func:`aeromag.compensation.report.flag_residual_outliers`).
    name : str or None
        How messages name it (:func:`aeromag.compensation.report.segment_name`).
    nulls : frozenset of str
        Optional keys the JSON holds although their value is None (``null``).
    extra : dict
        Keys this class does not know (written after the others).
    """

    id: int
    n: int | None = None
    kept: bool = True
    scores: list[float] | None = None
    residual_std: float | None = None
    n_fit: int | None = None
    cv_residual_std: float | None = None
    condition_number: float | None = None
    coef: list[float] | None = None
    too_short: bool | None = None
    min_samples: int | None = None
    robust_distance: float | None = None
    pca_outlier: bool | None = None
    residual_excess: float | None = None
    own_fit_excess: float | None = None
    readmitted: bool | None = None
    pool_residual_nT: float | None = None
    line: float | None = None
    pool_median_nT: float | None = None
    own_excess_nT: float | None = None
    own_excess_median_nT: float | None = None
    reason: str | None = None
    start_time: float | None = None
    end_time: float | None = None
    heading_deg: float | None = None
    residual_flagged: bool | None = None
    name: str | None = None
    nulls: frozenset[str] = frozenset()
    extra: dict[str, Any] = field(default_factory=dict)

    def drop(self, key: str) -> None:
        """Remove an optional attribute (no key in the JSON).

        Parameters
        ----------
        key : str
            Attribute name.
        """
        setattr(self, key, None)
        self.nulls = self.nulls - {key}

    def to_dict(self) -> dict[str, Any]:
        """The JSON entry: the keys that are set, in the report's order.

        Returns
        -------
        dict
        """
        d: dict[str, Any] = {}
        for key in _SEGMENT_ORDER:
            if key == "reason" and self.too_short:
                continue
            v = getattr(self, key)
            if v is not None or key in _SEGMENT_ALWAYS or key in self.nulls:
                d[key] = v
            if key == "min_samples" and self.too_short and self.reason is not None:
                d["reason"] = self.reason
        d.update(self.extra)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> SegmentRow:
        """A segment entry read from a file.

        Parameters
        ----------
        d : dict
            An entry of a report's ``segments``.

        Returns
        -------
        SegmentRow
        """
        kw, extra = split_fields(cls, d)
        nulls = frozenset(k for k, v in kw.items() if v is None) - _SEGMENT_ALWAYS
        kw.setdefault("id", -1)
        if "kept" in kw and kw["kept"] is None:
            kw["kept"] = False
        return cls(**kw, nulls=nulls, extra=extra)
