"""The library names parameters, the command line names flags, through one mapping.

The Python API says ``columns={'mag': 'mag_1_uc'}``, ``units={'flux': 'uT'}``,
``mag_from_fluxgate=True``, ``band_hz``; every command says ``--col mag=mag_1_uc``,
``--units flux=uT``, ``--mag-from-fluxgate``, ``--band`` -- in its errors, its warnings on
the terminal and in OUT.json, and (``aeromag batch``) in batch_summary.csv/.json, whether the
log ran in this process or in a worker.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from aeromag.cli import app

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "data_samples"
runner = CliRunner()
LIBRARY_WORDS = ("columns={", "units={", "mag_from_fluxgate", "band_hz")


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """A folder of two logs (a misnamed scalar; a fluxgate in uT) and a model for them."""
    from aeromag.workflows.compensate import calibrate_file

    d = tmp_path_factory.mktemp("messages")
    folder = d / "bin"
    folder.mkdir()
    df = pd.read_csv(SAMPLES / "survey.csv")
    df.rename(columns={"mag": "mag_1_uc"}).to_csv(folder / "renamed.csv", index=False)
    micro = df.copy()
    micro[["flux_x", "flux_y", "flux_z"]] /= 1000.0
    micro.to_csv(folder / "micro.csv", index=False)
    model = d / "model.json"
    calibrate_file(SAMPLES / "calibration.csv", model)
    return d, folder, model


def _library_words(text: str) -> list[str]:
    return [w for w in LIBRARY_WORDS if w in text]


def test_batch_cli_names_flags_in_output_summary_and_reports(logs):
    """Two workers (their own processes): the reasons and warnings printed, in
    batch_summary.csv/.json and in each log's report name the flags."""
    d, folder, model = logs
    out = d / "cli_out"
    factory = logging.getLogRecordFactory()
    r = runner.invoke(app, ["batch", str(folder), "-o", str(out), "--model", str(model),
                            "--workers", "2", "--no-progress"])
    assert r.exit_code == 1, r.output  # renamed.csv fails
    assert logging.getLogRecordFactory() is factory  # the CLI's mapping is undone
    assert "map it with --col mag=mag_1_uc, or pass --mag-from-fluxgate" in r.output
    assert "pass --units flux=uT" in r.output
    assert _library_words(r.output) == []
    csv_text = (out / "batch_summary.csv").read_text()
    assert "--col mag=mag_1_uc" in csv_text and "--units flux=uT" in csv_text
    assert _library_words(csv_text) == []
    summary = json.loads((out / "batch_summary.json").read_text())
    files = {Path(f["input"]).name: f for f in summary["files"]}
    assert "--col mag=mag_1_uc" in files["renamed.csv"]["error"]
    assert any("--units flux=uT" in w for w in files["micro.csv"]["warnings"])
    assert _library_words(json.dumps(summary["files"])) == []
    rep = json.loads((out / "micro_comp.json").read_text())
    assert any("--units flux=uT" in w for w in rep["warnings"])
    assert _library_words(json.dumps(rep["warnings"])) == []
    # the rest of the summary is what run_batch wrote
    assert summary["n_failed"] == 1 and summary["n_warn"] == 1


def test_batch_api_names_parameters(logs):
    """run_batch (here in this process, after the CLI ran) keeps the parameter names."""
    from aeromag.workflows.batch import run_batch

    d, folder, model = logs
    s = run_batch([str(folder)], d / "api_out", model=model, workers=1, progress=False)
    res = {Path(r.input).name: r for r in s.results}
    assert "columns={'mag': 'mag_1_uc'}" in res["renamed.csv"].error
    assert "mag_from_fluxgate=True" in res["renamed.csv"].error
    assert any("units={'flux': 'uT'}" in w for w in res["micro.csv"].warnings)
    assert "--units" not in " ".join(res["micro.csv"].warnings)
    assert "--col" not in (d / "api_out" / "batch_summary.csv").read_text()


def test_api_warning_names_the_parameter(caplog):
    """compensate() on a fluxgate in uT: the warning names units={'flux': 'uT'}, no flag."""
    from aeromag.compensation import CompensationConfig
    from aeromag.compensation.prepare import total_field_from_fluxgate
    from aeromag.workflows.compensate import compensate

    df = pd.read_csv(SAMPLES / "survey.csv")
    df[["flux_x", "flux_y", "flux_z"]] /= 1000.0
    with caplog.at_level("WARNING", logger="aeromag"):
        compensate(df)
    assert "pass units={'flux': 'uT'} (or mT, G)" in caplog.text
    assert "--units" not in caplog.text
    caplog.clear()
    with caplog.at_level("WARNING", logger="aeromag"):
        assert total_field_from_fluxgate(df, CompensationConfig(mag_from_fluxgate=True), "x")
    assert "x: mag_from_fluxgate=True: the log's 'mag' column is not used" in caplog.text


def test_cli_warning_in_out_json_names_the_flag(logs, tmp_path):
    """The same warning from 'aeromag compensate' (in this process): terminal and OUT.json."""
    _, folder, model = logs
    out = tmp_path / "o.csv"
    r = runner.invoke(app, ["compensate", str(folder / "micro.csv"), "-o", str(out),
                            "--model", str(model)])
    assert r.exit_code == 0, r.output
    assert "pass --units flux=uT (or mT, G)" in r.output
    assert "check their units (--units mag=..., --units flux=...)" in r.output
    warned = json.loads(out.with_suffix(".json").read_text())["warnings"]
    assert any("--units flux=uT" in w for w in warned)
    assert _library_words(json.dumps(warned)) == []


@pytest.fixture(scope="module")
def ms_log(tmp_path_factory):
    """The mission log with its time in milliseconds since 1970."""
    d = tmp_path_factory.mktemp("ms")
    df = pd.read_csv(SAMPLES / "mission.csv")
    df["time"] = df["time"] * 1000.0 + 1.7e12
    p = d / "ms.csv"
    df.to_csv(p, index=False)
    return p


@pytest.mark.parametrize("cmd", ["track", "detect", "navigate"])
def test_every_command_maps_library_errors(cmd, ms_log, tmp_path):
    """A time column in ms: the library says units={'time': 'ms'}, each command --units."""
    args = [cmd, str(ms_log), "-o", str(tmp_path / "o.csv")]
    if cmd == "track":
        args += ["--plan", str(SAMPLES / "mission_plan.csv")]
    r = runner.invoke(app, args)
    assert r.exit_code == 1, r.output
    err = [ln for ln in r.output.splitlines() if ln.startswith("error: ")]
    assert len(err) == 1 and "pass --units time=ms" in err[0], r.output
    assert _library_words(r.output) == []


def test_library_error_names_the_parameter(ms_log):
    from aeromag.errors import InputError
    from aeromag.io import read_log

    with pytest.raises(InputError, match=r"pass units=\{'time': 'ms'\}"):
        read_log(ms_log)
