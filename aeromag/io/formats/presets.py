"""Presets: native channel names of MagNav.jl / SGL mapped onto canonical columns."""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence

import pandas as pd

from ..columns import (
    FLUX_COLUMNS,
)

log = logging.getLogger(__name__)

#: MagNav.jl / SGL channel names -> canonical columns (first match wins, case-insensitive).
#: The HDF5 names (``tt``, ``mag_1_uc``, ``ins_yaw`` ...), MagNav's minimal ``XYZ0`` HDF5
#: names (``alt``, ``yaw`` ...) and the SGL ASCII ``.xyz`` names (``TIME``, ``UTM-Z``,
#: ``UNCOMPMAG1``, ``AZIMUTH`` ...).  Units, per the SGL/MagNav field lists: ``tt``/``TIME`` s
#: past midnight UTC, ``lat``/``LAT`` and ``lon``/``LONG`` deg, ``utm_z``/``UTM-Z`` m above the
#: WGS84 ellipsoid, magnetometers nT, ``ins_yaw``/``AZIMUTH``/``yaw`` deg clockwise from north
#: (the SGL ASCII readme of 2013 lists the attitude in "nT", a typo: the later lists say deg).
#: ``mag`` is Mag 1, the tail-stinger magnetometer, uncompensated (never the compensated
#: ``mag_1_c``/``COMPMAG1``: the pipeline compensates).
MAGNAV_PRESET: dict[str, tuple[str, ...]] = {
    "time": ("tt", "time"),
    "lat": ("lat",),
    "lon": ("lon", "long"),
    "alt": ("utm_z", "utm-z", "alt"),
    "mag": ("mag_1_uc", "uncompmag1"),
    "line": ("line",),
    "heading": ("ins_yaw", "azimuth", "yaw", "heading"),
    "pitch": ("ins_pitch", "pitch"),
    "roll": ("ins_roll", "roll"),
}

#: Fluxgates of the MagNav / SGL preset, in order of preference: the first whose three axes are
#: present and each hold data becomes ``flux_x/y/z`` [nT].  Flux A is the one MagNav.jl uses
#: (``flux_a``); flux B (tail, at the base of the stinger, nearest Mag 1) is next, then C, D.
MAGNAV_FLUXGATES: tuple[tuple[str, str, str], ...] = tuple(
    names
    for g in "abcd"
    for names in ((f"flux_{g}_x", f"flux_{g}_y", f"flux_{g}_z"),
                  (f"flux{g}_x", f"flux{g}_y", f"flux{g}_z"))
)


def apply_preset(df: pd.DataFrame, preset: Mapping[str, Sequence[str]],
                 fluxgates: Sequence[Sequence[str]] = ()) -> pd.DataFrame:
    """Add canonical columns as copies of the first matching native channel.

    A canonical column already in the table is left alone; matching is case-insensitive.  The
    native channels are kept, so a ``--col`` map naming them still works.

    Parameters
    ----------
    df : DataFrame
        Raw table.
    preset : mapping
        ``{canonical: (candidate native names, ...)}``.
    fluxgates : sequence of (x, y, z) names
        Candidate fluxgates for ``flux_x/y/z``, in order of preference: the first whose three
        axes are present and each hold data (not all missing) is taken as a whole (axes are
        never mixed between sensors).

    Returns
    -------
    DataFrame
        The same frame with canonical columns added.
    """
    lower = {str(c).lower(): c for c in df.columns}
    for canon, candidates in preset.items():
        if canon in df.columns:
            continue
        for cand in candidates:
            src = lower.get(cand.lower())
            if src is not None:
                df[canon] = df[src]
                break
    if fluxgates and not any(c in df.columns for c in FLUX_COLUMNS):
        for k, axes in enumerate(fluxgates):
            src = [lower.get(a.lower()) for a in axes]
            if any(c is None for c in src):
                continue
            if any(df[c].isna().all() for c in src):
                log.warning("fluxgate channels %s: an axis holds no data; trying the next"
                            " fluxgate", "/".join(map(str, src)))
                continue
            level = logging.DEBUG if k == 0 else logging.INFO  # not flux A: say so
            log.log(level, "flux_x/y/z <- %s (nT)", "/".join(map(str, src)))
            for canon, c in zip(FLUX_COLUMNS, src, strict=True):
                df[canon] = df[c]
            break
    return df
