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
   Kalman update per particle from its prior ``N(f(x_prev), Q)`` (:mod:`.unscented`) and
   samples that posterior, moving particles toward the high-likelihood region (exact for a
   linear-Gaussian model; a covariance carried per particle, as van der Merwe et al. 2000,
   made the proposal broader than the transition and the weights degenerate);
2. log-weights ``loglik + log p(x|x_prev) - log q(x)``, always with log-sum-exp;
3. ``log L_k = log sum_i w_{k-1,i} p_i`` is recorded (with uniform previous weights and the
   bootstrap proposal: the log of the mean particle likelihood of methods M5);
4. when ``ESS < ess_threshold * N`` the population is renewed: ``"multinomial"``,
   ``"systematic"`` or ``"genetic"`` (:mod:`.pf_operators`: roulette selection, neighbour
   crossover, Gaussian mutation of the offspring of low-weight particles).

``S_k`` (the sum of ``-log L_j`` over the last ``M`` steps) and its thresholds are in
:mod:`.pf_stats`; :class:`FilterBank` runs one filter per hypothesis and reports the most
likely (smallest ``S_k``).  Every name of both modules is re-exported here.

Everything is reproducible from ``seed`` (an int or a :class:`numpy.random.Generator`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .pf_operators import (
    as_rng,
    crossover,
    effective_sample_size,
    logsumexp,
    multinomial_resample,
    mutate,
    normalize_log_weights,
    roulette_select,
    systematic_resample,
)
from .pf_stats import Threshold, threshold_from_calm, threshold_from_runs, window_sum
from .sequential import InnovationStats, SequentialResult, Step
from .unscented import (
    angle_mean_fn,
    angle_residual_fn,
    robust_sqrt,
    sigma_points,
    unscented_transform,
)

__all__ = [
    "BankResult",
    "FilterBank",
    "ParticleFilter",
    "StateSpaceModel",
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
_PROPOSALS = ("bootstrap", "unscented")
#: The particle filter has no single innovation: ``Step.innovation`` is empty.
_NO_INNOVATION = np.empty(0)
_SCHEMES = ("systematic", "multinomial", "genetic")


class ParticleFilter:
    """Sequential importance resampling filter with bootstrap or unscented proposal.

    The package's sequential-filter convention (:mod:`aeromag._core.sequential`):
    :meth:`step` returns a :class:`Step` (posterior mean and std, log-likelihood, whether
    a measurement was used; no innovation: ``innovation`` is empty) and keeps the
    filter's own per-step figures in :attr:`last_stat`, :attr:`last_ess` and
    :attr:`last_renewed`; :meth:`run` returns a :class:`SequentialResult` with those per
    step in ``info`` (``stat``, ``ess``, ``renewed``).  In batch mode every array gets a
    leading batch axis.

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
        self.rng = as_rng(seed)
        self.ut = (float(ut_alpha), float(ut_beta), float(ut_kappa))
        self._LQ = robust_sqrt(model.Q)
        ang = tuple(model.angle_y)
        self._y_mean = angle_mean_fn(ang) if ang else None
        self._y_res = angle_residual_fn(ang) if ang else None
        self._m = None if model.R is None else model.R.shape[0]
        self.state_names = tuple(f"x{i}" for i in range(model.n))
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
        self.last_stat: Any = float("nan")
        self.last_ess: Any = float("nan")
        self.last_renewed: Any = False

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
    def step(self, y: np.ndarray | float | None, u: Any = None) -> Step:
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
        Step
            ``state`` and ``std``: weighted posterior mean and standard deviation;
            ``loglik``: ``log L_k`` (NaN without a measurement); ``used``: whether a
            measurement updated the weights; ``innovation`` empty.  ``S_k`` (NaN until the
            window is full), the effective sample size after weighting and whether the
            population was renewed are :attr:`last_stat`, :attr:`last_ess`,
            :attr:`last_renewed`.
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
            self.last_stat, self.last_ess, self.last_renewed = stat, ess, need
            return Step(mean, std, np.empty((B, 0)), ll, have)
        self.last_stat, self.last_ess = float(stat[0]), float(ess[0])
        self.last_renewed = bool(need[0])
        return Step(mean[0], std[0], _NO_INNOVATION, float(ll[0]), bool(have[0]))

    def run(self, ys: np.ndarray, us: Any = None) -> SequentialResult:
        """Run over a sequence of measurements from a fresh initial population.

        Parameters
        ----------
        ys : ndarray, shape (T, m) or (T,) (``(B, T, m)`` in batch mode)
            Measurements; NaN rows are prediction-only steps.
        us : ndarray, optional
            Controls, shape ``(T, p)`` (``(B, T, p)``), or None.

        Returns
        -------
        SequentialResult
            ``time_s`` the step index; ``state``, ``std`` (T, n): weighted posterior mean
            and standard deviation; ``loglik`` (T,): ``log L_k`` (NaN without a
            measurement; its ``nansum`` is the log marginal likelihood); ``innovation``
            None; ``innovations["y"]``: measured and missing steps; ``info``: ``stat``
            (``S_k``, the sum of ``-log L_j`` over the last ``window`` measured steps),
            ``ess``, ``renewed`` per step, ``window``, ``n_particles``, ``proposal``,
            ``scheme``, ``elapsed_s`` (wall time of the run, s).  Batch mode: a leading
            batch axis on every per-step array.
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
            mean[:, t], std[:, t] = np.atleast_2d(r.state), np.atleast_2d(r.std)
            ll[:, t], ess[:, t], ren[:, t] = r.loglik, self.last_ess, self.last_renewed
        stat = window_sum(-ll, self.window)
        sq = (lambda a: a) if self.batched else (lambda a: a[0])
        measured = int(np.isfinite(ll).sum())
        stats = InnovationStats(dof=int(ya.shape[-1]), n_fused=measured,
                                n_gated=int(ll.size - measured))
        return SequentialResult(
            time_s=np.arange(T, dtype=np.float64), state=sq(mean), std=sq(std),
            state_names=self.state_names, loglik=sq(ll), innovation=None,
            innovations={"y": stats},
            info={"stat": sq(stat), "ess": sq(ess), "renewed": sq(ren), "window": self.window,
                  "n_particles": self.n_particles, "proposal": self.proposal,
                  "scheme": self.scheme, "elapsed_s": time.perf_counter() - t0})


# --------------------------------------------------------------------------- bank
@dataclass
class BankResult:
    """Output of :meth:`FilterBank.run`.

    Attributes
    ----------
    names : list of str
        Hypotheses, in order.
    results : dict
        ``{name: SequentialResult}`` (:meth:`ParticleFilter.run` of each hypothesis).
    stat : ndarray, shape (H, T) (``(H, B, T)`` in batch mode)
        ``S_k`` of each hypothesis.
    most_likely : ndarray of int, shape (T,) (``(B, T)``)
        Index of the hypothesis with the smallest ``S_k`` (-1 until all windows are full).
    """

    names: list[str]
    results: dict[str, SequentialResult]
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
        rng = as_rng(seed)
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
        stat = np.stack([res[nm].info["stat"] for nm in self.names])
        filled = np.all(np.isfinite(stat), axis=0)
        best = np.argmin(np.where(np.isnan(stat), np.inf, stat), axis=0)
        best = np.where(filled, best, -1)
        return BankResult(names=self.names, results=res, stat=stat, most_likely=best)
