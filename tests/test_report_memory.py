"""Peak memory of the report's figures (issue 15 item 11): measured in a child process.

Each check runs in a fresh interpreter and reads its own ``VmHWM`` (Linux), so the numbers
are the child's alone; bounds have generous headroom (these are not timing tests).
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

pytestmark = pytest.mark.skipif(not Path("/proc/self/status").exists(),
                                reason="needs Linux /proc for the peak resident memory")


def _child_mb(code: str) -> dict[str, float]:
    """Run ``code`` in a fresh interpreter; it prints ``name value`` lines (MB)."""
    prelude = textwrap.dedent("""
        def _st(key):
            for line in open("/proc/self/status"):
                if line.startswith(key + ":"):
                    return int(line.split()[1]) / 1024
        def reset_peak():
            with open("/proc/self/clear_refs", "w") as fh:
                fh.write("5")
        def rss():
            return _st("VmRSS")
        def peak():
            return _st("VmHWM")
    """)
    p = subprocess.run([sys.executable, "-c", prelude + textwrap.dedent(code)],
                       capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr[-3000:]
    return {k: float(v) for k, v in (ln.split() for ln in p.stdout.splitlines() if ln)}


def test_png_of_a_long_noisy_line_stays_small() -> None:
    """A 2e6-sample band-passed residual (the envelope zigzags over the whole height in every
    pixel column) rendered in one Agg path kept a cell per pixel crossed: 165 MB above the
    figure on the benchmark log, 110 MB here.  Rendered in pieces (``agg.path.chunksize``)
    it is a few MB."""
    out = _child_mb("""
        import numpy as np
        from aeromag.plot import compensation as pc
        rng = np.random.default_rng(0)
        n = 2_000_000
        t = np.arange(n) * 0.1
        before = rng.standard_normal(n)
        after = 0.1 * rng.standard_normal(n)
        before[::300] = np.nan  # trimmed piece edges: the envelope breaks every 30 s
        after[::300] = np.nan
        fig = pc.plot_residuals(t, before, after, band_hz=(0.1, 0.9))
        del before, after
        import gc; gc.collect()
        base = rss()
        reset_peak()
        png = pc.figure_png(fig)
        print("png_peak", peak() - base)
        print("png_bytes", len(png) / 2**20)
    """)
    assert out["png_bytes"] > 0.01
    assert out["png_peak"] < 40, out  # 110 MB without the chunked rendering


def test_write_report_frees_each_figure(tmp_path: Path) -> None:
    """After the report, no figure (its Agg renderer) is left for the cyclic collector: the
    figures are reference cycles and their renderers held tens of MB each until a collection."""
    out = _child_mb(f"""
        import gc
        import numpy as np
        import aeromag.workflows.report as wr
        from aeromag.synthetic import simulate_calibration
        from aeromag.workflows.compensate import compensate_file
        df, _ = simulate_calibration(seed=3, n_boxes=1)
        df.to_csv({str(tmp_path / "cal.csv")!r}, index=False)
        compensate_file({str(tmp_path / "cal.csv")!r}, {str(tmp_path / "out.csv")!r})
        from matplotlib.figure import Figure
        gc.disable()  # only the report's own collections run
        seen = []
        real = wr.pc.figure_png
        def png(fig, *a, **k):
            seen.append(id(fig))
            return real(fig, *a, **k)
        wr.pc.figure_png = png
        wr.build_report({str(tmp_path / "out.csv")!r}, {str(tmp_path / "rep")!r})
        alive = sum(1 for o in gc.get_objects() if isinstance(o, Figure) and id(o) in seen)
        print("figures_drawn", len(seen))
        print("figures_alive", alive)
    """)
    assert out["figures_drawn"] >= 4
    assert out["figures_alive"] == 0, out


# --------------------------------------------------------------------------- the QC's steps
def _log(n: int = 300_000, ids_scale: int = 1):
    import numpy as np

    rng = np.random.default_rng(0)
    t = np.arange(n) * 0.1
    mag = 50000 + np.cumsum(rng.standard_normal(n)) * 0.01
    tl = rng.standard_normal(n)
    seg = np.repeat(np.arange(n // 3000 + 1), 3000)[:n] * ids_scale
    seg[:500] = -1
    return t, mag, tl, seg, seg % 7 != 0


@pytest.mark.parametrize("ids_scale", [1, 10**9])  # histogram path and np.unique path
def test_piece_residuals_per_segment_sums_unchanged(ids_scale: int) -> None:
    """The per-segment rms by histogram is bitwise the np.unique formulation it replaced."""
    import numpy as np

    from aeromag.qc.residuals import piece_residuals

    t, mag, tl, seg, kept = _log(ids_scale=ids_scale)
    r = piece_residuals(t, mag, tl, seg, kept, (0.1, 0.9), 4, fs_hz=10.0)
    ok = np.isfinite(r.after_bp) & (seg >= 0)
    ids, inv = np.unique(seg[ok], return_inverse=True)
    cnt = np.bincount(inv)
    ss = np.bincount(inv, r.after_bp[ok] ** 2)
    rows = list(zip(ids, ss, cnt, strict=True))
    assert r.by_segment == {int(i): float(np.sqrt(v / c)) for i, v, c in rows}
    assert r.n_by_segment == {int(i): int(c) for i, _, c in rows}


def test_piece_residuals_peak_per_row() -> None:
    """The band-passed pieces: rows written in place, inputs and labels let go once used
    (tracemalloc peak 131 bytes a row before, 85 now)."""
    import tracemalloc

    from aeromag.qc.residuals import piece_residuals

    t, mag, tl, seg, kept = _log(1_000_000)
    tracemalloc.start()
    try:
        piece_residuals(t, mag, tl, seg, kept, (0.1, 0.9), 4, fs_hz=10.0)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 105 * len(t), peak / len(t)


def test_qc_runs_the_fit_diagnostics_before_keeping_anything(monkeypatch) -> None:
    """The fit diagnostics (the QC's largest temporaries) run first, while the QC holds only
    its segment labels: they ran last, on top of the pieces and the manoeuvre labels (74
    bytes a row).  Same metrics."""
    import tracemalloc

    import aeromag.qc.quality as quality
    from aeromag.compensation.pipeline import compensate
    from aeromag.compensation.result import CompensationResult
    from aeromag.qc import compute_qc
    from aeromag.synthetic import simulate_calibration

    df, _ = simulate_calibration(seed=3, n_boxes=8)
    res = compensate(df)
    rebuilt = CompensationResult(res.data, res.model,
                                 {k: v for k, v in res.report.items() if k != "fit"},
                                 config=res.config)
    full = compute_qc(rebuilt).metrics
    assert full["fit"]["vif"]
    seen: dict[str, float] = {}
    real = quality.fit_diagnostics

    def spy(data, cfg, terms, **kw):
        seen["live"] = tracemalloc.get_traced_memory()[0] - seen["start"]
        return real(data, cfg, terms, **kw)

    monkeypatch.setattr(quality, "fit_diagnostics", spy)
    tracemalloc.start()
    try:
        seen["start"] = tracemalloc.get_traced_memory()[0]
        again = compute_qc(rebuilt).metrics
    finally:
        tracemalloc.stop()
    assert again == full
    assert seen["live"] < 20 * len(rebuilt.data), seen["live"] / len(rebuilt.data)


def test_band_passed_split_labels_in_place_unchanged() -> None:
    """band_passed's split labels built in place are the cumsum/where formulation's, so the
    band-passed samples (the FOM's) are bitwise the same; 27 -> 20 bytes a row of peak."""
    import tracemalloc

    import numpy as np

    from aeromag._core.filters import butter_sos, filter_stretches
    from aeromag._core.stretches import find_stretches
    from aeromag.qc.noise import band_passed

    t, mag, _, seg, kept = _log(1_000_000)
    mag[1000:1010] = np.nan
    split = np.where(kept, -1, seg)
    st = find_stretches(t, np.isfinite(mag), None)
    lab = np.cumsum(np.r_[True, (st[1:] != st[:-1]) | (split[1:] != split[:-1])]) - 1
    ref = filter_stretches(mag[None, :], np.where(st >= 0, lab, -1),
                           butter_sos("bandpass", (0.1, 0.9), 10.0, 4), axis=1)[0]
    tracemalloc.start()
    try:
        got = band_passed(mag, t, (0.1, 0.9), 4, split=split, fs_hz=10.0)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    np.testing.assert_array_equal(got, ref)
    assert peak < 23.5 * len(t), peak / len(t)
