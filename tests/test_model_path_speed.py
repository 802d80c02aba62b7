"""Equivalence of the --model path's speed and memory shortcuts with the plain computations.

Each shortcut (no copies of the added columns, decimation on the thread pool) must give exactly
what the straightforward code gives; speed itself is measured by ``benchmarks/run_all.py``.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from aeromag.compensation.apply import _with_columns


def _frame(n: int = 1000) -> pd.DataFrame:
    rng = np.random.default_rng(0)
    df = pd.DataFrame({"time": np.arange(n) / 10.0, "mag": rng.normal(5e4, 1, n),
                       "mag_tl": np.zeros(n), "line": np.arange(n) // 100})
    df.attrs["passthrough_csv"] = {"path": "x.csv", "columns": list(df.columns)}
    return df


def _added(n: int) -> dict:
    seg = np.arange(n) // 50
    missing = seg % 7 == 3
    return {"mag_tl": np.linspace(0, 1, n), "mag_comp": np.linspace(5e4, 5e4 + 1, n),
            "segment": pd.arrays.IntegerArray(np.where(missing, 0, seg), missing),
            "segment_kept": seg % 2 == 0}


def _plain(df: pd.DataFrame, added: dict) -> pd.DataFrame:
    out = df.copy(deep=False)
    for k, v in added.items():
        out[k] = v
    return out


@pytest.mark.parametrize("index", [None, np.arange(1000) * 3])
def test_added_columns_equal_setting_them_one_by_one(index):
    df = _frame()
    if index is not None:
        df.index = index
    added = _added(len(df))
    out = _with_columns(df, added)
    ref = _plain(df, added)
    pd.testing.assert_frame_equal(out, ref)
    assert list(out.columns) == ["time", "mag", "mag_tl", "line", "mag_comp", "segment",
                                 "segment_kept"]  # an existing mag_tl replaced where it was
    assert out.attrs == ref.attrs and out.attrs is not df.attrs
    assert out.attrs["passthrough_csv"] is not df.attrs["passthrough_csv"]
    # nothing copied: the new columns are the arrays given, the old ones the caller's
    assert np.shares_memory(out["mag_comp"].to_numpy(), added["mag_comp"])
    assert np.shares_memory(out["time"].to_numpy(), df["time"].to_numpy())


def test_caller_frame_untouched_when_the_output_is_written():
    df = _frame()
    before = df.copy()
    out = _with_columns(df, _added(len(df)))
    out.loc[0, "time"] = -1.0
    out.loc[0, "mag_tl"] = -1.0
    pd.testing.assert_frame_equal(df, before)


def test_duplicate_names_fall_back_to_one_by_one():
    df = pd.DataFrame(np.ones((5, 2)), columns=["a", "a"])
    added = {"mag_tl": np.arange(5.0)}
    pd.testing.assert_frame_equal(_with_columns(df, added), _plain(df, added))


def test_compensate_with_model_output_is_unchanged():
    """The applied model's table is the log plus exactly the four columns, values as before."""
    from aeromag.compensation import CompensationConfig
    from aeromag.compensation import run_compensation as compensate

    from .conftest import hand_flight

    df, _ = hand_flight(n=3000)
    fit = compensate(df, CompensationConfig())
    res = compensate(df, CompensationConfig(), model=fit.model)
    data = res.data
    assert list(data.columns) == [*df.columns, "mag_tl", "mag_comp", "segment",
                                  "segment_kept"]
    pd.testing.assert_frame_equal(data[list(df.columns)], df)
    np.testing.assert_array_equal(data["mag_tl"].to_numpy(), fit.data["mag_tl"].to_numpy())
