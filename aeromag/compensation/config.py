"""Options of the compensation pipeline: :class:`CompensationConfig` and its option groups.

The configuration is flat (``CompensationConfig(band_hz=..., shrink=...)``, the keywords the
command line and old code use) and grouped: :class:`FilterOptions`, :class:`SegmentOptions`,
:class:`ScreeningOptions` and :class:`FitChecks` each hold and check their own parameters;
``cfg.filter``, ``cfg.segments``, ``cfg.screening``, ``cfg.checks`` read them and
:meth:`CompensationConfig.from_groups` builds a configuration from them.  A bad value raises
:class:`ConfigError`, which names the parameter (the command line maps it to its flag).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
import pandas as pd

from ..errors import ConfigError, InputError
from .terms import parse_terms


def _positive(name: str, v: float | None) -> None:
    if v is not None and not (np.isfinite(v) and v > 0):
        raise ConfigError(name, v, "must be a positive number")


def _nonneg(name: str, v: float | None) -> None:
    if v is not None and not (np.isfinite(v) and v >= 0):
        raise ConfigError(name, v, "must be a number >= 0")


@dataclass(frozen=True)
class FilterOptions:
    """Filters: the fitting band, the final low-pass, their order, the trimmed edges.

    Attributes
    ----------
    band_hz : (float, float)
        Band-pass before fitting [Hz].
    order : int
        Butterworth order (1-10).
    lowpass_hz : float or None
        Cut-off of the final low-pass on ``mag_comp`` [Hz]; default the band's upper edge.
    filter_output : bool
        Low-pass ``mag_comp`` at all.
    trim_s : float or None
        Filter edge dropped at each end of every piece before fitting [s].
    decimate : bool
        Fit a high-rate log on a copy decimated to >= 80x the band's upper edge
        (:mod:`aeromag.compensation.decimation`); False fits every sample.
    """

    band_hz: tuple[float, float] = (0.1, 0.9)
    order: int = 4
    lowpass_hz: float | None = None
    filter_output: bool = True
    trim_s: float | None = None
    decimate: bool = True

    def __post_init__(self) -> None:
        lo, hi = (float(self.band_hz[0]), float(self.band_hz[1]))
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo < hi):
            raise ConfigError("band_hz", (lo, hi), "need 0 < LOW < HIGH in Hz")
        if int(self.order) != self.order or not 1 <= self.order <= 10:
            raise ConfigError("order", self.order, "must be an integer from 1 to 10")
        _positive("lowpass_hz", self.lowpass_hz)
        _nonneg("trim_s", self.trim_s)


@dataclass(frozen=True)
class SegmentOptions:
    """Stretches and segments.

    Attributes
    ----------
    segment_seconds : float
        Segment length when the log has no ``line`` column [s].
    min_segment_seconds : float or None
        Shortest usable segment after trimming [s]; default ``1 / band_hz[0]``.
    max_gap_s : float or None
        Longest time step inside a stretch [s]; default 5 sample intervals.
    max_interp_s : float
        Longest NaN gap interpolated [s].
    """

    segment_seconds: float = 60.0
    min_segment_seconds: float | None = None
    max_gap_s: float | None = None
    max_interp_s: float = 1.0

    def __post_init__(self) -> None:
        _positive("segment_seconds", self.segment_seconds)
        _positive("min_segment_seconds", self.min_segment_seconds)
        _positive("max_gap_s", self.max_gap_s)
        _nonneg("max_interp_s", self.max_interp_s)


@dataclass(frozen=True)
class ScreeningOptions:
    """PCA screening of the segments and its materiality guards.

    Attributes are those of :class:`CompensationConfig` with the same names.
    """

    screen: bool = True
    shrink: float = 1.0
    pca_variance: float = 0.8
    screen_quantile: float = 0.975
    max_iter: int = 10
    min_segments: int = 6
    min_excess: float = 1.5
    min_excess_nT: float = 0.01
    noise_factor: float = 3.0
    gross_excess: float = 10.0
    inlier_excess: float = 2.5
    inlier_own_excess: float = 4.0

    def __post_init__(self) -> None:
        _nonneg("shrink", self.shrink)
        _nonneg("min_excess", self.min_excess)
        _nonneg("min_excess_nT", self.min_excess_nT)
        _nonneg("noise_factor", self.noise_factor)
        for name in ("gross_excess", "inlier_excess", "inlier_own_excess"):
            _positive(name, getattr(self, name))
        if not 0 < self.pca_variance <= 1:
            raise ConfigError("pca_variance", self.pca_variance, "must be in (0, 1]")
        if not 0 < self.screen_quantile < 1:
            raise ConfigError("screen_quantile", self.screen_quantile, "must be in (0, 1)")


@dataclass(frozen=True)
class FitChecks:
    """Regularisation and the refusals of the final fit.

    Attributes
    ----------
    ridge : float
        Relative ridge parameter (0: plain least squares).
    max_condition : float
        Largest scaled condition number of an unregularised fit.
    max_interference : float
        Largest plausible interference as a fraction of the Earth field.
    """

    ridge: float = 0.0
    max_condition: float = 1e5
    max_interference: float = 0.25

    def __post_init__(self) -> None:
        _nonneg("ridge", self.ridge)
        _positive("max_condition", self.max_condition)
        _positive("max_interference", self.max_interference)


#: The estimators of the extended fit (``--estimator``).
ESTIMATORS = ("ridge", "pls", "mlp")

_GROUPS = {"filter": FilterOptions, "segments": SegmentOptions, "screening": ScreeningOptions,
           "checks": FitChecks}


@dataclass
class CompensationConfig:
    """Options of the compensation pipeline (all with the command line's defaults).

    Attributes
    ----------
    band_hz : (float, float)
        Band-pass applied to the target and every term before least squares [Hz].
    terms : str
        Term set (:func:`aeromag.compensation.terms.parse_terms`), default ``"16"``.
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
    noise_factor : float
        ... and by this many standard deviations of the data's in-band noise (default 3; the
        median over kept segments of the residual each segment's own TL fit leaves, sensor
        noise plus geology): the floor is ``max(min_excess_nT, noise_factor * noise)``.  An
        excess inside the noise is no fault whatever its ratio: a reviewer's fault-free box
        (0.02 nT sensor, 10 Hz, in-band noise 0.008 nT) lost its E and W yaw lines, 0.014 and
        0.020 nT above the median (ratios 2.8 and 3.5), to the 0.01 nT floor alone.  A fixed
        0.05 nT floor instead kept a simulated on-board source (0.063 nT above the median in
        band) whose out-of-band leak cost the clean lines 0.16 nT; 0 turns the noise floor off.
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
        Detect maneuvers and report the Figure of Merit in the ``qc`` block; None = on for
        calibration (:func:`calibrate_file`), off otherwise.
    max_condition : float
        Largest scaled condition number (columns of unit norm) of the final, unregularised fit;
        above it the fit is refused as ill-conditioned.  A box calibration with maneuvers
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
    mag_from_fluxgate : bool
        Take the magnitude of the fluxgate vector as the measured total field even when the
        log has ``mag`` (``--mag-from-fluxgate``).  Without it, a log with no ``mag`` uses the
        fluxgate magnitude (interface.md) with a warning, unless another column looks like a
        misnamed scalar (then it is an error); a model fitted on one kind of total field is
        never applied to the other
        (:func:`aeromag.compensation.prepare.total_field_from_fluxgate`).
    decimate : bool
        Fit a high-rate log on a copy decimated per stretch to at least 80 times the
        band's upper edge (:mod:`aeromag._core.decimate`; a 1 kHz log is fitted at 77 Hz, logs
        below 144 Hz are never decimated); the coefficients are applied to every original
        sample.
        ``--no-decimate`` fits every sample.
    reference : str or None
        Column of a reference total field [nT] (``--reference COL``): the interference is
        fitted against ``mag - COL`` over the full band, with an intercept, by a regularised
        fit chosen by cross-validation over blocks of time (:mod:`aeromag.compensation.extended`).
    extras : tuple of str
        More regressors beside the TL terms (``--extra COL,...``: currents, voltages), band-passed
        like them in a self-fit, over the full band with a reference.
    estimator : str
        ``ridge`` (default), ``pls`` (partial least squares) or ``mlp`` (a small network that
        corrects the linear prediction; needs ``reference``).  Used with ``reference`` or
        ``extras`` only.
    """

    # Defaults come from the option groups (one place for each).
    band_hz: tuple[float, float] = FilterOptions.band_hz
    terms: str = "16"
    segment_seconds: float = SegmentOptions.segment_seconds
    screen: bool = ScreeningOptions.screen
    filter_output: bool = FilterOptions.filter_output
    lowpass_hz: float | None = FilterOptions.lowpass_hz
    order: int = FilterOptions.order
    ridge: float = FitChecks.ridge
    shrink: float = ScreeningOptions.shrink
    pca_variance: float = ScreeningOptions.pca_variance
    screen_quantile: float = ScreeningOptions.screen_quantile
    max_iter: int = ScreeningOptions.max_iter
    min_segments: int = ScreeningOptions.min_segments
    min_excess: float = ScreeningOptions.min_excess
    min_excess_nT: float = ScreeningOptions.min_excess_nT
    noise_factor: float = ScreeningOptions.noise_factor
    min_segment_seconds: float | None = SegmentOptions.min_segment_seconds
    max_gap_s: float | None = SegmentOptions.max_gap_s
    max_interp_s: float = SegmentOptions.max_interp_s
    trim_s: float | None = FilterOptions.trim_s
    fom: bool | None = None
    max_condition: float = FitChecks.max_condition
    max_interference: float = FitChecks.max_interference
    gross_excess: float = ScreeningOptions.gross_excess
    inlier_excess: float = ScreeningOptions.inlier_excess
    inlier_own_excess: float = ScreeningOptions.inlier_own_excess
    decimate: bool = FilterOptions.decimate
    mag_from_fluxgate: bool = False
    reference: str | None = None
    extras: tuple[str, ...] = ()
    estimator: str = "ridge"

    def __post_init__(self) -> None:
        self.band_hz = (float(self.band_hz[0]), float(self.band_hz[1]))
        if isinstance(self.extras, str):
            self.extras = tuple(c.strip() for c in self.extras.split(",") if c.strip())
        self.extras = tuple(str(c) for c in (self.extras or ()))
        if self.estimator not in ESTIMATORS:
            raise ConfigError("estimator", self.estimator,
                              f"must be one of {', '.join(ESTIMATORS)}")
        if self.estimator == "mlp" and self.reference is None:  # no band-pass of a non-linearity
            raise ConfigError("estimator", self.estimator, "the network corrects a fit against "
                              "a reference: add --reference COL")
        if self.estimator != "ridge" and self.reference is None and not self.extras:
            raise ConfigError("estimator", self.estimator, "chooses the fit with --extra or "
                              "--reference; add one, or drop --estimator")
        if self.reference is not None and self.reference in self.extras:
            raise ConfigError("extras", ",".join(self.extras),
                              f"the reference {self.reference} cannot also be a regressor")
        for name in _GROUPS:  # each group checks its own parameters
            getattr(self, name)
        parse_terms(self.terms)

    def _group(self, cls: type) -> Any:
        return cls(**{f.name: getattr(self, f.name) for f in fields(cls)})

    @property
    def filter(self) -> FilterOptions:
        """The filter options."""
        return self._group(FilterOptions)

    @property
    def segments(self) -> SegmentOptions:
        """The stretch and segment options."""
        return self._group(SegmentOptions)

    @property
    def screening(self) -> ScreeningOptions:
        """The screening options."""
        return self._group(ScreeningOptions)

    @property
    def checks(self) -> FitChecks:
        """Regularisation and the fit's refusals."""
        return self._group(FitChecks)

    @classmethod
    def from_groups(cls, *, filter: FilterOptions | None = None,  # noqa: A002 - the group's name
                    segments: SegmentOptions | None = None,
                    screening: ScreeningOptions | None = None, checks: FitChecks | None = None,
                    **flat: Any) -> CompensationConfig:
        """Build a configuration from option groups (and flat keywords: ``terms``, ``fom``).

        Parameters
        ----------
        filter, segments, screening, checks : option group, optional
            Groups (defaults where not given).
        **flat
            Other keywords of :class:`CompensationConfig`.

        Returns
        -------
        CompensationConfig
        """
        kw: dict[str, Any] = {}
        for g in (filter, segments, screening, checks):
            if g is not None:
                kw.update(dataclasses.asdict(g))
        kw.update(flat)
        return cls(**kw)


#: CompensationConfig keywords that only steer a fit: applying a saved model ignores them, so
#: the command line refuses them with ``--model`` and an applied run's report leaves them out.
FIT_ONLY = ("terms", "decimate", "screen", "shrink", "pca_variance", "screen_quantile",
            "max_iter", "min_segments", "min_excess", "min_excess_nT", "noise_factor",
            "gross_excess",
            "inlier_excess", "inlier_own_excess", "ridge", "max_condition",
            "reference", "extras", "estimator")


#: CompensationConfig keywords that only the screening reads: with ``screen=False`` they decide
#: nothing (``shrink`` is not one: it also shrinks the per-segment coefficients reported).
SCREEN_ONLY = ("pca_variance", "screen_quantile", "max_iter", "min_segments", "min_excess",
               "min_excess_nT", "noise_factor", "gross_excess", "inlier_excess",
               "inlier_own_excess")

#: CompensationConfig keywords that the online (recursive) fit reads none of: it has no batch
#: fit and no screening (``terms`` it uses).
BATCH_FIT_ONLY = tuple(k for k in FIT_ONLY if k != "terms")

#: Why a setting cannot act, the one-line message of each cause.  ``{what}`` is the setting
#: (``noise_factor=2``, or a flag), ``{cond}`` what makes it idle (``screen=False``), ``{undo}``
#: how to make it act.  The command line fills in flags (:mod:`aeromag.cli._options`), the
#: library Python keywords (:data:`_PYTHON_SPELLING`).
UNUSED_MESSAGES = {
    "model": "{what} steers a fit, and {cond} applies a saved model: nothing is fitted; drop "
             "{what} ({undo})",
    "online": "{what} steers the batch fit or its screening, and {cond} fits sample by sample "
              "without either: nothing uses it; drop {what} ({undo})",
    "online_fom": "{what}: {cond} reports no Figure of Merit; drop {what} ({undo})",
    "screen": "{what} steers the screening, and {cond} skips it: nothing uses it; drop {what} "
              "({undo})",
    "filter": "{what} sets the final low-pass of mag_comp, and {cond} leaves mag_comp "
              "unfiltered: nothing uses it; drop {what} ({undo})",
}

#: ``{cond}`` and ``{undo}`` of each cause in a Python caller's words.
_PYTHON_SPELLING = {
    "model": ("model=MODEL", "or drop model=MODEL to fit"),
    "online": ("the online fit (compensate_online_file)",
               "or run the batch fit: aeromag.compensate, compensate_file"),
    "online_fom": ("the online fit (compensate_online_file)",
                   "aeromag report on the output gives the FOM of a calibration box"),
    "screen": ("screen=False", "or drop screen=False"),
    "filter": ("filter_output=False", "or drop filter_output=False"),
}


@dataclass(frozen=True)
class UnusedOption:
    """A setting that a run would not use (:func:`unused_options`).

    Attributes
    ----------
    keyword : str
        The :class:`CompensationConfig` keyword (``noise_factor``).
    value : object
        Its value.
    cause : str
        Why it cannot act, a key of :data:`UNUSED_MESSAGES`: ``"model"`` (a saved model is
        applied), ``"online"`` / ``"online_fom"`` (the recursive fit), ``"screen"``
        (``screen=False``), ``"filter"`` (``filter_output=False``).
    """

    keyword: str
    value: Any
    cause: str

    def message(self, what: str | None = None, cond: str | None = None,
                undo: str | None = None) -> str:
        """The one-line message; by default in a Python caller's words.

        Parameters
        ----------
        what, cond, undo : str, optional
            The setting, what makes it idle and how to make it act (the command line gives
            flags); default ``keyword=value`` and :data:`_PYTHON_SPELLING`.

        Returns
        -------
        str
        """
        py_cond, py_undo = _PYTHON_SPELLING[self.cause]
        value = self.value.item() if isinstance(self.value, np.generic) else self.value
        return UNUSED_MESSAGES[self.cause].format(
            what=what if what is not None else f"{self.keyword}={value!r}",
            cond=cond if cond is not None else py_cond,
            undo=undo if undo is not None else py_undo)


def changed_options(cfg: CompensationConfig) -> frozenset[str]:
    """Keywords of ``cfg`` whose value differs from the field's default.

    Parameters
    ----------
    cfg : CompensationConfig
        A configuration.

    Returns
    -------
    frozenset of str
        What the caller changed (``CompensationConfig(noise_factor=3)`` changes nothing).
    """
    out = set()
    for f in fields(cfg):
        v = getattr(cfg, f.name)
        if f.name == "band_hz":
            v = tuple(v)
        if v != f.default:
            out.add(f.name)
    return frozenset(out)


def unused_options(cfg: CompensationConfig, *, model: bool = False, online: bool = False,
                   given: frozenset[str] | set[str] | None = None) -> list[UnusedOption]:
    """The settings of ``cfg`` that a run would not use; the rule the command line refuses by.

    With a saved model nothing is fitted (every keyword of :data:`FIT_ONLY`); the online fit
    has no batch fit or screening (:data:`BATCH_FIT_ONLY`) and computes no Figure of Merit
    (``fom=True``); with ``screen=False`` the screening's thresholds (:data:`SCREEN_ONLY`)
    decide nothing; with ``filter_output=False`` the low-pass cut-off (``lowpass_hz``) does
    nothing.  ``shrink`` stays allowed with ``screen=False``: it also shrinks the per-segment
    coefficients the report holds.

    Parameters
    ----------
    cfg : CompensationConfig
        The run's configuration.
    model : bool
        A saved model is applied (nothing is fitted).
    online : bool
        The online (recursive least squares) fit runs.
    given : set of str, optional
        Keywords the user set; default those that differ from the field defaults
        (:func:`changed_options`), so a default value is never refused.

    Returns
    -------
    list of UnusedOption
        The first cause's settings first (model, then online, then screen), then the filter's;
        empty when every setting acts.
    """
    given = changed_options(cfg) if given is None else frozenset(given)
    found: list[UnusedOption] = []

    def add(keywords: tuple[str, ...], cause: str) -> None:
        found.extend(UnusedOption(k, getattr(cfg, k), cause) for k in keywords if k in given)

    if model:
        add(FIT_ONLY, "model")
    elif online:
        add(BATCH_FIT_ONLY, "online")
        if cfg.fom and "fom" in given:  # fom=False asks for what the online fit does anyway
            found.append(UnusedOption("fom", cfg.fom, "online_fom"))
    elif not cfg.screen:
        add(SCREEN_ONLY, "screen")
    if not cfg.filter_output:
        add(("lowpass_hz",), "filter")
    return found


def refuse_unused_options(cfg: CompensationConfig, *, model: bool = False,
                          online: bool = False) -> None:
    """Raise, in one line, when a setting the user changed cannot act in this run.

    The library's side of the command line's refusal (:func:`unused_options`): a tool that
    silently ignores a setting is worse than one that refuses it.  Default values are never
    refused; internal callers that build configurations leave the idle ones at their defaults.

    Parameters
    ----------
    cfg : CompensationConfig
        The run's configuration.
    model, online : bool
        As in :func:`unused_options`.

    Raises
    ------
    InputError
        Naming the first such keyword and what to drop, e.g. ``noise_factor=2 steers the
        screening, and screen=False skips it: nothing uses it; drop noise_factor=2 (or drop
        screen=False)``.
    """
    found = unused_options(cfg, model=model, online=online)
    if found:
        raise InputError(found[0].message())


def config_dict(cfg: CompensationConfig) -> dict[str, Any]:
    """``cfg`` as a JSON-ready dict; ``reference``, ``extras``, ``estimator`` only when set."""
    d = dataclasses.asdict(cfg)
    d["band_hz"] = list(cfg.band_hz)
    for key in _EXTENDED_KEYS:  # written only when used (reports without them unchanged)
        if d[key] == CompensationConfig.__dataclass_fields__[key].default:
            del d[key]
    if "extras" in d:
        d["extras"] = list(d["extras"])
    return d


#: The extended fit's keywords (:mod:`aeromag.compensation.extended`).
_EXTENDED_KEYS = ("reference", "extras", "estimator")


def resolve_gap(cfg: CompensationConfig, df: pd.DataFrame) -> CompensationConfig:
    """Fix the default gap (5 median time steps) once, so no step recomputes the median."""
    if cfg.max_gap_s is not None or "time" not in df.columns or len(df) < 2:
        return cfg
    t = df["time"].to_numpy(dtype=np.float64)
    med = float(np.median(np.diff(t)))
    if not med > 0:
        return cfg
    return dataclasses.replace(cfg, max_gap_s=5.0 * med)

