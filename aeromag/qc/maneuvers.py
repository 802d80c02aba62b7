"""Heading legs and pitch/roll/yaw manoeuvres of a calibration flight.

A compensation calibration ("FOM box") flies the four cardinal headings; on each heading the
aircraft makes a pitch, a roll and a yaw oscillation.  The Figure of Merit (:mod:`aeromag.qc.fom`)
sums the peak-to-peak interference over these 12 manoeuvres, so they must be found first.

Heading legs
    The heading comes from the ``heading`` column (attitude) when present, otherwise from the
    fluxgate (tilt-compensated with ``pitch``/``roll`` when present, level otherwise).  It is
    smoothed (circular moving average within each continuous stretch), the common offset of the
    four headings from the cardinals is estimated (mean of ``4 * heading`` on the circle), and
    each sample gets the nearest cardinal (N=0, E=1, S=2, W=3) when it lies within
    ``tolerance_deg`` of it.  Runs of one cardinal at least ``min_leg_s`` long are legs; the
    k-th visit of a heading belongs to box k.

Manoeuvres
    Each axis gets an angle signal: from the attitude, the high-passed pitch, roll and
    (unwrapped) heading; from the fluxgate alone, the high-passed direction cosines ``dc``
    projected on ``c x e_a`` (the direction a small rotation about body axis ``a`` moves the
    cosines), divided by its norm (an angle in radians).  The moving mean square of each signal
    over ``window_s`` is its energy; a sample is in a manoeuvre of the axis with the largest
    energy (explained share of ``|dc|^2`` for the fluxgate) when that axis' rms angle is above
    ``min_rms_deg``.  Runs shorter than ``min_maneuver_s`` are dropped.

    From the fluxgate alone, roll and yaw move the cosines the same way when the aircraft heads
    along the magnetic meridian (the field then lies in the body x-z plane): such a run is
    *ambiguous* and gets the label missing on its leg, in the customary flight order pitch,
    roll, yaw.  Attitude, when logged, has no such ambiguity.

A user-supplied manoeuvre column (values ``pitch``/``roll``/``yaw``, anything else meaning
none) overrides the detection.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
import pandas as pd

from .._core.angles import wrap_deg
from .._core.filters import sampling_rate
from .._core.runs import run_bounds
from .._core.stretches import find_stretches
from ..errors import InputError
from ._blocks import block_means
from ._heading import heading_unit
from ._lines import clip_to_lines
from ._windows import moving_mean, run_index, run_sums
from .maneuver_result import (
    CARDINALS,
    LABEL_DTYPES,
    MANEUVERS,
    ManeuverResult,
)

__all__ = ["CARDINALS", "MANEUVERS", "ManeuverResult", "detect_heading_legs",
           "detect_maneuvers", "moving_mean"]

log = logging.getLogger(__name__)

_AXIS_OF = {"pitch": 1, "roll": 0, "yaw": 2}


# --------------------------------------------------------------------------- helpers
# --------------------------------------------------------------------------- heading legs
def detect_heading_legs(
    df: pd.DataFrame,
    *,
    min_leg_s: float = 20.0,
    smooth_s: float = 10.0,
    tolerance_deg: float = 15.0,
    declination_deg: float = 0.0,
    max_gap_s: float | None = None,
    leg_column: str | None = None,
) -> tuple[pd.DataFrame, pd.DataFrame, float]:
    """Assign every sample to a cardinal heading leg (or none).

    Parameters
    ----------
    df : DataFrame
        Log with ``time`` [s] and ``heading`` [deg] or ``flux_x/y/z`` [nT].
    min_leg_s : float
        Shortest leg [s].
    smooth_s : float
        Width of the circular moving average of the heading [s].
    tolerance_deg : float
        Largest departure of the smoothed heading from its cardinal [deg].
    declination_deg : float
        Added to fluxgate headings [deg] (only names the cardinals; legs do not depend on it).
    max_gap_s : float, optional
        A longer time step splits legs [s] (default 5 sample intervals).
    leg_column : str, optional
        Column already holding the cardinal index (0-3, negative = none), e.g.
        ``truth_heading_leg``.

    Returns
    -------
    labels : DataFrame
        ``heading_leg``, ``leg_id``, ``box`` per sample.
    legs : DataFrame
        One row per leg.
    offset_deg : float
        Estimated offset of the flown headings from the cardinals [deg].
    """
    t = df["time"].to_numpy(dtype=np.float64)
    n = len(t)
    fs = sampling_rate(t)
    if leg_column is not None:
        card = df[leg_column].to_numpy(dtype=np.float64)
        card = np.where(np.isfinite(card) & (card >= 0), card, -1).astype(np.int64) % 4
        card = np.where(df[leg_column].to_numpy(dtype=np.float64) >= 0, card, -1)
        hs = np.full(n, np.nan)
        sc = None
        offset = 0.0
        stretch = find_stretches(t, None, max_gap_s)
    else:
        unit, ok = heading_unit(df, declination_deg)
        stretch = find_stretches(t, ok, max_gap_s)
        del ok
        half = max(1, int(round(smooth_s * fs / 2)))
        sc = moving_mean(unit, stretch, half)
        del unit  # each intermediate let go once used (the step held ~20 of them)
        hs = np.rad2deg(np.arctan2(sc[:, 1], sc[:, 0]))
        good = np.isfinite(hs)
        if not good.any():
            raise InputError("no usable heading samples for heading-leg detection")
        # Mean of the angle 4*hs (the cardinals fold onto one direction) without trigonometry:
        # from the unit vector (u, v) of hs, cos 2a = u^2 - v^2, sin 2a = 2uv, then again.
        u, v = sc[good, 0], sc[good, 1]
        r2 = u * u + v * v
        c2, s2 = (u * u - v * v) / r2, 2.0 * u * v / r2
        offset = float(np.rad2deg(np.arctan2(np.mean(2.0 * c2 * s2),
                                             np.mean(c2 * c2 - s2 * s2))) / 4.0)
        del u, v, r2, c2, s2
        rel = wrap_deg(hs - offset)
        del hs
        k = np.round(rel / 90.0)
        close = good & (np.abs(rel - 90.0 * k) <= tolerance_deg)
        del good
        card = np.where(close, np.mod(k, 4), -1).astype(np.int64)
        del rel, k, close
    # Runs of one cardinal within one stretch.
    key = np.where((card >= 0) & (stretch >= 0), card + 4 * stretch, -1)
    starts, stops, vals = run_bounds(key)
    dur = t[stops - 1] - t[starts] + 1.0 / fs
    keep = dur >= min_leg_s
    ks, ke, kv = starts[keep], stops[keep], vals[keep]
    card_of_leg = (kv % 4).astype(np.int64)
    box_of_leg = np.zeros(len(kv), dtype=np.int64)  # k-th visit of a heading = box k
    for c in range(4):
        sel = card_of_leg == c
        box_of_leg[sel] = np.arange(int(sel.sum()))
    leg_id = run_index(n, ks, ke)
    inleg = leg_id >= 0
    if len(kv):
        heading_leg = np.where(inleg, card_of_leg[np.maximum(leg_id, 0)], -1)
        box = np.where(inleg, box_of_leg[np.maximum(leg_id, 0)], -1)
    else:  # no heading leg at all (a short or hovering log): nothing to index
        heading_leg = box = np.full(n, -1, dtype=np.int64)
    if sc is not None and len(ks):  # circular mean of the smoothed heading over each leg
        # One reduceat over the legs' [start, stop) pairs (even entries), not a cumulative sum
        # of the whole log differenced at the legs' ends (0.007 s per 1e6 rows less).
        scf = np.zeros((n + 1, 2))
        np.copyto(scf[:n], sc, where=np.isfinite(sc))
        sums = np.add.reduceat(scf, np.column_stack([ks, ke]).ravel(), axis=0)[::2]
        mean_h = np.rad2deg(np.arctan2(sums[:, 1], sums[:, 0])) % 360.0
    else:
        mean_h = 90.0 * card_of_leg.astype(np.float64)
    labels = pd.DataFrame({"heading_leg": heading_leg, "leg_id": leg_id, "box": box},
                          index=df.index)
    legs = pd.DataFrame({"leg_id": np.arange(len(ks)), "box": box_of_leg,
                         "heading_leg": card_of_leg,
                         "heading": np.asarray(CARDINALS, dtype=object)[card_of_leg],
                         "t_start": t[ks], "t_end": t[ke - 1], "mean_heading_deg": mean_h},
                        columns=["leg_id", "box", "heading_leg", "heading", "t_start", "t_end",
                                 "mean_heading_deg"])
    return labels, legs, offset


# --------------------------------------------------------------------------- manoeuvres
def _best_of(share: np.ndarray) -> np.ndarray:
    """Axis of the largest share per sample (axis 0 where the shares are NaN)."""
    return np.argmax(np.where(np.isnan(share), -1.0, share), axis=1)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.cross(a, b)`` of (n, 3) arrays, bitwise, without its axis moves and temporaries."""
    out = np.empty_like(a)
    a0, a1, a2 = a[:, 0], a[:, 1], a[:, 2]
    b0, b1, b2 = b[:, 0], b[:, 1], b[:, 2]
    np.subtract(a1 * b2, a2 * b1, out=out[:, 0])
    np.subtract(a2 * b0, a0 * b2, out=out[:, 1])
    np.subtract(a0 * b1, a1 * b0, out=out[:, 2])
    return out


def _axis_energy(df: pd.DataFrame, stretch: np.ndarray, fs: float, highpass_hz: float,
                 half: int, use_attitude: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per sample: the axis (roll=x, pitch=y, yaw=z) with the largest energy share, that
    axis' rms angle [deg] (0 where undefined), and the ambiguity cosine between the best two
    axes' cosine-motion directions (fluxgate; 0 from attitude)."""
    n = len(df)
    # High-pass: minus the moving mean over 1 / highpass_hz within the leg (a vectorised
    # pass; the legs are many and short, an IIR filter per leg costs a Python call each).
    hw = max(1, int(round(fs / highpass_hz / 2)))

    def highpass(x: np.ndarray) -> np.ndarray:
        return x - moving_mean(x, stretch, hw)

    if use_attitude:
        head = np.unwrap(np.deg2rad(df["heading"].to_numpy(dtype=np.float64)))
        ang = np.column_stack([np.deg2rad(df["roll"].to_numpy(dtype=np.float64)),
                               np.deg2rad(df["pitch"].to_numpy(dtype=np.float64)), head])
        del head
        # In place, each intermediate let go once used (bitwise as highpass, square, share
        # and _best_of on fresh arrays): the attitude energy rose ~+38 MB at 2e6 rows.
        m = moving_mean(ang, stretch, hw)
        np.subtract(ang, m, out=ang)
        del m
        np.square(ang, out=ang)
        e = moving_mean(ang, stretch, half)
        del ang
        tot = e.sum(axis=1, keepdims=True)
        np.maximum(tot, 1e-30, out=tot)
        share = e / tot
        del tot
        np.copyto(share, -1.0, where=np.isnan(share))
        best = np.argmax(share, axis=1)  # _best_of
        del share
        eb = np.take_along_axis(e, best[:, None], axis=1)[:, 0]
        del e
        return best, np.nan_to_num(np.rad2deg(np.sqrt(eb))), np.zeros(n)
    flux = df[["flux_x", "flux_y", "flux_z"]].to_numpy(dtype=np.float64)
    c = flux / np.linalg.norm(flux, axis=1, keepdims=True)
    dc = highpass(c)
    cb = c - dc  # the slowly varying cosines
    # A small rotation about body axis a moves the cosines along v_a = cb x e_a; the motion
    # dc projects on it as (cb x dc)_a / |v_a| (up to sign), with |v_a|^2 = |cb|^2 - cb_a^2.
    vn2 = np.maximum(np.einsum("nk,nk->n", cb, cb)[:, None] - cb * cb, 1e-24)
    num2 = _cross(cb, dc)
    np.square(num2, out=num2)
    stack = np.empty((n, 7))
    np.divide(num2, vn2, out=stack[:, :3])                 # proj^2
    np.divide(stack[:, :3], vn2, out=stack[:, 3:6])        # (proj / |v|)^2: angle^2 [rad^2]
    stack[:, 6] = np.einsum("nk,nk->n", dc, dc)
    mm = moving_mean(stack, stretch, half)
    share = mm[:, :3] / np.maximum(mm[:, 6:7], 1e-30)
    masked = np.where(np.isnan(share), -1.0, share)
    best = np.argmax(masked, axis=1)  # _best_of(share)
    rows = np.arange(n)
    masked[rows, best] = -np.inf
    second = np.argmax(masked, axis=1)
    rms = np.rad2deg(np.sqrt(mm[rows, 3 + best]))
    # cos between v_a and v_b (a != b): |cb_a cb_b| / (|v_a| |v_b|).
    cos12 = np.abs(cb[rows, best] * cb[rows, second]) / np.sqrt(vn2[rows, best]
                                                                * vn2[rows, second])
    return best, np.nan_to_num(rms), cos12


def detect_maneuvers(
    df: pd.DataFrame,
    *,
    rate_hz: float | None = 2.0,
    maneuver_column: str | None = None,
    leg_column: str | None = None,
    source: str | None = None,
    min_leg_s: float = 20.0,
    min_maneuver_s: float = 10.0,
    window_s: float = 4.0,
    highpass_hz: float = 0.04,
    min_rms_deg: float = 1.0,
    ambiguity_cos: float = 0.95,
    smooth_s: float = 10.0,
    tolerance_deg: float = 15.0,
    declination_deg: float = 0.0,
    max_gap_s: float | None = None,
    fs_hz: float | None = None,
) -> ManeuverResult:
    """Find the heading legs and the pitch/roll/yaw manoeuvres of a calibration flight.

    Parameters
    ----------
    df : DataFrame
        Log with ``time`` [s] and attitude (``heading``, ``pitch``, ``roll`` [deg]) and/or the
        fluxgate (``flux_x/y/z`` [nT]).
    maneuver_column : str, optional
        Column holding the manoeuvre of each sample (``pitch``/``roll``/``yaw``); default a
        column named ``maneuver`` when the log has one, else detection.
    leg_column : str, optional
        Column holding the cardinal index (0-3) of each sample; default: detection.
    source : str, optional
        Name for messages.
    min_leg_s, min_maneuver_s : float
        Shortest heading leg and manoeuvre [s].
    window_s : float
        Width of the moving energy window [s].
    highpass_hz : float
        High-pass removing each leg's mean attitude/cosines [Hz].
    min_rms_deg : float
        Smallest rms angle of a manoeuvre [deg].
    ambiguity_cos : float
        Fluxgate only: the best two axes are ambiguous when their cosine-motion directions
        have ``|cos|`` above this.
    smooth_s, tolerance_deg, declination_deg, max_gap_s : float
        See :func:`detect_heading_legs`.
    rate_hz : float or None
        Working rate of the detection [Hz]: a log sampled faster is reduced to means over
        blocks of ``floor(fs / rate_hz)`` samples (within each continuous stretch, headings on
        the circle) before detection, and the labels are expanded back to every sample.  The
        detection's own time scales (10 s heading smoothing, 4 s energy windows, 10 s shortest
        manoeuvre) are far longer than 1 / rate_hz, so this costs a few tenths of a second of
        edge placement and saves most of the time on 10 Hz to 1 kHz logs.  None: full rate.
    fs_hz : float, optional
        Sampling rate of ``df`` [Hz] when the caller knows it (default: from ``time``).

    Returns
    -------
    ManeuverResult
    """
    src = source or str(df.attrs.get("source", "<log>"))
    if "time" not in df.columns:
        raise InputError(f"{src}: missing column 'time'")
    if len(df) < 10:
        raise InputError(f"{src}: only {len(df)} rows; too few for manoeuvre detection")
    if maneuver_column is None and "maneuver" in df.columns:
        maneuver_column = "maneuver"
    kw = dict(maneuver_column=maneuver_column, leg_column=leg_column, source=src,
              min_leg_s=min_leg_s, min_maneuver_s=min_maneuver_s, window_s=window_s,
              highpass_hz=highpass_hz, min_rms_deg=min_rms_deg, ambiguity_cos=ambiguity_cos,
              smooth_s=smooth_s, tolerance_deg=tolerance_deg,
              declination_deg=declination_deg)
    t = df["time"].to_numpy(dtype=np.float64)
    fs = sampling_rate(t) if fs_hz is None else fs_hz
    step = int(fs // rate_hz) if rate_hz else 1
    if step < 2 or maneuver_column is not None or leg_column is not None:
        res = _narrow(_detect_full(df, max_gap_s=max_gap_s, **kw))
    else:
        small, cnt = block_means(df, t, step, 5.0 / fs if max_gap_s is None else max_gap_s)
        if len(small) < 10:
            del small
            res = _narrow(_detect_full(df, max_gap_s=max_gap_s, **kw))
        else:
            red = _detect_full(small, max_gap_s=None, **kw)
            del small
            res = _expand(red, df, t, fs, cnt)
            del red
    # a manoeuvre never spans two lines (its tail would sample a neighbour, maybe a fault)
    if "line" in df.columns:
        res = clip_to_lines(res, df["line"], t, fs)
    return res


def _narrow(res: ManeuverResult) -> ManeuverResult:
    """``res`` with its labels in :data:`LABEL_DTYPES` (as :func:`_expand` builds them)."""
    res.labels = res.labels.astype(LABEL_DTYPES)
    return res


def _expand(res: ManeuverResult, df: pd.DataFrame, t: np.ndarray, fs: float,
            cnt: np.ndarray) -> ManeuverResult:
    """Labels and tables of a block-rate detection on every sample of the log."""
    lab = res.labels
    # Each label repeated once, straight into its own narrow dtype (LABEL_DTYPES), and handed
    # to the frame without the copy into one consolidated int64 block: the four int64 columns
    # and their copy peaked at +140 MB at 2e6 rows, the labels now hold 28 MB.
    cols: dict[str, Any] = {c: np.repeat(lab[c].to_numpy().astype(LABEL_DTYPES[c]), cnt)
                            for c in ("heading_leg", "leg_id", "box")}
    cols["maneuver"] = pd.Categorical.from_codes(
        np.repeat(np.asarray(lab["maneuver"].cat.codes), cnt),
        categories=lab["maneuver"].cat.categories)
    cols["maneuver_id"] = np.repeat(
        lab["maneuver_id"].to_numpy().astype(LABEL_DTYPES["maneuver_id"]), cnt)
    labels = pd.DataFrame(cols, index=df.index, copy=False)
    first = np.r_[0, np.cumsum(cnt)]  # block k spans samples first[k]:first[k + 1]
    legs = res.legs.copy()
    table = res.table.copy()
    for tab, col, key in ((legs, "leg_id", "leg_id"), (table, "maneuver_id", "id")):
        if tab.empty:
            continue
        a, b, ids = run_bounds(lab[col].to_numpy())  # in blocks
        pos = np.searchsorted(ids, tab[key].to_numpy())
        sa, sb = first[a[pos]], first[b[pos]]
        tab["t_start"] = t[sa]
        tab["t_end"] = t[sb - 1]
        if col == "maneuver_id":
            tab["n"] = sb - sa
            tab["duration_s"] = t[sb - 1] - t[sa] + 1.0 / fs
    return ManeuverResult(labels, table, legs, res.method, res.heading_offset_deg, res.notes)


def _detect_full(
    df: pd.DataFrame,
    *,
    maneuver_column: str | None,
    leg_column: str | None,
    source: str,
    min_leg_s: float,
    min_maneuver_s: float,
    window_s: float,
    highpass_hz: float,
    min_rms_deg: float,
    ambiguity_cos: float,
    smooth_s: float,
    tolerance_deg: float,
    declination_deg: float,
    max_gap_s: float | None,
) -> ManeuverResult:
    """:func:`detect_maneuvers` at the log's own rate."""
    src = source
    if "time" not in df.columns:
        raise InputError(f"{src}: missing column 'time'")
    if len(df) < 10:
        raise InputError(f"{src}: only {len(df)} rows; too few for manoeuvre detection")
    if maneuver_column is None and "maneuver" in df.columns:
        maneuver_column = "maneuver"
    if maneuver_column is not None and maneuver_column not in df.columns:
        raise InputError(f"{src}: no column {maneuver_column!r} for the manoeuvres")
    labels, legs, offset = detect_heading_legs(
        df, min_leg_s=min_leg_s, smooth_s=smooth_s, tolerance_deg=tolerance_deg,
        declination_deg=declination_deg, max_gap_s=max_gap_s, leg_column=leg_column)
    t = df["time"].to_numpy(dtype=np.float64)
    n = len(t)
    fs = sampling_rate(t)
    notes: list[str] = []
    leg_id = labels["leg_id"].to_numpy()
    has_att = {"heading", "pitch", "roll"} <= set(df.columns) and bool(
        df[["heading", "pitch", "roll"]].notna().all(axis=1).mean() > 0.5)
    rms_axis = np.full(n, np.nan)
    ambiguous = np.zeros(n, dtype=bool)
    if maneuver_column is not None:
        method = f"column:{maneuver_column}"
        vals = df[maneuver_column].astype(str).str.strip().str.lower().to_numpy()
        code = np.full(n, -1, dtype=np.int64)
        for j, m in enumerate(MANEUVERS):
            code[vals == m] = j
    else:
        method = "attitude" if has_att else "fluxgate"
        if not has_att and not {"flux_x", "flux_y", "flux_z"} <= set(df.columns):
            raise InputError(f"{src}: manoeuvre detection needs heading/pitch/roll or the"
                             " fluxgate flux_x/flux_y/flux_z")
        cols = ["heading", "pitch", "roll"] if has_att else ["flux_x", "flux_y", "flux_z"]
        ok = df[cols].notna().all(axis=1).to_numpy()
        # Filter within each leg only: turns between legs must not ring into the manoeuvres.
        stretch = np.where(ok & (leg_id >= 0), leg_id, -1)
        half = max(1, int(round(window_s * fs / 2)))
        best_axis, best_rms, cos12 = _axis_energy(df, stretch, fs, highpass_hz, half, has_att)
        axis_to_man = np.array([_AXIS_OF[m] for m in MANEUVERS])  # man index -> axis
        man_of_axis = np.argsort(axis_to_man)  # axis -> man index
        active = (best_rms >= min_rms_deg) & (leg_id >= 0)
        code = np.where(active, man_of_axis[best_axis], -1)
        rms_axis = best_rms
        ambiguous = active & (cos12 > ambiguity_cos)
    code = np.where(leg_id >= 0, code, -1)
    # Runs of one manoeuvre within one leg; drop short ones.
    key = np.where(code >= 0, code + 3 * leg_id, -1)
    starts, stops, vals = run_bounds(key)
    dur = t[stops - 1] - t[starts] + 1.0 / fs
    keep = dur >= min_maneuver_s
    starts, stops, vals = starts[keep], stops[keep], vals[keep]
    lid = (vals // 3).astype(np.int64)
    man_code = (vals % 3).astype(np.int64)
    length = stops - starts
    amb = (2 * run_sums(ambiguous.astype(np.int64), starts, stops) > length) \
        if len(starts) else np.zeros(0, dtype=bool)
    if method == "fluxgate":
        _resolve_ambiguous(lid, man_code, amb, notes)
    leg_box = legs["box"].to_numpy(dtype=np.int64)
    leg_card = legs["heading_leg"].to_numpy(dtype=np.int64)
    rms_sum = run_sums(np.where(np.isfinite(rms_axis), rms_axis, np.nan), starts, stops)
    table = pd.DataFrame({
        "id": np.arange(len(starts)), "box": leg_box[lid], "heading_leg": leg_card[lid],
        "heading": np.asarray(CARDINALS, dtype=object)[leg_card[lid]],
        "maneuver": np.asarray(MANEUVERS, dtype=object)[man_code], "leg_id": lid,
        "t_start": t[starts], "t_end": t[stops - 1],
        "duration_s": t[stops - 1] - t[starts] + 1.0 / fs, "n": length,
        "rms_deg": rms_sum / np.maximum(length, 1), "ambiguous": amb.astype(bool)})
    mid = run_index(n, starts, stops)
    codes = np.where(mid >= 0, man_code[np.maximum(mid, 0)] + 1, 0) if len(starts) \
        else np.zeros(n, dtype=np.int64)
    labels["maneuver"] = pd.Categorical.from_codes(codes, categories=["", *MANEUVERS])
    labels["maneuver_id"] = mid
    res = ManeuverResult(labels, table, legs, method, offset, notes)
    full = res.complete_boxes
    nb = int(table["box"].nunique()) if len(table) else 0
    if nb and len(full) < nb:
        notes.append(f"{nb - len(full)} of {nb} box(es) miss some of the 12 manoeuvres")
    log.info("%s: %d legs, %d manoeuvres (%s), complete boxes %s", src, len(legs), len(table),
             method, full)
    return res


def _resolve_ambiguous(lid: np.ndarray, man: np.ndarray, amb: np.ndarray,
                       notes: list[str]) -> None:
    """Fluxgate roll/yaw ambiguity: give ambiguous runs the labels missing on their leg.

    ``lid`` (leg of each run, runs in time order), ``man`` (manoeuvre index, changed in place)
    and ``amb`` (ambiguous flag) describe the runs.
    """
    n_fixed = 0
    if amb.any():  # vectorised over legs (a Python loop per leg is quadratic in the legs)
        legs, pos = np.unique(lid, return_inverse=True)
        nm = len(MANEUVERS)
        sure = np.zeros((len(legs), nm), dtype=bool)
        sure[pos[~amb], man[~amb]] = True
        n_missing = nm - sure.sum(axis=1)
        n_unsure = np.bincount(pos[amb], minlength=len(legs))
        runs = np.flatnonzero(amb & (n_unsure == n_missing)[pos])
        runs = runs[np.argsort(pos[runs], kind="stable")]  # by leg, in flight order
        if len(runs):
            leg_of = pos[runs]
            first = np.searchsorted(leg_of, leg_of)  # first run of the same leg
            rank = np.arange(len(runs)) - first
            missing = np.argsort(sure, axis=1, kind="stable")  # missing manoeuvres first
            new = missing[leg_of, rank]
            n_fixed = int(np.count_nonzero(man[runs] != new))
            man[runs] = new
    if amb.any():
        notes.append("fluxgate only: roll and yaw cannot be told apart on headings along the"
                     " magnetic meridian; ambiguous manoeuvres were named in flight order"
                     f" pitch, roll, yaw ({n_fixed} renamed)")
