"""Base-magnetometer memory dumps: GEM Systems GSM-19 base files and Geometrics G-856 dumps.

Both are text files that a base-station magnetometer writes when its memory is downloaded.
Each reader returns the table the CSV and IAGA-2002 readers return (``time`` UTC s since
1970, ``mag`` nT) plus the instrument's own columns, with ``df.attrs["notes"]`` (what was
dropped or shifted, for OUT.json) and ``df.attrs[ROWS_ATTR]`` (where each row is in the
file).  :func:`sniff_base_dump` recognises them from their content, whatever the extension.

**GEM Systems GSM-19 base file** (``NNname.b``; GEM Systems, *GSM-19 Series Magnetometers,
Version 7* manual, ch. 6 "Data organization and transfer",
https://www.easymanua.ls/gem/gsm-19/manual?p=71: file extension ``.b`` = base, a new file at
each midnight crossing; layout as read by MagPy, ``geomagpy/magpy``
``magpy/lib/format_gsm19.py``)::

    /Gem Systems GSM-19W 3101329 v7.0 28 VI 2019 M ew3fl.v7o     <- instrument, firmware
    /ID 1 file 05base.b   02 XI 14                                <- file; date DD MONTH YY
    /datum  50000.00                                              (month in Roman numerals)
    /UTC+01                                                       <- optional: clock offset
    /time nT sq
    005000.0  50494.29 99                                         <- hhmmss.s, field nT, quality

Firmware v6 writes the same header lines without the leading ``/``; the day and the month
may be glued (``09 VII10``, ``02VIII12``).  The date is the file's (``ID`` line); a file
without one needs ``date``.  ``/UTC+hh`` says the clock runs hh hours ahead of UTC: the times
are shifted back to UTC (as MagPy does) and a note says so; without that line the times are
taken as UTC (the file does not say otherwise).  A time that steps back by more than 12 h is
a midnight crossing (the next day).  The quality ``sq`` is GEM's two-digit quality ``XY``
(X: measuring time, 9 = full; Y: signal, 9 = optimal, 0 = unacceptable reading; Ocean
Networks Canada's description of GEM's GSM-90 quality indicator,
https://wiki.oceannetworks.ca/display/DP/194): a reading with Y = 0 is dropped and counted.

**Geometrics G-856 dump** (Geometrics, *G-856AX Memory-Mag Operation Manual*, appendix
"Output format",
https://manualshive.com/en/manual/geometrics/memory-mag-g-856ax/2214709?page=50: each line
is 29 ASCII characters, starting with a space or an asterisk and a 3-digit line number; the
rest of the field list as written and read by PyMaGra, ``HZeyen/pymagra``
``Pymagra/in_out/geometrics.py``, ``Geometrics.read_base`` and ``write_base``)::

    *  0 306 005000    1 504943                                   <- flag, line, day of year,
                                                                     hhmmss, station, 0.1 nT

The reading is in tenths of a nT.  A ``?`` before the reading (PyMaGra strips it) is taken as
the instrument's doubt about that reading: it is dropped and counted.  The dump gives the
day of the year but no year: ``date`` (``--date YYYY-MM-DD``, the survey's UTC date) gives it
(the year before for a dump begun in late December for a January date), and a day that drops
back (365 -> 1) is in the next year.  Times are taken as UTC.
"""

from __future__ import annotations

import datetime as _dt
import logging
import os
import re
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import InputError
from .messages import clean
from .rows import ROWS_ATTR, rows_in_runs

log = logging.getLogger(__name__)

__all__ = ["read_g856", "read_gsm19", "sniff_base_dump", "EARTH_FIELD_NT"]

#: Total fields a base magnetometer on the Earth can read [nT] (a wider band than the
#: 22,000-67,000 nT of the surface field, as the log readers use).
EARTH_FIELD_NT = (1_000.0, 120_000.0)

_GSM19_HEAD = re.compile(r"^\s*/?\s*Gem Systems GSM-19", re.IGNORECASE | re.MULTILINE)
_GSM19_ID = re.compile(r"^/?ID\b.*?\bfile\s+\S*?\s*\.(\w+)\s*(.*)$", re.IGNORECASE)
_GSM19_DATE = re.compile(r"^(\d{1,2})\s*([IVX]+)\s*(\d{2}|\d{4})$", re.IGNORECASE)
_GSM19_UTC = re.compile(r"^/?UTC\s*([+-])\s*(\d{1,2})(?::?(\d{2}))?\s*$", re.IGNORECASE)
_HHMMSS = re.compile(r"^(\d{2})(\d{2})(\d{2}(?:\.\d*)?)$")
_G856 = re.compile(r"^([ *])\s*(\d{1,3})\s+(\d{1,3})\s+(\d{6})\s*(\d{1,5})\s*(\?)?\s*(\d{1,7})\s*$")
_ROMAN = {"I": 1, "II": 2, "III": 3, "IV": 4, "V": 5, "VI": 6, "VII": 7, "VIII": 8, "IX": 9,
          "X": 10, "XI": 11, "XII": 12}


def _text_lines(path: Path) -> list[str]:
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise InputError(f"{clean(path)}: cannot read the base record ({exc.strerror})") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise InputError(f"{clean(path)}: line {line}: bytes that are not UTF-8 text; a base "
                         "dump is plain ASCII: download it again as text") from None
    return text.splitlines()


def sniff_base_dump(head: str) -> str | None:
    """The base-dump format of a file from its first lines, else None.

    Parameters
    ----------
    head : str
        The start of the file (a few kB of text).

    Returns
    -------
    {"gsm19", "g856"} or None
    """
    if _GSM19_HEAD.search(head[:2048]):
        return "gsm19"
    lines = [ln for ln in head.splitlines()[:-1] or head.splitlines() if ln.strip()][:5]
    if lines and all(_G856.match(ln) for ln in lines):
        return "g856"
    return None


def _parse_date(date: str | None, path: Path, what: str) -> _dt.date:
    if date is None:
        raise InputError(f"{clean(path)}: {what}: pass --date YYYY-MM-DD (Python: date=...), "
                         "the UTC date of the survey")
    try:
        return _dt.datetime.strptime(str(date).strip(), "%Y-%m-%d").date()
    except ValueError:
        raise InputError(f"--date {date}: not a date; write YYYY-MM-DD") from None


def _seconds_of_day(token: str, path: Path, line: int) -> float:
    m = _HHMMSS.match(token)
    if m is None:
        raise InputError(f"{clean(path)}: line {line}: time {clean(token)!r} is not hhmmss[.s]")
    h, mi, s = int(m[1]), int(m[2]), float(m[3])
    if h > 23 or mi > 59 or s >= 60.0:
        raise InputError(f"{clean(path)}: line {line}: time {clean(token)!r} is not a time of "
                         "day (hh 00-23, mm and ss 00-59)")
    return h * 3600.0 + mi * 60.0 + s


def _check_field(mag: np.ndarray, lines: np.ndarray, path: Path) -> None:
    bad = ~((mag >= EARTH_FIELD_NT[0]) & (mag <= EARTH_FIELD_NT[1]))
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise InputError(f"{clean(path)}: line {int(lines[k])}: {mag[k]:g} nT is no Earth "
                         f"field ({EARTH_FIELD_NT[0]:,.0f}-{EARTH_FIELD_NT[1]:,.0f} nT); "
                         "is this a base-station dump?")


def _midnight_wraps(sod: np.ndarray) -> np.ndarray:
    """Day offset of each time of day: a step back by more than 12 h crosses midnight."""
    return np.concatenate(([0], np.cumsum(np.diff(sod) < -43_200.0)))


def _line_list(lines: list[int], limit: int = 5) -> str:
    shown = ", ".join(str(x) for x in lines[:limit])
    return ("line " if len(lines) == 1 else "lines ") + shown + (
        " ..." if len(lines) > limit else "")


def _table(path: Path, t: np.ndarray, mag: np.ndarray, extra: dict[str, np.ndarray],
           lines: np.ndarray, notes: list[str], fmt: str) -> pd.DataFrame:
    if t.size < 2:
        raise InputError(f"{clean(path)}: {t.size} usable reading(s) in the {fmt} file; a base "
                         "record needs at least two")
    df = pd.DataFrame({"time": t, "mag": mag, **extra})
    runs = np.flatnonzero(np.r_[True, np.diff(lines) != 1])
    df.attrs[ROWS_ATTR] = rows_in_runs(runs.tolist(), lines[runs].tolist())
    df.attrs["notes"] = notes
    df.attrs["format"] = fmt
    for n in notes:
        log.warning(n)
    return df


def read_gsm19(path: str | os.PathLike[str], date: str | None = None) -> pd.DataFrame:
    """Read a GEM Systems GSM-19 base-station file (``.b``; layout in the module docstring).

    Parameters
    ----------
    path : path-like
        The file.
    date : str, optional
        ``YYYY-MM-DD`` of the first reading, used only when the file has no ``ID`` line
        with its date.

    Returns
    -------
    DataFrame
        ``time`` (UTC s since 1970), ``mag`` (nT), ``quality`` (GEM's two digits); readings
        of quality Y = 0 dropped, counted in ``attrs["notes"]``.

    Raises
    ------
    InputError
        No GSM-19 header, a file of another survey mode (``.m``, ``.g`` ...), no date, or a
        line that is not ``hhmmss.s field quality`` (naming the line).
    """
    p = Path(path)
    text = _text_lines(p)
    day: _dt.date | None = None
    offset_s = 0.0
    offset_txt = ""
    head = False
    sod, mag, qual, where = [], [], [], []
    for i, raw in enumerate(text, start=1):
        ln = raw.strip()
        if not ln:
            continue
        if _GSM19_HEAD.match(ln):
            head = True
            continue
        m = _GSM19_ID.match(ln)
        if m:
            if m[1].lower() != "b":
                raise InputError(f"{clean(p)}: line {i}: a GSM-19 '.{clean(m[1])}' file (not a "
                                 "base file '.b'): give the base station's file to --base")
            dm = _GSM19_DATE.match(m[2].strip())
            if dm and dm[2].upper() in _ROMAN:
                yy = int(dm[3])
                year = yy if yy > 999 else (2000 + yy if yy < 80 else 1900 + yy)
                try:
                    day = _dt.date(year, _ROMAN[dm[2].upper()], int(dm[1]))
                except ValueError:
                    raise InputError(f"{clean(p)}: line {i}: {clean(m[2].strip())!r} is not a "
                                     "date (DD MONTH YY, month in Roman numerals)") from None
            continue
        m = _GSM19_UTC.match(ln)
        if m:
            hours = int(m[2]) + (int(m[3]) / 60.0 if m[3] else 0.0)
            offset_s = (1.0 if m[1] == "+" else -1.0) * hours * 3600.0
            offset_txt = ln.lstrip("/")
            continue
        if ln.startswith("/") or re.match(r"^(datum|time\b)", ln, re.IGNORECASE):
            continue
        tok = ln.split()
        if len(tok) != 3:
            raise InputError(f"{clean(p)}: line {i}: {len(tok)} fields; a GSM-19 base reading "
                             "is 'hhmmss.s field quality' (3 fields)")
        sod.append(_seconds_of_day(tok[0], p, i))
        try:
            mag.append(float(tok[1]))
        except ValueError:
            raise InputError(f"{clean(p)}: line {i}: field {clean(tok[1])!r} is not a number "
                             "(nT)") from None
        if not re.fullmatch(r"\d{1,2}", tok[2]):
            raise InputError(f"{clean(p)}: line {i}: quality {clean(tok[2])!r} is not GEM's "
                             "two-digit quality (00-99)")
        qual.append(int(tok[2]))
        where.append(i)
    if not head:
        raise InputError(f"{clean(p)}: no 'Gem Systems GSM-19' header line: not a GSM-19 file")
    if day is None:
        day = _parse_date(date, p, "the GSM-19 file gives no date (no 'ID ... .b DD MONTH YY' "
                          "line)")
    s = np.asarray(sod, dtype=np.float64)
    f = np.asarray(mag, dtype=np.float64)
    q = np.asarray(qual, dtype=np.int64)
    rows = np.asarray(where, dtype=np.int64)
    _check_field(f, rows, p)
    epoch = (_dt.datetime(day.year, day.month, day.day) - _dt.datetime(1970, 1, 1)).total_seconds()
    t = epoch + s + 86_400.0 * _midnight_wraps(s) - offset_s
    notes = []
    if offset_s:
        notes.append(f"{p.name}: GSM-19 clock at {offset_txt}: times shifted by "
                     f"{-offset_s / 3600.0:+g} h to UTC")
    bad = q % 10 == 0
    if bad.any():
        notes.append(f"{p.name}: {int(bad.sum())} of {q.size} GSM-19 readings of quality Y = 0 "
                     f"(unacceptable signal) dropped ({_line_list(rows[bad].tolist())})")
    keep = ~bad
    return _table(p, t[keep], f[keep], {"quality": q[keep]}, rows[keep], notes, "GSM-19")


def read_g856(path: str | os.PathLike[str], date: str | None = None) -> pd.DataFrame:
    """Read a Geometrics G-856 memory dump (layout in the module docstring).

    Parameters
    ----------
    path : path-like
        The file.
    date : str
        ``YYYY-MM-DD``, the survey's UTC date: its year dates the dump's days of the year.

    Returns
    -------
    DataFrame
        ``time`` (UTC s since 1970), ``mag`` (nT), ``station``; readings marked ``?``
        dropped, counted in ``attrs["notes"]``.

    Raises
    ------
    InputError
        No ``date``, or a line that is not a G-856 reading (naming the line).
    """
    p = Path(path)
    text = _text_lines(p)
    doy, sod, reading, station, doubt, where = [], [], [], [], [], []
    for i, raw in enumerate(text, start=1):
        if not raw.strip():
            continue
        m = _G856.match(raw.rstrip("\r\n"))
        if m is None:
            raise InputError(f"{clean(p)}: line {i}: not a G-856 reading (expected "
                             "'* LLL DDD HHMMSS STATION READING', reading in 0.1 nT)")
        d = int(m[3])
        if not 1 <= d <= 366:
            raise InputError(f"{clean(p)}: line {i}: day of year {d} is not 1-366")
        doy.append(d)
        sod.append(_seconds_of_day(m[4], p, i))
        station.append(int(m[5]))
        doubt.append(m[6] == "?")
        reading.append(int(m[7]))
        where.append(i)
    if not where:
        raise InputError(f"{clean(p)}: no G-856 reading in the file")
    first = _parse_date(date, p, "a G-856 dump gives the day of year but no year")
    d = np.asarray(doy, dtype=np.int64)
    # a dump started late in December for a survey dated in January began the year before
    start = first.year - int(d[0] - first.timetuple().tm_yday > 300)
    year = start + np.concatenate(([0], np.cumsum(np.diff(d) < -300)))
    jan1 = np.array([(_dt.datetime(int(y), 1, 1) - _dt.datetime(1970, 1, 1)).total_seconds()
                     for y in year])
    ndays = np.where([_dt.date(int(y), 12, 31).timetuple().tm_yday == 366 for y in year],
                     366, 365)
    rows = np.asarray(where, dtype=np.int64)
    if np.any(d > ndays):
        k = int(np.flatnonzero(d > ndays)[0])
        raise InputError(f"{clean(p)}: line {int(rows[k])}: day of year {int(d[k])} does not "
                         f"exist in {int(year[k])} (from --date {first}); check --date")
    t = jan1 + (d - 1) * 86_400.0 + np.asarray(sod, dtype=np.float64)
    f = np.asarray(reading, dtype=np.float64) / 10.0
    _check_field(f, rows, p)
    flag = np.asarray(doubt, dtype=bool)
    notes = []
    if flag.any():
        notes.append(f"{p.name}: {int(flag.sum())} of {flag.size} G-856 readings marked '?' "
                     f"dropped ({_line_list(rows[flag].tolist())})")
    keep = ~flag
    return _table(p, t[keep], f[keep], {"station": np.asarray(station)[keep]}, rows[keep],
                  notes, "G-856")
