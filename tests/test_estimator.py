"""The scikit-learn estimator TollesLawson: conventions and coefficient recovery."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.base import clone

from aeromag.simulate import default_aircraft_coef, simulate_calibration
from aeromag.tolles_lawson import TERMS_16, TollesLawson


def test_get_params_clone_roundtrip():
    est = TollesLawson(terms="16", band=(0.05, 0.8), ridge=1e-4, order=3, max_gap_s=2.0)
    p = est.get_params()
    assert p == {"terms": "16", "band": (0.05, 0.8), "ridge": 1e-4, "order": 3,
                 "max_gap_s": 2.0}
    c = clone(est)
    assert c is not est and c.get_params() == p
    assert TollesLawson(**p).get_params() == p
    c.set_params(ridge=0.0)
    assert c.ridge == 0.0 and est.ridge == 1e-4
    assert not hasattr(c, "coef_")


@pytest.fixture(scope="module")
def cal():
    return simulate_calibration(seed=8, n_boxes=2)[0]


def test_fit_recovers_simulator_coefficients(cal):
    X = cal[["time", "flux_x", "flux_y", "flux_z"]]
    est = TollesLawson()
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
    a = TollesLawson().fit(X, cal["mag"]).coef_
    b = TollesLawson().fit(X.to_numpy(), cal["mag"].to_numpy()).coef_
    assert np.allclose(a, b)
