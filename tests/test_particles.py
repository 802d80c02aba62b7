"""The particle-filter library: operators, log-weights, exactness, the growth model, the bank."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from aeromag._core.particles import (
    FilterBank,
    ParticleFilter,
    StateSpaceModel,
    crossover,
    effective_sample_size,
    logsumexp,
    multinomial_resample,
    mutate,
    normalize_log_weights,
    roulette_select,
    systematic_resample,
    threshold_from_calm,
    threshold_from_runs,
    window_sum,
)
from aeromag.detection.benchmark_models import growth_model, kalman_filter, linear_gaussian_model
from aeromag.synthetic.benchmarks import simulate_growth, simulate_linear_gaussian

W = np.array([0.30, 0.05, 0.15, 0.02, 0.08, 0.25, 0.10, 0.05])


# --------------------------------------------------------------------------- weights
def test_logsumexp_and_normalisation_survive_tiny_likelihoods():
    # R = 1e-5 and 0.2 residuals: log-likelihoods below -2000; plain exp() underflows to 0.
    ll = -0.5 * (np.array([0.20, 0.21, 0.22, 0.30]) ** 2) / 1e-5
    assert np.all(np.exp(ll) == 0.0)
    norm, tot = normalize_log_weights(ll)
    w = np.exp(norm)
    assert w.sum() == pytest.approx(1.0)
    assert w[0] > w[1] > w[2] > w[3]
    assert np.isfinite(tot) and tot == pytest.approx(ll[0] + np.log(np.sum(np.exp(ll - ll[0]))))
    assert logsumexp(np.array([-np.inf, -np.inf])) == -np.inf
    # a population that explains nothing stays uniform, never NaN
    norm2, tot2 = normalize_log_weights(np.array([-np.inf, np.nan, -np.inf]))
    np.testing.assert_allclose(np.exp(norm2), 1 / 3)
    assert tot2 == -np.inf


def test_effective_sample_size_hand_cases():
    assert effective_sample_size(np.zeros(50)) == pytest.approx(50.0)
    assert effective_sample_size(np.array([0.0, -np.inf, -np.inf])) == pytest.approx(1.0)
    w = np.array([0.5, 0.25, 0.25])
    assert effective_sample_size(np.log(w)) == pytest.approx(1 / np.sum(w**2))


# --------------------------------------------------------------------------- operators
def test_roulette_selection_frequencies_match_weights_chi_square():
    rng = np.random.default_rng(0)
    n = 200_000
    idx = roulette_select(np.log(W), rng, n=n)
    counts = np.bincount(idx, minlength=W.size)
    chi2, p = stats.chisquare(counts, n * W)
    assert p > 1e-3, (chi2, p)
    # and it is plain multinomial resampling
    assert roulette_select is multinomial_resample


def test_roulette_selection_rejects_wrong_weights():
    # The test above can fail: the same counts against other weights give a tiny p.
    rng = np.random.default_rng(1)
    idx = roulette_select(np.log(W), rng, n=200_000)
    counts = np.bincount(idx, minlength=W.size)
    other = np.roll(W, 1)
    assert stats.chisquare(counts, 200_000 * other)[1] < 1e-10


def test_systematic_resampling_copies_floor_or_ceil_of_n_w():
    rng = np.random.default_rng(2)
    n = 1000
    w = rng.dirichlet(np.ones(n))
    for _ in range(5):
        counts = np.bincount(systematic_resample(np.log(w), rng), minlength=n)
        assert counts.sum() == n
        assert np.all(counts >= np.floor(n * w) - 1e-9) and np.all(counts <= np.ceil(n * w))


def test_batched_resampling_uses_each_rows_weights():
    rng = np.random.default_rng(3)
    lw = np.log(np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]) + 1e-300)
    idx = multinomial_resample(lw, rng)
    assert np.all(idx[0] == 0) and np.all(idx[1] == 2)
    idx = systematic_resample(lw, rng)
    assert np.all(idx[0] == 0) and np.all(idx[1] == 2)


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 41), d=st.integers(1, 3), p_c=st.floats(0.0, 1.0),
       blend=st.floats(0.0, 1.0), seed=st.integers(0, 2**31))
def test_crossover_preserves_each_pairs_sum(n, d, p_c, blend, seed):
    rng = np.random.default_rng(seed)
    x = rng.normal(scale=10.0, size=(n, d))
    y, crossed = crossover(x, rng, p_c, blend)
    npair = n // 2
    np.testing.assert_allclose(y[0:2 * npair:2] + y[1:2 * npair:2],
                               x[0:2 * npair:2] + x[1:2 * npair:2], rtol=1e-12, atol=1e-9)
    if n % 2:
        np.testing.assert_array_equal(y[-1], x[-1])
        assert not crossed[-1]
    np.testing.assert_array_equal(y[~crossed], x[~crossed])
    # a crossed pair is the blend of its parents
    a, b = x[0:2 * npair:2], x[1:2 * npair:2]
    m = crossed[0:2 * npair:2]
    np.testing.assert_allclose(y[0:2 * npair:2][m], (blend * a + (1 - blend) * b)[m],
                               rtol=1e-12, atol=1e-9)


def test_crossover_rate_is_p_c():
    rng = np.random.default_rng(4)
    _, crossed = crossover(np.zeros((20_000, 1)), rng, 0.3)
    assert crossed[::2].mean() == pytest.approx(0.3, abs=0.02)


def test_mutation_touches_only_low_weight_particles_at_rate_p_m():
    rng = np.random.default_rng(5)
    n = 20_000
    x = np.zeros((n, 2))
    w = rng.dirichlet(np.ones(n))
    low = w < 1.0 / n
    y, mutated = mutate(x, np.log(w), rng, p_m=0.2, scale=[1.0, 3.0])
    assert not np.any(mutated & ~low)
    np.testing.assert_array_equal(y[~mutated], x[~mutated])
    assert np.all(np.any(y[mutated] != 0.0, axis=1))
    rate = mutated[low].mean()
    se = np.sqrt(0.2 * 0.8 / low.sum())
    assert abs(rate - 0.2) < 4 * se
    # the mutation is Gaussian with the given scale per component
    np.testing.assert_allclose(y[mutated].std(axis=0), [1.0, 3.0], rtol=0.08)


def test_operators_reject_bad_probabilities():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError):
        crossover(np.zeros((4, 1)), rng, 1.5)
    with pytest.raises(ValueError):
        mutate(np.zeros((4, 1)), np.zeros(4), rng, -0.1)


# --------------------------------------------------------------------------- statistics
def test_window_sum_hand_derived():
    v = np.array([1.0, 2.0, np.nan, 3.0, 4.0, np.inf, 5.0, 6.0, 7.0])
    s = window_sum(v, 3)
    expected = [np.nan, np.nan, np.nan, 6.0, 9.0, np.inf, np.inf, np.inf, 18.0]
    np.testing.assert_array_equal(s, expected)
    np.testing.assert_array_equal(window_sum(np.arange(5.0), 1), np.arange(5.0))
    two = window_sum(np.vstack([np.arange(4.0), np.ones(4)]), 2)
    np.testing.assert_array_equal(two[1], [np.nan, 2, 2, 2])


def test_threshold_from_runs_uses_the_runs_maxima():
    rng = np.random.default_rng(6)
    s = rng.normal(size=(400, 300))
    th = threshold_from_runs(s, 99.0)
    mx = s.max(axis=1)
    assert th.value == pytest.approx(np.percentile(mx, 99.0))
    assert th.false_alarm_rate == pytest.approx(np.mean(mx > th.value))
    assert 0.0 < th.false_alarm_rate <= 0.011
    # a percentile over all samples would alarm on most runs
    per_sample = np.percentile(s, 99.0)
    assert np.mean(mx > per_sample) > 0.9
    th2 = threshold_from_calm(s[0], percentile=100.0, factor=1.0, margin=0.5)
    assert th2.value == pytest.approx(s[0].max() + 0.5) and th2.false_alarm_rate == 0.0


# --------------------------------------------------------------------------- exactness
F = np.array([[1.0, 0.1], [0.0, 0.95]])
H = np.array([[1.0, 0.0]])
Q = np.diag([0.01, 0.05])
R = np.array([[0.25]])
X0, P0 = np.zeros(2), np.eye(2)


@pytest.mark.parametrize("proposal", ["bootstrap", "unscented"])
def test_pf_converges_to_the_kalman_filter_on_a_linear_gaussian_model(proposal):
    _, y = simulate_linear_gaussian(F, H, Q, R, X0, P0, 40, seed=3)
    km, kc, kl = kalman_filter(y, F, H, Q, R, X0, P0)
    md = linear_gaussian_model(F, H, Q, R, X0, P0)
    err = {}
    for n in (100, 10_000):
        res = ParticleFilter(md, n, proposal=proposal, seed=11).run(y)
        sd = np.sqrt(np.diagonal(kc, axis1=1, axis2=2))
        err[n] = np.abs(res.state - km) / sd
        if n == 10_000:
            # Monte-Carlo error of a weighted mean is about sd / sqrt(ESS) (ESS >= N/4 here);
            # resampling adds a few times that: stay within 6 of it.
            assert np.max(err[n]) < 6.0 / np.sqrt(n / 4)
            np.testing.assert_allclose(res.std, sd, rtol=0.1)
            assert abs(np.nansum(res.loglik, axis=-1) - kl.sum()) < 0.5
            np.testing.assert_allclose(res.loglik, kl, atol=0.15)
    assert np.sqrt(np.mean(err[10_000] ** 2)) < 0.3 * np.sqrt(np.mean(err[100] ** 2))


def test_batched_filter_matches_kalman_on_every_problem():
    _, y = simulate_linear_gaussian(F, H, Q, R, X0, P0, 30, seed=4)
    km, kc, kl = kalman_filter(y, F, H, Q, R, X0, P0)
    sd = np.sqrt(np.diagonal(kc, axis1=1, axis2=2))
    ys = np.stack([y, y + 1.0, y])           # three problems at once
    res = ParticleFilter(linear_gaussian_model(F, H, Q, R, X0, P0), 4000, batch=3,
                         seed=1).run(ys)
    assert res.state.shape == (3, 30, 2) and res.info["stat"].shape == (3, 30)
    assert np.max(np.abs(res.state[0] - km) / sd) < 0.4
    assert np.max(np.abs(res.state[2] - km) / sd) < 0.4
    assert abs(np.nansum(res.loglik, axis=-1)[0] - kl.sum()) < 1.0
    km1, _, kl1 = kalman_filter(y + 1.0, F, H, Q, R, X0, P0)    # each row its own data
    assert np.max(np.abs(res.state[1] - km1) / sd) < 0.4
    assert abs(np.nansum(res.loglik, axis=-1)[1] - kl1.sum()) < 1.0


def test_same_seed_same_result_and_missing_measurements_predict_only():
    md = linear_gaussian_model(F, H, Q, R, X0, P0)
    _, y = simulate_linear_gaussian(F, H, Q, R, X0, P0, 30, seed=5)
    y[10:13] = np.nan
    a = ParticleFilter(md, 300, scheme="genetic", seed=7).run(y)
    b = ParticleFilter(md, 300, scheme="genetic", seed=7).run(y)
    np.testing.assert_array_equal(a.state, b.state)
    np.testing.assert_array_equal(a.info["stat"], b.info["stat"])
    assert np.all(np.isnan(a.loglik[10:13])) and np.all(np.isfinite(a.loglik[:10]))
    assert not np.any(a.info["renewed"][10:13])
    assert np.all(np.isfinite(a.state))
    # S_k skips the missing steps: its window holds the last M measured steps
    assert a.info["stat"][12] == a.info["stat"][9]


def test_step_matches_run():
    md = growth_model()
    _, y = simulate_growth(T=20, seed=2)
    res = ParticleFilter(md, 200, window=5, seed=3).run(y)
    pf = ParticleFilter(md, 200, window=5, seed=3)
    steps, stats = [], []
    for v in y:
        steps.append(pf.step(v))
        stats.append(pf.last_stat)
    np.testing.assert_allclose([s.state[0] for s in steps], res.state[:, 0])
    np.testing.assert_allclose([s.std[0] for s in steps], res.std[:, 0])
    np.testing.assert_allclose([s.loglik for s in steps], res.loglik)
    np.testing.assert_allclose(stats, res.info["stat"], equal_nan=True)
    assert all(s.used and s.innovation.size == 0 for s in steps)
    assert res.state_names == ("x0",) and res.innovations["y"].n_fused == len(y)


# --------------------------------------------------------------------------- growth model
def test_growth_model_rmse_bootstrap_and_genetic_on_the_same_runs():
    md = growth_model(Q=10.0, R=1.0)
    xs, ys = simulate_growth(T=100, Q=10.0, R=1.0, seed=2024, n_runs=60)
    boot = ParticleFilter(md, 100, scheme="multinomial", batch=60, seed=1).run(ys)
    gen = ParticleFilter(md, 100, scheme="genetic", batch=60, seed=1).run(ys)
    rmse_b = np.sqrt(np.mean((boot.state[..., 0] - xs) ** 2, axis=1))
    rmse_g = np.sqrt(np.mean((gen.state[..., 0] - xs) ** 2, axis=1))
    assert 3.0 <= rmse_b.mean() <= 8.0, rmse_b.mean()
    assert rmse_g.mean() <= 1.1 * rmse_b.mean(), (rmse_g.mean(), rmse_b.mean())


def test_growth_model_unscented_proposal_runs_and_tracks():
    md = growth_model()
    xs, ys = simulate_growth(T=100, seed=9, n_runs=20)
    res = ParticleFilter(md, 100, proposal="unscented", batch=20, seed=2).run(ys)
    rmse = np.sqrt(np.mean((res.state[..., 0] - xs) ** 2, axis=1))
    assert np.all(np.isfinite(rmse)) and 2.0 < rmse.mean() < 9.0


# --------------------------------------------------------------------------- bank
def _biased_model(bias: float) -> StateSpaceModel:
    md = linear_gaussian_model(F, H, Q, R, X0, 0.01 * P0)
    base = md.loglik
    return StateSpaceModel(f=md.f, Q=md.Q, x0=md.x0, P0=md.P0,
                           loglik=lambda y, x, k: base(y - bias, x, k))


def test_bank_isolates_the_hypothesis_that_made_the_data():
    _, y = simulate_linear_gaussian(F, H, Q, R, X0, 0.01 * P0, 80, seed=8)
    y = y + 2.0                                   # the sensor reads 2 too high
    bank = FilterBank({"nominal": _biased_model(0.0), "bias+2": _biased_model(2.0),
                       "bias-2": _biased_model(-2.0)}, n_particles=500, window=10, seed=3)
    res = bank.run(y)
    assert res.stat.shape == (3, 80)
    assert np.all(res.most_likely[:9] == -1)
    # the bias is a constant offset of a random-walk-like state: the nominal filter absorbs
    # it after a while, but not in the first windows
    assert res.most_likely_name(9) == "bias+2"
    assert res.results["bias-2"].info["stat"][9] > res.results["bias+2"].info["stat"][9]


def test_filter_rejects_bad_settings():
    md = growth_model()
    with pytest.raises(ValueError):
        ParticleFilter(md, 100, proposal="optimal")
    with pytest.raises(ValueError):
        ParticleFilter(md, 100, scheme="stratified")
    with pytest.raises(ValueError):
        ParticleFilter(md, 1)
    with pytest.raises(ValueError):
        ParticleFilter(StateSpaceModel(f=md.f, Q=md.Q, loglik=md.loglik, x0=md.x0, P0=md.P0),
                       10, proposal="unscented")


def test_batched_unscented_rows_without_measurement_only_predict():
    _, y = simulate_linear_gaussian(F, H, Q, R, X0, P0, 20, seed=6)
    km, _, _ = kalman_filter(y, F, H, Q, R, X0, P0)
    ys = np.stack([y, y])
    ys[1, 5:] = np.nan                     # the second problem loses its sensor at step 6
    res = ParticleFilter(linear_gaussian_model(F, H, Q, R, X0, P0), 4000, batch=2,
                         proposal="unscented", seed=2).run(ys)
    assert np.all(np.isnan(res.loglik[1, 5:])) and np.all(np.isfinite(res.loglik[0]))
    # prediction only: the mean follows F (velocity decays, position integrates it)
    pred = res.state[1, 4].copy()
    for _ in range(15):
        pred = F @ pred
    np.testing.assert_allclose(res.state[1, -1], pred, atol=0.05)
    np.testing.assert_allclose(res.state[0, -1], km[-1], atol=0.1)


def test_gumbel_threshold_extrapolates_the_maxima():
    rng = np.random.default_rng(12)
    # runs whose maxima follow a Gumbel law (loc 5, scale 2): the fitted 99th percentile
    # alarms on about 1 % of new runs
    s = np.concatenate([rng.gumbel(5.0, 2.0, size=(400, 1)), np.zeros((400, 50))], axis=1)
    gum = threshold_from_runs(s, 99.0, fit="gumbel")
    assert gum.info["model_false_alarm_rate"] == pytest.approx(0.01)
    assert gum.value == pytest.approx(5.0 - 2.0 * np.log(-np.log(0.99)), abs=1.0)
    new = rng.gumbel(5.0, 2.0, size=20_000)
    assert np.mean(new > gum.value) == pytest.approx(0.01, abs=0.005)
    # maxima of Gaussian noise approach the Gumbel law from below: the fit is conservative
    g = rng.normal(size=(300, 400))
    th = threshold_from_runs(g, 99.0, fit="gumbel")
    far = np.mean(rng.normal(size=(2000, 400)).max(axis=1) > th.value)
    assert far <= 0.012
    with pytest.raises(ValueError):
        threshold_from_runs(s, 100.0, fit="gumbel")
