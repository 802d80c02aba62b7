"""Review 17: what a user met trying aeromag (Python and the command line).

1. ``compensate_file`` fitted on the log itself warns without a calibration box, as the CLI.
2. A fit or screening option that the run does not use is refused in one line
   (``batch --model``, ``compensate --online``, ``--no-screen``).
3. ``compass_file(earth_field=(F, I))`` and a bad unit name the parameter (and the flag).
4. The improvement-ratio warning shows a number below 1; the online fit's advice is its own.
5. The track summary says how many legs were checked before how many were flagged.
"""

from __future__ import annotations

import json
import logging
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.compensation import CompensationMetrics
from aeromag.compensation.checks import metric_warnings
from aeromag.errors import InputError

_m = CompensationMetrics.from_dict  # a metrics block as a report file holds it

runner = CliRunner()
SAMPLES = Path(__file__).resolve().parents[1] / "data_samples"


def _error(r) -> str:  # noqa: ANN001 - click Result
    return (r.stderr if r.stderr_bytes is not None else r.output).strip()


# --------------------------------------------------------------------------- 1. self-check
def test_compensate_file_fitted_on_itself_warns_without_a_box(tmp_path, caplog):
    from aeromag.workflows.compensate import compensate_file

    out = tmp_path / "out.csv"
    with caplog.at_level(logging.WARNING, logger="aeromag"):
        res = compensate_file(SAMPLES / "survey.csv", out)  # no self_check=: the default
    assert res.report.self_calibration is not None
    assert res.report.self_calibration.calibration_box is False
    warned = [r.getMessage() for r in caplog.records if "without a calibration box" in
              r.getMessage()]
    assert warned and "flattering" in warned[0] and "model=MODEL" in warned[0]
    rep = json.loads(out.with_suffix(".json").read_text())
    assert any("without a calibration box" in w for w in rep["warnings"])


def test_compensate_file_with_a_model_is_not_self_checked(tmp_path, caplog):
    from aeromag.workflows.compensate import calibrate_file, compensate_file

    model = tmp_path / "model.json"
    calibrate_file(SAMPLES / "calibration.csv", model)
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="aeromag"):
        res = compensate_file(SAMPLES / "survey.csv", tmp_path / "out.csv", model=model)
    assert res.report.self_calibration is None
    assert not any("calibration box" in r.getMessage() for r in caplog.records)


# --------------------------------------------------------------------------- 2. refusals
@pytest.fixture()
def logs(tmp_path):
    d = tmp_path / "logs"
    d.mkdir()
    shutil.copy(SAMPLES / "survey.csv", d / "surv.csv")
    (tmp_path / "model.json").write_text("{}")  # never read: the options are refused first
    return d


def test_batch_model_refuses_noise_factor(logs, tmp_path):
    out = tmp_path / "out"
    r = runner.invoke(app, ["batch", str(logs), "-o", str(out), "--model",
                            str(tmp_path / "model.json"), "--noise-factor", "2"])
    assert r.exit_code == 1, r.output
    err = _error(r)
    assert err == ("error: --noise-factor steers a fit, and --model applies a saved model: "
                   "nothing is fitted; drop --noise-factor (or drop --model to fit)")
    assert "ok" not in r.stdout
    assert not (out / "surv_comp.csv").exists()


@pytest.mark.parametrize("flag,value", [("--noise-factor", "2"), ("--ridge", "1e-3"),
                                        ("--max-condition", "1e7"), ("--min-excess", "2"),
                                        ("--pca-variance", "0.5"), ("--shrink", "0"),
                                        ("--no-decimate", None), ("--no-screen", None)])
def test_compensate_online_refuses_batch_fit_options(tmp_path, flag, value):
    out = tmp_path / "out.csv"
    args = ["compensate", str(SAMPLES / "survey.csv"), "-o", str(out), "--online", flag]
    r = runner.invoke(app, args + ([value] if value is not None else []))
    assert r.exit_code == 1, r.output
    err = _error(r)
    assert err.count("\n") == 0
    assert err.startswith(f"error: {flag} steers the batch fit or its screening, and --online")
    assert err.endswith(f"drop {flag} (or drop --online)")
    assert not out.exists()


def test_compensate_online_refuses_fom(tmp_path):
    # the recursive fit computes no Figure of Merit: --fom was accepted and did nothing
    out = tmp_path / "out.csv"
    r = runner.invoke(app, ["compensate", str(SAMPLES / "calibration.csv"), "-o", str(out),
                            "--online", "--fom"])
    assert r.exit_code == 1, r.output
    err = _error(r)
    assert err.count("\n") == 0 and err.startswith("error: --fom: --online reports no Figure")
    assert not out.exists()


@pytest.mark.parametrize("command", ["compensate", "calibrate", "batch"])
@pytest.mark.parametrize("flag", ["--noise-factor", "--min-excess", "--min-excess-nt",
                                  "--pca-variance", "--screen-quantile"])
def test_no_screen_refuses_screening_thresholds(tmp_path, logs, command, flag):
    inp = logs if command == "batch" else SAMPLES / "survey.csv"
    out = tmp_path / ("out" if command == "batch" else
                      "m.json" if command == "calibrate" else "out.csv")
    r = runner.invoke(app, [command, str(inp), "-o", str(out), "--no-screen", flag, "0.5"])
    assert r.exit_code == 1, r.output
    assert _error(r) == (f"error: {flag} steers the screening, and --no-screen skips it: "
                         f"nothing uses it; drop {flag} (or drop --no-screen)")
    assert not out.exists()


def test_online_keeps_terms_and_no_screen_keeps_shrink(tmp_path):
    # --terms steers the recursive fit; --shrink the per-segment coefficients OUT.json reports.
    r = runner.invoke(app, ["compensate", str(SAMPLES / "survey.csv"), "-o",
                            str(tmp_path / "a.csv"), "--online", "--terms", "9"])
    assert r.exit_code == 0, r.output
    r = runner.invoke(app, ["compensate", str(SAMPLES / "survey.csv"), "-o",
                            str(tmp_path / "b.csv"), "--no-screen", "--shrink", "0"])
    assert r.exit_code == 0, r.output
    assert json.loads((tmp_path / "b.json").read_text())["screening"]["shrink"] == 0.0


# --------------------------------------------------------------------------- 3. parameters
@pytest.mark.parametrize("field", [(5e4, 70), 5e4, (5e4, 70, 0, 1)])
def test_compass_file_earth_field_not_three_numbers(tmp_path, field):
    import aeromag

    with pytest.raises(InputError, match=r"earth_field=\(F, I, D\)") as e:
        aeromag.workflows.compass_file(SAMPLES / "calibration.csv", tmp_path / "c.csv",
                                       earth_field=field)
    assert "calibration.csv" in str(e.value)


def test_compass_file_earth_field_not_numbers(tmp_path):
    import aeromag

    with pytest.raises(InputError, match=r"earth_field=\(F, I, D\).*must be numbers"):
        aeromag.workflows.compass_file(SAMPLES / "calibration.csv", tmp_path / "c.csv",
                             earth_field=(5e4, "seventy", 0))


def test_bad_unit_names_the_parameter_and_the_flag(tmp_path):
    import aeromag

    with pytest.raises(InputError) as e:
        aeromag.workflows.compass_file(SAMPLES / "calibration.csv", tmp_path / "c.csv",
                             earth_field=(5e4, 70, 0), units={"flux": "furlong"})
    assert "units={'flux': 'furlong'}: unknown field unit 'furlong'" in str(e.value)
    with pytest.raises(InputError, match=r"units=\{'time': 'fortnight'\}: unknown time unit"):
        aeromag.workflows.compensate_file(SAMPLES / "survey.csv", tmp_path / "o.csv",
                                units={"time": "fortnight"})
    for cmd, out in (("compass", "c.csv"), ("compensate", "o.csv")):
        extra = ["--earth-field", "5e4", "70", "0"] if cmd == "compass" else []
        r = runner.invoke(app, [cmd, str(SAMPLES / "calibration.csv"), "-o",
                                str(tmp_path / out), "--units", "flux=furlong", *extra])
        assert r.exit_code == 1, r.output
        err = _error(r)
        assert "--units flux=furlong: unknown field unit 'furlong'" in err, err
        assert "units=" not in err


# --------------------------------------------------------------------------- 4. wording
def test_improvement_ratio_just_below_one_reads_below_one():
    (w,) = metric_warnings(_m({"improvement_ratio": 0.9996, "residual_std_nT": 0.1}), fitted=True)
    assert "improvement ratio 0.9996 < 1" in w
    (w,) = metric_warnings(_m({"improvement_ratio": 0.5, "residual_std_nT": 0.1}))
    assert "improvement ratio 0.5 < 1" in w


def test_online_ratio_below_one_gives_the_online_advice():
    m = CompensationMetrics(improvement_ratio=0.9, residual_std_nT=0.1)
    (w,) = metric_warnings(m, fitted=True, online=True)
    assert "calibrate on a flight with maneuvers" not in w
    assert "online fit" in w and "forgetting=" in w and "terms=" in w
    from aeromag.cli._options import flag_message

    cli = flag_message(w)
    assert "--forgetting 0.9999" in cli and "--terms 9" in cli
    (w,) = metric_warnings(_m({"improvement_ratio": 0.9, "residual_std_nT": 0.1}), fitted=True)
    assert "calibrate on a flight with maneuvers" in w  # the batch fit keeps its advice


# --------------------------------------------------------------------------- 5. track
def test_track_summary_counts_the_checked_legs_first(tmp_path):
    out = tmp_path / "t.csv"
    r = runner.invoke(app, ["track", str(SAMPLES / "calibration.csv"), "--plan",
                            str(SAMPLES / "plan.csv"), "-o", str(out)])
    assert r.exit_code == 0, r.output
    rep = json.loads(out.with_suffix(".json").read_text())
    n, checked = rep["n_legs"], rep["n_legs_checked"]
    assert 0 < checked < n
    legs = "leg" if checked == 1 else "legs"
    assert f": 0 of {checked} checked {legs} flagged ({n - checked} of {n} not flown" in r.output
    assert f"/{n} legs flagged" not in r.output
