"""Issue 30, readers: every reader and every path (whole file, --chunk-rows) fails the same
one-line way on a stray quote, a header column named like a column the reader makes, a
channel that cannot be opened, and reads a column map the same way (hypothesis fuzz)."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.errors import InputError
from aeromag.io import read_log
from aeromag.io.stream import iter_log_batches

DATA = Path(__file__).resolve().parents[1] / "data_samples"
MAGDRONE = DATA / "formats" / "magdrone_r3_sample.csv"
MAGARROW = DATA / "formats" / "magarrow_sample.csv"
FUZZ = settings(max_examples=25, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])


def _both_paths(path: Path, **kw) -> list[str]:
    """The errors of the whole-file reader and of the chunked reader (all columns)."""
    out = []
    with pytest.raises(InputError) as whole:
        read_log(path, **kw)
    out.append(str(whole.value))
    with pytest.raises(InputError) as chunked:
        for _ in iter_log_batches(path, None, batch_rows=7, colmap=kw.get("columns")):
            pass
    out.append(str(chunked.value))
    return out


def _lines(path: Path, repeat: int) -> tuple[list[str], int]:
    """Lines of a sample (data rows repeated ``repeat`` times) and the first data line index."""
    lines = [s.rstrip("\r\n") + "\n" for s in path.read_text(encoding="utf-8").splitlines()]
    first = next(i for i, s in enumerate(lines) if s.lstrip().startswith(("Timestamp",
                                                                          "Counter"))) + 1
    return lines[:first] + lines[first:] * repeat, first


@FUZZ
@given(which=st.sampled_from(["magdrone", "magarrow", "csv"]), at=st.integers(0, 10_000),
       field=st.integers(0, 8), big=st.booleans())
def test_a_stray_quote_is_one_line_naming_its_line(tmp_path_factory, which, at, field, big):
    """Before: ``_csv.Error: field larger than field limit (131072)`` (a traceback) once the
    rest of the file after the quote passed 128 kB; now the line of the quote, everywhere."""
    d = tmp_path_factory.mktemp("q")
    if which == "csv":
        lines = pd.read_csv(DATA / "survey.csv").iloc[: 3000 if big else 60].to_csv(
            index=False).splitlines(keepends=True)
        first, sep = 1, ","
    else:
        src = MAGDRONE if which == "magdrone" else MAGARROW
        lines, first = _lines(src, 400 if big else 1)
        sep = ";" if which == "magdrone" else ","
    i = first + at % (len(lines) - first)
    cells = lines[i].split(sep)
    j = field % max(1, len(cells) - 1)
    cells[j] = '"' + cells[j]
    lines[i] = sep.join(cells)
    p = d / f"{which}.csv"
    p.write_text("".join(lines), encoding="utf-8")
    for msg in _both_paths(p):
        assert "\n" not in msg and msg.startswith(f"{p}: line {i + 1}: "), msg
        if which != "magarrow":  # no other quote in the file: the quote is never closed
            assert "a double quote" in msg and "remove the stray quote" in msg, msg


@FUZZ
@given(which=st.sampled_from(["magdrone", "magarrow"]),
       name=st.sampled_from(["time", "time ", " mag", "lat", "flux_x", "lon"]),
       pos=st.integers(0, 40))
def test_a_header_column_named_like_a_made_column_is_refused(tmp_path_factory, which, name,
                                                             pos):
    """Before: ``ValueError: cannot insert time, already exists`` (MagArrow with a second
    ``time `` column); now one line naming the column, in both paths."""
    d = tmp_path_factory.mktemp("h")
    src = MAGDRONE if which == "magdrone" else MAGARROW
    sep = ";" if which == "magdrone" else ","
    lines, first = _lines(src, 1)
    head = lines[first - 1].rstrip("\r\n").rstrip(sep).split(sep)
    made = {"magarrow": {"time", "mag", "lat", "lon"},
            "magdrone": {"time", "flux_x", "lat", "lon"}}[which]
    k = 1 + pos % len(head)  # the first column names the format (Timestamp, Counter)
    head.insert(k, name)
    lines[first - 1] = sep.join(head) + (sep if which == "magdrone" else "") + "\n"
    for r in range(first, len(lines)):
        cells = lines[r].split(sep)
        cells.insert(k, "1")
        lines[r] = sep.join(cells)
    p = d / "log.csv"
    p.write_text("".join(lines), encoding="utf-8")
    if name.strip() not in made:
        read_log(p)  # a column the reader does not make is just another column
        return
    for msg in _both_paths(p):
        assert msg.startswith(f"{p}: line {first}, column {k + 1} ('{name.strip()}')"), msg
        assert "rename that column" in msg


def _h5(path: Path, n: int = 400, broken: str | None = None, how: str = "soft") -> Path:
    h5py = pytest.importorskip("h5py")
    s = pd.read_csv(DATA / "survey.csv").iloc[:n]
    names = {"time": "tt", "mag": "mag_1_uc", "flux_x": "flux_a_x", "flux_y": "flux_a_y",
             "flux_z": "flux_a_z", "lat": "lat", "lon": "lon", "alt": "utm_z", "line": "line"}
    with h5py.File(path, "w") as h:
        for c, k in names.items():
            if k == broken:
                h[k] = (h5py.SoftLink("/nowhere") if how == "soft"
                        else h5py.ExternalLink("missing.h5", "/x"))
            else:
                h[k] = s[c].to_numpy()
    return path


@FUZZ
@given(broken=st.sampled_from(["lat", "lon", "utm_z", "line"]),
       how=st.sampled_from(["soft", "external"]), batch=st.integers(3, 500))
def test_an_hdf5_channel_that_cannot_be_opened_is_named_in_every_path(tmp_path_factory, caplog,
                                                                     broken, how, batch):
    """Before: a ``lat`` link to nothing vanished from the output silently (exit 0)."""
    p = _h5(tmp_path_factory.mktemp("h5") / "log.h5", broken=broken, how=how)
    for read in (lambda: read_log(p),
                 lambda: pd.concat(list(iter_log_batches(p, None, batch_rows=batch)))):
        caplog.clear()
        with caplog.at_level(logging.WARNING):
            df = read()
        assert broken not in df.columns
        warned = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
        assert any(f"'{broken}' cannot be opened" in w for w in warned), warned


def test_a_damaged_hdf5_dataset_is_an_error_naming_it(tmp_path):
    h5py = pytest.importorskip("h5py")
    p = tmp_path / "d.h5"
    s = pd.read_csv(DATA / "survey.csv").iloc[:400]
    with h5py.File(p, "w") as h:
        h["tt"] = s["time"].to_numpy()
        h["mag_1_uc"] = s["mag"].to_numpy()
        h.create_dataset("lat", data=s["lat"].to_numpy(), compression="gzip", chunks=(50,))
    with h5py.File(p) as h:
        off = h["lat"].id.get_chunk_info(2).byte_offset
    b = bytearray(p.read_bytes())
    b[off + 8: off + 40] = b"\x00" * 32
    p.write_bytes(bytes(b))
    for msg in _both_paths(p):
        assert msg.startswith(f"{p}: dataset 'lat' cannot be read"), msg


@FUZZ
@given(want=st.lists(st.sampled_from(["time", "mag", "flux_x", "flux_y", "flux_z", "lat"]),
                     min_size=1, max_size=6, unique=True), batch=st.integers(2, 20))
def test_a_column_map_reads_the_same_in_every_path(want, batch):
    """Before: ``--col flux_x=CompassX`` worked whole and was refused by --chunk-rows
    ("column 'CompassX' (mapped to 'flux_x') not found; columns are: time")."""
    cmap = {"flux_x": "CompassX", "flux_y": "CompassY", "flux_z": "CompassZ"}
    whole = read_log(MAGARROW, columns=cmap)
    chunked = pd.concat(list(iter_log_batches(MAGARROW, None, want, colmap=cmap,
                                              batch_rows=batch)), ignore_index=True)
    assert list(chunked.columns) == want
    for c in want:
        np.testing.assert_array_equal(chunked[c].to_numpy(np.float64),
                                      whole[c].to_numpy(np.float64))


def test_cli_chunked_accepts_the_map_the_whole_file_accepts(tmp_path):
    """The two paths of ``compensate --model`` agree on a mapped MagArrow log: both reach the
    same (too short to measure) verdict instead of the chunked one refusing the map."""
    runner = CliRunner()
    model = tmp_path / "m.json"
    assert runner.invoke(app, ["calibrate", str(DATA / "calibration.csv"), "-o",
                               str(model)]).exit_code == 0
    cols = ["--col", "flux_x=CompassX", "--col", "flux_y=CompassY", "--col", "flux_z=CompassZ"]
    msgs = []
    for extra in ([], ["--chunk-rows", "5"]):
        r = runner.invoke(app, ["compensate", str(MAGARROW), "--model", str(model), *cols,
                                "-o", str(tmp_path / "o.csv"), *extra])
        msgs.append(r.output)
    assert "not found" not in msgs[1], msgs[1]
