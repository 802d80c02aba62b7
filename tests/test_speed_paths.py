"""Fast paths give what the simple computation gives (issue 17).

Each test compares a vectorised or shortcut path with the plain computation it replaces, or
checks that a start-up shortcut leaves the library as it found it.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from aeromag._core import filters

_WARM = """
import scipy._lib._array_api as aa
orig = aa.FunctionDoc
from aeromag.cli.compensate import _warm
_warm(screen=True)
import scipy.signal
assert aa.FunctionDoc is orig, "scipy's docstring parser not put back"
doc = scipy.signal.butter.__doc__
assert "Array API Standard Support" in doc, "support note lost"
assert "\\n    Parameters\\n    ----------" in doc, "docstring re-parsed at import"
print("ok")
"""


def test_warm_imports_scipy_without_reparsing_its_docstrings() -> None:
    # A fresh interpreter: scipy.signal must not be imported yet.
    out = subprocess.run([sys.executable, "-c", _WARM], capture_output=True, text=True,
                         check=False)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def _stretches(rng: np.random.Generator, n: int) -> np.ndarray:
    """Stretch labels: runs of a few lengths (some too short to filter), gaps between."""
    lab = np.full(n, -1, dtype=np.int64)
    i, k = 0, 0
    while i < n:
        L = int(rng.choice([5, 40, 300, 300, 300, 450, 2000]))
        lab[i:i + L] = k
        i += L + int(rng.integers(0, 3))
        k += 1
    return lab


@pytest.mark.parametrize("axis", [0, 1])
def test_filter_stretches_stacked_equals_one_by_one(axis: int, monkeypatch) -> None:
    rng = np.random.default_rng(17)
    n = 60_000
    lab = _stretches(rng, n)
    x = rng.normal(size=(3, n)).cumsum(axis=1)
    x[1, 12_345] = np.nan  # one stretch of row 1 not finite: that stretch NaN in every row
    xa = x if axis == 1 else x.T.copy()
    sos = filters.butter_sos("bandpass", (0.1, 0.9), 10.0, 4)
    fast = filters.filter_stretches(xa, lab, sos, axis=axis)
    monkeypatch.setattr(filters, "_MIN_BATCHED_STRETCHES", 10**9)  # the plain loop
    plain = filters.filter_stretches(xa, lab, sos, axis=axis)
    assert np.isnan(plain).any()
    np.testing.assert_array_equal(fast, plain)  # bitwise, NaN where NaN
