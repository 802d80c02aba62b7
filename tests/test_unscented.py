"""The unscented transform: exact on linear-Gaussian models, robust square roots, angles."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aeromag._core.unscented import (
    CovarianceError,
    angle_mean_fn,
    angle_residual_fn,
    robust_sqrt,
    sigma_points,
    sigma_weights,
    unscented_transform,
)


def _random_spd(rng, n):
    a = rng.normal(size=(n, n))
    return a @ a.T + 0.1 * np.eye(n)


@pytest.mark.parametrize("alpha,beta,kappa", [(1.0, 2.0, 0.0), (1e-3, 2.0, 0.0),
                                              (0.5, 2.0, 1.0)])
def test_ut_equals_kalman_filter_on_linear_gaussian_model(alpha, beta, kappa):
    rng = np.random.default_rng(1)
    n, m = 5, 3
    F = rng.normal(size=(n, n))
    H = rng.normal(size=(m, n))
    Q = _random_spd(rng, n)
    R = _random_spd(rng, m)
    x = rng.normal(size=n)
    P = _random_spd(rng, n)
    z = rng.normal(size=m)
    # Kalman filter, by hand.
    xp = F @ x
    Pp = F @ P @ F.T + Q
    S = H @ Pp @ H.T + R
    K = Pp @ H.T @ np.linalg.inv(S)
    xu = xp + K @ (z - H @ xp)
    Pu = Pp - K @ S @ K.T
    # Unscented Kalman filter.
    xp2, Pp2, _ = unscented_transform(lambda X: X @ F.T, x, P, alpha, beta, kappa, noise_cov=Q)
    zp, S2, Pxz = unscented_transform(lambda X: X @ H.T, xp2, Pp2, alpha, beta, kappa,
                                      noise_cov=R)
    K2 = Pxz @ np.linalg.inv(S2)
    xu2 = xp2 + K2 @ (z - zp)
    Pu2 = Pp2 - K2 @ S2 @ K2.T
    tol = dict(rtol=1e-9, atol=1e-9 * np.abs(Pp).max())
    np.testing.assert_allclose(xp2, xp, **tol)
    np.testing.assert_allclose(Pp2, Pp, **tol)
    np.testing.assert_allclose(S2, S, **tol)
    np.testing.assert_allclose(xu2, xu, rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(Pu2, Pu, rtol=1e-8, atol=1e-8 * np.abs(Pu).max())


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 6), seed=st.integers(0, 2**31 - 1),
       alpha=st.floats(0.05, 1.0), kappa=st.floats(0.0, 3.0))
def test_sigma_points_reproduce_mean_and_covariance(n, seed, alpha, kappa):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=n)
    P = _random_spd(rng, n)
    X, Wm, Wc = sigma_points(x, P, alpha, 2.0, kappa)
    assert X.shape == (2 * n + 1, n)
    assert np.isclose(Wm.sum(), 1.0)
    np.testing.assert_allclose(Wm @ X, x, atol=1e-9 * (1 + np.abs(x).max()))
    d = X - x
    # The covariance weights without the (1 - alpha^2 + beta) term reproduce P exactly.
    lam = alpha**2 * (n + kappa) - n
    wc = Wc.copy()
    wc[0] = lam / (n + lam)
    np.testing.assert_allclose((wc[:, None] * d).T @ d, P, rtol=1e-8, atol=1e-8)


def test_batched_transform_equals_one_at_a_time():
    rng = np.random.default_rng(2)
    B, n = 7, 3
    xs = rng.normal(size=(B, n))
    Ps = np.stack([_random_spd(rng, n) for _ in range(B)])

    def f(X):
        return np.stack([np.sin(X[..., 0]) + X[..., 1] ** 2, X[..., 2] * X[..., 0]], axis=-1)

    m, C, X = unscented_transform(f, xs, Ps)
    assert m.shape == (B, 2) and C.shape == (B, 2, 2) and X.shape == (B, n, 2)
    for b in range(B):
        mb, Cb, Xb = unscented_transform(f, xs[b], Ps[b])
        np.testing.assert_allclose(m[b], mb, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(C[b], Cb, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(X[b], Xb, rtol=1e-10, atol=1e-12)


def test_robust_sqrt_survives_indefinite_and_singular_matrices():
    rng = np.random.default_rng(3)
    v = rng.normal(size=(6, 2))
    singular = v @ v.T                       # rank 2
    indefinite = singular.copy()
    indefinite[0, 0] -= 1e-9                 # rounding-level negative eigenvalue
    asym = _random_spd(rng, 6)
    asym[0, 1] += 1e-10
    for P in (singular, indefinite, asym, np.zeros((6, 6))):
        S = robust_sqrt(P)
        assert np.all(np.isfinite(S))
        np.testing.assert_allclose(S @ S.T, 0.5 * (P + P.T), atol=1e-6 * (1 + np.abs(P).max()))


def test_nonfinite_covariance_is_a_clear_error():
    P = np.eye(3)
    P[1, 1] = np.nan
    with pytest.raises(CovarianceError, match="diverged"):
        robust_sqrt(P)


def test_weights_validate_their_parameters():
    with pytest.raises(ValueError):
        sigma_weights(0)
    with pytest.raises(ValueError):
        sigma_weights(3, alpha=0.0)
    Wm, Wc, gamma = sigma_weights(4, 1.0, 2.0, 0.0)
    assert Wm[0] == 0.0 and Wc[0] == 2.0 and np.isclose(gamma, 2.0)


def test_angle_aware_mean_and_residual_across_the_wrap():
    # A heading near +-pi: the plain mean would be ~0 (wrong), the circular one ~pi.
    x = np.array([np.pi - 0.01, 1.0])
    P = np.diag([0.05**2, 0.1])
    res = angle_residual_fn([0])
    mean = angle_mean_fn([0])

    def add(a, d):
        out = a + d
        out[..., 0] = np.mod(out[..., 0] + np.pi, 2 * np.pi) - np.pi
        return out

    X, Wm, Wc = sigma_points(x, P, add_fn=add)
    assert np.any(X[:, 0] < 0)               # some points wrapped to -pi
    m, C, _ = unscented_transform(lambda Z: Z, x, P, sigma=(X, Wm, Wc), mean_fn=mean,
                                  residual_fn=res, state_residual_fn=res)
    assert abs(abs(m[0]) - (np.pi - 0.01)) < 1e-9
    np.testing.assert_allclose(C, P, rtol=1e-6)
    r = res(np.array([np.pi - 0.01]), np.array([-np.pi + 0.01]))
    np.testing.assert_allclose(r, [-0.02], atol=1e-12)
