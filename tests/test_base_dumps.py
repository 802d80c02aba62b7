"""GEM GSM-19 base files and Geometrics G-856 dumps as base-station records (issue 27, item 3).

The writers here are the tests' own, from the layouts documented in docs/formats.md (not
the library's code): a record written in each layout must read back to the same UTC times
and fields, flagged readings dropped and counted, and ``aeromag level --base`` must give the
diurnal of the CSV base record it was converted from.
"""

from __future__ import annotations

import datetime as dt
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.errors import InputError
from aeromag.io.base import read_base, read_base_file
from aeromag.io.formats import REGISTRY

SAMPLES = Path(__file__).resolve().parents[1] / "data_samples"
ROMAN = ["I", "II", "III", "IV", "V", "VI", "VII", "VIII", "IX", "X", "XI", "XII"]


def _utc(t: float) -> dt.datetime:
    return dt.datetime.fromtimestamp(t, dt.UTC)


def write_gsm19(path: Path, t: np.ndarray, mag: np.ndarray, q: np.ndarray, *, v7: bool = True,
                utc_offset_h: int = 0, glued: bool = False, with_date: bool = True) -> Path:
    """A GSM-19 base file: header, then 'hhmmss.s field quality', clock at UTC+offset."""
    local = [_utc(x + utc_offset_h * 3600.0) for x in t]
    d0 = local[0]
    sl = "/" if v7 else ""
    sep = "" if glued else " "
    head = [f"{sl}Gem Systems GSM-19W 3101329 v{'7.0' if v7 else '6.0'} 24 X 2003",
            f"{sl}ID 1 file 07base.b   "
            + (f"{d0.day:02d}{sep}{ROMAN[d0.month - 1]}{sep}{d0:%y}" if with_date else ""),
            f"{sl}datum  50000.00"]
    if utc_offset_h:
        head.append(f"/UTC{utc_offset_h:+03d}")
    if v7:
        head += ["/12.3V", "/time nT sq"]
    rows = [f"{d:%H%M%S}.{d.microsecond // 100_000}  {m:8.2f} {int(k):02d}"
            for d, m, k in zip(local, mag, q, strict=True)]
    path.write_text("\n".join(head + [""] + rows) + "\n", encoding="ascii")
    return path


def write_g856(path: Path, t: np.ndarray, mag: np.ndarray, doubt: np.ndarray) -> Path:
    """A G-856 dump: 29-character lines '* LLL DDD HHMMSS SSSSS RRRRRR' (0.1 nT), CRLF."""
    rows = []
    for k, (x, m, f) in enumerate(zip(t, mag, doubt, strict=True)):
        d = _utc(x)
        rows.append(f"*{k % 1000:3d} {d.timetuple().tm_yday:3d} {d:%H%M%S}{7:5d}"
                    f"{'?' if f else ' '}{round(m * 10):6d}")
    path.write_bytes(("\r\n".join(rows) + "\r\n").encode("ascii"))
    return path


# --------------------------------------------------------------------------- round trips
@settings(max_examples=25, deadline=None)
@given(start=st.integers(1_262_304_000, 1_893_456_000),  # 2010-2030
       steps=st.lists(st.integers(1, 600), min_size=2, max_size=40),
       data=st.data(), v7=st.booleans(), glued=st.booleans(),
       offset=st.sampled_from([0, 0, 1, -5, 10]))
def test_gsm19_round_trip(tmp_path_factory, start, steps, data, v7, glued, offset):
    t = start + np.cumsum([0, *steps]).astype(float)
    mag = np.round(np.array(data.draw(st.lists(st.floats(20_000, 70_000), min_size=t.size,
                                               max_size=t.size))), 2)
    q = np.array(data.draw(st.lists(st.sampled_from([99, 99, 99, 89, 90, 0, 59]),
                                    min_size=t.size, max_size=t.size)))
    good = q % 10 != 0
    p = write_gsm19(tmp_path_factory.mktemp("g") / "07base.b", t, mag, q, v7=v7,
                    utc_offset_h=offset, glued=glued)
    if good.sum() < 2:
        with pytest.raises(InputError, match="at least two"):
            read_base_file(p)
        return
    df = read_base_file(p)
    np.testing.assert_array_equal(df["time"].to_numpy(), t[good])
    np.testing.assert_allclose(df["mag"].to_numpy(), mag[good], atol=1e-9)
    notes = " ".join(df.attrs["notes"])
    assert (f"{int((~good).sum())} of {t.size}" in notes) == bool((~good).any())
    assert ("to UTC" in notes) == bool(offset)


@settings(max_examples=25, deadline=None)
@given(start=st.integers(1_262_304_000, 1_893_456_000),
       steps=st.lists(st.integers(1, 20_000), min_size=2, max_size=40), data=st.data())
def test_g856_round_trip(tmp_path_factory, start, steps, data):
    t = start + np.cumsum([0, *steps]).astype(float)  # may cross midnights and a new year
    mag = np.round(np.array(data.draw(st.lists(st.floats(20_000, 70_000), min_size=t.size,
                                               max_size=t.size))), 1)
    doubt = np.array(data.draw(st.lists(st.booleans(), min_size=t.size, max_size=t.size)))
    p = write_g856(tmp_path_factory.mktemp("g") / "dump.txt", t, mag, doubt)
    date = f"{_utc(t[0]):%Y-%m-%d}"
    if (~doubt).sum() < 2:
        with pytest.raises(InputError, match="at least two"):
            read_base_file(p, date=date)
        return
    df = read_base_file(p, date=date)
    np.testing.assert_array_equal(df["time"].to_numpy(), t[~doubt])
    np.testing.assert_allclose(df["mag"].to_numpy(), mag[~doubt], atol=1e-6)
    assert any(f"{int(doubt.sum())} of {t.size}" in n for n in df.attrs["notes"]) == doubt.any()


def test_gsm19_midnight_wrap_and_utc_offset(tmp_path):
    t0 = dt.datetime(2014, 11, 2, 23, 59, 58, tzinfo=dt.UTC).timestamp()
    t = t0 + np.arange(5.0)
    p = write_gsm19(tmp_path / "w.b", t, np.full(5, 50_000.0), np.full(5, 99))
    np.testing.assert_array_equal(read_base_file(p)["time"], t)  # 23:59:58 ... 00:00:02
    # clock one hour ahead of UTC: the header says so; the times come back in UTC
    p = write_gsm19(tmp_path / "o.b", t, np.full(5, 50_000.0), np.full(5, 99), utc_offset_h=1)
    assert "-1 h" in " ".join(read_base_file(p).attrs["notes"])
    np.testing.assert_array_equal(read_base_file(p)["time"], t)


def test_g856_new_year(tmp_path):
    t = dt.datetime(2014, 12, 31, 23, 59, 58, tzinfo=dt.UTC).timestamp() + np.arange(5.0)
    p = write_g856(tmp_path / "ny.txt", t, np.full(5, 50_000.0), np.zeros(5, bool))
    for date in ("2014-12-31", "2015-01-01"):  # the survey's date on either side of midnight
        np.testing.assert_array_equal(read_base(p, date=date)[0], t)


def test_shipped_samples_are_read_and_sniffed_whatever_the_extension(tmp_path):
    gsm = SAMPLES / "formats" / "gsm19_base_sample.b"
    g856 = SAMPLES / "formats" / "g856_base_sample.txt"
    if not gsm.exists():
        pytest.skip("data_samples/formats absent")
    ref = pd.read_csv(SAMPLES / "level_base.csv").iloc[:40]
    t, v, _, notes = read_base(gsm)
    keep = np.arange(40) != 17
    np.testing.assert_array_equal(t, ref["time"].to_numpy()[keep])
    np.testing.assert_allclose(v, ref["mag"].to_numpy()[keep], atol=1e-9)
    assert notes == ["gsm19_base_sample.b: 1 of 40 GSM-19 readings of quality Y = 0 "
                     "(unacceptable signal) dropped (line 24)"]
    t, v, _, notes = read_base(g856, date="2014-11-02")
    keep = np.arange(40) != 23
    np.testing.assert_array_equal(t, ref["time"].to_numpy()[keep])
    np.testing.assert_allclose(v, np.round(ref["mag"].to_numpy()[keep], 1), atol=1e-9)
    assert "1 of 40 G-856 readings marked '?' dropped (line 24)" in notes[0]
    for src, name in ((gsm, "base.csv"), (g856, "BASE.DAT")):  # content, not extension
        (tmp_path / name).write_bytes(src.read_bytes())
        assert read_base(tmp_path / name, date="2014-11-02")[0].size == 39
    assert {"gsm19", "g856"} <= set(REGISTRY)


# --------------------------------------------------------------------------- refusals
def _one_line(exc: pytest.ExceptionInfo, *words: str) -> None:
    msg = str(exc.value)
    assert "\n" not in msg, msg
    for w in words:
        assert w in msg, msg


def test_refusals_name_file_and_line(tmp_path):
    t = 1_414_889_400.0 + np.arange(3.0)
    good = write_gsm19(tmp_path / "g.b", t, np.full(3, 50_000.0), np.full(3, 99))
    lines = good.read_text().splitlines()
    cases = {
        "two.b": (lines[:-1] + ["005002.0  50000.00"], "line 9", "3 fields"),
        "q.b": (lines[:-1] + ["005002.0  50000.00 a"], "line 9", "quality 'a'"),
        "time.b": (lines[:-1] + ["255002.0  50000.00 99"], "line 9", "not a time of day"),
        "nt.b": (lines[:-1] + ["005002.0  500.00 99"], "line 9", "no Earth field"),
        "mob.b": ([lines[0], lines[1].replace(".b ", ".m "), *lines[2:]], "line 2",
                  "not a base file"),
    }
    for name, (text, *words) in cases.items():
        (tmp_path / name).write_text("\n".join(text) + "\n")
        with pytest.raises(InputError) as e:
            read_base(tmp_path / name)
        _one_line(e, name, *words)
    nodate = write_gsm19(tmp_path / "nd.b", t, np.full(3, 5e4), np.full(3, 99), with_date=False)
    with pytest.raises(InputError) as e:
        read_base(nodate)
    _one_line(e, "nd.b", "no date", "--date YYYY-MM-DD")
    assert read_base(nodate, date="2014-11-02")[0][0] == t[0]

    dump = write_g856(tmp_path / "d.txt", t, np.full(3, 50_000.0), np.zeros(3, bool))
    with pytest.raises(InputError) as e:
        read_base(dump)
    _one_line(e, "d.txt", "day of year but no year", "--date YYYY-MM-DD")
    rows = dump.read_text().splitlines()
    (tmp_path / "bad.txt").write_text("\n".join([*rows, "*  2 306 0050"]) + "\n")
    with pytest.raises(InputError) as e:
        read_base(tmp_path / "bad.txt", date="2014-11-02")
    _one_line(e, "bad.txt", "line 4", "not a G-856 reading")
    (tmp_path / "leap.txt").write_text("\n".join([r.replace(" 306 ", " 366 ") for r in rows]))
    with pytest.raises(InputError) as e:
        read_base(tmp_path / "leap.txt", date="2014-11-02")
    _one_line(e, "leap.txt", "line 1", "366 does not exist in 2014")


# --------------------------------------------------------------------------- aeromag level
@pytest.fixture(scope="module")
def converted(tmp_path_factory):
    if not (SAMPLES / "level_survey.csv").exists():
        pytest.skip("data_samples not generated (cli/make_samples.sh)")
    d = tmp_path_factory.mktemp("conv")
    b = pd.read_csv(SAMPLES / "level_base.csv")
    t, m = b["time"].to_numpy(), b["mag"].to_numpy()
    q = np.full(t.size, 99)
    q[[100, 1000]] = 90  # two unacceptable readings: dropped, the record interpolates over them
    write_gsm19(d / "base.b", t, m, q)
    write_g856(d / "base.txt", t, m, np.zeros(t.size, bool))
    pd.DataFrame({"time": t, "mag": np.round(m, 1)}).to_csv(d / "base01.csv", index=False)
    b[q == 99].to_csv(d / "base_kept.csv", index=False)
    return d


def _level(args: list[str], out: Path) -> pd.DataFrame:
    r = CliRunner().invoke(app, ["level", str(SAMPLES / "level_survey.csv"), "--no-igrf",
                                 "-o", str(out), *args])
    assert r.exit_code == 0, r.output
    return pd.read_csv(out)


def test_level_with_gsm19_and_g856_bases_matches_the_csv_base(converted, tmp_path):
    csv = _level(["--base", str(SAMPLES / "level_base.csv")], tmp_path / "c.csv")
    kept = _level(["--base", str(converted / "base_kept.csv")], tmp_path / "k.csv")
    gsm = _level(["--base", str(converted / "base.b")], tmp_path / "g.csv")
    # the same record (fields to 0.01 nT) less the two flagged readings: the diurnal of the
    # CSV without them, to 0.01 nT; dropping them moves the diurnal by their noise only (the
    # simulated base noise is 0.05 nT: at most 4 of it)
    assert np.nanmax(np.abs(gsm["diurnal"] - kept["diurnal"])) <= 0.01
    assert np.nanmax(np.abs(gsm["diurnal"] - csv["diurnal"])) < 0.2
    assert np.nanmedian(np.abs(gsm["diurnal"] - csv["diurnal"])) < 0.01
    rep = json.loads((tmp_path / "g.json").read_text())
    n = len(pd.read_csv(SAMPLES / "level_base.csv"))
    assert f"2 of {n} GSM-19 readings of quality Y = 0" in " ".join(rep["warnings"])
    # G-856 records 0.1 nT: it matches the CSV record rounded to 0.1 nT, to 0.01 nT
    c01 = _level(["--base", str(converted / "base01.csv")], tmp_path / "c01.csv")
    g856 = _level(["--base", str(converted / "base.txt"), "--date", "2014-11-02"],
                  tmp_path / "d.csv")
    assert np.nanmax(np.abs(g856["diurnal"] - c01["diurnal"])) <= 0.01
    assert np.nanmax(np.abs(g856["diurnal"] - csv["diurnal"])) < 0.1  # the rounding, no more


def test_level_g856_without_date_is_one_line_as_a_subprocess(converted, tmp_path):
    out = tmp_path / "x.csv"
    r = subprocess.run([sys.executable, "-m", "aeromag", "level",
                        str(SAMPLES / "level_survey.csv"), "--no-igrf", "--base",
                        str(converted / "base.txt"), "-o", str(out)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 1
    last = r.stderr.strip().splitlines()[-1]
    assert last.startswith("error:") and "base.txt" in last and "--date YYYY-MM-DD" in last
    assert "Traceback" not in r.stderr and not out.exists()
