"""Compensation metrics on band-passed fields (interface.md ``metrics``)."""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any, Self

import numpy as np

from .._core.filters import (
    butter_sos,
    filter_stretches,
    filter_stretches_each,
    min_filter_length,
    sampling_rate,
    trim_mask,
)
from .._core.moments import masked_std
from .._core.runs import true_runs
from .._core.stretches import find_stretches
from ..errors import InputError
from .config import CompensationConfig

log = logging.getLogger(__name__)


def split_fields(cls: type, d: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """Split a JSON block into the keyword arguments of dataclass ``cls`` and the other keys.

    Parameters
    ----------
    cls : type
        A dataclass (its ``extra`` and ``nulls`` fields are not keys of the block).
    d : dict
        The block as read from JSON.

    Returns
    -------
    known, other : dict
    """
    names = {f.name for f in dataclasses.fields(cls)} - {"extra", "nulls"}
    return ({k: v for k, v in d.items() if k in names},
            {k: v for k, v in d.items() if k not in names})


def block_dict(obj: Any, skip: tuple[str, ...] = ()) -> dict[str, Any]:
    """A flat JSON block from a dataclass: its fields in order (but ``skip``), then ``extra``.

    Parameters
    ----------
    obj : dataclass instance
        With an ``extra`` dict of the keys it does not know.
    skip : tuple of str
        Fields left out.

    Returns
    -------
    dict
    """
    d = {f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)
         if f.name != "extra" and f.name not in skip}
    d.update(obj.extra)
    return d


def block_from_dict(cls: type, d: dict[str, Any] | None) -> Any:
    """:func:`block_dict` read back: ``cls`` from a JSON block (None for none).

    Parameters
    ----------
    cls : type
        A dataclass with an ``extra`` field and defaults for every other one.
    d : dict or None
        The block.

    Returns
    -------
    object or None
        A ``cls``, its unknown keys in ``extra``.
    """
    if not d:
        return None
    kw, extra = split_fields(cls, d)
    return cls(**kw, extra=extra)


class NullableBlock:
    """Base of a block whose optional fields are written when set, a None one as ``null``.

    The subclass is a dataclass with a ``nulls`` field: the optional keys that are written
    as ``null`` although their value is None (None alone means "absent").
    """

    nulls: frozenset[str]

    def set(self, key: str, value: Any) -> None:
        """Set an optional attribute; a None value is still written (as ``null``).

        Parameters
        ----------
        key : str
            Attribute name.
        value : object
            Its value.
        """
        setattr(self, key, value)
        self.nulls = self.nulls | {key} if value is None else self.nulls - {key}


class FlatBlock:
    """Base of a dataclass whose JSON block is its fields in order, then its ``extra``.

    The subclass is a dataclass with an ``extra`` dict field and a default for every other
    field; :meth:`to_dict` is :func:`block_dict`, :meth:`from_dict` :func:`block_from_dict`.
    """

    def to_dict(self) -> dict[str, Any]:
        """The JSON block (the fields in order, then ``extra``).

        Returns
        -------
        dict
        """
        return block_dict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> Self | None:
        """The block read from a file (None for none); unknown keys go to ``extra``.

        Parameters
        ----------
        d : dict or None

        Returns
        -------
        instance of the class, or None
        """
        return block_from_dict(cls, d)


@dataclass
class CompensationMetrics:
    """The headline metrics of a compensation (the report's ``metrics`` block).

    Every figure is taken on band-passed fields (zero-phase Butterworth in ``band_hz``, per
    continuous stretch, each dropped segment on its own, filter edges trimmed); see
    ``definition`` and :func:`aeromag.compensation.metrics.compensation_metrics`.

    Attributes
    ----------
    definition : str
        How the figures are computed, in words.
    n_samples : int
        Samples of the kept segments the headline is taken over.
    std_before_nT, residual_std_nT : float
        Over the kept segments: std of band-passed ``mag`` and of ``mag - mag_tl`` [nT].
    improvement_ratio : float
        ``std_before_nT / residual_std_nT`` [-] (NaN without a residual).
    kept_std_before_nT, kept_residual_std_nT, kept_improvement_ratio : float
        The same, under their explicit names [nT, nT, -].
    all_n_samples, all_std_before_nT, all_residual_std_nT, all_improvement_ratio
        The same over all segments [-, nT, nT, -].
    band_hz : list of float
        The fitting band [Hz].
    n_rows_without_mag : int or None
        Rows without a measured total field (their ``mag_comp`` is NaN); None when not counted.
    extra : dict
        Other keys of a metrics block read from a file or added by a workflow (the online
        run's ``coverage``, ``after_warmup``), written after the others.
    """

    definition: str | None = None
    n_samples: int | None = None
    std_before_nT: float | None = None
    residual_std_nT: float | None = None
    improvement_ratio: float | None = None
    kept_std_before_nT: float | None = None
    kept_residual_std_nT: float | None = None
    kept_improvement_ratio: float | None = None
    all_n_samples: int | None = None
    all_std_before_nT: float | None = None
    all_residual_std_nT: float | None = None
    all_improvement_ratio: float | None = None
    band_hz: list[float] | None = None
    n_rows_without_mag: int | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The JSON ``metrics`` block (``n_rows_without_mag`` only when counted).

        Returns
        -------
        dict
        """
        d = block_dict(self, skip=() if self.n_rows_without_mag is not None
                       else ("n_rows_without_mag",))
        if self.band_hz is not None:
            d["band_hz"] = list(self.band_hz)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> CompensationMetrics | None:
        """A metrics block read from a JSON file (None for none; missing figures are None).

        Parameters
        ----------
        d : dict or None
            The ``metrics`` block.

        Returns
        -------
        CompensationMetrics or None
        """
        return block_from_dict(cls, d)



def compensation_metrics(
    mag: np.ndarray, mag_comp: np.ndarray, time_s: np.ndarray, stretch: np.ndarray,
    cfg: CompensationConfig, kept: np.ndarray | None = None,
) -> CompensationMetrics:
    """Improvement ratio and residual std on band-passed fields (interface.md metrics).

    Parameters
    ----------
    mag, mag_comp : ndarray, shape (n,)
        Uncompensated and compensated total field as written [nT].
    time_s : ndarray, shape (n,)
        Times [s].
    stretch : ndarray of int, shape (n,)
        Stretch labels.
    cfg : CompensationConfig
        Band and order.
    kept : ndarray of bool, optional
        Samples of kept segments (extra metrics over them).

    Returns
    -------
    CompensationMetrics
        See :func:`metrics_dict`: ``improvement_ratio`` (std band-passed ``mag`` / std
        band-passed ``mag_comp``), ``residual_std_nT``, ``std_before_nT``, ``n_samples``, over
        the kept segments, and ``all_*`` over all samples.  Pass ``mag - mag_tl`` (unfiltered)
        as ``mag_comp`` for the figures the pipeline reports.
    """
    return band_metrics(mag, mag_comp, time_s, stretch, cfg, kept=kept)[0]


def band_metrics(
    mag: np.ndarray, mag_comp: np.ndarray, time_s: np.ndarray, stretch: np.ndarray,
    cfg: CompensationConfig, kept: np.ndarray | None = None, fs_hz: float | None = None,
    stretch_bp: np.ndarray | None = None, mag_bp: np.ndarray | None = None,
    source: str = "<log>",
) -> tuple[CompensationMetrics, np.ndarray]:
    """:func:`compensation_metrics` and the band-passed ``mag_comp`` it used (NaN outside).

    ``stretch_bp`` and ``mag_bp``, when given, are the stretches of finite ``mag_comp`` and
    ``mag`` already band-passed over them (computed here otherwise).
    """
    fs = sampling_rate(time_s) if fs_hz is None else fs_hz
    sos = butter_sos("bandpass", cfg.band_hz, fs, cfg.order)
    if stretch_bp is not None:
        st = stretch_bp
    else:
        fin = np.isfinite(mag_comp)
        # Re-label so a NaN inside a stretch splits it (filters never run over NaN).
        st = stretch if fin[stretch >= 0].all() else find_stretches(
            time_s, fin & (stretch >= 0), cfg.max_gap_s)
    if mag_bp is not None:
        comp_bp = filter_stretches(np.asarray(mag_comp, dtype=np.float64)[None, :], st, sos,
                                   axis=1)[0]
    elif len(mag) > 2_000_000:  # one at a time: each filter's temporaries are 3 x the series
        mag_bp = filter_stretches(np.asarray(mag, dtype=np.float64)[None, :], st, sos,
                                  axis=1)[0]
        comp_bp = filter_stretches(np.asarray(mag_comp, dtype=np.float64)[None, :], st, sos,
                                   axis=1)[0]
    else:
        mag_bp, comp_bp = filter_stretches_each([mag, mag_comp], st, sos)
    trim = (0.5 / cfg.band_hz[0]) if cfg.trim_s is None else cfg.trim_s
    fin = np.isfinite(mag_bp) & np.isfinite(comp_bp)
    use = trim_mask(st, time_s, trim) & fin
    require_samples(int(use.sum()), fs, cfg.band_hz, source)
    before = masked_std(mag_bp, use)
    after = masked_std(comp_bp, use)
    kept_std = None
    if kept is not None:
        uk = use if kept.all() else use & kept
        if uk.any():
            kept_std = ((before, after) if uk is use
                        else (masked_std(mag_bp, uk), masked_std(comp_bp, uk)))
    n_kept = int(use.sum()) if kept is None or kept.all() else int((use & kept).sum())
    out = metrics_dict(int(use.sum()), before, after, kept_std, cfg.band_hz, n_kept=n_kept)
    comp_bp[~use] = np.nan
    return out, comp_bp



#: What the metrics are, in the report's words.
DEFINITION = ("std of mag and of mag - mag_tl (unfiltered), each band-passed once in band_hz"
              " (zero-phase Butterworth, per stretch, each dropped segment on its own), filter"
              " edges trimmed; headline figures over the kept segments, all_* over all"
              " segments; improvement_ratio = std_before_nT / residual_std_nT")


def require_samples(n_used: int, fs_hz: float, band_hz: tuple[float, float], source: str) -> None:
    """Refuse metrics on too few band-passed samples (a log too short for the band).

    Parameters
    ----------
    n_used : int
        Band-passed samples left after trimming the filter edges.
    fs_hz : float
        Sampling rate [Hz].
    band_hz : (float, float)
        The fitting band [Hz].
    source : str
        File name for the message.

    Raises
    ------
    InputError
        With fewer samples than one period of the band's lower edge (and fewer than 10).
    """
    need = max(10, int(np.ceil(fs_hz / band_hz[0])))
    if n_used < need:
        raise InputError(
            f"{source}: too short to measure the compensation: {n_used} sample(s) remain in"
            f" continuous stretches band-passed {band_hz[0]:g}-{band_hz[1]:g} Hz with the filter"
            f" edges trimmed, and the metrics need at least {need} ({need / fs_hz:.3g} s); give"
            " a longer log (or a higher low edge of band_hz)")


def metrics_dict(n_samples: int, before: float, after: float,
                 kept: tuple[float, float] | None, band_hz: tuple[float, float], *,
                 n_kept: int | None = None) -> CompensationMetrics:
    """The ``metrics`` block from band-passed standard deviations (in memory and chunked).

    Parameters
    ----------
    n_samples : int
        Samples the all-segment standard deviations were taken over.
    before, after : float
        Over all segments: std of band-passed ``mag`` and of band-passed ``mag - mag_tl`` [nT].
    kept : (float, float) or None
        The same over the kept segments (None: all segments are kept).
    band_hz : (float, float)
        The fitting band [Hz].
    n_kept : int, optional
        Samples of the kept segments (default ``n_samples``).

    Returns
    -------
    CompensationMetrics
        ``definition``; the headline over the kept segments: ``n_samples``,
        ``std_before_nT``, ``residual_std_nT``, ``improvement_ratio`` (before / after), also
        as ``kept_*``; beside them the same over all segments (``all_*``); ``band_hz``.
    """
    def ratio(b: float, a: float) -> float:
        return b / a if a > 0 else float("nan")

    kb, ka = kept if kept is not None else (before, after)
    return CompensationMetrics(
        definition=DEFINITION,
        n_samples=int(n_samples if n_kept is None else n_kept),
        std_before_nT=kb,
        residual_std_nT=ka,
        improvement_ratio=ratio(kb, ka),
        kept_std_before_nT=kb,
        kept_residual_std_nT=ka,
        kept_improvement_ratio=ratio(kb, ka),
        all_n_samples=int(n_samples),
        all_std_before_nT=before,
        all_residual_std_nT=after,
        all_improvement_ratio=ratio(before, after),
        band_hz=list(band_hz),
    )


#: Rows per block of :func:`residual_metrics` (whole stretches are added to a block until it
#: holds this many rows; a longer stretch is a block of its own).
BLOCK_ROWS = 1 << 16


def stretch_runs(time_s: np.ndarray, mag: np.ndarray, mag_tl: np.ndarray,
                 segment: np.ndarray, kept: np.ndarray, max_gap_s: float | None, *,
                 block_rows: int = BLOCK_ROWS) -> tuple[np.ndarray, np.ndarray]:
    """Runs of the stretches the compensation metrics of a compensated log are taken over.

    The runs of ``isolate_dropped(find_stretches(t, isfinite(mag - mag_tl), max_gap_s),
    segment, kept)`` (:func:`aeromag.compensation.apply.isolate_dropped`,
    :func:`aeromag._core.stretches.find_stretches`), found with boolean masks built in blocks
    of rows: no full-length label, difference or time-step array.

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Times [s].
    mag, mag_tl : ndarray, shape (n,)
        Total field and the model's interference [nT].
    segment : ndarray of int, shape (n,)
        Segment per sample (-1: none).
    kept : ndarray of bool, shape (n,)
        Samples of kept segments (each dropped segment is a stretch of its own).
    max_gap_s : float or None
        Largest time step inside a stretch [s] (None: 5 median time steps).
    block_rows : int
        Rows per block of the temporaries.

    Returns
    -------
    starts, stops : ndarray of int64
        Half-open ``[start, stop)`` row ranges of the stretches, in order.
    """
    t = np.asarray(time_s, dtype=np.float64)
    n = len(t)
    if n == 0:
        e = np.zeros(0, dtype=np.int64)
        return e, e
    if max_gap_s is None:
        max_gap_s = 5.0 * float(np.median(np.diff(t), overwrite_input=True))
    has = segment >= 0
    isolate = not kept[has].all()
    del has
    ok = np.empty(n, dtype=bool)
    start = np.empty(n, dtype=bool)  # first sample of a run
    for a in range(0, n, block_rows):
        b = min(n, a + block_rows)
        np.isfinite(np.subtract(mag[a:b], mag_tl[a:b]), out=ok[a:b])
    start[0] = ok[0]
    for a in range(1, n, block_rows):
        b = min(n, a + block_rows)
        # find_stretches: a sample continues its predecessor when both are valid and the
        # time step is at most max_gap_s
        cont = np.less_equal(np.subtract(t[a:b], t[a - 1:b - 1]), max_gap_s)
        cont &= ok[a - 1:b - 1]
        np.logical_not(cont, out=cont)
        cont &= ok[a:b]
        if isolate:  # isolate_dropped: a new run where the dropped segment changes
            s = segment[a - 1:b]
            dropped = np.where((s >= 0) & ~kept[a - 1:b], s, -1)
            cont |= (dropped[1:] != dropped[:-1]) & ok[a:b]
        start[a:b] = cont
    starts = np.flatnonzero(start)
    # a run stops before the next run's start or the next invalid sample
    stops = [np.flatnonzero(ok[a - 1:b - 1] & (start[a:b] | ~ok[a:b])) + a
             for a, b in ((a, min(n, a + block_rows)) for a in range(1, n, block_rows))]
    if ok[-1]:
        stops.append(np.array([n]))
    del ok, start
    stops_all = np.concatenate(stops) if stops else np.zeros(0, dtype=np.int64)
    return starts.astype(np.int64), stops_all.astype(np.int64)


def run_blocks(starts: np.ndarray, stops: np.ndarray, block_rows: int = BLOCK_ROWS,
               ) -> Iterator[tuple[int, int, np.ndarray]]:
    """Blocks of whole runs: ``(a, b, labels)`` with stretch labels of rows ``a:b``.

    Parameters
    ----------
    starts, stops : ndarray of int
        Runs in order (:func:`stretch_runs`).
    block_rows : int
        Runs are added to a block while it spans at most this many rows (a longer run is a
        block of its own).

    Yields
    ------
    a, b : int
        Rows of the block.
    labels : ndarray of int64, shape (b - a,)
        Run number per row of the block (-1 between runs), as
        :func:`aeromag._core.filters.filter_stretches` takes them.
    """
    i, k = 0, len(starts)
    while i < k:
        a = int(starts[i])
        j = int(np.searchsorted(stops, a + block_rows, side="right"))
        j = max(j, i + 1)
        b = int(stops[j - 1])
        lab = np.zeros(b - a, dtype=np.int64)
        lab[starts[i:j] - a] = 1
        np.cumsum(lab, out=lab)
        inrun = np.zeros(b - a + 1, dtype=np.int8)
        inrun[starts[i:j] - a] += 1
        inrun[stops[i:j] - a] -= 1
        np.cumsum(inrun, out=inrun)
        lab -= 1
        lab[inrun[:-1] == 0] = -1
        yield a, b, lab
        i = j


def residual_metrics(
    time_s: np.ndarray, mag: np.ndarray, mag_tl: np.ndarray, starts: np.ndarray,
    stops: np.ndarray, cfg: CompensationConfig, kept: np.ndarray, *, fs_hz: float,
    visit: Callable[[int, int, np.ndarray, np.ndarray], None] | None = None,
    source: str = "<log>", block_rows: int = BLOCK_ROWS,
) -> CompensationMetrics:
    """:func:`compensation_metrics` of ``mag`` and ``mag - mag_tl``, in blocks of stretches.

    The same figures, bit for bit, as ``compensation_metrics(mag, mag - mag_tl, t, stretch,
    cfg, kept=kept)`` with ``stretch`` the labels of the runs ``starts``/``stops``
    (:func:`stretch_runs`), without its full-length temporaries (the difference, the labels,
    both band-passed series and their masks): each block of whole stretches is band-passed on
    its own, and only the samples the metrics use are kept, packed, in ``mag``'s own buffer
    and one other.  ``mag`` is overwritten.

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Times [s].
    mag : ndarray of float64, shape (n,)
        Total field [nT]; **overwritten** (the caller's temporary).
    mag_tl : ndarray, shape (n,)
        The model's interference [nT] (float32 or float64).
    starts, stops : ndarray of int
        The stretches (:func:`stretch_runs`).
    cfg : CompensationConfig
        Band, order, trim.
    kept : ndarray of bool, shape (n,)
        Samples of kept segments.
    fs_hz : float
        Sampling rate [Hz] (:func:`aeromag._core.filters.sampling_rate` of ``time_s``).
    visit : callable, optional
        ``visit(a, b, after, labels)`` for each block, with ``after = mag - mag_tl`` of rows
        ``a:b`` [nT] and the block's stretch labels, before ``mag`` is overwritten there.
    source : str
        File name for messages.
    block_rows : int
        Rows per block (:func:`run_blocks`).

    Returns
    -------
    CompensationMetrics
        :func:`metrics_dict`, as :func:`compensation_metrics` returns it.

    Raises
    ------
    InputError
        Too few band-passed samples (:func:`require_samples`).
    """
    t = np.asarray(time_s, dtype=np.float64)
    n = len(t)
    sos = butter_sos("bandpass", cfg.band_hz, fs_hz, cfg.order)
    trim = (0.5 / cfg.band_hz[0]) if cfg.trim_s is None else cfg.trim_s
    use = np.zeros(n, dtype=bool)
    comp = np.empty(n)  # band-passed mag - mag_tl at the used samples, packed
    pos = 0
    for a, b, lab in run_blocks(starts, stops, block_rows):
        X = np.empty((2, b - a))
        X[0] = mag[a:b]
        np.subtract(mag[a:b], mag_tl[a:b], out=X[1])
        if visit is not None:
            visit(a, b, X[1], lab)
        Xf = filter_stretches(X, lab, sos, axis=1)
        del X
        ub = trim_mask(lab, t[a:b], trim)
        ub &= np.isfinite(Xf).all(axis=0)
        use[a:b] = ub
        k = int(ub.sum())
        # rows before a are consumed: the packed band-passed mag goes into mag's buffer
        mag[pos:pos + k] = Xf[0][ub]
        comp[pos:pos + k] = Xf[1][ub]
        pos += k
        del Xf, ub, lab
    require_samples(pos, fs_hz, cfg.band_hz, source)
    use_runs = _run_lengths(use)
    kin = kept_runs = None
    n_kept = pos
    if not kept.all():
        kin = kept[use]  # which packed samples are of kept segments
        np.logical_and(use, kept, out=use)  # use & kept
        kept_runs = _run_lengths(use)
        n_kept = int(kin.sum())
    del use
    mag_bp, comp_bp = mag[:pos], comp[:pos]
    # one stretch over the whole log: the filter returned views with a negative stride
    rev = (len(starts) == 1 and starts[0] == 0 and stops[0] == n
           and n >= min_filter_length(sos))
    if kept_runs is None:
        before = _packed_std(mag_bp, use_runs, rev)
        after = _packed_std(comp_bp, use_runs, rev)
        kept_std: tuple[float, float] | None = (before, after)
    else:
        kept_std = None
        if n_kept:
            kept_std = (_packed_std(mag_bp[kin], kept_runs, rev),
                        _packed_std(comp_bp[kin], kept_runs, rev))
        before = _packed_std(mag_bp, use_runs, rev)
        after = _packed_std(comp_bp, use_runs, rev)
    return metrics_dict(pos, before, after, kept_std, cfg.band_hz, n_kept=n_kept)


def _run_lengths(mask: np.ndarray) -> np.ndarray:
    """Lengths of the runs of True in ``mask``, in order (as :func:`masked_std` finds them)."""
    starts, stops = true_runs(mask)
    return stops - starts


def _packed_std(v: np.ndarray, lengths: np.ndarray, reversed_x: bool = False) -> float:
    """``masked_std(x, m)`` from ``v = x[m]`` and the lengths of ``m``'s runs; may overwrite ``v``.

    The same arithmetic as :func:`aeromag._core.moments.masked_std`: more than 1000 runs are
    ``np.std(x[m])`` (here computed in ``v``'s own buffer: the same sums in the same order as
    numpy's ``_var``, without its full-size temporary), fewer are summed run by run (the
    runs are ``v``'s consecutive slices).  ``reversed_x``: ``x`` was a view with a negative
    stride (what the filter returns for one stretch over the whole log), whose dot products
    numpy sums in another order than BLAS does: each run is then summed as such a view too.
    """
    cnt = int(lengths.sum())
    if cnt == 0:
        return float("nan")
    if len(lengths) > 1000:
        # numpy's _var: mean = sum / n; x = (a - mean) ** 2; sum(x) / n; then sqrt
        mean = np.add.reduce(v, keepdims=True)
        np.true_divide(mean, cnt, out=mean, casting="unsafe")
        np.subtract(v, mean, out=v)
        np.square(v, out=v)
        ret = np.add.reduce(v)
        return float(np.sqrt(ret.dtype.type(ret / np.intp(cnt))))
    ends = np.cumsum(lengths)
    bounds = zip((ends - lengths).tolist(), ends.tolist(), strict=True)
    runs = [v[a:b][::-1].copy()[::-1] if reversed_x else v[a:b] for a, b in bounds]
    mean = sum(float(r.sum()) for r in runs) / cnt
    s2 = sum(float(r @ r) for r in runs)
    if mean * mean > 1e-6 * s2 / cnt:  # far from zero mean: deviations, not raw squares
        return float(np.sqrt(sum(float(((r - mean) ** 2).sum()) for r in runs) / cnt))
    return float(np.sqrt(max(s2 / cnt - mean * mean, 0.0)))
