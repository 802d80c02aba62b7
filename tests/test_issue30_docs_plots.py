"""Issue 30: the PCA score plot's legend hides no segment; docs/formats.md names every
registered format and no longer says Parquet needs an extra."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]


def test_the_pca_legend_is_outside_the_axes_and_hides_no_segment():
    import aeromag as am
    from aeromag.plot.compensation import plot_pca_scores

    res = am.calibrate(pd.read_csv(ROOT / "data_samples" / "calibration.csv"))
    fig = plot_pca_scores(res.report)
    ax = fig.axes[0]
    fig.canvas.draw()
    legend = ax.get_legend().get_window_extent()
    axes = ax.get_window_extent()
    assert not legend.overlaps(axes), (legend, axes)
    sc = np.array([s.scores[:2] for s in res.report.segments], dtype=float)
    pts = ax.transData.transform(sc)
    inside = [legend.contains(x, y) for x, y in pts]
    assert not any(inside)
    import matplotlib.pyplot as plt

    plt.close(fig)


def test_formats_page_names_every_format_and_no_parquet_extra():
    from aeromag.io.formats import REGISTRY

    page = (ROOT / "docs" / "formats.md").read_text(encoding="utf-8")
    for name in REGISTRY:
        assert f"`{name}`" in page.split("## Reading CSV")[0], name
    assert "pip install 'aeromag[parquet]'" not in page
