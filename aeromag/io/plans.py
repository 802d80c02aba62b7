"""Mission plans from files: CSV of waypoints, QGroundControl ``.plan``, ``.waypoints``.

* **CSV**: a header row and columns ``lat``, ``lon`` (degrees, WGS84) and ``alt`` (m), one row
  per waypoint in flight order.
* **QGroundControl ``.plan``** (JSON, ``"fileType": "Plan"``): ``mission.items`` in order;
  each ``SimpleItem`` has ``command`` (a MAVLink ``MAV_CMD``), ``frame`` (``MAV_FRAME``) and
  ``params`` (7 numbers: latitude, longitude and altitude are ``params[4:7]``); survey and
  corridor ``ComplexItem`` s hold their generated simple items in
  ``TransectStyleComplexItem.Items``.  ``mission.plannedHomePosition`` is
  ``[lat, lon, alt]`` with the altitude above mean sea level.
* **Mission Planner / ArduPilot ``.waypoints``** (``QGC WPL 110``): one tab-separated line per
  item, ``INDEX CURRENT_WP FRAME COMMAND P1 P2 P3 P4 LAT LON ALT AUTOCONTINUE``; item 0 is the
  home position (absolute altitude).

Of the items, the navigation waypoints (:data:`NAV_COMMANDS`: waypoint, spline waypoint and
the loiters, which fly to a position) are the plan's waypoints, in mission order; take-off,
landing, return-to-launch, delays, speed changes, camera and every other command are skipped.
Altitudes relative to home (frames 3 and 6) are made absolute with the home altitude; absolute
frames (0, 5) are kept; terrain frames (10, 11) use QGroundControl's ``AMSLAltAboveTerrain``
when the file has it and are refused otherwise.  Ground stations give altitudes above mean sea
level: against a log on the WGS84 ellipsoid that is a constant offset (the geoid undulation),
which the track check detects and reports.
"""

from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path
from typing import Any

import pandas as pd

from ..errors import InputError
from ..track.plan import PLAN_NEEDS, validate_plan
from .log import read_log
from .outputs import register_input

__all__ = ["NAV_COMMANDS", "PLAN_SUFFIXES", "read_plan"]

#: MAVLink commands whose position is a waypoint of the plan: NAV_WAYPOINT (16),
#: NAV_LOITER_UNLIM (17), NAV_LOITER_TURNS (18), NAV_LOITER_TIME (19), NAV_SPLINE_WAYPOINT (82).
NAV_COMMANDS = {16: "waypoint", 17: "loiter", 18: "loiter turns", 19: "loiter time",
                82: "spline waypoint"}

#: Frames whose altitude is absolute (above mean sea level) and relative to home.
_ABSOLUTE_FRAMES = {0, 5}
_RELATIVE_FRAMES = {3, 6}
_TERRAIN_FRAMES = {10, 11}

#: Suffixes read as ground-station mission files (anything else is a CSV-like table).
PLAN_SUFFIXES = {".plan": "qgc-plan", ".waypoints": "qgc-wpl"}

#: Largest plan file read, bytes.
MAX_PLAN_BYTES = 64 << 20


def _blank_file(path: Path, most: int = 1 << 16) -> bool:
    """True when a file holds nothing but white space (and a UTF-8 byte-order mark)."""
    try:
        if path.stat().st_size > most:
            return False
        data = path.read_bytes()
    except OSError:
        return False  # the reader reports it
    return not data.removeprefix(b"\xef\xbb\xbf").strip()


def _read_text(p: Path) -> str:
    try:
        if p.stat().st_size > MAX_PLAN_BYTES:
            raise InputError(f"{p}: {p.stat().st_size} bytes is too large for a mission file"
                             f" (at most {MAX_PLAN_BYTES >> 20} MB); check the plan's path")
        raw = p.read_bytes()
    except OSError as exc:
        raise InputError(f"{p}: cannot read the plan ({exc.strerror}); check the plan's path"
                         ) from None
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise InputError(f"{p}: line {line}: not UTF-8 text (byte 0x{raw[exc.start]:02x});"
                         " a mission file is text: check that this is the right file") from None


def _frame_alt(where: str, frame: int, alt: float, home_alt: float | None,
               terrain_amsl: Any = None) -> float:
    """Absolute altitude of an item, m."""
    if frame in _ABSOLUTE_FRAMES:
        return alt
    if frame in _RELATIVE_FRAMES:
        if home_alt is None:
            raise InputError(f"{where}: altitude relative to home but the file has no home"
                             " altitude; add the home position to the mission")
        return home_alt + alt
    if frame in _TERRAIN_FRAMES:
        if isinstance(terrain_amsl, (int, float)) and math.isfinite(terrain_amsl):
            return float(terrain_amsl)
        raise InputError(f"{where}: altitude above terrain (frame {frame}) cannot be made"
                         " absolute without a terrain model; plan with relative or absolute"
                         " altitudes")
    raise InputError(f"{where}: coordinate frame {frame} is not a global frame (0, 3, 5, 6, 10,"
                     " 11); a plan needs latitude, longitude and altitude")


def _number(where: str, name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{where}: {name} is {value!r}, not a number; fix the mission item")
    v = float(value)
    if not math.isfinite(v):
        raise InputError(f"{where}: {name} is {value!r}, not a finite number")
    return v


def _read_waypoints(p: Path) -> pd.DataFrame:
    """Mission Planner / ArduPilot ``QGC WPL 110`` text file."""
    text = _read_text(p)
    lines = text.splitlines()
    first = next((i for i, ln in enumerate(lines) if ln.strip()), None)
    if first is None:
        raise InputError(f"{p}: the plan is empty; {PLAN_NEEDS}")
    head = lines[first].strip().split()
    if len(head) < 3 or head[:2] != ["QGC", "WPL"]:
        raise InputError(f"{p}: line {first + 1}: expected the header 'QGC WPL 110' of a"
                         " .waypoints mission file; save the mission from the ground station"
                         " again, or give a CSV plan")
    if head[2] != "110":
        raise InputError(f"{p}: line {first + 1}: 'QGC WPL {head[2]}' is not supported (only"
                         " version 110)")
    home_alt: float | None = None
    rows: list[tuple[float, float, float, int, int]] = []
    expect = 0
    for i in range(first + 1, len(lines)):
        ln = lines[i].strip()
        if not ln:
            continue
        where = f"{p}: line {i + 1}"
        fields = re.split(r"\t| +", ln)
        if len(fields) != 12:
            raise InputError(f"{where}: {len(fields)} field(s), expected 12 (INDEX CURRENT_WP"
                             " FRAME COMMAND P1 P2 P3 P4 LAT LON ALT AUTOCONTINUE)")
        try:
            index, _cur, frame, command = (int(f) for f in fields[:4])
        except ValueError:
            raise InputError(f"{where}: INDEX, CURRENT_WP, FRAME and COMMAND must be integers:"
                             f" {' '.join(fields[:4])!r}") from None
        if index != expect:
            raise InputError(f"{where}: item index {index}, expected {expect} (items must be"
                             " numbered in order from 0)")
        expect += 1
        try:
            lat, lon, alt = (float(f) for f in fields[8:11])
        except ValueError:
            raise InputError(f"{where}: latitude, longitude or altitude {fields[8:11]!r} is not"
                             " a number") from None
        if not all(math.isfinite(v) for v in (lat, lon, alt)):
            raise InputError(f"{where}: latitude, longitude and altitude must be finite")
        if index == 0:
            home_alt = alt if frame in _ABSOLUTE_FRAMES else None
            continue
        if command not in NAV_COMMANDS:
            continue
        rows.append((lat, lon, _frame_alt(where, frame, alt, home_alt), i + 1, command))
    if expect == 0:
        raise InputError(f"{p}: the mission has no items (not even the home position)")
    return _table(rows, p, "qgc-wpl", home_alt)


def _plan_items(items: Any, where: str, out: list[tuple[dict, str]]) -> None:
    if not isinstance(items, list):
        raise InputError(f"{where}: 'items' must be a list of mission items")
    for j, item in enumerate(items):
        w = f"{where}, item {j + 1}"
        if not isinstance(item, dict):
            raise InputError(f"{w}: a mission item must be a JSON object")
        kind = item.get("type")
        if kind == "SimpleItem":
            out.append((item, w))
        elif kind == "ComplexItem":
            tsc = item.get("TransectStyleComplexItem")
            if isinstance(tsc, dict) and "Items" in tsc:
                _plan_items(tsc["Items"], f"{w} ({item.get('complexItemType', 'complex')})", out)
            else:
                raise InputError(
                    f"{w}: complex item {item.get('complexItemType')!r} has no generated"
                    " waypoints (TransectStyleComplexItem.Items); export the mission as"
                    " .waypoints from the ground station")
        else:
            raise InputError(f"{w}: unknown item type {kind!r} (SimpleItem or ComplexItem)")


def _json_line(text: str, item: dict) -> int | None:
    """Line of an item in the file (found by its doJumpId), for messages."""
    jid = item.get("doJumpId")
    if isinstance(jid, int):
        m = re.search(r'"doJumpId"\s*:\s*' + str(jid) + r"\b", text)
        if m:
            return text.count("\n", 0, m.start()) + 1
    return None


def _read_qgc_plan(p: Path) -> pd.DataFrame:
    """QGroundControl ``.plan`` (JSON)."""
    text = _read_text(p)
    if not text.strip():
        raise InputError(f"{p}: the plan is empty; {PLAN_NEEDS}")
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{p}: line {exc.lineno}: not valid JSON ({exc.msg}); a QGroundControl"
                         " .plan is a JSON document") from None
    except RecursionError:
        raise InputError(f"{p}: JSON nested too deeply for a QGroundControl .plan") from None
    if not isinstance(doc, dict) or doc.get("fileType") != "Plan":
        raise InputError(f"{p}: not a QGroundControl plan (no \"fileType\": \"Plan\"); give a"
                         " .plan saved by QGroundControl, a .waypoints file or a CSV plan")
    mission = doc.get("mission")
    if not isinstance(mission, dict) or "items" not in mission:
        raise InputError(f"{p}: the plan has no mission items (mission.items)")
    home = mission.get("plannedHomePosition")
    home_alt = None
    if isinstance(home, list) and len(home) >= 3 and isinstance(home[2], (int, float)) \
            and not isinstance(home[2], bool) and math.isfinite(home[2]):
        home_alt = float(home[2])
    items: list[tuple[dict, str]] = []
    _plan_items(mission["items"], str(p), items)
    rows: list[tuple[float, float, float, int, int]] = []
    for item, w in items:
        line = _json_line(text, item)
        where = w if line is None else f"{w} (line {line})"
        command = item.get("command")
        if isinstance(command, bool) or not isinstance(command, int):
            raise InputError(f"{where}: 'command' is {command!r}, not a MAVLink command number")
        if command not in NAV_COMMANDS:
            continue
        params = item.get("params")
        if not isinstance(params, list) or len(params) != 7:
            raise InputError(f"{where}: 'params' must be a list of 7 values")
        frame = item.get("frame")
        if isinstance(frame, bool) or not isinstance(frame, int):
            raise InputError(f"{where}: 'frame' is {frame!r}, not a MAVLink frame number")
        lat = _number(where, "latitude (params[4])", params[4])
        lon = _number(where, "longitude (params[5])", params[5])
        alt = _number(where, "altitude (params[6])", params[6])
        rows.append((lat, lon, _frame_alt(where, frame, alt, home_alt,
                                          item.get("AMSLAltAboveTerrain")),
                     line if line is not None else 0, command))
    return _table(rows, p, "qgc-plan", home_alt)


def _table(rows: list[tuple[float, float, float, int, int]], p: Path, fmt: str,
           home_alt: float | None) -> pd.DataFrame:
    if len(rows) < 2:
        raise InputError(f"{p}: the mission has {len(rows)} navigation waypoint(s); a plan needs"
                         " at least 2 (one leg); take-off, landing and other commands do not"
                         " count")
    df = pd.DataFrame({"lat": [r[0] for r in rows], "lon": [r[1] for r in rows],
                       "alt": [r[2] for r in rows]})
    df.attrs.update(source=str(p), format=fmt, lines=[r[3] for r in rows],
                    commands=[NAV_COMMANDS[r[4]] for r in rows], home_alt=home_alt,
                    altitude_reference="above mean sea level (ground station)")
    return df


def read_plan(path: str | os.PathLike[str]) -> pd.DataFrame:
    """Read and validate a mission plan: CSV, QGroundControl ``.plan`` or ``.waypoints``.

    Parameters
    ----------
    path : path-like
        The plan file (see the module docstring for the formats).

    Returns
    -------
    DataFrame
        ``lat``, ``lon`` [deg] and ``alt`` [m] per waypoint in flight order (see
        :func:`aeromag.track.validate_plan`); ``attrs`` hold ``source``, ``format`` and, for
        ground-station files, the file line of each waypoint and the home altitude.
    """
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{p}: plan file not found (or not a file); check the plan's path")
    register_input(p, "plan")  # no output of the command may overwrite it (issue 16)
    fmt = PLAN_SUFFIXES.get(p.suffix.lower())
    if _blank_file(p):
        if fmt == "qgc-plan":
            raise InputError(f"{p}: the plan is empty; a QGroundControl .plan is a JSON file with"
                             " \"fileType\": \"Plan\" and mission.items (save it again from"
                             " QGroundControl)")
        if fmt == "qgc-wpl":
            raise InputError(f"{p}: the plan is empty; a .waypoints file starts with the header"
                             " 'QGC WPL 110' (save it again from Mission Planner)")
        raise InputError(f"{p}: the plan is empty; {PLAN_NEEDS}")
    if fmt is None:
        head = _peek(p)
        fmt = "qgc-wpl" if head.startswith("QGC WPL") else (
            "qgc-plan" if head.startswith("{") else None)
    if fmt == "qgc-wpl":
        df = _read_waypoints(p)
    elif fmt == "qgc-plan":
        df = _read_qgc_plan(p)
    else:
        # No required columns here: validate_plan says what a plan needs (--col is for logs).
        df = read_log(p, required=(), min_rows=0)
        df.attrs["format"] = "csv"
    df.attrs["source"] = str(p)
    out = validate_plan(df, str(p))
    out.attrs.update(df.attrs)
    return out


def _peek(p: Path) -> str:
    try:
        with open(p, "rb") as fh:
            return fh.read(64).removeprefix(b"\xef\xbb\xbf").decode("utf-8", "replace").lstrip()
    except OSError:
        return ""
