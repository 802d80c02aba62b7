"""The QC's fit diagnostics built block by block give the whole-array values, bit for bit.

``prepare(flux_columns=True)`` keeps the fluxgate as its columns and forms its magnitude and
stretch labels block by block; ``segment_normal_equations`` filters the pieces in blocks and
adds them into per-segment sums; ``loso_cv`` solves the leave-one-out systems in blocks.
Each is compared with the whole-array computation (small blocks, so that a log of a few
thousand rows crosses many block edges).
"""

from __future__ import annotations

import importlib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from aeromag._core.stretches import find_stretches
from aeromag.compensation.config import CompensationConfig
from aeromag.compensation.terms import TERMS_16
from aeromag.errors import InputError
from aeromag.io import read_log

prep_mod = importlib.import_module("aeromag.compensation.prepare")
normal_mod = importlib.import_module("aeromag.compensation.normal")
fd_mod = importlib.import_module("aeromag._core.fit_diagnostics")

SAMPLE = Path(__file__).resolve().parents[1] / "data_samples" / "calibration.csv"
TERMS = tuple(t for t in TERMS_16 if t != "bias")


@pytest.fixture(scope="module")
def log() -> pd.DataFrame:
    return read_log(SAMPLE)


def _gappy(df: pd.DataFrame, float32: bool, seed: int = 1) -> pd.DataFrame:
    d = df.copy()
    rng = np.random.default_rng(seed)
    n = len(d)
    for c in ("flux_x", "flux_y", "flux_z"):
        d.loc[rng.integers(0, n, 20), c] = np.nan  # short gaps: interpolated
    j = int(rng.integers(100, n - 100))
    d.loc[j:j + 30, "flux_x"] = np.nan  # a long one: invalid samples, a stretch break
    d.loc[500:540, "mag"] = np.nan
    if float32:
        d["flux_z"] = d["flux_z"].astype(np.float32)  # no gap: kept as the float32 column
    return d


@pytest.fixture
def small_blocks(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(prep_mod, "_BLOCK_ROWS", 97)
    monkeypatch.setattr(normal_mod, "_BLOCK_SAMPLES", 300)


@pytest.mark.parametrize("float32", [False, True])
def test_column_prepare_equals_the_whole_copy(log, small_blocks, float32):
    d = _gappy(log, float32)
    cfg = CompensationConfig()
    full = prep_mod.prepare(d, cfg)
    cols = prep_mod.prepare(d, cfg, flux_columns=True)
    assert cols.flux is None
    assert np.array_equal(np.column_stack(cols.flux_columns).astype(np.float64), full.flux,
                          equal_nan=True)
    for name in ("time", "mag", "flux_ok", "valid", "stretch", "segment"):
        assert np.array_equal(getattr(cols, name), getattr(full, name), equal_nan=True), name
    assert (cols.fs, cols.field_nT, cols.mag_from_flux) == (full.fs, full.field_nT,
                                                            full.mag_from_flux)
    given = prep_mod.prepare(d, cfg, flux_columns=True, segment=full.segment)
    assert given.segment is full.segment and np.array_equal(given.stretch, full.stretch)


def test_blocked_stretches_equal_find_stretches():
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.choice([0.1, 0.1, 0.1, 0.9], size=5000))
    valid = rng.random(5000) > 0.02
    valid[:3] = False
    for block in (1, 7, 100, 4999, 10_000):
        got = prep_mod._stretches_int32(t, valid, 0.5, block=block)
        assert got.dtype == np.int32
        assert np.array_equal(got, find_stretches(t, valid, 0.5)), block


@pytest.mark.parametrize("float32", [False, True])
def test_blocked_normal_equations_equal_one_block(log, monkeypatch, float32):
    cfg = CompensationConfig()
    d = _gappy(log, float32)
    ref_prep = prep_mod.prepare(d, cfg)
    monkeypatch.setattr(normal_mod, "_BLOCK_SAMPLES", 10**9)
    ref = normal_mod.segment_normal_equations(ref_prep, TERMS, cfg)
    assert ref.too_short  # the gaps leave a segment too short: the compaction is exercised
    monkeypatch.setattr(normal_mod, "_BLOCK_SAMPLES", 300)
    monkeypatch.setattr(prep_mod, "_BLOCK_ROWS", 97)
    for prep in (ref_prep, prep_mod.prepare(d, cfg, flux_columns=True)):
        for batch in (65_536, 8_192, 500):
            got = normal_mod.segment_normal_equations(prep, TERMS, cfg, batch_samples=batch)
            for name in ("ids", "n", "gram", "rhs", "yy"):
                assert np.array_equal(getattr(got, name), getattr(ref, name)), (name, batch)
            assert got.too_short == ref.too_short
            assert got.gram.flags.c_contiguous and got.rhs.flags.c_contiguous


def test_blocked_loso_equals_one_block(log, monkeypatch):
    cfg = CompensationConfig()
    stats = normal_mod.segment_normal_equations(prep_mod.prepare(log, cfg), TERMS, cfg)
    kept = np.ones(len(stats.ids), dtype=bool)
    kept[::3] = False
    monkeypatch.setattr(fd_mod, "_LOSO_BLOCK", 10**9)
    ref = fd_mod.loso_cv(stats, kept, 0.01)
    monkeypatch.setattr(fd_mod, "_LOSO_BLOCK", 5)
    got = fd_mod.loso_cv(stats, kept, 0.01)
    pd.testing.assert_frame_equal(got, ref, check_exact=True)


def test_column_prepare_refuses_a_bad_field_as_the_copy_does(log, small_blocks):
    d = log.copy()
    for c in ("flux_x", "flux_y", "flux_z"):
        d[c] = d[c] * 1e15
    cfg = CompensationConfig()
    with pytest.raises(InputError) as full:
        prep_mod.prepare(d, cfg)
    with pytest.raises(InputError) as cols:
        prep_mod.prepare(d, cfg, flux_columns=True)
    assert str(cols.value) == str(full.value)
    assert "fluxgate magnitude" in str(cols.value)


def test_compact_moves_rows_forward():
    x = np.arange(40.0).reshape(10, 2, 2)
    keep = np.array([1, 0, 1, 1, 0, 0, 1, 1, 1, 0], dtype=bool)
    want = x[keep].copy()
    got = normal_mod._compact(x, keep, block=2)
    assert np.array_equal(got, want) and got.flags.c_contiguous
