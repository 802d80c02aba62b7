"""``aeromag compensate`` / ``calibrate`` through typer's runner and as a real subprocess."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from aeromag.cli import app

from .conftest import hand_flight

runner = CliRunner()


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    df, _ = hand_flight(seed=11, n=6000)
    df.drop(columns=["truth_mag_tl", "truth_clean"]).to_csv(d / "flight.csv", index=False)
    renamed = df.rename(columns={"mag": "mag_1_uc", "flux_x": "fx"})
    renamed.assign(fx=renamed["fx"] / 1000.0).to_csv(d / "renamed.csv", index=False)
    return d


def test_compensate_writes_csv_and_json(logs, tmp_path):
    out = tmp_path / "o" / "comp.csv"
    r = runner.invoke(app, ["compensate", str(logs / "flight.csv"), "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert "improvement ratio" in r.output
    df = pd.read_csv(out)
    assert {"mag_tl", "mag_comp", "segment", "segment_kept"} <= set(df.columns)
    rep = json.loads(out.with_suffix(".json").read_text())
    assert len(rep["coef"]) == 16 and rep["metrics"]["improvement_ratio"] > 10


def test_calibrate_then_compensate_with_model(logs, tmp_path):
    m = tmp_path / "aircraft.json"
    r = runner.invoke(app, ["calibrate", str(logs / "flight.csv"), "-o", str(m)])
    assert r.exit_code == 0, r.output
    out = tmp_path / "s.csv"
    r = runner.invoke(app, ["compensate", str(logs / "flight.csv"), "--model", str(m), "-o",
                            str(out), "--no-filter"])
    assert r.exit_code == 0, r.output
    assert set(pd.read_csv(out)["segment_kept"]) == {True}
    # The report's config says what the application used: no fit-only options.
    cfg = json.loads(out.with_suffix(".json").read_text())["config"]
    assert "terms" not in cfg and "ridge" not in cfg and cfg["filter_output"] is False


@pytest.mark.parametrize("extra", [["--terms", "9"], ["--no-screen"], ["--ridge", "0.1"],
                                   ["--terms", "16"], ["--no-decimate"]])
def test_fit_options_with_model_are_refused(logs, tmp_path, extra):
    """--model applies a saved model: a fit-only option given with it would be ignored
    silently (the 16-term model applied while the config said terms 9)."""
    m = tmp_path / "m.json"
    assert runner.invoke(app, ["calibrate", str(logs / "flight.csv"), "-o", str(m)]).exit_code == 0
    out = tmp_path / "s.csv"
    r = runner.invoke(app, ["compensate", str(logs / "flight.csv"), "--model", str(m), "-o",
                            str(out), *extra])
    msg = r.output.strip()
    assert r.exit_code == 1 and msg.startswith("error: ") and "\n" not in msg, msg
    assert extra[0] in msg and not out.exists()
    # Apply-relevant options stay accepted.
    r = runner.invoke(app, ["compensate", str(logs / "flight.csv"), "--model", str(m), "-o",
                            str(out), "--band", "0.1", "0.9", "--no-filter"])
    assert r.exit_code == 0, r.output


def test_calibrate_refuses_a_model_name_that_is_not_json(logs, tmp_path):
    out = tmp_path / "model.csv"
    r = runner.invoke(app, ["calibrate", str(logs / "flight.csv"), "-o", str(out)])
    msg = r.output.strip()
    assert r.exit_code == 1 and msg.startswith("error: ") and "\n" not in msg, msg
    assert ".json" in msg and not out.exists()


def test_simulate_onto_a_file_is_one_line(logs, tmp_path):
    r = runner.invoke(app, ["simulate", "-o", str(logs / "flight.csv"), "--small"])
    msg = r.output.strip()
    assert r.exit_code == 1 and msg.startswith("error: ") and "\n" not in msg, msg
    assert "flight.csv" in msg


def test_column_map_and_units_options(logs, tmp_path):
    out = tmp_path / "r.csv"
    r = runner.invoke(app, ["compensate", str(logs / "renamed.csv"), "-o", str(out),
                            "--col", "mag=mag_1_uc", "--col", "flux_x=fx", "--units",
                            "flux_x=uT", "--band", "0.1", "0.9", "--terms", "16",
                            "--segment-seconds", "60"])
    assert r.exit_code == 0, r.output
    rep = json.loads(out.with_suffix(".json").read_text())
    assert rep["metrics"]["improvement_ratio"] > 10


BAD = {
    "missing_column": "time,mag,flux_x,flux_y\n0,1,2,3\n0.1,1,2,3\n",
    "text_in_numbers": "time,mag,flux_x,flux_y,flux_z\n0,1,2,3,4\n0.1,x,2,3,4\n",
    "empty": "",
    "one_row": "time,mag,flux_x,flux_y,flux_z\n0,1,2,3,4\n",
}


@pytest.mark.parametrize("name", sorted(BAD) + ["constant_flux", "band_above_nyquist"])
def test_bad_inputs_give_one_line_error_and_no_output(tmp_path, logs, name):
    if name in BAD:
        src = tmp_path / f"{name}.csv"
        src.write_text(BAD[name])
        extra: list[str] = []
    elif name == "constant_flux":
        src = tmp_path / "const.csv"
        df = pd.read_csv(logs / "flight.csv").assign(flux_x=1.0, flux_y=2.0, flux_z=3.0)
        df.to_csv(src, index=False)
        extra = []
    else:
        src = logs / "flight.csv"
        extra = ["--band", "0.1", "7"]
    out = tmp_path / "out" / "x.csv"
    r = runner.invoke(app, ["compensate", str(src), "-o", str(out), *extra])
    assert r.exit_code != 0
    msg = r.output.strip()
    assert msg.startswith("error: ") and "\n" not in msg, msg
    assert src.name in msg
    assert "Traceback" not in msg
    assert not out.exists() and not out.with_suffix(".json").exists()
    if out.parent.exists():
        assert list(out.parent.iterdir()) == []


def test_real_subprocess(logs, tmp_path):
    out = tmp_path / "sub.csv"
    # ``python -m aeromag``: the real entry point, with its background import thread.
    cmd = [sys.executable, "-m", "aeromag", "compensate", str(logs / "flight.csv"), "-o",
           str(out)]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert out.exists() and out.with_suffix(".json").exists()
    bad = subprocess.run(cmd[:4] + [str(tmp_path / "nope.csv"), "-o", str(out)],
                         capture_output=True, text=True, timeout=120)
    assert bad.returncode == 1
    assert bad.stderr.strip().count("\n") == 0 and "nope.csv" in bad.stderr
    assert "Traceback" not in bad.stderr


def test_help_lists_fixed_options():
    r = runner.invoke(app, ["compensate", "--help"])
    for opt in ("--model", "--band", "--terms", "--segment-seconds", "--no-screen",
                "--no-filter", "--col"):
        assert opt in r.output


def test_chunked_model_application_equals_in_memory(logs, tmp_path):
    m = tmp_path / "m.json"
    assert runner.invoke(app, ["calibrate", str(logs / "flight.csv"), "-o", str(m)]).exit_code == 0
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    r1 = runner.invoke(app, ["compensate", str(logs / "flight.csv"), "--model", str(m), "-o",
                             str(a)])
    r2 = runner.invoke(app, ["compensate", str(logs / "flight.csv"), "--model", str(m), "-o",
                             str(b), "--chunk-rows", "1000"])
    assert r1.exit_code == 0 and r2.exit_code == 0, r2.output
    da, db = pd.read_csv(a), pd.read_csv(b)
    pd.testing.assert_frame_equal(da, db, check_exact=False, rtol=1e-9, atol=1e-9)
    r3 = runner.invoke(app, ["compensate", str(logs / "flight.csv"), "-o", str(b),
                             "--chunk-rows", "1000"])
    assert r3.exit_code == 1 and "--model" in r3.output


IMPORT_RECORDER = """
import sys, threading
seen = []
class Rec:
    def find_spec(self, name, path=None, target=None):
        if threading.current_thread() is not threading.main_thread():
            seen.append((threading.current_thread().name, name))
        return None
sys.meta_path.insert(0, Rec())
from aeromag.cli import main
sys.argv = ["aeromag", "compensate", sys.argv[1], "-o", sys.argv[2]]
try:
    main()
except SystemExit as e:
    assert not e.code, e.code
print(sorted(set(seen)))
"""


def test_compensate_imports_only_on_the_main_thread(logs, tmp_path):
    """Two threads importing one package at once can get a partially initialised module (it
    crashed scikit-learn's import on a cold bytecode cache): every import of a CLI run happens
    on the main thread, whatever runs on other threads."""
    p = subprocess.run([sys.executable, "-c", IMPORT_RECORDER, str(logs / "flight.csv"),
                        str(tmp_path / "c.csv")], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr[-2000:]
    assert p.stdout.strip().splitlines()[-1] == "[]"


def test_unwritable_output_is_one_line_without_traceback(logs, tmp_path):
    (tmp_path / "jdir" / "o.json").mkdir(parents=True)  # OUT.json is a folder
    cases = [tmp_path, logs / "flight.csv" / "o.csv", tmp_path / "jdir" / "o.csv"]
    for out in cases:
        r = runner.invoke(app, ["compensate", str(logs / "flight.csv"), "-o", str(out)])
        assert r.exit_code == 1, (out, r.output)
        # (the hand flight has no calibration box: its self-fit warning may come first)
        msg = [ln for ln in r.output.strip().splitlines() if not ln.startswith("WARNING: ")]
        assert len(msg) == 1 and msg[0].startswith("error: ") and "Traceback" not in r.output
    assert sorted(p.name for p in (tmp_path / "jdir").iterdir()) == ["o.json"]  # nothing left


def test_empty_time_names_the_row(tmp_path):
    src = tmp_path / "gap.csv"
    src.write_text("time,mag,flux_x,flux_y,flux_z\n0,1,2,3,4\n,1,2,3,4\n0.2,1,2,3,4\n")
    r = runner.invoke(app, ["compensate", str(src), "-o", str(tmp_path / "o.csv")])
    assert r.exit_code == 1
    msg = r.output.strip()
    assert msg.startswith("error: ") and "\n" not in msg
    assert "gap.csv" in msg and "'time'" in msg and "line 3" in msg


def test_json_output_name_is_refused(logs, tmp_path):
    out = tmp_path / "o.json"
    r = runner.invoke(app, ["compensate", str(logs / "flight.csv"), "-o", str(out)])
    assert r.exit_code == 1 and ".json" in r.output and not out.exists()


def test_fitting_a_survey_on_itself_warns_without_a_calibration_box(tmp_path):
    """A survey (two headings, no box) fitted on itself: an excellent in-sample headline but
    the heading-dependent level of mag_tl is not determined; OUT.json and the terminal say so,
    while a calibration box fitted on itself does not warn."""
    samples = Path(__file__).resolve().parents[1] / "data_samples"
    out = tmp_path / "s.csv"
    r = runner.invoke(app, ["compensate", str(samples / "survey.csv"), "-o", str(out)])
    assert r.exit_code == 0, r.output
    rep = json.loads(out.with_suffix(".json").read_text())
    sc = rep["self_calibration"]
    assert sc["calibration_box"] is False and "in-sample" in sc["metrics"]
    assert any("without a calibration box" in w and "calibrate" in w for w in rep["warnings"])
    assert "without a calibration box" in r.output and "in-sample" in r.output
    out2 = tmp_path / "c.csv"
    r = runner.invoke(app, ["compensate", str(samples / "calibration.csv"), "-o", str(out2)])
    assert r.exit_code == 0, r.output
    rep = json.loads(out2.with_suffix(".json").read_text())
    assert rep["self_calibration"]["calibration_box"] is True
    assert not any("calibration box" in w for w in rep.get("warnings", []))
