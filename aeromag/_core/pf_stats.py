"""The fault statistic S_k and its thresholds (fault-free runs or a calm stretch).

Part of the particle-filter library (:mod:`aeromag._core.particles` re-exports every name).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["Threshold", "threshold_from_calm", "threshold_from_runs", "window_sum"]


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
