"""Where an online Tolles-Lawson fit had not (re-)converged: its residual scale and spans.

The a-priori residuals of :class:`aeromag.compensation.online.OnlineTL` give the running
residual scale (:func:`running_mean_square`, for ``mag_tl_std``) and a windowed NIS test
against the log's converged level (:func:`convergence_spans`); :class:`OnlineTLResult` is
what :meth:`OnlineTL.compensate` returns (docs/online.md, "Uncertainty and convergence").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._core.sequential import SequentialResult

__all__ = ["NIS_THRESHOLD", "OnlineTLResult", "UnconvergedSpan", "convergence_spans",
           "running_mean_square"]

#: Windowed a-priori NIS (mean over the window of the standardised squared residuals,
#: divided by its median over the log) above which the fit is taken as not converged: 50 is
#: a residual RMS seven times the log's typical one.  Measured (docs/online.md, seeds 0-2):
#: at most 7-15 after the warm-up on the simulator's flights without a jump, 27 000-58 000
#: right after a jump of the interference and above 50 for the next 350-450 s.
NIS_THRESHOLD = 50.0


def running_mean_square(z2: np.ndarray, forgetting: float,
                        state: tuple[float, float] | None = None
                        ) -> tuple[np.ndarray, tuple[float, float]]:
    """Exponentially weighted mean of ``z2`` over the memory ``1 / (1 - forgetting)``.

    Normalised by the sum of the weights (no start-up bias); NaN samples weigh nothing.

    Parameters
    ----------
    z2 : ndarray, shape (N,)
        Squared standardised residuals [nT^2].
    forgetting : float
        lambda (1: the plain mean so far).
    state : (float, float), optional
        Weighted sum and sum of weights carried from a previous call.

    Returns
    -------
    mean : ndarray, shape (N,)
        Mean after each sample (NaN before the first finite one) [nT^2].
    state : (float, float)
        To continue with the next piece.
    """
    from scipy.signal import lfilter

    ok = np.isfinite(z2)
    x = np.where(ok, z2, 0.0)
    w = ok.astype(np.float64)
    s0, w0 = state if state is not None else (0.0, 0.0)
    lam = float(forgetting)
    if not len(x):
        return x, (s0, w0)
    num, zn = lfilter([1.0], [1.0, -lam], x, zi=[lam * s0])
    den, zd = lfilter([1.0], [1.0, -lam], w, zi=[lam * w0])
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(den > 0, num / np.where(den > 0, den, 1.0), np.nan)
    return mean, (float(num[-1]), float(den[-1]))


@dataclass(frozen=True)
class UnconvergedSpan:
    """A stretch of output issued before the online fit (re-)converged.

    Attributes
    ----------
    start_s, end_s : float
        First and last time of the stretch [s].
    kind : str
        ``"warmup"`` (starts within the first memory of the log: the estimate had not yet
        converged) or ``"change"`` (the interference changed: the a-priori residuals rose).
    peak_nis_ratio : float
        Largest windowed NIS ratio in the stretch.
    n_samples : int
    """

    start_s: float
    end_s: float
    kind: str
    peak_nis_ratio: float
    n_samples: int

    def to_dict(self) -> dict[str, float | int | str]:
        """Plain dictionary for the JSON edge."""
        return dict(self.__dict__)


@dataclass
class OnlineTLResult:
    """What :meth:`OnlineTL.compensate` returns: the filter's run and the TL's own fields.

    The per-sample interference, its uncertainty and the convergence check.

    Attributes
    ----------
    fit : SequentialResult
        :meth:`OnlineTL.run` (coefficients, their std, the a-priori residuals).
    mag_tl : ndarray, shape (N,)
        Interference of each sample with the estimate before it [nT] (NaN where unusable).
    mag_tl_std : ndarray, shape (N,)
        Its predicted one-sigma uncertainty [nT] (see :meth:`OnlineTL.run`).
    nis_ratio : ndarray, shape (N,)
        Windowed a-priori NIS against the log's median level (see :func:`convergence_spans`).
    converged : ndarray of bool, shape (N,)
        False on the samples of :attr:`spans`.
    spans : list of UnconvergedSpan
    """

    fit: SequentialResult
    mag_tl: np.ndarray
    mag_tl_std: np.ndarray
    nis_ratio: np.ndarray
    converged: np.ndarray
    spans: list[UnconvergedSpan]

    @property
    def coef(self) -> np.ndarray:
        """Final coefficients [nT; eddy nT*s]."""
        return self.fit.info["coef"]

    @property
    def coef_history(self) -> np.ndarray:
        """Coefficients after each sample, shape (N, p)."""
        return self.fit.state

    @property
    def terms(self) -> tuple[str, ...]:
        """Term names."""
        return self.fit.state_names

    @property
    def skipped(self) -> np.ndarray:
        """Samples not used."""
        return self.fit.info["skipped"]


def convergence_spans(time_s: np.ndarray, z2: np.ndarray, forgetting: float, *,
                      window: int | None = None, threshold: float = NIS_THRESHOLD,
                      ) -> tuple[np.ndarray, np.ndarray, list[UnconvergedSpan]]:
    """Where the output was issued before the fit (re-)converged: a windowed NIS test.

    The a-priori residuals ``z2`` (standardised by the RLS prior variance) are averaged over
    a trailing window; the ratio of that mean to its median over the log is the windowed
    NIS against the log's converged level.  A sample whose ratio exceeds ``threshold`` is
    not converged, and so is every sample within one memory (``1 / (1 - forgetting)``
    samples) after it: the estimate needs about one memory to forget what it learnt before
    a change; two such stretches less than one memory apart are one.  The first memory of
    the log (the warm-up) is never converged: stretches starting there have ``kind``
    ``"warmup"``, the others ``"change"``.

    Parameters
    ----------
    time_s : ndarray, shape (N,)
        Times [s].
    z2 : ndarray, shape (N,)
        Squared standardised a-priori residuals (``SequentialResult.info["z2"]``), NaN
        where the sample was not used [nT^2].
    forgetting : float
        lambda of the fit.
    window : int, optional
        Trailing window [samples]; a tenth of the memory (at least 20) when omitted.
    threshold : float
        Ratio above which the fit is not converged (:data:`NIS_THRESHOLD`).

    Returns
    -------
    nis_ratio : ndarray, shape (N,)
    converged : ndarray of bool, shape (N,)
    spans : list of UnconvergedSpan
    """
    t = np.asarray(time_s, dtype=np.float64)
    z = np.asarray(z2, dtype=np.float64)
    n = len(z)
    memory = int(round(1.0 / (1.0 - forgetting))) if forgetting < 1 else n
    w = int(window) if window is not None else max(20, memory // 10)
    ok = np.isfinite(z)
    cs = np.r_[0.0, np.cumsum(np.where(ok, z, 0.0))]
    cn = np.r_[0, np.cumsum(ok)]
    lo = np.maximum(np.arange(n) + 1 - w, 0)
    cnt = cn[1:] - cn[lo]
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(cnt > 0, (cs[1:] - cs[lo]) / np.maximum(cnt, 1), np.nan)
    idx = np.flatnonzero(ok)
    after = idx[idx >= (idx[0] + min(memory, n) if idx.size else 0)]
    ref_rows = after if after.size > w else idx
    ref = float(np.nanmedian(mean[ref_rows])) if ref_rows.size else float("nan")
    if not (np.isfinite(ref) and ref > 0):
        return np.full(n, np.nan), np.ones(n, dtype=bool), []
    ratio = mean / ref
    bad = np.nan_to_num(ratio) > threshold
    # every sample within one memory after a bad one is not converged either
    last_bad = np.where(bad, np.arange(n), -(memory + 1))
    np.maximum.accumulate(last_bad, out=last_bad)
    unconv = np.arange(n) - last_bad <= memory
    # the warm-up: the first memory of the log is never converged
    first = int(idx[0]) if idx.size else 0
    unconv[:min(n, first + memory)] = True
    # two stretches less than one memory apart are one (the fit had not settled between)
    gaps = np.flatnonzero(np.diff(np.r_[0, unconv.astype(np.int8), 0]))
    for a, b in zip(gaps[1:-1:2], gaps[2::2], strict=True):
        if b - a <= memory:
            unconv[a:b] = True
    spans = []
    if unconv.any():
        edges = np.flatnonzero(np.diff(np.r_[0, unconv.astype(np.int8), 0]))
        for a, b in zip(edges[::2], edges[1::2], strict=True):
            kind = "warmup" if a <= first + memory else "change"
            spans.append(UnconvergedSpan(float(t[a]), float(t[b - 1]), kind,
                                         float(np.nanmax(ratio[a:b])), int(b - a)))
    return ratio, ~unconv, spans
