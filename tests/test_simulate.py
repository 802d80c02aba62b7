"""Tests of the flight simulator (aeromag.simulate) and the ``aeromag simulate`` command."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pyproj
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import signal
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.errors import InputError
from aeromag.synthetic import FAULT_KINDS, TERM_NAMES
from aeromag.synthetic.calibration import simulate_calibration
from aeromag.synthetic.physics import (
    EarthField,
    body_field,
    default_aircraft_coef,
    geodetic_to_local,
    local_to_geodetic,
    ned_to_body_dcm,
    tl_interference,
    tl_terms,
)
from aeromag.synthetic.survey import simulate_survey, survey_plan
from aeromag.workflows.simulate import write_simulation

from .conftest import ned_to_body

REPO = Path(__file__).resolve().parents[1]
SAMPLES = REPO / "data_samples"

# Small flights keep the whole module at a few seconds.
CAL_KW = {"n_boxes": 1, "manoeuvre_s": 15.0}
SUR_KW = {"n_lines": 4, "line_length_m": 200.0}


@pytest.fixture(scope="module")
def cal() -> tuple[pd.DataFrame, dict]:
    return simulate_calibration(seed=3, **CAL_KW)


@pytest.fixture(scope="module")
def survey() -> tuple[pd.DataFrame, dict]:
    return simulate_survey(seed=3, **SUR_KW)


# --------------------------------------------------------------------------- reproducibility
def test_same_seed_same_flight_other_seed_differs() -> None:
    a, ta = simulate_calibration(seed=5, **CAL_KW)
    b, tb = simulate_calibration(seed=5, **CAL_KW)
    c, _ = simulate_calibration(seed=6, **CAL_KW)
    pd.testing.assert_frame_equal(a, b)
    assert ta == tb
    assert not np.allclose(a["mag"], c["mag"])
    assert not np.allclose(a["pitch"], c["pitch"])
    s1, _ = simulate_survey(seed=5, **SUR_KW)
    s2, _ = simulate_survey(seed=5, **SUR_KW)
    s3, _ = simulate_survey(seed=6, **SUR_KW)
    pd.testing.assert_frame_equal(s1, s2)
    assert not np.allclose(s1["truth_anomaly"], s3["truth_anomaly"])


# --------------------------------------------------------------------------- hand-derived
def test_earth_field_ned_by_hand() -> None:
    e = EarthField(intensity_nT=50000.0, inclination_deg=60.0, declination_deg=0.0)
    np.testing.assert_allclose(e.ned, [25000.0, 0.0, 50000.0 * np.sqrt(3) / 2], atol=1e-9)
    assert np.linalg.norm(EarthField().ned) == pytest.approx(50000.0)


def test_body_field_level_north_and_east_by_hand() -> None:
    e = EarthField()
    bn, be, bd = e.ned
    b = body_field(e.ned, [0.0, 90.0, 180.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    # Heading north, level: body axes are the NED axes.
    np.testing.assert_allclose(b[0], [bn, be, bd], atol=1e-9)
    # Heading east: body x points east, body y points south, z down.
    np.testing.assert_allclose(b[1], [be, -bn, bd], atol=1e-9)
    # Heading south: x south, y west.
    np.testing.assert_allclose(b[2], [-bn, -be, bd], atol=1e-9)
    cos = b[1] / np.linalg.norm(b[1])
    assert cos[0] == pytest.approx(be / 50000.0)
    assert cos[1] == pytest.approx(-bn / 50000.0)


def test_body_field_pitch_and_roll_by_hand() -> None:
    b_ned = np.array([20000.0, 0.0, 40000.0])
    # Nose up 30 deg: x = cos30 N - sin30 D, z = sin30 N + cos30 D.
    b = body_field(b_ned, [0.0], [30.0], [0.0])[0]
    c, s = np.cos(np.pi / 6), 0.5
    np.testing.assert_allclose(b, [c * 2e4 - s * 4e4, 0.0, s * 2e4 + c * 4e4], atol=1e-9)
    # Right wing down 90 deg: body y points down, z points west (-east).
    b = body_field([1.0, 2.0, 3.0], [0.0], [0.0], [90.0])[0]
    np.testing.assert_allclose(b, [1.0, 3.0, -2.0], atol=1e-12)


@settings(max_examples=30, deadline=None)
@given(
    st.floats(-180, 360), st.floats(-80, 80), st.floats(-80, 80),
)  # fmt: skip
def test_dcm_is_a_rotation_matching_an_independent_formula(h: float, p: float, r: float) -> None:
    c = ned_to_body_dcm([h], [p], [r])
    ref = ned_to_body(np.deg2rad([r]), np.deg2rad([p]), np.deg2rad([h]))
    np.testing.assert_allclose(c, ref, atol=1e-12)
    np.testing.assert_allclose(c[0] @ c[0].T, np.eye(3), atol=1e-12)
    assert np.linalg.det(c[0]) == pytest.approx(1.0)


def test_term_names_and_default_coefficients() -> None:
    assert TERM_NAMES == (
        "cx", "cy", "cz", "cx*cx", "cx*cy", "cx*cz", "cy*cy", "cy*cz",
        "cx*cx'", "cx*cy'", "cx*cz'", "cy*cx'", "cy*cy'", "cy*cz'", "cz*cx'", "cz*cy'",
    )  # fmt: skip
    k = default_aircraft_coef()
    assert k.shape == (16,)
    assert 5 <= np.abs(k[:3]).max() <= 100  # permanent: tens of nT
    assert 5 <= np.abs(k[3:8]).max() <= 100  # induced: tens of nT
    assert 0.1 <= np.abs(k[8:]).max() <= 10  # eddy: a few nT*s


def test_single_term_interference_by_hand_and_no_derivative_across_gap() -> None:
    # A body field whose cosines are easy to write down, with a gap between samples 2 and 3.
    t = np.array([0.0, 0.1, 0.2, 10.0, 10.1, 10.2])
    ang = np.deg2rad(np.array([0.0, 2.0, 6.0, 30.0, 31.0, 33.0]))
    mag = 60000.0  # s = 1.2
    b = mag * np.column_stack([np.cos(ang), np.zeros(6), np.sin(ang)])
    cx, cz = np.cos(ang), np.sin(ang)
    # Only "cx*cz'" = 3 nT*s: h = 3 * s * cx * dcz/dt.
    coef = np.zeros(16)
    coef[TERM_NAMES.index("cx*cz'")] = 3.0
    dcz = np.array([
        (cz[1] - cz[0]) / 0.1, (cz[2] - cz[0]) / 0.2, (cz[2] - cz[1]) / 0.1,  # before the gap
        (cz[4] - cz[3]) / 0.1, (cz[5] - cz[3]) / 0.2, (cz[5] - cz[4]) / 0.1,  # after it
    ])  # fmt: skip
    np.testing.assert_allclose(tl_interference(b, t, coef), 3.0 * 1.2 * cx * dcz, rtol=1e-9)
    # Only "cz" = 10 nT (permanent): h = 10 * cz; only "cx*cx" = 4 nT: h = 4 * s * cx^2.
    coef = np.zeros(16)
    coef[2], coef[3] = 10.0, 4.0
    np.testing.assert_allclose(tl_interference(b, t, coef), 10.0 * cz + 4.0 * 1.2 * cx**2)
    terms = tl_terms(b, t)
    assert terms.shape == (6, 16)
    np.testing.assert_allclose(terms[:, 1], 0.0, atol=1e-15)  # cy = 0


def test_truth_interference_matches_an_independent_computation(cal) -> None:
    df, truth = cal
    # Recompute h from the logged attitude with the conftest DCM and the explicit formula,
    # per stretch (time gaps cut the derivative).
    ned = np.array(truth["earth_ned_nT"])
    c_bn = ned_to_body(*(np.deg2rad(df[k].to_numpy()) for k in ("roll", "pitch", "heading")))
    b = np.einsum("nij,j->ni", c_bn, ned)
    bt = np.linalg.norm(b, axis=1)
    c = b / bt[:, None]
    t = df["time"].to_numpy()
    stretch = np.r_[0, np.cumsum(np.diff(t) > 1.0)]
    d = np.vstack([np.gradient(c[stretch == k], t[stretch == k], axis=0)
                   for k in np.unique(stretch)])
    s = bt / 50000.0
    (cx, cy, cz), (dx, dy, dz) = c.T, d.T
    cols = [cx, cy, cz, s * cx * cx, s * cx * cy, s * cx * cz, s * cy * cy, s * cy * cz,
            s * cx * dx, s * cx * dy, s * cx * dz, s * cy * dx, s * cy * dy, s * cy * dz,
            s * cz * dx, s * cz * dy]
    h = np.column_stack(cols) @ np.array(truth["coef"])
    np.testing.assert_allclose(df["truth_mag_tl"], h, atol=1e-6)
    # Manoeuvres of +-5-10 deg give several nT peak-to-peak, far above the noise.
    ptp = df.groupby("line")["truth_mag_tl"].agg(np.ptp)
    assert ptp.min() > 1.0
    assert ptp.median() > 3.0


# --------------------------------------------------------------------------- consistency
def test_residual_is_white_noise_of_the_configured_level() -> None:
    for level in (0.02, 0.1):
        df, _ = simulate_calibration(seed=11, noise_nT=level, **CAL_KW)
        r = (df["mag"] - df["truth_mag_tl"] - df["truth_mag_clean"]).to_numpy()
        assert (df["truth_fault"] == "").all()
        assert np.all(df["truth_fault_nT"] == 0)
        assert r.std() == pytest.approx(level, rel=0.06)
        assert abs(r.mean()) < 4 * level / np.sqrt(r.size)
        lag1 = np.corrcoef(r[:-1], r[1:])[0, 1]
        assert abs(lag1) < 0.06


def test_flux_magnitude_is_the_total_field(cal, survey) -> None:
    for df, truth in (cal, survey):
        flux = np.linalg.norm(df[["flux_x", "flux_y", "flux_z"]].to_numpy(), axis=1)
        field = df["truth_mag_clean"] - df["truth_diurnal"]
        err = flux - field
        assert abs(err.mean()) < 0.1
        assert err.std() == pytest.approx(truth["flux_noise_nT"], rel=0.1)
        np.testing.assert_allclose(field - truth["earth"]["intensity_nT"],
                                   df["truth_anomaly"], atol=1e-6)


def test_calibration_structure(cal) -> None:
    df, truth = cal
    assert df["line"].nunique() == 12
    assert set(df["truth_maneuver"]) == {"pitch", "roll", "yaw"}
    per_line = df.groupby("line").agg(man=("truth_maneuver", "first"),
                                      leg=("truth_heading_leg", "first"))
    assert per_line["man"].tolist() == ["pitch", "roll", "yaw"] * 4
    assert per_line["leg"].tolist() == [0] * 3 + [1] * 3 + [2] * 3 + [3] * 3
    # Mean heading of each leg is the nominal cardinal heading; manoeuvre amplitudes as asked.
    hdg = np.rad2deg(np.unwrap(np.deg2rad(df["heading"])))
    for leg, nominal in enumerate((0.0, 90.0, 180.0, 270.0)):
        sel = df["truth_heading_leg"].to_numpy() == leg
        assert np.mod(hdg[sel].mean() - nominal + 180, 360) - 180 == pytest.approx(0, abs=1.5)
    roll = df.loc[df["truth_maneuver"] == "roll", "roll"]
    assert 8.0 < roll.abs().max() < 12.0
    assert truth["terms"] == list(TERM_NAMES)
    assert json.loads(json.dumps(truth)) == truth  # JSON-serialisable as is


def test_time_gaps_between_headings_only_when_turns_are_cut() -> None:
    df, truth = simulate_calibration(seed=2, n_boxes=2, manoeuvre_s=10.0)
    dt = np.diff(df["time"].to_numpy())
    gaps = np.flatnonzero(dt > 1.0)
    assert len(gaps) == 7  # 8 headings
    assert np.allclose(dt[gaps], truth["turn_s"] + 0.1)
    # Every gap is at a change of heading leg, never inside one.
    legs = df["truth_heading_leg"].to_numpy()
    assert np.all(legs[gaps] != legs[gaps + 1])
    kept, _ = simulate_calibration(seed=2, n_boxes=1, manoeuvre_s=10.0, cut_turns=False)
    assert np.diff(kept["time"]).max() < 0.11
    assert set(kept.loc[kept["line"] == -1, "truth_maneuver"]) == {"turn"}


def test_survey_geology_is_long_wavelength_and_attitude_carries_the_band(survey) -> None:
    df, truth = survey
    assert 3.0 < df["truth_anomaly"].abs().max() < 80.0
    assert len(truth["dipoles"]) == 5
    assert all(30 <= d["depth_m"] <= 120 for d in truth["dipoles"])
    sos = signal.butter(4, [0.1, 0.9], "bandpass", fs=truth["rate_hz"], output="sos")
    for _, g in df.groupby("line"):
        tl = signal.sosfiltfilt(sos, g["truth_mag_tl"]).std()
        anom = signal.sosfiltfilt(sos, g["truth_anomaly"]).std()
        assert tl > 0.3
        assert anom < 0.2 * tl
    assert df["truth_diurnal"].abs().max() < 10.0
    assert df["truth_diurnal"].abs().max() > 0.0


# --------------------------------------------------------------------------- faults
def test_explicit_faults_have_the_expected_effects() -> None:
    kinds = {1: "flux_bias", 4: "noise_burst", 7: "onboard_source", 10: "scalar_drift"}
    ref, _ = simulate_calibration(seed=4, **CAL_KW)
    df, truth = simulate_calibration(seed=4, faults=kinds, **CAL_KW)
    line = df["line"].to_numpy()
    for seg in range(12):
        assert set(df.loc[line == seg, "truth_fault"]) == {kinds.get(seg, "")}
    assert [(f["segment"], f["kind"]) for f in truth["faults"]] == sorted(kinds.items())
    params = {f["segment"]: f["params"] for f in truth["faults"]}
    dmag = (df["mag"] - ref["mag"]).to_numpy()
    dflux = (df[["flux_x", "flux_y", "flux_z"]] - ref[["flux_x", "flux_y", "flux_z"]]).to_numpy()
    # Nothing changes outside the faulted segments; the truth columns never change.
    clean = ~np.isin(line, list(kinds))
    assert np.all(dmag[clean] == 0) and np.all(dflux[clean] == 0)
    for col in ("truth_mag_tl", "truth_mag_clean", "truth_anomaly", "truth_diurnal"):
        pd.testing.assert_series_equal(df[col], ref[col])
    np.testing.assert_allclose(dmag, df["truth_fault_nT"], atol=1e-9)
    # flux_bias: one fluxgate axis jumps by 100-2000 nT; the scalar is unaffected.
    sel = line == 1
    axis = "xyz".index(params[1]["axis"])
    assert np.all(dmag[sel] == 0)
    np.testing.assert_allclose(dflux[sel, axis], params[1]["bias_nT"])
    assert 100 <= abs(params[1]["bias_nT"]) <= 2000
    assert np.all(np.delete(dflux[sel], axis, axis=1) == 0)
    # noise_burst: extra white noise of 1-3 nT rms on the scalar only.
    sel = line == 4
    assert 0.8 < dmag[sel].std() < 3.3
    assert dmag[sel].std() == pytest.approx(params[4]["std_nT"], rel=0.2)
    assert np.all(dflux[sel] == 0)
    # onboard_source: a permanent-like term c.p (+ induced) seen by the scalar only.
    sel = line == 7
    cos = df.loc[sel, ["flux_x", "flux_y", "flux_z"]].to_numpy()
    cos = cos / np.linalg.norm(cos, axis=1)[:, None]
    expected = cos @ np.array(params[7]["permanent_nT"])
    if params[7]["induced_nT"] is not None:
        s = df.loc[sel, "truth_mag_clean"].to_numpy() / 50000.0
        expected += s * np.einsum("ni,ij,nj->n", cos, np.array(params[7]["induced_nT"]), cos)
    np.testing.assert_allclose(dmag[sel], expected, atol=0.05)
    assert np.ptp(dmag[sel]) > 0.5  # it varies with attitude, unlike a constant offset
    assert 10 <= np.linalg.norm(params[7]["permanent_nT"]) <= 40
    assert np.all(dflux[sel] == 0)
    # scalar_drift: a few nT with in-band content, not seen by the fluxgate.
    sel = line == 10
    sos = signal.butter(4, [0.1, 0.9], "bandpass", fs=10.0, output="sos")
    assert signal.sosfiltfilt(sos, dmag[sel]).std() > 0.3
    assert 0.5 < np.abs(dmag[sel]).max() < 10
    assert np.all(dflux[sel] == 0)


def test_fault_fraction_and_bad_fault_arguments() -> None:
    df, truth = simulate_calibration(seed=8, faults=0.25, **CAL_KW)
    assert len(truth["faults"]) == 3
    assert {f["kind"] for f in truth["faults"]} <= set(FAULT_KINDS)
    assert len({f["kind"] for f in truth["faults"]}) == 3  # kinds cycled
    faulted = set(df.loc[df["truth_fault"] != "", "line"])
    assert faulted == {f["segment"] for f in truth["faults"]}
    all_f, truth_all = simulate_survey(seed=8, faults=1.0, **SUR_KW)
    assert (all_f["truth_fault"] != "").all()
    assert {f["kind"] for f in truth_all["faults"]} == set(FAULT_KINDS)
    with pytest.raises(InputError, match="unknown kind"):
        simulate_calibration(faults={0: "gremlin"}, **CAL_KW)
    with pytest.raises(InputError, match="segment 99"):
        simulate_calibration(faults={99: "flux_bias"}, **CAL_KW)
    with pytest.raises(InputError, match="between 0 and 1"):
        simulate_calibration(faults=1.5, **CAL_KW)
    with pytest.raises(InputError, match="coef"):
        simulate_calibration(coef=[1.0, 2.0], **CAL_KW)


# --------------------------------------------------------------------------- geometry
def test_survey_geometry_in_metres_and_plan_at_line_ends() -> None:
    spacing, length, n_lines = 25.0, 240.0, 4
    df, truth = simulate_survey(seed=1, n_lines=n_lines, line_length_m=length, spacing_m=spacing,
                                line_azimuth_deg=30.0, wander_m=0.0, pos_noise_m=0.0)
    # Independent geodesy: WGS84 geodetic -> ECEF (a rigid frame, metres).
    to_ecef = pyproj.Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
    xyz = np.column_stack(to_ecef.transform(df["lon"].to_numpy(), df["lat"].to_numpy(),
                                            df["alt"].to_numpy()))
    plan = survey_plan(truth)
    assert list(plan.columns) == ["lat", "lon", "alt"] and len(plan) == 2 * n_lines
    wp = np.column_stack(to_ecef.transform(plan["lon"].to_numpy(), plan["lat"].to_numpy(),
                                           plan["alt"].to_numpy()))
    line = df["line"].to_numpy()
    ends = []
    for k in range(n_lines):
        p = xyz[line == k]
        assert np.linalg.norm(p[-1] - p[0]) == pytest.approx(length, abs=0.01)
        # Samples evenly spaced along a straight line.
        step = np.linalg.norm(np.diff(p, axis=0), axis=1)
        assert np.ptp(step) < 0.001
        # Plan waypoints 2k, 2k+1 are the start and end of line k.
        assert np.linalg.norm(wp[2 * k] - p[0]) < 0.01
        assert np.linalg.norm(wp[2 * k + 1] - p[-1]) < 0.01
        ends.append((p[0], p[-1]))
    for k in range(n_lines - 1):
        a, b = ends[k]
        u = (b - a) / np.linalg.norm(b - a)
        for q in ends[k + 1]:
            dist = np.linalg.norm(np.cross(q - a, u))
            assert dist == pytest.approx(spacing, abs=0.01)
        # Alternate directions: line k+1 starts where line k ends (one spacing across).
        assert np.linalg.norm(ends[k + 1][0] - b) == pytest.approx(spacing, abs=0.01)
    # Heading of even lines is the azimuth, odd lines the reverse.
    first = df.groupby("line")["heading"].median()
    assert first[0] == pytest.approx(30.0, abs=3) and first[1] == pytest.approx(210.0, abs=3)


def test_local_geodetic_round_trip_and_rtk_noise() -> None:
    e, n, u = np.array([0.0, 123.4, -50.0]), np.array([0.0, -77.7, 300.0]), np.array([10, 0, 5.0])
    lat, lon, alt = local_to_geodetic(e, n, u)
    back = geodetic_to_local(lat, lon, alt)
    np.testing.assert_allclose(np.column_stack(back), np.column_stack([e, n, u]), atol=1e-6)
    # 0.001 deg of latitude is ~111 m, never 0.001 m.
    assert geodetic_to_local(46.801, 7.15, 600.0)[1] == pytest.approx(111.2, abs=0.2)
    noisy, truth = simulate_survey(seed=1, n_lines=2, line_length_m=160.0, wander_m=0.0)
    exact, _ = simulate_survey(seed=1, n_lines=2, line_length_m=160.0, wander_m=0.0,
                               pos_noise_m=0.0)
    d = np.column_stack(geodetic_to_local(noisy["lat"], noisy["lon"], noisy["alt"])) - \
        np.column_stack(geodetic_to_local(exact["lat"], exact["lon"], exact["alt"]))
    assert d.std(axis=0) == pytest.approx([0.02] * 3, rel=0.15)


# --------------------------------------------------------------------------- files and CLI
def _check_written(out: Path) -> None:
    for name in ("calibration.csv", "survey.csv", "plan.csv", "truth.json"):
        assert (out / name).is_file(), name
    cal = pd.read_csv(out / "calibration.csv", keep_default_na=False)
    assert cal["line"].nunique() >= 12
    for col in ("time", "lat", "lon", "alt", "flux_x", "flux_y", "flux_z", "mag", "line",
                "heading", "pitch", "roll", "truth_mag_tl", "truth_mag_clean", "truth_anomaly",
                "truth_diurnal", "truth_fault", "truth_maneuver"):
        assert col in cal.columns, col
    assert list(pd.read_csv(out / "plan.csv").columns) == ["lat", "lon", "alt"]
    truth = json.loads((out / "truth.json").read_text())
    assert set(truth) == {"calibration", "survey"}
    assert truth["survey"]["terms"] == list(TERM_NAMES)
    assert not list(out.glob(".*.tmp"))


def test_write_simulation_rounds_and_keeps_the_truth_consistent(tmp_path: Path) -> None:
    paths = write_simulation(tmp_path, seed=2, faults=0.2, small=True)
    assert set(paths) == {"calibration", "survey", "plan", "truth"}
    _check_written(tmp_path)
    sur = pd.read_csv(paths["survey"], keep_default_na=False)
    r = sur["mag"] - sur["truth_mag_tl"] - sur["truth_mag_clean"] - sur["truth_fault_nT"]
    assert r.std() == pytest.approx(0.02, rel=0.15)
    truth = json.loads(paths["truth"].read_text())
    faulted = sur.loc[sur["truth_fault"] != "", "line"].unique()
    assert sorted(faulted) == [f["segment"] for f in truth["survey"]["faults"]]
    for size in (p.stat().st_size for p in paths.values()):
        assert size < 600_000


def test_cli_writes_the_four_files(tmp_path: Path) -> None:
    out = tmp_path / "sim"
    res = CliRunner().invoke(app, ["simulate", "-o", str(out), "--small", "--seed", "3",
                                   "--faults", "0.1"])
    assert res.exit_code == 0, res.output
    _check_written(out)
    for name in ("calibration.csv", "survey.csv", "plan.csv", "truth.json"):
        assert name in res.output
    bad = CliRunner().invoke(app, ["simulate", "-o", str(tmp_path / "bad"), "--rate", "0"])
    assert bad.exit_code == 1
    assert "error:" in bad.output and "Traceback" not in bad.output
    assert not (tmp_path / "bad" / "calibration.csv").exists()
    helptext = CliRunner().invoke(app, ["simulate", "--help"])
    assert helptext.exit_code == 0 and "--faults" in helptext.output


def test_cli_as_a_real_process(tmp_path: Path) -> None:
    exe = shutil.which("aeromag") or str(Path(sys.executable).with_name("aeromag"))
    cmd = [exe] if Path(exe).exists() else [sys.executable, "-c",
                                             "from aeromag.cli import main; main()"]
    proc = subprocess.run([*cmd, "simulate", "-o", str(tmp_path), "--small", "--seed", "1"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    _check_written(tmp_path)
    printed = {Path(x).name for x in proc.stdout.split()}
    assert {"calibration.csv", "survey.csv", "plan.csv", "truth.json"} <= printed


def test_shipped_samples_match_the_recipe(tmp_path: Path) -> None:
    if not (SAMPLES / "truth.json").exists():
        pytest.skip("data_samples not generated yet (cli/make_samples.sh)")
    recipe = (REPO / "cli" / "make_samples.sh").read_text()
    assert "--small" in recipe and "--seed 1" in recipe and "--faults 0.1" in recipe
    write_simulation(tmp_path, seed=1, small=True, faults=0.1)
    for name in ("calibration.csv", "survey.csv", "plan.csv"):
        assert (SAMPLES / name).stat().st_size < 600_000
        shipped = pd.read_csv(SAMPLES / name, keep_default_na=False)
        fresh = pd.read_csv(tmp_path / name, keep_default_na=False)
        pd.testing.assert_frame_equal(shipped, fresh, check_exact=False, atol=2e-4, rtol=0)


def test_cli_calls_the_mission_simulator_hook(tmp_path: Path, monkeypatch) -> None:

    calls = []

    def fake(out_dir, *, seed=0, small=False):
        calls.append((Path(out_dir), seed))
        p = Path(out_dir) / "mission.csv"
        p.write_text("time\n0\n")
        return {"mission": p, "plan": p, "truth": p}

    import aeromag.workflows.mission as mission_files

    monkeypatch.setattr(mission_files, "write_mission_files", fake)
    res = CliRunner().invoke(app, ["simulate", "-o", str(tmp_path), "--small", "--seed", "7"])
    assert res.exit_code == 0, res.output
    assert calls == [(tmp_path, 7)]
    # Our plan.csv / truth.json are still reported next to the mission's files.
    assert "plan.csv" in res.output and "mission.csv" in res.output
