"""Particle filters for any state-space model given as vectorised Python callables.

The model (:class:`StateSpaceModel`) is

    x_k = f(x_{k-1}, k, u_k) + w_k,   w_k ~ N(0, Q)          (or any sampler ``sample``)
    y_k ~ p(y_k | x_k),               log p given by ``loglik``

with, for the unscented proposal, a Gaussian measurement ``y_k = h(x_k, k) + v_k``,
``v_k ~ N(0, R)``.  Every callable is vectorised over particles: it receives states of shape
``(K, n)`` (or ``(B, K, n)`` when the filter runs ``B`` independent problems at once, e.g. many
Monte-Carlo runs), the measurement ``y`` as ``(m,)`` (``(B, 1, m)``) and the control ``u`` as
given (``(B, 1, p)`` in batch mode), and returns ``(K, n)``, ``(K,)`` or ``(K, m)``.

What the filter does at each step (:meth:`ParticleFilter.step`):

1. proposal: ``"bootstrap"`` samples the transition; ``"unscented"`` makes one unscented
   Kalman update per particle from the prior ``N(f(x_prev), Q)`` of that particle and
   samples the Gaussian posterior, which moves particles toward the high-likelihood region
   (the unscented version of Doucet's local approximation of the optimal proposal, exact for
   a linear-Gaussian model; van der Merwe et al. 2000 carry a covariance per particle
   instead, which makes the proposal broader than the transition and the weights degenerate
   on models with small Q); the transform is :mod:`aeromag._core.unscented`;
2. log-weights are updated (``loglik + log p(x|x_prev) - log q(x)``), always in logs with
   log-sum-exp: with a measurement variance of 1e-5 plain weights underflow to zero;
3. the per-step log-likelihood ``log L_k = log sum_i w_{k-1,i} p_i`` (``p_i`` the incremental
   weight) is recorded; with uniform previous weights and the bootstrap proposal it is the
   log of the mean particle likelihood of methods M5;
4. when the effective sample size falls below ``ess_threshold * N`` the population is
   renewed by ``"multinomial"`` or ``"systematic"`` resampling or by the ``"genetic"``
   replacement: roulette selection (:func:`roulette_select`), neighbour crossover
   (:func:`crossover`) and Gaussian mutation of the offspring of low-weight particles
   (:func:`mutate`).

The fault statistic is ``S_k = sum of -log L_j over the last M steps`` (:func:`window_sum`);
a threshold comes from fault-free runs (:func:`threshold_from_runs`, a percentile of the runs'
maxima, with the per-run false-alarm rate it implies) or from a calm stretch of one record
(:func:`threshold_from_calm`).  :class:`FilterBank` runs one filter per fault hypothesis and
reports the most likely one (smallest ``S_k``).

Everything is reproducible from ``seed`` (an int or a :class:`numpy.random.Generator`).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .unscented import (
    angle_mean_fn,
    angle_residual_fn,
    robust_sqrt,
    sigma_points,
    unscented_transform,
)

log = logging.getLogger(__name__)

__all__ = [
    "BankResult",
    "FilterBank",
    "PFResult",
    "ParticleFilter",
    "StateSpaceModel",
    "StepResult",
    "Threshold",
    "crossover",
    "effective_sample_size",
    "logsumexp",
    "multinomial_resample",
    "mutate",
    "normalize_log_weights",
    "roulette_select",
    "systematic_resample",
    "threshold_from_calm",
    "threshold_from_runs",
    "window_sum",
]

_LOG2PI = float(np.log(2.0 * np.pi))


# --------------------------------------------------------------------------- weights
def logsumexp(a: np.ndarray, axis: int = -1) -> np.ndarray:
    """``log(sum(exp(a)))`` along ``axis`` without overflow or underflow.

    Parameters
    ----------
    a : ndarray
        Log-values (``-inf`` allowed).
    axis : int
        Axis to reduce.

    Returns
    -------
    ndarray
        The reduced log-sum; ``-inf`` where every entry is ``-inf``.
    """
    a = np.asarray(a, dtype=np.float64)
    m = np.max(a, axis=axis, keepdims=True)
    m_safe = np.where(np.isfinite(m), m, 0.0)
    with np.errstate(divide="ignore"):
        out = np.log(np.sum(np.exp(a - m_safe), axis=axis, keepdims=True)) + m_safe
    return np.squeeze(out, axis=axis)


def normalize_log_weights(logw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Normalise log-weights over the last axis.

    Parameters
    ----------
    logw : ndarray, shape (..., N)
        Unnormalised log-weights.

    Returns
    -------
    logw_norm : ndarray, shape (..., N)
        Log-weights whose exponentials sum to one; uniform where every weight was ``-inf``
        or NaN (a population that explains nothing is kept, not turned into NaN).
    log_total : ndarray, shape (...)
        Log of the sum of the unnormalised weights (``-inf`` in the degenerate case).
    """
    logw = np.asarray(logw, dtype=np.float64)
    logw = np.where(np.isnan(logw), -np.inf, logw)
    tot = logsumexp(logw, axis=-1)
    bad = ~np.isfinite(tot)
    norm = logw - np.where(bad, 0.0, tot)[..., None]
    if np.any(bad):
        n = logw.shape[-1]
        norm = np.where(bad[..., None], -np.log(n), norm)
    return norm, tot


def effective_sample_size(logw: np.ndarray) -> np.ndarray:
    """Effective sample size ``1 / sum(w_i^2)`` of normalised weights.

    Parameters
    ----------
    logw : ndarray, shape (..., N)
        Log-weights (normalised or not).

    Returns
    -------
    ndarray, shape (...)
        Between 1 and N.
    """
    norm, _ = normalize_log_weights(logw)
    return np.exp(-logsumexp(2.0 * norm, axis=-1))


# --------------------------------------------------------------------------- resampling
def _as_rng(seed: int | np.random.Generator | None) -> np.random.Generator:
    return seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)


def _inverse_cdf(logw: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Indices ``i`` with ``cdf[i-1] <= u < cdf[i]`` for sorted ``u`` in [0, 1), per batch."""
    norm, _ = normalize_log_weights(logw)
    cdf = np.cumsum(np.exp(norm), axis=-1)
    cdf[..., -1] = 1.0
    n = logw.shape[-1]
    if cdf.ndim == 1:
        return np.minimum(np.searchsorted(cdf, u, side="right"), n - 1)
    flat_cdf = cdf.reshape(-1, n) + np.arange(cdf.size // n)[:, None]
    flat_u = u.reshape(-1, u.shape[-1]) + np.arange(cdf.size // n)[:, None]
    idx = np.searchsorted(flat_cdf.ravel(), flat_u.ravel(), side="right")
    idx = idx.reshape(flat_u.shape) - n * np.arange(cdf.size // n)[:, None]
    return np.clip(idx, 0, n - 1).reshape(u.shape)


def multinomial_resample(logw: np.ndarray, rng: np.random.Generator,
                         n: int | None = None) -> np.ndarray:
    """Multinomial resampling: ``n`` independent draws of indices with probability ``w_i``.

    Parameters
    ----------
    logw : ndarray, shape (..., N)
        Log-weights.
    rng : numpy.random.Generator
        Random source.
    n : int, optional
        Number of draws (default ``N``).

    Returns
    -------
    ndarray of int, shape (..., n)
        Parent indices, sorted ascending along the last axis.
    """
    logw = np.asarray(logw, dtype=np.float64)
    n = logw.shape[-1] if n is None else int(n)
    u = np.sort(rng.random(logw.shape[:-1] + (n,)), axis=-1)
    return _inverse_cdf(logw, u)


#: Roulette-wheel selection of the genetic replacement is multinomial resampling.
roulette_select = multinomial_resample


def systematic_resample(logw: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Systematic resampling: one uniform offset, ``N`` evenly spaced pointers.

    Parameters
    ----------
    logw : ndarray, shape (..., N)
        Log-weights.
    rng : numpy.random.Generator
        Random source.

    Returns
    -------
    ndarray of int, shape (..., N)
        Parent indices, sorted ascending (particle ``i`` is copied ``floor(N w_i)`` or
        ``ceil(N w_i)`` times).
    """
    logw = np.asarray(logw, dtype=np.float64)
    n = logw.shape[-1]
    u = (rng.random(logw.shape[:-1] + (1,)) + np.arange(n)) / n
    return _inverse_cdf(logw, u)


def crossover(x: np.ndarray, rng: np.random.Generator, p_c: float = 0.3,
              blend: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Neighbour crossover: blend the pairs (0, 1), (2, 3), ... each with probability ``p_c``.

    A crossed pair becomes ``a' = b_ * a + (1 - b_) * b`` and ``b' = b_ * b + (1 - b_) * a``
    with blend ``b_`` (methods M5 uses ``b_ = p_c``), so each pair's sum is preserved.  An
    odd last particle is left alone.

    Parameters
    ----------
    x : ndarray, shape (..., N, n)
        Particles.
    rng : numpy.random.Generator
        Random source.
    p_c : float
        Probability that a pair is crossed, in [0, 1].
    blend : float, optional
        Blend coefficient in [0, 1] (default ``p_c``).

    Returns
    -------
    x_new : ndarray, shape (..., N, n)
        Particles after crossover (a new array).
    crossed : ndarray of bool, shape (..., N)
        True for both members of every crossed pair.
    """
    if not 0.0 <= p_c <= 1.0:
        raise ValueError("crossover probability p_c must be in [0, 1]")
    b = p_c if blend is None else float(blend)
    if not 0.0 <= b <= 1.0:
        raise ValueError("crossover blend must be in [0, 1]")
    x = np.asarray(x, dtype=np.float64)
    out = x.copy()
    npair = x.shape[-2] // 2
    crossed = np.zeros(x.shape[:-1], dtype=bool)
    if npair == 0:
        return out, crossed
    pick = rng.random(x.shape[:-2] + (npair,)) < p_c
    a = x[..., 0:2 * npair:2, :]
    c = x[..., 1:2 * npair:2, :]
    m = pick[..., None]
    out[..., 0:2 * npair:2, :] = np.where(m, b * a + (1.0 - b) * c, a)
    out[..., 1:2 * npair:2, :] = np.where(m, b * c + (1.0 - b) * a, c)
    crossed[..., 0:2 * npair:2] = pick
    crossed[..., 1:2 * npair:2] = pick
    return out, crossed


def mutate(x: np.ndarray, logw: np.ndarray, rng: np.random.Generator, p_m: float = 0.1,
           scale: np.ndarray | float = 1.0, low_weight: float = 1.0,
           ) -> tuple[np.ndarray, np.ndarray]:
    """Gaussian mutation of low-weight particles.

    A particle is *low-weight* when its normalised weight is below ``low_weight / N`` (by
    default below the uniform weight); each low-weight particle is mutated with probability
    ``p_m`` by adding ``N(0, scale**2)`` noise per component.  Others are never touched.

    Parameters
    ----------
    x : ndarray, shape (..., N, n)
        Particles.
    logw : ndarray, shape (..., N)
        Their log-weights (fitness).
    rng : numpy.random.Generator
        Random source.
    p_m : float
        Mutation probability of a low-weight particle, in [0, 1].
    scale : float or ndarray broadcastable to (..., 1, n)
        Standard deviation of the mutation, in the state's units.
    low_weight : float
        Low-weight threshold as a multiple of the uniform weight ``1/N``.

    Returns
    -------
    x_new : ndarray, shape (..., N, n)
        Particles after mutation (a new array).
    mutated : ndarray of bool, shape (..., N)
        Which particles were mutated.
    """
    if not 0.0 <= p_m <= 1.0:
        raise ValueError("mutation probability p_m must be in [0, 1]")
    x = np.asarray(x, dtype=np.float64)
    n = x.shape[-2]
    norm, _ = normalize_log_weights(logw)
    low = norm < np.log(low_weight / n)
    mutated = low & (rng.random(low.shape) < p_m)
    noise = rng.standard_normal(x.shape) * np.asarray(scale, dtype=np.float64)
    return np.where(mutated[..., None], x + noise, x), mutated


# --------------------------------------------------------------------------- statistics
def window_sum(values: np.ndarray, window: int) -> np.ndarray:
    """Sum of the last ``window`` finite values, at every position (``S_k`` of methods M5).

    NaN entries (steps without a measurement) are skipped: at such a position the sum of the
    last ``window`` finite values before it is repeated.  Until ``window`` finite values have
    been seen the result is NaN.  An infinite value makes the sums that contain it infinite.

    Parameters
    ----------
    values : ndarray, shape (..., T)
        Per-step values (e.g. ``-log L_k``).
    window : int
        Number of values summed, ``M >= 1``.

    Returns
    -------
    ndarray, shape (..., T)
    """
    if int(window) < 1:
        raise ValueError("window must be at least 1")
    m = int(window)
    v = np.asarray(values, dtype=np.float64)
    shape = v.shape
    v2 = v.reshape(-1, shape[-1])
    out = np.full(v2.shape, np.nan)
    for r in range(v2.shape[0]):
        row = v2[r]
        ok = ~np.isnan(row)
        vals = row[ok]
        if vals.size < m:
            continue
        inf = np.isinf(vals)
        fin = np.where(inf, 0.0, vals)
        cs = np.concatenate([[0.0], np.cumsum(fin)])
        ci = np.concatenate([[0], np.cumsum(inf)])
        s = cs[m:] - cs[:-m]
        s = np.where(ci[m:] - ci[:-m] > 0, np.inf, s)
        count = np.cumsum(ok)            # finite values seen up to and including each step
        have = count >= m
        out[r, have] = s[count[have] - m]
    return out.reshape(shape)


@dataclass
class Threshold:
    """A detection threshold and what it implies.

    Attributes
    ----------
    value : float
        Threshold on ``S_k`` (alarm when ``S_k > value``).
    percentile : float
        Percentile it was taken at.
    method : str
        ``"runs"`` (percentile of fault-free runs' maxima) or ``"calm"``.
    false_alarm_rate : float
        ``"runs"``: fraction of the fault-free runs whose maximum exceeds ``value`` (the
        per-run false-alarm rate); ``"calm"``: fraction of the calm stretch's samples above it.
    n : int
        Number of runs (or calm samples) it was estimated from.
    info : dict
        Extra figures (JSON-ready).
    """

    value: float
    percentile: float
    method: str
    false_alarm_rate: float
    n: int
    info: dict[str, Any] = field(default_factory=dict)


def threshold_from_runs(stats: np.ndarray, percentile: float = 99.0,
                        fit: str = "empirical") -> Threshold:
    """Threshold from fault-free runs: a percentile of the runs' maxima of ``S_k``.

    A percentile over all samples would give far more false alarms per run, since a run
    alarms as soon as any of its samples is above the threshold.

    Parameters
    ----------
    stats : ndarray, shape (runs, T)
        ``S_k`` of each fault-free run (NaN ignored).
    percentile : float
        Percentile of the maxima, in (0, 100] (below 100 for ``fit="gumbel"``).
    fit : {"empirical", "gumbel"}
        ``"empirical"``: the sample percentile of the maxima (at 99 with 200 runs, the
        second largest); ``"gumbel"``: the percentile of a Gumbel distribution fitted to the
        maxima (the extreme-value law of a maximum), which extrapolates the tail instead of
        resting on its one or two largest values.

    Returns
    -------
    Threshold
        ``false_alarm_rate`` is the fraction of these runs that would alarm (about
        ``1 - percentile/100``); an independent set of runs measures it without bias.
        ``info["model_false_alarm_rate"]`` is the fitted law's exceedance probability.
    """
    s = np.asarray(stats, dtype=np.float64)
    if s.ndim != 2 or s.shape[0] < 2:
        raise ValueError("stats must have shape (runs, T) with at least 2 runs")
    mx = np.nanmax(np.where(np.isnan(s), -np.inf, s), axis=1)
    mx = mx[np.isfinite(mx) | (mx > 0)]
    info: dict[str, Any] = {"max_median": float(np.median(mx)), "max_max": float(mx.max()),
                            "fit": fit}
    if fit == "empirical":
        value = float(np.percentile(mx, percentile))
    elif fit == "gumbel":
        from scipy import stats as sps

        if not 0.0 < percentile < 100.0:
            raise ValueError("a Gumbel threshold needs a percentile below 100")
        loc, scale = sps.gumbel_r.fit(mx)
        value = float(sps.gumbel_r.ppf(percentile / 100.0, loc, scale))
        info.update(gumbel_loc=float(loc), gumbel_scale=float(scale),
                    model_false_alarm_rate=1.0 - percentile / 100.0)
    else:
        raise ValueError(f"fit must be 'empirical' or 'gumbel', not {fit!r}")
    far = float(np.mean(mx > value))
    return Threshold(value=value, percentile=float(percentile), method="runs",
                     false_alarm_rate=far, n=int(mx.size), info=info)


def threshold_from_calm(stat: np.ndarray, calm: np.ndarray | None = None,
                        percentile: float = 100.0, factor: float = 1.0,
                        margin: float = 0.0) -> Threshold:
    """Threshold from a calm (fault-free) stretch of one record.

    ``value = factor * percentile(S_k over the calm samples) + margin``.  With the default
    ``percentile = 100`` (the calm maximum) the factor and margin are the safety that a
    single stretch needs in place of many fault-free runs.

    Parameters
    ----------
    stat : ndarray, shape (T,)
        ``S_k`` of the record.
    calm : ndarray of bool, shape (T,), optional
        Calm samples (default all).
    percentile : float
        Percentile of the calm ``S_k`` values, in (0, 100].
    factor, margin : float
        Scale and offset applied to that percentile (``S_k`` units).

    Returns
    -------
    Threshold
        ``false_alarm_rate`` is the fraction of calm samples above the threshold.

    Raises
    ------
    ValueError
        The calm stretch holds no finite ``S_k``.
    """
    s = np.asarray(stat, dtype=np.float64)
    sel = np.ones(s.shape, dtype=bool) if calm is None else np.asarray(calm, dtype=bool)
    vals = s[sel & np.isfinite(s)]
    if vals.size == 0:
        raise ValueError("no finite S_k in the calm stretch (is it shorter than the window?)")
    base = float(np.percentile(vals, percentile))
    value = factor * base + margin
    return Threshold(value=float(value), percentile=float(percentile), method="calm",
                     false_alarm_rate=float(np.mean(vals > value)), n=int(vals.size),
                     info={"calm_percentile_value": base, "factor": float(factor),
                           "margin": float(margin), "calm_median": float(np.median(vals))})


# --------------------------------------------------------------------------- model
ModelFn = Callable[..., np.ndarray]


@dataclass
class StateSpaceModel:
    """A state-space model as callables vectorised over particles.

    Attributes
    ----------
    f : callable
        ``f(x, k, u)`` -> mean of ``x_k`` given ``x_{k-1} = x``; ``x`` of shape ``(..., K, n)``.
    Q : ndarray, shape (n, n)
        Covariance of the additive Gaussian process noise.
    loglik : callable
        ``loglik(y, x, k)`` -> ``log p(y | x)``, shape ``(..., K)``; ``y`` always keeps its
        last axis ``m`` (``(m,)``, or ``(B, 1, m)`` in batch mode), so index it ``y[..., j]``.
    x0 : ndarray, shape (n,)
        Mean of the initial state (before the first step).
    P0 : ndarray, shape (n, n)
        Covariance of the initial state.
    h : callable, optional
        ``h(x, k)`` -> mean measurement, ``(..., K, m)`` (unscented proposal only).
    R : ndarray, shape (m, m), optional
        Measurement noise covariance (unscented proposal only).
    angle_y : sequence of int
        Measurement components that are angles, rad (wrapped residuals, circular means).
    sample : callable, optional
        ``sample(x, k, u, rng)`` drawing ``x_k`` (replaces ``f`` + Gaussian noise for the
        bootstrap proposal; the genetic mutation and the unscented proposal still use ``f``
        and ``Q``).
    sample_x0 : callable, optional
        ``sample_x0(rng, shape)`` drawing initial particles of shape ``shape + (n,)``
        (default Gaussian ``N(x0, P0)``).
    """

    f: ModelFn
    Q: np.ndarray
    loglik: ModelFn
    x0: np.ndarray
    P0: np.ndarray
    h: ModelFn | None = None
    R: np.ndarray | None = None
    angle_y: Sequence[int] = ()
    sample: ModelFn | None = None
    sample_x0: ModelFn | None = None

    def __post_init__(self) -> None:
        self.x0 = np.atleast_1d(np.asarray(self.x0, dtype=np.float64))
        n = self.x0.size
        self.Q = np.asarray(self.Q, dtype=np.float64).reshape(n, n)
        self.P0 = np.asarray(self.P0, dtype=np.float64).reshape(n, n)
        if self.R is not None:
            self.R = np.atleast_2d(np.asarray(self.R, dtype=np.float64))

    @property
    def n(self) -> int:
        """State dimension."""
        return int(self.x0.size)


def _gauss_logpdf(d: np.ndarray, L: np.ndarray) -> np.ndarray:
    """log N(d; 0, L L^T) over the last axis, batched (``L`` lower-triangular).

    ``L`` of shape (n, n) is shared by every row of ``d`` (one inverse); a state of one
    component is a division (no batched solve: it dominates the cost of small filters)."""
    n = d.shape[-1]
    if n == 1:
        sd = L[..., 0, 0]
        z2 = (d[..., 0] / sd) ** 2
        logdet = 2.0 * np.log(np.abs(sd))
    elif L.ndim == 2:
        z = d @ np.linalg.inv(L).T
        z2 = np.sum(z * z, axis=-1)
        logdet = 2.0 * float(np.sum(np.log(np.abs(np.diag(L)))))
    else:
        z = np.linalg.solve(L, d[..., None])[..., 0]
        z2 = np.sum(z * z, axis=-1)
        logdet = 2.0 * np.sum(np.log(np.abs(np.diagonal(L, axis1=-2, axis2=-1))), axis=-1)
    return -0.5 * (z2 + logdet + n * _LOG2PI)


# --------------------------------------------------------------------------- filter
@dataclass
class StepResult:
    """One step of :class:`ParticleFilter` (arrays get a leading batch axis in batch mode).

    Attributes
    ----------
    mean, std : ndarray, shape (n,)
        Weighted posterior mean and standard deviation of the state.
    loglik : float or ndarray
        ``log L_k`` (NaN when the step had no measurement).
    stat : float or ndarray
        ``S_k`` over the last ``window`` steps (NaN until the window is full).
    ess : float or ndarray
        Effective sample size after weighting.
    renewed : bool or ndarray
        Whether the population was resampled (or genetically replaced).
    """

    mean: np.ndarray
    std: np.ndarray
    loglik: Any
    stat: Any
    ess: Any
    renewed: Any


@dataclass
class PFResult:
    """Output of :meth:`ParticleFilter.run` (arrays get a leading batch axis in batch mode).

    Attributes
    ----------
    mean, std : ndarray, shape (T, n)
        Weighted posterior mean and standard deviation per step.
    loglik : ndarray, shape (T,)
        ``log L_k`` per step (NaN without a measurement).
    stat : ndarray, shape (T,)
        ``S_k``: sum of ``-log L_j`` over the last ``window`` measured steps.
    ess : ndarray, shape (T,)
        Effective sample size after weighting.
    renewed : ndarray of bool, shape (T,)
        Steps at which the population was renewed.
    window : int
        ``M``.
    n_particles : int
        ``N``.
    proposal, scheme : str
        Proposal and renewal scheme used.
    elapsed_s : float
        Wall time of the run, s.
    """

    mean: np.ndarray
    std: np.ndarray
    loglik: np.ndarray
    stat: np.ndarray
    ess: np.ndarray
    renewed: np.ndarray
    window: int
    n_particles: int
    proposal: str
    scheme: str
    elapsed_s: float

    @property
    def total_loglik(self) -> np.ndarray:
        """Sum of ``log L_k`` over the measured steps (the log marginal likelihood)."""
        return np.nansum(self.loglik, axis=-1)


_PROPOSALS = ("bootstrap", "unscented")
_SCHEMES = ("systematic", "multinomial", "genetic")


class ParticleFilter:
    """Sequential importance resampling filter with bootstrap or unscented proposal.

    Parameters
    ----------
    model : StateSpaceModel
        The model.
    n_particles : int
        Number of particles ``N``.
    proposal : {"bootstrap", "unscented"}
        Proposal distribution (``"unscented"`` needs ``model.h`` and ``model.R``).
    scheme : {"systematic", "multinomial", "genetic"}
        How the population is renewed when the effective sample size is low.
    ess_threshold : float
        Renew when ``ESS < ess_threshold * N``; 1.0 (default) renews at every step, as the
        bootstrap filter of Gordon et al. and methods M5 do; 0 never renews.
    window : int
        ``M`` of the statistic ``S_k``.
    p_c, blend : float
        Crossover probability and blend (genetic scheme; blend defaults to ``p_c``).
    p_m : float
        Mutation probability of a low-weight particle's offspring (genetic scheme).
    mutation_scale : float
        Mutation standard deviation as a multiple of the population's weighted standard
        deviation per state component (genetic scheme).
    low_weight : float
        Low-weight threshold as a multiple of ``1/N`` (genetic scheme).
    batch : int, optional
        Run this many independent problems at once (measurements of shape ``(B, m)``).
    seed : int or numpy.random.Generator, optional
        Random source.
    ut_alpha, ut_beta, ut_kappa : float
        Unscented-transform scaling (unscented proposal).
    """

    def __init__(self, model: StateSpaceModel, n_particles: int = 500, *,
                 proposal: str = "bootstrap", scheme: str = "systematic",
                 ess_threshold: float = 1.0, window: int = 10, p_c: float = 0.3,
                 blend: float | None = None, p_m: float = 0.1, mutation_scale: float = 0.5,
                 low_weight: float = 1.0, batch: int | None = None,
                 seed: int | np.random.Generator | None = None, ut_alpha: float = 1.0,
                 ut_beta: float = 2.0, ut_kappa: float = 0.0) -> None:
        if proposal not in _PROPOSALS:
            raise ValueError(f"proposal must be one of {_PROPOSALS}, not {proposal!r}")
        if scheme not in _SCHEMES:
            raise ValueError(f"scheme must be one of {_SCHEMES}, not {scheme!r}")
        if int(n_particles) < 2:
            raise ValueError("n_particles must be at least 2")
        if int(window) < 1:
            raise ValueError("window must be at least 1")
        if proposal == "unscented" and (model.h is None or model.R is None):
            raise ValueError("the unscented proposal needs model.h and model.R")
        self.model = model
        self.n_particles = int(n_particles)
        self.proposal = proposal
        self.scheme = scheme
        self.ess_threshold = float(ess_threshold)
        self.window = int(window)
        self.p_c, self.blend, self.p_m = float(p_c), blend, float(p_m)
        self.mutation_scale = float(mutation_scale)
        self.low_weight = float(low_weight)
        self.batched = batch is not None
        self.batch = int(batch) if batch is not None else 1
        self.rng = _as_rng(seed)
        self.ut = (float(ut_alpha), float(ut_beta), float(ut_kappa))
        self._LQ = robust_sqrt(model.Q)
        if model.R is not None:
            m = model.R.shape[0]
            self._y_mean = angle_mean_fn(model.angle_y) if len(model.angle_y) else None
            self._y_res = angle_residual_fn(model.angle_y) if len(model.angle_y) else None
            self._m = m
        self.reset()

    # ------------------------------------------------------------------ helpers
    def _call(self, fn: ModelFn, x: np.ndarray, *args: Any) -> np.ndarray:
        """Call a model function on (B, K, n) particles with batch-aware arguments."""
        if self.batched:
            args = tuple(a if a is None or np.ndim(a) == 0 or isinstance(a, (int, float))
                         else np.asarray(a)[:, None, ...] for a in args)
            return np.asarray(fn(x, *args))
        return np.asarray(fn(x[0], *args))[None]

    def reset(self) -> None:
        """Start again from ``k = 0``: a fresh initial population (drawn at the next step)
        and an empty window of the statistic."""
        shape = (self.batch, self.n_particles)
        self.x = None
        self.logw = np.full(shape, -np.log(self.n_particles))
        self.k = 0
        self._buf = np.full((self.batch, self.window), np.nan)
        self._nbuf = np.zeros(self.batch, dtype=np.int64)

    def _draw_initial(self) -> None:
        shape = (self.batch, self.n_particles)
        md = self.model
        if md.sample_x0 is not None:
            self.x = np.asarray(md.sample_x0(self.rng, shape), dtype=np.float64)
        else:
            L0 = robust_sqrt(md.P0)
            self.x = md.x0 + self.rng.standard_normal(shape + (md.n,)) @ L0.T

    def _propose(self, y: np.ndarray | None, u: Any, k: int,
                 have: np.ndarray | None = None) -> np.ndarray:
        """Move the particles to step k; return the log-weight increment.

        ``have`` flags the batch rows that have a measurement (the others are moved by the
        transition alone, whatever the proposal)."""
        md = self.model
        B, N, n = self.x.shape
        if self.proposal == "bootstrap" or y is None:
            if md.sample is not None:
                self.x = self._call(lambda x, u_: md.sample(x, k, u_, self.rng), self.x, u)
            else:
                mean = self._call(lambda x, u_: md.f(x, k, u_), self.x, u)
                self.x = mean + self.rng.standard_normal(mean.shape) @ self._LQ.T
            if y is None:
                return np.zeros((B, N))
            return self._call(lambda x, y_: md.loglik(y_, x, k), self.x, y)
        # ---- unscented proposal: one unscented Kalman update per particle, conditioned on
        # the particle: prior N(f(x_prev), Q), measurement through the unscented transform.
        a, b, kap = self.ut
        xp = self._call(lambda x, u_: md.f(x, k, u_), self.x, u)            # (B, N, n)
        Pp = np.broadcast_to(md.Q, (B, N, n, n))

        def h_sig(X: np.ndarray) -> np.ndarray:
            s = X.shape
            out = self._call(lambda x: md.h(x, k), X.reshape(B, -1, n))
            return out.reshape(s[:-1] + (self._m,))

        sig = sigma_points(xp, Pp, a, b, kap, sqrt=np.broadcast_to(self._LQ, (B, N, n, n)))
        yp, Pyy, Pxy = unscented_transform(h_sig, xp, Pp, a, b, kap, noise_cov=md.R,
                                           mean_fn=self._y_mean, residual_fn=self._y_res,
                                           sigma=sig)
        yb = np.asarray(y, dtype=np.float64)
        yb = yb[:, None, :] if self.batched else yb[None, None, :]
        innov = self._y_res(yb, yp) if self._y_res else yb - yp
        if self._m == 1:
            K = Pxy / Pyy                                                  # (B,N,n,1)
        else:
            K = np.swapaxes(np.linalg.solve(Pyy, np.swapaxes(Pxy, -1, -2)), -1, -2)
        xh = xp + np.einsum("...ij,...j->...i", K, innov)
        Ph = Pp - np.einsum("...ij,...jk,...lk->...il", K, Pyy, K)
        Lh = np.sqrt(np.maximum(Ph, 0.0)) if n == 1 else robust_sqrt(Ph)
        z = self.rng.standard_normal(xh.shape)
        xn = xh + np.einsum("...ij,...j->...i", Lh, z)
        if have is not None and not np.all(have):
            prior = xp + np.einsum("ij,...j->...i", self._LQ, self.rng.standard_normal(xp.shape))
            xn = np.where(have[:, None, None], xn, prior)
        logq = _gauss_logpdf(xn - xh, Lh)
        logp = _gauss_logpdf(xn - xp, self._LQ)
        self.x = xn
        ll = self._call(lambda x, y_: md.loglik(y_, x, k), self.x, y)
        return ll + logp - logq

    def _renew(self, need: np.ndarray) -> None:
        """Resample (or genetically replace) the batches flagged in ``need``."""
        if not np.any(need):
            return
        rows = np.flatnonzero(need)
        x, lw = self.x[rows], self.logw[rows]
        if self.scheme == "systematic":
            idx = systematic_resample(lw, self.rng)
        else:
            idx = multinomial_resample(lw, self.rng)
        newx = np.take_along_axis(x, idx[..., None], axis=1)
        if self.scheme == "genetic":
            parent_lw = np.take_along_axis(lw, idx, axis=1)
            newx, _ = crossover(newx, self.rng, self.p_c, self.blend)
            w = np.exp(normalize_log_weights(lw)[0])[..., None]
            mu = np.sum(w * x, axis=1, keepdims=True)
            sd = np.sqrt(np.sum(w * (x - mu) ** 2, axis=1, keepdims=True))
            newx, _ = mutate(newx, parent_lw, self.rng, self.p_m, self.mutation_scale * sd,
                             self.low_weight)
        self.x[rows] = newx
        self.logw[rows] = -np.log(self.n_particles)

    # ------------------------------------------------------------------ public
    def step(self, y: np.ndarray | float | None, u: Any = None) -> StepResult:
        """Advance one step with measurement ``y`` (None or NaN: predict only) and control ``u``.

        Parameters
        ----------
        y : array_like or None
            Measurement, shape ``(m,)`` (``(B, m)`` in batch mode); NaN rows mean no
            measurement for that problem.
        u : any
            Control passed to ``f`` (``(B, p)`` in batch mode).

        Returns
        -------
        StepResult
        """
        if self.x is None:
            self._draw_initial()
        self.k += 1
        k = self.k
        B = self.batch
        have = np.ones(B, dtype=bool)
        if y is not None:
            ya = np.asarray(y, dtype=np.float64)
            ya2 = ya.reshape(B, -1)
            have = ~np.any(np.isnan(ya2), axis=1)
            if not np.any(have):
                y = None
            else:
                # Missing rows get a harmless value; their weights are not updated.
                fill = np.where(np.isnan(ya2), 0.0, ya2)
                y = fill if self.batched else fill[0]
        else:
            have[:] = False
        inc = self._propose(y, u, k, have)
        inc = np.where(np.isnan(inc), -np.inf, inc)
        inc = np.where(have[:, None], inc, 0.0)
        # self.logw is normalised at the end of every step, so the log of the new total is
        # log L_k = log sum_i w_{k-1,i} p_i.
        lw = self.logw + inc
        norm, tot = normalize_log_weights(lw)
        ll = np.where(have, tot, np.nan)
        self.logw = norm
        w1 = np.exp(norm)
        w = w1[..., None]
        mean = np.sum(w * self.x, axis=1)
        std = np.sqrt(np.maximum(np.sum(w * (self.x - mean[:, None]) ** 2, axis=1), 0.0))
        ess = 1.0 / np.sum(w1 * w1, axis=-1)
        # S_k ring buffer over measured steps.
        hb = np.flatnonzero(have)
        self._buf[hb, self._nbuf[hb] % self.window] = -ll[hb]
        self._nbuf[hb] += 1
        full = self._nbuf >= self.window
        with np.errstate(invalid="ignore"):
            stat = np.where(full, np.sum(self._buf, axis=1), np.nan)
        need = ess < self.ess_threshold * self.n_particles
        if self.ess_threshold >= 1.0:
            need = np.ones(B, dtype=bool)
        need &= have
        self._renew(need)
        if self.batched:
            return StepResult(mean, std, ll, stat, ess, need)
        return StepResult(mean[0], std[0], float(ll[0]), float(stat[0]), float(ess[0]),
                          bool(need[0]))

    def run(self, ys: np.ndarray, us: Any = None) -> PFResult:
        """Run over a sequence of measurements from a fresh initial population.

        Parameters
        ----------
        ys : ndarray, shape (T, m) or (T,) (``(B, T, m)`` in batch mode)
            Measurements; NaN rows are prediction-only steps.
        us : ndarray, optional
            Controls, shape ``(T, p)`` (``(B, T, p)``), or None.

        Returns
        -------
        PFResult
        """
        t0 = time.perf_counter()
        self.reset()
        ya = np.asarray(ys, dtype=np.float64)
        if self.batched:
            ya = ya.reshape(ya.shape[0], ya.shape[1], -1)
            T = ya.shape[1]
        else:
            ya = ya.reshape(ya.shape[0], -1)
            T = ya.shape[0]
        ua = None if us is None else np.asarray(us, dtype=np.float64)
        n = self.model.n
        mean = np.empty((self.batch, T, n))
        std = np.empty((self.batch, T, n))
        ll = np.empty((self.batch, T))
        ess = np.empty((self.batch, T))
        ren = np.empty((self.batch, T), dtype=bool)
        for t in range(T):
            y = ya[:, t] if self.batched else ya[t]
            u = None if ua is None else (ua[:, t] if self.batched else ua[t])
            r = self.step(y, u)
            mean[:, t], std[:, t] = np.atleast_2d(r.mean), np.atleast_2d(r.std)
            ll[:, t], ess[:, t], ren[:, t] = r.loglik, r.ess, r.renewed
        stat = window_sum(-ll, self.window)
        sq = (lambda a: a) if self.batched else (lambda a: a[0])
        return PFResult(mean=sq(mean), std=sq(std), loglik=sq(ll), stat=sq(stat), ess=sq(ess),
                        renewed=sq(ren), window=self.window, n_particles=self.n_particles,
                        proposal=self.proposal, scheme=self.scheme,
                        elapsed_s=time.perf_counter() - t0)


# --------------------------------------------------------------------------- bank
@dataclass
class BankResult:
    """Output of :meth:`FilterBank.run`.

    Attributes
    ----------
    names : list of str
        Hypotheses, in order.
    results : dict
        ``{name: PFResult}``.
    stat : ndarray, shape (H, T) (``(H, B, T)`` in batch mode)
        ``S_k`` of each hypothesis.
    most_likely : ndarray of int, shape (T,) (``(B, T)``)
        Index of the hypothesis with the smallest ``S_k`` (-1 until all windows are full).
    """

    names: list[str]
    results: dict[str, PFResult]
    stat: np.ndarray
    most_likely: np.ndarray

    def most_likely_name(self, t: int = -1) -> str | list[str]:
        """Name(s) of the most likely hypothesis at step ``t``."""
        idx = self.most_likely[..., t]
        if np.ndim(idx) == 0:
            return self.names[int(idx)] if idx >= 0 else ""
        return [self.names[int(i)] if i >= 0 else "" for i in idx]


class FilterBank:
    """One particle filter per hypothesis, run on the same data; the smallest ``S_k`` wins.

    Parameters
    ----------
    models : mapping of str to StateSpaceModel
        Hypothesis name -> its model (e.g. ``"nominal"``, ``"sensor_bias"``, ...).
    seed : int or numpy.random.Generator, optional
        Random source (each filter gets its own child stream).
    **kwargs
        Passed to every :class:`ParticleFilter`.
    """

    def __init__(self, models: Mapping[str, StateSpaceModel], *,
                 seed: int | np.random.Generator | None = None, **kwargs: Any) -> None:
        if not models:
            raise ValueError("a filter bank needs at least one hypothesis")
        rng = _as_rng(seed)
        seeds = rng.spawn(len(models)) if hasattr(rng, "spawn") else [
            np.random.default_rng(s) for s in rng.integers(0, 2**63, len(models))]
        self.names = list(models)
        self.filters = {name: ParticleFilter(md, seed=s, **kwargs)
                        for (name, md), s in zip(models.items(), seeds, strict=True)}

    def run(self, ys: np.ndarray, us: Any = None) -> BankResult:
        """Run every hypothesis' filter on ``ys``.

        Parameters
        ----------
        ys, us : ndarray
            As :meth:`ParticleFilter.run`.

        Returns
        -------
        BankResult
        """
        res = {name: f.run(ys, us) for name, f in self.filters.items()}
        stat = np.stack([res[nm].stat for nm in self.names])
        filled = np.all(np.isfinite(stat), axis=0)
        best = np.argmin(np.where(np.isnan(stat), np.inf, stat), axis=0)
        best = np.where(filled, best, -1)
        return BankResult(names=self.names, results=res, stat=stat, most_likely=best)
