"""Help text, ``--version``, usage errors and column-map warnings of the command line."""

from __future__ import annotations

import logging
import re
import subprocess
import sys

import pytest
import typer.main
from typer.testing import CliRunner

import aeromag
from aeromag.cli import app
from aeromag.cli._app import column_options

from .conftest import hand_flight

runner = CliRunner()

COMMANDS = ("compensate", "calibrate", "simulate", "track", "batch", "report", "compass", "detect",
            "navigate", "grid", "level")


def _help(*args: str) -> str:
    r = runner.invoke(app, [*args, "--help"], terminal_width=100)
    assert r.exit_code == 0, r.output
    return r.output


def test_version():
    r = runner.invoke(app, ["--version"])
    assert r.exit_code == 0
    assert r.output.strip() == f"aeromag {aeromag.__version__}"
    p = subprocess.run([sys.executable, "-m", "aeromag", "--version"], capture_output=True,
                       text=True, timeout=60)
    assert p.returncode == 0 and p.stdout.strip() == f"aeromag {aeromag.__version__}"


def test_overview_lists_each_command_with_one_whole_sentence():
    text = _help()
    lines = text[text.index("Commands:"):].splitlines()[1:]
    rows = {ln.split()[0]: ln.split(None, 1)[1] for ln in lines if ln.strip()}
    assert set(rows) == set(COMMANDS)
    for name, summary in rows.items():
        assert summary.endswith(".") and not summary.endswith("..."), (name, summary)
    assert "--version" in text


@pytest.mark.parametrize("command", COMMANDS)
def test_help_text_is_shown_as_written(command):
    """Every bracket of every help string survives (no markup eats '[columns]'), and flags are
    not shown as if they took a value."""
    text = _help(command)
    assert "<bool>" not in text
    click_cmd = typer.main.get_command(app).commands[command]
    for param in click_cmd.params:
        for token in re.findall(r"\S*\[[^\]]*\]\S*", getattr(param, "help", None) or ""):
            assert token.rstrip(".,;)") in text, (command, param.name, token)
    for token in re.findall(r"\S*\[[^\]]*\]\S*", click_cmd.help or ""):
        assert token.rstrip(".,;)") in text, (command, token)


def test_brackets_and_metavars():
    for command in ("compensate", "calibrate", "track", "batch"):
        assert "[columns]" in _help(command) and "[units]" in _help(command)
    batch = _help("batch")
    assert "'aeromag[dask]'" in batch
    assert "--threshold M " in batch and "--plan PLAN.csv" in batch
    assert "--model MODEL.json" in batch and "-o OUTDIR" in batch
    assert "INPUTS" in batch.splitlines()[0] and "{inputs}" not in batch
    track = _help("track")
    assert "--threshold M " in track and "--plan PLAN.csv" in track
    assert "SURVEY.csv" in track.splitlines()[0]
    assert "SURVEY.csv" in _help("compensate").splitlines()[0]
    assert "CAL.csv" in _help("calibrate").splitlines()[0]


def test_simulate_help_lists_the_mission_files():
    text = _help("simulate")
    for name in ("calibration.csv", "survey.csv", "plan.csv", "truth.json", "mission.csv",
                 "mission_plan.csv", "mission_truth.json"):
        assert name in text


def test_non_numeric_band_is_a_short_usage_error(tmp_path):
    r = runner.invoke(app, ["compensate", str(tmp_path / "x.csv"), "-o", str(tmp_path / "o.csv"),
                            "--band", "a", "b"])
    assert r.exit_code == 2
    assert "Invalid value for '--band'" in r.output and "number" in r.output
    assert "Traceback" not in r.output and "╭" not in r.output
    assert len(r.output.strip().splitlines()) <= 4


def test_non_canonical_map_target_warns(caplog, tmp_path):
    with caplog.at_level(logging.WARNING, logger="aeromag.cli"):
        cols, _ = column_options(["foo=mag", "mag_heading=compass", "flux_x=fx"], None, None)
    assert cols == {"foo": "mag", "mag_heading": "compass", "flux_x": "fx"}
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1 and "\n" not in warnings[0]
    assert "--col foo=mag" in warnings[0] and "--mag-from-fluxgate" in warnings[0]
    assert "NAME=SOURCE" in warnings[0]
    caplog.clear()
    toml = tmp_path / "m.toml"
    toml.write_text('[columns]\nbar = "gps_lat"\nlat = "lat1"\n')
    with caplog.at_level(logging.WARNING, logger="aeromag.cli"):
        column_options(None, toml, None)
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1 and "--map" in warnings[0] and "'bar'" in warnings[0]


def test_shipped_map_file_draws_no_warning(caplog):
    from pathlib import Path

    shipped = Path(__file__).resolve().parents[1] / "cli" / "magnav_sgl_map.toml"
    with caplog.at_level(logging.WARNING, logger="aeromag.cli"):
        column_options(None, shipped, None)
    assert not caplog.records


def test_cli_warns_on_renamed_mag_even_in_batch(tmp_path):
    df, _ = hand_flight(seed=2, n=3000)
    log = tmp_path / "f.csv"
    df.drop(columns=["truth_mag_tl", "truth_clean"]).to_csv(log, index=False)
    for args in (["compensate", str(log), "-o", str(tmp_path / "c.csv")],
                 ["batch", str(log), "-o", str(tmp_path / "b"), "--workers", "1",
                  "--no-progress"]):
        p = subprocess.run([sys.executable, "-m", "aeromag", *args, "--col", "foo=mag"],
                           capture_output=True, text=True, timeout=120)
        # Without its scalar the log is refused (issue 15: no silent fluxgate fallback) ...
        assert p.returncode == 1, p.stderr
        assert "no 'mag' column" in p.stderr + p.stdout
        # ... and the map entry that caused it is named once.
        lines = [ln for ln in p.stderr.splitlines() if "foo=mag" in ln]
        assert len(lines) == 1 and lines[0].startswith("WARNING: --col foo=mag"), p.stderr
