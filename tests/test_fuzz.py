"""Fuzz suite (issue 16): mutated logs of every format through every command that reads them.

Good logs (CSV, Parquet, Geosoft XYZ, MagNav HDF5, MagArrow, MagDrone, and a mission log with
its plan) are mutated by hypothesis (truncated, bytes inserted or flipped, lines duplicated or
deleted, delimiters changed, bytes that are not UTF-8, huge numbers, empty fields) and run
through ``compensate``, ``compensate --model``, ``compensate --model --chunk-rows``,
``calibrate`` and ``track`` -- in-process with typer's CliRunner (fast), and a few as real
subprocesses.  Properties of every run:

* no traceback: exit status 0 or 1, a one-line ``error: FILE: ...`` on failure;
* no hang: each run has a time limit;
* no partial or stale file: on failure no output exists, on success exactly the outputs,
  and never a temporary file;
* exit 0 only when every row and every column of the input is in the output with its values
  (checked against an independent reading of the mutated file), or the loss is reported in
  the output's JSON ``warnings``.

Profiles: ``HYPOTHESIS_PROFILE=ci`` (default; a few dozen examples per test, about a minute
in all) and ``HYPOTHESIS_PROFILE=long`` (by hand: ``HYPOTHESIS_PROFILE=long python -m pytest
tests/test_fuzz.py -p no:cacheprovider``; see docs/formats.md).
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from aeromag.cli import app

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "data_samples"
SAMPLES = DATA / "formats"  # copies of ../shared/data/formats

settings.register_profile("aeromag-fuzz-ci", max_examples=int(os.environ.get(
    "AEROMAG_FUZZ_EXAMPLES", "30")), deadline=None,
    derandomize=not os.environ.get("AEROMAG_FUZZ_RANDOM"), print_blob=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture,
                           HealthCheck.data_too_large])
settings.register_profile("aeromag-fuzz-long", max_examples=1500, deadline=None,
                          print_blob=True,
                          suppress_health_check=[HealthCheck.too_slow,
                                                 HealthCheck.function_scoped_fixture,
                                                 HealthCheck.data_too_large])
PROFILE = settings.get_profile(
    "aeromag-fuzz-long" if os.environ.get("HYPOTHESIS_PROFILE") == "long" else "aeromag-fuzz-ci")

#: Seconds one in-process run may take before it counts as a hang.
RUN_LIMIT_S = 60

runner = CliRunner()


# --------------------------------------------------------------------------- seeds
@pytest.fixture(scope="module")
def seeds(tmp_path_factory) -> dict[str, Path]:
    """Good logs of every format (a survey, a mission with its plan) and a model."""
    d = tmp_path_factory.mktemp("seeds")
    from aeromag.io.formats import write_table

    survey = pd.read_csv(DATA / "survey.csv").iloc[:1200]
    survey = survey.drop(columns=[c for c in survey.columns if c.startswith("truth_")])
    out: dict[str, Path] = {}
    out["csv"] = d / "survey.csv"
    survey.to_csv(out["csv"], index=False)
    out["parquet"] = d / "survey.parquet"
    write_table(survey, out["parquet"])
    out["xyz"] = d / "survey.xyz"
    write_table(survey, out["xyz"])
    h5py = pytest.importorskip("h5py")
    out["hdf5"] = d / "survey.h5"
    names = {"time": "tt", "mag": "mag_1_uc", "flux_x": "flux_a_x", "flux_y": "flux_a_y",
             "flux_z": "flux_a_z", "lat": "lat", "lon": "lon", "alt": "utm_z", "line": "line"}
    with h5py.File(out["hdf5"], "w") as h:
        for c, n in names.items():
            h[n] = survey[c].to_numpy()
    out["magdrone"] = d / "magdrone.csv"
    out["magdrone"].write_text(_magdrone_text(survey))
    if (SAMPLES / "magarrow_sample.csv").exists():
        out["magarrow"] = d / "magarrow.csv"
        shutil.copy(SAMPLES / "magarrow_sample.csv", out["magarrow"])
    out["mission"] = d / "mission.csv"
    pd.read_csv(DATA / "mission.csv").iloc[:1500].to_csv(out["mission"], index=False)
    out["plan"] = d / "plan.csv"
    shutil.copy(DATA / "mission_plan.csv", out["plan"])
    out["calibration"] = d / "calibration.csv"
    shutil.copy(DATA / "calibration.csv", out["calibration"])
    out["model"] = d / "aircraft.json"
    r = runner.invoke(app, ["calibrate", str(out["calibration"]), "-o", str(out["model"])])
    assert r.exit_code == 0, r.output
    return out


def _magdrone_text(df: pd.DataFrame) -> str:
    """A SENSYS MagDrone R3 native log (metadata, ';' table) of the survey's fluxgate."""
    head = ["20201023_101034_MD-R3_#0056", "MagDroneR3: 000056", "SampleFrequence: 10 [Hz]", "",
            "Timestamp [ms]; B1x [nT]; B1y [nT]; B1z [nT]; B2x [nT]; B2y [nT]; B2z [nT];"
            " Latitude [Decimal Degrees]; Longitude [Decimal Degrees]; Altitude [m];"
            " Satellites; Quality;"]
    rows = [f"{int(round(t * 1000))};{x:.2f};{y:.2f};{z:.2f};{x + 1:.2f};{y + 1:.2f};"
            f"{z + 1:.2f};{la:.7f};{lo:.7f};{a:.1f};7;1;"
            for t, x, y, z, la, lo, a in zip(df["time"], df["flux_x"], df["flux_y"],
                                             df["flux_z"], df["lat"], df["lon"], df["alt"],
                                             strict=True)]
    return "\n".join(head + rows) + "\n"


# --------------------------------------------------------------------------- mutations
_NUM = st.sampled_from([b"1e999", b"-1e999", b"99999999999999999999", b"1e308", b"nan",
                        b"inf", b"-0", b"0x1F", b"1,5", b"", b"true", b"\xff", b"9" * 400])


@st.composite
def mutation(draw: st.DrawFn) -> tuple:
    kind = draw(st.sampled_from(["truncate", "insert", "flip", "dup_line", "del_line",
                                 "delimiter", "non_utf8", "huge_number", "empty_field",
                                 "swap_lines"]))
    return (kind, draw(st.floats(0, 1)), draw(st.binary(min_size=1, max_size=8)),
            draw(_NUM), draw(st.sampled_from([b";", b"\t", b" ", b"|", b",,"])),
            draw(st.integers(0, 2**31)))


def mutate(data: bytes, muts: list[tuple]) -> bytes:
    """Apply mutations; each works on a position chosen by a fraction of the length."""
    for kind, frac, blob, num, delim, salt in muts:
        if not data:
            break
        pos = min(len(data) - 1, int(frac * len(data)))
        lines = data.split(b"\n")
        li = min(len(lines) - 1, int(frac * len(lines)))
        if kind == "truncate":
            data = data[:pos]
        elif kind == "insert":
            data = data[:pos] + blob + data[pos:]
        elif kind == "flip":
            b = bytearray(data)
            for k in range(1 + salt % 4):
                b[(pos + k * 7919) % len(b)] ^= 1 << (salt + k) % 8
            data = bytes(b)
        elif kind == "dup_line":
            lines.insert(li, lines[li])
            data = b"\n".join(lines)
        elif kind == "del_line":
            del lines[li]
            data = b"\n".join(lines)
        elif kind == "swap_lines" and li + 1 < len(lines):
            lines[li], lines[li + 1] = lines[li + 1], lines[li]
            data = b"\n".join(lines)
        elif kind == "delimiter":
            if salt % 3 == 0:
                data = data.replace(b",", delim)
            else:
                lines[li] = lines[li].replace(b",", delim)
                data = b"\n".join(lines)
        elif kind == "non_utf8":
            data = data[:pos] + b"\xc3\x28\xff" + data[pos:]
        elif kind in ("huge_number", "empty_field"):
            rep = num if kind == "huge_number" else b""
            for sep in (b",", b";", b" "):
                cells = lines[li].split(sep)
                if len(cells) > 1:
                    cells[salt % len(cells)] = rep
                    lines[li] = sep.join(cells)
                    break
            data = b"\n".join(lines)
    return data


# --------------------------------------------------------------------------- running
class Hang(BaseException):
    """A run took longer than RUN_LIMIT_S."""


def _on_alarm(signum: int, frame: object) -> None:
    raise Hang()


def invoke(args: list[str]) -> tuple[int, str]:
    """Run the CLI in-process with a time limit; fail on a traceback or a hang."""
    old = signal.signal(signal.SIGALRM, _on_alarm)
    signal.alarm(RUN_LIMIT_S)
    try:
        r = runner.invoke(app, args)
    except Hang:
        pytest.fail(f"hang: aeromag {' '.join(args)} ran more than {RUN_LIMIT_S} s")
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    if r.exception is not None and not isinstance(r.exception, SystemExit):
        import traceback

        tb = "".join(traceback.format_exception(r.exception))
        pytest.fail(f"traceback from aeromag {' '.join(args)}:\n{tb}")
    assert r.exit_code in (0, 1), (r.exit_code, r.output)
    assert "Traceback" not in r.output, r.output
    if r.exit_code == 1:
        errs = [ln for ln in r.output.splitlines() if ln.startswith("error: ")]
        assert len(errs) == 1, f"not one error line: {r.output!r}"
    return r.exit_code, r.output


def _files(d: Path) -> set[str]:
    return {p.name for p in d.iterdir()}


# --------------------------------------------------------------------------- independent reads
_NA = {"", "#N/A", "#N/A N/A", "#NA", "-1.#IND", "-1.#QNAN", "-NaN", "-nan", "1.#IND",
       "1.#QNAN", "<NA>", "N/A", "NA", "NULL", "NaN", "None", "n/a", "nan", "null"}


def _csv_table(data: bytes, delimiter: str = ",", header_prefix: str | None = None
               ) -> tuple[list[str], list[list[str]]] | None:
    """Header and data rows of a delimited text file, read independently of aeromag.

    None when the file is not UTF-8 text (aeromag must refuse it then).
    """
    try:
        text = data.decode("utf-8").removeprefix("\ufeff")
    except UnicodeDecodeError:
        return None
    rows = list(csv.reader(io.StringIO(text.replace("\r\n", "\n")), delimiter=delimiter,
                           skipinitialspace=True))
    rows = [r for r in rows if any(c.strip() for c in r)]
    if header_prefix is not None:
        at = next((i for i, r in enumerate(rows) if r and r[0].strip().startswith(
            header_prefix)), None)
        if at is None:
            return None
        rows = rows[at:]
    if not rows:
        return None
    header = [c.strip() for c in rows[0]]
    while header and not header[-1]:
        header.pop()
    return header, rows[1:]


def _same_cell(a: str, b: str) -> bool:
    a, b = a.strip(), b.strip()
    if a == b:
        return True
    if (a in _NA) and (b in _NA):
        return True
    if a.lower() in ("true", "false") and a.lower() == b.lower():
        return True
    try:
        x, y = float(a), float(b)
    except ValueError:
        return False
    return x == y or (math.isnan(x) and math.isnan(y))


def _reported_loss(report: dict) -> bool:
    text = " ".join(str(w) for w in report.get("warnings") or [])
    return any(k in text for k in ("dropped", "duplicate", "cut short", "removed"))


def check_csv_preserved(inp: bytes, out_csv: Path, report: dict, delimiter: str = ",",
                        header_prefix: str | None = None, renamed: dict | None = None) -> None:
    """Every input row and column is in the output with its values, or the loss is reported."""
    table = _csv_table(inp, delimiter, header_prefix)
    assert table is not None, "exit 0 on a file that is not UTF-8 text"
    header, rows = table
    out = _csv_table(out_csv.read_bytes())
    assert out is not None
    oh, orows = out
    renamed = renamed or {}
    lost = _reported_loss(report)
    n = len(header)
    full = [r for r in rows if len(r) >= n]
    assert len(full) == len(rows) or lost, "a short row was accepted without a word"
    if len(orows) != len(rows):
        assert len(orows) < len(rows) and lost, (
            f"{len(rows)} input rows, {len(orows)} output rows, no loss reported")
        return
    idx = {name: j for j, name in enumerate(oh)}
    for j, name in enumerate(header):
        name = renamed.get(name, name)
        if not name or name not in idx:
            assert lost or not name, f"input column {name!r} missing from the output"
            continue
        if name == "time" and rows and not _numeric(rows[0][j] if j < len(rows[0]) else ""):
            continue  # date-times become seconds
        k = idx[name]
        for i, (r, o) in enumerate(zip(rows, orows, strict=True)):
            a = r[j] if j < len(r) else ""
            assert _same_cell(a, o[k] if k < len(o) else ""), (
                f"row {i + 1}, column {name!r}: input {a!r} became {o[k]!r}")


def _numeric(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


# --------------------------------------------------------------------------- commands
COMMANDS = {
    "self": lambda inp, out, s: ["compensate", inp, "-o", out, "--no-screen"],
    "model": lambda inp, out, s: ["compensate", inp, "--model", str(s["model"]), "-o", out],
    "chunked": lambda inp, out, s: ["compensate", inp, "--model", str(s["model"]),
                                    "--chunk-rows", "500", "-o", out],
    "calibrate": lambda inp, out, s: ["calibrate", inp, "-o", out.replace(".csv", ".json")],
}


def _run_case(seeds: dict[str, Path], fmt: str, command: str, muts: list[tuple],
              allow: bool) -> None:
    src = seeds[fmt]
    data = mutate(src.read_bytes(), muts)
    work = Path(tempfile.mkdtemp(prefix="fuzz", dir=src.parent))
    try:
        inp = work / src.name
        inp.write_bytes(data)
        out = work / "out.csv"
        args = COMMANDS[command](str(inp), str(out), seeds)
        if allow and command != "calibrate":
            args.append("--allow-truncated")
        before = _files(work)
        code, text = invoke(args)
        after = _files(work) - before
        assert not [f for f in after if f.endswith(".tmp")], after
        if code == 1:
            assert not after, f"files left after a failure: {after}"
            err = next(ln for ln in text.splitlines() if ln.startswith("error: "))
            assert inp.name in err or "-o " in err, f"the error names no file: {err}"
            return
        if command == "calibrate":
            from aeromag.io.model_file import read_model_document

            assert after == {"out.json"}
            read_model_document(work / "out.json")
            return
        assert after == {"out.csv", "out.json"}, after
        report = json.loads((work / "out.json").read_text())
        if fmt == "csv":
            check_csv_preserved(data, out, report)
        elif fmt == "magdrone":
            _check_rows(data, out, report, _magdrone_rows(data))
        elif fmt == "xyz":
            _check_rows(data, out, report, _xyz_rows(data))
        elif fmt == "parquet":
            _check_rows(data, out, report, _parquet_rows(inp))
        elif fmt == "hdf5":
            _check_rows(data, out, report, _hdf5_rows(inp))
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _check_rows(data: bytes, out: Path, report: dict, n_in: int | None) -> None:
    n_out = len(pd.read_csv(out, low_memory=False))
    assert n_in is not None, "exit 0 on a file an independent reader cannot read"
    assert n_out == n_in or (n_out < n_in and _reported_loss(report)), (n_in, n_out)


def _magdrone_rows(data: bytes) -> int | None:
    t = _csv_table(data, ";", "Timestamp")
    return None if t is None else len(t[1])


def _xyz_rows(data: bytes) -> int | None:
    try:
        text = data.decode("utf-8").removeprefix("\ufeff")
    except UnicodeDecodeError:
        return None
    import re

    head = re.compile(r"^(line|tie|trend|base|test|random|special)\s+(-?\d+|\*)|^[ltbsrdp]\d+",
                      re.I)
    return sum(1 for ln in text.replace("\r", "\n").split("\n")
               if ln.strip() and not ln.strip().startswith("/")
               and not (ln.strip()[0].isalpha() and head.match(ln.strip())))


def _parquet_rows(path: Path) -> int | None:
    import pyarrow.parquet as pq

    try:
        return pq.read_table(path).num_rows
    except Exception:  # noqa: BLE001
        return None


def _hdf5_rows(path: Path) -> int | None:
    import h5py

    try:
        with h5py.File(path, "r") as h:
            return len(h["tt"])
    except Exception:  # noqa: BLE001
        return None


FORMATS = ["csv", "parquet", "xyz", "hdf5", "magdrone", "magarrow"]


@settings(PROFILE)
@given(fmt=st.sampled_from(FORMATS), muts=st.lists(mutation(), min_size=1, max_size=3),
       allow=st.booleans())
def test_fuzz_compensate_with_model(seeds, fmt, muts, allow):
    if fmt not in seeds:
        pytest.skip("format sample absent")
    _run_case(seeds, fmt, "model", muts, allow)


@settings(PROFILE)
@given(fmt=st.sampled_from(["csv", "parquet", "xyz", "magdrone"]),
       muts=st.lists(mutation(), min_size=1, max_size=3), allow=st.booleans())
def test_fuzz_compensate_chunked(seeds, fmt, muts, allow):
    _run_case(seeds, fmt, "chunked", muts, allow)


@settings(PROFILE)
@given(fmt=st.sampled_from(["csv", "parquet", "xyz", "hdf5"]),
       muts=st.lists(mutation(), min_size=1, max_size=2))
def test_fuzz_compensate_self_fitted(seeds, fmt, muts):
    _run_case(seeds, fmt, "self", muts, False)


@settings(PROFILE)
@given(muts=st.lists(mutation(), min_size=1, max_size=2), fmt=st.sampled_from(["csv",
                                                                                "calibration"]))
def test_fuzz_calibrate(seeds, muts, fmt):
    _run_case(seeds, "calibration" if fmt == "calibration" else "csv", "calibrate", muts, False)


@settings(PROFILE)
@given(muts=st.lists(mutation(), min_size=1, max_size=3), on_plan=st.booleans())
def test_fuzz_track(seeds, muts, on_plan):
    """The mission log (or, sometimes, its plan) mutated through 'aeromag track'."""
    work = Path(tempfile.mkdtemp(prefix="fuzz", dir=seeds["mission"].parent))
    try:
        log, plan = work / "mission.csv", work / "plan.csv"
        log.write_bytes(seeds["mission"].read_bytes())
        plan.write_bytes(seeds["plan"].read_bytes())
        target = plan if on_plan else log
        data = mutate(target.read_bytes(), muts)
        target.write_bytes(data)
        before = _files(work)
        code, _ = invoke(["track", str(log), "--plan", str(plan), "-o", str(work / "t.csv")])
        after = _files(work) - before
        assert not [f for f in after if f.endswith(".tmp")], after
        if code == 1:
            assert not after, f"files left after a failure: {after}"
            err = next(ln for ln in _.splitlines() if ln.startswith("error: "))
            assert target.name in err or "-o " in err, f"the error names no file: {err}"
            return
        assert {"t.csv", "t.json"} <= after, after
        if not on_plan:
            check_csv_preserved(data, work / "t.csv", json.loads((work / "t.json").read_text()))
    finally:
        shutil.rmtree(work, ignore_errors=True)


# --------------------------------------------------------------------------- real processes
@pytest.mark.parametrize("kind", ["truncate", "non_utf8", "delimiter"])
def test_fuzz_real_subprocess(seeds, tmp_path, kind):
    """A few mutated logs through a real 'python -m aeromag' (a time limit, no traceback,
    no file left on failure)."""
    rng = np.random.default_rng(len(kind))
    data = mutate(seeds["csv"].read_bytes(), [(kind, float(rng.uniform(0.3, 0.9)), b"x",
                                               b"1e999", b";", 3)])
    inp = tmp_path / "in.csv"
    inp.write_bytes(data)
    p = subprocess.run([sys.executable, "-m", "aeromag", "compensate", str(inp), "--model",
                        str(seeds["model"]), "-o", str(tmp_path / "o.csv")],
                       capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert p.returncode in (0, 1) and "Traceback" not in p.stderr, p.stderr
    left = {f.name for f in tmp_path.iterdir()} - {"in.csv"}
    if p.returncode == 1:
        assert p.stderr.startswith("error: ") and not left, (p.stderr, left)
    else:
        assert left == {"o.csv", "o.json"}
        check_csv_preserved(data, tmp_path / "o.csv", json.loads(
            (tmp_path / "o.json").read_text()))
