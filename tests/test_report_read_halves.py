"""The report's plain-CSV reader parsing a log in two halves at once (issue 15, item 11).

With the split threshold lowered to 0 bytes and two cores assumed, every log here is parsed
as two halves (the second on a thread, its rows counted from the first half's line breaks);
the frame must be the one-reader frame and the validating reader's, and whatever the halves
cannot vouch for (blank lines, quoted fields, a bad value in either half, ids beyond int32)
must fall back or be read again, never give a shifted or partial frame.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from aeromag.errors import InputError
from aeromag.synthetic import simulate_calibration
from aeromag.workflows import _csv_halves as halves_mod
from aeromag.workflows import _report_read as rep
from aeromag.workflows.compensate import compensate_file


@pytest.fixture(scope="module")
def out_csv(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("halves")
    df, _ = simulate_calibration(seed=5, n_boxes=1)
    df.to_csv(d / "cal.csv", index=False)
    compensate_file(d / "cal.csv", d / "out.csv")
    return d / "out.csv"


@pytest.fixture
def halves(monkeypatch):
    """Split every log, whatever its size and the machine's cores; count the splits."""
    monkeypatch.setattr(halves_mod, "_SPLIT_MIN_BYTES", 0)
    monkeypatch.setattr(halves_mod, "_cores", lambda: 2)
    seen: list[int | None] = []
    real = rep._split_point

    def spy(src: Path, data_start: int) -> int | None:
        seen.append(real(src, data_start))
        return seen[-1]

    monkeypatch.setattr(rep, "_split_point", spy)
    return seen


def _one_reader(src: Path, monkeypatch) -> pd.DataFrame:
    with monkeypatch.context() as m:
        m.setattr(rep, "_split_point", lambda *_: None)
        return rep._read_csv_fast(src)


def test_two_halves_give_the_one_reader_frame(out_csv: Path, halves, monkeypatch) -> None:
    two = rep._read_csv_fast(out_csv)
    assert halves and halves[0] is not None, "the log was not split"
    size = out_csv.stat().st_size
    assert 0.4 * size < halves[0] < 0.6 * size
    pd.testing.assert_frame_equal(two, _one_reader(out_csv, monkeypatch), check_exact=True)
    pd.testing.assert_frame_equal(two, rep._read_batches(out_csv), check_exact=True)
    assert two["segment"].dtype == np.int32 and two["flux_x"].dtype == np.float32


def _lines(src: Path) -> list[str]:
    return src.read_text().splitlines()


def test_blank_line_in_first_half_is_not_a_shifted_frame(out_csv: Path, tmp_path: Path,
                                                         halves) -> None:
    lines = _lines(out_csv)
    lines.insert(100, "")  # a blank line: one more line break than rows in the first half
    f = tmp_path / "blank.csv"
    f.write_text("\n".join(lines) + "\n")
    with pytest.raises(rep._NotPlain, match="line breaks"):
        rep._read_csv_fast(f)
    pd.testing.assert_frame_equal(rep.read_columns(f), rep._read_batches(out_csv),
                                  check_exact=True)


@pytest.mark.parametrize("where", [0.25, 0.75])
def test_bad_value_in_either_half_falls_back_with_the_validating_error(
        out_csv: Path, tmp_path: Path, halves, where: float) -> None:
    lines = _lines(out_csv)
    head = lines[0].split(",")
    row = int(where * (len(lines) - 1)) + 1
    f = lines[row].split(",")
    f[head.index("mag")] = "abc"
    lines[row] = ",".join(f)
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(lines) + "\n")
    with pytest.raises(rep._NotPlain):
        rep._read_csv_fast(bad)
    with pytest.raises(InputError, match="mag"):
        rep.read_columns(bad)


@pytest.mark.parametrize("where", [0.1, 0.9])
def test_ids_beyond_int32_in_either_half_read_again_as_int64(out_csv: Path, tmp_path: Path,
                                                             halves, where: float) -> None:
    df = pd.read_csv(out_csv)
    i = int(where * len(df))
    df.loc[df.index[i:i + 3], "segment"] = 2**40
    wide = tmp_path / "wide.csv"
    df.to_csv(wide, index=False)
    fast = rep._read_csv_fast(wide)
    assert fast["segment"].dtype == np.int64
    assert np.array_equal(fast["segment"].to_numpy(), df["segment"].to_numpy())
    pd.testing.assert_frame_equal(fast, rep._read_batches(wide), check_exact=True)


def test_quoted_field_is_read_by_one_reader(tmp_path: Path, halves) -> None:
    f = tmp_path / "quoted.csv"
    rows = [f"{i * 0.1:.1f},{50000 + i},\"a\nb\"" for i in range(400)]
    f.write_text("time,mag,note\n" + "\n".join(rows) + "\n")
    d = rep._read_csv_fast(f)
    assert halves == []  # quotes in the sample: no split looked for
    assert len(d) == 400 and np.array_equal(d["mag"].to_numpy(), 50000 + np.arange(400.0))


def test_last_row_without_line_break(out_csv: Path, tmp_path: Path, halves,
                                     monkeypatch) -> None:
    f = tmp_path / "noeol.csv"
    f.write_text(out_csv.read_text().rstrip("\n"))
    pd.testing.assert_frame_equal(rep._read_csv_fast(f), _one_reader(out_csv, monkeypatch),
                                  check_exact=True)


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(n=st.integers(1, 300), crlf=st.booleans(), seed=st.integers(0, 2**31 - 1),
       digits=st.integers(1, 17))
def test_any_split_of_a_numeric_log_reads_every_row_once(tmp_path: Path, halves, n: int,
                                                         crlf: bool, seed: int,
                                                         digits: int) -> None:
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.01, 1.0, n))
    mag = rng.normal(50000, 3000, n)
    seg = rng.integers(0, 40, n)
    eol = "\r\n" if crlf else "\n"
    body = eol.join(f"{float(a)!r},{b:.{digits}g},{s}"
                    for a, b, s in zip(t, mag, seg, strict=True))
    f = tmp_path / "prop.csv"
    f.write_bytes(("time,mag,segment" + eol + body + eol).encode())
    d = rep._read_csv_fast(f)
    if n >= 20:  # the middle falls before the last row: split
        assert halves[-1] is not None
    assert len(d) == n
    assert np.array_equal(d["time"].to_numpy(), t)
    assert np.array_equal(d["mag"].to_numpy(), np.array([float(f"{b:.{digits}g}")
                                                         for b in mag]))
    assert np.array_equal(d["segment"].to_numpy(), seg)


def test_columns_hold_their_rows_only_and_line_narrowed_when_lossless(out_csv: Path,
                                                                     tmp_path: Path) -> None:
    d = rep.read_columns(out_csv)
    for c in d.columns:
        x = d[c].to_numpy()
        base = x if x.base is None else x.base
        assert base.nbytes == x.nbytes, f"{c} holds {base.nbytes - x.nbytes} bytes past its rows"
    assert d["line"].dtype == np.float32
    assert np.array_equal(d["line"].to_numpy(), pd.read_csv(out_csv)["line"].to_numpy())
    df = pd.read_csv(out_csv)
    df.loc[df.index[7], "line"] = 16777217.0  # 2**24 + 1: not a float32
    f = tmp_path / "bigline.csv"
    df.to_csv(f, index=False)
    e = rep.read_columns(f)
    assert e["line"].dtype == np.float64 and e["line"].iloc[7] == 16777217.0
