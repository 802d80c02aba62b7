"""The total field a compensated log was compensated on (``mag`` or the fluxgate magnitude)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from .._core.stretches import interpolate_short_gaps
from ..compensation.config import CompensationConfig
from ..compensation.report_types import CompensationReport
from ..conventions import FLUX_COLUMNS
from ..errors import InputError

__all__ = ["fluxgate_is_total_field", "prepared_total_field"]


def fluxgate_is_total_field(data: pd.DataFrame, report: CompensationReport) -> bool:
    """Whether the compensation took the fluxgate magnitude as the total field.

    Parameters
    ----------
    data : DataFrame
        The compensated log.
    report : CompensationReport
        Its report (OUT.json: ``mag_from_fluxgate``).

    Returns
    -------
    bool
        True when the report says so or the log has no ``mag`` column.
    """
    return bool(report.mag_from_fluxgate) or "mag" not in data.columns


def prepared_total_field(data: pd.DataFrame, report: CompensationReport,
                         cfg: CompensationConfig) -> np.ndarray:
    """The total field as the compensation used it (short NaN gaps interpolated).

    ``mag``, or ``|flux|`` when the fluxgate magnitude was the total field
    (:func:`fluxgate_is_total_field`), as :func:`aeromag.compensation.prepare.prepare` built it.

    Parameters
    ----------
    data : DataFrame
        The compensated log (``time``, ``mag`` or ``flux_x/y/z`` [nT]).
    report : CompensationReport
        Its report (``mag_from_fluxgate``).
    cfg : CompensationConfig
        ``max_interp_s``: the longest NaN gap the compensation interpolated [s].

    Returns
    -------
    ndarray
        Total field per row [nT] (NaN where the compensation had none).

    Raises
    ------
    InputError
        The fluxgate magnitude is the total field but the log has no flux_x/flux_y/flux_z.
    """
    t = data["time"].to_numpy(dtype=np.float64)
    if fluxgate_is_total_field(data, report):
        if not set(FLUX_COLUMNS) <= set(data.columns):
            raise InputError(f"{data.attrs.get('source', '<log>')}: no 'mag' column and no"
                             " flux_x/flux_y/flux_z: no total field to measure")
        sq = np.zeros(len(t))
        for c in FLUX_COLUMNS:
            v, _ = interpolate_short_gaps(data[c].to_numpy(dtype=np.float64), t,
                                          cfg.max_interp_s, copy=False)
            sq += v * v
        return np.sqrt(sq)
    return interpolate_short_gaps(data["mag"].to_numpy(dtype=np.float64), t, cfg.max_interp_s)[0]
