"""The recursive least-squares kernel: exactness against batch and weighted least squares,
step == run, NaN handling, bounded covariance, validation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aeromag._core.rls import RecursiveLeastSquares, check_forgetting
from aeromag.errors import InputError


def _data(seed: int, n_samples: int = 400, n: int = 4, m: int = 3, noise: float = 0.01):
    rng = np.random.default_rng(seed)
    phi = np.column_stack([rng.normal(size=(n_samples, n - 1)), np.ones(n_samples)])
    theta = rng.normal(size=(n, m))
    y = phi @ theta + noise * rng.normal(size=(n_samples, m))
    return phi, y, theta


def _weighted_ls(phi, y, lam, alpha, floor, theta0=None):
    """Independent reference: lstsq of the weighted rows plus the prior rows."""
    k, n = phi.shape
    m = y.shape[1]
    t0 = np.zeros((n, m)) if theta0 is None else theta0
    w = lam ** np.arange(k - 1, -1, -1)
    wp = lam ** k / alpha + (1 - lam ** k) * floor
    a = np.vstack([np.sqrt(w)[:, None] * phi, np.sqrt(wp) * np.eye(n)])
    b = np.vstack([np.sqrt(w)[:, None] * y, np.sqrt(wp) * t0])
    return np.linalg.lstsq(a, b, rcond=None)[0]


def _hist(res):
    """The parameter history (N, n, m) of a SequentialResult of the kernel."""
    n = res.info["theta_final"].shape
    return res.state.reshape(len(res.state), *n)


def _stepped(est, phi, y):
    out = []
    for p, q in zip(phi, y, strict=True):
        est.step(q, p)
        out.append(est.theta.copy())
    return np.array(out)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_lambda_one_equals_batch_least_squares(seed):
    phi, y, _ = _data(seed)
    alpha = 1e8
    est = RecursiveLeastSquares(4, 3, forgetting=1.0, alpha=alpha)
    res = est.run(y, phi)
    # The prior 1/alpha is the only difference from plain lstsq; with it, equal to rounding.
    ref = _weighted_ls(phi, y, 1.0, alpha, 0.0)
    np.testing.assert_allclose(res.info['theta_final'], ref, rtol=0, atol=1e-11)
    plain = np.linalg.lstsq(phi, y, rcond=None)[0]
    np.testing.assert_allclose(res.info['theta_final'], plain, rtol=0, atol=1e-7)
    # Every prefix too (the history is the batch fit on the samples so far).
    for k in (10, 57, 200):
        np.testing.assert_allclose(_hist(res)[k - 1], _weighted_ls(phi[:k], y[:k], 1.0,
                                                                  alpha, 0.0), atol=1e-9)


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("lam,floor", [(0.96, None), (0.9, 0.0), (0.99, 0.5)])
def test_forgetting_equals_exponentially_weighted_least_squares(seed, lam, floor):
    phi, y, _ = _data(seed)
    alpha = 100.0
    est = RecursiveLeastSquares(4, 3, forgetting=lam, alpha=alpha, floor=floor)
    res = est.run(y, phi)
    fl = 1 / alpha if floor is None else floor
    for k in (5, 50, 400):
        np.testing.assert_allclose(_hist(res)[k - 1], _weighted_ls(phi[:k], y[:k], lam, alpha,
                                                                  fl), rtol=0, atol=1e-10)


@pytest.mark.parametrize("seed", [3, 4])
@pytest.mark.parametrize("lam", [1.0, 0.975, 0.84])
def test_step_and_run_agree(seed, lam):
    phi, y, _ = _data(seed, n=16, m=1)
    a = RecursiveLeastSquares(16, 1, forgetting=lam, alpha=1e3)
    b = RecursiveLeastSquares(16, 1, forgetting=lam, alpha=1e3)
    hist = _stepped(a, phi, y)
    res = b.run(y, phi)
    np.testing.assert_allclose(hist, _hist(res), rtol=0, atol=1e-10)
    np.testing.assert_allclose(a.P, b.P, rtol=1e-9, atol=1e-12)
    # run continues from the state: two halves equal the whole
    c = RecursiveLeastSquares(16, 1, forgetting=lam, alpha=1e3)
    c.run(y[:150], phi[:150])
    r2 = c.run(y[150:], phi[150:])
    np.testing.assert_allclose(_hist(r2), _hist(res)[150:], rtol=0, atol=1e-10)


def test_noise_free_recovery_to_1e9():
    phi, y, theta = _data(7, n_samples=300, noise=0.0)
    for lam in (1.0, 0.96):
        est = RecursiveLeastSquares(4, 3, forgetting=lam, alpha=1e10, floor=0.0)
        res = est.run(y, phi)
        rel = np.abs(res.info['theta_final'] - theta).max() / np.abs(theta).max()
        assert rel < 1e-9, (lam, rel)


def test_nan_sample_skipped_and_reported():
    phi, y, _ = _data(5)
    y[10, 1] = np.nan
    phi[20, 0] = np.inf
    a = RecursiveLeastSquares(4, 3, forgetting=0.96, alpha=100.0)
    b = RecursiveLeastSquares(4, 3, forgetting=0.96, alpha=100.0)
    res = a.run(y, phi)
    assert res.innovations['y'].n_gated == 2 and res.info['skipped'][[10, 20]].all()
    assert np.isfinite(_hist(res)).all() and np.isfinite(res.info['covariance']).all()
    np.testing.assert_array_equal(_hist(res)[10], _hist(res)[9])
    # equal to running without those samples at all
    keep = ~res.info['skipped']
    ref = b.run(y[keep], phi[keep])
    np.testing.assert_allclose(res.info['theta_final'], ref.info['theta_final'], atol=1e-12)
    # the step form skips too
    c = RecursiveLeastSquares(4, 3, forgetting=0.96, alpha=100.0)
    assert c.step(y[10], phi[10]).used is False and c.n_skipped == 1
    assert np.isfinite(c.theta).all()


def test_covariance_bounded_when_not_excited():
    """A regressor stuck in one direction for 5000 samples: textbook RLS winds up, ours not."""
    rng = np.random.default_rng(0)
    n_s = 5000
    phi = np.column_stack([np.ones(n_s), 0.3 * np.ones(n_s), np.zeros(n_s), np.ones(n_s)])
    phi += 1e-9 * rng.normal(size=phi.shape)
    y = phi @ np.ones((4, 3))
    alpha = 1e3
    ours = RecursiveLeastSquares(4, 3, forgetting=0.96, alpha=alpha)
    r = ours.run(y, phi)
    ev = np.linalg.eigvalsh(r.info['covariance'])
    assert ev.max() <= alpha * (1 + 1e-9) and ev.min() > 0
    # the step form keeps the bound at every sample
    ours2 = RecursiveLeastSquares(4, 3, forgetting=0.96, alpha=alpha)
    for p, q in zip(phi[:500], y[:500], strict=True):
        ours2.step(q, p)
        assert np.linalg.eigvalsh(ours2.P).max() <= alpha * (1 + 1e-9)
        np.testing.assert_array_equal(ours2.P, ours2.P.T)
    textbook = RecursiveLeastSquares(4, 3, forgetting=0.96, alpha=alpha, floor=0.0)
    for p, q in zip(phi[:500], y[:500], strict=True):
        textbook.step(q, p)
    assert np.linalg.eigvalsh(textbook.P).max() > 1e6 * alpha  # 0.96**-500 wind-up


@settings(max_examples=25, deadline=None)
@given(lam=st.floats(0.8, 1.0), seed=st.integers(0, 10_000))
def test_property_step_equals_run(lam, seed):
    phi, y, _ = _data(seed, n_samples=60)
    a = RecursiveLeastSquares(4, 3, forgetting=lam, alpha=1e2)
    b = RecursiveLeastSquares(4, 3, forgetting=lam, alpha=1e2)
    np.testing.assert_allclose(_stepped(a, phi, y), _hist(b.run(y, phi)), atol=1e-9)


@pytest.mark.parametrize("bad", [0.0, -0.5, 1.0001, float("nan"), 2])
def test_forgetting_outside_range_refused(bad):
    with pytest.raises(InputError, match=r"\(0, 1\]"):
        check_forgetting(bad)
    with pytest.raises(InputError):
        RecursiveLeastSquares(4, 1, forgetting=bad)


@pytest.mark.parametrize("lam", [1.0, 0.97])
def test_step_and_run_give_the_same_sequential_result(lam):
    """One convention: step's Step and run's SequentialResult carry the same state, std,
    a-priori innovation and log-likelihood, skipped samples included."""
    phi, y, _ = _data(11, n_samples=120, n=5, m=2)
    y[30] = np.nan
    a = RecursiveLeastSquares(5, 2, forgetting=lam, alpha=50.0, noise_std=0.01)
    b = RecursiveLeastSquares(5, 2, forgetting=lam, alpha=50.0, noise_std=0.01)
    steps = [a.step(q, p) for p, q in zip(phi, y, strict=True)]
    res = b.run(y, phi, predict=2 * phi)
    assert res.state_names[:3] == ("theta_0_0", "theta_0_1", "theta_1_0")
    np.testing.assert_allclose(np.array([s.state for s in steps]), res.state, atol=1e-10)
    np.testing.assert_allclose(np.array([s.std for s in steps]), res.std, rtol=1e-7)
    np.testing.assert_allclose(np.array([s.innovation for s in steps]), res.innovation,
                               atol=1e-10)
    np.testing.assert_allclose([s.loglik for s in steps], res.loglik, rtol=1e-9)
    assert not steps[30].used and np.isnan(res.loglik[30])
    # the predictor's variance is x.T P x / lambda scaled by the noise: x = 2 phi gives 4x
    used = ~res.info["skipped"]
    np.testing.assert_allclose(res.info["predict_var"][used],
                               4 * 0.01 ** 2 * res.info["prior_var"][used], rtol=1e-9)
    assert a.stats.n_fused == res.innovations["y"].n_fused == 119
    assert a.stats.nis_sum == pytest.approx(res.innovations["y"].nis_sum, rel=1e-9)


def test_nis_is_consistent_when_the_noise_is_right():
    """With the true noise level the mean NIS per degree of freedom is about 1 (chi-square
    with 3 x 2000 degrees of freedom: 1 +- 0.05 at 3 sigma)."""
    phi, y, _ = _data(12, n_samples=2000, noise=0.01)
    res = RecursiveLeastSquares(4, 3, forgetting=1.0, alpha=1e6, noise_std=0.01).run(y, phi)
    assert 0.95 < res.innovations["y"].mean_nis_per_dof < 1.05
    wrong = RecursiveLeastSquares(4, 3, forgetting=1.0, alpha=1e6, noise_std=0.003).run(y, phi)
    assert wrong.innovations["y"].mean_nis_per_dof > 5


@settings(max_examples=30, deadline=None)
@given(lam=st.floats(0.8, 1.0), seed=st.integers(0, 10_000),
       scale=st.floats(1e-3, 1e3), stuck=st.booleans())
def test_property_covariance_stays_symmetric_positive_definite(lam, seed, scale, stuck):
    """Both forms keep P symmetric positive definite, for any forgetting factor, regressor
    scale, and a regressor stuck in one direction (the wind-up case), and P <= alpha I."""
    rng = np.random.default_rng(seed)
    phi = scale * rng.normal(size=(80, 4))
    if stuck:
        phi[:, 1:] = 1e-9 * rng.normal(size=(80, 3))
    y = phi @ rng.normal(size=(4, 2))
    alpha = 1e2
    a = RecursiveLeastSquares(4, 2, forgetting=lam, alpha=alpha)
    b = RecursiveLeastSquares(4, 2, forgetting=lam, alpha=alpha)
    for p, q in zip(phi, y, strict=True):
        a.step(q, p)
        np.testing.assert_array_equal(a.P, a.P.T)
        ev = np.linalg.eigvalsh(a.P)
        assert ev.min() > 0 and ev.max() <= alpha * (1 + 1e-9)
    res = b.run(y, phi)
    P = res.info["covariance"]
    np.testing.assert_array_equal(P, P.T)
    ev = np.linalg.eigvalsh(P)
    assert ev.min() > 0 and ev.max() <= alpha * (1 + 1e-9)
    assert np.all(res.std > 0) and np.all(res.std <= np.sqrt(alpha) * (1 + 1e-9))
