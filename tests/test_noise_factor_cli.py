"""``--noise-factor K``: screening's in-band noise floor from the command line (issue 15).

A PCA outlier is dropped only when its excess residual also clears K standard deviations of
the in-band noise (``CompensationConfig.noise_factor``, default 3).  On the fault-free 12-line
box of :mod:`tests.test_screening_noise` the default keeps every line, while K = 0 (no noise
floor) drops the E and W yaw lines 5 and 11; each command that fits takes the flag, and a
bad value is a one-line error naming the flag (not the library's ``noise_factor``).
"""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from aeromag.cli import app

from .test_screening_noise import box_flight

runner = CliRunner()


@pytest.fixture(scope="module")
def box(tmp_path_factory):
    d = tmp_path_factory.mktemp("noise_factor")
    path = d / "box.csv"
    box_flight(1).to_csv(path, index=False)
    return path


def _run(cmd: str, box, out_dir, *extra: str) -> dict:
    """Run ``cmd`` on the box; return its report (MODEL.json, OUT.json or NAME_comp.json)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    if cmd == "calibrate":
        out = out_dir / "model.json"
        report = out
    elif cmd == "compensate":
        out = out_dir / "box_comp.csv"
        report = out.with_suffix(".json")
    else:
        out = out_dir
        report = out_dir / "box_comp.json"
    args = [cmd, str(box), "-o", str(out), *extra]
    if cmd == "batch":
        args += ["--workers", "1", "--no-progress"]
    r = runner.invoke(app, args)
    assert r.exit_code == 0, r.output
    return json.loads(report.read_text())


@pytest.mark.parametrize("cmd", ["calibrate", "compensate", "batch"])
def test_noise_factor_changes_which_segments_are_kept(cmd, box, tmp_path):
    default = _run(cmd, box, tmp_path / "default")
    assert default["screening"]["dropped"] == []
    off = _run(cmd, box, tmp_path / "off", "--noise-factor", "0")
    assert off["screening"]["dropped"] == [5, 11]
    assert [s["id"] for s in off["segments"] if not s["kept"]] == [5, 11]
    assert all(s["kept"] for s in default["segments"]) and len(default["segments"]) == 12
    # The value reaches the report's settings (what the run used).
    assert off["config"]["noise_factor"] == 0.0
    assert default["config"]["noise_factor"] == 3.0


@pytest.mark.parametrize("value", ["-1", "nan"])
@pytest.mark.parametrize("cmd", ["calibrate", "compensate"])
def test_a_bad_noise_factor_is_one_line_naming_the_flag(cmd, value, box, tmp_path):
    out = tmp_path / ("m.json" if cmd == "calibrate" else "o.csv")
    r = runner.invoke(app, [cmd, str(box), "-o", str(out), "--noise-factor", value])
    assert r.exit_code == 1, r.output
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith(f"error: --noise-factor {value}: "), r.output
    assert ">= 0" in lines[0] and "noise_factor" not in lines[0]
    assert not out.exists()


def test_noise_factor_steers_a_fit_so_model_refuses_it(box, tmp_path):
    model = tmp_path / "m.json"
    assert runner.invoke(app, ["calibrate", str(box), "-o", str(model)]).exit_code == 0
    out = tmp_path / "o.csv"
    r = runner.invoke(app, ["compensate", str(box), "--model", str(model), "-o", str(out),
                            "--noise-factor", "2"])
    assert r.exit_code == 1 and "drop --noise-factor" in r.output and not out.exists()


def test_the_flag_maps_to_the_config_keyword():
    """One row of the option table, on every fitting command, setting ``noise_factor``."""
    from aeromag.cli._options import OPTIONS, flag_message

    rows = [o for o in OPTIONS if o.config == "noise_factor"]
    assert len(rows) == 1 and rows[0].flags == ("--noise-factor",)
    assert rows[0].commands == {"calibrate", "compensate", "batch"}
    assert flag_message("noise_factor=-1 is negative") == "--noise-factor -1 is negative"
    for cmd in ("calibrate", "compensate", "batch"):
        r = runner.invoke(app, [cmd, "--help"], env={"COLUMNS": "200"})
        assert "--noise-factor" in r.output and "standard deviations" in r.output
