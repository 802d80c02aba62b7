"""Diurnal correction from a base-station record.

The base record (read by :mod:`aeromag.io.base`: CSV ``time,mag`` or IAGA-2002) is cleaned of
spikes (a sample more than ``spike_mad`` local robust deviations and ``spike_min_nT`` from
the running median is a spike, removed and reported; see :func:`clean_base`), interpolated
linearly in UTC to each survey sample, and referred to a datum (the base's mean over the
survey, or a given value).  A sample outside the base's coverage (before its first, after
its last sample, or inside a gap longer than ``max_gap_s``) is never extrapolated: it is an
error, or, when allowed, a warning with that sample's diurnal NaN.

A survey not covered by its base record is often a base in another time base: local time
instead of UTC, or a day off.  When shifting the survey by whole hours (up to 14) or one day
would put it inside the base record, the error says so.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import median_filter

from ..errors import InputError

log = logging.getLogger(__name__)

__all__ = ["BaseRecord", "DiurnalResult", "clean_base", "diurnal_correction"]


@dataclass
class BaseRecord:
    """A base-station record.

    Attributes
    ----------
    time_s : ndarray
        UTC seconds since 1970, increasing.
    mag_nT : ndarray
        Total field [nT] (NaN: missing).
    source : str
        File it came from.
    notes : tuple of str
        What the reader dropped or shifted (flagged readings, a clock offset), reported
        among the diurnal step's warnings.
    """

    time_s: np.ndarray
    mag_nT: np.ndarray
    source: str = "<base>"
    notes: tuple[str, ...] = ()


@dataclass
class DiurnalResult:
    """The diurnal correction of a survey.

    Attributes
    ----------
    diurnal_nT : ndarray
        Base field at each sample's time minus the datum [nT] (NaN: not covered).
    datum_nT : float
        The datum [nT].
    datum_source : str
        ``"survey mean"`` or ``"given"``.
    coverage_s : tuple of float
        First and last time of the base record [s].
    spikes_s : list of float
        Times of the removed spikes [s].
    n_uncovered : int
        Samples outside the base's coverage.
    source : str
        Base file.
    warnings : list of str
        What was warned about.
    """

    diurnal_nT: np.ndarray
    datum_nT: float
    datum_source: str
    coverage_s: tuple[float, float]
    spikes_s: list[float]
    n_uncovered: int
    source: str
    warnings: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        """JSON-ready form (OUT.json ``diurnal``)."""
        return {"source": self.source, "datum_nT": self.datum_nT,
                "datum": self.datum_source, "coverage_s": list(self.coverage_s),
                "n_spikes": len(self.spikes_s), "spikes_s": self.spikes_s[:100],
                "n_uncovered": self.n_uncovered,
                "range_nT": float(np.nanmax(self.diurnal_nT) - np.nanmin(self.diurnal_nT))
                if np.isfinite(self.diurnal_nT).any() else None}


def clean_base(base: BaseRecord, *, window: int = 5, scale_window: int = 15,
               spike_mad: float = 6.0, spike_min_nT: float = 2.0
               ) -> tuple[BaseRecord, np.ndarray]:
    """Remove spikes from a base record (robust: running median and a local MAD).

    A spike (a car, a person with keys) departs from the running median of ``window``
    samples by more than ``spike_mad`` local robust deviations (1.4826 x the running median
    of the sample-to-sample steps over ``scale_window`` samples) and by ``spike_min_nT``.  The
    local scale grows during a magnetically active spell, so real pulsations (smooth swings
    of several nT over minutes, as in Boulder's 2 November 2014) stay.

    Parameters
    ----------
    base : BaseRecord
        The record.
    window : int
        Running-median window, samples (odd).
    scale_window : int
        Window of the local robust scale, samples (odd).
    spike_mad : float
        Threshold in local robust standard deviations.
    spike_min_nT : float
        Smallest departure that counts as a spike [nT].

    Returns
    -------
    cleaned : BaseRecord
        Spikes set to NaN.
    spikes : ndarray of bool
        The removed samples.
    """
    v = np.asarray(base.mag_nT, dtype=np.float64)
    ok = np.isfinite(v)
    spikes = np.zeros(v.size, dtype=bool)
    if ok.sum() >= scale_window:
        vv = v[ok]
        r = vv - median_filter(vv, size=window, mode="nearest")
        step = np.abs(np.diff(vv, prepend=vv[0]))
        scale = 1.4826 * median_filter(step, size=scale_window, mode="nearest")
        thr = np.maximum(spike_mad * scale, spike_min_nT)
        spikes[np.flatnonzero(ok)[np.abs(r) > thr]] = True
    out = v.copy()
    out[spikes] = np.nan
    return BaseRecord(base.time_s, out, base.source), spikes


def _covered(t: np.ndarray, bt: np.ndarray, max_gap_s: float) -> np.ndarray:
    """Sample times inside the base's coverage (between two base samples <= max_gap apart)."""
    inside = (t >= bt[0]) & (t <= bt[-1])
    j = np.clip(np.searchsorted(bt, t, side="right"), 1, bt.size - 1)
    gap = bt[j] - bt[j - 1]
    exact = bt[j - 1] == t
    return inside & ((gap <= max_gap_s) | exact)


def _time_base_hint(t: np.ndarray, bt: np.ndarray, max_gap_s: float) -> str:
    """Say what shift would make the base cover the survey (local time, a day off)."""
    frac0 = _covered(t, bt, max_gap_s).mean()
    cover = {h: _covered(t + h * 3600.0, bt, max_gap_s).mean()
             for h in [24, -24, *range(-14, 15)] if h != 0}
    good = [h for h, f in cover.items() if f > frac0 + 0.5 and f >= max(cover.values()) - 1e-9]
    if not good:
        return ""
    hours = sorted((h for h in good if abs(h) < 24), key=lambda h: (abs(h), h))
    said = []
    if hours:
        said.append(f"by {hours[0]:+d} h (local time instead of UTC?)")
    said += [f"by {h:+d} h (a day off: wrong date?)" for h in good if abs(h) == 24]
    return (f"; shifted {' or '.join(said)} the survey would fall inside it: check the time "
            "base of the base record and of the survey")


def diurnal_correction(time_s: np.ndarray, base: BaseRecord, *, datum_nT: float | None = None,
                       allow_uncovered: bool = False, max_gap_s: float | None = None,
                       spike_mad: float = 6.0) -> DiurnalResult:
    """The base station's variation at each survey sample.

    Parameters
    ----------
    time_s : ndarray
        Survey sample times, UTC seconds since 1970.
    base : BaseRecord
        The base record.
    datum_nT : float, optional
        The datum [nT] (default: the base's mean over the survey's time span).
    allow_uncovered : bool
        Samples outside the base's coverage get NaN with a warning (default: an error).
    max_gap_s : float, optional
        A base gap longer than this is not interpolated across [s] (default 5 median steps).
    spike_mad : float
        Spike threshold, robust standard deviations.

    Returns
    -------
    DiurnalResult

    Raises
    ------
    InputError
        The base does not cover the survey (and ``allow_uncovered`` is False), naming the
        spans and a likely time-base mistake.
    """
    src = base.source
    bt = np.asarray(base.time_s, dtype=np.float64)
    if bt.size < 2 or np.any(np.diff(bt) <= 0):
        raise InputError(f"{src}: base-station times must be increasing, with at least two "
                         "samples")
    cleaned, spikes = clean_base(base, spike_mad=spike_mad)
    warnings: list[str] = list(base.notes)
    if spikes.any():
        msg = (f"{src}: {int(spikes.sum())} base-station spike(s) removed (first at "
               f"{bt[spikes][0]:.0f} s; robust threshold {spike_mad:g} MAD)")
        log.warning(msg)
        warnings.append(msg)
    ok = np.isfinite(cleaned.mag_nT)
    bt_ok, bv = bt[ok], cleaned.mag_nT[ok]
    if bt_ok.size < 2:
        raise InputError(f"{src}: the base record has fewer than two valid samples")
    if max_gap_s is None:
        max_gap_s = 5.0 * float(np.median(np.diff(bt)))
    t = np.asarray(time_s, dtype=np.float64)
    tf = np.isfinite(t)
    cov = np.zeros(t.size, dtype=bool)
    cov[tf] = _covered(t[tf], bt_ok, max_gap_s)
    n_out = int(np.count_nonzero(tf & ~cov))
    span = (float(bt[0]), float(bt[-1]))
    if n_out and not allow_uncovered or not cov.any():
        tt = t[tf]
        raise InputError(
            f"{src}: the base record ({span[0]:.0f}-{span[1]:.0f} s UTC) does not cover "
            f"{n_out} of {tf.sum()} survey samples ({tt.min():.0f}-{tt.max():.0f} s)"
            f"{_time_base_hint(tt, bt_ok, max_gap_s)}; give a base record that covers the "
            "survey (or --allow-base-gaps to leave those samples' diurnal empty)")
    field_at = np.full(t.size, np.nan)
    field_at[cov] = np.interp(t[cov], bt_ok, bv)
    if n_out:
        msg = (f"{src}: {n_out} survey sample(s) outside the base's coverage: their diurnal "
               "(and tmi) left empty")
        log.warning(msg)
        warnings.append(msg)
    if datum_nT is None:
        t0, t1 = np.nanmin(t), np.nanmax(t)
        inside = (bt_ok >= t0) & (bt_ok <= t1)
        datum = float(bv[inside].mean()) if inside.sum() >= 2 else float(np.nanmean(field_at))
        how = "survey mean"
    else:
        datum, how = float(datum_nT), "given"
    return DiurnalResult(field_at - datum, datum, how, span,
                         [float(v) for v in bt[spikes]], n_out, src, warnings)
