"""Deprecated: the heading detector and the combination of detectors moved.

They are :mod:`aeromag.detection.heading` and :mod:`aeromag.detection.combine`; this path works
for one release.
"""

from __future__ import annotations

import warnings

import numpy as np

from .detection.combine import combine_alarms as _combine
from .detection.heading import (  # noqa: F401
    DEFAULT_CALM_SECONDS,
    MIN_CALM_SAMPLES,
    SIGMA_FLOOR_DEG,
    CalmWindow,
    HeadingResult,
    calm_mask,
    heading_columns_available,
    heading_detector,
    heading_difference,
    mag_heading_from_flux,
    parse_calm_window,
)

warnings.warn("aeromag.detect is deprecated: use aeromag.detection.heading and "
              "aeromag.detection.combine", DeprecationWarning, stacklevel=2)


def combine_alarms(track_alarm: np.ndarray, heading_alarm: np.ndarray | None,
                   groups: np.ndarray, how: str = "or") -> np.ndarray:
    """Deprecated two-detector form of :func:`aeromag.detection.combine.combine_alarms`.

    Parameters
    ----------
    track_alarm, heading_alarm : ndarray of bool (heading may be None)
    groups : ndarray of int
        Leg per sample, -1 for none.
    how : {"or", "and"}

    Returns
    -------
    ndarray of bool
    """
    return _combine([track_alarm, heading_alarm], groups, how)
