"""Reading logs: column maps, units, validation, atomic writes."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aeromag.errors import InputError
from aeromag.io import (
    atomic_path,
    parse_column_map,
    read_log,
    read_map_file,
    unit_factor,
    write_csv,
    write_json,
)


def _log(tmp_path, text, name="log.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_column_map_and_units(tmp_path):
    p = _log(tmp_path, "TIME,mag_1_uc,fx,fy,fz\n0,50000,10,20,30\n0.1,50001,11,21,31\n")
    df = read_log(p, columns={"time": "TIME", "mag": "mag_1_uc", "flux_x": "fx",
                              "flux_y": "fy", "flux_z": "fz"}, units={"flux": "uT"})
    assert list(df.columns) == ["time", "mag", "flux_x", "flux_y", "flux_z"]
    np.testing.assert_allclose(df["flux_x"], [10000, 11000])
    np.testing.assert_allclose(df["mag"], [50000, 50001])  # not converted: not asked


def test_units_are_never_guessed(tmp_path):
    p = _log(tmp_path, "time,mag\n0,0.5\n1,0.5\n")
    assert read_log(p)["mag"].iloc[0] == 0.5
    assert read_log(p, units={"mag": "G"})["mag"].iloc[0] == pytest.approx(50000.0)
    with pytest.raises(InputError, match="unknown field unit"):
        read_log(p, units={"mag": "furlong"})


def test_missing_column_names_file_and_column(tmp_path):
    p = _log(tmp_path, "time,mag\n0,1\n1,2\n")
    with pytest.raises(InputError) as e:
        read_log(p, required=("time", "flux_x"))
    msg = str(e.value)
    assert "log.csv" in msg and "flux_x" in msg and "columns={'NAME': 'SOURCE'}" in msg
    with pytest.raises(InputError, match="'nope'"):
        read_log(p, columns={"mag": "nope"})


def test_text_in_numeric_column_names_line(tmp_path):
    p = _log(tmp_path, "time,mag\n0,1\n1,2\n2,abc\n")
    with pytest.raises(InputError, match=r"column 'mag', line 4: value 'abc'"):
        read_log(p)


def test_empty_and_one_row_files(tmp_path):
    with pytest.raises(InputError, match="empty"):
        read_log(_log(tmp_path, "", "e.csv"))
    with pytest.raises(InputError, match="only 1 data row"):
        read_log(_log(tmp_path, "time,mag\n0,1\n", "o.csv"))


def test_exact_duplicates_dropped_and_time_must_increase(tmp_path):
    df = read_log(_log(tmp_path, "time,mag\n0,1\n1,2\n1,2\n2,3\n"))
    assert list(df["time"]) == [0, 1, 2]
    with pytest.raises(InputError, match="line 4.*strictly increasing"):
        read_log(_log(tmp_path, "time,mag\n0,1\n1,2\n1,5\n2,3\n", "d.csv"))
    with pytest.raises(InputError, match="line 3"):
        read_log(_log(tmp_path, "time,mag\n0,1\n,2\n", "n.csv"))


def test_map_file(tmp_path):
    m = _log(tmp_path, '[columns]\nmag = "m1"\n[units]\nmag = "nT"\n', "map.toml")
    cols, units = read_map_file(m)
    assert cols == {"mag": "m1"} and units == {"mag": "nT"}
    with pytest.raises(InputError, match="not a valid TOML"):
        read_map_file(_log(tmp_path, "[columns\n", "bad.toml"))


def test_parse_column_map_errors():
    assert parse_column_map(["mag=a", " flux_x = b "]) == {"mag": "a", "flux_x": "b"}
    for bad in ("mag", "=x", "mag="):
        with pytest.raises(InputError, match="NAME=VALUE"):
            parse_column_map([bad])


def test_unit_factors():
    assert unit_factor("nT") == 1 and unit_factor("uT") == 1e3 and unit_factor("µT") == 1e3
    assert unit_factor("mT") == 1e6 and unit_factor("G") == 1e5


def test_atomic_write_leaves_nothing_on_failure(tmp_path):
    target = tmp_path / "out.csv"
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


def test_bools_written_true_false_and_json_nan_is_null(tmp_path):
    p = write_csv(pd.DataFrame({"a": [1.5, 2.5], "k": [True, False]}), tmp_path / "x.csv")
    assert p.read_text().splitlines() == ["a,k", "1.5,true", "2.5,false"]
    j = write_json({"x": float("nan"), "y": np.float64(2.0), "z": np.arange(2)},
                   tmp_path / "x.json")
    assert j.read_text().replace(" ", "").replace("\n", "") == '{"x":null,"y":2.0,"z":[0,1]}'


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(-1e6, 1e6, allow_nan=False), min_size=2, max_size=30))
def test_numbers_round_trip_through_csv(tmp_path_factory, values):
    d = tmp_path_factory.mktemp("rt")
    df = pd.DataFrame({"time": np.arange(len(values), dtype=float), "mag": values})
    write_csv(df, d / "r.csv")
    back = read_log(d / "r.csv")
    np.testing.assert_array_equal(back["mag"].to_numpy(), np.asarray(values, dtype=float))


@settings(max_examples=30, deadline=None)
@given(st.text(alphabet=st.characters(blacklist_categories=("Cs",), blacklist_characters="=,\n\r"),
               min_size=1, max_size=10).filter(lambda s: s.strip() == s and s),
       st.text(alphabet="abcdefghij_0123", min_size=1, max_size=10))
def test_parse_column_map_property(name, source):
    assert parse_column_map([f"{name}={source}"]) == {name: source}


def test_outputs_get_normal_permissions(tmp_path):
    import os
    import stat

    p = write_csv(pd.DataFrame({"a": [1.0]}), tmp_path / "p.csv")
    mask = os.umask(0)
    os.umask(mask)
    assert stat.S_IMODE(p.stat().st_mode) == 0o666 & ~mask


def test_writer_round_trips_missing_values_booleans_and_quoted_text(tmp_path):
    """NaN (empty), booleans, integers with missing values, whole-number floats (``.0``) and
    text that needs quoting (the writer falls back to quoting) read back as written."""
    from aeromag import io as aio

    rng = np.random.default_rng(3)
    n = 5 * 1000 + 17
    x = rng.normal(0, 1e4, n)
    x[rng.integers(0, n, 40)] = np.nan
    df = pd.DataFrame({
        "time": np.arange(n) * 0.1, "x": x, "whole": np.floor(x / 100) * 100,
        "seg": pd.array(np.where(np.arange(n) % 97 == 0, None, np.arange(n) // 50),
                        dtype="Int64"),
        "kept": np.arange(n) % 3 > 0,
    })
    aio.write_csv(df, tmp_path / "t3.csv")
    df2 = df.assign(note=np.where(np.arange(n) == n - 3, 'a "quoted", text', "plain"))
    quoted = aio.write_csv(df2, tmp_path / "q3.csv").read_bytes()
    back = pd.read_csv(tmp_path / "t3.csv")
    np.testing.assert_array_equal(back["x"].to_numpy(), df["x"].to_numpy())
    assert back["whole"].dtype == np.float64
    assert back["kept"].dtype == bool
    assert b'"a ""quoted"", text"' in quoted


def test_reader_takes_a_column_that_turns_decimal_or_text_further_down(tmp_path):
    """Types frozen on the first block must not break a log whose integer column turns
    decimal further down, or whose text column starts empty: the file is read whole."""
    n = 3000
    rows = ["time,flux_x,flux_y,flux_z,mag,count,note"]
    for i in range(n):
        count = f"{i}" if i < 2000 else f"{i}.5"
        note = "" if i < 2500 else "gps,ok" if i % 2 else "x"
        rows.append(f"{i * 0.1:.1f},20000,3000,45000,50000.{i % 10},{count},"
                    + (f'"{note}"' if "," in note else note))
    p = tmp_path / "log.csv"
    p.write_text("\n".join(rows) + "\n")
    df = read_log(p)
    ref = pd.read_csv(p)
    assert len(df) == n
    np.testing.assert_array_equal(df["count"].to_numpy(), ref["count"].to_numpy())
    assert df["count"].dtype == np.float64
    assert df["note"].iloc[-1] == "gps,ok" and pd.isna(df["note"].iloc[0])
    # A uniform log streams, block by block, to the same values as pandas.
    q = tmp_path / "uniform.csv"
    q.write_text("time,flux_x,mag,line\n" + "".join(
        f"{i * 0.1:.1f},{20000 + i % 7},{50000 + i / 7},{i // 600}\n" for i in range(n)))
    a, b = read_log(q), pd.read_csv(q)
    for c in b.columns:
        np.testing.assert_array_equal(a[c].to_numpy(), b[c].to_numpy())


def _plain_log(tmp_path, name="plain.csv", eol="\n", tail_newline=True, extra_line=None):
    rows = ["time,flux_x,flux_y,flux_z,mag,line"]
    for i in range(2500):
        rows.append(f"{i * 0.1:.1f},{20000 + i % 13}.25,3000,45000,{50000 + i / 3:.4f},{i // 500}")
    if extra_line is not None:
        rows.append(extra_line)
        rows.append("250.1,20000,3000,45000,50000,5")
    text = eol.join(rows) + (eol if tail_newline else "")
    p = tmp_path / name
    p.write_bytes(text.encode())
    return p


@pytest.mark.parametrize("eol,tail", [("\n", True), ("\r\n", True), ("\n", False)])
def test_passthrough_copies_input_lines_and_appends_columns(tmp_path, monkeypatch, eol, tail):
    """Input lines copied verbatim (their own number formatting kept), added columns appended,
    across many blocks and threads; values equal to the column-by-column writer's."""
    from aeromag import io as aio

    monkeypatch.setattr(aio, "PASSTHROUGH_BLOCK_BYTES", 997)
    src = _plain_log(tmp_path, eol=eol, tail_newline=tail)
    df = read_log(src)
    assert df.attrs["passthrough_csv"]["columns"] == list(df.columns)
    extra = pd.DataFrame({"mag_tl": np.linspace(-3, 3, len(df)) / 7,
                          "segment": pd.array(np.arange(len(df)) // 100, dtype="Int64"),
                          "segment_kept": np.arange(len(df)) % 5 > 0})
    out = tmp_path / "out.csv"
    assert aio.write_csv_passthrough(src, list(df.columns), extra, out)
    lines = out.read_text().split("\n")
    src_lines = src.read_text().replace("\r\n", "\n").rstrip("\n").split("\n")
    assert lines[0] == src_lines[0] + ",mag_tl,segment,segment_kept"
    assert lines[1].startswith(src_lines[1] + ",")  # e.g. '20000.25' and '50000.0000' kept
    assert lines[-1] == "" and len(lines) == len(df) + 2
    ref = tmp_path / "ref.csv"
    write_csv(pd.concat([df, extra], axis=1), ref)
    a, b = pd.read_csv(out), pd.read_csv(ref)
    assert list(a.columns) == list(b.columns)
    for c in a.columns:
        np.testing.assert_array_equal(a[c].to_numpy(), b[c].to_numpy())


@pytest.mark.parametrize("bad", ["", '250.0,"20000",3000,45000,50000,5'])
def test_passthrough_refuses_files_that_are_not_plain(tmp_path, bad):
    """A blank line (which the readers skip) or quoting: the caller writes column by column."""
    from aeromag import io as aio

    src = _plain_log(tmp_path, extra_line=bad)
    df = read_log(src)
    extra = pd.DataFrame({"mag_tl": np.zeros(len(df))})
    assert not aio.write_csv_passthrough(src, list(df.columns), extra, tmp_path / "o.csv")


def test_passthrough_only_when_the_log_is_as_read(tmp_path):
    """Column maps, unit conversions and dropped duplicate rows turn the passthrough off."""
    src = _plain_log(tmp_path)
    assert "passthrough_csv" in read_log(src).attrs
    assert "passthrough_csv" not in read_log(src, columns={"mag": "mag"}).attrs
    assert "passthrough_csv" not in read_log(src, units={"flux": "nT"}).attrs
    dup = tmp_path / "dup.csv"
    text = src.read_text().split("\n")
    dup.write_text("\n".join(text[:5] + text[4:5] + text[5:]))
    assert "passthrough_csv" not in read_log(dup).attrs


def test_logs_read_equal_pandas_values_and_dtypes(tmp_path):
    """read_log gives pandas' values and dtypes, also with an empty integer cell."""
    n = 4000
    rows = ["time,mag,line,flag"] + [
        f"{i * 0.1:.1f},{'' if i % 777 == 5 else 50000 + i / 7},{i // 100},"
        f"{'true' if i % 3 else 'false'}" for i in range(n)]
    p = tmp_path / "big.csv"
    p.write_text("\n".join(rows) + "\n")
    df, ref = read_log(p), pd.read_csv(p)
    assert list(df.dtypes) == list(ref.dtypes)
    for c in ref.columns:
        np.testing.assert_array_equal(df[c].to_numpy(), ref[c].to_numpy())
    # An empty integer cell (pandas: float NaN) or a text column: not for the column reader.
    rows[3000] = rows[3000].replace(",29,", ",,")
    q = tmp_path / "gap.csv"
    q.write_text("\n".join(rows) + "\n")
    got = read_log(q)["line"].to_numpy()
    np.testing.assert_array_equal(got, pd.read_csv(q)["line"].to_numpy())
