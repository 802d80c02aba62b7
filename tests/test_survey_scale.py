"""The survey chain's memory-bounding steps give what the whole-array versions give (issue 27).

The speed and memory themselves are measured by ``benchmarks/bench_survey_scale.py``; here the
block sizes are made small so that every blocked step runs over many blocks, and each result
is checked against a brute-force or whole-array computation written in the test.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
from scipy.spatial.distance import cdist
from typer.testing import CliRunner

import aeromag as am
from aeromag._core import igrf as core_igrf
from aeromag.cli import app
from aeromag.io import read_log
from aeromag.io.formats import parquet as parquet_format
from aeromag.survey import crossings, gridding, igrf
from aeromag.survey.geometry import build_geometry
from aeromag.synthetic.level_survey import simulate_level_survey


def _grid_survey(rng: np.random.Generator, n_lines: int = 6, n_ties: int = 3,
                 step: float = 7.0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Lines east-west (wavy), ties north-south, in metres: x, y, line, value."""
    xs, ys, ls = [], [], []
    for i in range(n_lines):
        s = np.arange(0.0, 2000.0, step)
        xs.append(s if i % 2 == 0 else s[::-1])
        ys.append(i * 250.0 + 6.0 * np.sin(s / 90.0 + i))
        ls.append(np.full(s.size, 10.0 + i))
    for j in range(n_ties):
        s = np.arange(-100.0, 1400.0, step * 1.3)
        ys.append(s)
        xs.append(300.0 + j * 650.0 + 4.0 * np.cos(s / 70.0 + j))
        ls.append(np.full(s.size, 900.0 + j))
    x, y, line = (np.concatenate(a) for a in (xs, ys, ls))
    v = 40.0 * np.sin(x / 300.0) * np.cos(y / 400.0) + rng.normal(0, 0.1, x.size)
    return x, y, line, v


def _geometry(x: np.ndarray, y: np.ndarray, line: np.ndarray):
    return build_geometry(None, None, line, x_m=x, y_m=y, crs=32754,
                          ties=[900.0, 901.0, 902.0])


def test_crossings_screened_blockwise_are_every_segment_intersection(monkeypatch):
    x, y, line, v = _grid_survey(np.random.default_rng(3))
    geom = _geometry(x, y, line)
    full = crossings.find_crossings(geom, v)
    monkeypatch.setattr(crossings, "BLOCK_SAMPLES", 37)
    small = crossings.find_crossings(geom, v)
    for name in ("line_piece", "tie_piece", "x_m", "y_m", "mistie_nT", "gradient_nT_m"):
        assert np.array_equal(getattr(full, name), getattr(small, name)), name
    # brute force: every (line segment, tie segment) pair of the straight parts
    seg = np.flatnonzero((geom.piece[:-1] == geom.piece[1:]) & geom.straight[:-1]
                         & geom.straight[1:])
    tie = geom.is_tie[seg]
    a, b = seg[~tie], seg[tie]
    px, py = x[a][:, None], y[a][:, None]
    rx, ry = (x[a + 1] - x[a])[:, None], (y[a + 1] - y[a])[:, None]
    qx, qy = x[b][None, :], y[b][None, :]
    sx, sy = (x[b + 1] - x[b])[None, :], (y[b + 1] - y[b])[None, :]
    den = rx * sy - ry * sx
    t = ((qx - px) * sy - (qy - py) * sx) / den
    u = ((qx - px) * ry - (qy - py) * rx) / den
    i, j = np.nonzero((t >= 0) & (t <= 1) & (u >= 0) & (u <= 1))
    pairs = set(zip(geom.piece[a[i]].tolist(), geom.piece[b[j]].tolist(), strict=True))
    assert len(pairs) == 18  # 6 lines x 3 ties, each crossing once
    assert set(zip(full.line_piece.tolist(), full.tie_piece.tolist(), strict=True)) == pairs


def test_along_gradient_at_some_samples_is_the_whole_arrays():
    x, y, line, v = _grid_survey(np.random.default_rng(4))
    geom = _geometry(x, y, line)
    whole = crossings.along_gradient(geom, v)
    idx = np.random.default_rng(5).integers(0, v.size, 500)
    assert np.array_equal(crossings.along_gradient(geom, v, index=idx), whole[idx],
                          equal_nan=True)
    # and it is the along-track derivative where the field is known
    ok = np.isfinite(whole) & ~geom.is_tie & geom.straight
    exact = 40.0 / 300.0 * np.cos(x / 300.0) * np.cos(y / 400.0)
    sign = np.sign(np.gradient(x))  # lines flown both ways
    err = (whole - sign * exact)[ok]
    assert np.median(np.abs(err)) < 0.01


def test_blanking_by_blocks_is_the_distance_to_the_nearest_sample(monkeypatch):
    rng = np.random.default_rng(6)
    x = np.concatenate([rng.uniform(0, 1000, 300), rng.uniform(2000, 2600, 200)])
    y = np.concatenate([rng.uniform(0, 800, 300), rng.uniform(0, 500, 200)])
    xg, yg = np.arange(-100.0, 2800.0, 50.0), np.arange(-100.0, 1000.0, 50.0)
    monkeypatch.setattr(gridding, "BLOCK_SAMPLES", 11)  # trees of 44 samples
    far = gridding.far_from_samples(x, y, xg, yg, 120.0)
    gyy, gxx = np.meshgrid(yg, xg, indexing="ij")
    d = cdist(np.column_stack([gxx.ravel(), gyy.ravel()]), np.column_stack([x, y])).min(1)
    assert np.array_equal(far, (d > 120.0).reshape(far.shape))
    assert 0 < far.sum() < far.size


def test_igrf_by_blocks_and_day_pairs_is_the_same(monkeypatch):
    rng = np.random.default_rng(7)
    n = 3000
    lat = rng.uniform(-20.5, -19.5, n)
    lon = rng.uniform(139.5, 140.5, n)
    h = rng.uniform(100.0, 900.0, n)
    t = np.sort(rng.uniform(1_414_890_000.0, 1_414_890_000.0 + 3.5 * 86400.0, n))
    lat[10] = np.nan
    whole = igrf.igrf_total_intensity(lat, lon, h, t).igrf_nT
    monkeypatch.setattr(core_igrf, "BLOCK_SAMPLES", 101)  # the one IGRF evaluation
    blocks = igrf.igrf_total_intensity(lat, lon, h, t).igrf_nT
    assert np.array_equal(whole, blocks, equal_nan=True) and np.isnan(blocks[10])
    # against ppigrf itself at a few samples (the lattice's interpolation error is tiny)
    import datetime as dt

    import ppigrf

    for k in (0, 1500, n - 1):
        when = dt.datetime.fromtimestamp(t[k], dt.UTC).replace(tzinfo=None)
        e, nn, u = ppigrf.igrf(lon[k], lat[k], h[k] / 1000.0, when)
        f = float(np.sqrt(np.ravel(e)[0] ** 2 + np.ravel(nn)[0] ** 2 + np.ravel(u)[0] ** 2))
        assert abs(blocks[k] - f) < 0.5  # the model's secular change within a day, < 0.1 nT


def test_parquet_written_by_row_groups_and_read_by_columns(tmp_path, monkeypatch):
    rng = np.random.default_rng(8)
    df = pd.DataFrame({"time": np.arange(50.0), "mag": rng.normal(size=50),
                       "line": np.repeat([1.0, 2.0], 25),
                       "line_type": np.where(np.arange(50) < 25, "line", "tie")})
    monkeypatch.setattr(parquet_format, "ROW_GROUP", 7)
    path = parquet_format.write_parquet(df, tmp_path / "s.parquet")
    assert pq.ParquetFile(path).metadata.num_row_groups == 8
    pd.testing.assert_frame_equal(read_log(path, required=()), df)
    two = read_log(path, required=(), usecols=["mag", "time", "absent"])
    assert list(two.columns) == ["time", "mag"]
    np.testing.assert_array_equal(two["mag"].to_numpy(), df["mag"].to_numpy())


def test_level_leaves_the_callers_table_alone():
    df, base, _ = simulate_level_survey(0, n_lines=6, n_ties=2, line_length_m=1500.0,
                                        rate_hz=5.0)
    before = df.copy()
    res = am.level(df, base=base, igrf=False)
    pd.testing.assert_frame_equal(df, before)
    d = res.data
    assert d["line_type"].dtype == pd.Series(["line"]).dtype
    assert set(d["line_type"].unique()) <= {"", "line", "tie"}
    assert (d["line_type"] == "tie").sum() == int(res.geometry.is_tie.sum())
    np.testing.assert_array_equal(d["x_m"].to_numpy(), res.geometry.x_m)
    d.loc[0, "tmi"] = -1.0  # the result's table is its own: the input keeps its values
    pd.testing.assert_frame_equal(df, before)


def test_grid_reads_only_the_columns_it_uses(tmp_path):
    df, base, _ = simulate_level_survey(1, n_lines=8, n_ties=2, line_length_m=1500.0,
                                        rate_hz=5.0)
    lev = tmp_path / "lev.csv"
    r = CliRunner().invoke(app, ["level", _write(df, tmp_path / "s.csv"), "--no-igrf",
                                 "-o", str(lev), "--no-progress"])
    assert r.exit_code == 0, r.output
    out = pd.read_csv(lev)
    out["mag"] = "n/a"  # a column grid does not use, unreadable as a number
    out.to_csv(lev, index=False)
    r = CliRunner().invoke(app, ["grid", str(lev), "-o", str(tmp_path / "lev_grid.nc"),
                                 "--cell", "60"])
    assert r.exit_code == 0, r.output
    doc = json.loads((tmp_path / "lev_grid.json").read_text())
    assert doc["value"] == "tmi_lev" and doc["n_points"] == len(out)
    # the same grid as from the log without the unreadable column
    r = CliRunner().invoke(app, ["grid", _write(out.drop(columns="mag"), tmp_path / "b.csv"),
                                 "-o", str(tmp_path / "b_grid.nc"), "--cell", "60",
                                 "--crs", str(doc["crs"])])
    assert r.exit_code == 0, r.output
    import xarray as xr

    with xr.open_dataset(tmp_path / "lev_grid.nc") as a, \
            xr.open_dataset(tmp_path / "b_grid.nc") as b:
        np.testing.assert_array_equal(a["tmi_lev"].values, b["tmi_lev"].values)


def _write(df: pd.DataFrame, path) -> str:
    df.to_csv(path, index=False)
    return str(path)


@pytest.mark.parametrize("n", [0, 1])
def test_level_correction_of_few_samples(n):
    from aeromag.survey.levelling import LevellingResult

    r = LevellingResult("trend", [np.array([0.0, 10.0])], [np.array([1.0, 3.0])],
                        np.zeros(0), np.zeros(0))
    out = r.correction(np.zeros(n, dtype=np.int64), np.full(n, 5.0))
    assert out.shape == (n,) and np.all(out == 2.0)


def test_csv_written_in_slices_is_the_file_of_one_slice(tmp_path, monkeypatch):
    from aeromag.io import csv_write, write_csv

    rng = np.random.default_rng(9)
    n = 60
    df = pd.DataFrame({"time": np.arange(n) * 0.5, "mag": rng.normal(size=n),
                       "whole": np.r_[rng.normal(size=n - 1), 3.0],  # integral only at the end
                       "flag": rng.random(n) < 0.5,
                       "note": ["ok"] * (n - 1) + ["a, b"]})  # quoting needed in the last
    write_csv(df, tmp_path / "one.csv")
    monkeypatch.setattr(csv_write, "CSV_SLICE_ROWS", 7)
    write_csv(df, tmp_path / "sliced.csv")
    text = (tmp_path / "sliced.csv").read_bytes()
    assert text == (tmp_path / "one.csv").read_bytes()
    assert b"3.0\n" not in text or b',3.0,' in text  # an integral float keeps its ".0"
    back = pd.read_csv(tmp_path / "sliced.csv")
    assert back["whole"].dtype == np.float64 and back["note"].iloc[-1] == "a, b"
