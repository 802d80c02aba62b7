"""The data contract in code: canonical columns and units, TL term order, frames.

Everything here restates ``shared/interface.md`` (the contract of the command line and of the
data) so that code can refer to it by name; ``docs/conventions.md`` is the glossary.  This
module imports nothing from aeromag and may be imported by every layer.

Frames
------
Body axes: x forward, y right, z down.  Navigation frame: north-east-down (NED).
``heading``, ``pitch``, ``roll`` are the yaw-pitch-roll (Z-Y-X) Euler angles of the body in
NED; headings are true (geographic) unless a column says magnetic.
"""

from __future__ import annotations

__all__ = [
    "BODY_FRAME",
    "CANONICAL_COLUMNS",
    "EPOCH_DISPLAY_S",
    "COMPENSATE_COLUMNS",
    "EDDY_8",
    "FIELD_SCALE_NT",
    "FLUX_COLUMNS",
    "INDUCED_5",
    "NAV_FRAME",
    "PERMANENT",
    "TERMS_16",
    "TRACK_COLUMNS",
]

#: Canonical columns of a survey log and their units (interface.md, "Survey logs").
CANONICAL_COLUMNS: dict[str, str] = {
    "time": "s",
    "lat": "deg",
    "lon": "deg",
    "alt": "m",
    "flux_x": "nT",
    "flux_y": "nT",
    "flux_z": "nT",
    "mag": "nT",
    "line": "integer",
    "heading": "deg",
    "pitch": "deg",
    "roll": "deg",
    "mag_heading": "deg",
    "leg": "integer",
    "gyro_x": "rad/s",
    "gyro_y": "rad/s",
    "gyro_z": "rad/s",
    "acc_x": "m/s^2",
    "acc_y": "m/s^2",
    "acc_z": "m/s^2",
    "flow_x": "rad/s",
    "flow_y": "rad/s",
    "flow_quality": "0-255",
    "range_m": "m",
    "baro_alt": "m",
    "vel_n": "m/s",
    "vel_e": "m/s",
    "vel_d": "m/s",
}

#: The 3-axis fluxgate (vector magnetometer), body frame [nT].
FLUX_COLUMNS: tuple[str, str, str] = ("flux_x", "flux_y", "flux_z")

#: Columns that ``compensate`` adds, and their units.
COMPENSATE_COLUMNS: dict[str, str] = {
    "mag_tl": "nT",
    "mag_comp": "nT",
    "segment": "integer",
    "segment_kept": "bool",
}

#: Columns that ``track`` adds, and their units.
TRACK_COLUMNS: dict[str, str] = {
    "leg": "integer",
    "xtrack_m": "m",
    "track_alarm": "bool",
    "heading_diff_deg": "deg",
    "heading_alarm": "bool",
    "alarm": "bool",
}

#: ``|B|`` enters the induced and eddy terms as ``|B| / FIELD_SCALE_NT`` [nT].
FIELD_SCALE_NT = 50000.0

#: Times [s] in this range (2001-09-09 to 2099-12-04) are shown as UTC clock times in
#: summaries, tables and figure axes; other times are seconds since the start of the log.
EPOCH_DISPLAY_S = (1e9, 4.1e9)

#: TL term order (interface.md): permanent, induced (times ``|B|``), eddy (times ``|B|``).
PERMANENT: tuple[str, ...] = ("cx", "cy", "cz")
INDUCED_5: tuple[str, ...] = ("cx*cx", "cx*cy", "cx*cz", "cy*cy", "cy*cz")
EDDY_8: tuple[str, ...] = ("cx*cx'", "cx*cy'", "cx*cz'", "cy*cx'", "cy*cy'", "cy*cz'", "cz*cx'",
                           "cz*cy'")
#: The 16 terms of every report and model file, in order.
TERMS_16: tuple[str, ...] = PERMANENT + INDUCED_5 + EDDY_8

#: Body axes (x forward, y right, z down) and the navigation frame.
BODY_FRAME = "x forward, y right, z down"
NAV_FRAME = "NED"
