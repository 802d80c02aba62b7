"""Each command imports only what it needs, when it needs it, and only on the main thread.

Real subprocesses (a fresh interpreter each): ``import aeromag`` and ``aeromag --help`` import
none of the heavy packages; applying a model never imports scikit-learn, matplotlib or pyproj;
calibrating with ``--no-screen`` never imports scikit-learn; ``track`` imports matplotlib only
for ``--plot``.  A meta-path hook records the
thread of every first import: importing on a background thread beside the main thread once
crashed runs (a partially initialised scikit-learn), so every import must be on the main one.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "data_samples"
HEAVY = ("pandas", "scipy.signal", "sklearn", "matplotlib", "pyproj")

_PROBE = """
import json, runpy, sys, threading
from importlib.abc import MetaPathFinder

OFF_MAIN = []

class Probe(MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if threading.current_thread() is not threading.main_thread():
            OFF_MAIN.append((name, threading.current_thread().name))
        return None

sys.meta_path.insert(0, Probe())
code = 0
if ARGV is None:
    import aeromag  # noqa: F401
    import aeromag.cli  # noqa: F401
else:
    sys.argv = ["aeromag", *ARGV]
    try:
        runpy.run_module("aeromag", run_name="__main__", alter_sys=True)
    except SystemExit as e:
        code = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
print("@@" + json.dumps({"code": code, "mods": [m for m in HEAVY if m in sys.modules],
                         "off_main": OFF_MAIN}))
"""


def _probe(argv: list[str] | None, cwd: Path) -> dict:
    code = f"ARGV = {argv!r}\nHEAVY = {HEAVY!r}\n" + _PROBE
    env = dict(os.environ, COLUMNS="100")
    p = subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True,
                       env=env, timeout=300)
    line = next((ln for ln in p.stdout.splitlines() if ln.startswith("@@")), None)
    assert p.returncode == 0 and line is not None, p.stderr[-2000:]
    return json.loads(line[2:])


def test_import_aeromag_is_light(tmp_path):
    r = _probe(None, tmp_path)
    assert r["mods"] == [], r


@pytest.mark.parametrize("argv", [["--help"], *([c, "--help"] for c in (
    "calibrate", "compensate", "batch", "track", "report", "simulate", "compass", "detect",
    "navigate"))])
def test_help_imports_no_heavy_package(tmp_path, argv):
    r = _probe(argv, tmp_path)
    assert r["code"] == 0
    assert r["mods"] == [], r


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    d = tmp_path_factory.mktemp("imports")
    r = _probe(["calibrate", str(SAMPLES / "calibration.csv"), "-o", str(d / "m.json")], d)
    assert r["code"] == 0
    return d / "m.json", r


def test_calibrate_imports_on_the_main_thread_only(model):
    _, r = model
    assert "sklearn" in r["mods"]  # screening runs by default
    assert "matplotlib" not in r["mods"] and "pyproj" not in r["mods"], r
    assert r["off_main"] == [], r


def test_applying_a_model_imports_no_sklearn_matplotlib_pyproj(model, tmp_path):
    m, _ = model
    r = _probe(["compensate", str(SAMPLES / "survey.csv"), "--model", str(m), "-o",
                str(tmp_path / "out.csv")], tmp_path)
    assert r["code"] == 0
    assert set(r["mods"]) <= {"pandas", "scipy.signal"}, r
    assert r["off_main"] == [], r


def test_calibrate_without_screening_imports_no_sklearn(tmp_path):
    r = _probe(["calibrate", str(SAMPLES / "calibration.csv"), "--no-screen", "-o",
                str(tmp_path / "m.json")], tmp_path)
    assert r["code"] == 0
    assert "sklearn" not in r["mods"], r
    assert r["off_main"] == [], r


def test_track_imports_matplotlib_only_for_plots(tmp_path):
    argv = ["track", str(SAMPLES / "mission.csv"), "--plan", str(SAMPLES / "mission_plan.csv"),
            "-o", str(tmp_path / "t.csv")]
    r = _probe(argv, tmp_path)
    assert r["code"] == 0
    assert "matplotlib" not in r["mods"] and "sklearn" not in r["mods"], r
    assert r["off_main"] == [], r
    r = _probe([*argv[:-1], str(tmp_path / "t2.csv"), "--plot", str(tmp_path / "fig")], tmp_path)
    assert r["code"] == 0 and "matplotlib" in r["mods"], r
