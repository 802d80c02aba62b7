"""What the compensation returns: :class:`CompensationResult`."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from ..errors import InputError
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

    # Figures (matplotlib Figure objects, headless; see aeromag.plot.compensation).
    def plot_pca_scores(self, **kw: Any) -> Any:
        """The PCA score plot (PC1 vs PC2): kept/dropped segments, decision boundary."""
        from ..plot import compensation as pc

        return pc.plot_pca_scores(self.report, **kw)

    def plot_explained_variance(self, **kw: Any) -> Any:
        """Explained-variance bars of the screening PCA."""
        from ..plot import compensation as pc

        return pc.plot_explained_variance(self.report, **kw)

    def plot_timeseries(self, **kw: Any) -> Any:
        """Uncompensated vs compensated total field against time."""
        from ..plot import compensation as pc

        return pc.plot_timeseries(self._data(), **kw)

    def plot_psd(self, **kw: Any) -> Any:
        """Power spectral density before and after compensation."""
        from ..plot import compensation as pc

        kw.setdefault("band_hz", tuple(self.report["band_hz"]))
        return pc.plot_psd(self._data(), **kw)

    def plot_term_contributions(self, **kw: Any) -> Any:
        """Permanent / induced / eddy contributions to ``mag_tl``."""
        from ..plot import compensation as pc

        return pc.plot_term_contributions(self._data(), self.report, **kw)

    def plot_fom(self, **kw: Any) -> Any:
        """FOM bars per heading and manoeuvre (calibration flights)."""
        from ..plot import compensation as pc
        from ..qc import fom_table

        table = fom_table(self._data(), band_hz=tuple(self.report["band_hz"]))
        return pc.plot_fom(table, **kw)

    def plot_map(self, **kw: Any) -> Any:
        """Map of the flight coloured by the compensated field (needs lat/lon)."""
        from ..plot import compensation as pc

        return pc.plot_map(self._data(), **kw)

    def qc(self, **kw: Any) -> Any:
        """All quality-control metrics (:func:`aeromag.qc.compute_qc`)."""
        from ..qc import compute_qc

        return compute_qc(self._data(), self.report, **kw)

    def write_report(self, out_dir: str | os.PathLike[str]) -> Path:
        """Write the figures, ``qc.json`` and ``report.html`` into ``out_dir``."""
        from ..workflows.report import write_report

        return write_report(self._data(), self.report, out_dir)

    def _data(self) -> pd.DataFrame:
        if self.data is None:
            raise InputError("this result holds no compensated data (use compensate())")
        return self.data

