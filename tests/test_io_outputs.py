"""Issue 16: outputs written as a set, stale temporaries removed, -o checked, clean messages."""

from __future__ import annotations

import errno
import os
import signal
import stat
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.errors import InputError
from aeromag.io import atomic_path, write_csv, write_json
from aeromag.io.messages import clean
from aeromag.io.outputs import output_set, register_input, remove_stale_temporaries

DATA = Path(__file__).resolve().parents[1] / "data_samples"
runner = CliRunner()


def _df() -> pd.DataFrame:
    return pd.DataFrame({"time": [0.0, 0.1], "mag": [1.5, 2.5]})


def _temps(d: Path) -> list[Path]:
    return sorted(d.glob(".*.tmp"))


def test_output_set_all_or_none(tmp_path):
    """Class: a kill/failure between the CSV and the JSON left a CSV without its JSON (track)
    or a new JSON beside an old CSV (compensate)."""
    csv, js = tmp_path / "o.csv", tmp_path / "o.json"
    write_csv(_df(), csv)
    write_json({"v": 1}, js)
    old = csv.read_bytes(), js.read_bytes()
    with pytest.raises(KeyboardInterrupt), output_set():
        write_csv(_df().assign(mag=9.0), csv)
        write_json({"v": 2}, js)
        assert (csv.read_bytes(), js.read_bytes()) == old  # nothing renamed yet
        raise KeyboardInterrupt
    assert (csv.read_bytes(), js.read_bytes()) == old and not _temps(tmp_path)
    with output_set():
        write_csv(_df().assign(mag=9.0), csv)
        write_json({"v": 2}, js)
    assert b"9.0" in csv.read_bytes() and b'"v": 2' in js.read_bytes()
    assert not _temps(tmp_path)


def test_nested_writer_renames_in_order(tmp_path):
    """A writer that writes into another writer's temporary (XYZ inside write_outputs)."""
    from aeromag.io.formats import write_table

    out = tmp_path / "o.xyz"
    with output_set(), atomic_path(out) as tmp:
        write_table(_df(), tmp, "xyz")
    assert out.read_text().startswith("/ aeromag") and not _temps(tmp_path)


def test_stale_temporaries_of_dead_processes_are_removed(tmp_path):
    """Class: SIGKILL/SIGTERM left a hidden 23-40 MB .tmp that no later run removed."""
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        stale = tmp_path / f".o.csv.aeromag-{dead.pid}-0123abcd.tmp"
        mine = tmp_path / f".o.csv.aeromag-{live.pid}-0123abcd.tmp"
        other = tmp_path / f".x.csv.aeromag-{dead.pid}-0123abcd.tmp"
        for p in (stale, mine, other):
            p.write_text("partial")
        write_csv(_df(), tmp_path / "o.csv")
        assert not stale.exists()  # its writer is gone
        assert mine.exists()  # a live process may still be writing it
        assert other.exists()  # another output's
        assert remove_stale_temporaries(tmp_path / "x.csv") == [other]
    finally:
        live.kill()
        live.wait()


def test_output_must_be_a_regular_file(tmp_path):
    """Class: as root, -o /dev/null or a FIFO was replaced by a regular file (now refused)."""
    with pytest.raises(InputError, match="is a device, not a regular file"):
        write_csv(_df(), "/dev/null")
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
    fifo = tmp_path / "f.csv"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match="is a FIFO"):
        write_csv(_df(), fifo)
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    with pytest.raises(InputError, match="is a folder"):
        write_csv(_df(), tmp_path)
    r = runner.invoke(app, ["compensate", str(DATA / "survey.csv"), "--no-screen", "-o",
                            "/dev/null"])
    assert r.exit_code == 1 and "is a device" in r.output
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)


def test_output_may_not_be_an_input(tmp_path):
    """Class: 'compensate --model X.json -o X.csv' silently overwrote the model."""
    model = tmp_path / "X.json"
    r = runner.invoke(app, ["calibrate", str(DATA / "calibration.csv"), "-o", str(model)])
    assert r.exit_code == 0, r.output
    before = model.read_bytes()
    r = runner.invoke(app, ["compensate", str(DATA / "survey.csv"), "--model", str(model),
                            "-o", str(tmp_path / "X.csv")])
    assert r.exit_code == 1 and "would overwrite the model" in r.output
    assert model.read_bytes() == before and not (tmp_path / "X.csv").exists()
    assert not _temps(tmp_path)
    with output_set():
        register_input(tmp_path / "X.json", "model")
        with pytest.raises(InputError, match="would overwrite the model"):
            write_json({"a": 1}, tmp_path / "X.json")


def test_sigterm_cleans_up_like_ctrl_c(tmp_path):
    """Class: SIGTERM left the temporary file behind (no handler)."""
    csv = tmp_path / "o.csv"
    with pytest.raises(SystemExit) as exc, output_set():
        write_csv(_df(), csv)
        os.kill(os.getpid(), signal.SIGTERM)
        for _ in range(1000):  # the handler runs between bytecodes
            pass
    assert exc.value.code == 128 + signal.SIGTERM
    assert not csv.exists() and not _temps(tmp_path)
    assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL  # restored


def test_disk_full_and_read_only_name_the_output(tmp_path):
    """Class: the disk-full message said '<file>'; read-only messages named the temp file."""
    from aeromag.cli._app import os_error_message

    target = tmp_path / "o.csv"
    with pytest.raises(OSError) as exc, atomic_path(target):
        raise OSError(errno.ENOSPC, "No space left on device")
    assert exc.value.filename == str(target)
    assert os_error_message(exc.value).startswith(f"{target}: No space left on device; free")
    with pytest.raises(OSError) as exc, atomic_path(target) as tmp:
        raise OSError(errno.EROFS, "Read-only file system", str(tmp))
    assert exc.value.filename == str(target) and ".tmp" not in os_error_message(exc.value)
    assert not _temps(tmp_path)


def test_control_characters_are_never_echoed(tmp_path):
    """Class: column names with terminal escape codes were echoed raw."""
    assert clean("a\x1b[31mred\x1b[0m\x07b\rc\nd") == "a?red??b?c d"
    log = tmp_path / "l.csv"
    log.write_text("time,\x1b]0;pwned\x07mag\x1b[2J,flux_x,flux_y\n0,1,2,3\n0.1,1,2,3\n")
    r = runner.invoke(app, ["compensate", str(log), "-o", str(tmp_path / "o.csv")])
    assert r.exit_code == 1 and "error:" in r.output
    assert "\x1b" not in r.output and "\x07" not in r.output


def test_cli_refuses_unknown_output_extensions(tmp_path):
    """Issue 15 item 2: -o out.parquet / out.xyz write those formats; others are refused."""
    from aeromag.io import read_log

    model = tmp_path / "m.json"
    assert runner.invoke(app, ["calibrate", str(DATA / "calibration.csv"), "-o",
                               str(model)]).exit_code == 0
    ref = tmp_path / "r.csv"
    assert runner.invoke(app, ["compensate", str(DATA / "survey.csv"), "--model", str(model),
                               "-o", str(ref)]).exit_code == 0
    want = read_log(ref)
    for ext in ("parquet", "xyz"):
        out = tmp_path / f"o.{ext}"
        r = runner.invoke(app, ["compensate", str(DATA / "survey.csv"), "--model", str(model),
                                "-o", str(out)])
        assert r.exit_code == 0, r.output
        got = read_log(out)
        assert len(got) == len(want)
        pd.testing.assert_series_equal(got["mag_comp"], want["mag_comp"], check_names=False)
        assert got["line"].tolist() == want["line"].tolist()
    assert (tmp_path / "o.xyz").read_text().split("\n")[2] == "Line 0"  # Oasis line headers
    for bad in ("o.dat", "o"):
        r = runner.invoke(app, ["compensate", str(DATA / "survey.csv"), "--model", str(model),
                                "-o", str(tmp_path / bad)])
        assert r.exit_code == 1 and r.output.count("\n") == 1 and "-o " in r.output
        assert not (tmp_path / bad).exists()


def test_writer_errors_name_the_output_not_its_temporary(tmp_path):
    """Class: messages named the hidden temporary file instead of the output."""
    model = tmp_path / "m.json"
    assert runner.invoke(app, ["calibrate", str(DATA / "calibration.csv"), "-o",
                               str(model)]).exit_code == 0
    df = pd.read_csv(DATA / "survey.csv")
    df["blob"] = [b"\x00\x01"] * len(df)
    src = tmp_path / "bin.parquet"
    df.to_parquet(src)
    for out in ("o.csv", "o.xyz"):
        r = runner.invoke(app, ["compensate", str(src), "--model", str(model), "-o",
                                str(tmp_path / out)])
        assert r.exit_code == 1 and f"error: {tmp_path / out}: column 'blob'" in r.output
        assert ".tmp" not in r.output and not _temps(tmp_path)
    r = runner.invoke(app, ["compensate", str(src), "--model", str(model), "-o",
                            str(tmp_path / "o.parquet")])
    assert r.exit_code == 0, r.output  # Parquet holds bytes
