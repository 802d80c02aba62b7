"""Format readers and writers on awkward real-world input: Oasis montaj XYZ, logger CSVs,
native UAV logs, Parquet date-times, SGL channel names (one test group per reviewed bug)."""

from __future__ import annotations

import re
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from aeromag.errors import InputError
from aeromag.io import csv as aio
from aeromag.io import read_log, unit_factor
from aeromag.io.formats import read_table, read_xyz, write_table, write_xyz

SAMPLES = Path(__file__).resolve().parents[1] / "data_samples" / "formats"  # ../shared copies

HYP = settings(max_examples=40, deadline=None,
               suppress_health_check=[HealthCheck.function_scoped_fixture])

OASIS = """\
/ ------------------------------------------------------------------------------
/ XYZ EXPORT [03/14/2021]
/ DATABASE  [.\\survey.gdb]
/ ------------------------------------------------------------------------------
/
/         tt         lat          lon      mag_1_uc    flux_a_x   flux_a_y   flux_a_z
/=========== =========== ============ ============= ========== ========== ==========
//Flight 1
//Date 2021/03/14
Line 10
  1000.0   45.1000000  -75.100000   52000.12   20000.1  -3000.2   45000.3
  1000.1   45.1000100  -75.100010   52000.15   20000.2  -3000.1   45000.4
  1000.2   45.1000200  -75.100020          *   20000.3  -3000.0   45000.5
Tie 100
  1000.3   45.1000300  -75.100030   52000.20   20000.4  -2999.9   45000.6
  1000.4   45.1000400  -75.100040   52000.25   20000.5  -2999.8   45000.7
"""


def _write(tmp_path: Path, name: str, text: str | bytes) -> Path:
    p = tmp_path / name
    if isinstance(text, bytes):
        p.write_bytes(text)
    else:
        p.write_text(text)
    return p


# --------------------------------------------------------------------------- B1 XYZ names
def test_oasis_export_channel_names_and_values(tmp_path):
    """Title, underline, '//Flight' and '//Date' lines never become the channel names."""
    df = read_log(_write(tmp_path, "oasis.xyz", OASIS), required=("time", "mag", "flux_x"))
    assert list(df.columns[:7]) == ["tt", "lat", "lon", "mag_1_uc", "flux_a_x", "flux_a_y",
                                    "flux_a_z"]
    np.testing.assert_array_equal(df["time"], [1000.0, 1000.1, 1000.2, 1000.3, 1000.4])
    assert df["mag"].iloc[1] == 52000.15 and np.isnan(df["mag"].iloc[2])
    assert df["flux_z"].iloc[-1] == 45000.7 and df["lon"].iloc[0] == -75.1
    assert df["line"].tolist() == [10, 10, 10, 100, 100]
    assert df["line_type"].tolist() == ["line"] * 3 + ["tie"] * 2


def test_units_row_and_flight_line_after_the_names(tmp_path):
    text = ("/ tt lat lon mag_1_uc\n/ s deg deg nT\n//Flight 1\nLine 10\n1 45 -75 52000\n"
            "2 45 -75 52001\n")
    df = read_xyz(_write(tmp_path, "u.xyz", text))
    assert list(df.columns[:4]) == ["tt", "lat", "lon", "mag_1_uc"]
    assert df["mag_1_uc"].tolist() == [52000, 52001]


@pytest.mark.parametrize("text,where", [
    ("/ time mag\n1 50000 7\n2 50001 8\n3 50002 9\n", "line 2: 3 values"),  # fewer names
    ("/ time mag flux\nLine 1\n1 5 6\n2 5\n3 5 6\n", "line 4: 2 values but 3 channels"),
    ("/ time mag\n// c\nLine 1\n1 5\n\n2 5 6 7\n", "line 6: 4 values but 2 channels"),
])
def test_value_count_mismatch_is_an_error_naming_the_line(tmp_path, text, where):
    with pytest.raises(InputError, match=re.escape(where)) as e:
        read_xyz(_write(tmp_path, "bad.xyz", text))
    assert "bad.xyz" in str(e.value) and "\n" not in str(e.value)


_NAME = st.from_regex(r"[A-Za-z][A-Za-z0-9_]{0,7}", fullmatch=True)
_CLUTTER = st.sampled_from(["//Flight 1", "//Date 2021/03/14", "/", "/=====  =====",
                            "/ ------", "// note: turn"])


@HYP
@given(names=st.lists(_NAME, min_size=1, max_size=6, unique_by=str.lower),
       n=st.integers(1, 12), clutter=st.lists(_CLUTTER, max_size=4), data=st.data())
def test_property_xyz_values_come_back_under_their_names(tmp_path, names, n, clutter, data):
    """Whatever '//' lines and underlines Oasis adds after the names line, every value is
    read back exactly under its own channel name (never shifted)."""
    if any(nm.lower() in ("line", "line_type", "line_label", "segment") for nm in names):
        return
    vals = data.draw(st.lists(st.lists(st.floats(-1e9, 1e9, allow_nan=False, width=64),
                                       min_size=len(names), max_size=len(names)),
                              min_size=n, max_size=n))
    df = pd.DataFrame(vals, columns=names)
    p = tmp_path / "h.xyz"
    write_xyz(df, p)
    lines = p.read_text().split("\n")
    assert lines[2] == "Line 0"  # the writer's header of a table without lines, replaced:
    p.write_text("\n".join(lines[:2] + clutter + ["Line 7"] + lines[3:]))
    back = read_xyz(p)
    for c in names:
        np.testing.assert_array_equal(back[c].to_numpy(dtype=float), df[c].to_numpy())
    assert back["line"].tolist() == [7] * n


# --------------------------------------------------------------------------- B2 CSV rows
CLEAN = ("time,mag,flux_x,flux_y,flux_z\n0.0,50000.1,20000,-3000,45000\n"
         "0.1,50000.2,20001,-3001,45001\n")


def _no_arrow(monkeypatch):
    """Force the pandas reader (as when pyarrow is missing or cannot read the file)."""
    monkeypatch.setattr(aio, "read_csv_arrow", lambda path, names=None, **kw: None)


@pytest.mark.parametrize("pandas_only", [False, True])
def test_trailing_delimiter_on_every_row_is_dropped(tmp_path, monkeypatch, pandas_only):
    if pandas_only:
        _no_arrow(monkeypatch)
    ref = read_log(_write(tmp_path, "clean.csv", CLEAN))
    trailing = CLEAN.replace("\n0", ",\n0").rstrip("\n") + ",\n"
    got = read_log(_write(tmp_path, "t.csv", trailing))
    pd.testing.assert_frame_equal(got, ref, check_exact=True)
    assert "passthrough_csv" not in got.attrs  # its lines cannot be copied with new columns


@pytest.mark.parametrize("pandas_only", [False, True])
@pytest.mark.parametrize("text,where", [
    ("time,mag\n0,1,\n1,2,9\n", "line 3"),  # a value where the trailing field should be empty
    ("time,mag\n0,1\n1,2,9\n", "line 3"),
    ("time,mag\n0,1,9\n1,2,9\n", "line 2"),  # every row one too many: never the index
    ("time,mag\n0,1,,\n1,2,,\n", "line 2"),  # two extra fields
    ("time,mag\n\n0,1\n\n1,2,,,\n", "line 5"),
])
def test_extra_fields_are_errors_naming_the_line(tmp_path, monkeypatch, pandas_only, text,
                                                 where):
    if pandas_only:
        _no_arrow(monkeypatch)
    with pytest.raises(InputError, match=rf"x\.csv: {where}: ") as e:
        read_log(_write(tmp_path, "x.csv", text))
    assert "\n" not in str(e.value)


def test_empty_header_cells_and_text_columns(tmp_path):
    df = read_log(_write(tmp_path, "e.csv", "time,mag,,\n0,1,,\n1,2,,\n"))
    assert list(df.columns) == ["time", "mag"]
    with pytest.raises(InputError, match="column 3 has no name in the header"):
        read_log(_write(tmp_path, "f.csv", "time,mag,\n0,1,\n1,2,5\n"))
    # text column + trailing delimiter: the pandas path, same rule
    df = read_log(_write(tmp_path, "g.csv", "time,mag,note\n0,1,a b,\n1,2,c,\n"))
    assert df["note"].tolist() == ["a b", "c"] and df["mag"].tolist() == [1, 2]


def test_passthrough_only_when_every_row_has_the_header_fields(tmp_path):
    """Read through pandas (a text column), the lines are copied only when their field
    counts match the header; a short row turns it off (it would shift the new columns)."""
    good = read_log(_write(tmp_path, "a.csv", "time,mag,note\n0,1,x\n1,2,y\n"))
    assert "passthrough_csv" in good.attrs
    with pytest.raises(InputError, match=r"b.csv: line 4: the last row has 2 of the header's 3"
                       r" fields.*allow_truncated=True"):
        read_log(_write(tmp_path, "b.csv", "time,mag,note\n0,1,x\n1,2,y\n2,3\n"))
    short = read_log(tmp_path / "b.csv", allow_truncated=True)
    assert "passthrough_csv" not in short.attrs and len(short) == 2


_FLOATS = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)


@HYP
@given(st.lists(st.tuples(_FLOATS, _FLOATS), min_size=2, max_size=20),
       st.booleans(), st.lists(st.integers(0, 25), max_size=3), st.booleans())
def test_property_csv_readers_agree(tmp_path, rows, trailing, blanks, text_col):
    """pyarrow and pandas read the same table; a trailing delimiter never shifts a value."""
    lines = ["time,mag" + (",note" if text_col else "")]
    for i, (_, m) in enumerate(rows):
        lines.append(f"{i},{m!r}" + (f",n{i}" if text_col else "") + ("," if trailing else ""))
    for b in sorted(blanks, reverse=True):
        lines.insert(min(1 + b, len(lines)), "")
    p = tmp_path / "p.csv"
    p.write_text("\n".join(lines) + "\n")
    a = read_log(p)
    real = aio.read_csv_arrow
    try:
        aio.read_csv_arrow = lambda path, names=None, **kw: None
        b = read_log(p)
    finally:
        aio.read_csv_arrow = real
    pd.testing.assert_frame_equal(a, b, check_exact=True)
    np.testing.assert_array_equal(a["mag"].to_numpy(), [m for _, m in rows])


# --------------------------------------------------------------------------- B3 duplicates
@pytest.mark.parametrize("body", ["0,1,2,3\n1,1,2,3\n", "0,1,2,x\n1,1,2,y\n", "\r0,1,2,x\r"])
def test_duplicate_header_name_is_a_one_line_error(tmp_path, body):
    """Numeric (pyarrow), text (pandas, which would rename the copy 'mag.1') or old-Mac line
    ends: the same one-line error naming the column."""
    p = _write(tmp_path, "dup.csv", "time,mag,mag,note" + ("\n" + body if body[0] != "\r"
                                                            else body))
    with pytest.raises(InputError, match=r"dup\.csv: column 'mag' appears twice in the header "
                                         r"\(columns 2 and 3\)"):
        read_log(p)


def test_duplicate_name_in_a_numeric_log(tmp_path):
    """Columns are keyed by name: a duplicate must not collapse silently."""
    p = _write(tmp_path, "big.csv", "time,mag,mag\n" + "".join(f"{i},1,2\n" for i in range(50)))
    with pytest.raises(InputError, match="'mag' appears twice"):
        read_log(p)
    q = _write(tmp_path, "dup.xyz", "/ time mag mag\n1 2 3\n2 2 3\n")
    with pytest.raises(InputError, match="'mag' appears twice in the channel-name line"):
        read_log(q)


# --------------------------------------------------------------------------- B4 line headers
@pytest.mark.parametrize("header,line,kind,label", [
    ("Line 10", 10, None, None),
    ("LINE 10.1", 10, None, "LINE 10.1"),
    ("L1010.1", 1010, None, "L1010.1"),
    ("line 10", 10, None, None),
    ("T100", 100, "tie", None),
    ("Tie 100", 100, "tie", None),
    ("Line 10:16", 10, None, "Line 10:16"),
    ("Trend 5", 5, "trend", None),
    ("BASE 1", 1, "base", None),
    ("Test 2", 2, "test", None),
    ("Random 3", 3, "random", None),
    ("special 4", 4, "special", None),
])
def test_geosoft_line_header_forms(tmp_path, header, line, kind, label):
    df = read_log(_write(tmp_path, "h.xyz", f"/ time mag\n{header}\n1 50000\n2 50001\n"))
    assert df["line"].tolist() == [line, line] and df["line"].dtype == np.int64
    assert (df["line_type"].tolist() if "line_type" in df else None) == (
        None if kind is None else [kind, kind])
    assert (df["line_label"].tolist() if "line_label" in df else None) == (
        None if label is None else [label, label])


def test_line_and_tie_with_the_same_number_stay_apart(tmp_path):
    text = ("/ time mag\nLine 100\n1 5\n2 5\nTie 100\n3 5\n4 5\nLine 3086\n5 5\n"
            "L1010.1\n6 5\nL1010.2\n7 5\nLine 100\n8 5\n")
    df = read_log(_write(tmp_path, "t.xyz", text))
    assert df["line"].tolist() == [100, 100, 10001, 10001, 3086, 1010, 10002, 100]
    assert df["line_type"].tolist() == ["line", "line", "tie", "tie"] + ["line"] * 4
    assert df["line_label"].tolist()[2] == "Tie 100" and df["line_label"].iloc[6] == "L1010.2"
    # written back: the same headers, so the same ids
    write_xyz(df, tmp_path / "w.xyz")
    headers = [x for x in (tmp_path / "w.xyz").read_text().split("\n") if x[:1].isalpha()]
    assert headers == ["Line 100", "Tie 100", "Line 3086", "L1010.1", "L1010.2", "Line 100"]
    back = read_xyz(tmp_path / "w.xyz")
    assert back["line"].tolist() == df["line"].tolist()


_HEADER = st.tuples(st.sampled_from(["Line", "Tie", "Trend", "Base", "L", "T"]),
                    st.integers(0, 120), st.sampled_from(["", ".1", ".2", ":16"]))


@HYP
@given(st.lists(_HEADER, min_size=1, max_size=8))
def test_property_line_ids_distinct_per_header(tmp_path, headers):
    """Different headers never share an id, the same header always gets the same id, and a
    number used by one header only is kept as the id."""
    text = ["/ time mag"]
    for i, (word, num, suffix) in enumerate(headers):
        sep = "" if len(word) == 1 else " "
        text += [f"{word}{sep}{num}{suffix}", f"{i} 5"]
    df = read_xyz(_write(tmp_path, "p.xyz", "\n".join(text) + "\n"))
    kind = {"Line": "line", "L": "line", "Tie": "tie", "T": "tie", "Trend": "trend",
            "Base": "base"}
    keys = [(kind[w], n, s) for w, n, s in headers]
    ids = df["line"].tolist()
    by_key: dict = {}
    for k, i in zip(keys, ids, strict=True):
        assert by_key.setdefault(k, i) == i
    assert len(set(by_key.values())) == len(by_key)
    for k, i in by_key.items():
        if sum(1 for kk in by_key if kk[1] == k[1]) == 1:
            assert i == k[1]


# --------------------------------------------------------------------------- B5 BOM
def test_xyz_with_byte_order_mark_and_crlf(tmp_path):
    p = _write(tmp_path, "bom.xyz", b"\xef\xbb\xbf/ time mag\r\nLine 1\r\n1 50000\r\n2 50001\r\n")
    df = read_log(p)
    assert df["mag"].tolist() == [50000, 50001] and df["line"].tolist() == [1, 1]


# --------------------------------------------------------------------------- B6 XYZ writer
def test_missing_line_ids_are_written_once_and_read_back_missing(tmp_path):
    df = pd.DataFrame({"time": [0.0, 1.0, 2.0, 3.0, 4.0],
                       "line": [np.nan, 10.0, np.nan, np.nan, 11.0]})
    write_xyz(df, tmp_path / "n.xyz")
    lines = (tmp_path / "n.xyz").read_text().split("\n")[2:-1]
    assert lines == ["0.0", "Line 10", "1.0", "Line *", "2.0", "3.0", "Line 11", "4.0"]
    back = read_xyz(tmp_path / "n.xyz")
    np.testing.assert_array_equal(back["line"].to_numpy(), df["line"].to_numpy())


def test_text_and_large_line_ids(tmp_path):
    df = pd.DataFrame({"time": [1.0, 2.0, 3.0], "line": ["L10", "L10", "T20"]})
    write_xyz(df, tmp_path / "s.xyz")
    assert "L10" in (tmp_path / "s.xyz").read_text().split("\n")
    back = read_xyz(tmp_path / "s.xyz")
    assert back["line"].tolist() == [10, 10, 20] and back["line_type"].tolist()[2] == "tie"
    big = pd.DataFrame({"time": [1.0, 2.0], "line": [2**60 + 1] * 2})
    write_xyz(big, tmp_path / "b.xyz")
    assert read_xyz(tmp_path / "b.xyz")["line"].tolist() == [2**60 + 1] * 2
    with pytest.raises(InputError, match=r"column 'line', row 1: 'abc' is not a Geosoft line"):
        write_xyz(pd.DataFrame({"time": [1.0], "line": ["abc"]}), tmp_path / "x.xyz")
    assert not (tmp_path / "x.xyz").exists()


@pytest.mark.parametrize("df,match", [
    (pd.DataFrame({"time": [1.0, 2.0], "note": ["*", "x"]}), r"column 'note', row 1: text '\*'"),
    (pd.DataFrame({"note": ["y", "/x"], "time": [1.0, 2.0]}), r"column 'note', row 2"),
    (pd.DataFrame({"time": [1.0, 2.0], "note": ["a b", "x"]}), r"column 'note', row 1"),
    (pd.DataFrame({"time": [1.0, 2.0], "note": ["", "x"]}), r"column 'note', row 1"),
    (pd.DataFrame({"note": ["L10", "x"]}), r"row 1: 'L10' would read back as a line header"),
])
def test_text_xyz_cannot_hold_is_refused(tmp_path, df, match):
    with pytest.raises(InputError, match=match):
        write_xyz(df, tmp_path / "t.xyz")
    assert list(tmp_path.iterdir()) == []  # nothing half-written


def test_dates_and_text_round_trip(tmp_path):
    df = pd.DataFrame({"time": [1.0, 2.0], "note": ["/x", "Line"],
                       "ts": pd.to_datetime(["2020-01-01", "2020-01-01 00:00:01.5"],
                                             format="ISO8601")})
    write_xyz(df, tmp_path / "d.xyz")
    back = read_xyz(tmp_path / "d.xyz")
    assert back["note"].tolist() == ["/x", "Line"]
    assert pd.to_datetime(back["ts"], format="ISO8601").tolist() == df["ts"].tolist()


# --------------------------------------------------------------------------- B7 locations
def test_errors_name_the_file_line_in_every_text_format(tmp_path):
    with pytest.raises(InputError, match=r"column 'mag', line 7: value 'abc'"):
        read_log(_write(tmp_path, "a.xyz", "/ t\n/ time mag\n//F 1\nLine 1\n1 5\n2 6\n3 abc\n"))
    with pytest.raises(InputError, match=r"column 'mag', line 6: value 'oops'"):
        read_log(_write(tmp_path, "b.csv", "time,mag\n0,1\n\n1,2\n\n2,oops\n"))
    with pytest.raises(InputError, match=r"line 5: time 1 is not after 2;") as e:
        read_log(_write(tmp_path, "c.csv", "time,mag\n0,1\n\n2,2\n1,3\n"))
    assert "np.float64" not in str(e.value)


def test_hdf5_and_parquet_errors_name_the_sample_or_row(tmp_path):
    with h5py.File(tmp_path / "f.h5", "w") as h5:
        h5["tt"] = np.array([0.0, 0.1, 0.1, 0.3])
        h5["mag_1_uc"] = np.array([1.0, 2.0, 3.0, 4.0])
    with pytest.raises(InputError, match=r"f\.h5: column 'time', sample 3 \(index 2\): time 0.1"
                                         r" is not after 0.1"):
        read_log(tmp_path / "f.h5")
    pd.DataFrame({"time": [0.0, 1.0, 2.0], "mag": ["1", "2", "x"]}).to_parquet(tmp_path / "p.pq")
    with pytest.raises(InputError, match=r"column 'mag', row 3 \(index 2\): value 'x'"):
        read_log(tmp_path / "p.pq")


# --------------------------------------------------------------------------- B8 native logs
def _magdrone(tmp_path, old: str, new: str) -> Path:
    src = (SAMPLES / "magdrone_r3_sample.csv").read_text()
    assert old in src
    return _write(tmp_path, "md.csv", src.replace(old, new, 1))


def test_magdrone_garbage_is_an_error_naming_column_and_line(tmp_path):
    with pytest.raises(InputError, match=r"md\.csv: column 'B1x \[nT\]', line 26: value 'abc'"):
        read_log(_magdrone(tmp_path, "\n70;10193.91;", "\n70;abc;"))
    with pytest.raises(InputError, match=r"column 'Timestamp \[ms\]', line 25: value '6x5'"):
        read_log(_magdrone(tmp_path, "\n65;", "\n6x5;"))


@pytest.mark.parametrize("unit,factor", [("[s]", 1.0), ("[min]", 60.0), ("[us]", 1e-6)])
def test_magdrone_time_units_are_converted(tmp_path, unit, factor):
    df = read_log(_magdrone(tmp_path, "Timestamp [ms]", f"Timestamp {unit}"))
    clock = df["time_logger"] if "time_logger" in df.columns else df["time"]  # UTC when GPS fits
    np.testing.assert_allclose(clock.iloc[:2], np.array([60.0, 65.0]) * factor)


@pytest.mark.parametrize("header,match", [("Timestamp [fortnight]", "unknown unit 'fortnight'"),
                                          ("Timestamp", "no unit")])
def test_magdrone_unknown_or_missing_time_unit_is_an_error(tmp_path, header, match):
    with pytest.raises(InputError, match=rf"column 'Timestamp' has {match}"):
        read_log(_magdrone(tmp_path, "Timestamp [ms]", header))


@pytest.mark.parametrize("unit", ["\u00b5T", "\u03bcT", "uT"])
def test_magdrone_microtesla_both_spellings(tmp_path, unit):
    src = (SAMPLES / "magdrone_r3_sample.csv").read_text()
    p = _write(tmp_path, "u.csv", src.replace("B1x [nT]; B1y [nT]; B1z [nT]",
                                              f"B1x [{unit}]; B1y [{unit}]; B1z [{unit}]"))
    assert read_log(p)["flux_x"].iloc[0] == pytest.approx(10195.42e3)
    assert unit_factor(unit) == 1e3 and unit_factor("pT") == 1e-3


def test_magarrow_garbage_is_an_error(tmp_path):
    src = (SAMPLES / "magarrow_sample.csv").read_text()
    p = _write(tmp_path, "ma.csv", src.replace("51384.04790", "5138X.04790"))
    with pytest.raises(InputError, match=r"ma\.csv: column 'Mag', line 4: value '5138X.04790'"):
        read_log(p)
    q = _write(tmp_path, "mb.csv", src.replace("13:37:53.002", "13:37:xx"))
    with pytest.raises(InputError, match=r"columns 'Date'/'Time', line 4"):
        read_log(q)


# --------------------------------------------------------------------------- B9 date-times
@pytest.mark.parametrize("unit", ["s", "ms", "us", "ns"])
@pytest.mark.parametrize("tz", [None, "UTC", "Europe/Zurich"])
def test_parquet_datetime_time_becomes_epoch_seconds(tmp_path, unit, tz):
    t = pd.to_datetime(["2024-01-01 00:00:00", "2024-01-01 00:00:01", "2024-01-01 00:00:02"])
    if tz:
        t = t.tz_localize(tz)
    df = pd.DataFrame({"time": pd.Series(t).dt.as_unit(unit), "mag": [1.0, 2.0, 3.0]})
    df.to_parquet(tmp_path / "t.parquet")
    got = read_log(tmp_path / "t.parquet")["time"].to_numpy()
    start = pd.Timestamp("2024-01-01", tz=tz).tz_convert("UTC") if tz else pd.Timestamp(
        "2024-01-01", tz="UTC")
    np.testing.assert_array_equal(got, start.timestamp() + np.array([0.0, 1.0, 2.0]))


def test_sub_second_times_and_csv_iso_agree_with_parquet(tmp_path):
    iso = ["2024-01-01T00:00:00.1", "2024-01-01T00:00:00.2", "2024-01-01T00:00:00.300001"]
    _write(tmp_path, "i.csv", "time,mag\n" + "".join(f"{s},{k}\n" for k, s in enumerate(iso)))
    a = read_log(tmp_path / "i.csv")
    pd.DataFrame({"time": pd.to_datetime(iso), "mag": [0, 1, 2]}).to_parquet(tmp_path / "i.pq")
    b = read_log(tmp_path / "i.pq")
    np.testing.assert_array_equal(a["time"].to_numpy(), b["time"].to_numpy())
    assert a["time"].iloc[0] == 1704067200.1
    assert "passthrough_csv" not in a.attrs  # the time text is not what the log now holds
    with pytest.raises(InputError, match=r"column 'time', line 3: value 'soon'"):
        read_log(_write(tmp_path, "j.csv", f"time,mag\n{iso[0]},1\nsoon,2\n"))


def test_parquet_duration_time_becomes_seconds(tmp_path):
    df = pd.DataFrame({"time": pd.to_timedelta([0.0, 0.25, 1.5], unit="s"), "mag": [1, 2, 3]})
    df.to_parquet(tmp_path / "d.parquet")
    assert read_log(tmp_path / "d.parquet")["time"].tolist() == [0.0, 0.25, 1.5]


def test_parquet_with_time_as_index(tmp_path):
    df = pd.DataFrame({"time": [0.0, 0.1, 0.2], "mag": [1.0, 2.0, 3.0]}).set_index("time")
    df.to_parquet(tmp_path / "x.parquet")
    got = read_log(tmp_path / "x.parquet")
    assert got["time"].tolist() == [0.0, 0.1, 0.2] and got["mag"].tolist() == [1.0, 2.0, 3.0]


# --------------------------------------------------------------------------- B10 presets
def test_sgl_ascii_channel_names(tmp_path):
    n = 6
    cols = {"LINE": np.full(n, 1002.02), "TIME": 46370 + np.arange(n) / 10,
            "UTM-Z": np.full(n, 400.0), "MSL-Z": np.full(n, 435.0), "LAT": np.full(n, 45.3),
            "LONG": np.full(n, -76.5), "PITCH": np.full(n, 2.0), "ROLL": np.full(n, -3.0),
            "AZIMUTH": np.full(n, 91.5), "COMPMAG1": np.full(n, 53900.0),
            "UNCOMPMAG1": np.full(n, 54000.0), "UNCOMPMAG2": np.full(n, 54100.0),
            "FLUXB_X": np.full(n, 10001.0), "FLUXB_Y": np.full(n, -1999.0),
            "FLUXB_Z": np.full(n, 50001.0), "FLUXC_X": np.full(n, 7.0),
            "FLUXC_Y": np.full(n, 8.0), "FLUXC_Z": np.full(n, 9.0)}
    write_xyz(pd.DataFrame(cols), tmp_path / "Flt1002.xyz")
    df = read_log(tmp_path / "Flt1002.xyz",
                  required=("time", "mag", "flux_x", "alt", "heading", "line"))
    assert df["alt"].iloc[0] == 400.0  # ellipsoid, not MSL
    assert df["mag"].iloc[0] == 54000.0  # uncompensated Mag 1
    assert (df["flux_x"].iloc[0], df["flux_z"].iloc[0]) == (10001.0, 50001.0)  # B: no A
    assert (df["heading"].iloc[0], df["pitch"].iloc[0], df["roll"].iloc[0]) == (91.5, 2, -3)
    assert df["lon"].iloc[0] == -76.5 and df["line"].iloc[0] == 1002.02


def test_fluxgate_a_preferred_whole_and_yaw_is_heading(tmp_path):
    n = 4
    with h5py.File(tmp_path / "x.h5", "w") as h5:
        h5["tt"] = np.arange(n) / 10
        h5["mag_1_uc"] = np.full(n, 5e4)
        h5["yaw"] = np.full(n, 12.5)
        for ax in "xyz":
            h5[f"flux_a_{ax}"] = np.full(n, np.nan)  # Flux A present but empty (Flt1002)
            h5[f"flux_b_{ax}"] = np.full(n, 2.0)
            h5[f"flux_c_{ax}"] = np.full(n, 3.0)
        h5["flux_a_x"][...] = np.full(n, 1.0)  # data on one axis of A only
    df = read_log(tmp_path / "x.h5", required=("time", "flux_x", "heading"))
    assert df["heading"].tolist() == [12.5] * n
    # all three axes from one sensor, the first with data on every axis: B, never A's x + B
    assert [df[c].iloc[0] for c in ("flux_x", "flux_y", "flux_z")] == [2.0, 2.0, 2.0]
    with h5py.File(tmp_path / "x.h5", "a") as h5:
        for ax in "xyz":
            h5[f"flux_a_{ax}"][...] = np.full(n, 1.0)
    df = read_log(tmp_path / "x.h5", required=("time", "flux_x"))
    assert [df[c].iloc[0] for c in ("flux_x", "flux_y", "flux_z")] == [1.0, 1.0, 1.0]


def test_preset_never_overrides_a_users_map(tmp_path):
    df = pd.DataFrame({"tt": [0.0, 0.1], "flux_b_x": [1.0, 1.0], "flux_b_y": [2.0, 2.0],
                       "flux_b_z": [3.0, 3.0], "fx": [9.0, 9.0]})
    write_table(df, tmp_path / "m.xyz")
    got = read_log(tmp_path / "m.xyz", columns={"flux_x": "fx"})
    assert got["flux_x"].tolist() == [9.0, 9.0]
    assert read_table(tmp_path / "m.xyz")["flux_y"].tolist() == [2.0, 2.0]
