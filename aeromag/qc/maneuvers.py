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
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from .._core.angles import wrap_deg
from .._core.filters import butter_sos, filter_stretches, sampling_rate
from .._core.rotations import rotate_body_to_ned
from .._core.runs import run_bounds
from .._core.stretches import find_stretches
from ..errors import InputError

__all__ = ["CARDINALS", "MANEUVERS", "ManeuverResult", "detect_heading_legs",
           "detect_maneuvers", "moving_mean"]

log = logging.getLogger(__name__)

#: Cardinal headings in order of ``heading_leg`` (N=0, E=1, S=2, W=3).
CARDINALS: tuple[str, ...] = ("N", "E", "S", "W")
#: Manoeuvre names in customary flight order (also the order of the body rotation axes used:
#: pitch = body y, roll = body x, yaw = body z).
MANEUVERS: tuple[str, ...] = ("pitch", "roll", "yaw")
_AXIS_OF = {"pitch": 1, "roll": 0, "yaw": 2}


@dataclass
class ManeuverResult:
    """Heading legs and manoeuvres of a flight.

    Attributes
    ----------
    labels : DataFrame
        One row per input sample (same index): ``heading_leg`` (0-3, -1 outside legs),
        ``leg_id`` (run number, -1), ``box`` (visit number of that heading, -1),
        ``maneuver`` ("pitch"/"roll"/"yaw" or ""), ``maneuver_id`` (row of ``table``, -1).
    table : DataFrame
        One row per manoeuvre: ``id``, ``box``, ``heading_leg``, ``heading`` (N/E/S/W),
        ``maneuver``, ``t_start``/``t_end`` [s], ``duration_s`` [s], ``n`` (samples),
        ``rms_deg`` (rms angle of the manoeuvre axis, deg; NaN from a column), ``ambiguous``.
    legs : DataFrame
        One row per heading leg: ``leg_id``, ``box``, ``heading_leg``, ``heading``,
        ``t_start``/``t_end`` [s], ``mean_heading_deg``.
    method : str
        ``"attitude"``, ``"fluxgate"`` or ``"column:<name>"``.
    heading_offset_deg : float
        Common offset of the flown headings from the cardinals [deg].
    notes : list of str
        Anything the user should know (ambiguities, incomplete boxes).
    """

    labels: pd.DataFrame
    table: pd.DataFrame
    legs: pd.DataFrame
    method: str
    heading_offset_deg: float = 0.0
    notes: list[str] = field(default_factory=list)

    @property
    def complete_boxes(self) -> list[int]:
        """Boxes with all 12 (heading, manoeuvre) pairs."""
        t = self.table
        if t.empty:
            return []
        n = t.groupby("box")[["heading_leg", "maneuver"]].apply(
            lambda g: len(set(zip(g["heading_leg"], g["maneuver"], strict=True))))
        return [int(b) for b, c in n.items() if c == 12]


# --------------------------------------------------------------------------- helpers
def moving_mean(x: np.ndarray, stretch: np.ndarray, half_width: int) -> np.ndarray:
    """Centred moving mean within each stretch (windows shrink at stretch ends), vectorised.

    Parameters
    ----------
    x : ndarray, shape (n,) or (n, m)
        Samples (finite on valid samples).
    stretch : ndarray of int, shape (n,)
        Stretch labels; negative = invalid (output NaN).
    half_width : int
        Half window in samples (window ``2 * half_width + 1``).

    Returns
    -------
    ndarray
        Same shape as ``x``.
    """
    xv = np.asarray(x, dtype=np.float64)
    x2 = xv if xv.ndim == 2 else xv[:, None]
    n = len(x2)
    out = np.full_like(x2, np.nan)
    starts, stops, _ = run_bounds(stretch)
    if len(starts) == 0:
        return out if xv.ndim == 2 else out[:, 0]
    lens = stops - starts
    lo_b = np.repeat(starts, lens)
    hi_b = np.repeat(stops, lens)
    idx = np.flatnonzero(np.asarray(stretch) >= 0)
    cs = np.zeros((n + 1, x2.shape[1]))
    cs[1:] = np.cumsum(np.where(np.isfinite(x2), x2, 0.0), axis=0)
    lo = np.maximum(idx - half_width, lo_b)
    hi = np.minimum(idx + half_width + 1, hi_b)
    out[idx] = (cs[hi] - cs[lo]) / (hi - lo)[:, None]
    return out if xv.ndim == 2 else out[:, 0]


def _heading_source(df: pd.DataFrame, declination_deg: float) -> tuple[np.ndarray, str]:
    if "heading" in df.columns and df["heading"].notna().any():
        return df["heading"].to_numpy(dtype=np.float64), "attitude"
    if not {"flux_x", "flux_y", "flux_z"} <= set(df.columns):
        raise InputError("manoeuvre detection needs a 'heading' column or flux_x/flux_y/flux_z")
    z = np.zeros(len(df))
    pitch = df["pitch"].to_numpy(dtype=np.float64) if "pitch" in df.columns else z
    roll = df["roll"].to_numpy(dtype=np.float64) if "roll" in df.columns else z
    # Levelled field (roll and pitch undone, yaw 0): the magnetic heading is atan2(-y, x).
    flux = df[["flux_x", "flux_y", "flux_z"]].to_numpy(dtype=np.float64)
    lev = rotate_body_to_ned(flux, np.deg2rad(np.nan_to_num(roll)),
                             np.deg2rad(np.nan_to_num(pitch)), 0.0)
    h = np.mod(np.rad2deg(np.arctan2(-lev[:, 1], lev[:, 0])) + float(declination_deg), 360.0)
    return h, "fluxgate"


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
        offset = 0.0
        stretch = find_stretches(t, None, max_gap_s)
    else:
        h, _ = _heading_source(df, declination_deg)
        ok = np.isfinite(h)
        stretch = find_stretches(t, ok, max_gap_s)
        rad = np.deg2rad(np.where(ok, h, 0.0))
        half = max(1, int(round(smooth_s * fs / 2)))
        sc = moving_mean(np.column_stack([np.cos(rad), np.sin(rad)]), stretch, half)
        hs = np.rad2deg(np.arctan2(sc[:, 1], sc[:, 0]))
        good = np.isfinite(hs)
        if not good.any():
            raise InputError("no usable heading samples for heading-leg detection")
        four = np.deg2rad(4.0 * hs[good])
        offset = float(np.rad2deg(np.arctan2(np.sin(four).mean(), np.cos(four).mean())) / 4.0)
        rel = wrap_deg(hs - offset)
        k = np.round(rel / 90.0)
        close = good & (np.abs(rel - 90.0 * k) <= tolerance_deg)
        card = np.where(close, np.mod(k, 4), -1).astype(np.int64)
    # Runs of one cardinal within one stretch.
    key = np.where((card >= 0) & (stretch >= 0), card + 4 * stretch, -1)
    starts, stops, vals = run_bounds(key)
    dur = t[stops - 1] - t[starts] + 1.0 / fs
    keep = dur >= min_leg_s
    heading_leg = np.full(n, -1, dtype=np.int64)
    leg_id = np.full(n, -1, dtype=np.int64)
    box = np.full(n, -1, dtype=np.int64)
    rows: list[dict[str, Any]] = []
    visits = np.zeros(4, dtype=np.int64)
    for j, (a, b, v) in enumerate(zip(starts[keep], stops[keep], vals[keep], strict=True)):
        c = int(v % 4)
        heading_leg[a:b] = c
        leg_id[a:b] = j
        box[a:b] = visits[c]
        seg_h = hs[a:b]
        mh = float(np.rad2deg(np.arctan2(np.nanmean(np.sin(np.deg2rad(seg_h))),
                                         np.nanmean(np.cos(np.deg2rad(seg_h)))))) % 360.0 \
            if np.isfinite(seg_h).any() else float(90.0 * c)
        rows.append({"leg_id": j, "box": int(visits[c]), "heading_leg": c,
                     "heading": CARDINALS[c], "t_start": float(t[a]), "t_end": float(t[b - 1]),
                     "mean_heading_deg": mh})
        visits[c] += 1
    labels = pd.DataFrame({"heading_leg": heading_leg, "leg_id": leg_id, "box": box},
                          index=df.index)
    legs = pd.DataFrame(rows, columns=["leg_id", "box", "heading_leg", "heading", "t_start",
                                       "t_end", "mean_heading_deg"])
    return labels, legs, offset


# --------------------------------------------------------------------------- manoeuvres
def _axis_energy(df: pd.DataFrame, stretch: np.ndarray, fs: float, highpass_hz: float,
                 half: int, use_attitude: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-sample energy share per axis (roll=x, pitch=y, yaw=z), rms angle [deg], ambiguity
    cosine between the best two axes' directions."""
    n = len(df)
    sos = butter_sos("highpass", highpass_hz, fs, 2, option="highpass_hz")
    if use_attitude:
        head = np.unwrap(np.deg2rad(df["heading"].to_numpy(dtype=np.float64)))
        ang = np.column_stack([np.deg2rad(df["roll"].to_numpy(dtype=np.float64)),
                               np.deg2rad(df["pitch"].to_numpy(dtype=np.float64)), head])
        hp = filter_stretches(ang, stretch, sos, axis=0)
        e = moving_mean(hp**2, stretch, half)
        share = e / np.maximum(e.sum(axis=1, keepdims=True), 1e-30)
        rms = np.rad2deg(np.sqrt(e))
        return share, rms, np.zeros(n)
    flux = df[["flux_x", "flux_y", "flux_z"]].to_numpy(dtype=np.float64)
    c = flux / np.linalg.norm(flux, axis=1, keepdims=True)
    dc = filter_stretches(c, stretch, sos, axis=0)
    cbar = c - dc
    eye = np.eye(3)
    v = np.stack([np.cross(cbar, eye[a]) for a in range(3)], axis=1)  # (n, axis, 3)
    vn = np.linalg.norm(v, axis=2)
    vhat = v / np.maximum(vn, 1e-12)[..., None]
    proj = np.einsum("nak,nk->na", vhat, dc)
    e_share = moving_mean(proj**2, stretch, half)
    tot = moving_mean(np.einsum("nk,nk->n", dc, dc), stretch, half)
    share = e_share / np.maximum(tot, 1e-30)[:, None]
    ang2 = moving_mean((proj / np.maximum(vn, 1e-12)) ** 2, stretch, half)
    rms = np.rad2deg(np.sqrt(ang2))
    order = np.argsort(-share, axis=1)
    b1 = np.take_along_axis(vhat, order[:, :1, None], axis=1)[:, 0]
    b2 = np.take_along_axis(vhat, order[:, 1:2, None], axis=1)[:, 0]
    cos12 = np.abs(np.einsum("nk,nk->n", b1, b2))
    return share, rms, cos12


def detect_maneuvers(
    df: pd.DataFrame,
    *,
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
        share, rms, cos12 = _axis_energy(df, stretch, fs, highpass_hz, half, has_att)
        best_axis = np.argmax(np.nan_to_num(share, nan=-1.0), axis=1)
        best_rms = np.take_along_axis(np.nan_to_num(rms), best_axis[:, None], axis=1)[:, 0]
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
    rows: list[dict[str, Any]] = []
    for a, b, v in zip(starts, stops, vals, strict=True):
        lid = int(v // 3)
        leg = legs.loc[legs["leg_id"] == lid].iloc[0]
        rows.append({"box": int(leg["box"]), "heading_leg": int(leg["heading_leg"]),
                     "heading": leg["heading"], "maneuver": MANEUVERS[int(v % 3)],
                     "leg_id": lid, "start": int(a), "stop": int(b),
                     "t_start": float(t[a]), "t_end": float(t[b - 1]),
                     "duration_s": float(t[b - 1] - t[a] + 1.0 / fs), "n": int(b - a),
                     "rms_deg": float(np.mean(rms_axis[a:b])),
                     "ambiguous": bool(ambiguous[a:b].mean() > 0.5)})
    if method == "fluxgate":
        _resolve_ambiguous(rows, notes)
    table = pd.DataFrame(rows, columns=["box", "heading_leg", "heading", "maneuver", "leg_id",
                                        "start", "stop", "t_start", "t_end", "duration_s", "n",
                                        "rms_deg", "ambiguous"])
    table.insert(0, "id", np.arange(len(table)))
    man = np.full(n, "", dtype=object)
    mid = np.full(n, -1, dtype=np.int64)
    if len(table):
        lens = (table["stop"] - table["start"]).to_numpy()
        pos = np.concatenate([np.arange(a, b) for a, b in zip(table["start"], table["stop"],
                                                              strict=True)])
        mid[pos] = np.repeat(table["id"].to_numpy(), lens)
        man[pos] = np.repeat(table["maneuver"].to_numpy(dtype=object), lens)
    labels["maneuver"] = man.astype(str)
    labels["maneuver_id"] = mid
    table = table.drop(columns=["start", "stop"])
    res = ManeuverResult(labels, table, legs, method, offset, notes)
    full = res.complete_boxes
    nb = int(table["box"].nunique()) if len(table) else 0
    if nb and len(full) < nb:
        notes.append(f"{nb - len(full)} of {nb} box(es) miss some of the 12 manoeuvres")
    log.info("%s: %d legs, %d manoeuvres (%s), complete boxes %s", src, len(legs), len(table),
             method, full)
    return res


def _resolve_ambiguous(rows: list[dict[str, Any]], notes: list[str]) -> None:
    """Fluxgate roll/yaw ambiguity: give ambiguous runs the labels missing on their leg."""
    by_leg: dict[int, list[dict[str, Any]]] = {}
    for r in rows:
        by_leg.setdefault(r["leg_id"], []).append(r)
    n_fixed = 0
    for runs in by_leg.values():
        amb = [r for r in runs if r["ambiguous"]]
        if not amb:
            continue
        sure = {r["maneuver"] for r in runs if not r["ambiguous"]}
        missing = [m for m in MANEUVERS if m not in sure]
        amb.sort(key=lambda r: r["t_start"])
        if len(amb) == len(missing):
            for r, m in zip(amb, missing, strict=True):
                n_fixed += r["maneuver"] != m
                r["maneuver"] = m
    if any(r["ambiguous"] for r in rows):
        notes.append("fluxgate only: roll and yaw cannot be told apart on headings along the"
                     " magnetic meridian; ambiguous manoeuvres were named in flight order"
                     f" pitch, roll, yaw ({n_fixed} renamed)")
