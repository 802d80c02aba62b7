"""Input robustness leftovers (issue 15, no silent fallbacks): time in ms/us, absurd fields,
tab/semicolon-separated files, scalar HDF5 datasets, wide logs."""

from __future__ import annotations

import copy
import logging

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.compensation.config import CompensationConfig
from aeromag.compensation.prepare import prepare
from aeromag.errors import InputError
from aeromag.io import read_log
from aeromag.io.columns import ColumnNames
from aeromag.io.stream import iter_log_batches

runner = CliRunner()


@pytest.fixture(scope="module")
def survey(tmp_path_factory):
    """A small synthetic log at 10 Hz in nT with a line column and every canonical field."""
    rng = np.random.default_rng(1)
    n = 3000
    t = np.arange(n) * 0.1
    hd = np.deg2rad(30 * np.sin(t / 7.0))
    pitch = np.deg2rad(5 * np.sin(t / 3.0))
    fx = 30000 * np.cos(hd) * np.cos(pitch) + rng.normal(0, 1, n)
    fy = 30000 * np.sin(hd) + rng.normal(0, 1, n)
    fz = 42000 + 3000 * np.sin(pitch) + rng.normal(0, 1, n)
    mag = np.sqrt(fx**2 + fy**2 + fz**2) + 5 * np.sin(t / 2)
    return pd.DataFrame({"time": t, "flux_x": fx, "flux_y": fy, "flux_z": fz, "mag": mag,
                         "lat": 47.0, "lon": 8.0, "alt": 500.0})


def _write(df, path, **kw):
    df.to_csv(path, index=False, **kw)
    return path


# ---------------------------------------------------------------- 1. time in ms / us
def test_epoch_milliseconds_are_refused_naming_the_unit(survey, tmp_path):
    p = _write(survey.assign(time=1.7e12 + survey["time"] * 1e3), tmp_path / "ep.csv")
    with pytest.raises(InputError, match=r"ep\.csv: column 'time', line 2: .*looks like ms"
                       r" since 1970: pass units=\{'time': 'ms'\}"):
        read_log(p)
    df = read_log(p, units={"time": "ms"})
    np.testing.assert_allclose(np.diff(df["time"]), 0.1, atol=1e-6)  # float64 at 1.7e9 s
    assert df["time"].iloc[1] == 1700000000.1
    p2 = _write(survey.assign(time=1.7e15 + survey["time"] * 1e6), tmp_path / "us.csv")
    with pytest.raises(InputError, match="looks like us"):
        read_log(p2)
    # chunked mode: the same error, and the same conversion
    with pytest.raises(InputError, match="looks like ms"):
        next(iter_log_batches(p, None))
    b = next(iter_log_batches(p, None, units={"time": "ms"}))
    np.testing.assert_allclose(b["time"].iloc[:3] - b["time"].iloc[0], [0, 0.1, 0.2],
                               atol=1e-4)


def test_millisecond_steps_name_the_column_and_unit(survey, tmp_path):
    p = _write(survey.assign(time=survey["time"] * 1e3), tmp_path / "ms.csv")
    with pytest.raises(InputError, match=r"ms\.csv: column 'time' steps by 100 s .*if time is"
                       r" in ms, pass units=\{'time': 'ms'\}"):
        prepare(read_log(p), CompensationConfig())
    r = runner.invoke(app, ["compensate", str(p), "-o", str(tmp_path / "o.csv")])
    assert r.exit_code == 1 and "--units time=ms" in r.output and "--band" in r.output
    assert prepare(read_log(p, units={"time": "ms"}), CompensationConfig()).fs == pytest.approx(
        10.0)


def test_time_unit_errors(survey, tmp_path):
    p = _write(survey, tmp_path / "s.csv")
    with pytest.raises(InputError, match="unknown time unit 'min'"):
        read_log(p, units={"time": "min"})


# ---------------------------------------------------------------- 2. absurd fields
def test_absurd_total_field_is_refused(survey, tmp_path):
    p = _write(survey.assign(mag=1.8e19), tmp_path / "abs.csv")
    with pytest.raises(InputError, match=r"abs\.csv: column 'mag', data row 1: 1\.8e\+19 nT.*"
                       r"3000 of 3000 samples.*columns=\.\.\."):
        prepare(read_log(p), CompensationConfig())
    flux = survey.assign(**{c: survey[c] * 1e12 for c in ("flux_x", "flux_y", "flux_z")})
    with pytest.raises(InputError, match="fluxgate magnitude"):
        prepare(flux, CompensationConfig(), source="f.csv")
    r = runner.invoke(app, ["compensate", str(p), "-o", str(tmp_path / "o.csv")])
    assert r.exit_code == 1 and "--units mag=UNIT" in r.output, r.output


def test_spikes_and_other_units_are_not_refused(survey, caplog):
    spiky = survey.copy()
    spiky.loc[::50, "mag"] = 1.8e19  # 2 %: spikes, for the QC
    prepare(spiky, CompensationConfig(), source="spiky.csv")
    ut = survey.assign(**{c: survey[c] / 1000 for c in ("flux_x", "flux_y", "flux_z")})
    with caplog.at_level(logging.WARNING):
        prepare(ut, CompensationConfig(), source="ut.csv")  # a units warning, no error
    assert "units={'flux': 'uT'}" in caplog.text  # the library names the parameter


# ---------------------------------------------------------------- 3. delimiters
@pytest.mark.parametrize(("sep", "word"), [("\t", "tab"), (";", "semicolon")])
def test_other_delimiters_are_named(survey, tmp_path, sep, word):
    p = _write(survey, tmp_path / "d.csv", sep=sep)
    msg = rf"d\.csv: looks {word}-separated \(header line 1 has 7 {word}s and no comma\)"
    with pytest.raises(InputError, match=msg):
        read_log(p)
    with pytest.raises(InputError, match=msg):
        next(iter_log_batches(p, None))


def test_single_column_csv_still_reads(tmp_path):
    p = tmp_path / "one.csv"
    p.write_text("time\n0\n1\n2\n")
    assert len(read_log(p)) == 3


# ---------------------------------------------------------------- 4. HDF5 scalars
def test_hdf5_scalar_datasets_are_said_and_refused_when_mapped(survey, tmp_path, caplog):
    h5py = pytest.importorskip("h5py")
    p = tmp_path / "s.h5"
    with h5py.File(p, "w") as h:
        h["tt"] = survey["time"].to_numpy()
        h["mag_1_uc"] = survey["mag"].to_numpy()
        for a in "xyz":
            h[f"flux_a_{a}"] = survey[f"flux_{a}"].to_numpy()
        h["dt"] = 0.1
        h["mag_2_uc"] = 50000.0
    with caplog.at_level(logging.INFO, logger="aeromag"):
        df = read_log(p)
    assert "2 scalar dataset(s) skipped, not channels: 'dt', 'mag_2_uc'" in caplog.text
    assert "dt" not in df.columns
    with pytest.raises(InputError, match=r"dataset 'mag_2_uc' \(mapped to 'mag'\) is a scalar"):
        read_log(p, columns={"mag": "mag_2_uc"})
    with h5py.File(p, "a") as h:
        h["lat"] = 47.0
    with pytest.raises(InputError, match=r"dataset 'lat' \(the 'lat' channel\) is a scalar"):
        read_log(p)


# ---------------------------------------------------------------- 5. wide logs
def test_column_names_in_attrs_are_cheap_to_copy():
    names = ColumnNames(f"c{i}" for i in range(5000))
    got = copy.deepcopy({"columns": names})["columns"]
    assert got == names and got is not names and isinstance(got, ColumnNames)


def test_wide_csv_keeps_its_names_cheap(survey, tmp_path):
    wide = pd.concat([survey.iloc[:50], pd.DataFrame(
        np.zeros((50, 300)), columns=[f"c{i}" for i in range(300)])], axis=1)
    df = read_log(_write(wide, tmp_path / "w.csv"))
    assert isinstance(df.attrs["passthrough_csv"]["columns"], ColumnNames)
