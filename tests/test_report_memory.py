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
