"""Review of ``aeromag grid``: the transforms' signs, and the solve against a direct one.

An independent generator written here (not the project's simulator, not test_survey_grid's):
point dipoles under north-south lines 150 m apart, 7 m along-line steps, heading jitter.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.survey.grids import grid_dataset
from aeromag.survey.transforms import Transform, apply_transform

#: (east, north, depth below the sensor [m], moment [A m^2])
SOURCES = [(1800.0, 2500.0, 350.0, 3e8), (3300.0, 1400.0, 500.0, -2e8)]


def _unit(inc: float, dec: float) -> np.ndarray:
    i, d = np.radians(inc), np.radians(dec)
    return np.array([np.cos(i) * np.cos(d), np.cos(i) * np.sin(d), np.sin(i)])


def field(e: np.ndarray, n: np.ndarray, up: float = 0.0, inc: float = 90.0,
          dec: float = 0.0) -> np.ndarray:
    """Total-field anomaly [nT] of induced dipoles, ``up`` metres above the survey."""
    f = _unit(inc, dec)
    out = np.zeros(np.shape(e))
    for xe, yn, depth, m in SOURCES:
        r = np.stack([n - yn, e - xe, np.full(np.shape(e), -(depth + up))], -1)
        rn = np.linalg.norm(r, axis=-1)
        b = 1e-7 * m * (3 * (r @ f)[..., None] * r / rn[..., None] ** 2 - f) / rn[..., None] ** 3
        out += (b @ f) * 1e9
    return out


runner = CliRunner()


@pytest.fixture(scope="module")
def pole_grid():
    x = np.arange(0.0, 5000.0, 25.0)
    gx, gy = np.meshgrid(x, x)
    return grid_dataset(x, x, field(gx, gy), "t", 32633)


def test_tilt_is_positive_over_the_source_and_dz_positive_over_a_positive_anomaly(pole_grid):
    # before the review: harmonica's upward derivative made tilt -90 deg and dz -12 nT/m over
    # the 1395 nT peak of the shallow source (Oasis's 1VD and Miller & Singh's tilt: positive)
    peak = {"x": 1800.0, "y": 2500.0}
    assert pole_grid["t"].sel(peak).item() > 1000.0
    tilt = apply_transform(pole_grid["t"], Transform("tilt"))
    dz = apply_transform(pole_grid["t"], Transform("dz"))
    assert tilt.sel(peak).item() > 85.0
    assert dz.sel(peak).item() > 5.0 and dz.attrs["units"] == "nT/m"
    # the reversed (negative) source: negative tilt over it
    assert tilt.sel(x=3300.0, y=1400.0).item() < -60.0
    # dz against the analytic downward derivative of the dipoles
    gx, gy = np.meshgrid(pole_grid.x.values, pole_grid.y.values)
    true = (field(gx, gy, up=-1.0) - field(gx, gy, up=1.0)) / 2.0
    inner = (gx > 800) & (gx < 4200) & (gy > 800) & (gy < 4200)
    err = dz.values[inner] - true[inner]
    assert np.sqrt(np.mean(err ** 2)) < 0.05 * true[inner].std()


def test_dz_is_the_finite_difference_of_two_upward_continuations(pole_grid):
    up = {h: apply_transform(pole_grid["t"], Transform("up", h)) for h in (20.0, 30.0, 40.0)}
    fd = (up[20.0] - up[40.0]) / 20.0  # downward derivative at 30 m
    dz = apply_transform(up[30.0].rename("t"), Transform("dz"))
    inner = slice(40, -40)
    a, b = dz.values[inner, inner], fd.values[inner, inner]
    assert np.corrcoef(a.ravel(), b.ravel())[0, 1] > 0.999
    assert np.sqrt(np.mean((a - b) ** 2)) < 0.02 * b.std()


# --------------------------------------------------------------------------- refusals
def _survey(seed: int = 11, spacing: float = 150.0, step: float = 7.0, width: float = 3000.0,
            height: float = 3000.0) -> pd.DataFrame:
    """North-south lines with a random heading jitter (0.3 deg) and a track wander, ties."""
    rng = np.random.default_rng(seed)
    parts = []
    for k, xe in enumerate(np.arange(0.0, width + 1, spacing)):
        hd = np.radians(rng.normal(0.0, 0.3))
        s = np.arange(0.0, height, step)
        xs = xe + s * np.sin(hd) + np.cumsum(rng.normal(0.0, 0.3, s.size))
        ys = s * np.cos(hd)
        if k % 2:
            xs, ys = xs[::-1], ys[::-1]
        parts.append(pd.DataFrame({"x_m": xs, "y_m": ys, "line": 10 + k}))
    for j, yn in enumerate((500.0, 2000.0)):
        s = np.arange(0.0, width, step)
        parts.append(pd.DataFrame({"x_m": s, "y_m": yn + rng.normal(0, 1, s.size),
                                   "line": 500 + j}))
    df = pd.concat(parts, ignore_index=True)
    df["tmi"] = field(df.x_m.to_numpy(), df.y_m.to_numpy(), inc=-58.0, dec=7.0)
    return df


@pytest.fixture(scope="module")
def lat_lon_log(tmp_path_factory) -> Path:
    from aeromag._core.geodesy import unproject

    df = _survey()
    lat, lon = unproject(df.x_m.to_numpy() + 400000.0, df.y_m.to_numpy() + 6200000.0, 32633)
    path = tmp_path_factory.mktemp("review") / "syn.csv"
    pd.DataFrame({"LAT": lat, "LON": lon, "LN": df.line, "MAG": df.tmi}).to_csv(path,
                                                                                 index=False)
    return path


@pytest.mark.parametrize("args, message", [
    # before: --blank 0 or -10 wrote a grid with every (or 28,006 of 32,218) cells blank
    (["--blank", "0"], "--blank 0: the blanking distance must be a positive number"),
    (["--blank", "-10"], "--blank -10: the blanking distance must be a positive number"),
    # before: --crs 4326 gridded degrees as metres, a '0.00045 m' cell, exit 0
    (["--crs", "4326"], "--crs 4326: WGS 84 is geographic in degree, not metres"),
    (["--crs", "2229"], "is projected in US survey foot, not metres"),
])
def test_bad_blank_and_non_metre_crs_are_refused_in_one_line(lat_lon_log, tmp_path, args,
                                                             message):
    cols = ["--col", "lat=LAT", "--col", "lon=LON", "--col", "line=LN", "--value", "MAG"]
    r = runner.invoke(app, ["grid", str(lat_lon_log), "-o", str(tmp_path / "g.nc"), *cols,
                            *args])
    lines = r.output.strip().splitlines()
    assert r.exit_code == 1 and len(lines) == 1 and lines[0].startswith("error: "), r.output
    assert message in lines[0], lines[0]
    assert list(tmp_path.iterdir()) == []


def test_line_spacing_refusal_names_the_file(tmp_path):
    # before: 'error: cannot estimate the line spacing ...' without the file
    log = tmp_path / "one.csv"
    pd.DataFrame({"x_m": np.arange(50.0), "y_m": np.zeros(50), "tmi": np.arange(50.0)}
                 ).to_csv(log, index=False)
    r = runner.invoke(app, ["grid", str(log), "-o", str(tmp_path / "g.nc"), "--crs", "32633"])
    assert r.exit_code == 1
    assert r.output.strip() == (f"error: {log}: cannot estimate the line spacing (fewer than"
                                " two straight lines): give --cell")


# --------------------------------------------------------------------------- the solve
def test_tension_acts_at_a_fixed_length_so_a_finer_cell_does_not_stiffen_the_grid():
    """T = 0.25 in grid units of the cell made the answer depend on the cell asked for.

    Before the review, on these lines 150 m apart (the default cell 30 m): 11.8 nT rms
    against the true field at 15 m cells, 7.6 at 30 m, 4.4 at 60 m; now 7.9, 7.6, 7.2 (the
    tension acts at the default cell whatever the cell), and 3.3 nT at T = 0.
    """
    import aeromag as am

    df = _survey()
    df.attrs["crs"] = 32633
    rms = {}
    for cell in (15.0, 30.0):
        ds, summary = am.grid(df, cell_m=cell)
        assert summary.tension_length_m == pytest.approx(30.0)
        gx, gy = np.meshgrid(ds.x.values, ds.y.values)
        inner = (gx > 300) & (gx < 2700) & (gy > 300) & (gy < 2700)
        err = ds["tmi"].values - field(gx, gy, inc=-58.0, dec=7.0)
        rms[cell] = float(np.sqrt(np.nanmean(err[inner] ** 2)))
    assert rms[15.0] < 1.1 * rms[30.0], rms
    assert rms[30.0] < 0.08 * 111.7, rms  # field std 111.7 nT inside


def test_multigrid_matches_a_direct_solve_and_t0_is_the_thin_plate_spline():
    """CG from the coarser level against spsolve of the same normal equations, and Briggs's
    minimum curvature (T = 0) against verde's biharmonic Spline on the same data."""
    import verde as vd

    rng = np.random.default_rng(0)
    lx, ly = np.meshgrid(np.arange(0.0, 2000.0, 20.0), np.arange(0.0, 2001.0, 100.0))
    x = lx.ravel() + rng.normal(0, 2, lx.size)
    y = ly.ravel() + rng.normal(0, 2, lx.size)

    def smooth(e, n):
        return (100 * np.exp(-((e - 900) ** 2 + (n - 1100) ** 2) / (2 * 300.0 ** 2))
                + 40 * np.sin(e / 250.0) * np.cos(n / 400.0))

    v = smooth(x, y)
    from aeromag.survey.gridding import minimum_curvature

    xg, yg, g, s = minimum_curvature(x, y, v, cell_m=20.0, tension=0.0)
    tight = minimum_curvature(x, y, v, cell_m=20.0, tension=0.0, rtol=1e-9,
                              maxiter=5_000)[2]
    # measured: 0.002 nT rms between rtol 1e-6 and spsolve of the finest level (std 37 nT)
    assert np.sqrt(np.mean((g - tight) ** 2)) < 0.02 and s.residual < 1e-6
    gx, gy = np.meshgrid(xg, yg)
    spline = vd.Spline().fit((x, y), v).predict((gx, gy))
    inner = (gx > 300) & (gx < 1700) & (gy > 300) & (gy < 1700)
    # measured 0.034 nT rms (max 0.13) between the two, both within 0.04 nT of the truth
    assert np.sqrt(np.mean((g - spline)[inner] ** 2)) < 0.1
    assert np.sqrt(np.mean((g - smooth(gx, gy))[inner] ** 2)) < 0.1


def test_geotiff_with_transforms_is_written_and_read_back_with_its_crs(lat_lon_log, tmp_path):
    # before: the transforms' attribute 'transform' ('dz') is rioxarray's name for the affine
    # geotransform: -o GRID.tif --transform dz ended in a traceback (Affine() missing 'e', 'f')
    import rioxarray
    import xarray as xr

    cols = ["--col", "lat=LAT", "--col", "lon=LON", "--col", "line=LN", "--value", "MAG"]
    r = runner.invoke(app, ["grid", str(lat_lon_log), "-o", str(tmp_path / "g.tif"), *cols,
                            "--cell", "60", "--transform", "dz,tilt"])
    assert r.exit_code == 0, r.output
    tilt = rioxarray.open_rasterio(tmp_path / "g_tilt.tif")
    assert tilt.rio.crs.to_epsg() == 32633 and tilt.rio.resolution() == (60.0, -60.0)
    assert float(tilt.max()) > 60.0  # positive over the 350 m deep source
    r = runner.invoke(app, ["grid", str(lat_lon_log), "-o", str(tmp_path / "g.nc"), *cols,
                            "--cell", "60", "--transform", "dz"])
    assert r.exit_code == 0, r.output
    with xr.open_dataset(tmp_path / "g_dz.nc", decode_coords="all") as ds:
        assert ds.rio.crs.to_epsg() == 32633 and ds["MAG_dz"].attrs["units"] == "nT/m"
        # the netCDF's cell centres are the GeoTIFF's pixel centres
        np.testing.assert_allclose(ds.x.values, tilt.x.values)
        np.testing.assert_allclose(ds.y.values, tilt.y.values[::-1])


def test_grid_never_replaces_the_level_report_beside_it(tmp_path):
    """level -o lev.csv writes lev.json; grid lev.csv -o lev.nc would write lev.json too."""
    samples = Path(__file__).resolve().parents[1] / "data_samples"
    lev = tmp_path / "lev.csv"
    r = runner.invoke(app, ["level", str(samples / "level_survey.csv"), "--base",
                            str(samples / "level_base.csv"), "-o", str(lev)])
    assert r.exit_code == 0, r.output
    before = (tmp_path / "lev.json").read_bytes()
    r = runner.invoke(app, ["grid", str(lev), "-o", str(tmp_path / "lev.nc")])
    assert r.exit_code == 1, r.output
    lines = [ln for ln in r.output.splitlines() if ln.startswith("error: ")]
    assert len(lines) == 1 and "lev_grid.nc" in lines[0], r.output
    assert (tmp_path / "lev.json").read_bytes() == before
    assert not (tmp_path / "lev.nc").exists()
    # Another name works, and gridding again onto the same grid name replaces its own report.
    for _ in range(2):
        r = runner.invoke(app, ["grid", str(lev), "-o", str(tmp_path / "lev_grid.nc")])
        assert r.exit_code == 0, r.output
    assert (tmp_path / "lev.json").read_bytes() == before
