"""Navigation without GNSS: the 12-state unscented Kalman filter and its sensor models.

``NavFilter`` fuses a MEMS IMU with optical flow, a rangefinder, a barometer, the gravity
and magnetic-north vectors and (when used) GNSS, following the package's sequential
convention of :mod:`aeromag._core.sequential` (construct with parameters, ``step(y, u)``
-> ``Step``, ``run`` -> ``SequentialResult``).  ``UnscentedKalmanFilter``
is the generic filter it is built on.  See ``docs/navigate.md``.
"""

from .config import NavConfig
from .filter import ALL_SENSORS, NavFilter, NavInputs, magnetic_reference_from_log
from .pipeline import NAV_COLUMNS, NavigationResult, navigate
from .report import NavReport
from .ukf import DivergenceError, UnscentedKalmanFilter

__all__ = ["ALL_SENSORS", "NAV_COLUMNS", "DivergenceError", "NavConfig", "NavFilter",
           "NavInputs", "NavReport", "NavigationResult", "UnscentedKalmanFilter",
           "magnetic_reference_from_log", "navigate"]
