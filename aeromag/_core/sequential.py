"""The one convention of the sequential estimators: RLS, online TL, compass, UKF, particle filter.

Every sequential filter of the package has the same shape (``shared/architecture.md``)::

    flt = SomeFilter(params...)          # parameters only
    step = flt.step(y, u=None)           # one sample in: a :class:`Step` out
    res = flt.run(ys, us=None)           # arrays in: one :class:`SequentialResult` out

The filters that follow it: :class:`~aeromag._core.rls.RecursiveLeastSquares`,
:class:`~aeromag.compensation.online.OnlineTL`,
:class:`~aeromag.compass.calibration.CompassCalibration`,
:class:`~aeromag.nav.ukf.UnscentedKalmanFilter`, :class:`~aeromag.nav.filter.NavFilter` (its
``run`` takes the whole log as one :class:`~aeromag.nav.NavInputs`, its ``step`` one sample of
each sensor as a mapping) and :class:`~aeromag._core.particles.ParticleFilter`
(``benchmarks/structure_bars.py`` checks that every class with ``step`` and ``run`` returns these
two types).  A :class:`~aeromag._core.particles.FilterBank` is not a filter but one per
hypothesis: its ``BankResult`` holds their :class:`SequentialResult` objects.

Domain results (a compass calibration, a navigation run, a detection run) hold a
:class:`SequentialResult` and add their own fields; they do not re-declare the state, its
uncertainty or the innovations.  This is what MagNav.jl's ``FILTres`` does for all its filters.

Consistency is reported the same way by every filter: per measurement source, an
:class:`InnovationStats` (samples fused, down-weighted, rejected, and the normalised innovation
squared, NIS).  A consistent filter has a mean NIS per degree of freedom near 1.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["InnovationStats", "SequentialResult", "Step"]


@dataclass
class InnovationStats:
    """Innovation statistics of one measurement source.

    Attributes
    ----------
    dof : int
        Dimension of one measurement.
    n_fused : int
        Measurements that updated the state (down-weighted ones included).
    n_downweighted : int
        Fused measurements whose weight a robust update reduced (Huber, Student-t...).
    n_rejected : int
        Measurements refused as gross faults (not fused).
    n_gated : int
        Measurements not used because a validity condition failed (quality, tilt, range
        limits, field strength...): never offered to the update.
    nis_sum : float
        Sum of the normalised innovation squared over the fused measurements.
    """

    dof: int
    n_fused: int = 0
    n_downweighted: int = 0
    n_rejected: int = 0
    n_gated: int = 0
    nis_sum: float = 0.0

    @property
    def mean_nis(self) -> float | None:
        """Mean NIS of the fused measurements (about ``dof`` when consistent); None if none."""
        return self.nis_sum / self.n_fused if self.n_fused else None

    @property
    def mean_nis_per_dof(self) -> float | None:
        """Mean NIS divided by the measurement dimension (about 1 when consistent)."""
        m = self.mean_nis
        return None if m is None else m / self.dof

    def as_dict(self) -> dict[str, float | int | None]:
        """Plain dictionary for the JSON edge."""
        return {"dof": self.dof, "n_fused": self.n_fused,
                "n_downweighted": self.n_downweighted, "n_rejected": self.n_rejected,
                "n_gated": self.n_gated, "mean_nis": self.mean_nis,
                "mean_nis_per_dof": self.mean_nis_per_dof}


@dataclass(frozen=True)
class Step:
    """What ``step(y, u=None)`` returns, for every sequential filter.

    Attributes
    ----------
    state : ndarray, shape (n,)
        State estimate after this sample (units of the filter's ``state_names``).
    std : ndarray, shape (n,)
        One-sigma uncertainty of each state component, same units.
    innovation : ndarray, shape (m,)
        Prior innovation of the measurement(s) of this sample (empty when none).
    loglik : float
        Log-likelihood of this sample's measurement under the prior (NaN when none).
    used : bool
        Whether a measurement updated the state at this sample.
    """

    state: np.ndarray
    std: np.ndarray
    innovation: np.ndarray
    loglik: float = float("nan")
    used: bool = True


@dataclass
class SequentialResult:
    """What ``run(ys, us=None)`` returns, for every sequential filter.

    Attributes
    ----------
    time_s : ndarray, shape (N,)
        Time of each output sample, s (the sample index when the caller gave no time).
    state : ndarray, shape (N, n)
        State estimate after each sample.
    std : ndarray, shape (N, n)
        One-sigma uncertainty of each state component after each sample.
    state_names : tuple of str
        Name (with unit, e.g. ``"vn_mps"``) of each state component.
    loglik : ndarray, shape (N,)
        Log-likelihood of each sample's measurement under the prior (NaN where none).
    innovation : ndarray, shape (N, m) or None
        Prior innovation per sample, when the filter has one fixed measurement.
    innovations : dict of str to InnovationStats
        Consistency per measurement source.
    info : dict
        Settings and anything else the filter reports (noise levels used, warnings...).
    """

    time_s: np.ndarray
    state: np.ndarray
    std: np.ndarray
    state_names: tuple[str, ...]
    loglik: np.ndarray
    innovation: np.ndarray | None = None
    innovations: dict[str, InnovationStats] = field(default_factory=dict)
    info: dict = field(default_factory=dict)

    def column(self, name: str) -> np.ndarray:
        """The estimate of one named state component over time."""
        return self.state[:, self.state_names.index(name)]

    def std_of(self, name: str) -> np.ndarray:
        """The one-sigma uncertainty of one named state component over time."""
        return self.std[:, self.state_names.index(name)]
