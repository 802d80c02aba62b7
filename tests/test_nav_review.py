"""Review cases of the navigation filter (fixed seeds): defects found on realistic logs."""

from __future__ import annotations

import numpy as np

from aeromag._core.geodesy import geodetic_to_ned
from aeromag.nav import NavConfig, navigate
from aeromag.synthetic.quadrotor import FIELD_NED_NT, simulate_quadrotor

REF = np.array(FIELD_NED_NT)


def test_barometer_datum_stays_in_the_vertical_covariance():
    """Without a rangefinder the barometer holds the height; its datum (offset) is only known
    as well as the height was when the first sample came, so the vertical error must stay
    within the filter's own 3 sigma.  Fixing the offset once (the defect) shrank sigma_d to
    the barometer noise averaged over the samples while the first GNSS fix's vertical error
    stayed in the estimate."""
    fl = simulate_quadrotor("hover", seed=1, duration_s=30.0)
    log = fl.log.copy()
    t = log.time.to_numpy()
    gnss = np.flatnonzero(np.isfinite(log.lat.to_numpy()))
    log.loc[log.index[gnss[0]], "alt"] += 3.0     # a first fix 3 m off vertically (GNSS)
    res = navigate(log, gps="none", mag_reference_ned_nT=REF, source="sim",
                   sensors=("gps_pos", "gps_vel", "baro", "gravity", "mag", "flow"))
    origin = res.report.gps["origin"]
    T = fl.truth
    tru = geodetic_to_ned(T.lat.to_numpy(), T.lon.to_numpy(), T.alt.to_numpy(), tuple(origin))
    err = res.data.nav_d_m.to_numpy() - tru[:, 2]
    sd = res.data.nav_std_d_m.to_numpy()
    late = t > 5.0
    assert np.mean(np.abs(err[late]) <= 3 * sd[late]) > 0.95, (np.abs(err[late]).mean(),
                                                              np.median(sd[late]))


def test_accelerometer_bias_states_are_the_default():
    """Real MEMS accelerometers always have a bias: the default filter estimates it."""
    cfg = NavConfig()
    assert cfg.accel_bias
    fl = simulate_quadrotor("hover", seed=0, duration_s=10.0)
    res = navigate(fl.log, gps="none", mag_reference_ned_nT=REF, source="sim")
    assert {"bax_ms2", "bay_ms2", "baz_ms2"} <= set(res.report.settings["states"])



def test_gyro_in_deg_per_s_in_a_hover_warns_with_the_units_remedy():
    """A hover's rates stay far below 34.9 rad/s even in deg/s, so the full-scale test is
    silent while the bias alone (0.3 °/s read as rad/s) spins the attitude: the magnetometer
    comparison warns."""
    fl = simulate_quadrotor("hover", seed=0, duration_s=20.0)
    log = fl.log.copy()
    for c in ("gyro_x", "gyro_y", "gyro_z"):
        log[c] = np.degrees(log[c])
    assert np.nanmax(np.abs(log[["gyro_x", "gyro_y", "gyro_z"]].to_numpy())) < 34.9
    res = navigate(log, gps="none", mag_reference_ned_nT=REF, source="sim")
    assert any("units={'gyro': 'deg/s'}" in w for w in res.report.warnings)
    for scenario in ("hover", "rectangle"):            # rad/s: no false warning
        ok = navigate(simulate_quadrotor(scenario, seed=2, duration_s=20.0).log, gps="none",
                      mag_reference_ned_nT=REF, source="sim")
        assert not any("deg/s" in w for w in ok.report.warnings), ok.report.warnings


def test_the_origin_fix_is_not_fused_twice():
    """With --gps none the first fix defines the frame and the initial sigma (its accuracy);
    fusing it again as a measurement shrank the horizontal sigma by sqrt(2) with no new
    information (2.12 m -> 1.5 m per axis while the error is the fix's own)."""
    fl = simulate_quadrotor("hover", seed=0, duration_s=5.0)
    res = navigate(fl.log, gps="none", mag_reference_ned_nT=REF, source="sim")
    assert res.report.gps["n_fixes_fused"] == 0
    sd = res.data.nav_std_n_m.to_numpy()
    assert abs(np.median(sd) - NavConfig().gps_cep_m / 1.1774) < 0.05, np.median(sd)


def test_bad_option_values_name_the_option(tmp_path):
    from typer.testing import CliRunner

    from aeromag.cli import app

    log = simulate_quadrotor("hover", seed=0, duration_s=3.0).log
    path = tmp_path / "log.csv"
    log.to_csv(path, index=False)
    runner = CliRunner()
    for args, want in ((["--range-limits", "5", "1"], "--range-limits MIN MAX"),
                       (["--gyro-noise", "-1"], "--gyro-noise")):
        r = runner.invoke(app, ["navigate", str(path), "-o", str(tmp_path / "o.csv"), *args])
        assert r.exit_code == 1 and want in r.output, r.output
        assert "Traceback" not in r.output and not (tmp_path / "o.csv").exists()
