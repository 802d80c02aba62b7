"""Stretches, gaps, segments and the zero-phase filters."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import signal

from aeromag._core.filters import (
    bandpass_stretches,
    butter_sos,
    lowpass_stretches,
    sampling_rate,
    trim_mask,
)
from aeromag._core.runs import run_bounds
from aeromag._core.stretches import find_stretches, interpolate_short_gaps
from aeromag.compensation.segments import assign_segments
from aeromag.errors import InputError


def test_stretches_split_at_time_gaps_and_invalid_samples():
    t = np.r_[np.arange(0, 10, 0.1), np.arange(20, 30, 0.1)]
    valid = np.ones(len(t), bool)
    valid[50] = False
    s = find_stretches(t, valid)
    assert s[50] == -1
    assert len(np.unique(s[s >= 0])) == 3
    assert s[49] != s[51] and s[99] != s[100]


def test_short_gaps_interpolated_long_gaps_kept():
    t = np.arange(100) * 0.1
    x = np.sin(t)
    y = x.copy()
    y[10:13] = np.nan  # 0.4 s span between valid neighbours
    y[50:80] = np.nan  # 3.1 s
    f, n = interpolate_short_gaps(y, t, 1.0)
    assert n == 3
    np.testing.assert_allclose(f[10:13], np.interp(t[10:13], t[[9, 13]], x[[9, 13]]))
    assert np.isnan(f[50:80]).all()


def test_segments_by_line_and_by_windows():
    t = np.arange(0, 300, 0.1)
    st_ = find_stretches(t)
    seg = assign_segments(t, st_, None, 60.0)
    assert len(np.unique(seg)) == 5
    line = np.repeat([7.0, np.nan, 9.0], 1000)
    seg = assign_segments(t, st_, line)
    assert set(np.unique(seg)) == {-1, 7, 9}
    with pytest.raises(InputError):
        assign_segments(t, st_, None, 0.0)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(0.01, 5.0), min_size=2, max_size=60), st.floats(0.5, 100))
def test_windows_cover_valid_samples_in_order(steps, seg_s):
    t = np.cumsum(steps)
    stt = find_stretches(t, None, 1.0)
    seg = assign_segments(t, stt, None, seg_s)
    assert (seg >= 0).all()
    assert (np.diff(seg) >= 0).all()  # monotone in time
    # a segment never spans two stretches
    for s in np.unique(seg):
        assert len(np.unique(stt[seg == s])) == 1


def test_band_above_nyquist_is_an_input_error():
    with pytest.raises(InputError, match="Nyquist"):
        butter_sos("bandpass", (0.1, 6.0), 10.0)
    with pytest.raises(InputError, match="LOW < HIGH"):
        butter_sos("bandpass", (0.9, 0.1), 10.0)


def test_bandpass_matches_scipy_per_stretch_and_never_crosses_gaps():
    rng = np.random.default_rng(0)
    t = np.r_[np.arange(0, 60, 0.1), np.arange(100, 160, 0.1)]
    x = rng.normal(size=len(t))
    x[600:] += 1000.0  # a level jump hidden in the gap
    s = find_stretches(t)
    y = bandpass_stretches(x, t, s, (0.1, 0.9))
    sos = signal.butter(4, (0.1, 0.9), "bandpass", fs=10, output="sos")
    np.testing.assert_allclose(y[:600], signal.sosfiltfilt(sos, x[:600]), atol=1e-12)
    np.testing.assert_allclose(y[600:], signal.sosfiltfilt(sos, x[600:]), atol=1e-9)


def test_lowpass_keeps_level():
    t = np.arange(0, 100, 0.1)
    x = 50000 + np.sin(2 * np.pi * 0.05 * t) + 0.1 * np.sin(2 * np.pi * 3 * t)
    y = lowpass_stretches(x, t, find_stretches(t), 0.9)
    assert abs(np.mean(y) - np.mean(x)) < 1e-3
    assert np.std(y[100:-100] - 50000 - np.sin(2 * np.pi * 0.05 * t[100:-100])) < 0.01


def test_trim_mask_and_run_bounds():
    t = np.arange(0, 20, 1.0)
    s = np.r_[np.zeros(10, int), -np.ones(2, int), np.ones(8, int)]
    a, b, v = run_bounds(s)
    assert a.tolist() == [0, 12] and b.tolist() == [10, 20] and v.tolist() == [0, 1]
    m = trim_mask(s, t, 2.0)
    assert m.tolist() == [False] * 2 + [True] * 6 + [False] * 6 + [True] * 4 + [False] * 2
    assert sampling_rate(t) == 1.0


def test_non_integer_line_numbers_never_merge():
    from aeromag.compensation.segments import line_labels

    t = np.arange(0, 30, 0.1)
    line = np.repeat([1002.02, 1002.2, 1003.0], 100)
    seg = assign_segments(t, find_stretches(t), line)
    assert len(np.unique(seg)) == 3
    assert line_labels(line) == {0: 1002.02, 1: 1002.2, 2: 1003.0}
    assert line_labels(np.repeat([3.0, 4.0], 5)) is None


def test_batched_piece_normal_equations_equal_one_by_one():
    from aeromag._core.filters import piece_normal_equations

    rng = np.random.default_rng(2)
    t = np.arange(0, 200, 0.1)
    X = rng.normal(size=(3, len(t)))
    starts = np.array([0, 300, 600, 900, 1500])
    stops = np.array([300, 600, 900, 1500, 1510])  # equal lengths, a longer one, a too-short one
    sos = signal.butter(4, (0.1, 0.9), "bandpass", fs=10, output="sos")
    M, n = piece_normal_equations(X, t, starts, stops, sos, 2.5, batch_samples=500)
    for j, (a, b) in enumerate(zip(starts, stops, strict=True)):
        if b - a < 30:
            assert n[j] == 0 and not M[j].any()
            continue
        xf = signal.sosfiltfilt(sos, X[:, a:b], axis=1)
        tt = t[a:b]
        keep = (tt - tt[0] >= 2.5) & (tt[-1] - tt >= 2.5)
        np.testing.assert_allclose(M[j], xf[:, keep] @ xf[:, keep].T, rtol=1e-10, atol=1e-12)
        assert n[j] == keep.sum()


def test_trim_mask_by_search_equals_per_sample_test():
    """The binary-search trim gives exactly ``t - t_start >= trim`` and ``t_end - t >= trim``,
    also where rounding puts a sample right on the boundary (0.1 s steps, 2.5 s trim)."""
    from aeromag._core.filters import _trim_mask_any
    from aeromag._core.runs import run_bounds

    rng = np.random.default_rng(8)
    for t in (np.arange(20_000) * 0.1, np.cumsum(rng.uniform(0.01, 0.2, 20_000))):
        st = np.repeat(np.arange(40), 500)
        st[rng.integers(0, 20_000, 300)] = -1
        st = np.where(st >= 0, st + np.cumsum(st < 0), -1)  # invalid samples split stretches
        for trim in (0.0, 0.1, 2.5, 7.3, 60.0):
            a, b, _ = run_bounds(st)
            want = _trim_mask_any(t, st >= 0, a, b, trim) if trim > 0 else st >= 0
            np.testing.assert_array_equal(trim_mask(st, t, trim), want)


@settings(max_examples=30, deadline=None)
@given(L=st.integers(28, 400), m=st.integers(1, 5), order=st.integers(1, 6),
       seed=st.integers(0, 2**31 - 1))
def test_zero_phase_rows_is_bitwise_scipy_sosfiltfilt(L, m, order, seed):
    from aeromag._core.filters import pad_length, zero_phase_rows

    sos = butter_sos("bandpass", (0.1, 0.9), 10.0, order)
    x = np.random.default_rng(seed).normal(0, 1, (m, L)) * 1e4
    if L <= pad_length(sos):
        with pytest.raises(ValueError):
            zero_phase_rows(sos, x)
        return
    np.testing.assert_array_equal(zero_phase_rows(sos, x), signal.sosfiltfilt(sos, x, axis=1))


def test_threaded_filters_equal_serial_and_never_deadlock(monkeypatch):
    import aeromag._core.filters as F
    from aeromag._core import parallel

    sos = butter_sos("lowpass", 0.9, 10.0, 4)
    x = np.random.default_rng(1).normal(0, 1, (8, 200_000))
    ref = signal.sosfiltfilt(sos, x, axis=1)
    monkeypatch.setattr(F, "THREADS", 2)
    monkeypatch.setattr(parallel, "THREADS", 2)
    np.testing.assert_array_equal(F._sosfiltfilt(sos, x, 1), ref)
    np.testing.assert_array_equal(F._sosfiltfilt(sos, x.T, 0), ref.T)
    # Nested use (a pool task that filters a large array) runs serially, never waits on itself.
    out = parallel.parallel_map(lambda i: F._sosfiltfilt(sos, x, 1)[i], [0, 1, 2])
    for i, row in enumerate(out):
        np.testing.assert_array_equal(row, ref[i])
