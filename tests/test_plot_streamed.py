"""The report's long-line figures are enveloped block by block (issue 15, item 11).

The streamed envelopes, stretch bounds, term contributions and map subsample must equal, value
for value, the whole-array computations they replaced (so the PNGs stay pixel-identical), and
each figure's peak memory must stay a small multiple of a block, not of the log.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from aeromag._core.runs import run_bounds
from aeromag._core.stretches import find_stretches
from aeromag.plot import _series, maps
from aeromag.plot import _style as S
from aeromag.plot import compensation as pc


def _log_times(rng: np.random.Generator, n: int, t0: float = 0.0) -> np.ndarray:
    dt = np.full(n - 1, 0.1)
    gaps = rng.integers(0, n - 1, rng.integers(1, 200))
    dt[gaps] = rng.choice([0.6, 2.0, 50.0], len(gaps))  # gaps wider and narrower than a pixel
    return t0 + np.r_[0.0, np.cumsum(dt)]


def _reference(t: np.ndarray, y: np.ndarray, columns: int = S.DISPLAY_COLUMNS):
    """What the figures drew before: the whole-array envelope of ``_line``."""
    x, _, _ = S.time_axis(t)
    return S.envelope(x, y, columns, breaks=S._valid_runs(y, find_stretches(t)))


def _streamed(t: np.ndarray, y: np.ndarray, block: int, columns: int = S.DISPLAY_COLUMNS,
              guess=None):
    ax, gap = S.TimeAxis(t), S.stretch_gap_s(t)

    def blocks():
        for a in range(0, len(t), block):
            b = min(len(t), a + block)
            yield a, ax(t[a:b]), S.new_stretch(t, a, b, gap), [y[a:b]]
    return S.streamed_envelopes(len(t), blocks, 1, guess, columns)[0]


@pytest.mark.parametrize("seed", range(12))
def test_streamed_envelope_equals_the_whole_array_envelope(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.choice([5_000, 30_000, 120_000]))
    t = _log_times(rng, n, float(rng.choice([0.0, 1.6e9])))
    y = rng.standard_normal(n).cumsum()
    y[rng.random(n) < rng.choice([0.0, 0.002, 0.3])] = np.nan
    if seed % 3 == 0:  # trimmed ends: the drawable range is not the log's
        y[:2345] = np.nan
        y[-999:] = np.nan
    columns = int(rng.choice([2000, 250]))
    want = _reference(t, y, columns)
    x = S.time_axis(t)[0]
    for block in (97, 4096, 1 << 17):  # runs cut by block ends are joined
        for guess in (None, [(float(np.min(x)), float(np.max(x)))]):  # a wrong guess is redone
            got = _streamed(t, y, block, columns, guess)
            assert got[0].dtype == want[0].dtype
            np.testing.assert_array_equal(got[0], want[0])
            np.testing.assert_array_equal(got[1], want[1])


def test_streamed_envelope_of_nothing_drawable_is_empty() -> None:
    t = np.arange(20_000) * 0.1
    got = _streamed(t, np.full(len(t), np.nan), 1000)
    assert got[0].size == 0 and got[1].size == 0


def test_time_axis_without_a_copy_of_the_finite_times() -> None:
    for t in (np.array([np.nan, 1.7e9, 1.7e9 + 1]), np.arange(5.0) + 3, np.full(3, np.nan)):
        x, label, is_date = S.time_axis(t)
        fin = t[np.isfinite(t)]
        t0 = fin[0] if fin.size else 0.0
        np.testing.assert_array_equal(x, t / 86400.0 if is_date else t - t0)
        assert is_date == (fin.size > 0 and t0 >= 1e9)


def test_finite_stretch_bounds_equal_the_stretch_labels_runs() -> None:
    rng = np.random.default_rng(5)
    for _ in range(10):
        n = 40_000
        t = _log_times(rng, n)
        x = rng.standard_normal(n)
        x[rng.random(n) < 0.003] = np.nan
        x[:17] = np.nan
        a, b, _ = run_bounds(find_stretches(t, np.isfinite(x)))
        for block in (50, 1000, 1 << 17):
            a2, b2 = _series._finite_stretch_bounds(t, x, S.stretch_gap_s(t), block)
            np.testing.assert_array_equal(a2, a)
            np.testing.assert_array_equal(b2, b)


def test_every_nth_true_equals_flatnonzero_every_nth() -> None:
    rng = np.random.default_rng(0)
    m = rng.random(100_003) < 0.7
    for step in (1, 3, 17, 1000):
        for block in (10, 4096, 1 << 18):
            np.testing.assert_array_equal(maps._every_nth(m, step, block),
                                          np.flatnonzero(m)[::step])


@pytest.fixture(scope="module")
def res():
    from aeromag.compensation.pipeline import run_compensation as compensate
    from aeromag.synthetic import simulate_calibration

    df, _ = simulate_calibration(seed=6, n_boxes=1, faults={4: "noise_burst"})
    return compensate(df)


def _long(data, copies: int = 6):
    """The log flown ``copies`` times in a row (past the short-line path; a gap between)."""
    import pandas as pd

    span = float(data["time"].iloc[-1] - data["time"].iloc[0]) + 5.0
    parts = [data.assign(time=data["time"] + k * span) for k in range(copies)]
    return pd.concat(parts, ignore_index=True)


def _lines(fig):
    return [(ln.get_xdata(), ln.get_ydata(), ln.get_label()) for ln in fig.axes[0].get_lines()]


def test_figures_draw_the_whole_array_envelopes(res) -> None:
    data = _long(res.data)
    data.loc[data.index[200:260], "mag_comp"] = np.nan
    t = data["time"].to_numpy()
    fig = pc.plot_timeseries(data)
    want = [_reference(t, data["mag"].to_numpy()), _reference(t, data["mag_comp"].to_numpy())]
    for (x, y, _), (wx, wy) in zip(_lines(fig), want, strict=True):
        np.testing.assert_array_equal(x, wx)
        np.testing.assert_array_equal(y, wy)

    rng = np.random.default_rng(1)
    b, a = rng.standard_normal((2, len(t)))
    b[::300] = np.nan
    kept = np.ones(len(t), dtype=bool)
    kept[5000:9000] = False
    fig = pc.plot_residuals(t, b, a, kept=kept, band_hz=(0.1, 0.9))
    want = [_reference(t, b), _reference(t, np.where(kept, a, np.nan)),
            _reference(t, np.where(kept, np.nan, a))]
    got = _lines(fig)
    assert len(got) == 3
    for (x, y, _), (wx, wy) in zip(got, want, strict=True):
        np.testing.assert_array_equal(x, wx)
        np.testing.assert_array_equal(y, wy)


def test_term_figure_draws_the_contributions_and_their_std(res) -> None:
    data = _long(res.data)
    data.loc[data.index[100:130], "flux_x"] = np.nan  # no contribution there
    terms, coef = res.report.terms, res.report.coef
    parts = pc.term_contributions(data, terms, coef)
    got = _lines(pc.plot_term_contributions(data, res.report))
    t = data["time"].to_numpy()
    assert [g[2] for g in got] == [f"{c} (std {np.nanstd(parts[c].to_numpy()):.2f} nT)"
                                   for c in parts.columns]
    for (x, y, _), c in zip(got, parts.columns, strict=True):
        wx, wy = _reference(t, parts[c].to_numpy())
        np.testing.assert_array_equal(x, wx)
        np.testing.assert_array_equal(y, wy)


def test_blockwise_std_text_is_nanstd_text() -> None:
    rng = np.random.default_rng(3)
    for scale, mean in ((1.0, 0.0), (3.7, 5e4), (0.004, -20.0)):
        y = mean + scale * rng.standard_normal(333_333)
        y[rng.random(len(y)) < 0.01] = np.nan
        s = _series.NanStd()
        for i in range(0, len(y), 50_000):
            s.add(y[i:i + 50_000])
        assert s.text() == f"{np.nanstd(y):.2f}"
    boundary = _series.NanStd()
    boundary.add(np.array([0.0, 2 * 0.125]))  # std exactly 0.125: a rounding tie
    assert boundary.text() is None  # the caller takes np.nanstd's own digits
    empty = _series.NanStd()
    empty.add(np.full(4, np.nan))
    assert empty.text() is None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert f"{np.nanstd(np.full(4, np.nan)):.2f}" == "nan"
