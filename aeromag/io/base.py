"""Base-station records: CSV (``time``, ``mag``) and IAGA-2002 (``.min``, ``.sec``).

IAGA-2002 (INTERMAGNET's exchange format): header lines ending in ``|``, then a column line
``DATE TIME DOY XXXH XXXD XXXZ XXXF |`` (XXX the observatory code; the elements reported may
be HDZF, XYZF, XYZG...), then one row per sample; 99999 (missing) and 88888 (not recorded)
are empty values.  The total field is the ``F`` column; a file without one (or with it empty)
gives F from the vector components (sqrt(X^2 + Y^2 + Z^2), or sqrt(H^2 + Z^2); D is an angle).
Times are UTC.  The rows are read by pandas; only the header is looked at here.  IAGA-2002
is a format of the one registry (:mod:`aeromag.io.formats`, extensions ``.min``, ``.sec``),
so :func:`aeromag.io.read_log` reads it like any log.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import InputError
from .formats import Format, register
from .log import read_log

__all__ = ["IAGA_EXTENSIONS", "read_base", "read_iaga2002"]

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


def read_base(paths: str | os.PathLike[str] | Sequence[str | os.PathLike[str]]
              ) -> tuple[np.ndarray, np.ndarray, str]:
    """Read one or several base-station files (consecutive days are joined).

    Parameters
    ----------
    paths : path-like or sequence of path-like
        CSV (``time`` UTC s since 1970 or ISO 8601, ``mag`` nT) or IAGA-2002 files.

    Returns
    -------
    time_s, mag_nT : ndarray
        Sorted by time, duplicates dropped.
    source : str
        The file name(s), comma-separated.

    Raises
    ------
    InputError
        A file that does not read, or files that overlap with different values.
    """
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    ts, vs = [], []
    for path in paths:
        df = read_log(Path(path), required=("time", "mag"))
        ts.append(df["time"].to_numpy(dtype=float))
        vs.append(df["mag"].to_numpy(dtype=float))
    t = np.concatenate(ts)
    v = np.concatenate(vs)
    order = np.argsort(t, kind="stable")
    t, v = t[order], v[order]
    keep = np.r_[True, np.diff(t) > 0]
    return t[keep], v[keep], ", ".join(str(p) for p in paths)


register(Format("iaga2002", IAGA_EXTENSIONS, read=read_iaga2002))
