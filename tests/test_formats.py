"""Formats: round trips (CSV/Parquet/Geosoft XYZ), presets, real MagArrow/MagDrone samples."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pytest

from aeromag.errors import InputError
from aeromag.io import read_log, write_csv
from aeromag.io.formats import detect_format, read_table, read_xyz, write_table, write_xyz

SAMPLES = Path(__file__).resolve().parents[1] / "data_samples" / "formats"  # ../shared copies


def _log(n: int = 500, seed: int = 1) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 10.0
    df = pd.DataFrame({
        "time": t,
        "flux_x": 20000 + rng.normal(0, 300, n),
        "flux_y": -3000 + rng.normal(0, 300, n),
        "flux_z": 45000 + rng.normal(0, 300, n),
        "mag": 50000 + rng.normal(0, 1, n) * 1e-3 + 1 / 3,
        "line": np.repeat([1001, 1002, 9001], [200, 200, n - 400]),
        "tiny": rng.normal(0, 1e-300, n),
        "ok": rng.random(n) > 0.5,
    })
    df.loc[7, "mag"] = np.nan
    return df


def test_csv_parquet_csv_round_trip(tmp_path):
    df = _log()
    write_csv(df, tmp_path / "a.csv")
    a = read_table(tmp_path / "a.csv")
    write_table(a, tmp_path / "a.parquet")
    assert detect_format(tmp_path / "a.parquet") == "parquet"
    b = read_table(tmp_path / "a.parquet")
    write_table(b, tmp_path / "b.csv")
    c = read_table(tmp_path / "b.csv")
    pd.testing.assert_frame_equal(a, c, check_exact=True)
    for col in ("time", "flux_x", "mag", "tiny"):
        np.testing.assert_array_equal(c[col].to_numpy(), df[col].to_numpy())
    assert c["ok"].tolist() == df["ok"].tolist()


def test_geosoft_xyz_write_read_round_trip(tmp_path):
    df = _log()
    df["line_type"] = np.where(df["line"] >= 9000, "tie", "line")
    write_xyz(df, tmp_path / "s.xyz")
    text = (tmp_path / "s.xyz").read_text().splitlines()
    assert text[1].split()[1:4] == ["time", "flux_x", "flux_y"]
    assert "Line 1001" in text and "Line 1002" in text and "Tie 9001" in text
    assert any(" * " in f" {r} " for r in text)  # the missing mag
    back = read_xyz(tmp_path / "s.xyz")
    for col in df.columns:
        if col == "line_type":
            assert back[col].astype(str).str.lower().tolist() == (
                df[col].astype(str).str.lower().tolist())
        elif col == "ok":  # booleans are written 1/0 (Oasis channels are numbers)
            assert back[col].tolist() == df[col].astype(int).tolist()
        else:
            np.testing.assert_array_equal(back[col].to_numpy(dtype=float),
                                          df[col].to_numpy(dtype=float))
    # and through read_log, by extension
    lg = read_log(tmp_path / "s.xyz", required=("time", "flux_x", "line"))
    np.testing.assert_array_equal(lg["line"].to_numpy(), df["line"].to_numpy())


def test_xyz_without_lines_and_bad_xyz(tmp_path):
    df = _log().head(50).drop(columns=["line"])
    write_table(df, tmp_path / "n.xyz")
    back = read_xyz(tmp_path / "n.xyz")
    # Oasis needs a line header before the data: one Line 0 (no segment column either)
    assert (tmp_path / "n.xyz").read_text().split("\n")[2] == "Line 0"
    assert back["line"].tolist() == [0] * 50 and len(back) == 50
    (tmp_path / "bad.xyz").write_text("1 2 3\n")
    with pytest.raises(InputError, match="bad.xyz"):
        read_table(tmp_path / "bad.xyz")


def test_magnav_hdf5_and_sgl_xyz_presets(tmp_path):
    n = 300
    rng = np.random.default_rng(0)
    chans = {"tt": np.arange(n) / 10.0, "line": np.full(n, 1002.02), "lat": 45 + rng.random(n),
             "lon": -75 + rng.random(n), "utm_z": 400 + rng.random(n),
             "mag_1_uc": 52000 + rng.random(n), "mag_1_c": 51900 + rng.random(n),
             "flux_a_x": 20000 + rng.random(n), "flux_a_y": 1000 + rng.random(n),
             "flux_a_z": 45000 + rng.random(n), "ins_yaw": rng.random(n)}
    with h5py.File(tmp_path / "Flt1002.h5", "w") as h5:
        for k, v in chans.items():
            h5[k] = v
        h5["N"] = n  # a scalar: ignored
    lg = read_log(tmp_path / "Flt1002.h5", required=("time", "mag", "flux_x", "line"))
    np.testing.assert_array_equal(lg["time"], chans["tt"])
    np.testing.assert_array_equal(lg["mag"], chans["mag_1_uc"])
    np.testing.assert_array_equal(lg["flux_z"], chans["flux_a_z"])
    np.testing.assert_array_equal(lg["alt"], chans["utm_z"])
    assert lg["heading"].iloc[3] == chans["ins_yaw"][3]
    # user's map wins over the preset
    lg2 = read_log(tmp_path / "Flt1002.h5", columns={"mag": "mag_1_c"})
    np.testing.assert_array_equal(lg2["mag"], chans["mag_1_c"])
    # SGL-style XYZ with upper-case channel names
    sgl = pd.DataFrame({k.upper(): v for k, v in chans.items() if k != "line"})
    sgl = sgl.rename(columns={"TT": "TIME"})
    sgl["LINE"] = 1002
    write_xyz(sgl.drop(columns=["LINE"]).assign(line=1002), tmp_path / "f.xyz")
    lg3 = read_log(tmp_path / "f.xyz", required=("time", "mag", "flux_x"))
    np.testing.assert_array_equal(lg3["time"], chans["tt"])
    np.testing.assert_array_equal(lg3["flux_x"], chans["flux_a_x"])


def test_magarrow_sample_canonical_columns():
    p = SAMPLES / "magarrow_sample.csv"
    assert detect_format(p) == "magarrow"
    df = read_log(p, required=("time", "mag", "lat", "lon", "alt"))
    assert len(df) == 14
    # 2020-09-28 13:37:53.000 UTC in seconds since 1970, 1 kHz
    assert df["time"].iloc[0] == pytest.approx(1601300273.0, abs=1e-6)
    np.testing.assert_allclose(np.diff(df["time"]), 0.001, atol=1e-6)
    assert df["mag"].iloc[0] == 51383.18350 and df["mag"].iloc[-1] == 51383.46095
    assert 20000 < df["mag"].median() < 70000  # nT
    assert df["lat"].iloc[0] == pytest.approx(56.862286) and df["lon"].iloc[0] == pytest.approx(
        24.113613)
    # ellipsoidal height = GGA altitude (8.37 m MSL) + geoid separation (23.85 m)
    assert df["alt"].iloc[0] == pytest.approx(8.37 + 23.85)
    # sparse IMU rows stay sparse: compass only on some rows, raw counts, not a fluxgate
    assert df["CompassX"].notna().sum() == 1 and df["AccelerometerZ"].notna().sum() == 3
    assert "flux_x" not in df.columns


def test_magdrone_sample_canonical_columns():
    p = SAMPLES / "magdrone_r3_sample.csv"
    assert detect_format(p) == "magdrone"
    df = read_log(p, required=("time", "flux_x", "flux_y", "flux_z", "lat", "lon"))
    assert len(df) == 41
    np.testing.assert_allclose(df["time_logger"].iloc[:3], [0.060, 0.065, 0.070])  # ms -> s
    # UTC from the two GPS fixes (10:10:36.398 at 60 ms, 10:10:36.602 at 260 ms): the logger
    # clock plus the median offset, 36.340 s past 10:10 (item 15 of issue 15)
    t0 = pd.Timestamp("2020-10-23T10:10:36.400Z").timestamp()
    np.testing.assert_allclose(df["time"].iloc[:3], t0 + np.array([0.0, 0.005, 0.010]),
                               rtol=0, atol=1e-6)
    assert df["flux_x"].iloc[0] == 10195.42 and df["flux_z"].iloc[0] == 48024.38  # B1, nT
    assert df["B2x"].iloc[0] == 7772.00
    bt = np.linalg.norm(df[["flux_x", "flux_y", "flux_z"]].to_numpy(), axis=1)
    assert np.all((bt > 40000) & (bt < 60000))  # an Earth field in nT
    # no fix rows (0) are interpolated between fixes, never 0
    assert df["lat"].between(56.86, 56.87).all() and df["lon"].between(24.11, 24.12).all()
    assert "alt" not in df.columns and df["alt_msl"].iloc[0] == 7.6
    b2 = read_log(p, fmt="magdrone_b2", required=("flux_x",))
    assert b2["flux_x"].iloc[0] == 7772.00
    assert "Samples: 266847" in read_table(p).attrs["metadata"]


def test_unknown_format_and_empty_parquet(tmp_path):
    with pytest.raises(InputError, match="unknown format"):
        read_table(SAMPLES / "magdrone_r3_sample.csv", "nope")
    (tmp_path / "e.parquet").write_bytes(b"")
    with pytest.raises(InputError, match="e.parquet"):
        read_log(tmp_path / "e.parquet")
