"""The library names Python parameters; the command line shows the flag (issue 15).

The reader, the compass, detect, navigate, online-compensate and apply workflows word their
errors and warnings for a Python caller (``columns={'NAME': 'SOURCE'}``,
``earth_field=(F, I, D)``, ``date='YYYY-MM-DD'``, ``origin=(LAT, LON, ALT)``,
``units={'gyro': 'deg/s'}``, ``forgetting=0.999``, ``band_hz``, ``lowpass_hz``); every
command maps those words to its flags in one place
(:func:`aeromag.cli._options.flag_message`): ``--col NAME=SOURCE``, ``--earth-field F I D``,
``--date YYYY-MM-DD``, ``--origin LAT LON ALT``, ``--units gyro=deg/s``, ``--forgetting``,
``--band``, ``--lowpass``.
"""

from __future__ import annotations

import ast
import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.cli._options import flag_message
from aeromag.errors import InputError
from aeromag.io import write_csv

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "data_samples"
runner = CliRunner()
FLAG = re.compile(r"(?<![\w-])--[a-z]")
#: The modules of this change: none may name a command-line flag in a message.
MODULES = ("aeromag/io/log.py", "aeromag/workflows/compass.py", "aeromag/workflows/detect.py",
           "aeromag/workflows/navigate.py", "aeromag/workflows/online_compensate.py",
           "aeromag/compensation/apply.py", "aeromag/compensation/checks.py",
           "aeromag/compensation/online.py", "aeromag/workflows/batch.py",
           "aeromag/workflows/batch_inputs.py", "aeromag/workflows/batch_engines.py",
           "aeromag/_core/lstsq.py", "aeromag/_core/rls.py", "aeromag/io/units.py",
           "aeromag/io/plans.py", "aeromag/io/formats/magdrone.py", "aeromag/io/formats/xyz.py",
           *sorted(str(p.relative_to(ROOT)) for d in ("nav", "detection", "compass")
                   for p in (ROOT / "aeromag" / d).glob("*.py")))
EF = ["--earth-field", "54000", "57", "-5"]


def _error(r) -> str:
    """The command's one ``error: ...`` line (exit 1, no traceback; warnings may precede)."""
    assert r.exit_code == 1, r.output
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert all(ln.startswith("WARNING: ") for ln in lines[:-1]), r.output
    assert lines[-1].startswith("error: "), r.output
    return lines[-1]


def _no_flag(msg: str) -> None:
    assert not FLAG.search(msg), msg


# -- the one mapping ---------------------------------------------------------------------------

@pytest.mark.parametrize(("library", "cli"), [
    ("map them with columns={'NAME': 'SOURCE'}", "map them with --col NAME=SOURCE"),
    ("or map the position columns with columns=...", "or map the position columns with --col"),
    ("give earth_field=(F, I, D) (nT, degrees)", "give --earth-field F I D (nT, degrees)"),
    ("earth_field=(54000.0, 57.0, -5.0)", "--earth-field 54000 57 -5"),
    ("give date='YYYY-MM-DD', or earth_field=(F, I, D)",
     "give --date YYYY-MM-DD, or --earth-field F I D"),
    ("x: earth_field given: date='2017-07-01' is not used",
     "x: --earth-field given: --date 2017-07-01 is not used"),
    ("give origin=(LAT, LON, ALT) (or earth_field=(F, I, D))",
     "give --origin LAT LON ALT (or --earth-field F I D)"),
    ("x: units={'gyro': 'furlong'}: unknown gyro unit",
     "x: --units gyro=furlong: unknown gyro unit"),
    ("closer to 1 than forgetting=0.999), or (model=MODEL; limit: max_interference)",
     "closer to 1 than --forgetting 0.999), or (--model MODEL; limit: --max-interference)"),
    ("x: band_hz: 6 Hz is not below", "x: --band: 6 Hz is not below"),
    ("lowpass_hz [-1.0]: need a positive frequency", "--lowpass [-1.0]: need a positive frequency"),
    # the detectors, navigate, compass reference and batch (calm_window, gps: T0:T1 on the CLI)
    ("calm_window='30:x': expected seconds", "--calm-window 30:x: expected seconds"),
    ("calm_window=(10, 5): the end must be after the start",
     "--calm-window 10:5: the end must be after the start"),
    ("calm_window=-3.0: the window length", "--calm-window -3.0: the window length"),
    ("x: only 3 usable sample(s); choose another calm_window",
     "x: only 3 usable sample(s); choose another --calm-window"),
    ("sigmas=0.0: must be a positive number", "--heading-sigmas 0.0: must be a positive number"),
    ("sigma_floor_deg=-1.0: must be >= 0", "--heading-sigma-floor -1.0: must be >= 0"),
    ("n_particles=1: need at least 2; window=0: need",
     "--particles 1: need at least 2; --window 0: need"),
    ("choose a longer calm_window or give threshold=X",
     "choose a longer --calm-window or give --threshold X"),
    ("gps='30:x': write 'use', 'none' or 'T0:T1' (e.g. gps='30:60')",
     "--gps 30:x: write 'use', 'none' or 'T0:T1' (e.g. --gps 30:60)"),
    ("gps=(60.0, 30.0): the outage needs T1 > T0", "--gps 60:30: the outage needs T1 > T0"),
    ("x: origin=(37.0, 112.0, 800.0) ignored", "x: --origin 37 112 800 ignored"),
    ("scheduler=ADDRESS needs Dask distributed", "--scheduler ADDRESS needs Dask distributed"),
    ("scheduler='tcp://h:8786': cannot connect", "--scheduler tcp://h:8786: cannot connect"),
    ("date='17/07/2017': not a date; write YYYY-MM-DD, e.g. date='2024-06-15'",
     "--date 17/07/2017: not a date; write YYYY-MM-DD, e.g. --date 2024-06-15"),
    ("earth_field: intensity must be a positive number of nT",
     "--earth-field: intensity must be a positive number of nT"),
    ("(in g? use units={'acc': 'g'})", "(in g? use --units acc=g)"),
    ("check the IMU units (units=...) and", "check the IMU units (--units) and"),
    ("give date='YYYY-MM-DD' or earth_field=(F, I, D) for a true yaw",
     "give --date YYYY-MM-DD or --earth-field F I D for a true yaw"),
    ("map the rangefinder with columns={'range_m': 'SOURCE'}",
     "map the rangefinder with --col range_m=SOURCE"),
    # the readers and the least-squares kernels
    ("fix the value or map another column with columns={'NAME': 'SOURCE'}",
     "fix the value or map another column with --col NAME=SOURCE"),
    ("x: column 'm1' (mapped to 'mag') not found; fix the map (columns={'mag': 'SOURCE'})",
     "x: column 'm1' (mapped to 'mag') not found; fix the map (--col mag=SOURCE)"),
    ("not a MagDrone R3 log (give fmt=FORMAT if it is another format)",
     "not a MagDrone R3 log (give --format FORMAT if it is another format)"),
    ("(the last row: the file is cut short? allow_truncated=True drops it)",
     "(the last row: the file is cut short? --allow-truncated drops it)"),
    ("forgetting=0.0: a forgetting factor must be in (0, 1]",
     "--forgetting 0.0: a forgetting factor must be in (0, 1]"),
    ("widen band_hz or choose a smaller term set (terms=...)",
     "widen --band or choose a smaller term set (--terms ...)"),
    ("add maneuvers, use ridge=1e-3, or", "add maneuvers, use --ridge 1e-3, or"),
])
def test_flag_message_maps_the_library_words(library, cli):
    assert flag_message(library) == cli


def test_plain_words_are_left_alone():
    """``date``, ``origin`` and ``forgetting`` are English words: only their Python forms map."""
    text = ("the date of the flight, the origin of the frame and a forgetting factor; the calm"
            " window, a threshold, the gps and the scheduler; walk_deg has no flag")
    assert flag_message(text) == text


@pytest.mark.parametrize("module", MODULES)
def test_no_library_message_names_a_flag(module):
    """No string of the module's code (docstrings aside) names a ``--flag``."""
    tree = ast.parse((ROOT / module).read_text(encoding="utf-8"))
    docs = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Module | ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value,
                                                                     ast.Constant):
                docs.add(id(body[0].value))
    found = [(n.lineno, n.value) for n in ast.walk(tree)
             if isinstance(n, ast.Constant) and isinstance(n.value, str)
             and id(n) not in docs and FLAG.search(n.value)]
    assert found == []


# -- the reader --------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def no_flux(tmp_path_factory):
    p = tmp_path_factory.mktemp("words") / "no_flux.csv"
    pd.read_csv(SAMPLES / "survey.csv").drop(columns=["flux_x"]).to_csv(p, index=False)
    return p


def test_reader_missing_column(no_flux, tmp_path):
    from aeromag.io import read_log

    with pytest.raises(InputError) as e:
        read_log(no_flux, required=("time", "flux_x"))
    assert str(e.value).endswith("map them with columns={'NAME': 'SOURCE'}")
    _no_flag(str(e.value))
    line = _error(runner.invoke(app, ["compensate", str(no_flux), "-o", str(tmp_path / "o.csv")]))
    assert "missing column(s) flux_x" in line and line.endswith("map them with --col NAME=SOURCE")


# -- compass -----------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def compass_log():
    from aeromag.synthetic.compass import simulate_compass

    log, _ = simulate_compass(duration_s=4.0)
    log["lat"], log["lon"], log["alt"] = 37.87, 112.55, 800.0
    return log


def _compass_cli(log, tmp_path, *args):
    p = tmp_path / "c.csv"
    write_csv(log, p)
    out = tmp_path / "c_out.csv"
    r = runner.invoke(app, ["compass", str(p), "-o", str(out), *args])
    return r, out


@pytest.mark.parametrize(("drop", "kw", "python", "cli"), [
    (["flux_x"], {"earth_field": (54000.0, 57.0, -5.0)}, "map them with columns={'NAME': 'SOURCE'}",
     "map them with --col NAME=SOURCE"),
    (["roll"], {"earth_field": (54000.0, 57.0, -5.0)}, "map them with columns={'NAME': 'SOURCE'}",
     "map them with --col NAME=SOURCE"),
    (["lat", "lon", "alt"], {"date": "2017-07-01"},
     "give earth_field=(F, I, D) (nT, degrees) or map the position columns with columns=...",
     "give --earth-field F I D (nT, degrees) or map the position columns with --col"),
    ([], {}, "needs the flight's date: give date='YYYY-MM-DD', or earth_field=(F, I, D)",
     "needs the flight's date: give --date YYYY-MM-DD, or --earth-field F I D"),
])
def test_compass_errors(compass_log, tmp_path, drop, kw, python, cli):
    from aeromag.workflows.compass import compass_frame

    log = compass_log.drop(columns=drop)
    with pytest.raises(InputError) as e:
        compass_frame(log, source="c.csv", **kw)
    assert python in str(e.value)
    _no_flag(str(e.value))
    args = [] if not kw else (EF if "earth_field" in kw else ["--date", kw["date"]])
    r, out = _compass_cli(log, tmp_path, *args)
    assert cli in _error(r) and not out.exists()


def test_compass_no_complete_position(compass_log, tmp_path):
    from aeromag.workflows.compass import compass_frame

    log = compass_log.assign(lat=np.nan)
    with pytest.raises(InputError, match=r"no complete position; give earth_field=\(F, I, D\)"):
        compass_frame(log, date="2017-07-01")
    r, _ = _compass_cli(log, tmp_path, "--date", "2017-07-01")
    assert _error(r).endswith("no complete position; give --earth-field F I D")


def test_compass_warning_date_not_used(compass_log, tmp_path, caplog):
    from aeromag.workflows.compass import compass_frame

    with caplog.at_level("WARNING", logger="aeromag"):
        compass_frame(compass_log, earth_field=(54000.0, 57.0, -5.0), date="2017-07-01")
    assert "earth_field given: date='2017-07-01' is not used" in caplog.text
    _no_flag(caplog.text)
    r, out = _compass_cli(compass_log, tmp_path, *EF, "--date", "2017-07-01")
    assert r.exit_code == 0, r.output
    assert "--earth-field given: --date 2017-07-01 is not used" in r.output
    warned = json.loads(out.with_suffix(".json").read_text())["warnings"]
    assert any("--earth-field given: --date 2017-07-01 is not used" in w for w in warned)


# -- detect ------------------------------------------------------------------------------------

def test_detect_unknown_gyro_unit(tmp_path):
    from aeromag.workflows.detect import _gyro_units

    with pytest.raises(InputError) as e:
        _gyro_units({"gyro": "furlong"}, "m.csv")
    assert str(e.value) == "m.csv: units={'gyro': 'furlong'}: unknown gyro unit; use rad/s or deg/s"
    r = runner.invoke(app, ["detect", str(SAMPLES / "mission.csv"), "-o", str(tmp_path / "o.csv"),
                            "--units", "gyro=furlong"])
    assert _error(r).endswith("--units gyro=furlong: unknown gyro unit; use rad/s or deg/s")


# -- navigate ----------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def nav_log(tmp_path_factory):
    from aeromag.synthetic.quadrotor import simulate_quadrotor

    d = tmp_path_factory.mktemp("nav_words")
    flight = simulate_quadrotor("rectangle", seed=11, duration_s=6.0)
    p, bare = d / "flight.csv", d / "no_gnss.csv"
    write_csv(flight.log, p)
    write_csv(flight.log.drop(columns=["lat", "lon", "alt", "vel_n", "vel_e", "vel_d"]), bare)
    return p, bare


@pytest.mark.parametrize(("which", "kw", "args", "python", "cli"), [
    (0, {"units": {"gyro": "furlong"}}, ["--units", "gyro=furlong"],
     "units={'gyro': 'furlong'}: unknown unit", "--units gyro=furlong: unknown unit"),
    (0, {"date": "2024-06-01", "earth_field": (50000.0, 60.0, 2.0)},
     ["--date", "2024-06-01", "--earth-field", "50000", "60", "2"],
     "date='YYYY-MM-DD' and earth_field=(F, I, D) are both given",
     "--date YYYY-MM-DD and --earth-field F I D are both given"),
    (1, {"date": "2024-06-01"}, ["--date", "2024-06-01"],
     "date='2024-06-01' needs a position for IGRF: the log has no GNSS fix; give "
     "origin=(LAT, LON, ALT) (or earth_field=(F, I, D))",
     "--date 2024-06-01 needs a position for IGRF: the log has no GNSS fix; give "
     "--origin LAT LON ALT (or --earth-field F I D)"),
])
def test_navigate_errors(nav_log, tmp_path, which, kw, args, python, cli):
    from aeromag.workflows.navigate import navigate_file

    src = nav_log[which]
    with pytest.raises(InputError) as e:
        navigate_file(src, tmp_path / "api.csv", **kw)
    assert python in str(e.value)
    _no_flag(str(e.value))
    out = tmp_path / "o.csv"
    r = runner.invoke(app, ["navigate", str(src), "-o", str(out), *args])
    assert cli in _error(r) and not out.exists()


def test_navigate_units_for_a_missing_column(nav_log, tmp_path):
    from aeromag.workflows.navigate import navigate_file

    src = tmp_path / "no_flow.csv"
    df = pd.read_csv(nav_log[0])
    df.drop(columns=[c for c in df.columns if c.startswith("flow")]).to_csv(src, index=False)
    with pytest.raises(InputError, match=r"units=\{'flow': 'deg/s'\}: no column 'flow'"):
        navigate_file(src, tmp_path / "api.csv", units={"flow": "deg/s"})
    r = runner.invoke(app, ["navigate", str(src), "-o", str(tmp_path / "o.csv"),
                            "--units", "flow=deg/s"])
    assert "--units flow=deg/s: no column 'flow' in the log" in _error(r)


# -- compensate --online -----------------------------------------------------------------------

def test_online_undetermined_fit(tmp_path):
    from aeromag.errors import FitError
    from aeromag.workflows.online_compensate import compensate_online_file

    src = SAMPLES / "mission.csv"
    with pytest.raises(FitError) as e:
        compensate_online_file(src, tmp_path / "api.csv")
    msg = str(e.value)
    assert "forgetting=0.999" in msg and "model=MODEL" in msg and "max_interference" in msg
    _no_flag(msg)
    r = runner.invoke(app, ["compensate", "--online", str(src), "-o", str(tmp_path / "o.csv")])
    line = _error(r)
    assert "closer to 1 than --forgetting 0.999" in line
    assert "--model MODEL" in line and "--max-interference" in line


# -- applying a saved model --------------------------------------------------------------------

@pytest.fixture(scope="module")
def model(tmp_path_factory):
    from aeromag.workflows.compensate import calibrate_file

    p = tmp_path_factory.mktemp("words_model") / "m.json"
    calibrate_file(SAMPLES / "calibration.csv", p)
    return p


@pytest.mark.parametrize(("kw", "args", "python", "cli"), [
    ({"band_hz": (0.1, 6.0)}, ["--band", "0.1", "6"], "band_hz: 6 Hz is not below the Nyquist",
     "--band: 6 Hz is not below the Nyquist"),
    ({"lowpass_hz": 6.0}, ["--lowpass", "6"], "lowpass_hz: 6 Hz is not below the Nyquist",
     "--lowpass: 6 Hz is not below the Nyquist"),
])
def test_apply_filter_errors(model, tmp_path, kw, args, python, cli):
    from aeromag.compensation import CompensationConfig
    from aeromag.compensation.apply import apply_model
    from aeromag.compensation.model import TLModel

    df = pd.read_csv(SAMPLES / "survey.csv")
    with pytest.raises(InputError) as e:
        apply_model(df, TLModel.load(model), CompensationConfig(**kw))
    assert python in str(e.value)
    _no_flag(str(e.value))
    out = tmp_path / "o.csv"
    r = runner.invoke(app, ["compensate", str(SAMPLES / "survey.csv"), "--model", str(model),
                            "-o", str(out), *args])
    assert cli in _error(r) and not out.exists()


# -- the detectors, navigate's GNSS mode and origin, the compass reference (issue 15) ----------

@pytest.mark.parametrize(("kw", "args", "python", "cli"), [
    ({"calm_window": "30:x"}, ["--calm-window", "30:x"],
     "calm_window='30:x': expected seconds", "--calm-window 30:x: expected seconds"),
    ({"calm_window": "40:10"}, ["--calm-window", "40:10"],
     "calm_window=(40, 10): the end must be after the start",
     "--calm-window 40:10: the end must be after the start"),
    ({"n_particles": 1}, ["--particles", "1"], "n_particles=1: need at least 2 particles",
     "--particles 1: need at least 2 particles"),
    ({"window": 0}, ["--window", "0"], "window=0: need at least 1 sample",
     "--window 0: need at least 1 sample"),
])
def test_detect_errors(tmp_path, kw, args, python, cli):
    from aeromag.workflows.detect import detect_file

    src = SAMPLES / "mission.csv"
    with pytest.raises(InputError) as e:
        detect_file(src, tmp_path / "api.csv", **kw)
    assert python in str(e.value)
    _no_flag(str(e.value))
    out = tmp_path / "o.csv"
    r = runner.invoke(app, ["detect", str(src), "-o", str(out), *args])
    assert cli in _error(r) and not out.exists()


@pytest.mark.parametrize(("kw", "args", "python", "cli"), [
    ({"heading_sigmas": 0.0}, ["--heading-sigmas", "0"], "sigmas=0.0: must be a positive",
     "--heading-sigmas 0.0: must be a positive"),
    ({"heading_sigma_floor_deg": -1.0}, ["--heading-sigma-floor", "-1"],
     "sigma_floor_deg=-1.0: must be >= 0 degrees", "--heading-sigma-floor -1.0: must be >= 0"),
])
def test_heading_detector_errors_through_track(tmp_path, kw, args, python, cli):
    from aeromag.workflows.track import track_file

    src, plan = SAMPLES / "mission.csv", SAMPLES / "mission_plan.csv"
    with pytest.raises(InputError) as e:
        track_file(src, plan, tmp_path / "api.csv", **kw)
    assert python in str(e.value)
    _no_flag(str(e.value))
    out = tmp_path / "o.csv"
    r = runner.invoke(app, ["track", str(src), "--plan", str(plan), "-o", str(out), *args])
    assert cli in _error(r) and not out.exists()


@pytest.mark.parametrize(("gps", "python", "cli"), [
    ("30:x", "gps='30:x': write 'use', 'none' or 'T0:T1'", "--gps 30:x: write 'use', 'none'"),
    ("60:30", "gps='60:30': the outage needs T1 > T0", "--gps 60:30: the outage needs T1 > T0"),
])
def test_navigate_gps_mode(nav_log, tmp_path, gps, python, cli):
    from aeromag.workflows.navigate import navigate_file

    with pytest.raises(InputError) as e:
        navigate_file(nav_log[0], tmp_path / "api.csv", gps=gps)
    assert python in str(e.value)
    _no_flag(str(e.value))
    out = tmp_path / "o.csv"
    r = runner.invoke(app, ["navigate", str(nav_log[0]), "-o", str(out), "--gps", gps])
    assert cli in _error(r) and not out.exists()


def test_navigate_origin_ignored_warning(nav_log, tmp_path, caplog):
    from aeromag.workflows.navigate import navigate_file

    with caplog.at_level("WARNING", logger="aeromag"):
        res = navigate_file(nav_log[0], tmp_path / "api.csv", origin=(37.0, 112.0, 800.0))
    assert "origin=(37.0, 112.0, 800.0) ignored" in caplog.text
    assert all(not FLAG.search(w) for w in res.report.warnings), res.report.warnings
    assert res.report.gps["origin_from"] == "first GNSS fix"
    out = tmp_path / "o.csv"
    r = runner.invoke(app, ["navigate", str(nav_log[0]), "-o", str(out),
                            "--origin", "37", "112", "800"])
    assert r.exit_code == 0, r.output
    assert "--origin 37 112 800 ignored" in r.output
    warned = json.loads(out.with_suffix(".json").read_text())["warnings"]
    assert any("--origin 37 112 800 ignored" in w for w in warned)


@pytest.mark.parametrize(("kw", "args", "python", "cli"), [
    ({"date": "1850-01-01"}, ["--date", "1850-01-01"],
     "date='1850-01-01' is outside IGRF-14 (1900-2030); give the field with earth_field=(F, I, D)",
     "--date 1850-01-01 is outside IGRF-14 (1900-2030); give the field with --earth-field F I D"),
    ({"earth_field": (-1.0, 57.0, -5.0)}, ["--earth-field", "-1", "57", "-5"],
     "earth_field: intensity must be a positive number of nT",
     "--earth-field: intensity must be a positive number of nT"),
])
def test_compass_reference_errors(compass_log, tmp_path, kw, args, python, cli):
    from aeromag.workflows.compass import compass_frame

    with pytest.raises(InputError) as e:
        compass_frame(compass_log, source="c.csv", **kw)
    assert python in str(e.value)
    _no_flag(str(e.value))
    r, out = _compass_cli(compass_log, tmp_path, *args)
    assert cli in _error(r) and not out.exists()


def test_igrf_field_names_its_date_parameter():
    from aeromag.compass.reference import igrf_field

    with pytest.raises(InputError) as e:
        igrf_field([37.0], [112.0], 0.0, "17/07/2017")
    assert str(e.value).startswith("date='17/07/2017': not a date")
    _no_flag(str(e.value))


def test_forgetting_factor_python_and_cli(compass_log, tmp_path):
    from aeromag.workflows.compass import compass_frame

    with pytest.raises(InputError) as e:
        compass_frame(compass_log, earth_field=(54000.0, 57.0, -5.0), forgetting=0.0)
    assert "forgetting=0.0: a forgetting factor must be in (0, 1]" in str(e.value)
    _no_flag(str(e.value))
    r, out = _compass_cli(compass_log, tmp_path, *EF, "--forgetting", "0")
    assert "--forgetting 0.0: a forgetting factor must be in (0, 1]" in _error(r)
    assert not out.exists()


def test_missing_mapped_column_python_and_cli(tmp_path):
    from aeromag.io import read_log

    with pytest.raises(InputError) as e:
        read_log(SAMPLES / "survey.csv", columns={"mag": "m1"})
    assert "fix the map (columns={'mag': 'SOURCE'})" in str(e.value)
    _no_flag(str(e.value))
    line = _error(runner.invoke(app, ["compensate", str(SAMPLES / "survey.csv"), "--col",
                                      "mag=m1", "-o", str(tmp_path / "o.csv")]))
    assert "fix the map (--col mag=SOURCE)" in line


def test_track_messages_name_parameters_and_the_cli_flags(tmp_path):
    # check_track's value errors and its datum hints: Python names the keyword, the CLI the flag.
    import pandas as pd
    from typer.testing import CliRunner

    from aeromag.cli import app
    from aeromag.errors import InputError
    from aeromag.track.check import check_track

    log = pd.DataFrame({"time": [0.0, 1.0], "lat": [56.0, 56.0001], "lon": [24.0, 24.0],
                        "alt": [30.0, 30.0]})
    plan = pd.DataFrame({"lat": [56.0, 56.001], "lon": [24.0, 24.0], "alt": [30.0, 30.0]})
    for kw, word in (({"threshold_m": -1.0}, "threshold_m=-1.0"),
                     ({"min_duration_s": -2.0}, "min_duration_s=-2.0"),
                     ({"combine": "xor"}, "combine='xor'"),
                     ({"altitude_offset": "sea"}, "altitude_offset='sea'")):
        with pytest.raises(InputError) as err:
            check_track(log, plan, **kw)
        assert word in str(err.value) and "--" not in str(err.value)
    p_log, p_plan = tmp_path / "log.csv", tmp_path / "plan.csv"
    log.to_csv(p_log, index=False)
    plan.to_csv(p_plan, index=False)
    for extra, flag in ((["--threshold", "-1"], "--threshold -1"),
                        (["--combine", "xor"], "--combine xor"),
                        (["--altitude-offset", "sea"], "--altitude-offset sea")):
        r = CliRunner().invoke(app, ["track", str(p_log), "--plan", str(p_plan), "-o",
                                     str(tmp_path / "o.csv"), *extra])
        assert r.exit_code != 0 and flag in r.output, r.output


def test_a_warning_is_listed_once_in_out_json(tmp_path):
    # A report's own warning (library words) and the same warning logged (spelt with flags on
    # the command line) were both listed in OUT.json.
    import json

    import pandas as pd
    from typer.testing import CliRunner

    from aeromag.cli import app
    from aeromag.workflows.mission import write_mission_files

    m = write_mission_files(tmp_path / "m", seed=1, small=True)
    src, plan = pd.read_csv(m["mission"]), pd.read_csv(m["plan"])
    rel = tmp_path / "rel.csv"
    src.assign(alt=src["alt"] - plan["alt"][0] + 40.0).to_csv(rel, index=False)
    out = tmp_path / "o.csv"
    r = CliRunner().invoke(app, ["track", str(rel), "--plan", str(m["plan"]), "-o", str(out)])
    assert r.exit_code == 0, r.output
    warns = json.loads(out.with_suffix(".json").read_text())["warnings"]
    datum = [w for w in warns if "constant" in w and "altitude" in w]
    assert len(datum) == 1, warns
    assert "--altitude-offset none" in datum[0] and "--horizontal" in datum[0]
