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
    flux: np.ndarray | None  # (n, 3) float64; None with prepare(flux_columns=True)
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
    #: The log's fluxgate columns themselves (float32 or float64), with short gaps filled,
    #: when :func:`prepare` was called with ``flux_columns=True`` (``flux`` is then None).
    flux_columns: tuple[np.ndarray, ...] | None = None



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
        The model (its ``meta.mag_from_fluxgate`` says what it was fitted on).
    mag_from_flux : bool
        Whether this log's total field is the fluxgate magnitude.
    source : str
        File name for messages.

    Raises
    ------
    InputError
        On a mismatch.
    """
    fitted_on_flux = model.meta.mag_from_fluxgate
    if fitted_on_flux is None or bool(fitted_on_flux) == mag_from_flux:
        return
    kinds = ("the scalar magnetometer ('mag')", "the fluxgate magnitude")
    hint = ("map the scalar with columns={'mag': 'SOURCE'}" if mag_from_flux else
            "pass mag_from_fluxgate=True, or calibrate on the scalar magnetometer")
    raise InputError(f"{source}: the model was fitted on {kinds[bool(fitted_on_flux)]} but this"
                     f" log's total field is {kinds[mag_from_flux]}; applying it would be"
                     f" wrong: {hint}")


def prepare(
    df: pd.DataFrame, cfg: CompensationConfig, *, source: str | None = None,
    flux_columns: bool = False, segment: np.ndarray | None = None,
) -> Prepared:
    """Extract and validate the arrays the pipeline needs.

    Parameters
    ----------
    df : DataFrame
        Log with canonical columns (``time``, ``flux_x/y/z``, optional ``mag``, ``line``).
    cfg : CompensationConfig
        Pipeline options.
    source : str, optional
        File name quoted in errors (default ``df.attrs["source"]``).
    flux_columns : bool
        Keep the fluxgate as the log's own three columns (``Prepared.flux_columns``;
        ``Prepared.flux`` is None) and form its magnitude [nT] block by block, instead of an
        (n, 3) float64 copy and a full-length magnitude: the same values and checks, 64 MB
        fewer at 2e6 rows.  Only
        :func:`aeromag.compensation.normal.segment_normal_equations` reads such a result.
    segment : ndarray of int, shape (n,), optional
        Segment id per sample to use as they are (e.g. a compensated log's ``segment``
        column): segments are then not assigned from ``line`` or ``segment_seconds``
        (``line_of_segment`` is None, nothing is said about negative line numbers).

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
    if flux_columns:
        return _prepare_columns(df, cfg, src, t, segment)
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
    _check_varies(src, [flux[:, j] for j in range(3)], flux[int(np.argmax(flux_ok))], flux_ok)
    # |flux| once when it is the total field (the same values: a 16 MB temporary fewer)
    check_field_scale(src, mag if mag_from_flux else np.sqrt(bt2), None if mag_from_flux else mag)
    step = _every(flux_ok)
    flux_field = float(np.median(np.sqrt(bt2[::step][flux_ok[::step]])))
    del bt2
    return _finish(df, cfg, src, t, flux, None, mag, flux_ok, mag_from_flux, flux_field, segment)


def _check_varies(src: str, cols: list[np.ndarray], first: np.ndarray,
                  flux_ok: np.ndarray) -> None:
    """Refuse a fluxgate constant over its usable samples (``first``: the first such row)."""
    for j, col in enumerate(cols):
        if np.any((col != first[j]) & flux_ok):
            return
    raise FitError(
        f"{src}: columns flux_x, flux_y, flux_z are constant: the fluxgate did not record"
        " attitude changes; check the column map (columns=...) or the instrument"
    )


def _field_squared(cols: tuple[np.ndarray, ...], rows: slice | np.ndarray) -> np.ndarray:
    """|B|^2 [nT^2] of the fluxgate rows ``rows`` of its columns, as prepare forms it.

    The rows are cast to an (m, 3) float64 block and reduced by the same einsum as the
    whole (n, 3) copy: bitwise the same values, row by row.
    """
    first = cols[0][rows]
    f = np.empty((len(first), 3))
    f[:, 0] = first
    f[:, 1] = cols[1][rows]
    f[:, 2] = cols[2][rows]
    return np.einsum("ij,ij->i", f, f)


#: Rows per block where :func:`prepare` forms the fluxgate magnitude of its columns.
_BLOCK_ROWS = 1 << 16


def _prepare_columns(df: pd.DataFrame, cfg: CompensationConfig, src: str, t: np.ndarray,
                     segment: np.ndarray | None) -> Prepared:
    """:func:`prepare` with ``flux_columns=True``: the same checks, in the same order."""
    cols = []
    for c in FLUX_COLUMNS:
        col = df[c].to_numpy()
        if col.dtype not in (np.float32, np.float64):
            col = df[c].to_numpy(dtype=np.float64)
        if not np.isfinite(col).all():
            filled, n_filled = interpolate_short_gaps(col, t, cfg.max_interp_s, copy=False)
            if n_filled:
                col = filled  # float64: interpolated values
        cols.append(col)
    cols_t = tuple(cols)
    # Nothing above warns or raises: the total field is decided first, as prepare does
    # after its (n, 3) copy.
    mag_from_flux = total_field_from_fluxgate(df, cfg, src)
    n = len(t)
    flux_ok = np.empty(n, dtype=bool)
    mag = np.empty(n) if mag_from_flux else None
    lo, hi = EARTH_FIELD_RANGE_NT
    n_fin = n_out = 0
    for a in range(0, n, _BLOCK_ROWS):
        blk = slice(a, a + _BLOCK_ROWS)
        bt2 = _field_squared(cols_t, blk)
        np.isfinite(bt2, out=flux_ok[blk])
        flux_ok[blk] &= bt2 > 0
        if mag is not None:
            fm = np.sqrt(bt2, out=mag[blk])
        else:
            fm = np.sqrt(bt2)
        with np.errstate(invalid="ignore"):
            fin = np.isfinite(fm)
            n_fin += int(fin.sum())
            n_out += int((fin & ~((fm >= lo) & (fm <= hi))).sum())
    if mag is None:
        mag, _ = interpolate_short_gaps(df["mag"].to_numpy(dtype=np.float64), t, cfg.max_interp_s,
                                        copy=False)
    if not flux_ok.any():
        raise InputError(f"{src}: columns flux_x/flux_y/flux_z hold no usable sample")
    i0 = int(np.argmax(flux_ok))
    _check_varies(src, cols, np.array([c[i0] for c in cols], dtype=np.float64), flux_ok)
    # The fluxgate magnitude is only needed in full when check_field_scale may refuse it
    # (counted above with its own rule); otherwise an empty array passes its check as the
    # full one would.
    flux_mag = np.zeros(0)
    if n_fin and 2 * n_out > n_fin:
        flux_mag = mag if mag_from_flux else np.sqrt(_field_squared(cols_t, slice(None)))
    check_field_scale(src, flux_mag, None if mag_from_flux else mag)
    step = _every(flux_ok)
    bt2 = _field_squared(cols_t, slice(None, None, step))
    flux_field = float(np.median(np.sqrt(bt2[flux_ok[::step]])))
    return _finish(df, cfg, src, t, None, cols_t, mag, flux_ok, mag_from_flux, flux_field,
                   segment)


def _stretches_int32(t: np.ndarray, valid: np.ndarray, max_gap_s: float | None,
                     block: int = _BLOCK_ROWS) -> np.ndarray:
    """:func:`find_stretches` labels as int32, block by block (no full-length temporaries).

    The same labels: a sample starts a stretch where it is valid and either its
    predecessor is not or the step to it exceeds ``max_gap_s``; labels count the starts.
    """
    n = len(t)
    if max_gap_s is None or n == 0 or n >= 2**31 - 1:
        return find_stretches(t, valid, max_gap_s).astype(np.int32)
    lab = np.empty(n, dtype=np.int32)
    last = -1  # label of the last stretch started
    for a in range(0, n, block):
        b = min(a + block, n)
        ok = valid[a:b]
        new = np.ones(b - a, dtype=bool)
        if a:
            # The step from the block's previous sample, as in the whole-log difference.
            np.less_equal(np.diff(t[a - 1:b]), max_gap_s, out=new)
            new &= valid[a - 1:b - 1]
        else:
            np.less_equal(np.diff(t[:b]), max_gap_s, out=new[1:])
            new[1:] &= ok[:-1]
        new &= ok
        if a:
            np.logical_not(new, out=new)
        else:
            np.logical_not(new[1:], out=new[1:])
        new &= ok
        np.cumsum(new, dtype=np.int32, out=lab[a:b])
        lab[a:b] += last
        last = int(lab[b - 1])
        lab[a:b][~ok] = -1
    return lab


def _finish(df: pd.DataFrame, cfg: CompensationConfig, src: str, t: np.ndarray,
            flux: np.ndarray | None, cols: tuple[np.ndarray, ...] | None, mag: np.ndarray,
            flux_ok: np.ndarray, mag_from_flux: bool, flux_field: float,
            segment: np.ndarray | None) -> Prepared:
    """The rest of :func:`prepare` once the fluxgate and the total field are read."""
    mag_sub = None if mag_from_flux else mag[:: _every(mag)]
    _warn_units(src, flux_field, mag_sub)
    # The Earth field's magnitude: the scalar magnetometer's when there is one.
    fin = mag_sub[np.isfinite(mag_sub)] if mag_sub is not None else np.zeros(0)
    field_nT = float(np.median(fin)) if fin.size else flux_field
    valid = flux_ok & np.isfinite(mag)
    if valid.sum() < 2:
        raise InputError(f"{src}: column 'mag' holds no usable sample")
    if segment is not None:
        # The sampling rate first (its median's temporaries are gone before the stretches'
        # exist); with the segments given nothing in between can raise.
        fs = sampling_rate(t)
        _check_time_step(t, fs, cfg, src)
        stretch = (find_stretches(t, valid, cfg.max_gap_s) if cols is None
                   else _stretches_int32(t, valid, cfg.max_gap_s))
        from_line = "line" in df.columns and bool(
            np.isfinite(df["line"].to_numpy(dtype=np.float64)).any())
        line_of_segment = None
    else:
        stretch = find_stretches(t, valid, cfg.max_gap_s)
        line = df["line"].to_numpy(dtype=np.float64) if "line" in df.columns else None
        if line is not None and not np.isfinite(line).any():
            line = None
        segment = assign_segments(t, stretch, line, cfg.segment_seconds)
        fs = sampling_rate(t)
        _check_time_step(t, fs, cfg, src)
        from_line = line is not None
        line_of_segment = line_labels(line)
    heading = df["heading"].to_numpy(dtype=np.float64) if "heading" in df.columns else None
    return Prepared(t, flux, mag, flux_ok, valid, stretch, segment, fs, src, mag_from_flux,
                    line_of_segment, field_nT, heading, from_line, cols)


#: Total fields [nT] taken for an Earth field: it is 22,000-67,000 nT at the surface; the
#: margins leave room for a strong local anomaly.
EARTH_FIELD_RANGE_NT: tuple[float, float] = (1_000.0, 120_000.0)

#: The Earth's field at the surface [nT]: a total field whose median is this in uT or G is
#: refused with the units remedy (a level off by 1000 or 1e5 would be silent otherwise).
EARTH_FIELD_NT: tuple[float, float] = (20_000.0, 70_000.0)
#: Units a total-field log is found in instead of nT (issue 30: uT, and gauss).
TOTAL_FIELD_UNITS = ("uT", "G")

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
        unit = next((u for u, f in _UNIT_FACTORS.items() if lo <= abs(med) * f <= hi), None)
        total = next((u for u in TOTAL_FIELD_UNITS if EARTH_FIELD_NT[0] <= med
                      * _UNIT_FACTORS[u] <= EARTH_FIELD_NT[1]), None)
        if total is not None and (group == "mag" or mag is None):
            unit = total
            # The total field itself in another unit: every level and the residual would be
            # off by that factor ("residual std 0.0001 nT"): never go on silently.
            key = "mag" if group == "mag" else "flux"
            i = int(np.flatnonzero(out)[0])
            raise InputError(
                f"{src}: {what}, data row {i + 1}: {v[i]:.6g}, median {med:.4g}: no Earth"
                f" field in nT (22,000-67,000 nT), but {med * _UNIT_FACTORS[unit]:,.0f} nT if"
                f" it is in {unit}: pass units={{'{key}': '{unit}'}}"
                + (" (and units={'flux': ...} if the fluxgate is not in nT either)"
                   if key == "mag" else "") + ", or check the column map (columns=...)")
        if unit is not None:
            continue  # the fluxgate beside a scalar in nT: the units warning says which
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

