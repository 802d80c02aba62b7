"""Generic sequential estimation: the numerics under the domain filters, for your own models.

Every filter here follows the one sequential convention of :mod:`aeromag._core.sequential`:
construct with parameters, ``step(y, u=None)`` returns a :class:`Step`, ``run(ys, us=None)``
returns a :class:`SequentialResult`.  The domain packages (compensation, compass, nav,
detection) wrap these for magnetometer logs; use them directly for any other state-space model::

    from aeromag.estimation import ParticleFilter, StateSpaceModel
"""

from __future__ import annotations

from aeromag._core.particles import FilterBank, ParticleFilter, StateSpaceModel, threshold_from_runs
from aeromag._core.rls import RecursiveLeastSquares
from aeromag._core.sequential import InnovationStats, SequentialResult, Step
from aeromag._core.unscented import sigma_points, unscented_transform
from aeromag.nav import UnscentedKalmanFilter

__all__ = [
    "FilterBank",
    "InnovationStats",
    "ParticleFilter",
    "RecursiveLeastSquares",
    "SequentialResult",
    "StateSpaceModel",
    "Step",
    "UnscentedKalmanFilter",
    "sigma_points",
    "threshold_from_runs",
    "unscented_transform",
]
