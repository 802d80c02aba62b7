"""Apply a saved model to a log too large for memory, chunk by chunk, file to file.

:func:`apply_model_chunked` gives the output of ``compensate_file(..., model=...)`` (same
columns, same values to float rounding, same report keys) while holding only about
``chunk_rows + 2 * overlap`` rows at a time:

1. a scan of ``time`` (and ``line``) finds the global sampling rate (median time step, from
   the distinct time steps and their counts) and checks that time increases;
2. a scan of ``time``, fluxgate and ``mag`` finds the continuous stretches (their start and end
   times: segment windows and filter-edge trimming depend on them);
3. the apply pass reads windows of ``chunk_rows`` rows plus ``overlap`` rows on each side,
   computes ``mag_tl`` (time derivatives need one neighbour), the zero-phase low-pass of
   ``mag_comp`` and the band-passed metrics, and writes only the window's core.

Why it is exact: the IIR filters are run forward and backward over each window; a window's
edge perturbs the result by at most ``r**overlap`` times the signal, where ``r`` is the largest
pole radius of the filters, and ``overlap`` is chosen so that this is below 1e-18 (see
:func:`overlap_rows`).  Where a stretch starts or ends inside a window, the filter sees the
very same edge as the in-memory run.  Metrics are accumulated with Chan's parallel variance.

CSV (pyarrow streaming reader) and Parquet (row groups) are streamed; other formats are read
whole and then processed in chunks.
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd

from .._core.filters import butter_sos, filter_stretches, min_filter_length, trim_mask
from .._core.moments import StreamingMoments
from .._core.stretches import find_stretches, interpolate_short_gaps
from ..compensation.apply import missing_total_field
from ..compensation.checks import check_metrics
from ..compensation.config import CompensationConfig
from ..compensation.metrics import metrics_dict, require_samples
from ..compensation.model import TLModel
from ..compensation.prepare import (
    check_field_scale,
    check_total_field,
    total_field_from_fluxgate,
)
from ..compensation.report import AppliedRun, applied_report
from ..compensation.report_types import ChunkSettings, CompensationMetrics, CompensationReport
from ..errors import InputError
from ..io import (
    FLUX_COLUMNS,
    atomic_path,
    csv_header,
    floats_as_pandas_text,
    json_path_for,
    plain_number,
    write_arrow_csv,
)
from ..io.formats import output_format
from ..io.log import duplicates_warning
from ..io.messages import check_input_file
from ..io.stream import duplicate_rows, iter_log_batches, locate_row
from ..qc.quality import QCMetrics
from ..qc.residuals import piece_labels
from .compensate import check_outputs, write_report_json

log = logging.getLogger(__name__)

DEFAULT_CHUNK_ROWS = 1_000_000


# --------------------------------------------------------------------------- reading
def _windows(batches: Iterator[pd.DataFrame], chunk_rows: int, overlap: int
             ) -> Iterator[tuple[pd.DataFrame, int, int, int]]:
    """Yield ``(window, core_start, core_stop, first_row)`` with ``overlap`` rows each side."""
    buf: list[pd.DataFrame] = []
    buf_rows = 0
    buf_start = 0  # global row index of buf's first row
    emit = 0  # global row index of the next row to emit
    eof = False
    it = iter(batches)
    while True:
        while not eof and buf_rows - (emit - buf_start) < chunk_rows + overlap:
            try:
                b = next(it)
            except StopIteration:
                eof = True
                break
            if len(b):
                buf.append(b)
                buf_rows += len(b)
        if buf_rows - (emit - buf_start) <= 0:
            return
        win = pd.concat(buf, ignore_index=True) if len(buf) > 1 else buf[0]
        buf = [win]
        a = emit - buf_start
        stop = buf_rows if eof else min(a + chunk_rows, buf_rows - overlap)
        yield win, a, stop, buf_start
        emit = buf_start + stop
        drop = max(0, stop - overlap)
        if drop:
            buf = [win.iloc[drop:].reset_index(drop=True)]
            buf_rows -= drop
            buf_start += drop
        if eof and emit >= buf_start + buf_rows:
            return


# --------------------------------------------------------------------------- helpers
def overlap_rows(fs_hz: float, cfg: CompensationConfig, *, eps: float = 1e-18) -> int:
    """Rows of context on each side of a chunk so that chunked results equal in-memory ones.

    Parameters
    ----------
    fs_hz : float
        Sampling rate [Hz].
    cfg : CompensationConfig
        Band, low-pass and order of the filters; ``max_interp_s`` of the gap interpolation.
    eps : float
        Largest relative effect of a window edge on a core sample.

    Returns
    -------
    int
        ``ceil(log(eps) / log(r))`` for the slowest filter pole radius ``r``, times 1.5 for
        the polynomial factor of repeated poles, plus the filters' edge padding and the
        longest interpolated gap.
    """
    cut = cfg.lowpass_hz if cfg.lowpass_hz is not None else cfg.band_hz[1]
    n = 0
    for sos in (butter_sos("bandpass", cfg.band_hz, fs_hz, cfg.order),
                butter_sos("lowpass", cut, fs_hz, cfg.order, option="lowpass_hz")):
        r = max(float(np.max(np.abs(np.roots(s[3:])))) for s in sos)
        decay = math.ceil(math.log(eps) / math.log(r)) if 0 < r < 1 else 10_000
        n = max(n, int(1.5 * decay) + min_filter_length(sos))
    return n + int(math.ceil(cfg.max_interp_s * fs_hz)) + 8


# --------------------------------------------------------------------------- main
def apply_model_chunked(
    in_path: str | os.PathLike[str], out_path: str | os.PathLike[str],
    model: TLModel | str | os.PathLike[str], cfg: CompensationConfig | None = None, *,
    chunk_rows: int = DEFAULT_CHUNK_ROWS, columns: dict[str, str] | None = None,
    units: dict[str, str] | None = None, fmt: str | None = None,
) -> CompensationReport:
    """Apply a saved model chunk by chunk; write ``OUT.csv`` and ``OUT.json`` atomically.

    Parameters
    ----------
    in_path : path-like
        Input log (CSV or Parquet streamed; other formats read whole).
    out_path : path-like
        Output CSV; the report goes to the same name with ``.json``.
    model : TLModel or path-like
        The saved model.
    cfg : CompensationConfig, optional
        Options (as for ``compensate_file``).
    chunk_rows : int
        Rows written per chunk; memory is about ``chunk_rows + 2 * overlap_rows`` rows.
    columns, units : dict, optional
        Column map and unit conversions.
    fmt : str, optional
        Input format.

    Returns
    -------
    CompensationReport
        The report written to ``OUT.json`` (interface.md keys, plus ``n_rows`` and
        ``chunked``: chunk and overlap rows).
    """
    cfg = cfg or CompensationConfig()
    src = Path(in_path)
    source = str(src)
    check_input_file(src)  # a FIFO, folder or link loop: one line, never a hang
    check_outputs(src, out_path, json_path_for(Path(out_path)))
    if output_format(out_path) != "csv":
        raise InputError(f"{out_path}: the chunked mode (chunk_rows=) writes CSV, streamed chunk"
                         " by chunk; give an output ending in .csv, or apply the model without"
                         " chunk_rows for Parquet or XYZ")
    if chunk_rows < 1:
        raise InputError(f"chunk_rows={chunk_rows}: must be a positive row count")
    if not isinstance(model, TLModel):
        mpath = Path(model)
        model = TLModel.load(mpath)
        model.meta.path = str(mpath)
    if model.extended is not None:  # extras, an intercept or a network: the whole-log path
        raise InputError(f"{model.meta.path or 'the model'}: a model with --extra or "
                         "--reference is applied to the whole log: drop --chunk-rows")
    colmap = dict(columns or {})

    drop = np.zeros(0, dtype=np.int64)  # exact duplicate rows, found in pass 1

    def batches(names: list[str] | None = None, batch_rows: int = 250_000
                ) -> Iterator[pd.DataFrame]:
        """Canonical, validated batches: io's one reading path, as read_log (issue 16)."""
        return iter_log_batches(src, fmt, names, colmap=colmap, units=units, drop=drop,
                                batch_rows=batch_rows)

    # ---- pass 1: time steps, line values, row count
    first = next(batches(batch_rows=2), None)
    if first is None or len(first) == 0:
        raise InputError(f"{source}: no data rows")
    present = set(first.columns)
    missing = [c for c in ("time", *FLUX_COLUMNS) if c not in present]
    if missing:
        raise InputError(f"{source}: missing column(s) {', '.join(missing)}; map them with"
                         " columns={'NAME': 'SOURCE'}")
    has_mag = not total_field_from_fluxgate(first, cfg, source)
    check_total_field(model, not has_mag, source)
    has_line = "line" in present
    steps: dict[float, int] = {}
    lines: set[float] = set()
    n_rows = 0
    prev_t = None
    same_t: list[np.ndarray] = []  # rows whose time equals the previous row's
    same_v: list[np.ndarray] = []  # and that time
    for b in batches(["time", *(["line"] if has_line else [])]):
        t = b["time"].to_numpy(np.float64)
        tt = t if prev_t is None else np.r_[prev_t, t]
        dt = np.diff(tt)
        back = 0 if prev_t is None else 1
        if (dt < 0).any():
            i = int(np.flatnonzero(dt < 0)[0])
            where = locate_row(src, fmt, n_rows + i - back + 1)
            raise InputError(f"{source}: column 'time', {where}: time {plain_number(tt[i + 1])}"
                             f" is not after {plain_number(tt[i])}; time must be strictly"
                             " increasing (sort the log or fix the row)")
        if (dt == 0).any():
            same_t.append(n_rows + np.flatnonzero(dt == 0) + 1 - back)
            same_v.append(tt[np.flatnonzero(dt == 0) + 1])
            dt = dt[dt != 0]
        u, c = np.unique(dt, return_counts=True)
        for v, k in zip(u.tolist(), c.tolist(), strict=True):
            steps[v] = steps.get(v, 0) + k
        if has_line:
            ln = b["line"].to_numpy(np.float64)
            lines.update(np.unique(ln[np.isfinite(ln)]).tolist())
        prev_t = t[-1:] if len(t) else prev_t
        n_rows += len(t)
    if same_t:
        cand = np.concatenate(same_t)
        dup = duplicate_rows(src, fmt, cand, colmap=colmap, units=units)
        other = np.setdiff1d(cand, dup)
        if other.size:
            i = int(other[0])
            t_i = plain_number(np.concatenate(same_v)[int(np.searchsorted(cand, i))])
            raise InputError(f"{source}: column 'time', {locate_row(src, fmt, i)}: time {t_i}"
                             f" is not after {t_i}; time must be strictly increasing (sort the"
                             " log or fix the row)")
        log.warning("%s", duplicates_warning(source, int(dup.size),
                                             locate_row(src, fmt, int(dup[0]))))
        drop = dup
        n_rows -= int(dup.size)
    if n_rows < 2:
        raise InputError(f"{source}: only {n_rows} data row(s); need at least 2")
    med = _median_from_counts(steps)
    fs = 1.0 / med
    max_gap = cfg.max_gap_s if cfg.max_gap_s is not None else 5.0 * med
    line_codes = None
    if has_line and lines:
        vals = np.array(sorted(lines))
        if not np.all(vals == np.round(vals)):
            line_codes = vals
    # The QC trims each piece's ends: a window's edge (not a piece end) must stay in its overlap.
    qc_trim = 0.25 / cfg.band_hz[0] if cfg.trim_s is None else float(cfg.trim_s)
    overlap = max(overlap_rows(fs, cfg), int(math.ceil(2 * qc_trim * fs)) + 1)
    need = ["time", *FLUX_COLUMNS, *(["mag"] if has_mag else [])]

    def arrays(w: pd.DataFrame) -> dict[str, np.ndarray]:
        t = w["time"].to_numpy(np.float64)
        flux = np.empty((len(t), 3))
        for j, c in enumerate(FLUX_COLUMNS):
            flux[:, j], _ = interpolate_short_gaps(w[c].to_numpy(np.float64), t,
                                                   cfg.max_interp_s)
        if has_mag:
            mag, _ = interpolate_short_gaps(w["mag"].to_numpy(np.float64), t, cfg.max_interp_s)
        else:
            mag = np.sqrt(np.einsum("ij,ij->i", flux, flux))
        ok = np.all(np.isfinite(flux), axis=1)
        f0 = np.where(ok[:, None], flux, 0.0)
        ok &= np.einsum("ij,ij->i", f0, f0) > 0
        return {"t": t, "flux": flux, "mag": mag, "flux_ok": ok, "valid": ok & np.isfinite(mag)}

    # ---- pass 2: stretch start / end times
    s_start: list[np.ndarray] = []
    s_end: list[np.ndarray] = []
    for w, a, b, _ in _windows(batches(need), chunk_rows, overlap):
        ar = arrays(w)
        if not s_start:  # the level checks of prepare(), on the first window
            bt = np.sqrt(np.einsum("ij,ij->i", ar["flux"], ar["flux"]))
            check_field_scale(source, bt, ar["mag"] if has_mag else None)
        st = find_stretches(ar["t"], ar["valid"], max_gap)
        starts = (st >= 0) & np.r_[True, st[1:] != st[:-1]]
        ends = (st >= 0) & np.r_[st[1:] != st[:-1], True]
        s_start.append(ar["t"][a:b][starts[a:b]])
        s_end.append(ar["t"][a:b][ends[a:b]])
    t0s = np.concatenate(s_start) if s_start else np.zeros(0)
    t1s = np.concatenate(s_end) if s_end else np.zeros(0)
    if len(t0s) == 0:
        raise InputError(f"{source}: columns flux_x/flux_y/flux_z/mag hold no usable sample")
    dur = np.maximum(t1s - t0s, 0.0)
    nwin = np.maximum(1, np.round(dur / cfg.segment_seconds)).astype(np.int64)
    width = np.where(dur > 0, dur / nwin, 1.0)
    offset = np.r_[0, np.cumsum(nwin)[:-1]]

    # ---- pass 3: apply and write
    cut = cfg.lowpass_hz if cfg.lowpass_hz is not None else cfg.band_hz[1]
    sos_low = butter_sos("lowpass", cut, fs, cfg.order, option="lowpass_hz")
    sos_band = butter_sos("bandpass", cfg.band_hz, fs, cfg.order)
    trim = (0.5 / cfg.band_hz[0]) if cfg.trim_s is None else cfg.trim_s
    m_use, m_kept = StreamingMoments(), StreamingMoments()
    # Fourth differences of mag and of mag - mag_tl (the QC noise levels), by first sample.
    d4_before = StreamingMoments(mean=np.zeros(1), m2=np.zeros(1))
    d4_after = StreamingMoments(mean=np.zeros(1), m2=np.zeros(1))
    seg_n: dict[int, int] = {}
    seg_stats: dict[int, np.ndarray] = {}
    q_sums = {"all": np.zeros(3), "seg": np.zeros(3)}  # n, sum before^2, sum after^2
    out_csv = Path(out_path)
    header_written = False
    n_no_mag = 0
    import pyarrow as pa

    with atomic_path(out_csv) as tmp, open(tmp, "wb") as fh:
        for w, a, b, _ in _windows(batches(), chunk_rows, overlap):
            ar = arrays(w)
            t = ar["t"]
            st = find_stretches(t, ar["valid"], max_gap)
            fst = find_stretches(t, ar["flux_ok"], max_gap)
            mag_tl = np.full(len(t), np.nan)
            okf = fst >= 0
            mag_tl[okf] = model.predict(ar["flux"][okf], t[okf], fst[okf])
            comp = ar["mag"] - mag_tl
            gid = np.searchsorted(t0s, t, side="right") - 1
            seg = np.full(len(t), -1, dtype=np.int64)
            if has_line:
                ln = w["line"].to_numpy(np.float64)
                okl = np.isfinite(ln) & (st >= 0)
                if line_codes is None:
                    seg[okl] = ln[okl].astype(np.int64)
                else:
                    seg[okl] = np.searchsorted(line_codes, ln[okl])
            else:
                v = st >= 0
                g = gid[v]
                win = np.minimum(((t[v] - t0s[g]) / width[g]).astype(np.int64), nwin[g] - 1)
                seg[v] = offset[g] + win
            if cfg.filter_output:
                comp_out = filter_stretches(comp[None, :], st, sos_low, axis=1)[0]
                fill = np.isnan(comp_out) & (st >= 0)
                comp_out[fill] = comp[fill]
            else:
                comp_out = comp
            # metrics on band-passed mag and mag - mag_tl (compensation_metrics, streamed)
            st2 = find_stretches(t, np.isfinite(comp) & (st >= 0), max_gap)
            Xf = filter_stretches(np.vstack([ar["mag"], comp]), st2, sos_band, axis=1)
            core = slice(a, b)
            fin = np.all(np.isfinite(Xf), axis=0)
            g2 = np.clip(gid, 0, len(t0s) - 1)
            inner = (st2 >= 0) & (t - t0s[g2] >= trim) & (t1s[g2] - t >= trim)
            use = inner & fin
            kept = np.ones(len(seg), dtype=bool)  # a saved model: every sample is kept
            Xc = Xf[:, core]
            # As compute_qc: the mag column as read (gaps not interpolated).
            if has_mag:
                raw_mag = w["mag"].to_numpy(np.float64)
            else:
                fl = w[list(FLUX_COLUMNS)].to_numpy(np.float64)
                raw_mag = np.sqrt(np.einsum("ij,ij->i", fl, fl))
            for mom, x in ((d4_before, raw_mag), (d4_after, raw_mag - mag_tl)):
                mom.add(_fourth_differences(x, t, max_gap, a, b)[None, :])
            m_use.add(Xc[:, use[core]])
            m_kept.add(Xc[:, (use & kept)[core]])
            sc = seg[core]
            ids, cnt = np.unique(sc[sc >= 0], return_counts=True)
            for i, c in zip(ids.tolist(), cnt.tolist(), strict=True):
                seg_n[i] = seg_n.get(i, 0) + c
            # The QC residuals as aeromag.qc.piece_residuals: mag and mag - mag_tl band-passed
            # per piece (one segment in one stretch), trimmed at the piece's ends; a window's
            # edge is not a piece end, and the overlap (> trim) keeps its trim out of the core.
            qx = np.vstack([raw_mag, raw_mag - mag_tl])
            lab = piece_labels(t, np.isfinite(qx).all(axis=0), seg, max_gap)
            qf = filter_stretches(qx, lab, sos_band, axis=1)
            quse = (trim_mask(lab, t, qc_trim) & np.isfinite(qf).all(axis=0))[core]
            qf = qf[:, core]
            qseg = quse & (sc >= 0)
            for key, m in (("all", quse), ("seg", qseg)):
                q_sums[key] += [m.sum(), np.sum(qf[0, m] ** 2), np.sum(qf[1, m] ** 2)]
            if qseg.any():
                gi, ginv = np.unique(sc[qseg], return_inverse=True)
                acc = np.vstack([np.bincount(ginv), np.bincount(ginv, qf[1, qseg] ** 2)])
                for j, i in enumerate(gi.tolist()):
                    seg_stats[i] = seg_stats.get(i, np.zeros(2)) + acc[:, j]
            no_mag = missing_total_field(w, not has_mag)  # mag_comp empty there, as in memory
            if no_mag is not None:
                comp_out = np.where(no_mag, np.nan, comp_out)
                n_no_mag += int(no_mag[core].sum())
            out = w.iloc[a:b].copy()
            out["mag_tl"] = mag_tl[core]
            out["mag_comp"] = comp_out[core]
            out["segment"] = pd.array(np.where(sc >= 0, sc, 0), dtype="Int64")
            out.loc[sc < 0, "segment"] = pd.NA
            out["segment_kept"] = kept[core]
            for c in ("line", "leg"):
                # Read as float (a chunk may hold gaps); written as the integers they are.
                if c in out.columns and out[c].dtype.kind == "f":
                    v = out[c].to_numpy()
                    fin = np.isfinite(v)
                    if np.all(v[fin] == np.round(v[fin])):
                        out[c] = pd.arrays.IntegerArray(np.where(fin, v, 0).astype(np.int64),
                                                        ~fin)
            table = floats_as_pandas_text(pa.Table.from_pandas(out, preserve_index=False))
            if not header_written:
                fh.write(csv_header(out.columns).encode("utf-8"))
                header_written = True
            pos = fh.tell()
            try:
                write_arrow_csv(table, fh, "none")
            except pa.ArrowInvalid:  # a string needs quoting
                fh.seek(pos)
                fh.truncate()
                write_arrow_csv(table, fh, "needed")
        fh.flush()
        metrics = _metrics(m_use, m_kept, cfg, fs, source)
        metrics.n_rows_without_mag = n_no_mag
        check_metrics(metrics, source=source)
        residual = {i: float(np.sqrt(s[1] / s[0])) for i, s in seg_stats.items()}
        qc = _qc_block(metrics, residual, q_sums if seg_n else {**q_sums, "seg": q_sums["all"]},
                       d4_before, d4_after, cfg, qc_trim)
        report = applied_report(AppliedRun(
            source, model, cfg, fs, {int(i): int(n) for i, n in seg_n.items()}, metrics,
            residual, qc, n_rows=n_rows, chunked=ChunkSettings(int(chunk_rows), int(overlap))))
        write_report_json(report, json_path_for(out_csv))
    return report


def _fourth_differences(x: np.ndarray, t: np.ndarray, max_gap_s: float, a: int, b: int
                        ) -> np.ndarray:
    """Fourth differences starting at rows ``a..b-1`` of a window.

    Inside continuous finite stretches only, as :func:`aeromag.qc.fourth_difference_noise`
    counts them.
    """
    st = find_stretches(t, np.isfinite(x), max_gap_s)
    stop = min(b, len(x) - 4)
    if stop <= a:
        return np.zeros(0)
    seg = x[a:stop + 4]
    d4 = np.diff(np.where(np.isfinite(seg), seg, 0.0), n=4)
    same = (st[a + 4:stop + 4] == st[a:stop]) & (st[a:stop] >= 0)
    return d4[same]


def _qc_block(metrics: CompensationMetrics, residual: dict[int, float],
              sums: dict[str, np.ndarray], d4_before: StreamingMoments,
              d4_after: StreamingMoments, cfg: CompensationConfig, trim_s: float
              ) -> QCMetrics:
    """The report's ``qc`` block, as :func:`aeromag.qc.compute_qc` gives it for a saved model."""
    from ..qc import FOURTH_DIFF_NORM
    from ..qc.fom import fom_not_applicable
    from ..qc.quality import QC_SKIPPED_FOM, QC_SKIPPED_NOTE, headline_metrics
    from ..qc.residuals import rms_summary
    from ..qc.summaries import NoiseSummary

    def noise(m: StreamingMoments) -> float:
        return float(m.std()[0] / FOURTH_DIFF_NORM) if m.n else float("nan")

    every, kept = rms_summary(*sums["all"]), rms_summary(*sums["seg"])
    return QCMetrics(
        list(cfg.band_hz),
        **headline_metrics(metrics, kept, every, trim_s),  # the headline is OUT.json metrics
        compensation_metrics=metrics,
        residual_std_by_segment_nT={str(k): v for k, v in sorted(residual.items())},
        noise=NoiseSummary(
            band_hz=list(cfg.band_hz),
            band_std_before_nT=metrics.all_std_before_nT,
            band_std_after_nT=metrics.all_residual_std_nT,
            fourth_difference_before_nT=noise(d4_before),
            fourth_difference_after_nT=noise(d4_after),
        ),
        fom=fom_not_applicable(QC_SKIPPED_FOM),
        notes=[QC_SKIPPED_NOTE],
    )


def _median_from_counts(counts: dict[float, int]) -> float:
    """``np.median`` of a multiset given as ``{value: count}`` (mean of the two middles)."""
    vals = np.array(sorted(counts))
    cum = np.cumsum([counts[v] for v in vals])
    n = int(cum[-1])
    lo = vals[np.searchsorted(cum, (n - 1) // 2 + 1)]
    hi = vals[np.searchsorted(cum, n // 2 + 1)]
    return float(lo) if n % 2 else float(np.mean([lo, hi]))


def _metrics(use: StreamingMoments, kept: StreamingMoments, cfg: CompensationConfig,
             fs_hz: float, source: str) -> CompensationMetrics:
    """The metrics of :func:`aeromag.compensation.metrics.compensation_metrics` from moments."""
    require_samples(use.n, fs_hz, cfg.band_hz, source)
    before, after = (float(x) for x in use.std())
    kept_std = None
    if kept.n and kept.n != use.n:
        b2, a2 = (float(x) for x in kept.std())
        kept_std = (b2, a2)
    return metrics_dict(use.n, before, after, kept_std, cfg.band_hz, n_kept=kept.n)
