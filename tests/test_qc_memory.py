"""Memory of the QC: the same numbers with fewer full-length arrays alive.

``compute_qc`` frees its full-length temporaries (``mag - mag_tl``, the heading legs, the kept
mask) before the fit diagnostics build theirs, hands them its segment labels instead of
computing them again, and :func:`segment_labels` reads an integer column as one int64 array.
"""

from __future__ import annotations

import dataclasses
import tracemalloc

import numpy as np
import pandas as pd
import pytest

from aeromag.compensation.pipeline import run_compensation as compensate
from aeromag.compensation.result import CompensationResult
from aeromag.compensation.terms import TERMS_16
from aeromag.qc import fit_diagnostics, segment_labels
from aeromag.synthetic import simulate_calibration


@pytest.fixture(scope="module")
def rebuilt():
    """A compensated calibration flight whose report lacks the fit block (QC rebuilds it)."""
    df, _ = simulate_calibration(seed=3, n_boxes=8)
    res = compensate(df)
    report = dataclasses.replace(res.report, fit=None)
    return CompensationResult(res.data, res.model, report, config=res.config)


def _labels_general(data: pd.DataFrame) -> np.ndarray:
    """The general path of segment_labels (float64, NaN -> -1), the reference."""
    s = pd.to_numeric(data["segment"], errors="coerce").to_numpy(dtype=np.float64)
    return np.where(np.isfinite(s), s, -1).astype(np.int64)


@pytest.mark.parametrize("col", [
    np.array([-1, 0, 0, 3, 7, -1], dtype=np.int64),
    np.array([-1, 0, 0, 3, 7, -1], dtype=np.int32),
    pd.array([1, None, 2, 2, None, 5], dtype="Int64"),
    np.array([1.0, np.nan, 2.0, 2.0, np.nan, 5.0]),
    np.array(["1", "", "2", "x", "4", "5"], dtype=object),
])
def test_segment_labels_same_values(col):
    data = pd.DataFrame({"segment": col})
    got = segment_labels(data)
    assert got.dtype == np.int64
    np.testing.assert_array_equal(got, _labels_general(data))


def test_segment_labels_one_array_for_integers():
    n = 1_000_000
    data = pd.DataFrame({"segment": np.repeat(np.arange(n // 1000), 1000)})
    tracemalloc.start()
    try:
        lab = segment_labels(data)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert lab.base is None or not np.shares_memory(lab, data["segment"].to_numpy())
    # the result (8 bytes a row) and nothing else: the float64 path peaked at ~25 bytes a row
    assert peak < 10 * n, peak


def test_fit_diagnostics_given_labels_identical(rebuilt):
    data, cfg = rebuilt.data, rebuilt.config
    d0, s0 = fit_diagnostics(data, cfg, TERMS_16)
    d1, s1 = fit_diagnostics(data, cfg, TERMS_16, seg=segment_labels(data))
    assert d0 == d1
    pd.testing.assert_frame_equal(s0, s1)


def test_segment_labels_without_copy_keeps_an_int32_column():
    """copy=False hands back the report reader's int32 column itself (no int64 copy)."""
    seg = np.repeat(np.arange(50, dtype=np.int32), 20)
    data = pd.DataFrame({"segment": seg})
    lab = segment_labels(data, copy=False)
    assert lab.dtype == np.int32
    assert np.shares_memory(lab, data["segment"].to_numpy())
    np.testing.assert_array_equal(lab, _labels_general(data))
    assert segment_labels(data).dtype == np.int64  # a copy is int64 as before
