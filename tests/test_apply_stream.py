"""Applying a saved model, streamed or in memory: the library names Python parameters.

The reader and the chunked mode word their errors for a Python caller
(``allow_truncated=True``, ``chunk_rows=``, ``columns={'NAME': 'SOURCE'}``, ``lowpass_hz``);
the command line turns those words into its flags (``--allow-truncated``, ``--chunk-rows``,
``--col``, ``--lowpass``) through :func:`aeromag.cli._options.flag_message`.
"""

from __future__ import annotations

import re

import pytest
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.compensation.config import CompensationConfig
from aeromag.errors import InputError
from aeromag.io import read_log, write_csv
from aeromag.workflows.chunked import apply_model_chunked, overlap_rows
from aeromag.workflows.compensate import calibrate_file

from .conftest import hand_flight

runner = CliRunner()
FLAG = re.compile(r"(?<![\w-])--[a-z]")


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("apply_stream")
    src = d / "log.csv"
    write_csv(hand_flight(seed=3, n=4000)[0], src)
    model = d / "m.json"
    calibrate_file(src, model)
    return d, src, model


def _cut_last_row(src, dest):
    b = src.read_bytes()
    dest.write_bytes(b[: b.rfind(b"\n", 0, len(b) - 1) + 12])  # inside the last row
    return dest


def test_truncated_row_names_the_parameter_and_the_cli_the_flag(files):
    d, src, model = files
    p = _cut_last_row(src, d / "cut.csv")
    with pytest.raises(InputError, match=r"cut.csv: line \d+: the last row .*allow_truncated=True")\
            as e:
        read_log(p)
    assert not FLAG.search(str(e.value))
    assert len(read_log(p, allow_truncated=True)) == len(read_log(src)) - 1
    r = runner.invoke(app, ["compensate", str(p), "--model", str(model), "-o",
                            str(d / "cut_out.csv")])
    assert r.exit_code != 0
    assert "--allow-truncated to drop that row" in r.output and "allow_truncated" not in r.output


def test_chunked_errors_name_parameters(files):
    d, src, model = files
    with pytest.raises(InputError, match=r"chunk_rows=0: must be a positive row count") as e:
        apply_model_chunked(src, d / "a.csv", model, chunk_rows=0)
    assert not FLAG.search(str(e.value))
    with pytest.raises(InputError, match=r"the chunked mode \(chunk_rows=\) writes CSV") as e:
        apply_model_chunked(src, d / "a.parquet", model, chunk_rows=100)
    assert not FLAG.search(str(e.value))
    renamed = d / "renamed.csv"
    renamed.write_text(src.read_text().replace("flux_x", "fx", 1))
    with pytest.raises(InputError, match=r"flux_x; map them with columns=\{'NAME': 'SOURCE'\}")\
            as e:
        apply_model_chunked(renamed, d / "a.csv", model, chunk_rows=100)
    assert not FLAG.search(str(e.value))
    cfg = CompensationConfig(band_hz=(0.1, 0.5), lowpass_hz=7.0)
    with pytest.raises(InputError, match=r"lowpass_hz: 7 Hz is not below the Nyquist") as e:
        overlap_rows(10.0, cfg)
    assert not FLAG.search(str(e.value))


def test_chunked_cli_names_the_flags(files):
    d, src, model = files
    r = runner.invoke(app, ["compensate", str(src), "--model", str(model), "--chunk-rows",
                            "100", "-o", str(d / "x.parquet")])
    assert r.exit_code != 0
    assert "the chunked mode (--chunk-rows) writes CSV" in r.output
    assert "without --chunk-rows for Parquet" in r.output and "chunk_rows" not in r.output
    renamed = d / "renamed_cli.csv"
    renamed.write_text(src.read_text().replace("flux_x", "fx", 1))
    r = runner.invoke(app, ["compensate", str(renamed), "--model", str(model), "--chunk-rows",
                            "100", "-o", str(d / "y.csv")])
    assert r.exit_code != 0
    assert "map them with --col NAME=SOURCE" in r.output and "columns={" not in r.output
