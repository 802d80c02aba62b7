"""The scikit-learn estimator TollesLawsonRegressor: conventions and coefficient recovery."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.base import clone

from aeromag.compensation.estimator import TollesLawsonRegressor
from aeromag.compensation.terms import TERMS_16
from aeromag.synthetic.calibration import simulate_calibration
from aeromag.synthetic.physics import default_aircraft_coef


def test_get_params_clone_roundtrip():
    est = TollesLawsonRegressor(terms="16", band=(0.05, 0.8), ridge=1e-4, order=3, max_gap_s=2.0)
    p = est.get_params()
    assert p == {"terms": "16", "band": (0.05, 0.8), "ridge": 1e-4, "order": 3,
                 "max_gap_s": 2.0, "max_condition": 1e5, "max_interference": 0.25}
    c = clone(est)
    assert c is not est and c.get_params() == p
    assert TollesLawsonRegressor(**p).get_params() == p
    c.set_params(ridge=0.0)
    assert c.ridge == 0.0 and est.ridge == 1e-4
    assert not hasattr(c, "coef_")


@pytest.fixture(scope="module")
def cal():
    return simulate_calibration(seed=8, n_boxes=2)[0]


def test_fit_recovers_simulator_coefficients(cal):
    X = cal[["time", "flux_x", "flux_y", "flux_z"]]
    est = TollesLawsonRegressor()
    assert est.fit(X, cal["mag"]) is est
    assert est.terms_ == TERMS_16
    truth = default_aircraft_coef()
    err = np.abs(est.coef_ - truth)
    assert np.all(err <= 0.05 * np.abs(truth) + 0.3), (est.coef_, truth)
    assert est.score(X, cal["mag"]) > 50
    tl = est.predict(X)
    resid = tl - cal["truth_mag_tl"].to_numpy()
    assert np.std(resid - np.mean(resid)) < 0.3  # nT, level aside (invisible in the band)
    fitted = clone(est)
    assert not hasattr(fitted, "coef_")


def test_numpy_input_matches_dataframe(cal):
    X = cal[["time", "flux_x", "flux_y", "flux_z"]]
    a = TollesLawsonRegressor().fit(X, cal["mag"]).coef_
    b = TollesLawsonRegressor().fit(X.to_numpy(), cal["mag"].to_numpy()).coef_
    assert np.allclose(a, b)


def _level_flight(seed: int = 0, n: int = 6000) -> tuple[np.ndarray, np.ndarray]:
    """Straight and level at 10 Hz with 1 degree of smooth attitude jitter: nearly collinear
    TL terms (scaled condition number between 1e5 and 1e7)."""
    from aeromag.synthetic import body_field

    rng = np.random.default_rng(seed)
    t = np.arange(n) / 10.0
    kernel = np.hanning(21) / np.hanning(21).sum()
    jit = [np.convolve(rng.standard_normal(n), kernel, mode="same") * 4.0 for _ in range(3)]
    b = body_field(np.array([20000.0, 1000.0, 45000.0]), 30.0 + jit[0], jit[1], jit[2])
    X = np.column_stack([t, b])
    y = np.linalg.norm(b, axis=1) + 0.01 * rng.standard_normal(n)
    return X, y


def test_estimator_refuses_what_calibrate_refuses():
    """The estimator shares the pipeline's fit: an ill-conditioned fit is refused at 1e5 (the
    old estimator refused only near 1e7 and fitted such data silently)."""
    from aeromag.errors import FitError

    X, y = _level_flight()
    with pytest.raises(FitError, match="ill-conditioned"):
        TollesLawsonRegressor().fit(X, y)
    # The same data, regularised, fit.
    assert TollesLawsonRegressor(ridge=1e-3, max_interference=10.0).fit(X, y).coef_.shape == (16,)


def test_transform_is_mag_minus_predict(cal):
    X = cal[["time", "flux_x", "flux_y", "flux_z"]]
    est = TollesLawsonRegressor().fit(X, cal["mag"])
    comp = est.transform(X, cal["mag"])
    np.testing.assert_allclose(comp, cal["mag"].to_numpy() - est.predict(X))
    np.testing.assert_allclose(est.transform(cal[["time", "flux_x", "flux_y", "flux_z", "mag"]]),
                               comp)


def test_library_errors_name_the_parameter_not_the_flag(cal):
    """A notebook user has no --segment-seconds: the library names the keyword."""
    from aeromag.errors import AeromagError

    X = cal[["time", "flux_x", "flux_y", "flux_z"]].to_numpy()
    with pytest.raises(AeromagError) as exc:
        TollesLawsonRegressor().fit(X[:150], cal["mag"].to_numpy()[:150])
    msg = str(exc.value)
    assert "--" not in msg and "segment_seconds=" in msg, msg


# --------------------------------------------------------------------------- check_estimator
_NOT_A_LOG = ("scikit-learn's generated data is no magnetometer log: X must be the four columns"
              " time [s], flux_x, flux_y, flux_z [nT] (its X has 1 to 10 random features)")
_NO_EARTH_FIELD = ("scikit-learn's generated y is no total field in nT (about +-1): refused"
                   " with the --units remedy, as a log in uT is (issue 30)")
#: The checks TollesLawson cannot meet, and why: every one needs X to be arbitrary features
#: and y any number, which a Tolles-Lawson fit on (time, fluxgate) against a total field is
#: not.  The others (tags, get/set_params, clone, NaN/inf/sparse/complex/empty/1-sample
#: refusals, y required, fit_transform, not-fitted errors ...) pass.
EXPECTED_FAILED_CHECKS = {name: _NOT_A_LOG for name in (
    "check_fit_score_takes_y", "check_estimators_overwrite_params",
    "check_dont_overwrite_parameters", "check_estimators_fit_returns_self",
    "check_readonly_memmap_input", "check_positive_only_tag_during_fit",
    "check_estimators_dtypes", "check_dtype_object", "check_pipeline_consistency",
    "check_estimators_nan_inf", "check_estimators_pickle", "check_f_contiguous_array_estimator",
    "check_regressors_train", "check_regressor_data_not_an_array", "check_supervised_y_2d",
    "check_regressors_int", "check_transformer_data_not_an_array", "check_transformer_general",
    "check_transformer_preserve_dtypes", "check_methods_sample_order_invariance",
    "check_methods_subset_invariance", "check_dict_unchanged", "check_fit_idempotent",
    "check_fit_check_is_fitted", "check_n_features_in", "check_fit2d_predict1d")}
EXPECTED_FAILED_CHECKS.update({name: _NO_EARTH_FIELD for name in (
    "check_n_features_in_after_fitting", "check_regressors_no_decision_function")})


def test_check_estimator_fails_only_the_stated_checks():
    """Issue 30: check_estimator raised at once (transformer tags missing, transform without
    y); now it runs, and exactly the checks stated above (with their reason) fail."""
    import warnings

    from sklearn.utils.estimator_checks import check_estimator

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = check_estimator(TollesLawsonRegressor(), on_fail=None,
                              expected_failed_checks=EXPECTED_FAILED_CHECKS)
    failed = {r["check_name"] for r in res if r["status"] == "failed"}
    passed = {r["check_name"] for r in res if r["status"] == "passed"}
    xfail = {r["check_name"] for r in res if r["status"] == "xfail"}
    assert failed == set(), failed
    assert xfail == set(EXPECTED_FAILED_CHECKS)
    for must in ("check_estimator_tags_renamed", "check_estimators_empty_data_messages",
                 "check_estimator_sparse_array", "check_complex_data", "check_requires_y_none",
                 "check_fit2d_1sample", "check_fit2d_1feature", "check_get_params_invariance"):
        assert must in passed, must
