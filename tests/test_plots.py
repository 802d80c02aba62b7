"""Every compensation plot runs headless and writes a non-empty PNG."""

from __future__ import annotations

import numpy as np
import pytest

from aeromag.compensation.pipeline import run_compensation as compensate
from aeromag.errors import InputError
from aeromag.plot import compensation as pc
from aeromag.qc import compute_qc
from aeromag.synthetic import simulate_calibration


@pytest.fixture(scope="module")
def res():
    df, _ = simulate_calibration(seed=6, n_boxes=1, faults={4: "noise_burst"})
    r = compensate(df)
    return r, compute_qc(r, fit=False)


PNG = b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("name", ["pca", "ev", "ts", "psd", "terms", "fom", "map"])
def test_plot_writes_png(res, tmp_path, name):
    r, q = res
    path = tmp_path / f"{name}.png"
    calls = {
        "pca": lambda: pc.plot_pca_scores(r.report, path=path),
        "ev": lambda: pc.plot_explained_variance(r.report, path=path),
        "ts": lambda: pc.plot_timeseries(r.data, path=path),
        "psd": lambda: pc.plot_psd(r.data, band_hz=(0.1, 0.9), path=path),
        "terms": lambda: pc.plot_term_contributions(r.data, r.report, path=path),
        "fom": lambda: pc.plot_fom(q.fom, path=path),
        "map": lambda: pc.plot_map(r.data, path=path),
    }
    fig = calls[name]()
    assert fig.axes
    data = path.read_bytes()
    assert data.startswith(PNG) and len(data) > 5000


def test_draws_into_given_axes(res):
    r, _ = res
    fig, ax = pc.new_figure()
    assert pc.plot_pca_scores(r.report, ax=ax) is fig
    assert ax.get_title().endswith("1 dropped")


def test_term_contributions_sum_to_mag_tl(res):
    r, _ = res
    parts = pc.term_contributions(r.data, r.report.terms, r.report.coef)
    assert list(parts.columns) == ["permanent", "induced", "eddy"]
    assert ((parts.sum(axis=1) - r.data["mag_tl"]).abs().max()) < 1e-9
    # Block by block (derivatives at block ends from their neighbours), from float32 columns.
    small = pc.term_contributions(r.data, r.report.terms, r.report.coef, block=97)
    np.testing.assert_allclose(small.to_numpy(), parts.to_numpy(), rtol=0, atol=1e-9)
    d32 = r.data.astype({c: np.float32 for c in ("flux_x", "flux_y", "flux_z")})
    p32 = pc.term_contributions(d32, r.report.terms, r.report.coef, block=97)
    want = pc.term_contributions(d32.astype({c: np.float64 for c in ("flux_x", "flux_y",
                                                                       "flux_z")}),
                                 r.report.terms, r.report.coef)
    np.testing.assert_allclose(p32.to_numpy(), want.to_numpy(), rtol=0, atol=1e-9)


def test_missing_inputs_raise(res):
    r, _ = res
    with pytest.raises(InputError):
        pc.plot_pca_scores({"segments": [{"id": 0, "scores": None}]})
    with pytest.raises(InputError):
        pc.plot_map(r.data.drop(columns=["lat"]))


def test_envelope_keeps_extremes_and_gaps():
    rng = np.random.default_rng(0)
    n = 1_000_000
    x = np.arange(n) * 0.1
    y = rng.normal(size=n)
    y[123_456] = 50.0
    st = np.zeros(n, dtype=np.int64)
    st[600_000:] = 1  # a gap: never drawn across
    ex, ey = pc.envelope(x, y, columns=1000, breaks=st)
    assert len(ex) < 5000 and np.nanmax(ey) == 50.0 and np.nanmin(ey) == y.min()
    assert np.isnan(ey).sum() == 1
    short = pc.envelope(x[:100], y[:100])
    assert np.array_equal(short[1], y[:100])


def test_time_axes_are_utc_or_flight_relative(res):
    r, _ = res
    x, label, is_date = pc.time_axis(np.array([1.7e9, 1.7e9 + 1.0]))
    assert is_date and "UTC" in label
    x, label, is_date = pc.time_axis(np.array([100.0, 101.0]))
    assert not is_date and x[0] == 0.0 and "since start" in label
    d = r.data.copy()
    d["time"] += 1.714551e9  # epoch seconds
    fig = pc.plot_timeseries(d)
    fig.canvas.draw()
    ax = fig.axes[0]
    assert ax.xaxis.get_offset_text().get_text() in ("", "2024-May-01")  # no +1.7e9 offset
    assert "UTC" in ax.get_xlabel()
    assert all("e+09" not in t.get_text() for t in ax.get_xticklabels())


def test_map_in_metres_with_dropped_lines(res):
    r, _ = res
    fig = pc.plot_map(r.data)
    ax = fig.axes[0]
    assert ax.get_xlabel() == "east (m)" and ax.get_ylabel() == "north (m)"
    labels = [t.get_text() for t in ax.texts]
    assert any(s.startswith("line") or s.startswith("segment") for s in labels)


def test_figures_display_in_jupyter_without_matplotlib_inline(res):
    """Issue 15 item 12: a returned figure renders as PNG through IPython's formatter."""
    import matplotlib
    from IPython.core.interactiveshell import InteractiveShell

    backend = matplotlib.get_backend()
    r, _ = res
    import aeromag as am

    fig = am.plot.plot_pca_scores(r)
    fmt, _ = InteractiveShell.instance().display_formatter.format(fig)
    assert fmt["image/png"].startswith(PNG) if isinstance(fmt["image/png"], bytes) \
        else fmt["image/png"]
    assert matplotlib.get_backend() == backend  # no backend switch
