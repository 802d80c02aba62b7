"""Plots (matplotlib, one figure style): every function takes ``ax=`` and/or ``path=``.

Compensation diagnostics (:mod:`aeromag.plot.compensation`), maps (:mod:`aeromag.plot.maps`,
:mod:`aeromag.plot.grid_map`), levelling (:mod:`aeromag.plot.levelling`) and track checks
(:mod:`aeromag.plot.track`).  Names are imported on first use (``am.plot.plot_psd``).
"""

from __future__ import annotations

from aeromag._core.lazy import lazy_names

#: Public name -> module that defines it.
_API: dict[str, str] = {
    "plot_pca_scores": "aeromag.plot.compensation",
    "plot_explained_variance": "aeromag.plot.compensation",
    "plot_timeseries": "aeromag.plot.compensation",
    "plot_residuals": "aeromag.plot.compensation",
    "plot_psd": "aeromag.plot.compensation",
    "plot_term_contributions": "aeromag.plot.compensation",
    "plot_fom": "aeromag.plot.compensation",
    "plot_map": "aeromag.plot.maps",
    "plot_grid_map": "aeromag.plot.grid_map",
    "plot_mistie_histogram": "aeromag.plot.levelling",
    "plot_stacked_profiles": "aeromag.plot.levelling",
    "plot_track": "aeromag.plot.track",
    "plot_track_map": "aeromag.plot.track",
    "plot_track_timeseries": "aeromag.plot.track",
}

__all__ = sorted(_API)

__getattr__, __dir__ = lazy_names(__name__, _API)
