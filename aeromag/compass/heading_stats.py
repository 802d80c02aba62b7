"""Statistics of a compass heading error (the metrics of a calibration)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["HeadingErrorStats", "heading_error_stats"]


@dataclass(kw_only=True)
class HeadingErrorStats:
    """RMS, mean and largest absolute heading error over the finite samples.

    Attributes
    ----------
    rms_deg, mean_deg, max_abs_deg : float or None
        Heading error statistics [deg] (None when no sample is finite); JSON
        ``heading_err_rms_deg``, ``heading_err_mean_deg``, ``heading_err_max_abs_deg``.
    """

    rms_deg: float | None = None
    mean_deg: float | None = None
    max_abs_deg: float | None = None

    def to_dict(self) -> dict[str, float | None]:
        """JSON-ready dict (the ``heading_err_*`` keys of a compass report's ``metrics``)."""
        return {"heading_err_rms_deg": self.rms_deg, "heading_err_mean_deg": self.mean_deg,
                "heading_err_max_abs_deg": self.max_abs_deg}

    @classmethod
    def from_dict(cls, d: dict[str, float | None]) -> HeadingErrorStats:
        """Read the ``heading_err_*`` keys written by :meth:`to_dict`."""
        return cls(rms_deg=d["heading_err_rms_deg"], mean_deg=d["heading_err_mean_deg"],
                   max_abs_deg=d["heading_err_max_abs_deg"])


def heading_error_stats(err_deg: np.ndarray) -> HeadingErrorStats:
    """RMS and mean of a heading error over its finite samples.

    Parameters
    ----------
    err_deg : ndarray
        Heading error [deg], wrapped.

    Returns
    -------
    HeadingErrorStats
        RMS, mean and largest absolute error [deg] (None when no finite sample).
    """
    e = np.asarray(err_deg, dtype=np.float64)
    e = e[np.isfinite(e)]
    if not e.size:
        return HeadingErrorStats()
    return HeadingErrorStats(rms_deg=float(np.sqrt(np.mean(e * e))), mean_deg=float(e.mean()),
                             max_abs_deg=float(np.abs(e).max()))
