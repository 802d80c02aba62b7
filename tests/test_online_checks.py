"""``aeromag compensate --online`` runs the batch fit's metric checks (issue 15).

The online fit's headline metrics get :func:`aeromag.compensation.checks.check_metrics` (one
implementation): an improvement ratio below 1 or an implausible residual is a warning,
recorded in OUT.json's ``warnings`` (from the command line and from the Python API), and
``--strict`` makes it the command's one-line error with nothing written.

The log that the online fit makes worse: a flight with maneuvers and no aircraft interference
at all (every TL coefficient 0).  The recursive estimate chases the sensor noise, so
``mag - mag_tl`` varies more in band than ``mag`` did (improvement ratio about 0.89).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.compensation import CompensationMetrics

from .conftest import hand_flight

_m = CompensationMetrics.from_dict  # a metrics block as a report file holds it

runner = CliRunner()


def _log(path, **kw):
    df, _ = hand_flight(seed=1, n=6000, **kw)
    df.drop(columns=["truth_mag_tl", "truth_clean"]).to_csv(path, index=False)
    return path


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("online_checks")
    return {"worse": _log(d / "quiet.csv", coef=np.zeros(16)),
            "good": _log(d / "good.csv"),
            "noisy": _log(d / "noisy.csv", noise=200.0)}


def _report(out):
    return json.loads(out.with_suffix(".json").read_text())


def test_an_online_fit_that_makes_things_worse_is_a_recorded_warning(logs, tmp_path):
    from aeromag.cli._options import flag_message
    from aeromag.compensation.checks import metric_warnings

    log = str(logs["worse"])
    out = tmp_path / "o.csv"
    r = runner.invoke(app, ["compensate", "--online", log, "-o", str(out)])
    assert r.exit_code == 0, r.output
    rep = _report(out)
    ratio = rep["metrics"]["improvement_ratio"]
    assert 0.5 < ratio < 1.0
    warned = [w for w in rep.get("warnings", []) if "improvement ratio" in w]
    assert len(warned) == 1 and warned[0].startswith(f"{log}: ") and "< 1" in warned[0]
    # The words of the batch fit's checks (one implementation), with the online advice
    # (forgetting=, terms=) spelt as the command line's flags.
    assert warned == [flag_message(w) for w in
                      metric_warnings(_m(rep["metrics"]), source=log, fitted=True, online=True)]
    assert "--forgetting 0.9999" in warned[0]
    assert "improvement ratio" in r.output  # and on the terminal


def test_strict_refuses_it_with_one_line_and_writes_nothing(logs, tmp_path):
    out = tmp_path / "strict" / "o.csv"
    r = runner.invoke(app, ["compensate", "--online", str(logs["worse"]), "-o", str(out),
                            "--strict"])
    assert r.exit_code == 1, r.output
    err = [ln for ln in r.output.splitlines() if ln.startswith("error: ")]
    assert len(err) == 1 and "improvement ratio" in err[0] and "--strict" in err[0]
    assert "Traceback" not in r.output
    assert not out.exists() and not out.with_suffix(".json").exists()
    assert not out.parent.exists() or list(out.parent.iterdir()) == []  # no temporaries


def test_an_implausible_residual_is_a_warning(logs, tmp_path):
    out = tmp_path / "n.csv"
    r = runner.invoke(app, ["compensate", "--online", str(logs["noisy"]), "-o", str(out)])
    assert r.exit_code == 0, r.output
    rep = _report(out)
    assert rep["metrics"]["residual_std_nT"] > 50.0
    assert any("is implausible for a compensated survey" in w for w in rep["warnings"])


def test_a_good_online_fit_passes_strict(logs, tmp_path):
    out = tmp_path / "g.csv"
    r = runner.invoke(app, ["compensate", "--online", str(logs["good"]), "-o", str(out),
                            "--strict"])
    assert r.exit_code == 0, r.output
    rep = _report(out)
    assert rep["metrics"]["improvement_ratio"] > 2.0
    assert not rep.get("warnings")


def test_the_python_api_records_the_warning_too(logs, tmp_path, caplog):
    from aeromag.workflows.online_compensate import compensate_online_file

    out = tmp_path / "api.csv"
    with caplog.at_level("WARNING", logger="aeromag"):
        rep = compensate_online_file(logs["worse"], out)
    assert any("improvement ratio" in w for w in rep.warnings)
    assert _report(out)["warnings"] == rep.warnings
    assert "improvement ratio" in caplog.text


def test_the_frame_function_logs_it(logs, caplog):
    import pandas as pd

    from aeromag.workflows.online_compensate import compensate_online_frame

    df = pd.read_csv(logs["worse"])
    with caplog.at_level("WARNING", logger="aeromag"):
        _, rep, _ = compensate_online_frame(df, source="quiet.csv")
    assert rep.metrics.improvement_ratio < 1.0
    assert "quiet.csv: the online fit leaves more band-passed variation" in caplog.text
    assert "forgetting=0.9999" in caplog.text  # the library's words
