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

