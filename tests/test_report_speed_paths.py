"""The report's fast paths give what the plain formulations give (equivalence only, no timing).

* the display envelope (in-place column keys, no masked copies when every sample is valid)
  equals the masked formulation it replaced;
* the batched Welch PSD (linear detrend as a projection) is scipy's, stretch by stretch.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from aeromag.synthetic import simulate_calibration
from aeromag.workflows.compensate import compensate_file
from aeromag.workflows.report import load_compensated


@pytest.fixture(scope="module")
def out_csv(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("speed")
    df, _ = simulate_calibration(seed=3, n_boxes=1)
    df.to_csv(d / "cal.csv", index=False)
    compensate_file(d / "cal.csv", d / "out.csv")
    return d / "out.csv"


def _edit(src: Path, dst: Path, row: int, col: str, value: str) -> Path:
    lines = src.read_text().splitlines()
    head = lines[0].split(",")
    f = lines[row + 1].split(",")
    f[head.index(col)] = value
    lines[row + 1] = ",".join(f)
    dst.write_text("\n".join(lines) + "\n")
    return dst


def _envelope_reference(x, y, columns=2000, breaks=None):
    """The envelope as first written (full-length masked copies): the fast one must equal it."""
    from aeromag._core.runs import run_bounds

    xf = np.asarray(x, dtype=np.float64)
    yv = np.asarray(y, dtype=np.float64)
    lab = np.zeros(len(yv), dtype=np.int64) if breaks is None else np.asarray(breaks)
    lab = np.where(np.isfinite(yv) & np.isfinite(xf), lab, -1)
    good = lab >= 0
    if not good.any():
        return np.zeros(0), np.zeros(0)
    if len(yv) > 4 * columns:
        lo, hi = float(np.min(xf[good])), float(np.max(xf[good]))
        width = (hi - lo) / columns if hi > lo else 1.0
        col = np.clip(((xf - lo) / width).astype(np.int64), 0, columns - 1)
        a, b, _ = run_bounds(np.where(good, col + columns * (lab - lab[good].min()), -1))
        px = np.column_stack([xf[a], xf[b - 1]]).ravel()
        py = np.column_stack([np.minimum.reduceat(np.where(good, yv, np.inf), a),
                              np.maximum.reduceat(np.where(good, yv, -np.inf), a)]).ravel()
        seg = np.repeat(lab[a], 2)
    else:
        px, py, seg = xf[good], yv[good], lab[good]
    brk = np.flatnonzero(seg[1:] != seg[:-1]) + 1
    return np.insert(px, brk, np.nan), np.insert(py, brk, np.nan)


def test_envelope_equals_the_masked_reference():
    from aeromag.plot._style import envelope

    rng = np.random.default_rng(5)
    n = 200_000
    x = np.arange(n) * 0.1
    y = rng.normal(size=n)
    st = np.repeat(np.arange(400), n // 400)
    holes = y.copy()
    holes[rng.random(n) < 0.2] = np.nan
    holes[50_000:60_000] = np.nan
    unlabelled = st.copy()
    unlabelled[:3000] = -1
    bad_x = x.copy()
    bad_x[7] = np.nan
    for xx, yy, bb in [(x, y, None), (x, y, st), (x, holes, st), (x, y, unlabelled),
                       (bad_x, y, st), (x / 86400 + 19000, holes, None),
                       (x.astype(np.float32), y.astype(np.float32), st),
                       (x[:3000], holes[:3000], st[:3000]), (x, np.full(n, np.nan), None)]:
        got, want = envelope(xx, yy, breaks=bb), _envelope_reference(xx, yy, breaks=bb)
        for g, w in zip(got, want, strict=True):
            np.testing.assert_array_equal(g, w)


def test_welch_equals_scipy_per_stretch():
    """The batched PSD (linear detrend as a projection) is scipy's Welch averaged over the
    stretches, weighted by their length."""
    from scipy import signal

    from aeromag.plot.compensation import _welch

    rng = np.random.default_rng(2)
    t = np.r_[np.arange(3000), np.arange(5000) + 4000.0, np.arange(1700) + 10000.0] * 0.1
    x = np.cumsum(rng.normal(size=len(t))) + 50000.0 + 3 * np.sin(2 * np.pi * 0.3 * t)
    f, p = _welch(x, t, 512)
    parts = [(3000, slice(0, 3000)), (5000, slice(3000, 8000)), (1700, slice(8000, 9700))]
    want = sum(n * signal.welch(x[s], fs=10.0, nperseg=512, detrend="linear")[1]
               for n, s in parts) / 9700
    np.testing.assert_allclose(f, signal.welch(x[:3000], fs=10.0, nperseg=512)[0])
    np.testing.assert_allclose(p, want, rtol=1e-9)


def test_envelope_bridges_only_subpixel_gaps_between_subpixel_stretches():
    """8000 stretches narrower than a pixel (a calibration cut at every turn) draw as one line,
    not 8000 pieces; a gap wider than a pixel column, or a change between two wide stretches,
    still breaks it."""
    from aeromag.plot._style import envelope

    n_st, per = 8000, 250
    x = (np.arange(n_st)[:, None] * (per + 100) + np.arange(per)).ravel() * 0.1
    st = np.repeat(np.arange(n_st), per)
    y = np.sin(x / 50.0)
    width = (x[-1] - x[0]) / 2000  # 140 s a column: stretches 25 s, gaps 10 s
    ex, ey = envelope(x, y, columns=2000, breaks=st)
    assert np.isnan(ey).sum() == 0 and len(ex) <= 2 * 2000 + 2 * n_st
    assert np.nanmax(ey) == y.max() and np.nanmin(ey) == y.min()
    far = x.copy()
    far[per * 4000:] += 3 * width  # one gap wider than a column
    ex, ey = envelope(far, y, columns=2000, breaks=st)
    assert np.isnan(ey).sum() == 1
    i = int(np.flatnonzero(np.isnan(ex))[0])
    assert ex[i - 1] == far[per * 4000 - 1] and ex[i + 1] == far[per * 4000]


def test_map_of_single_precision_positions_equals_double(out_csv: Path) -> None:
    """The map converts only its drawn samples to float64: the same points and colours as a
    frame converted to float64 as a whole (the conversion is exact)."""
    from aeromag.plot.maps import plot_map

    d32 = load_compensated(out_csv)[0].data
    d32.loc[d32.index[200:260], "segment_kept"] = False
    d32.loc[d32.index[10:20], "lat"] = np.nan
    d64 = d32.astype({c: np.float64 for c in ("lat", "lon", "alt")})
    a, b = plot_map(d32, max_points=500), plot_map(d64, max_points=500)
    for ca, cb in zip(a.axes[0].collections, b.axes[0].collections, strict=True):
        np.testing.assert_array_equal(ca.get_offsets(), cb.get_offsets())
        if ca.get_array() is not None:
            np.testing.assert_array_equal(ca.get_array(), cb.get_array())
