"""The map names a dropped line as surveyors do: 'line 4', not 'line 4.0' (issue 15 review)."""

from __future__ import annotations

import matplotlib
import matplotlib.figure

matplotlib.use("Agg")

import numpy as np
import pandas as pd

from aeromag.plot.maps import plot_map


def test_dropped_float_line_is_labelled_without_decimals():
    n = 400
    line = np.repeat([3.0, 4.0], n // 2)  # float column, as a CSV with a missing line id reads
    df = pd.DataFrame({
        "lat": 46.8 + np.linspace(0, 0.01, n), "lon": 7.1 + np.where(line == 3.0, 0, 0.001),
        "mag_comp": np.linspace(5e4, 5e4 + 10, n), "line": line,
        "segment": (line - 3).astype(int), "segment_kept": line == 3.0,
    })
    fig = plot_map(df)
    texts = [t.get_text() for t in fig.axes[0].texts]
    assert texts == ["line 4"], texts


def test_masked_residual_is_not_drawn_across_the_samples_it_leaves_out():
    from aeromag.plot._style import _line

    fig = matplotlib.figure.Figure()
    ax = fig.add_subplot()
    t = np.arange(300.0)
    y = np.where((t < 100) | (t >= 200), 1.0, np.nan)  # dropped, kept (masked), dropped
    _line(ax, t, y, np.zeros(300, dtype=np.int64))
    xs = ax.lines[0].get_xdata()
    pieces = np.split(xs, np.flatnonzero(np.isnan(xs)))
    spans = [(np.nanmin(p), np.nanmax(p)) for p in pieces if np.isfinite(p).any()]
    assert spans == [(0.0, 99.0), (200.0, 299.0)], spans
