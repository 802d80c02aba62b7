"""Arrays of a log ready for fitting or applying: fluxgate, total field, stretches, segments."""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from .._core.filters import sampling_rate
from .._core.stretches import find_stretches, interpolate_short_gaps
from ..conventions import CANONICAL_COLUMNS, FLUX_COLUMNS
from ..errors import FitError, InputError
from .config import CompensationConfig
from .segments import assign_segments, line_labels

log = logging.getLogger(__name__)


@dataclass
class Prepared:
    """Arrays of a log ready for fitting/applying (see :func:`prepare`)."""

    time: np.ndarray
    flux: np.ndarray
    mag: np.ndarray
    flux_ok: np.ndarray
    valid: np.ndarray
    stretch: np.ndarray
    segment: np.ndarray
    fs: float
    source: str
    mag_from_flux: bool
    line_of_segment: dict[int, float] | None = None
    field_nT: float = float("nan")  # median total field (mag, else the fluxgate's) [nT]
    heading_deg: np.ndarray | None = None  # the log's heading column, when it has one [deg]
    from_line: bool = False  # segments are the log's flight lines (not time windows)



def total_field_from_fluxgate(df: pd.DataFrame, cfg: CompensationConfig, source: str) -> bool:
    """Whether the fluxgate magnitude is the measured total field.

    interface.md: when the log has no ``mag``, the fluxgate magnitude is the total field.  It
    is never a silent fallback: that draws a warning (recorded in OUT.json), and a log without
    ``mag`` whose other columns hold a scalar-like field (a misnamed or mis-mapped scalar,
    e.g. ``mag_1_uc``, median 10,000-100,000) is refused unless ``cfg.mag_from_fluxgate``
    (``--mag-from-fluxgate`` on the command line) says so; the option also makes the fluxgate
    magnitude the total field when the log has a ``mag``.

    Parameters
    ----------
    df : DataFrame
        The log (a first batch of rows is enough).
    cfg : CompensationConfig
        Options (``mag_from_fluxgate``).
    source : str
        File name for messages.

    Returns
    -------
    bool
        True when the fluxgate magnitude is the total field.

    Raises
    ------
    InputError
        No ``mag``, a column that looks like one, and no ``cfg.mag_from_fluxgate``.
    """
    has_mag = "mag" in df.columns
    if cfg.mag_from_fluxgate:
        if has_mag:
            log.warning("%s: mag_from_fluxgate=True: the log's 'mag' column is not used; the"
                        " fluxgate magnitude is the measured total field", source)
        return True
    if has_mag:
        return False
    names = {str(c).lower() for c in df.columns}
    scalar_like = [c for c in df.columns if c not in CANONICAL_COLUMNS
                   and not _vector_component(str(c), names) and _field_like(df[c])]
    if scalar_like:
        c = scalar_like[0]
        raise InputError(
            f"{source}: no 'mag' column, but column {c!r} looks like a scalar magnetometer"
            f" (median {float(np.nanmedian(df[c].to_numpy(dtype=np.float64))):.0f}); map it"
            f" with columns={{'mag': '{c}'}}, or pass mag_from_fluxgate=True to take the"
            " fluxgate magnitude as the total field")
    log.warning("%s: no 'mag' column: the fluxgate magnitude is the measured total field"
                " (a model fitted on a scalar magnetometer is not applied to it)", source)
    return True


def _vector_component(name: str, names_lower: set[str]) -> bool:
    """Whether ``name`` is one axis of a 3-axis sensor whose other two axes are columns too.

    A second fluxgate (the MagDrone R3 logs ``B1x..B1z`` and ``B2x..B2z``, no scalar) has
    components of total-field size; they are no misnamed scalar magnetometer.
    """
    m = re.fullmatch(r"(.*?)([_\-. ]?)([xyz])", name, flags=re.IGNORECASE)
    if m is None or not m.group(1):
        return False
    stem, sep, axis = m.group(1).lower(), m.group(2), m.group(3).lower()
    return all(f"{stem}{sep}{a}" in names_lower for a in "xyz" if a != axis)


def _field_like(col: pd.Series) -> bool:
    """A numeric column whose median looks like a total field in nT (10,000-100,000 nT).

    A scalar magnetometer reads a positive total field, so the median must be positive.
    """
    if not pd.api.types.is_numeric_dtype(col) or pd.api.types.is_bool_dtype(col):
        return False
    v = col.to_numpy(dtype=np.float64)
    v = v[np.isfinite(v)]
    return bool(v.size) and 10_000.0 <= float(np.median(v)) <= 100_000.0


def check_total_field(model: Any, mag_from_flux: bool, source: str) -> None:
    """Refuse a model fitted on one kind of total field applied to the other.

    A model fitted on the scalar magnetometer removes the interference the scalar sees; the
    fluxgate's magnitude sees another (and the reverse), so the result would be wrong.

    Parameters
    ----------
    model : TLModel
        The model (its ``meta["mag_from_fluxgate"]`` says what it was fitted on).
    mag_from_flux : bool
        Whether this log's total field is the fluxgate magnitude.
    source : str
        File name for messages.

    Raises
    ------
    InputError
        On a mismatch.
    """
    fitted_on_flux = model.meta.get("mag_from_fluxgate")
    if fitted_on_flux is None or bool(fitted_on_flux) == mag_from_flux:
        return
    kinds = ("the scalar magnetometer ('mag')", "the fluxgate magnitude")
    hint = ("map the scalar with columns={'mag': 'SOURCE'}" if mag_from_flux else
            "pass mag_from_fluxgate=True, or calibrate on the scalar magnetometer")
    raise InputError(f"{source}: the model was fitted on {kinds[bool(fitted_on_flux)]} but this"
                     f" log's total field is {kinds[mag_from_flux]}; applying it would be"
                     f" wrong: {hint}")


def prepare(df: pd.DataFrame, cfg: CompensationConfig, *, source: str | None = None) -> Prepared:
    """Extract and validate the arrays the pipeline needs.

    Parameters
    ----------
    df : DataFrame
        Log with canonical columns (``time``, ``flux_x/y/z``, optional ``mag``, ``line``).
    cfg : CompensationConfig
        Pipeline options.
    source : str, optional
        File name quoted in errors (default ``df.attrs["source"]``).

    Returns
    -------
    Prepared
    """
    src = source or str(df.attrs.get("source", "<log>"))
    missing = [c for c in ("time", *FLUX_COLUMNS) if c not in df.columns]
    if missing:
        raise InputError(
            f"{src}: missing column(s) {', '.join(missing)}; map them with"
            " columns={'NAME': 'SOURCE'}")
    t = df["time"].to_numpy(dtype=np.float64)
    if len(t) < 2:
        raise InputError(f"{src}: only {len(t)} row(s); a log needs many samples to fit")
    flux = np.empty((len(t), 3), dtype=np.float64)
    for j, c in enumerate(FLUX_COLUMNS):
        flux[:, j], _ = interpolate_short_gaps(df[c].to_numpy(dtype=np.float64), t,
                                               cfg.max_interp_s, copy=False)
    # |B|^2 is NaN where any axis is, so one pass finds the usable fluxgate samples.
    bt2 = np.einsum("ij,ij->i", flux, flux)
    flux_ok = np.isfinite(bt2) & (bt2 > 0)
    mag_from_flux = total_field_from_fluxgate(df, cfg, src)
    if mag_from_flux:
        mag = np.sqrt(bt2)
    else:
        mag, _ = interpolate_short_gaps(df["mag"].to_numpy(dtype=np.float64), t, cfg.max_interp_s,
                                        copy=False)
    if not flux_ok.any():
        raise InputError(f"{src}: columns flux_x/flux_y/flux_z hold no usable sample")
    first = flux[int(np.argmax(flux_ok))]
    varies = False
    for j in range(3):
        col = flux[:, j]
        if np.any((col != first[j]) & flux_ok):
            varies = True
            break
    if not varies:
        raise FitError(
            f"{src}: columns flux_x, flux_y, flux_z are constant: the fluxgate did not record"
            " attitude changes; check the column map (columns=...) or the instrument"
        )
    # |flux| once when it is the total field (the same values: a 16 MB temporary fewer)
    check_field_scale(src, mag if mag_from_flux else np.sqrt(bt2), None if mag_from_flux else mag)
    step = _every(flux_ok)
    flux_field = float(np.median(np.sqrt(bt2[::step][flux_ok[::step]])))
    mag_sub = None if mag_from_flux else mag[:: _every(mag)]
    _warn_units(src, flux_field, mag_sub)
    del bt2
    # The Earth field's magnitude: the scalar magnetometer's when there is one.
    fin = mag_sub[np.isfinite(mag_sub)] if mag_sub is not None else np.zeros(0)
    field_nT = float(np.median(fin)) if fin.size else flux_field
    valid = flux_ok & np.isfinite(mag)
    if valid.sum() < 2:
        raise InputError(f"{src}: column 'mag' holds no usable sample")
    stretch = find_stretches(t, valid, cfg.max_gap_s)
    line = df["line"].to_numpy(dtype=np.float64) if "line" in df.columns else None
    if line is not None and not np.isfinite(line).any():
        line = None
    segment = assign_segments(t, stretch, line, cfg.segment_seconds)
    fs = sampling_rate(t)
    _check_time_step(t, fs, cfg, src)
    heading = df["heading"].to_numpy(dtype=np.float64) if "heading" in df.columns else None
    return Prepared(t, flux, mag, flux_ok, valid, stretch, segment, fs, src, mag_from_flux,
                    line_labels(line), field_nT, heading, line is not None)


#: Total fields [nT] taken for an Earth field: it is 22,000-67,000 nT at the surface; the
#: margins leave room for a strong local anomaly.
EARTH_FIELD_RANGE_NT: tuple[float, float] = (1_000.0, 120_000.0)

#: Field units and their factors to nT (as io.units has them), for the message only.
_UNIT_FACTORS = {"uT": 1e3, "mT": 1e6, "G": 1e5, "mG": 1e2, "pT": 1e-3, "T": 1e9}


def check_field_scale(src: str, flux_mag: np.ndarray, mag: np.ndarray | None) -> None:
    """Refuse a total field that is no Earth field in any unit on most samples.

    The total field is the fluxgate magnitude and (when used) ``mag``.  When more than half of
    the finite values lie outside :data:`EARTH_FIELD_RANGE_NT` and their median is no field in
    that range in any known unit either (uT, mT, G, mG, pT, T: those draw the units warning of
    :func:`prepare`, never a conversion), the column holds something else: a logger's error
    value (1.8e19, -9999), a mis-mapped column.  Fewer such samples are spikes, for the QC.

    Parameters
    ----------
    src : str
        File name quoted in the error.
    flux_mag : ndarray
        Fluxgate magnitude per sample [nT].
    mag : ndarray or None
        Scalar magnetometer [nT], or None when the fluxgate magnitude is the total field.

    Raises
    ------
    InputError
        Naming the column, the first such data row and what to do.
    """
    lo, hi = EARTH_FIELD_RANGE_NT
    checks = [("the fluxgate magnitude (flux_x, flux_y, flux_z)", "flux", flux_mag)]
    if mag is not None:
        checks.insert(0, ("column 'mag'", "mag", mag))
    for what, group, v in checks:
        with np.errstate(invalid="ignore"):
            fin = np.isfinite(v)
            out = fin & ~((v >= lo) & (v <= hi))
        n_fin, n_out = int(fin.sum()), int(out.sum())
        if not n_fin or 2 * n_out <= n_fin:
            continue
        med = float(np.median(v[fin]))
        if any(lo <= abs(med) * f <= hi for f in _UNIT_FACTORS.values()):
            continue  # a field in another unit: the units warning says which
        i = int(np.flatnonzero(out)[0])
        raise InputError(
            f"{src}: {what}, data row {i + 1}: {v[i]:.6g} nT, and {n_out} of {n_fin} samples"
            f" (median {med:.4g}) are outside {lo:,.0f}-{hi:,.0f} nT, no Earth field"
            f" (22,000-67,000 nT) in any unit: check the column map (columns=...), the units"
            f" (units={{'{group}': 'UNIT'}}) and the logger")


def _check_time_step(t: np.ndarray, fs: float, cfg: CompensationConfig, src: str) -> None:
    """Refuse a log sampled too slowly for the band when its time looks like ms / us / ns.

    A time step of 1 "s" or more with a band edge above the Nyquist frequency is most often a
    ``time`` logged in milliseconds (a 10 Hz log steps by 100) or microseconds (PX4): the band
    error alone would not say so.  The message names the column, the step and the unit.
    """
    hi = float(cfg.band_hz[1])
    step = 1.0 / fs if fs > 0 else float("inf")
    if hi < fs / 2.0 or not 1.0 <= step < 1e12:
        return
    unit = "ms" if step < 1e3 else "us" if step < 1e6 else "ns"
    raise InputError(
        f"{src}: column 'time' steps by {step:g} s (median), a sampling rate of {fs:g} Hz, too"
        f" slow for band_hz up to {hi:g} Hz; if time is in {unit}, pass"
        f" units={{'time': '{unit}'}}, else choose band_hz below {fs / 2.0:g} Hz")


def _every(x: np.ndarray, most: int = 100_000) -> int:
    """Stride that leaves at most ``most`` samples of ``x`` (for cheap medians)."""
    return max(1, len(x) // most)


def _warn_units(src: str, med: float, mag: np.ndarray | None) -> None:
    """Warn (never convert) when field magnitudes do not look like nT.

    ``med`` is the median fluxgate magnitude, ``mag`` a subsample of the scalar.
    """
    if not 1_000.0 <= med <= 200_000.0:
        log.warning(
            "%s: the fluxgate magnitude is %.4g, not an Earth field in nT (20000-70000);"
            " if the fluxgate is in uT, mT or G pass units={'flux': 'uT'} (or mT, G)", src,
            med)
    if mag is not None:
        fin = mag[np.isfinite(mag)]
        mm = float(np.median(fin)) if fin.size else float("nan")
        if np.isfinite(mm) and not 0.1 < mm / med < 10.0:
            log.warning(
                "%s: median mag %.4g and fluxgate magnitude %.4g differ by more than 10x;"
                " check their units (units={'mag': '...'}, units={'flux': '...'})", src, mm,
                med)

