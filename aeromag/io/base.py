"""Base-station records: CSV, IAGA-2002 and GEM GSM-19 / Geometrics G-856 memory dumps.

CSV has ``time``, ``mag``; IAGA-2002 is ``.min``, ``.sec``; the dumps are read by
:mod:`.base_dumps`.

IAGA-2002 (INTERMAGNET's exchange format): header lines ending in ``|``, then a column line
``DATE TIME DOY XXXH XXXD XXXZ XXXF |`` (XXX the observatory code; the elements reported may
be HDZF, XYZF, XYZG...), then one row per sample; 99999 (missing) and 88888 (not recorded)
are empty values.  The total field is the ``F`` column; a file without one (or with it empty)
gives F from the vector components (sqrt(X^2 + Y^2 + Z^2), or sqrt(H^2 + Z^2); D is an angle).
Times are UTC.  The rows are read by pandas; only the header is looked at here.  IAGA-2002
is a format of the one registry (:mod:`aeromag.io.formats`, extensions ``.min``, ``.sec``),
so :func:`aeromag.io.read_log` reads it like any log.  :func:`read_base` recognises a GSM-19
or G-856 dump from its content (whatever the extension) before it falls back on the registry.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import InputError
from .base_dumps import read_g856, read_gsm19, sniff_base_dump
from .formats import Format, register
from .log import read_log

__all__ = ["IAGA_EXTENSIONS", "read_base", "read_base_file", "read_iaga2002"]

IAGA_EXTENSIONS = (".min", ".sec")
_MISSING = (88888.0, 99999.0)


def read_iaga2002(path: str | os.PathLike[str]) -> pd.DataFrame:
    """Read an IAGA-2002 file.

    Parameters
    ----------
    path : path-like
        The file.

    Returns
    -------
    DataFrame
        ``time`` (UTC s since 1970), ``mag`` (F, nT) and the elements as read (``H``,
        ``D``, ``Z``, ``X``, ``Y``...); ``attrs["f_source"]`` is ``"F"`` or the components.

    Raises
    ------
    InputError
        No column line, no usable total field, or an unreadable row.
    """
    p = Path(path)
    names = None
    skip = 0
    try:
        with open(p, encoding="ascii", errors="replace") as fh:
            for i, line in enumerate(fh):
                if line.startswith("DATE"):
                    names = line.replace("|", " ").split()
                    skip = i + 1
                    break
                if i > 200:
                    break
    except OSError as exc:
        raise InputError(f"{p}: cannot read the base record ({exc.strerror})") from None
    if not names or names[:2] != ["DATE", "TIME"]:
        raise InputError(f"{p}: not an IAGA-2002 file (no 'DATE TIME DOY ...' column line); "
                         "give a CSV with time,mag or an IAGA-2002 .min/.sec file")
    elems = [n[-1] if len(n) == 4 else n for n in names[3:]]
    try:
        df = pd.read_csv(p, sep=r"\s+", skiprows=skip, header=None, names=names,
                         dtype={names[0]: str, names[1]: str})
    except (ValueError, pd.errors.ParserError) as exc:
        raise InputError(f"{p}: IAGA-2002 rows do not parse: {exc}") from None
    when = pd.to_datetime(df[names[0]] + "T" + df[names[1]], format="ISO8601", utc=True,
                          errors="coerce")
    if when.isna().any():
        row = int(np.flatnonzero(when.isna().to_numpy())[0]) + skip + 1
        raise InputError(f"{p}: line {row}: DATE/TIME is not a date and time")
    out = pd.DataFrame({"time": (when - pd.Timestamp("1970-01-01", tz="UTC")).dt.total_seconds()
                        .to_numpy()})
    for name, e in zip(names[3:], elems, strict=True):
        v = pd.to_numeric(df[name], errors="coerce").to_numpy(dtype=float, copy=True)
        v[np.isin(v, _MISSING) | (v >= 88880.0)] = np.nan
        out[e] = v
    f_src = "F"
    if "F" not in out or not np.isfinite(out["F"]).any():
        if {"X", "Y", "Z"} <= set(out):
            out["F"] = np.sqrt(out["X"] ** 2 + out["Y"] ** 2 + out["Z"] ** 2)
            f_src = "sqrt(X^2+Y^2+Z^2)"
        elif {"H", "Z"} <= set(out):
            out["F"] = np.hypot(out["H"], out["Z"])
            f_src = "sqrt(H^2+Z^2)"
        else:
            raise InputError(f"{p}: no F column and no X, Y, Z or H, Z components to compute "
                             "the total field from")
    out["mag"] = out.pop("F")
    out.attrs["f_source"] = f_src
    return out


def read_base_file(path: str | os.PathLike[str], date: str | None = None) -> pd.DataFrame:
    """Read one base-station file of any supported layout, recognised from its content.

    Parameters
    ----------
    path : path-like
        A GSM-19 base file or G-856 dump (recognised from their first lines, whatever the
        extension), else CSV (``time`` UTC s since 1970 or ISO 8601, ``mag`` nT), IAGA-2002
        or another registered format (from the extension).
    date : str, optional
        ``YYYY-MM-DD``: dates a dump that gives no date (G-856: its year; GSM-19 without an
        ``ID`` line: its day).

    Returns
    -------
    DataFrame
        ``time`` (UTC s since 1970) and ``mag`` (nT) at least; ``attrs["notes"]`` lists what
        a dump reader dropped or shifted (empty for the other formats).
    """
    p = Path(path)
    try:
        with open(p, "rb") as fh:
            head = fh.read(4096).decode("utf-8", errors="replace")
    except OSError:
        head = ""
    kind = sniff_base_dump(head)
    if kind == "gsm19":
        return read_gsm19(p, date=date)
    if kind == "g856":
        return read_g856(p, date=date)
    df = read_log(p, required=("time", "mag"))
    df.attrs["notes"] = []
    return df


def read_base(paths: str | os.PathLike[str] | Sequence[str | os.PathLike[str]],
              date: str | None = None) -> tuple[np.ndarray, np.ndarray, str, list[str]]:
    """Read one or several base-station files (consecutive days are joined).

    Parameters
    ----------
    paths : path-like or sequence of path-like
        Files of any layout :func:`read_base_file` reads (they may differ).
    date : str, optional
        ``YYYY-MM-DD``, for dumps that give no date (see :func:`read_base_file`).

    Returns
    -------
    time_s, mag_nT : ndarray
        UTC s since 1970 and nT, sorted by time, duplicates dropped.
    source : str
        The file name(s), comma-separated.
    notes : list of str
        What the dump readers dropped (flagged readings, with their count) or shifted (a
        clock offset to UTC), for the report.

    Raises
    ------
    InputError
        A file that does not read, or files that overlap with different values.
    """
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    ts, vs, notes = [], [], []
    for path in paths:
        df = read_base_file(path, date=date)
        ts.append(df["time"].to_numpy(dtype=float))
        vs.append(df["mag"].to_numpy(dtype=float))
        notes += list(df.attrs.get("notes", []))
    t = np.concatenate(ts)
    v = np.concatenate(vs)
    order = np.argsort(t, kind="stable")
    t, v = t[order], v[order]
    keep = np.r_[True, np.diff(t) > 0]
    return t[keep], v[keep], ", ".join(str(p) for p in paths), notes


register(Format("iaga2002", IAGA_EXTENSIONS, read=read_iaga2002))
register(Format("gsm19", (".b",), read=lambda p: read_gsm19(p),
                sniff=lambda head: sniff_base_dump(head) == "gsm19"))
register(Format("g856", read=lambda p: read_g856(p),
                sniff=lambda head: sniff_base_dump(head) == "g856"))
