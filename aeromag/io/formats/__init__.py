"""The one registry of log formats: extension, sniffing, reader and writer of each.

:func:`read_table` returns the raw table of a file as a :class:`pandas.DataFrame`, with the
canonical column names of ``shared/interface.md`` wherever the format defines them;
:func:`aeromag.io.read_log` then validates it exactly as it validates a CSV log.
:func:`write_table` writes CSV, Parquet or Geosoft XYZ atomically.

Formats (chosen by ``fmt`` or by the file's extension; ``.csv`` files are sniffed for the
native UAV layouts):

=============  ==================  ==========================================================
name           extensions          notes
=============  ==================  ==========================================================
``csv``        .csv .txt           the default (:mod:`aeromag.io.csv`)
``parquet``    .parquet .pq        needs pyarrow (``aeromag[parquet]``)
``xyz``        .xyz                Geosoft XYZ: ``/`` comment lines (the one before the data
                                   with one name per value names the channels), line headers
                                   (``Line 10``, ``Tie 100``, ``L1010.1``, ``Line 10:16``,
                                   ``Trend``/``Base``/``Test``/``Random``/``Special N``), ``*``
                                   for a missing value; SGL/MagNav channel names are mapped by
                                   the ``magnav`` preset
``hdf5``       .h5 .hdf5           MagNav.jl / SGL HDF5: one 1-D dataset per channel (``tt``,
                                   ``mag_1_uc``, ``flux_a_x`` ...), ``magnav`` preset; h5py
``csv_compressed`` .xz .gz .bz2    a compressed CSV (``NAME.csv.xz``), read as a stream
``magarrow``   (sniffed .csv)      Geometrics MagArrow native CSV
``magdrone``   (sniffed .csv)      SENSYS MagDrone R3 native CSV (fluxgate B1; ``magdrone_b2``
                                   takes B2)
=============  ==================  ==========================================================

Another module adds a format with :func:`register` (for example a UAV flight-log reader):
``register(Format("ulog", (".ulg",), read=read_ulog))``.  Presets map native channel names
and units onto canonical columns; see ``docs/formats.md``.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from ...errors import InputError
from ..csv import read_csv
from ..csv_write import write_csv
from ..rows import ROWS_ATTR
from .compressed import read_compressed_csv
from .hdf5 import check_scalar_channels, read_hdf5
from .magarrow import read_magarrow
from .magdrone import read_magdrone
from .parquet import read_parquet, write_parquet
from .presets import MAGNAV_FLUXGATES, MAGNAV_PRESET, apply_preset
from .xyz import GEOSOFT_DUMMY, XYZ_LINE_HEADER, XYZ_LINE_TYPES, read_xyz, write_xyz


@dataclass(frozen=True)
class Format:
    """One log format of the registry.

    Attributes
    ----------
    name : str
        Format name (``fmt=`` of the readers, ``--format`` of the command line).
    extensions : tuple of str
        File extensions (lower case, with the dot) that select this format.
    read : callable or None
        ``read(path) -> DataFrame``: the raw table (canonical names where the format defines
        them), with ``df.attrs[ROWS_ATTR]`` telling where each row is in the file.
    write : callable or None
        ``write(df, path) -> Path``, atomic; None for a format aeromag does not write.
    sniff : callable or None
        ``sniff(head) -> bool`` on the first 4 kB (text) of a ``.csv`` file: True when the
        file is in this native layout.
    options : tuple of str
        Keyword options ``read`` takes (``"allow_truncated"`` for text formats).
    """

    name: str
    extensions: tuple[str, ...] = ()
    read: Callable[[Path], pd.DataFrame] | None = None
    write: Callable[[pd.DataFrame, Path], Path] | None = None
    sniff: Callable[[str], bool] | None = None
    options: tuple[str, ...] = ()


#: The registry, in sniffing order.
REGISTRY: dict[str, Format] = {}


def register(fmt: Format) -> Format:
    """Add (or replace) a format in the registry.

    Parameters
    ----------
    fmt : Format
        The format.

    Returns
    -------
    Format
        ``fmt``.
    """
    REGISTRY[fmt.name] = fmt
    return fmt


def _sniff_magarrow(head: str) -> bool:
    import csv

    first = head.lstrip("\ufeff").lstrip("\r\n").split("\n", 1)[0]
    try:
        cells = [c.strip() for c in next(csv.reader([first]))]
    except (csv.Error, StopIteration):
        return False
    return {"Counter", "Date", "Time", "Mag"} <= set(cells)


def _sniff_magdrone(head: str) -> bool:
    return bool(re.search(r"^\ufeff?MagDrone", head, re.MULTILINE)
                or re.search(r'^\ufeff?\s*"?Timestamp\s*\[[^\]\n]*\]"?\s*;', head,
                             re.MULTILINE))


def _read_xyz(path: Path, **kw: bool) -> pd.DataFrame:
    return apply_preset(read_xyz(path, **kw), MAGNAV_PRESET, MAGNAV_FLUXGATES)


def _read_hdf5(path: Path) -> pd.DataFrame:
    df = apply_preset(read_hdf5(path), MAGNAV_PRESET, MAGNAV_FLUXGATES)
    check_scalar_channels(df, MAGNAV_PRESET, str(path))
    return df


_TEXT = ("allow_truncated",)
register(Format("csv", (".csv", ".txt"), read=read_csv, write=write_csv,
                options=(*_TEXT, "usecols", "dtypes")))
register(Format("parquet", (".parquet", ".pq"), read=read_parquet, write=write_parquet,
                options=("usecols",)))
register(Format("xyz", (".xyz",), read=_read_xyz, write=write_xyz, options=_TEXT))
register(Format("hdf5", (".h5", ".hdf5"), read=_read_hdf5))
register(Format("csv_compressed", (".xz", ".gz", ".bz2"), read=read_compressed_csv))
register(Format("magarrow", read=read_magarrow, sniff=_sniff_magarrow, options=_TEXT))
register(Format("magdrone", read=read_magdrone, sniff=_sniff_magdrone, options=_TEXT))
register(Format("magdrone_b2", read=lambda p, **kw: read_magdrone(p, sensor=2, **kw),
                options=_TEXT))


def formats() -> tuple[str, ...]:
    """Names of the registered formats."""
    return tuple(REGISTRY)


def extensions() -> dict[str, str]:
    """``{extension: format name}`` of the registered formats."""
    return {ext: f.name for f in REGISTRY.values() for ext in f.extensions}


#: Formats by file extension (as registered at import; see :func:`extensions`).
EXTENSIONS: dict[str, str] = extensions()

#: Names of the built-in formats (see :func:`formats`).
FORMATS: tuple[str, ...] = formats()


# --------------------------------------------------------------------------- detection
def detect_format(path: str | os.PathLike[str], fmt: str | None = None) -> str:
    """Return the format name of ``path``: ``fmt`` when given, else from extension and content.

    Parameters
    ----------
    path : path-like
        The file.
    fmt : str, optional
        Explicit format (one of :func:`formats`).

    Returns
    -------
    str
        A registered format name.
    """
    p = Path(path)
    if fmt:
        f = fmt.strip().lower().replace("-", "_")
        if f not in REGISTRY:
            raise InputError(f"{p}: unknown format {fmt!r}; use one of {', '.join(REGISTRY)}")
        return f
    f = extensions().get(p.suffix.lower(), "csv")
    if f == "csv":
        f = sniff_csv(p) or "csv"
    return f


def sniff_csv(path: Path) -> str | None:
    """Recognise a native CSV layout (MagArrow, MagDrone ...) from the first 4 kB, else None."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096).decode("utf-8", errors="replace")
    except OSError:
        return None
    for f in REGISTRY.values():
        if f.sniff is not None and f.sniff(head):
            return f.name
    return None


# --------------------------------------------------------------------------- reading
#: Delimiters a log is sometimes written with instead of commas, and their names.
_OTHER_DELIMITERS = {"\t": ("tab", "tabs"), ";": ("semicolon", "semicolons"),
                     "|": ("pipe", "pipes")}


def check_delimiter(path: Path) -> None:
    """Refuse a CSV log whose header is one field holding tabs, semicolons or pipes.

    Such a file is tab- (or ``;``-) separated: read as CSV it is one column, and every
    canonical column would be reported missing.  aeromag's CSV is comma-separated (with
    ``.`` decimals); a file that is not is an error naming the delimiter and what to do.

    Parameters
    ----------
    path : Path
        The file (read as format ``csv``).

    Raises
    ------
    InputError
        When the header looks separated by another delimiter.
    """
    from ..csv import csv_header_fields
    from ..messages import clean

    head = csv_header_fields(path)
    if head is None or len(head[0]) != 1:
        return
    names, line = head
    counts = {d: names[0].count(d) for d in _OTHER_DELIMITERS}
    d = max(counts, key=counts.__getitem__)
    if counts[d] == 0:
        return
    one, many = _OTHER_DELIMITERS[d]
    decimals = " with '.' decimals" if d == ";" else ""
    raise InputError(
        f"{clean(path)}: looks {one}-separated (header line {line} has {counts[d]}"
        f" {many if counts[d] > 1 else one} and no comma); aeromag reads comma-separated CSV:"
        f" save it comma-separated{decimals} (e.g. from a spreadsheet, or"
        f" tr '{repr(d)[1:-1]}' ',' < IN > OUT.csv when no value holds a comma)")


def read_table(path: str | os.PathLike[str], fmt: str | None = None) -> pd.DataFrame:
    """Read the raw table of a log file in any supported format.

    Parameters
    ----------
    path : path-like
        The file.
    fmt : str, optional
        Format name (default from the extension; ``.csv`` files are sniffed for native UAV
        layouts).

    Returns
    -------
    DataFrame
        One row per sample; canonical column names where the format or its preset defines
        them (``time`` [s], ``mag``/``flux_*`` [nT], ``lat``/``lon`` [deg], ``alt`` [m]), other
        channels under their own names.  ``df.attrs["format"]`` holds the format name.
    """
    df = read_table_rows(path, fmt)
    df.attrs.pop(ROWS_ATTR, None)
    return df


def read_table_rows(path: str | os.PathLike[str], fmt: str | None = None, *,
                    allow_truncated: bool = False,
                    usecols: Sequence[str] | None = None,
                    dtypes: dict[str, Any] | None = None) -> pd.DataFrame:
    """:func:`read_table`, with ``df.attrs[ROWS_ATTR]`` telling where each row is in the file.

    Used by :func:`aeromag.io.read_log` to name the file line (or the sample) of a bad value.
    ``allow_truncated`` is passed to the text formats (see :func:`aeromag.io.read_log`);
    ``usecols`` keeps only these columns (source names; parsed alone where the format's
    reader can, the CSV reader).
    """
    from ..messages import check_input_file

    p = Path(path)
    check_input_file(p)
    f = detect_format(p, fmt)
    reader = REGISTRY[f].read
    if f == "csv":
        check_delimiter(p)
    if reader is None:
        raise InputError(f"{p}: aeromag cannot read the {f} format")
    opts: dict[str, Any] = {"allow_truncated": allow_truncated} if allow_truncated else {}
    if usecols is not None:
        opts["usecols"] = list(usecols)
    if dtypes:
        opts["dtypes"] = dict(dtypes)
    df = reader(p, **{k: v for k, v in opts.items() if k in REGISTRY[f].options})
    if usecols is not None and "usecols" not in REGISTRY[f].options:
        want = set(usecols)
        attrs = dict(df.attrs)
        df = df[[c for c in df.columns if c in want]]
        df.attrs.update(attrs)
    df.attrs["format"] = f
    return df


# --------------------------------------------------------------------------- writing
def output_format(path: str | os.PathLike[str]) -> str:
    """The format an output log is written in, from its extension (``-o OUT.ext``).

    Parameters
    ----------
    path : path-like
        The output file.

    Returns
    -------
    str
        ``"csv"`` (``.csv``, ``.txt``), ``"parquet"`` (``.parquet``, ``.pq``) or ``"xyz"``
        (Geosoft XYZ with line headers, ``.xyz``): the registered formats with a writer.

    Raises
    ------
    InputError
        For any other extension (never a CSV under another name), or a path that is not a
        regular file path (see :func:`aeromag.io.outputs.check_output_path`).
    """
    from ..messages import clean
    from ..outputs import check_output_path

    p = Path(path)
    check_output_path(p)  # a folder, device or FIFO: say so first
    ext = p.suffix.lower()
    f = extensions().get(ext)
    if f is None or REGISTRY[f].write is None:
        writable = sorted(e for e, n in extensions().items() if REGISTRY[n].write is not None)
        what = f"'{clean(ext)}' is not a format aeromag writes" if ext else "no extension"
        raise InputError(f"-o {clean(p)}: {what}; name the output with one of"
                         f" {', '.join(writable)} (e.g. -o {clean(p.stem or 'out')}.csv)")
    return f


def write_table(df: pd.DataFrame, path: str | os.PathLike[str], fmt: str | None = None) -> Path:
    """Write a table atomically as CSV, Parquet or Geosoft XYZ.

    Parameters
    ----------
    df : DataFrame
        The table (index not written).
    path : path-like
        Destination.
    fmt : {"csv", "parquet", "xyz"}, optional
        Default from the extension.

    Returns
    -------
    Path
        The written path.
    """
    p = Path(path)
    f = (fmt or extensions().get(p.suffix.lower(), "csv")).lower()
    writer = REGISTRY[f].write if f in REGISTRY else None
    if writer is None:
        raise InputError(f"{p}: cannot write format {f!r}; use csv, parquet or xyz")
    return writer(df, p)


__all__ = [
    "EXTENSIONS", "FORMATS", "GEOSOFT_DUMMY", "MAGNAV_FLUXGATES", "MAGNAV_PRESET", "REGISTRY",
    "XYZ_LINE_HEADER", "XYZ_LINE_TYPES", "Format", "apply_preset", "check_delimiter",
    "detect_format",
    "extensions", "formats", "output_format", "read_magarrow", "read_magdrone", "read_table",
    "read_table_rows", "read_xyz", "register", "sniff_csv", "write_table", "write_xyz",
]
