"""Peak memory of the QC's steps (issue 15 item 11), measured with tracemalloc.

Each bound is in bytes per row of a generated calibration log, with headroom over what was
measured (not timing tests), and each change is checked bitwise against the formula it
replaced.
"""

from __future__ import annotations

import tracemalloc
import warnings

import numpy as np
import pandas as pd
import pytest

from aeromag._core.filters import sampling_rate
from aeromag._core.runs import run_bounds
from aeromag._core.stretches import find_stretches
from aeromag.qc import _blocks
from aeromag.qc import maneuvers as mv
from aeromag.synthetic import simulate_calibration


@pytest.fixture(scope="module")
def cal() -> pd.DataFrame:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        df, _ = simulate_calibration(seed=1, n_boxes=70)  # 210,000 rows at 10 Hz
    return df


def _peak(fn, *a, **kw):
    """(result, peak bytes, bytes still held) of ``fn(*a, **kw)`` under tracemalloc."""
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        out = fn(*a, **kw)
        cur, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return out, peak, cur


def test_detect_maneuvers_peak_and_labels_memory(cal):
    mv.detect_maneuvers(cal.iloc[:3000])  # imports and caches first
    res, peak, held = _peak(mv.detect_maneuvers, cal)
    n = len(cal)
    # Measured 63.5 B/row peak and 14.7 B/row held (was 94.9 and 41.7: int64 labels, the
    # frame's consolidated copies, full-length block-mean temporaries).
    assert peak / n < 75, f"detect_maneuvers peak {peak / n:.1f} B/row"
    assert held / n < 20, f"detect_maneuvers keeps {held / n:.1f} B/row"
    lab = res.labels
    assert lab["heading_leg"].dtype == np.int8
    for c in ("leg_id", "box", "maneuver_id"):
        assert lab[c].dtype == np.int32
    assert len(res.table) > 800


def _old_block_means(df, t, step, max_gap_s):
    """The block means before the chunked passes (full-length temporaries)."""
    n = len(t)
    s0, s1, _ = run_bounds(find_stretches(t, None, max_gap_s))
    nb = -(-(s1 - s0) // step)
    sid = np.repeat(np.arange(len(s0)), nb)
    off = np.cumsum(nb) - nb
    first = s0[sid] + step * (np.arange(int(nb.sum())) - off[sid])
    cnt = np.diff(np.r_[first, n])

    def mean(x):
        tot = np.add.reduceat(x, first, dtype=np.float64)
        if np.isfinite(tot).all():
            return tot / cnt
        fin = np.isfinite(x)
        k = np.add.reduceat(fin, first, dtype=np.float64)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(k > 0, np.add.reduceat(np.where(fin, x, 0), first,
                                                   dtype=np.float64) / k, np.nan)

    out = {"time": mean(t - t[0]) + t[0] + 1e6 * sid}
    for c in ("pitch", "roll", "flux_x", "flux_y", "flux_z"):
        if c in df.columns:
            x = df[c].to_numpy()
            out[c] = mean(x if x.dtype.kind == "f" else x.astype(np.float64))
    if "heading" in df.columns:
        h = df["heading"].to_numpy(dtype=np.float64)
        h0 = np.repeat(h[first], cnt)
        ref = np.where(np.isfinite(h0), h0, 0.0)
        d = h - ref
        d -= 360.0 * np.rint(d / 360.0)
        out["heading"] = (mean(d) + ref[first]) % 360.0
    return pd.DataFrame(out), cnt


@pytest.mark.parametrize("chunk", [7, 1000, 1 << 18])
def test_block_means_bitwise_as_before(cal, monkeypatch, chunk):
    monkeypatch.setattr(_blocks, "CHUNK", chunk)
    df = cal.iloc[:40_000].copy()
    for c in ("heading", "pitch", "flux_y"):
        df[c] = df[c].astype(np.float32)  # as the report reads them
    t = df["time"].to_numpy().copy()
    t[20_000:] += 30.0  # a gap
    df["time"] = t
    df.loc[df.index[[5, 6, 1234, 30_001]], ["heading", "flux_x"]] = np.nan
    df.loc[df.index[17], "roll"] = np.inf
    new, cnt = _blocks.block_means(df, t, 5, 0.5)
    old, cnt0 = _old_block_means(df, t, 5, 0.5)
    np.testing.assert_array_equal(cnt, cnt0)
    # With a usable attitude the detection never reads the fluxgate: its means are not made.
    assert set(old.columns) - set(new.columns) == {"flux_x", "flux_y", "flux_z"}
    pd.testing.assert_frame_equal(new, old[list(new.columns)], check_exact=True)
    # Without one (attitude mostly missing) the fluxgate's means are made, bitwise as before.
    df[["pitch", "roll"]] = np.nan
    new, cnt = _blocks.block_means(df, t, 5, 0.5)
    old, cnt0 = _old_block_means(df, t, 5, 0.5)
    np.testing.assert_array_equal(cnt, cnt0)
    assert set(new.columns) == set(old.columns)
    pd.testing.assert_frame_equal(new, old[list(new.columns)], check_exact=True)


def test_gap_runs_equal_find_stretches(monkeypatch):
    rng = np.random.default_rng(0)
    for n in (1, 2, 5, 100, 5000):
        for chunk in (3, 7, 1 << 18):
            monkeypatch.setattr(_blocks, "CHUNK", chunk)
            t = np.cumsum(rng.choice([0.1, 0.1, 0.1, 2.0], size=n))
            if n > 3:
                t[n // 2] = np.nan
            a = run_bounds(find_stretches(t, None, 0.5))[:2]
            b = _blocks._gap_runs(t, 0.5)
            for x, y in zip(a, b, strict=True):
                np.testing.assert_array_equal(x, y)


def test_labels_values_as_int64_detection(cal):
    """The narrow labels hold the values of the int64 ones the detection builds."""
    df = cal.iloc[:60_000]
    res = mv.detect_maneuvers(df, rate_hz=None)
    full = mv._detect_full(df, maneuver_column=None, leg_column=None, source="x",
                           min_leg_s=20.0, min_maneuver_s=10.0, window_s=4.0,
                           highpass_hz=0.04, min_rms_deg=1.0, ambiguity_cos=0.95,
                           smooth_s=10.0, tolerance_deg=15.0, declination_deg=0.0,
                           max_gap_s=None)
    assert full.labels["leg_id"].dtype == np.int64  # the helper's own labels
    t = df["time"].to_numpy()
    full = mv.clip_to_lines(full, df["line"], t, sampling_rate(t))
    for c in ("heading_leg", "leg_id", "box", "maneuver_id"):
        assert res.labels[c].dtype == mv.LABEL_DTYPES[c]
        np.testing.assert_array_equal(res.labels[c].to_numpy(), full.labels[c].to_numpy())
    assert (res.labels["maneuver"] == full.labels["maneuver"]).all()
    pd.testing.assert_frame_equal(res.table, full.table, check_exact=True)


@pytest.fixture(scope="module")
def compensated(cal):
    from aeromag.compensation.pipeline import run_compensation as compensate

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = compensate(cal, source="cal.csv")
    return res


def test_fom_table_peak_memory(compensated):
    from aeromag.qc.fom import fom_table

    data, cfg = compensated.data, compensated.config
    man = mv.detect_maneuvers(data, max_gap_s=cfg.max_gap_s)
    kw = dict(band_hz=cfg.band_hz, order=cfg.order, max_gap_s=cfg.max_gap_s)
    fom_table(data.iloc[:5000], mv.detect_maneuvers(data.iloc[:5000]), **kw)  # warm-up
    tab, peak, _ = _peak(fom_table, data, man, **kw)
    n = len(data)
    # Measured 48.0 B/row (was 68.0: the NaN-padded copy of each band-passed field,
    # int64 dropped-segment labels, every field made up front and the last one kept).
    assert peak / n < 56, f"fom_table peak {peak / n:.1f} B/row"
    assert len(tab) > 800 and tab["ptp_after_nT"].notna().all()


def test_fit_diagnostics_prepares_no_heading_and_same_result(compensated, monkeypatch):
    """prepare gets no heading (no float64 copy of it while the normal equations are built),
    the stretch labels are int32 there, and the diagnostics are those of the old formula.

    A tracemalloc bound is no use here: the normal equations filter on the thread pool, and
    the peak at 210,000 rows varied 290-340 B/row with the threads' timing (the old code
    348).  At 2e6 rows the step's peak went 165 -> 149 -> 131 MB.
    """
    from aeromag.compensation.normal import segment_normal_equations
    from aeromag.qc import diagnostics as dg
    from aeromag.qc.labels import kept_mask, segment_labels

    data = compensated.data.copy()
    for c in ("heading", "pitch", "roll", "flux_x", "flux_y", "flux_z"):
        data[c] = data[c].astype(np.float32)  # as the report reads them
    cfg, terms = compensated.config, tuple(compensated.report.terms)
    seg = segment_labels(data)
    seen: list[list[str]] = []
    orig_prepare = dg.prepare

    def spy(df, *a, **kw):
        seen.append(list(df.columns))
        return orig_prepare(df, *a, **kw)

    monkeypatch.setattr(dg, "prepare", spy)
    stretch_dtypes: list[np.dtype] = []
    orig_normal = dg.segment_normal_equations

    def spy_normal(prep, *a, **kw):
        stretch_dtypes.append(prep.stretch.dtype)
        return orig_normal(prep, *a, **kw)

    monkeypatch.setattr(dg, "segment_normal_equations", spy_normal)
    diag, cv = dg.fit_diagnostics(data, cfg, terms, seg=seg)
    assert seen and "heading" not in seen[0] and "flux_x" in seen[0]
    assert stretch_dtypes == [np.int32]  # half the int64 labels while the sums are built
    # the old formula: prepare on the log with its heading
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        prep = orig_prepare(data.drop(columns=["mag_tl", "mag_comp"]), cfg)
    assert prep.heading_deg is not None
    prep.segment = seg
    fit_terms = tuple(x for x in terms if x != "bias")
    stats = segment_normal_equations(prep, fit_terms, cfg)
    kept = np.isin(stats.ids, np.unique(seg[kept_mask(data) & (seg >= 0)]))
    d0, cv0 = dg.diagnostics_from_stats(stats, kept, fit_terms, cfg.ridge)
    assert d0 == diag
    pd.testing.assert_frame_equal(cv0, cv, check_exact=True)


def _old_grouped_std(x, groups):
    """grouped_std before its squares went in place."""
    g = np.asarray(groups)
    ok = np.isfinite(x) & (g >= 0)
    if not ok.any():
        return {}
    if ok.all():
        gk, xk = g.astype(np.int64, copy=False), np.asarray(x)
    else:
        gk = g[ok].astype(np.int64, copy=False)
        xk = x[ok]
    top = int(gk.max())
    if top <= 4 * gk.size + 1024:
        n = np.bincount(gk, minlength=top + 1)
        ids = np.flatnonzero(n)
        s1 = np.bincount(gk, xk, minlength=top + 1)[ids]
        s2 = np.bincount(gk, xk * xk, minlength=top + 1)[ids]
        n = n[ids]
    else:
        ids, inv = np.unique(gk, return_inverse=True)
        n = np.bincount(inv)
        s1 = np.bincount(inv, xk)
        s2 = np.bincount(inv, xk * xk)
    mean = s1 / n
    std = np.sqrt(np.maximum(s2 / n - mean * mean, 0.0))
    return {int(i): float(s) for i, s in zip(ids, std, strict=True)}


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_grouped_std_squares_in_place(dtype):
    from aeromag.qc.noise import grouped_std

    rng = np.random.default_rng(2)
    n = 400_000
    x = rng.normal(size=n).astype(dtype)
    x[::97] = np.nan  # the copying path
    heading = rng.integers(-1, 4, size=n).astype(np.int8)  # heading legs, as the QC passes
    sparse = np.where(heading >= 0, heading.astype(np.int64) * 10**7, -1)  # the unique path
    for g in (heading, sparse):
        assert grouped_std(x, g) == _old_grouped_std(x, g)
    clean = rng.normal(size=n)
    assert grouped_std(clean, heading) == _old_grouped_std(clean, heading)
    grouped_std(x[:1000], heading[:1000])
    _, peak, _ = _peak(grouped_std, x, heading)
    # Measured 13.7 B/row (float64; was 20.0: a second full-length array for the squares).
    if dtype == np.float64:
        assert peak / n < 17, f"grouped_std peak {peak / n:.1f} B/row"
