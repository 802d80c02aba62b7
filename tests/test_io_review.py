"""Hostile inputs found by the IO review (issue 16's hidden-corpus warning).

Each class here failed before its fix: a FIFO given as the log hung both reading paths; a
symbolic-link loop gave a traceback; nested Parquet columns gave a traceback on the chunked
path and a lossy ``[1. 2.]`` text on the in-memory one; a Parquet column name used twice was
worded as a damaged file in memory; a 10 MB cell was echoed whole in the error line.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from aeromag.errors import InputError
from aeromag.io import read_log
from aeromag.io.messages import MAX_ECHO_CHARS, clean
from aeromag.io.stream import iter_log_batches

ROOT = Path(__file__).resolve().parents[1]


def _log(n: int = 60) -> pd.DataFrame:
    t = np.arange(n) * 0.1
    return pd.DataFrame({"time": t, "mag": 50000 + np.sin(t), "flux_x": 20000 + t,
                         "flux_y": 1000 - t, "flux_z": 45000 + 0 * t})


def _both_paths(p: Path, match: str) -> None:
    with pytest.raises(InputError, match=match):
        read_log(p)
    with pytest.raises(InputError, match=match):
        list(iter_log_batches(p, None, batch_rows=10))


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this system")
def test_fifo_as_log_is_an_error_not_a_hang(tmp_path):
    p = tmp_path / "f.csv"
    os.mkfifo(p)  # opening it for reading would block for ever (no writer)
    _both_paths(p, "not a regular file")


def test_symlink_loop_and_dangling_link(tmp_path):
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    os.symlink(b, a)
    os.symlink(a, b)
    _both_paths(a, "loop of symbolic links")
    d = tmp_path / "d.csv"
    os.symlink(tmp_path / "missing.csv", d)
    _both_paths(d, "symbolic link to a file that does not exist")


def test_symlink_loop_through_the_command_has_no_traceback(tmp_path):
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    os.symlink(b, a)
    os.symlink(a, b)
    r = subprocess.run([sys.executable, "-m", "aeromag", "compensate", str(a), "-o",
                        str(tmp_path / "o.csv")], capture_output=True, text=True, timeout=120,
                       cwd=tmp_path)
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr
    assert r.stderr.strip().splitlines() == [r.stderr.strip()]
    assert "a.csv: a loop of symbolic links" in r.stderr
    assert {f.name for f in tmp_path.iterdir()} == {"a.csv", "b.csv"}


@pytest.mark.parametrize("kind", ["list", "struct"])
def test_nested_parquet_column_is_an_error_on_both_paths(tmp_path, kind):
    pa = pytest.importorskip("pyarrow")
    pq = pytest.importorskip("pyarrow.parquet")
    df = _log()
    t = pa.Table.from_pandas(df, preserve_index=False)
    col = (pa.array([[1.0, 2.0]] * len(df)) if kind == "list"
           else pa.array([{"a": 1, "b": "x"}] * len(df)))
    p = tmp_path / "n.parquet"
    pq.write_table(t.append_column("extra", col), p)
    _both_paths(p, "column 'extra' is nested")


def test_parquet_name_used_twice_is_named_in_memory(tmp_path):
    pa = pytest.importorskip("pyarrow")
    pq = pytest.importorskip("pyarrow.parquet")
    t = pa.Table.from_pandas(_log(), preserve_index=False)
    t = pa.Table.from_arrays(list(t.columns) + [t.column("mag")], names=t.column_names + ["mag"])
    p = tmp_path / "d.parquet"
    pq.write_table(t, p)
    _both_paths(p, "column 'mag' appears more than once")


def test_huge_cell_is_not_echoed_whole(tmp_path):
    p = tmp_path / "l.csv"
    text = _log().to_csv(index=False).splitlines()
    text[1] += "," + "1" * 200_000
    p.write_text("\n".join(text) + "\n")
    with pytest.raises(InputError) as e:
        read_log(p)
    msg = clean(e.value)
    assert "line 2" in msg and "more fields" in msg and "200000" not in msg
    assert len(msg) < 3 * MAX_ECHO_CHARS, len(msg)
    assert "characters]..." in msg
    assert clean("x" * MAX_ECHO_CHARS) == "x" * MAX_ECHO_CHARS  # short text unchanged


@pytest.mark.parametrize("key,value,match", [
    ("band_hz", [0.9, 0.1], "pass band it records is"),
    ("band_hz", "NaN", "pass band it records is"),
    ("sampling_rate_hz", -1, "sampling_rate_hz is -1"),
    ("filter_order", 1e9, "filter_order is"),
    ("mag_from_fluxgate", "yes", "mag_from_fluxgate is"),
])
def test_model_fit_settings_are_validated(tmp_path, key, value, match):
    """A model whose recorded fit settings are nonsense was accepted (IO review)."""
    import json

    from aeromag.io.model_file import read_model_document

    terms = ["cx", "cy", "cz"]
    doc = {"terms": terms, "coef": [1.0, 2.0, 3.0], "scale_nT": 50000.0, "band_hz": [0.1, 0.9],
           "sampling_rate_hz": 10.0, "filter_order": 4, "mag_from_fluxgate": False}
    p = tmp_path / "m.json"
    p.write_text(json.dumps(doc))
    assert read_model_document(p)["band_hz"] == [0.1, 0.9]
    doc[key] = value
    p.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=match):
        read_model_document(p)
    doc[key] = None  # not recorded: accepted
    p.write_text(json.dumps(doc))
    read_model_document(p)
