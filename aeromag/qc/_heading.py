"""Heading of every sample for the manoeuvre detection: from attitude, else the fluxgate."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..errors import InputError

__all__: list[str] = []


def _heading_source(df: pd.DataFrame, declination_deg: float) -> tuple[np.ndarray, str]:
    if "heading" in df.columns and df["heading"].notna().any():
        return df["heading"].to_numpy(dtype=np.float64), "attitude"
    if not {"flux_x", "flux_y", "flux_z"} <= set(df.columns):
        raise InputError("manoeuvre detection needs a 'heading' column or flux_x/flux_y/flux_z")
    z = np.zeros(len(df))
    pitch = df["pitch"].to_numpy(dtype=np.float64) if "pitch" in df.columns else z
    roll = df["roll"].to_numpy(dtype=np.float64) if "roll" in df.columns else z
    # Levelled field (roll then pitch undone, the first two rows of the body-to-NED rotation
    # at yaw 0): Xh = bx cos(th) + (by sin(ph) + bz cos(ph)) sin(th), Yh = by cos(ph) -
    # bz sin(ph); the magnetic heading is atan2(-Yh, Xh).
    bx, by, bz = (df[c].to_numpy(dtype=np.float64) for c in ("flux_x", "flux_y", "flux_z"))
    th = np.deg2rad(np.nan_to_num(pitch))
    ph = np.deg2rad(np.nan_to_num(roll))
    if not (th.any() or ph.any()):
        xh, yh = bx, by
    else:
        xh = bx * np.cos(th) + (by * np.sin(ph) + bz * np.cos(ph)) * np.sin(th)
        yh = by * np.cos(ph) - bz * np.sin(ph)
    h = np.mod(np.rad2deg(np.arctan2(-yh, xh)) + float(declination_deg), 360.0)
    return h, "fluxgate"


def heading_unit(df: pd.DataFrame, declination_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """``(cos, sin)`` of :func:`_heading_source`'s heading and where it is finite.

    From the fluxgate without trigonometry: ``(Xh, -Yh) / |(Xh, Yh)|``, rotated by the
    declination.
    """
    if "heading" in df.columns and df["heading"].notna().any():
        h, _ = _heading_source(df, declination_deg)
        ok = np.isfinite(h)
        rad = np.deg2rad(np.where(ok, h, 0.0))
        return np.column_stack([np.cos(rad), np.sin(rad)]), ok
    if not {"flux_x", "flux_y", "flux_z"} <= set(df.columns):
        raise InputError("manoeuvre detection needs a 'heading' column or flux_x/flux_y/flux_z")
    bx, by, bz = (df[c].to_numpy(dtype=np.float64) for c in ("flux_x", "flux_y", "flux_z"))
    pitch = df["pitch"].to_numpy(dtype=np.float64) if "pitch" in df.columns else None
    roll = df["roll"].to_numpy(dtype=np.float64) if "roll" in df.columns else None
    th = np.deg2rad(np.nan_to_num(pitch)) if pitch is not None else None
    ph = np.deg2rad(np.nan_to_num(roll)) if roll is not None else None
    if (th is None or not th.any()) and (ph is None or not ph.any()):
        xh, yh = bx, by
    else:
        th = np.zeros(len(df)) if th is None else th
        ph = np.zeros(len(df)) if ph is None else ph
        xh = bx * np.cos(th) + (by * np.sin(ph) + bz * np.cos(ph)) * np.sin(th)
        yh = by * np.cos(ph) - bz * np.sin(ph)
    r = np.hypot(xh, yh)
    ok = np.isfinite(r)
    pos = ok & (r > 0)  # a zero horizontal field has heading 0, as arctan2(0, 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        cs = np.column_stack([np.where(pos, xh / r, 1.0), np.where(pos, -yh / r, 0.0)])
    if declination_deg:
        d = np.deg2rad(float(declination_deg))
        cd, sd = np.cos(d), np.sin(d)
        cs = np.column_stack([cs[:, 0] * cd - cs[:, 1] * sd, cs[:, 0] * sd + cs[:, 1] * cd])
    return cs, ok
