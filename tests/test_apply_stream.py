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


# --------------------------------------------------------------------------- the writer
def _hostile_extra(n: int):
    import numpy as np
    import pandas as pd

    rng = np.random.default_rng(7)
    tl = rng.normal(size=n) * 30
    tl[::97] = np.nan
    tl[1::89] = 3.0  # integral: written 3.0, as pandas writes it
    tl[2::83] = -0.0
    tl[3::79] = np.inf
    tl[4::73] = -np.inf
    tl[5::71] = 5e-324
    tl[6::67] = 1e22
    seg = np.arange(n, dtype=np.int64) // 50 - 3
    return pd.DataFrame({
        "mag_tl": tl, "mag_comp": 50000 + rng.normal(size=n),
        "segment": pd.arrays.IntegerArray(seg, np.arange(n) % 61 == 0),
        "segment_kept": np.arange(n) % 7 != 0, "big": np.int64(2) ** 62 - np.arange(n)})


@pytest.mark.parametrize("ending", [b"\n", b""])
def test_passthrough_writes_what_the_csv_writer_writes(tmp_path, monkeypatch, ending):
    """The lines copied with the added columns joined on (pyarrow's cast text, in blocks of
    whole lines) are byte for byte the whole table written by write_csv."""
    import pandas as pd

    import aeromag.io.csv as csv_mod
    from aeromag.io.csv_write import write_csv_passthrough

    monkeypatch.setattr(csv_mod, "PASSTHROUGH_BLOCK_BYTES", 4096)  # many blocks
    df = hand_flight(seed=5, n=3000)[0]
    src = tmp_path / "src.csv"
    write_csv(df, src)
    if not ending:
        src.write_bytes(src.read_bytes().rstrip(b"\n"))
    extra = _hostile_extra(len(df))
    out, ref = tmp_path / "out.csv", tmp_path / "ref.csv"
    assert write_csv_passthrough(src, list(df.columns), extra, out)
    write_csv(pd.concat([df, extra], axis=1), ref)
    assert out.read_bytes() == ref.read_bytes()


def test_passthrough_text_and_crlf(tmp_path):
    """Text that needs quoting is refused (the caller writes it another way); CRLF lines are
    joined without their CR, as before."""
    import pandas as pd

    from aeromag.io.csv_write import write_csv_passthrough

    src = tmp_path / "src.csv"
    src.write_bytes(b"time,mag\r\n0,1.5\r\n1,2.5\r\n")
    extra = pd.DataFrame({"mag_tl": [0.5, float("nan")], "segment_kept": [True, False]})
    out = tmp_path / "out.csv"
    assert write_csv_passthrough(src, ["time", "mag"], extra, out)
    assert out.read_bytes() == b"time,mag,mag_tl,segment_kept\n0,1.5,0.5,true\n1,2.5,,false\n"
    note = pd.DataFrame({"note": ["a,b", "c"]})
    assert not write_csv_passthrough(src, ["time", "mag"], note, tmp_path / "x.csv")
