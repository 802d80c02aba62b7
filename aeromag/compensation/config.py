"""Options of the compensation pipeline (:class:`CompensationConfig`)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from ..errors import InputError


@dataclass
class CompensationConfig:
    """Options of the compensation pipeline (all with the command line's defaults).

    Attributes
    ----------
    band_hz : (float, float)
        Band-pass applied to the target and every term before least squares [Hz].
    terms : str
        Term set (:func:`aeromag.tolles_lawson.parse_terms`), default ``"16"``.
    segment_seconds : float
        Segment length when the log has no ``line`` column [s].
    screen : bool
        PCA screening of segments (``--no-screen`` turns it off).
    filter_output : bool
        Low-pass filter ``mag_comp`` (``--no-filter`` turns it off).
    lowpass_hz : float or None
        Cut-off of the final low-pass [Hz]; default the band's upper edge.
    order : int
        Butterworth order.
    ridge : float
        Relative ridge parameter of the final fit (0 = plain least squares).
    shrink : float
        Strength of the per-segment shrinkage toward the pooled fit (screening only).
    pca_variance : float
        Cumulative explained variance of the retained components (0-1].
    screen_quantile : float
        Chi-square quantile of the screening cut-off.
    max_iter : int
        Most screening rounds.
    min_segments : int
        Fewest fitted segments for screening; fewer are fitted without screening.
    min_excess : float
        A segment outside the PCA main cluster is dropped only when the pooled fit leaves it a
        band-passed residual std above ``min_excess`` (default 1.5) times the median over kept
        segments (an outlier that the pool fits as well as any other segment is statistically, not
        practically, different and is kept).
    min_excess_nT : float
        ... and only when that residual also exceeds the median by this much [nT]: with a quiet
        sensor at a high rate, in-band residuals of 0.001 nT differ by large ratios that no
        survey can see.
    gross_excess : float
        The guard also asks the segment's own-fit excess (the part of its pooled residual that
        its own TL fit removes; geology is removed by none) to be material, unless its pooled
        residual is this many times the median (:func:`aeromag.screening.material`).
    inlier_excess, inlier_own_excess : float
        A segment inside the PCA main cluster is still dropped (the worst one per round) when
        its pooled residual exceeds ``inlier_excess`` times the median and its own-fit excess
        ``inlier_own_excess`` times its median: with few segments a fault can mask itself in
        the score plot (:func:`aeromag.screening.masked_outlier`).
    min_segment_seconds : float or None
        Shortest usable segment after trimming [s]; default ``1 / band_hz[0]``.
    max_gap_s : float or None
        Longest time step inside a stretch [s]; default 5 sample intervals.
    max_interp_s : float
        Longest NaN gap interpolated [s]; longer gaps split stretches.
    trim_s : float or None
        Filter edge dropped at each end of every segment piece before fitting [s]; default
        ``0.25 / band_hz[0]``.
    fom : bool or None
        Detect manoeuvres and report the Figure of Merit in the ``qc`` block; None = on for
        calibration (:func:`calibrate_file`), off otherwise.
    max_condition : float
        Largest scaled condition number (columns of unit norm) of the final, unregularised fit;
        above it the fit is refused as ill-conditioned.  A box calibration with manoeuvres
        gives about 1e2; straight-and-level flight with 1 degree of attitude jitter about 3e5,
        where coefficients come out at 1e5 nT and the unfiltered ``mag_tl`` carries that
        error as level shifts between headings.  A ridge (``ridge > 0``) lifts the limit.
    max_interference : float
        Largest plausible aircraft interference, as a fraction of the Earth field's magnitude
        (the median fluxgate magnitude): a fitted model whose ``|mag_tl|`` (99th percentile)
        exceeds it on the log it was fitted on is refused.  A fit can be well conditioned in
        the band and still be undetermined at low frequency (e.g. survey lines on two headings
        only: cz against a constant, cx*cx and cy*cy), and then the unfiltered model returns
        tens of thousands of nT.  A saved model that does so only draws a warning.
    decimate : bool
        Fit a high-rate log on a copy decimated per stretch to at least 40 times the band's
        upper edge (:mod:`aeromag._core.decimate`; a 1 kHz log is fitted at 37 Hz, a 10 Hz log
        is never decimated); the coefficients are applied to every original sample.
        ``--no-decimate`` fits every sample.
    """

    band_hz: tuple[float, float] = (0.1, 0.9)
    terms: str = "16"
    segment_seconds: float = 60.0
    screen: bool = True
    filter_output: bool = True
    lowpass_hz: float | None = None
    order: int = 4
    ridge: float = 0.0
    shrink: float = 1.0
    pca_variance: float = 0.8
    screen_quantile: float = 0.975
    max_iter: int = 10
    min_segments: int = 6
    min_excess: float = 1.5
    min_excess_nT: float = 0.01
    min_segment_seconds: float | None = None
    max_gap_s: float | None = None
    max_interp_s: float = 1.0
    trim_s: float | None = None
    fom: bool | None = None
    max_condition: float = 1e5
    max_interference: float = 0.25
    gross_excess: float = 10.0
    inlier_excess: float = 2.5
    inlier_own_excess: float = 4.0
    decimate: bool = True

    def __post_init__(self) -> None:
        self.band_hz = (float(self.band_hz[0]), float(self.band_hz[1]))
        lo, hi = self.band_hz
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo < hi):
            raise InputError(f"--band {lo:g} {hi:g}: need 0 < LOW < HIGH in Hz")
        positive = {"--segment-seconds": self.segment_seconds, "--lowpass": self.lowpass_hz,
                    "--max-gap": self.max_gap_s, "--max-condition": self.max_condition,
                    "--min-segment-seconds": self.min_segment_seconds,
                    "--max-interference": self.max_interference,
                    "gross_excess": self.gross_excess, "inlier_excess": self.inlier_excess,
                    "inlier_own_excess": self.inlier_own_excess}
        for opt, v in positive.items():
            if v is not None and not (np.isfinite(v) and v > 0):
                raise InputError(f"{opt} {v:g}: must be a positive number")
        nonneg = {"--ridge": self.ridge, "--shrink": self.shrink, "--max-interp":
                  self.max_interp_s, "--min-excess": self.min_excess, "--min-excess-nt":
                  self.min_excess_nT, "--trim": self.trim_s}
        for opt, v in nonneg.items():
            if v is not None and not (np.isfinite(v) and v >= 0):
                raise InputError(f"{opt} {v:g}: must be a number >= 0")
        if not 0 < self.pca_variance <= 1:
            raise InputError(f"--pca-variance {self.pca_variance}: must be in (0, 1]")
        if not 0 < self.screen_quantile < 1:
            raise InputError(f"--screen-quantile {self.screen_quantile}: must be in (0, 1)")
        if int(self.order) != self.order or not 1 <= self.order <= 10:
            raise InputError(f"filter order {self.order}: must be an integer from 1 to 10")



def _config_dict(cfg: CompensationConfig) -> dict[str, Any]:
    d = dataclasses.asdict(cfg)
    d["band_hz"] = list(cfg.band_hz)
    return d



def _resolve_gap(cfg: CompensationConfig, df: pd.DataFrame) -> CompensationConfig:
    """Fix the default gap (5 median time steps) once, so no step recomputes the median."""
    if cfg.max_gap_s is not None or "time" not in df.columns or len(df) < 2:
        return cfg
    t = df["time"].to_numpy(dtype=np.float64)
    med = float(np.median(np.diff(t)))
    if not med > 0:
        return cfg
    return dataclasses.replace(cfg, max_gap_s=5.0 * med)

