"""The issue-26 structure bars hold (``benchmarks/structure_bars.py``, pure ast: a few seconds).

The audit is independent of ``tests/test_architecture.py``; here it runs as a user would run it
(exit 0 when every bar holds), and on a copy of the package with one planted fault per bar, to
show that it sees each one.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "structure_bars.py"


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True,
                          timeout=300, cwd=ROOT)


def test_every_structure_bar_holds():
    r = _run()
    assert r.returncode == 0, r.stdout + r.stderr
    assert "FAIL" not in r.stdout


#: One fault per bar, in modules that only the copy has.
PLANTED = {
    "_core/zz_a.py": '''"""Planted faults."""
import ctypes
import gc
import os
import threading
from concurrent.futures import ThreadPoolExecutor as Pool

from scipy.signal._arraytools import axis_slice


def f():
    from aeromag._core import zz_b, rls

    gc.freeze()
    threading.Thread(target=print).start()
    return zz_b, rls._upper_products, Pool, axis_slice, ctypes, os.environ.get("AEROMAG_FOO")
''',
    "_core/zz_b.py": '''"""Planted: the other half of a circle, type-only."""
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from . import zz_a


def g(a: zz_a.Z) -> None:
    ...
''',
    "_core/zz_c.py": '''"""Planted: a forwarding module."""
from aeromag._core.rls import RecursiveLeastSquares

__all__ = ["RecursiveLeastSquares"]
''',
    "_core/zz_d.py": '''"""Planted: a filter with its own result type."""
class ZFilter:
    def step(self, y, u=None) -> "ZStep":
        ...

    def run(self, ys, us=None) -> "ZResult":
        ...
''',
}


def test_the_audit_sees_each_planted_fault(tmp_path):
    shutil.copytree(ROOT / "aeromag", tmp_path / "aeromag",
                    ignore=shutil.ignore_patterns("__pycache__"))
    for rel, text in PLANTED.items():
        (tmp_path / "aeromag" / rel).write_text(text)
    r = _run("--json", "--root", str(tmp_path))
    assert r.returncode == 1, r.stdout + r.stderr
    bars = json.loads(r.stdout)["bars"]
    base = json.loads(_run("--json").stdout)["bars"]
    grew = {name: bars[name]["measured"] - base[name]["measured"] for name in bars}
    assert grew["import cycles (all imports)"] == 1
    assert bars["import cycles (all imports)"]["items"] == [
        "aeromag._core.zz_a <-> aeromag._core.zz_b"]
    assert grew["private names across modules"] == 1
    assert grew["allocator/GC tricks"] >= 2  # ctypes, gc.freeze
    assert grew["forwarding modules"] == 1
    assert grew["run() result types of the filters"] == 1
    assert not bars["run() result types of the filters"]["ok"]
    assert grew["private SciPy/NumPy APIs"] >= 1
    assert grew["thread pools outside _core/parallel"] == 1
    assert grew["processes/threads outside it, unlisted"] == 1
    assert grew["AEROMAG_* environment variables"] == 1
