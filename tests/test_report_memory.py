"""The QC's memory-lean steps give the numbers of the formulations they replaced (bitwise)."""

from __future__ import annotations

import pytest


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
