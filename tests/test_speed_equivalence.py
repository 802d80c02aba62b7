"""Speed changes of the calibrate path (issue 17) that must leave every output unchanged."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

import aeromag as am
from aeromag.synthetic import simulate_calibration

threadpoolctl = pytest.importorskip("threadpoolctl")


def _blas_threads() -> int:
    return max((i["num_threads"] for i in threadpoolctl.threadpool_info()
                if i["user_api"] == "blas"), default=1)


def test_calibrate_screens_on_one_blas_thread(monkeypatch: pytest.MonkeyPatch) -> None:
    # A threaded OpenBLAS spent 0.17-0.19 s CPU on the screening's 1667 x 16 SVD (0.0005 s on
    # one thread): am.calibrate runs its fit and QC on one BLAS thread, and restores it after.
    df, _ = simulate_calibration(seed=3)
    import scipy.linalg  # noqa: F401 - its BLAS is loaded before the count below

    outside = _blas_threads()
    if outside < 2:
        pytest.skip("BLAS runs on one thread here already")
    screening = importlib.import_module("aeromag.compensation.screening")
    seen: list[int] = []
    real = screening.pca_screen

    def spy(*a: object, **k: object) -> object:
        seen.append(_blas_threads())
        return real(*a, **k)

    monkeypatch.setattr(screening, "pca_screen", spy)
    res = am.calibrate(df)
    assert seen and set(seen) == {1}
    assert _blas_threads() == outside
    assert np.all(np.isfinite(res.model.coef))



def _clip_reference(mid: np.ndarray, line: np.ndarray) -> tuple[np.ndarray, dict[int, tuple]]:
    """The per-manoeuvre loop that clip_to_lines replaced: kept (start, stop) per manoeuvre."""
    import pandas as pd

    from aeromag._core.runs import run_bounds

    codes = pd.factorize(pd.Series(line), use_na_sentinel=True)[0]
    new = mid.copy()
    spans = {}
    a, b, ids = run_bounds(mid)
    for s, e, i in zip(a, b, ids, strict=True):
        c = codes[s:e]
        if i < 0 or not (c != c[0]).any():
            continue
        cut = np.flatnonzero(np.r_[True, c[1:] != c[:-1], True])
        k = int(np.argmax(np.diff(cut)))
        ks, ke = s + cut[k], s + cut[k + 1]
        new[s:ks] = -1
        new[ke:e] = -1
        spans[int(i)] = (ks, ke)
    return new, spans


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("kind", ["float", "int", "str"])
def test_clip_to_lines_vectorised_equals_the_loop(seed: int, kind: str) -> None:
    # Manoeuvres crossing lines (missing lines too, ties of equal parts) clip as the loop did.
    import pandas as pd

    from aeromag.qc._lines import clip_to_lines
    from aeromag.qc.maneuvers import MANEUVERS, ManeuverResult

    rng = np.random.default_rng(seed)
    n = 3000
    t = np.arange(n) * 0.1
    line = np.repeat(rng.integers(0, 4, n // 20), 20).astype(float)
    line[rng.random(n) < 0.02] = np.nan
    line[np.repeat(rng.random(n // 20) < 0.25, 20)] = np.nan  # whole lines missing
    lengths = rng.integers(5, 60, n)
    mid = np.full(n, -1)
    i, j = 0, 0
    while i < n:
        L = int(lengths[i])
        if rng.random() < 0.7:
            mid[i:i + L] = j
            j += 1
        i += L + int(rng.integers(0, 3))
    ids = np.unique(mid[mid >= 0])
    if kind == "int":
        line = np.nan_to_num(line, nan=-7).astype(np.int64)
    elif kind == "str":
        line = np.array([None if x != x else f"L{x:g}" for x in line], dtype=object)
    lab = pd.DataFrame({"heading_leg": 0, "leg_id": 0, "box": 0, "maneuver_id": mid})
    lab["maneuver"] = pd.Categorical.from_codes(np.where(mid >= 0, 1 + mid % 3, 0),
                                                categories=["", *MANEUVERS])
    first = np.array([np.flatnonzero(mid == k)[0] for k in ids])
    last = np.array([np.flatnonzero(mid == k)[-1] for k in ids])
    tab = pd.DataFrame({"id": ids[::-1], "t_start": t[first][::-1], "t_end": t[last][::-1],
                        "n": (last - first + 1)[::-1], "duration_s": 0.0})
    got = clip_to_lines(ManeuverResult(lab, tab, pd.DataFrame(), "fluxgate"), line, t, 10.0)
    want_mid, spans = _clip_reference(mid, line)
    assert spans  # the case clips something
    np.testing.assert_array_equal(got.labels["maneuver_id"].to_numpy(), want_mid)
    np.testing.assert_array_equal(got.labels["maneuver"].cat.codes.to_numpy() == 0,
                                  want_mid < 0)
    row = {int(k): r for r, k in enumerate(got.table["id"])}
    for k, (ks, ke) in spans.items():
        assert got.table["t_start"].iloc[row[k]] == t[ks]
        assert got.table["t_end"].iloc[row[k]] == t[ke - 1]
        assert got.table["n"].iloc[row[k]] == ke - ks


def test_cross_is_numpys_bitwise() -> None:
    from aeromag.qc.maneuvers import _cross

    rng = np.random.default_rng(7)
    a, b = rng.normal(size=(1000, 3)), 1e-3 * rng.normal(size=(1000, 3))
    np.testing.assert_array_equal(_cross(a, b), np.cross(a, b))


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_block_means_with_non_finite_samples(bad: float) -> None:
    # The block mean sums first and checks the sums: a block with a NaN or inf sample still
    # gets the mean of its finite samples (NaN when it has none), as before.
    import pandas as pd

    from aeromag.qc._blocks import block_means

    rng = np.random.default_rng(1)
    n, step = 1000, 5
    t = np.arange(n) * 0.1
    x = rng.normal(size=n)
    x[[3, 4, 17]] = bad
    x[40:45] = bad  # a whole block
    df = pd.DataFrame({"time": t, "flux_x": x, "flux_y": x, "flux_z": x})
    small, cnt = block_means(df, t, step, 0.5)
    blocks = x.reshape(-1, step)
    fin = np.isfinite(blocks)
    with np.errstate(invalid="ignore"):
        want = np.where(fin.any(axis=1), np.where(fin, blocks, 0).sum(axis=1) / fin.sum(axis=1),
                        np.nan)
    assert (cnt == step).all()
    np.testing.assert_allclose(small["flux_x"].to_numpy(), want, rtol=1e-12)
    assert np.isnan(small["flux_x"].to_numpy()[8])


@pytest.mark.parametrize("seed", range(8))
def test_moving_mean_writes_every_sample(seed: int) -> None:
    # moving_mean fills an uninitialised array: every sample must still get its window mean
    # (or NaN outside a stretch), stretch ends and array ends included.
    from aeromag.qc._windows import moving_mean

    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 120))
    h = int(rng.integers(0, 9))
    lab = np.repeat(np.arange(n), rng.integers(1, 12, n))[:n]
    lab[rng.random(n) < 0.15] = -1
    x = rng.normal(size=(n, 2))
    got = moving_mean(x, lab, h)
    want = np.full((n, 2), np.nan)
    for i in np.flatnonzero(lab >= 0):
        a, b = i, i + 1
        while a > 0 and lab[a - 1] == lab[i]:
            a -= 1
        while b < n and lab[b] == lab[i]:
            b += 1
        want[i] = x[max(a, i - h):min(b, i + h + 1)].mean(axis=0)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


def test_leg_mean_heading_up_to_the_last_sample() -> None:
    # The legs' circular mean headings come from one reduceat over [start, stop) pairs; a leg
    # that ends on the log's last sample is summed to its end.
    import pandas as pd

    from aeromag.qc.maneuvers import detect_heading_legs

    t = np.arange(2400) * 0.1
    heading = np.where(t < 120, 88.0, 181.0) + 1.5 * np.sin(t)
    labels, legs, _ = detect_heading_legs(pd.DataFrame({"time": t, "heading": heading}))
    assert legs["heading"].tolist() == ["E", "S"] and legs["t_end"].iloc[-1] == t[-1]
    for _, leg in legs.iterrows():
        sel = labels["leg_id"].to_numpy() == leg["leg_id"]
        assert 0 < leg["mean_heading_deg"] - heading[sel].mean() + 0.5 < 1.0  # smoothed
