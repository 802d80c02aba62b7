"""The TL design matrix, derivatives, solver, model files and the estimator."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.base import clone

from aeromag._core.lstsq import solve_normal
from aeromag.compensation.estimator import TollesLawsonRegressor
from aeromag.compensation.model import TLModel
from aeromag.compensation.terms import (
    EDDY_8,
    INDUCED_5,
    PERMANENT,
    TERMS_16,
    design_matrix,
    parse_terms,
    time_derivative,
)
from aeromag.errors import FitError, InputError

from .conftest import COEF16, hand_flight


def test_term_names_and_order_match_interface():
    assert TERMS_16 == (
        "cx", "cy", "cz",
        "cx*cx", "cx*cy", "cx*cz", "cy*cy", "cy*cz",
        "cx*cx'", "cx*cy'", "cx*cz'", "cy*cx'", "cy*cy'", "cy*cz'", "cz*cx'", "cz*cy'",
    )
    assert len(PERMANENT) == 3 and len(INDUCED_5) == 5 and len(EDDY_8) == 8


def test_design_matrix_columns_against_hand_formulas():
    rng = np.random.default_rng(3)
    n = 7
    t = np.cumsum(rng.uniform(0.05, 0.15, n))
    flux = rng.normal(0, 30000, (n, 3))
    A = design_matrix(flux, t)
    for i in range(1, n - 1):  # interior samples: hand-written central difference
        b = flux[i]
        bt = float(np.sqrt(b @ b))
        c = b / bt
        cm = flux[i - 1] / np.linalg.norm(flux[i - 1])
        cp = flux[i + 1] / np.linalg.norm(flux[i + 1])
        hs, hd = t[i] - t[i - 1], t[i + 1] - t[i]
        d = (hs**2 * cp + (hd**2 - hs**2) * c - hd**2 * cm) / (hs * hd * (hs + hd))
        s = bt / 50000.0
        x, y, z = c
        dx, dy, dz = d
        expect = [x, y, z, s * x * x, s * x * y, s * x * z, s * y * y, s * y * z,
                  s * x * dx, s * x * dy, s * x * dz, s * y * dx, s * y * dy, s * y * dz,
                  s * z * dx, s * z * dy]
        np.testing.assert_allclose(A[i], expect, rtol=1e-12, atol=1e-15)


def test_level_flight_north_permanent_columns_are_field_direction():
    # Heading north, level: body axes = NED axes, so cosines = the field's NED direction.
    inc = np.deg2rad(60.0)
    b = 48000.0 * np.array([np.cos(inc), 0.0, np.sin(inc)])
    flux = np.tile(b, (5, 1))
    A = design_matrix(flux, np.arange(5.0))
    np.testing.assert_allclose(A[:, 0], np.cos(inc))
    np.testing.assert_allclose(A[:, 2], np.sin(inc))
    np.testing.assert_allclose(A[:, 3], 48000 / 50000 * np.cos(inc) ** 2)
    np.testing.assert_allclose(A[:, 8:], 0.0, atol=1e-15)  # no motion, no eddy currents


def test_time_derivative_matches_gradient_per_stretch():
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(0.08, 0.12, 200))
    x = rng.normal(size=(200, 3))
    stretch = np.repeat([0, 1, 2, 3], [60, 1, 89, 50])
    d = time_derivative(x, t, stretch)
    for k in range(4):
        m = stretch == k
        if m.sum() == 1:
            np.testing.assert_array_equal(d[m], 0.0)
        else:
            np.testing.assert_allclose(d[m], np.gradient(x[m], t[m], axis=0), rtol=1e-10)


def test_derivative_never_crosses_a_gap():
    t = np.r_[np.arange(10.0), 100 + np.arange(10.0)]
    x = np.r_[np.zeros(10), np.ones(10)]  # a jump across the gap only
    d = time_derivative(x, t, np.repeat([0, 1], 10))
    np.testing.assert_array_equal(d, 0.0)


def test_exact_recovery_without_noise():
    df, _ = hand_flight(seed=2, noise=0.0, flux_noise=0.0)
    X = df[["time", "flux_x", "flux_y", "flux_z"]]
    est = TollesLawsonRegressor().fit(X, df["mag"])
    np.testing.assert_allclose(est.coef_, COEF16, rtol=1e-5, atol=1e-5)


def test_recovery_with_noise_and_prediction_matches_truth():
    df, h = hand_flight(seed=5)
    est = TollesLawsonRegressor(band=(0.1, 0.9)).fit(df[["time", "flux_x", "flux_y", "flux_z"]],
                                             df["mag"])
    pred = est.predict(df[["time", "flux_x", "flux_y", "flux_z"]])
    # The model's in-band part matches the truth to noise level; its level is the model's.
    err = (pred - h) - np.mean(pred - h)
    assert np.std(err) < 0.05
    assert est.score(df[["time", "flux_x", "flux_y", "flux_z"]], df["mag"]) > 50
    assert est.condition_number_ > 1


def test_estimator_follows_sklearn_conventions():
    est = TollesLawsonRegressor(terms="18", band=(0.2, 1.0), ridge=1e-3)
    params = est.get_params()
    assert params == {"terms": "18", "band": (0.2, 1.0), "ridge": 1e-3, "order": 4,
                      "max_gap_s": None, "max_condition": 1e5, "max_interference": 0.25}
    c = clone(est)
    assert c.get_params() == params and c is not est
    assert not hasattr(c, "coef_")


def test_parse_terms_presets_and_groups():
    assert parse_terms("16") == TERMS_16
    assert len(parse_terms("18")) == 18
    assert parse_terms("permanent,induced_5,eddy_8") == TERMS_16
    assert parse_terms("p,i3,e3,b") == (
        "cx", "cy", "cz", "cx*cx", "cy*cy", "cz*cz", "cx*cx'", "cy*cy'", "cz*cz'", "bias")
    with pytest.raises(InputError, match="unknown term"):
        parse_terms("permanent,magic")


def test_bias_term_is_fitted_on_the_unfiltered_level():
    df, _ = hand_flight(seed=4, noise=0.0, flux_noise=0.0)
    df = df.assign(mag=df["mag"] + 123.0 - df["truth_clean"])  # interference + a bias only
    # mag here is no total field (~140 nT), so the interference limit is lifted
    est = TollesLawsonRegressor(terms="16,bias", max_interference=10.0)
    est.fit(df[["time", "flux_x", "flux_y", "flux_z"]], df["mag"])
    assert est.coef_[-1] == pytest.approx(123.0, abs=1e-3)


def test_singular_fit_is_a_fit_error():
    g = np.zeros((3, 3))
    with pytest.raises(FitError, match="never varies"):
        solve_normal(g, np.zeros(3))
    g = np.ones((3, 3))  # collinear columns
    with pytest.raises(FitError, match="ill-conditioned"):
        solve_normal(g, np.ones(3))


def test_model_file_round_trip(tmp_path):
    m = TLModel(TERMS_16, COEF16, meta={"band_hz": [0.1, 0.9]})
    p = m.save(tmp_path / "m.json")
    d = json.loads(p.read_text())
    assert d["terms"] == list(TERMS_16) and d["coef"] == list(COEF16)
    m2 = TLModel.load(p)
    assert m2.terms == TERMS_16
    np.testing.assert_array_equal(m2.coef, COEF16)
    (tmp_path / "bad.json").write_text('{"terms": ["cx"], "coef": [1, 2]}')
    with pytest.raises(InputError, match="bad.json"):
        TLModel.load(tmp_path / "bad.json")
    (tmp_path / "junk.json").write_text("not json")
    with pytest.raises(InputError, match="not valid JSON"):
        TLModel.load(tmp_path / "junk.json")


@settings(max_examples=40, deadline=None)
@given(st.floats(1e3, 1e5), st.lists(st.floats(-1, 1), min_size=3, max_size=3))
def test_design_matrix_is_scale_invariant_in_direction(scale, v):
    # Permanent columns depend only on the field's direction; induced scale with |B|.
    v = np.asarray(v)
    if np.linalg.norm(v) < 1e-3:
        return
    flux = np.tile(v, (4, 1))
    a1 = design_matrix(flux * scale, np.arange(4.0))
    a2 = design_matrix(flux * 2 * scale, np.arange(4.0))
    # (atol: hypothesis finds subnormal components, where only absolute agreement holds)
    np.testing.assert_allclose(a1[:, :3], a2[:, :3], rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(2 * a1[:, 3:8], a2[:, 3:8], rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("block", [1, 2, 7, 64, 10_000])
def test_blocked_prediction_equals_design_matrix(block):
    """Block-by-block evaluation (one sample of context each side) equals A @ coef, also
    where stretches begin or end on a block boundary and for one-sample stretches."""
    from aeromag.compensation.model import predict_interference

    rng = np.random.default_rng(block)
    n = 300
    t = np.cumsum(rng.uniform(0.05, 0.15, n))
    flux = rng.normal(0, 1, (n, 3)) * 300 + np.array([20000.0, 3000.0, 45000.0])
    stretch = np.repeat(np.arange(8), [7, 1, 56, 64, 2, 100, 1, 69])
    coef = rng.normal(0, 5, 16)
    want = design_matrix(flux, t, stretch=stretch) @ coef
    got = predict_interference(flux, t, TERMS_16, coef, stretch=stretch, block=block)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
    m = TLModel(TERMS_16, coef)
    np.testing.assert_allclose(m.predict(flux, t, stretch), want, rtol=0, atol=1e-9)


def test_blocked_derivative_equals_whole_array():
    """time_derivative works block by block on long logs: bitwise the same as one pass, with
    stretch boundaries right at, before and after block edges."""
    from aeromag.compensation.terms import PREDICT_BLOCK, _time_derivative, time_derivative

    rng = np.random.default_rng(5)
    n = 3 * PREDICT_BLOCK + 123
    t = np.cumsum(rng.uniform(0.05, 0.15, n))
    f = rng.normal(size=(n, 3))
    cuts = [PREDICT_BLOCK - 1, PREDICT_BLOCK, PREDICT_BLOCK + 1, 2 * PREDICT_BLOCK,
            2 * PREDICT_BLOCK + 2, 3 * PREDICT_BLOCK]
    st = np.zeros(n, dtype=np.int64)
    for c in cuts:
        st[c:] += 1
    np.testing.assert_array_equal(time_derivative(f, t, st), _time_derivative(f, t, st))
    np.testing.assert_allclose(time_derivative(f[:, 0], t), np.gradient(f[:, 0], t),
                               rtol=1e-9, atol=1e-12)


def test_derivative_of_rows_is_bitwise_the_per_row_derivative():
    """The batched derivative used by the fit equals time_derivative row by row, including
    stretch changes, one-sample stretches and labels marking samples beyond the log."""
    from aeromag.compensation.terms import time_derivative, time_derivative_rows

    rng = np.random.default_rng(11)
    q, m = 6, 40
    t = np.cumsum(rng.uniform(0.05, 0.15, (q, m)), axis=1)
    f = rng.normal(size=(q, m, 3))
    lab = np.cumsum(rng.random((q, m)) < 0.15, axis=1)
    lab[0, 0] = -2
    lab[1, -1] = -2
    got = time_derivative_rows(f, t, lab)
    for r in range(q):
        np.testing.assert_array_equal(got[r], time_derivative(f[r], t[r], lab[r]))
