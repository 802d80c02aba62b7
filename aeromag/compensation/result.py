"""What the compensation returns: :class:`CompensationResult`."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from .config import CompensationConfig
from .model import TLModel
from .screening import ScreenResult

if TYPE_CHECKING:
    from .fit import FitOutcome


@dataclass
class CompensationResult:
    """What the pipeline returns.

    Attributes
    ----------
    data : DataFrame
        The input log plus ``mag_tl``, ``mag_comp``, ``segment``, ``segment_kept``.
    model : TLModel
        The model applied (fitted here or loaded).
    report : dict
        The JSON report (interface.md keys and more).
    screen : ScreenResult or None
        The last PCA screening (None when not screened).
    segment_table : DataFrame or None
        The report's ``segments`` as a table (fits only).
    fit : FitOutcome or None
        Everything the fit decided and measured (None when a saved model was applied).
    config : CompensationConfig or None
        The configuration the log was compensated with.
    comp_bp_nT : ndarray or None
        ``mag_comp`` band-passed in the fitting band, as the metrics used it (NaN on filter
        edges and gaps) [nT]: quality control reuses it instead of filtering again.
    segment : ndarray of int or None
        Segment id per sample (-1: none).
    fs_hz : float or None
        Sampling rate [Hz].
    """

    data: pd.DataFrame | None
    model: TLModel
    report: dict[str, Any]
    screen: ScreenResult | None = None
    segment_table: pd.DataFrame | None = field(default=None, repr=False)
    fit: FitOutcome | None = field(default=None, repr=False)
    config: CompensationConfig | None = None
    comp_bp_nT: np.ndarray | None = field(default=None, repr=False)
    segment: np.ndarray | None = field(default=None, repr=False)
    fs_hz: float | None = None

    @property
    def metrics(self) -> dict[str, Any]:
        """The report's ``metrics`` block (empty for a fit without data)."""
        return self.report.get("metrics") or {}
