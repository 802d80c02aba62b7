"""Weights, resampling and the genetic operators of the particle filters (log-weights).

Part of the particle-filter library (:mod:`aeromag._core.particles` re-exports every name):
normalisation (log-sum-exp: :func:`scipy.special.logsumexp`), effective sample size,
multinomial (= roulette) and systematic resampling, neighbour crossover and the Gaussian
mutation of low-weight particles.  Every function works over any leading batch axes
(``(..., N)`` weights, ``(..., N, n)`` particles).
"""

from __future__ import annotations

import numpy as np
from scipy.special import logsumexp

__all__ = [
    "crossover",
    "effective_sample_size",
    "logsumexp",
    "multinomial_resample",
    "mutate",
    "normalize_log_weights",
    "roulette_select",
    "systematic_resample",
]


# --------------------------------------------------------------------------- weights
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
def as_rng(seed: int | np.random.Generator | None) -> np.random.Generator:
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
