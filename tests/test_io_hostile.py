"""Issue 16: every reader survives hostile input; model and map files are validated.

Each test names the failure class of the issue it covers; each fails on the code before the
fix (a traceback, a silent placeholder, a dropped dataset, an accepted absurd model ...).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from aeromag.errors import InputError
from aeromag.io import read_log, read_map_file, write_csv
from aeromag.io.formats import read_table, write_table
from aeromag.io.model_file import read_model_document

SAMPLES = Path(__file__).resolve().parents[1] / "data_samples" / "formats"  # ../shared copies
MAGDRONE = SAMPLES / "magdrone_r3_sample.csv"
MAGARROW = SAMPLES / "magarrow_sample.csv"
need_samples = pytest.mark.skipif(not MAGDRONE.exists(), reason="data_samples/formats absent")


def _log(n: int = 50) -> pd.DataFrame:
    t = np.arange(n) * 0.1
    return pd.DataFrame({"time": t, "mag": 50000 + np.sin(t), "flux_x": 20000 + t,
                         "flux_y": 1000.0 + 2 * t, "flux_z": 45000.0 - t, "note": "ok"})


def _csv_bytes(n: int = 50) -> bytes:
    p = Path(os.environ.get("TMPDIR", "/tmp")) / f"aeromag_hostile_{os.getpid()}.csv"
    write_csv(_log(n), p)
    b = p.read_bytes()
    p.unlink()
    return b


# --------------------------------------------------------------------------- CSV
def test_binary_garbage_as_csv_is_one_line_error(tmp_path):
    """Class: binary garbage given as a CSV (was 'file is empty' or a decode traceback)."""
    rng = np.random.default_rng(1)
    p = tmp_path / "g.csv"
    p.write_bytes(rng.integers(0, 256, 4000, dtype=np.uint8).tobytes())
    with pytest.raises(InputError, match=r"g.csv: line \d+: binary data .*not a text CSV log"):
        read_log(p)
    p.write_bytes(b"\x00\x01\x02" * 500)
    with pytest.raises(InputError, match="binary data"):
        read_log(p)


def test_non_utf8_csv_names_the_line(tmp_path):
    """Class: a non-UTF-8 byte in a CSV (was 'codec can't decode', no line)."""
    lines = _csv_bytes().split(b"\n")
    lines[7] = lines[7].replace(b",ok", b",\xe9t\xe9")
    p = tmp_path / "u.csv"
    p.write_bytes(b"\n".join(lines))
    with pytest.raises(InputError, match=r"u.csv: line 8: bytes that are not UTF-8.*iconv"):
        read_log(p)


def test_truncated_last_row_is_an_error_or_dropped_when_allowed(tmp_path):
    """Class: a log cut in the middle of a row was padded with empty values (exit 0)."""
    b = _csv_bytes()
    p = tmp_path / "t.csv"
    p.write_bytes(b[: b.rfind(b"\n", 0, len(b) - 1) + 12])  # cut inside the last row
    with pytest.raises(InputError, match=r"t.csv: line 51: the last row has \d of the header's"
                       r" 6 fields.*allow_truncated=True"):
        read_log(p)
    df = read_log(p, allow_truncated=True)
    assert len(df) == 49 and df["flux_z"].notna().all()


def test_short_row_inside_the_file_is_always_an_error(tmp_path):
    lines = _csv_bytes().split(b"\n")
    lines[10] = b",".join(lines[10].split(b",")[:3])
    p = tmp_path / "s.csv"
    p.write_bytes(b"\n".join(lines))
    for allow in (False, True):
        with pytest.raises(InputError, match=r"s.csv: line 11: 3 fields but the header names 6"):
            read_log(p, allow_truncated=allow)


def test_true_false_where_numbers_are_needed_is_an_error(tmp_path):
    """Class: true/false columns read as fluxgate values 0/1 (exit 0)."""
    df = _log()
    df["flag"] = np.arange(len(df)) % 2 == 0
    p = tmp_path / "b.csv"
    write_csv(df.drop(columns="flux_x"), p)
    with pytest.raises(InputError, match=r"column 'flux_x', line 2: value .*true/false"):
        read_log(p, columns={"flux_x": "flag"})


def test_text_in_an_unused_column_is_kept(tmp_path):
    """Class: a text value in a column the command does not use: kept, no error."""
    df = _log()
    df["extra"] = 1.5
    p = tmp_path / "x.csv"
    write_csv(df, p)
    text = p.read_text().replace(",1.5\n", ",oops\n", 1)
    p.write_text(text)
    out = read_log(p)
    assert out["extra"].iloc[0] == "oops" and len(out) == 50


def test_infinite_values_and_absurd_times_are_errors(tmp_path):
    b = _csv_bytes().decode()
    p = tmp_path / "i.csv"
    p.write_text(b.replace("\n0.5,", "\n1e400,", 1))
    with pytest.raises(InputError, match=r"i.csv: column 'time', line 7: value inf is infinite"):
        read_log(p)
    p.write_text(b.replace("\n0.5,", "\n1e20,", 1).replace("\n0.6,", "\n2e20,", 1))
    with pytest.raises(InputError, match=r"beyond 1e\+11 s .*ms, us or ns"):
        read_log(p)


def test_duplicate_rows_are_reported(tmp_path, caplog):
    """Class: exact duplicate rows dropped with no message in batch (now a warning)."""
    lines = _csv_bytes().split(b"\n")
    p = tmp_path / "d.csv"
    p.write_bytes(b"\n".join([*lines[:6], lines[5], *lines[6:]]))
    with caplog.at_level("WARNING", logger="aeromag"):
        df = read_log(p)
    assert len(df) == 50
    assert "dropped 1 exact duplicate row(s) (the first at line 7" in caplog.text


# --------------------------------------------------------------------------- Parquet / HDF5
def test_corrupt_parquet_is_one_line_error(tmp_path):
    """Class: corrupt Parquet (also on the chunked path: see test_fuzz)."""
    p = tmp_path / "c.parquet"
    write_table(_log(), p)
    b = p.read_bytes()
    p.write_bytes(b[: len(b) // 2])
    with pytest.raises(InputError, match=r"c.parquet: cannot read as Parquet .*undamaged"):
        read_log(p)
    # Page checksums (written since issue 16) catch bytes flipped inside the data.
    data = bytearray(b)
    data[len(b) // 3] ^= 0xFF
    p.write_bytes(bytes(data))
    try:
        df = read_log(p)
    except InputError as exc:
        assert "c.parquet" in str(exc)
    else:  # the flipped byte was in metadata that still decodes: values must be intact
        pd.testing.assert_series_equal(df["mag"], _log()["mag"], check_names=False)


def test_parquet_binary_column_cannot_be_written_as_csv(tmp_path):
    """Class: a Parquet binary column when writing the output (raw bytes in the CSV)."""
    df = _log()
    df["blob"] = [b"\x00\x01"] * len(df)
    with pytest.raises(InputError, match=r"column 'blob' holds binary data.*\.parquet"):
        write_csv(df, tmp_path / "o.csv")
    assert not list(tmp_path.iterdir())


h5py = pytest.importorskip("h5py")


def _h5(path: Path, **extra: np.ndarray) -> Path:
    n = 100
    with h5py.File(path, "w") as h:
        h["tt"] = np.arange(n) / 10.0
        h["mag_1_uc"] = np.full(n, 5e4)
        for a in "xyz":
            h[f"flux_a_{a}"] = np.ones(n)
        h["dt"] = 0.1  # a scalar: metadata, ignored
        for k, v in extra.items():
            h[k] = v
    return path


def test_hdf5_dataset_of_other_length_or_2d_is_an_error(tmp_path):
    """Class: HDF5 datasets of another length or 2-D dropped with no message."""
    assert len(read_log(_h5(tmp_path / "ok.h5"))) == 100
    with pytest.raises(InputError, match=r"dataset 'flux_b_x' has 99 samples while the"
                       r" channels have 100"):
        read_log(_h5(tmp_path / "len.h5", flux_b_x=np.ones(99)))
    with pytest.raises(InputError, match=r"dataset 'att' is 2-D \(shape 100x3\)"):
        read_log(_h5(tmp_path / "2d.h5", att=np.ones((100, 3))))


def test_corrupt_hdf5_is_one_line_error(tmp_path):
    """Class: corrupt HDF5 structure (tracebacks from h5py)."""
    b = _h5(tmp_path / "a.h5").read_bytes()
    rng = np.random.default_rng(3)
    for k in range(6):
        data = bytearray(b)
        at = int(rng.integers(0, len(b) - 64))
        data[at:at + 64] = rng.integers(0, 256, 64, dtype=np.uint8).tobytes()
        p = tmp_path / f"c{k}.h5"
        p.write_bytes(bytes(data))
        try:
            read_log(p)
        except InputError as exc:
            assert f"c{k}.h5" in str(exc) and "\n" not in str(exc)


# --------------------------------------------------------------------------- XYZ
def test_xyz_absurd_line_number_and_bad_bytes(tmp_path):
    """Classes: 'Line 99999999999999999999' (OverflowError) and bad bytes in XYZ
    (silently replaced by U+FFFD)."""
    body = b"\n".join(b"%d 50000 1 2 3" % i for i in range(20))
    p = tmp_path / "a.xyz"
    p.write_bytes(b"/ time mag flux_x flux_y flux_z\nLine 99999999999999999999\n" + body)
    with pytest.raises(InputError, match=r"a.xyz: line 2: line header .*beyond 2\*\*62"):
        read_log(p)
    p.write_bytes(b"/ time mag flux_x flux_y flux_z\nLine 1\n" + body.replace(b"50000", b"5\xff0",
                                                                            1))
    with pytest.raises(InputError, match=r"a.xyz: line 3: bytes that are not UTF-8"):
        read_log(p)


def test_xyz_truncated_last_row(tmp_path):
    body = "\n".join(f"{i} 50000 1 2 3" for i in range(20)) + "\n20 500"
    p = tmp_path / "t.xyz"
    p.write_text("/ time mag flux_x flux_y flux_z\nLine 1\n" + body)
    with pytest.raises(InputError, match=r"line 23: 2 values but 5 channels.*allow_truncated=True"):
        read_log(p)
    assert len(read_log(p, allow_truncated=True)) == 20


# --------------------------------------------------------------------------- MagDrone / MagArrow
@need_samples
def test_magdrone_bad_bytes_huge_timestamp_and_extra_semicolon(tmp_path):
    """Classes: a non-UTF-8 byte or a huge timestamp in a MagDrone file (tracebacks); an extra
    ';' at the end of the rows shifted every column."""
    md = MAGDRONE.read_bytes()
    p = tmp_path / "m.csv"
    p.write_bytes(md.replace(b"10194.52", b"1019\xff.52"))
    with pytest.raises(InputError, match=r"m.csv: line 25: bytes that are not UTF-8"):
        read_log(p)
    p.write_bytes(md.replace(b"\n65;", b"\n99999999999999999999999999;"))
    with pytest.raises(InputError, match=r"m.csv: column 'time', line 25"):
        read_log(p)
    lines = md.split(b"\n")
    at = next(i for i, x in enumerate(lines) if x.startswith(b"Timestamp"))
    lines[at] = lines[at].rstrip(b"; \r")  # header without the trailing ';', rows with it
    p.write_bytes(b"\n".join(lines))
    good = read_log(MAGDRONE)
    got = read_log(p)
    pd.testing.assert_frame_equal(got, good)


@need_samples
def test_vendor_detection_with_quoted_headers(tmp_path):
    """Class: vendor-format detection refused quoted headers."""
    md = MAGDRONE.read_bytes().replace(b"Timestamp [ms]", b'"Timestamp [ms]"')
    (tmp_path / "md.csv").write_bytes(md.replace(b"MagDroneR3", b"Probe"))
    assert read_table(tmp_path / "md.csv").attrs["format"] == "magdrone"
    lines = MAGARROW.read_bytes().split(b"\n")
    lines[0] = b",".join(b'"%s"' % c for c in lines[0].split(b","))
    (tmp_path / "ma.csv").write_bytes(b"\n".join(lines))
    pd.testing.assert_frame_equal(read_log(tmp_path / "ma.csv"), read_log(MAGARROW))


@need_samples
def test_magdrone_utc_time_from_gps():
    """Issue 15 item 15: the MagDrone reader gives UTC time from its GPS columns."""
    df = read_log(MAGDRONE)
    t0 = pd.Timestamp("2020-10-23 10:10:36.400", tz="UTC").timestamp()
    assert df["time"].iloc[0] == pytest.approx(t0, abs=1e-6)
    np.testing.assert_allclose(np.diff(df["time"]), np.diff(df["time_logger"]), atol=1e-6)


# --------------------------------------------------------------------------- model and map files
@pytest.fixture
def model_doc():
    terms = ["cx", "cy", "cz", "cx*cx", "cx*cy", "cx*cz", "cy*cy", "cy*cz",
             "cx*cx'", "cx*cy'", "cx*cz'", "cy*cx'", "cy*cy'", "cy*cz'", "cz*cx'", "cz*cy'"]
    return {"terms": terms, "coef": [1.0] * 16, "scale_nT": 50000.0, "source": "x"}


@pytest.mark.parametrize("change,match", [
    ({"scale_nT": 0}, "scale_nT is 0"),
    ({"scale_nT": -5.0}, "scale_nT is -5.0"),
    ({"scale_nT": "big"}, "scale_nT is 'big'"),
    ({"scale_nT": None}, "scale_nT is None"),
    ({"terms": ["cx"] * 16}, "term 'cx' appears more than once"),
    ({"terms": ["cx"] * 200000, "coef": [1.0] * 200000}, "200000 terms"),
    ({"terms": ["cx", "warp"], "coef": [1.0, 2.0]}, "unknown term 'warp'"),
    ({"coef": [1.0] * 15}, "16 terms but 15 coefficients"),
    ({"coef": [1e400] + [1.0] * 15}, "coefficient of 'cx' is inf"),
    ({"coef": ["1"] + [1.0] * 15}, "coefficient of 'cx' is '1'"),
    ({"terms": "cx"}, "needs 'terms' and 'coef' lists"),
])
def test_model_file_schema(tmp_path, model_doc, change, match):
    """Class: bad model files accepted (scale_nT 0 or NaN, one term 16 times, 200,000 terms)
    or tracebacks (bad scale_nT)."""
    p = tmp_path / "m.json"
    p.write_text(json.dumps({**model_doc, **change}).replace("Infinity", "1e400"))
    with pytest.raises(InputError, match=match):
        read_model_document(p)


def test_model_file_limits(tmp_path, model_doc):
    """Class: deeply nested documents, non-UTF-8, NaN, /dev/zero read without limit."""
    p = tmp_path / "m.json"
    p.write_text(json.dumps(model_doc))
    assert read_model_document(p)["scale_nT"] == 50000.0
    p.write_text("[" * 100000 + "]" * 100000)
    with pytest.raises(InputError, match="nested too deeply"):
        read_model_document(p)
    deep: list = [1]
    for _ in range(40):
        deep = [deep]
    p.write_text(json.dumps({**model_doc, "meta": deep}))
    with pytest.raises(InputError, match="nested more than 32 levels"):
        read_model_document(p)
    p.write_bytes(b'{"terms": ["\xff"]}')
    with pytest.raises(InputError, match="not UTF-8"):
        read_model_document(p)
    p.write_text(json.dumps(model_doc).replace("1.0", "NaN", 1))
    with pytest.raises(InputError, match="NaN is not a number"):
        read_model_document(p)
    if Path("/dev/zero").exists():
        with pytest.raises(InputError, match="not a regular file"):
            read_model_document("/dev/zero")
    big = tmp_path / "big.json"
    with open(big, "wb") as fh:
        fh.truncate((32 << 20) + 10)
    with pytest.raises(InputError, match="larger than 32 MB"):
        read_model_document(big)


@pytest.mark.parametrize("text,match", [
    ('[columns]\nmag = 3\n', "'mag' = 3: write NAME"),
    ('[columns]\nmag = "m"\n[units]\nflux = "furlong"\n', "unknown field unit 'furlong'"),
    ('[columns]\nmag = {a = "b"}\n', "write NAME = \"VALUE\""),
    ('[columns]\nmag = {a = {b = {c = "d"}}}\n', "nested tables"),
    ("a = " + "[" * 3000 + "]" * 3000 + "\n", "nested|not a valid TOML"),
    ('[colums]\nmag = "m"\n', "unknown table or key 'colums'"),
    ('[columns\nmag = "m"\n', "not a valid TOML column map"),
])
def test_map_file_schema(tmp_path, text, match):
    """Class: odd --map TOML files (tracebacks, accepted nonsense)."""
    p = tmp_path / "map.toml"
    p.write_text(text)
    with pytest.raises(InputError, match=match):
        read_map_file(p)


def test_map_file_limits(tmp_path):
    p = tmp_path / "map.toml"
    p.write_bytes(b'[columns]\nmag = "\xff"\n')
    with pytest.raises(InputError, match="not UTF-8"):
        read_map_file(p)
    if Path("/dev/zero").exists():
        with pytest.raises(InputError, match="not a regular file"):
            read_map_file("/dev/zero")
    p.write_text('[columns]\nmag = "mag_1_uc"\n[units]\nflux = "uT"\n')
    assert read_map_file(p) == ({"mag": "mag_1_uc"}, {"flux": "uT"})
