"""Kill test (issue 16): SIGKILL, SIGTERM and SIGINT at random moments of a real run.

``aeromag compensate --model`` runs as a subprocess on a larger log and is killed at random
moments (fixed seed).  After SIGTERM or SIGINT nothing is left behind; after SIGKILL at most a
temporary file of the killed process stays, and only until the next run, which removes it.
Either both outputs (OUT.csv and OUT.json, complete) exist or neither does, and the re-run
succeeds with complete outputs.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

DATA = Path(__file__).resolve().parents[1] / "data_samples"

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")


@pytest.fixture(scope="module")
def big(tmp_path_factory) -> tuple[Path, Path, int]:
    """A 50,250-row survey (the sample tiled in time) and a model."""
    d = tmp_path_factory.mktemp("kill")
    one = pd.read_csv(DATA / "survey.csv")
    span = float(one["time"].iloc[-1] - one["time"].iloc[0]) + 0.1
    parts = []
    for k in range(25):
        part = one.copy()
        part["time"] = part["time"] + k * span
        part["line"] = part["line"] + 100 * k
        parts.append(part)
    log = d / "big.csv"
    pd.concat(parts, ignore_index=True).to_csv(log, index=False)
    model = d / "aircraft.json"
    subprocess.run([sys.executable, "-m", "aeromag", "calibrate", str(DATA / "calibration.csv"),
                    "-o", str(model)], check=True, capture_output=True, timeout=120)
    return log, model, 25 * len(one)


def _run(log: Path, model: Path, out: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "aeromag", "compensate", str(log),
                             "--model", str(model), "-o", str(out)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=out.parent)


def _complete(out: Path, n_rows: int) -> None:
    assert out.with_suffix(".json").exists()
    assert len(pd.read_csv(out, usecols=["time", "mag_comp"])) == n_rows


def test_kill_at_random_moments_leaves_nothing_behind(big, tmp_path):
    log, model, n_rows = big
    out = tmp_path / "out.csv"
    t0 = time.monotonic()
    p = _run(log, model, out)
    assert p.wait(300) == 0, p.stderr.read().decode()
    full = time.monotonic() - t0  # a whole run, imports included
    _complete(out, n_rows)
    rng = np.random.default_rng(16)
    for sig in (signal.SIGKILL, signal.SIGTERM, signal.SIGINT, signal.SIGKILL):
        for _ in range(1):
            for f in tmp_path.iterdir():
                f.unlink()
            p = _run(log, model, out)
            time.sleep(float(rng.uniform(0.2, 1.0)) * full)
            p.send_signal(sig)
            code = p.wait(120)
            err = p.stderr.read().decode()
            assert "Traceback" not in err, err
            names = {f.name for f in tmp_path.iterdir()}
            temps = {n for n in names if n.endswith(".tmp")}
            outs = names - temps
            if code == 0:  # finished before the signal
                assert outs == {"out.csv", "out.json"}
                _complete(out, n_rows)
            else:
                assert outs in (set(), {"out.csv", "out.json"}), (sig, outs)  # all or none
                if outs:
                    _complete(out, n_rows)
                if sig != signal.SIGKILL:
                    assert not temps, (sig, temps)  # cleaned up like Ctrl-C
                else:
                    assert all(f"aeromag-{p.pid}-" in t for t in temps), temps
            # the re-run succeeds and removes what a killed run left
            r = _run(log, model, out)
            assert r.wait(300) == 0, r.stderr.read().decode()
            names = {f.name for f in tmp_path.iterdir()}
            assert names == {"out.csv", "out.json"}, names
            _complete(out, n_rows)
