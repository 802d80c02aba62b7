"""File formats beyond plain CSV: Parquet, Geosoft XYZ, MagNav/SGL HDF5 and XYZ, UAV logs.

:func:`read_table` returns the raw table of a file as a :class:`pandas.DataFrame`, with the
canonical column names of ``shared/interface.md`` wherever the format defines them;
:func:`aeromag.io.read_log` then validates it exactly as it validates a CSV log.
:func:`write_table` writes CSV, Parquet or Geosoft XYZ atomically.

Formats (chosen by ``fmt`` or by the file's extension; ``.csv`` files are sniffed for the
native UAV layouts):

=============  ==================  ==========================================================
name           extensions          notes
=============  ==================  ==========================================================
``csv``        .csv .txt           the default (read by :mod:`aeromag.io`)
``parquet``    .parquet .pq        needs pyarrow (``aeromag[parquet]``)
``xyz``        .xyz                Geosoft XYZ: ``/`` comment lines (the one before the data
                                   with one name per value names the channels), line headers
                                   (``Line 10``, ``Tie 100``, ``L1010.1``, ``Line 10:16``,
                                   ``Trend``/``Base``/``Test``/``Random``/``Special N``), ``*``
                                   for a missing value; SGL/MagNav channel names are mapped by
                                   the ``magnav`` preset
``hdf5``       .h5 .hdf5           MagNav.jl / SGL HDF5: one 1-D dataset per channel (``tt``,
                                   ``mag_1_uc``, ``flux_a_x`` ...), ``magnav`` preset; h5py
``magarrow``   (sniffed .csv)      Geometrics MagArrow native CSV
``magdrone``   (sniffed .csv)      SENSYS MagDrone R3 native CSV (fluxgate B1; ``magdrone_b2``
                                   takes B2)
=============  ==================  ==========================================================

Presets map native channel names and units onto canonical columns; see ``docs/formats.md``.
"""

from __future__ import annotations

import io as _io
import logging
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from .errors import InputError
from .io import (
    FIELD_UNITS_TO_NT,
    FLUX_COLUMNS,
    ROWS_ATTR,
    atomic_path,
    check_unique_names,
    datetime_seconds,
    numeric_values,
    row_location,
    rows_after_header,
    rows_in_runs,
    rows_numbered,
    write_csv,
)

log = logging.getLogger(__name__)

#: Formats by file extension.
EXTENSIONS: dict[str, str] = {
    ".csv": "csv",
    ".txt": "csv",
    ".parquet": "parquet",
    ".pq": "parquet",
    ".xyz": "xyz",
    ".h5": "hdf5",
    ".hdf5": "hdf5",
}

FORMATS: tuple[str, ...] = ("csv", "parquet", "xyz", "hdf5", "magarrow", "magdrone",
                            "magdrone_b2")

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

_MISSING_XYZ = "*"


# --------------------------------------------------------------------------- detection
def detect_format(path: str | os.PathLike[str], fmt: str | None = None) -> str:
    """Return the format name of ``path``: ``fmt`` when given, else from extension and content.

    Parameters
    ----------
    path : path-like
        The file.
    fmt : str, optional
        Explicit format (one of :data:`FORMATS`).

    Returns
    -------
    str
        One of :data:`FORMATS`.
    """
    p = Path(path)
    if fmt:
        f = fmt.strip().lower().replace("-", "_")
        if f not in FORMATS:
            raise InputError(f"{p}: unknown format {fmt!r}; use one of {', '.join(FORMATS)}")
        return f
    f = EXTENSIONS.get(p.suffix.lower(), "csv")
    if f == "csv":
        f = sniff_csv(p) or "csv"
    return f


def sniff_csv(path: Path) -> str | None:
    """Recognise the native CSV of a MagArrow or MagDrone from the first 4 kB, else None."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096).decode("utf-8", errors="replace")
    except OSError:
        return None
    first = head.lstrip("\ufeff").split("\n", 1)[0]
    cells = [c.strip() for c in first.split(",")]
    if {"Counter", "Date", "Time", "Mag"} <= set(cells):
        return "magarrow"
    if re.search(r"^MagDrone", head, re.MULTILINE) or re.search(
        r"^Timestamp \[ms\];", head, re.MULTILINE
    ):
        return "magdrone"
    return None


# --------------------------------------------------------------------------- reading
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


def read_table_rows(path: str | os.PathLike[str], fmt: str | None = None) -> pd.DataFrame:
    """:func:`read_table`, with ``df.attrs[ROWS_ATTR]`` telling where each row is in the file.

    Used by :func:`aeromag.io.read_log` to name the file line (or the sample) of a bad value.
    """
    p = Path(path)
    if not p.exists():
        raise InputError(f"{p}: file not found")
    if p.is_dir():
        raise InputError(f"{p}: is a folder, not a log file")
    f = detect_format(p, fmt)
    if f == "csv":
        from .io import _read_csv

        df = _read_csv(p)
    elif f == "parquet":
        df = _read_parquet(p)
    elif f == "xyz":
        df = apply_preset(read_xyz(p), MAGNAV_PRESET, MAGNAV_FLUXGATES)
    elif f == "hdf5":
        df = apply_preset(_read_hdf5(p), MAGNAV_PRESET, MAGNAV_FLUXGATES)
    elif f == "magarrow":
        df = read_magarrow(p)
    else:
        df = read_magdrone(p, sensor=2 if f == "magdrone_b2" else 1)
    df.attrs["format"] = f
    return df


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


def _read_parquet(path: Path) -> pd.DataFrame:
    """Read a Parquet file; a named pandas index (``df.set_index("time")``) becomes a column.

    Types are kept; a datetime ``time`` is turned into seconds by :func:`aeromag.io.read_log`.
    """
    try:
        import pyarrow.parquet as pq
    except ImportError:  # pragma: no cover - pyarrow is a test dependency
        raise InputError(
            f"{path}: reading Parquet needs pyarrow: pip install 'aeromag[parquet]'") from None
    try:
        df = pq.read_table(path).to_pandas()
    except Exception as exc:  # noqa: BLE001 - any pyarrow failure is a bad file
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputError(f"{path}: cannot read as Parquet ({msg}); is it a Parquet file?") from None
    named = [n for n in df.index.names if n is not None]
    if named:
        # Saved with e.g. df.set_index("time"): the index is a column of the log.
        clash = [n for n in named if n in df.columns]
        if clash:
            raise InputError(f"{path}: {clash[0]!r} is both the index and a column; save the"
                             " table with a plain index (df.reset_index(drop=True))")
        df = df.reset_index()
    df.attrs[ROWS_ATTR] = rows_numbered("row")
    return df


def _read_hdf5(path: Path) -> pd.DataFrame:
    """Read the 1-D datasets of an HDF5 file (the length most of them share) as columns."""
    try:
        import h5py
    except ImportError:  # pragma: no cover
        raise InputError(f"{path}: reading HDF5 needs h5py: pip install 'aeromag[hdf5]'") from None
    try:
        with h5py.File(path, "r") as h5:
            arrays = {}
            for name, ds in h5.items():
                if isinstance(ds, h5py.Dataset) and ds.ndim == 1 and ds.shape[0] > 1:
                    arrays[name] = ds[()]
    except OSError as exc:
        raise InputError(f"{path}: cannot read as HDF5 ({exc}); is it an HDF5 file?") from None
    if not arrays:
        raise InputError(f"{path}: no 1-D channel datasets in this HDF5 file")
    lengths = pd.Series({k: len(v) for k, v in arrays.items()})
    n = int(lengths.mode().iloc[0])
    skipped = sorted(k for k, v in arrays.items() if len(v) != n)
    if skipped:
        log.info("%s: skipped HDF5 datasets of another length: %s", path, ", ".join(skipped))
    df = pd.DataFrame({k: v for k, v in arrays.items() if len(v) == n})
    df.attrs[ROWS_ATTR] = rows_numbered("sample")
    return df


#: Geosoft line types: the header words Oasis montaj writes, and the letters of compact line
#: names (``L1010.1``), as Geosoft's gxpy ``create_line_name`` spells them.
XYZ_LINE_TYPES: tuple[str, ...] = ("line", "tie", "trend", "base", "test", "random", "special")
_XYZ_LINE_LETTERS: dict[str, str] = {"l": "line", "t": "tie", "b": "base", "s": "test",
                                     "r": "trend", "d": "random", "p": "special"}

#: A line header: ``Line 10``, ``LINE 10.1`` (number.version), ``Line 10:16`` (:flight),
#: ``Tie 100``, ``Trend 5``, ``Base 1``, ``Test 2``, ``Random 3``, ``Special 4`` (any case), a
#: compact line name ``L1010.1`` / ``T100``, or ``Line *`` (rows without a line id).
XYZ_LINE_HEADER = re.compile(
    r"^(?:(?P<word>line|tie|trend|base|test|random|special)\s+(?P<num>-?\d+|\*)"
    r"|(?P<letter>[ltbsrdp])(?P<cnum>\d+))"
    r"(?:\.(?P<ver>\d+))?(?::(?P<flt>\d+))?$",
    re.IGNORECASE,
)

#: Geosoft's dummy (missing) value of floating-point channels, when written as a number.
GEOSOFT_DUMMY = -1.0e32

#: Unit words: a ``/`` line made only of these is a units row, never the channel names.
_UNIT_WORDS = frozenset({
    "-", "s", "sec", "ms", "us", "m", "km", "ft", "deg", "degrees", "rad", "nt", "ut",
    "\u00b5t", "\u03bct", "pt", "mt", "g", "mg", "gauss", "nt/m", "m/s", "m/s2", "m/s^2",
    "deg/s", "kpa", "hpa", "pa", "a", "v", "hz", "c", "degc", "%", "none", "counts",
})

_NAME_TOKEN = re.compile(r"^[A-Za-z_][^\s]*$")


def _line_key(m: re.Match[str]) -> tuple[str, int, int, int | None] | None:
    """(type, number, version, flight) of a line header; None for ``Line *``."""
    if m.group("word"):
        kind, num = m.group("word").lower(), m.group("num")
    else:
        kind, num = _XYZ_LINE_LETTERS[m.group("letter").lower()], m.group("cnum")
    if num == "*":
        return None
    flight = m.group("flt")
    return kind, int(num), int(m.group("ver") or 0), int(flight) if flight else None


def _line_ids(keys: Sequence[tuple[str, int, int, int | None] | None]
              ) -> tuple[dict[tuple[str, int, int, int | None], int], bool]:
    """Integer ids of the line labels of a file; also whether some label lost its number.

    A flight line keeps its number; then the other types (tie, trend, ...) keep theirs, in file
    order, while it is free.  A label whose number is taken (``Tie 100`` beside ``Line 100``,
    ``L1010.2`` beside ``L1010.1``, the same line on another flight) gets ``B + 1``, ``B + 2``,
    ... in file order, ``B`` being the smallest power of ten above every number in the file,
    so that such ids never collide with, nor pass for, a line number of the file.
    """
    order = list(dict.fromkeys(k for k in keys if k is not None))
    ids: dict[tuple[str, int, int, int | None], int] = {}
    taken: set[int] = set()
    for lines_first in (True, False):
        for k in order:
            if k in ids or (k[0] == "line") != lines_first:
                continue
            if k[1] not in taken:
                ids[k] = k[1]
                taken.add(k[1])
    rest = [k for k in order if k not in ids]
    if rest:
        base = 10 ** len(str(max(abs(k[1]) for k in order)))
        for j, k in enumerate(rest, start=1):
            ids[k] = base + j
    return ids, bool(rest)


def _xyz_channel_names(p: Path, comments: Sequence[tuple[int, str]], n_values: int,
                       where: str) -> list[str]:
    """Pick the channel-name line among the ``/`` lines before the data.

    ``//`` lines (Oasis ``//Flight 1``, ``//Date ...``) and underlines (``/=====``) are never
    names; among the others, the line with as many names as the first data row has values is
    taken, preferring one made of name-like words and never a units row (``/ s deg m nT``)
    after such a line; of several, the last one before the data.  ``n_values`` is the number
    of values most data rows have, ``where`` the first such row (for the message).
    """
    cands: list[tuple[int, list[str]]] = []
    for ln, text in comments:
        if text.startswith("//"):
            continue
        tokens = text[1:].split()
        if not tokens or all(set(t) <= set("=-_*~+#") for t in tokens):
            continue
        cands.append((ln, tokens))
    if not cands:
        raise InputError(f"{p}: no channel-name line ('/ name1 name2 ...') before the data")
    fit = [(ln, t) for ln, t in cands if len(t) == n_values]
    # A units row follows the names it annotates: one after another fitting line is skipped.
    fit = [(ln, t) for k, (ln, t) in enumerate(fit)
           if k == 0 or not all(x.lower() in _UNIT_WORDS or x[:1] in "[(" for x in t)]
    named = [(ln, t) for ln, t in fit if all(_NAME_TOKEN.match(x) for x in t)]
    pick = named or fit
    if not pick:
        ln, t = cands[-1]
        raise InputError(
            f"{p}: {where}: {n_values} values, but no '/' line before the data names"
            f" {n_values} channels (line {ln} names {len(t)}: {' '.join(t[:8])}"
            f"{' ...' if len(t) > 8 else ''}); every data row needs one value per channel")
    return pick[-1][1]


def _xyz_field_counts(blob: bytes) -> np.ndarray:
    """Blank-separated fields on each line of ``blob`` (lines stripped, ``\\n``-joined).

    Vectorised: a field starts at a byte that is neither a blank (space, tab: the parser's
    separators) nor a newline, after one that is.
    """
    raw = np.frombuffer(blob, dtype=np.uint8)
    nl = raw == 10
    gap = raw == 32
    gap |= raw == 9
    gap |= nl
    start = np.empty_like(gap)
    start[0] = not gap[0]
    np.logical_not(gap[1:], out=start[1:])
    start[1:] &= gap[:-1]
    line_starts = np.empty(int(nl.sum()) + 1, dtype=np.int64)
    line_starts[0] = 0
    line_starts[1:] = np.flatnonzero(nl) + 1
    return np.add.reduceat(start.view(np.uint8), line_starts, dtype=np.int64)


def read_xyz(path: str | os.PathLike[str]) -> pd.DataFrame:
    """Read a Geosoft XYZ file (line-based ASCII).

    ``/`` lines are comments.  The channel names are on the ``/`` line before the data whose
    word count matches the values of the data rows (``//`` lines, ``/====`` underlines and
    units rows are never names; see :func:`_xyz_channel_names`).  Every data row must have
    one value per channel: a row with more or fewer is an error naming its line (columns are
    never shifted).  ``*`` and Geosoft's numeric dummy -1e32 are missing values.  A UTF-8 BOM
    is ignored.

    Line headers (:data:`XYZ_LINE_HEADER`: ``Line 10``, ``LINE 10.1``, ``L1010.1``, ``Tie 100``,
    ``T100``, ``Line 10:16``, ``Trend``/``Base``/``Test``/``Random``/``Special N``) start a line;
    the rows that follow get an integer id in ``line`` (the line number; see
    :func:`_line_ids` when two labels share a number), ``line_type`` (``line``, ``tie``, ...;
    when the file has other types than flight lines) and ``line_label`` (the header as written;
    when the number alone does not tell the lines apart: versions, flights, shared numbers).
    Rows before the first header, or after ``Line *``, have no line (NaN).  A channel already
    named ``line`` (any case) is kept and no header ids are added.

    Parameters
    ----------
    path : path-like
        The file.

    Returns
    -------
    DataFrame
        The channels (numbers as float64 where every value parses).
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8-sig", errors="replace")
    except OSError as exc:
        raise InputError(f"{p}: cannot read ({exc})") from None
    lines = text.split("\n") if "\n" in text or "\r" not in text else text.split("\r")
    del text
    comments: list[tuple[int, str]] = []
    data: list[str] = []
    run_rows: list[int] = []
    run_lines: list[int] = []
    seg_keys: list[tuple[str, int, int, int | None] | None] = [None]
    seg_labels: list[str | None] = [None]
    seg_start: list[int] = [0]
    last = -2
    # Header lines are few; data lines are collected in bulk (one join + one parser call).
    for ln, raw in enumerate(lines, start=1):
        s = raw.strip()
        if not s:
            continue
        c0 = s[0]
        if c0 == "/":
            if not data:
                comments.append((ln, s))
            continue
        if c0.isalpha():
            m = XYZ_LINE_HEADER.match(s)
            if m:
                seg_keys.append(_line_key(m))
                seg_labels.append(" ".join(s.split()))
                seg_start.append(len(data))
                continue
        if ln != last + 1:
            run_rows.append(len(data))
            run_lines.append(ln)
        last = ln
        data.append(s)
    del lines
    if not data:
        raise InputError(f"{p}: no data rows in this XYZ file")
    rows = rows_in_runs(run_rows, run_lines)
    blob = "\n".join(data).encode("utf-8")
    n_rows = len(data)
    del data
    counts = _xyz_field_counts(blob)
    # The channel count is the values most rows have (a short or long row is reported below).
    typical = int(np.argmax(np.bincount(counts)))
    first = int(np.argmax(counts == typical))
    names = _xyz_channel_names(p, comments, typical, row_location(rows, first))
    check_unique_names(names, str(p), what="channel-name line")
    wrong = np.flatnonzero(counts != len(names))
    if wrong.size:
        i = int(wrong[0])
        raise InputError(
            f"{p}: {row_location(rows, i)}: {int(counts[i])} values but {len(names)} channels"
            f" ({' '.join(names[:8])}{' ...' if len(names) > 8 else ''}); every data row needs"
            " one value per channel ('*' for a missing one)")
    try:
        df = pd.read_csv(_io.BytesIO(blob), sep=r"\s+", header=None, names=names,
                         index_col=False, na_values=[_MISSING_XYZ], keep_default_na=False,
                         engine="c", encoding="utf-8")
    except (pd.errors.ParserError, ValueError) as exc:
        msg = str(exc).strip().splitlines()[-1]
        raise InputError(f"{p}: cannot parse the XYZ data ({msg}); every row needs"
                         f" {len(names)} values separated by blanks") from None
    del blob
    if len(df) != n_rows:  # pragma: no cover - defensive: the counts were checked
        raise InputError(f"{p}: the XYZ data rows could not be read one per line")
    for c in df.columns:
        if df[c].dtype == np.float64:
            dummy = df[c].to_numpy() == GEOSOFT_DUMMY
            if dummy.any():
                log.info("%s: %d Geosoft dummy value(s) -1e32 in %r read as missing", p,
                         int(dummy.sum()), c)
                df[c] = np.where(dummy, np.nan, df[c].to_numpy())
    if len(seg_keys) > 1:
        _add_line_columns(df, names, seg_keys, seg_labels, seg_start, n_rows)
    df.attrs[ROWS_ATTR] = rows
    return df


def _add_line_columns(df: pd.DataFrame, names: Sequence[str],
                      seg_keys: Sequence[tuple[str, int, int, int | None] | None],
                      seg_labels: Sequence[str | None], seg_start: Sequence[int],
                      n_rows: int) -> None:
    """``line`` / ``line_type`` / ``line_label`` of the rows from the XYZ line headers."""
    counts = np.diff(np.r_[np.asarray(seg_start, dtype=np.int64), n_rows])
    ids, renumbered = _line_ids(seg_keys)
    lower = {n.lower() for n in names}
    present = [k for k, c in zip(seg_keys, counts, strict=True) if c and k is not None]
    missing = any(k is None and c for k, c in zip(seg_keys, counts, strict=True))
    if "line" not in lower:
        if missing:  # float with NaN, as pandas reads an integer column with blanks
            seg_id = np.array([np.nan if k is None else ids[k] for k in seg_keys], np.float64)
        else:
            seg_id = np.array([0 if k is None else ids[k] for k in seg_keys], np.int64)
        df["line"] = np.repeat(seg_id, counts)
    if any(k[0] != "line" for k in present) and "line_type" not in lower:
        kinds = np.array([None if k is None else k[0] for k in seg_keys], dtype=object)
        df["line_type"] = np.repeat(kinds, counts)
    if (renumbered or any(k[2] or k[3] is not None for k in present)) and (
            "line_label" not in lower):
        labels = np.array([None if k is None else lab
                           for k, lab in zip(seg_keys, seg_labels, strict=True)], dtype=object)
        df["line_label"] = np.repeat(labels, counts)
    if renumbered:
        moved = [f"{lab} -> {ids[k]}" for k, lab in dict.fromkeys(
            zip(seg_keys, seg_labels, strict=True)) if k is not None and ids[k] != k[1]]
        log.info("line numbers shared by several line labels; new ids (kept in line_label):"
                 " %s%s", ", ".join(moved[:5]), " ..." if len(moved) > 5 else "")


def _parse_datetime_seconds(date: pd.Series, clock: pd.Series, source: str,
                            rows: Mapping[str, object] | None = None) -> np.ndarray:
    """``Date`` + ``Time`` columns -> seconds since 1970-01-01 UTC (float64)."""
    stamp = date.astype(str).str.strip() + " " + clock.astype(str).str.strip()
    dt = pd.to_datetime(stamp, format="mixed", errors="coerce", utc=True)
    bad = dt.isna().to_numpy()
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"{source}: columns 'Date'/'Time', {row_location(rows, i)}: cannot"
                         f" read {stamp.iloc[i]!r} as a date and time; fix or remove the row")
    return datetime_seconds(dt, source, rows)


def _native_values(s: pd.Series, source: str, column: str,
                   rows: Mapping[str, object] | None) -> np.ndarray:
    """float64 values of an instrument channel; an unparseable cell is an error (never NaN)."""
    return numeric_values(s, source, column, rows,
                          remedy="fix or remove that row of the instrument log")


def _interp_sparse(t: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Linear interpolation in time over the finite samples (NaN outside their span)."""
    ok = np.isfinite(values)
    if ok.sum() < 2:
        return values
    out = np.interp(t, t[ok], values[ok])
    out[(t < t[ok][0]) | (t > t[ok][-1])] = np.nan
    return out


def read_magarrow(path: str | os.PathLike[str]) -> pd.DataFrame:
    """Read the native CSV of a Geometrics MagArrow.

    Canonical columns: ``time`` = ``Date`` + ``Time`` (UTC) in seconds since 1970-01-01;
    ``mag`` = ``Mag`` [nT] (NaN where ``MagValid`` is 0); ``lat``/``lon`` = ``Latitude`` /
    ``Longitude`` [deg] (the instrument interpolates them to every row); ``alt`` = height above
    the WGS84 ellipsoid [m] = ``Altitude`` (above mean sea level, from the GGA sentence) +
    ``HeightOverEllipsoid`` (which holds the GGA geoid separation), interpolated in time between
    the GNSS rows.  A value of ``Mag``, ``MagValid``, the position or height columns that is
    not a number (or a ``Date``/``Time`` that is not a date and time) is an error naming its
    line; the empty fields the rows end with are dropped.  The IMU channels (``CompassX/Y/Z``
    raw counts, gyroscope, accelerometer) are logged on sparse rows only and stay NaN
    elsewhere; the compass is not a calibrated fluxgate in nT, so no ``flux_*`` columns are
    made (map them with ``--col`` and ``--units`` if yours is calibrated).

    Parameters
    ----------
    path : path-like
        The MagArrow CSV.

    Returns
    -------
    DataFrame
    """
    from .io import _read_csv

    p = Path(path)
    src = str(p)
    # The rows end with one or two delimiters more than the header has (GNSS rows two): the
    # CSV reader drops these empty fields (and refuses a row where one holds a value) instead
    # of shifting the columns.
    df = _read_csv(p, spare_fields=_MAGARROW_SPARE_FIELDS)
    rows = df.attrs.get(ROWS_ATTR)
    missing = [c for c in ("Date", "Time", "Mag") if c not in df.columns]
    if missing:
        raise InputError(f"{p}: not a MagArrow log: missing column(s) {', '.join(missing)}")
    t = _parse_datetime_seconds(df["Date"], df["Time"], src, rows)
    out = df.drop(columns=["Date", "Time"])
    out.attrs.clear()
    out.insert(0, "time", t)
    mag = _native_values(out.pop("Mag"), src, "Mag", rows)
    if "MagValid" in out.columns:
        valid = _native_values(out["MagValid"], src, "MagValid", rows)
        invalid = valid == 0
        if invalid.any():
            log.info("%s: %d sample(s) with MagValid=0 set to NaN", p, int(invalid.sum()))
            mag = np.where(invalid, np.nan, mag)
    out.insert(1, "mag", mag)
    rename = {"Latitude": "lat", "Longitude": "lon"}
    out = out.rename(columns={k: v for k, v in rename.items() if k in out.columns})
    for c in ("lat", "lon"):
        if c in out.columns:
            out[c] = _native_values(out[c], src, {"lat": "Latitude", "lon": "Longitude"}[c],
                                    rows)
    if "Altitude" in out.columns:
        msl = _native_values(out["Altitude"], src, "Altitude", rows)
        sep = (_native_values(out["HeightOverEllipsoid"], src, "HeightOverEllipsoid", rows)
               if "HeightOverEllipsoid" in out.columns else np.zeros(len(out)))
        alt = _interp_sparse(t, msl + sep)
        if np.isfinite(alt).any():
            out["alt"] = alt
    out.attrs["units"] = {"time": "s", "mag": "nT", "lat": "deg", "lon": "deg", "alt": "m"}
    out.attrs[ROWS_ATTR] = rows
    return out


#: Empty fields a MagArrow row may have after the header's last column (1 to 2 seen).
_MAGARROW_SPARE_FIELDS = 4

_MAGDRONE_UNIT = re.compile(r"^\s*(.*?)\s*\[(.*)\]\s*$")

#: Time units of a MagDrone ``Timestamp [unit]`` header: seconds = value * num / den (a
#: division where exact, so that 65 ms is exactly the float nearest 0.065 s).
_TIME_UNITS: dict[str, tuple[float, float]] = {
    "ns": (1.0, 1e9), "us": (1.0, 1e6), "\u00b5s": (1.0, 1e6), "\u03bcs": (1.0, 1e6),
    "ms": (1.0, 1e3), "s": (1.0, 1.0), "sec": (1.0, 1.0), "min": (60.0, 1.0),
    "h": (3600.0, 1.0),
}


def read_magdrone(path: str | os.PathLike[str], *, sensor: int = 1) -> pd.DataFrame:
    """Read the native CSV of a SENSYS MagDrone R3 (metadata header, then a ``;`` table).

    The metadata lines before the ``Timestamp [ms];...`` header are kept in
    ``df.attrs["metadata"]``.  Canonical columns: ``time`` = ``Timestamp [ms]`` / 1000 [s since
    the logger started; another time unit in the header (ns, us, s, min, h) is converted, a
    missing or unknown one is an error]; ``flux_x/y/z`` = fluxgate ``B1x/B1y/B1z``
    (``sensor=2``: ``B2``), converted to nT from the unit in the header (the R3 writes nT; pT,
    uT/µT/μT, mT, G are converted, a missing or unknown unit is an error); the other fluxgate
    stays as ``B2x``... (or ``B1x``...).  A value of these columns, or of the GPS columns, that
    is not a number is an error naming its line (never silently NaN).  There is no scalar
    ``mag``: the pipeline then uses the fluxgate magnitude.  GPS columns hold 0 on rows
    without a fix; there ``lat``/``lon`` [deg] are interpolated in time between fixes
    (Quality > 0), and ``Altitude`` (above mean sea level: the file holds no geoid separation)
    becomes ``alt_msl`` [m], not ``alt``.

    Parameters
    ----------
    path : path-like
        The MagDrone CSV.
    sensor : {1, 2}
        Fluxgate mapped to ``flux_x/y/z``.

    Returns
    -------
    DataFrame
    """
    p = Path(path)
    if sensor not in (1, 2):
        raise InputError(f"{p}: MagDrone fluxgate {sensor} does not exist; use 1 or 2")
    meta: list[str] = []
    header_at = None
    with open(p, encoding="utf-8", errors="replace") as fh:
        for i, line in enumerate(fh):
            if line.lstrip().startswith("Timestamp"):
                header_at = i
                break
            if line.strip():
                meta.append(line.strip())
            if i > 500:
                break
    if header_at is None:
        raise InputError(f"{p}: no 'Timestamp [ms];...' header line: not a MagDrone R3 log")
    try:
        raw = pd.read_csv(p, sep=";", skiprows=header_at, skipinitialspace=True,
                          low_memory=False)
    except (pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        msg = str(exc).strip().splitlines()[-1]
        raise InputError(f"{p}: cannot parse the MagDrone table ({msg})") from None
    raw = raw.loc[:, [c for c in raw.columns if not str(c).startswith("Unnamed")]]
    names: dict[str, str] = {}
    units: dict[str, str] = {}
    for c in raw.columns:
        m = _MAGDRONE_UNIT.match(str(c))
        base, unit = (m.group(1), m.group(2)) if m else (str(c).strip(), "")
        if base in names.values():  # e.g. 'GPSTime' and 'GPSTime [hh:mm:ss.sss]'
            base = f"{base}_{unit}".replace(":", "").replace(".", "")
        names[c] = base
        units[base] = unit
    df = raw.rename(columns=names)
    src = str(p)
    rows = rows_after_header(p, header_at + 1)
    check_unique_names([str(c) for c in df.columns], src, what="MagDrone header")
    if "Timestamp" not in df.columns:
        raise InputError(f"{p}: no 'Timestamp' column in the MagDrone table")
    tu = units.get("Timestamp", "").strip()
    scale = _TIME_UNITS.get(tu.lower())
    if scale is None:
        raise InputError(
            f"{p}: column 'Timestamp' has {'unknown unit ' + repr(tu) if tu else 'no unit'} in"
            f" the header; expected one of {', '.join(_TIME_UNITS)} as in 'Timestamp [ms]'")
    t = _native_values(df.pop("Timestamp"), src, f"Timestamp [{tu}]", rows)
    t = t * scale[0] / scale[1]
    df.insert(0, "time", t)
    out_units = {"time": "s"}
    for axis in "xyz":
        col = f"B{sensor}{axis}"
        if col not in df.columns:
            raise InputError(f"{p}: MagDrone column {col!r} not found; columns: "
                             + ", ".join(map(str, df.columns)))
        unit = units.get(col, "").strip()
        factor = FIELD_UNITS_TO_NT.get(unit.lower())
        if factor is None:
            raise InputError(
                f"{p}: column {col!r} has {'unknown unit ' + repr(unit) if unit else 'no unit'}"
                f" in the header; expected a field unit such as nT, as in '{col} [nT]'")
        df[f"flux_{axis}"] = _native_values(df.pop(col), src, f"{col} [{unit}]", rows) * factor
        out_units[f"flux_{axis}"] = "nT"
    if "Latitude" in df.columns and "Longitude" in df.columns:
        lat = _native_values(df.pop("Latitude"), src, "Latitude", rows)
        lon = _native_values(df.pop("Longitude"), src, "Longitude", rows)
        q = (_native_values(df["Quality"], src, "Quality", rows)
             if "Quality" in df.columns else np.where((lat != 0) | (lon != 0), 1.0, 0.0))
        fix = q > 0
        df["lat"] = _interp_sparse(t, np.where(fix, lat, np.nan))
        df["lon"] = _interp_sparse(t, np.where(fix, lon, np.nan))
        if "Altitude" in df.columns:
            alt = _native_values(df.pop("Altitude"), src, "Altitude", rows)
            df["alt_msl"] = _interp_sparse(t, np.where(fix, alt, np.nan))
        out_units.update(lat="deg", lon="deg", alt_msl="m")
    df.attrs["metadata"] = meta
    df.attrs["units"] = {**units, **out_units}
    df.attrs[ROWS_ATTR] = rows
    return df


# --------------------------------------------------------------------------- writing
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
    f = (fmt or EXTENSIONS.get(p.suffix.lower(), "csv")).lower()
    if f == "csv":
        return write_csv(df, p)
    if f == "parquet":
        import pyarrow as pa
        import pyarrow.parquet as pq

        table = pa.Table.from_pandas(df, preserve_index=False)
        with atomic_path(p) as tmp:
            pq.write_table(table, tmp)
        return p
    if f == "xyz":
        return write_xyz(df, p)
    raise InputError(f"{p}: cannot write format {f!r}; use csv, parquet or xyz")


def write_xyz(df: pd.DataFrame, path: str | os.PathLike[str], *,
              title: str = "aeromag Geosoft XYZ export") -> Path:
    """Write a Geosoft XYZ file atomically.

    A ``/`` title line, a ``/`` line of channel names, then the rows.  When the table has a
    ``line`` (or ``line_label``) column, a line header starts every run of rows with the same
    line, and the ``line``/``line_type``/``line_label`` columns are not repeated on the rows:

    * ``line_label`` (as :func:`read_xyz` makes it), when it holds a valid header such as
      ``Tie 100`` or ``L1010.1``, is written as it is;
    * else ``line``: a number is written ``Line 10`` (``Tie``, ``Trend``, ... from
      ``line_type``), ``Line 1010.1`` for a non-integer number; a text id is written as it is
      when it is a Geosoft line name (``L10``, ``T100``, ``Line 10:16``) or a number;
    * rows without a line id at the start of the table are written before the first header
      (no line, as read back); later ones under ``Line *`` (read back as missing).

    Numbers are written in their shortest round-trip form, missing values as ``*``, booleans
    as ``true``/``false``, date-times in ISO 8601 (UTC, ``T`` separator): reading the file back
    gives every value exactly.  Text that XYZ cannot hold (blanks, empty, ``*``, a first
    column starting with ``/``) is an error naming its column and row.

    Parameters
    ----------
    df : DataFrame
        The table.
    path : path-like
        Destination.
    title : str
        Text of the first comment line.

    Returns
    -------
    Path
    """
    p = Path(path)
    line_cols = [c for c in ("line", "line_type", "line_label") if c in df.columns]
    if "line" not in df.columns and "line_label" not in df.columns:
        line_cols = []
    body = df.drop(columns=line_cols)
    names = [str(c) for c in body.columns]
    for c in names:
        if not c or any(ch.isspace() for ch in c):
            raise InputError(f"{p}: channel name {c!r} has blanks or is empty; XYZ names must"
                             " be single words")
    check_unique_names(names, str(p), what="table")
    body = _xyz_ready(body, p)
    text = body.to_csv(sep=" ", header=False, index=False, na_rep=_MISSING_XYZ,
                       lineterminator="\n")
    rows = text.split("\n")[:-1]
    del text
    _check_xyz_rows(body, rows, p)
    out: list[str] = [f"/ {title}", "/ " + " ".join(names)]
    if line_cols:
        for a, b, header in _xyz_line_runs(df, p):
            if header is not None:
                out.append(header)
            out.extend(rows[a:b])
    else:
        out.extend(rows)
    with atomic_path(p) as tmp:
        tmp.write_text("\n".join(out) + "\n", encoding="utf-8")
    return p


def _xyz_ready(body: pd.DataFrame, p: Path) -> pd.DataFrame:
    """Booleans as ``true``/``false``, date-times as ISO 8601; text XYZ cannot hold refused."""
    conv: dict[str, object] = {}
    for j, c in enumerate(body.columns):
        s = body[c]
        if pd.api.types.is_bool_dtype(s.dtype):
            conv[c] = np.where(s.to_numpy(dtype=bool, na_value=False), "true", "false")
            if s.isna().any():
                conv[c] = np.where(s.isna().to_numpy(), None, conv[c])
        elif pd.api.types.is_datetime64_any_dtype(s.dtype):
            utc = isinstance(s.dtype, pd.DatetimeTZDtype)
            v = (s.dt.tz_convert("UTC").dt.tz_localize(None) if utc else s).to_numpy()
            iso = np.datetime_as_string(v, unit=np.datetime_data(v.dtype)[0]).astype(object)
            if utc:
                iso = iso + "Z"
            iso[np.isnat(v)] = None
            conv[c] = iso
        elif pd.api.types.is_timedelta64_dtype(s.dtype):
            raise InputError(f"{p}: column {c!r} holds durations; XYZ has no such type: convert"
                             " it to seconds first")
        elif not pd.api.types.is_numeric_dtype(s.dtype):
            txt = s[s.notna()].astype(str)
            bad = txt.str.contains(r"\s", regex=True) | (txt == "") | (txt == _MISSING_XYZ)
            if j == 0:
                bad |= txt.str.startswith("/")
            if bad.any():
                where = int(np.flatnonzero(s.notna().to_numpy())[np.argmax(bad.to_numpy())])
                raise InputError(
                    f"{p}: column {c!r}, row {where + 1}: text {txt[bad].iloc[0]!r} cannot be"
                    " written to Geosoft XYZ (no blanks, not empty, not '*' which means"
                    " missing, not starting with '/' in the first column); change the value"
                    " or drop the column")
    if conv:
        body = body.assign(**{str(k): v for k, v in conv.items()})
    return body


def _check_xyz_rows(body: pd.DataFrame, rows: Sequence[str], p: Path) -> None:
    """A row of text that would read back as a line header (only possible with 1-2 channels
    and text in the first) is refused."""
    if not rows or body.shape[1] > 2 or pd.api.types.is_numeric_dtype(body.iloc[:, 0].dtype):
        return
    for i, r in enumerate(rows):
        if XYZ_LINE_HEADER.match(r):
            raise InputError(f"{p}: row {i + 1}: {r!r} would read back as a line header;"
                             " put a numeric channel first")


def _xyz_line_runs(df: pd.DataFrame, p: Path) -> list[tuple[int, int, str | None]]:
    """(first row, end row, header text or None) of every run of rows on the same line."""
    n = len(df)
    if n == 0:
        return []
    key_cols = [c for c in ("line", "line_type", "line_label") if c in df.columns]
    change = np.zeros(n, dtype=bool)
    change[0] = True
    for c in key_cols:
        s = df[c]
        prev = s.shift(1)
        diff = (s.ne(prev) & ~(s.isna() & prev.isna())).to_numpy(dtype=bool, na_value=True)
        change[1:] |= diff[1:]
    starts = np.flatnonzero(change)
    stops = np.r_[starts[1:], n]
    out = []
    for a, b in zip(starts.tolist(), stops.tolist(), strict=True):
        header = _xyz_header_of(df, a, p)
        if header is None and a > 0:
            header = "Line *"
        out.append((a, b, header))
    return out


def _xyz_header_of(df: pd.DataFrame, i: int, p: Path) -> str | None:
    """The line header of row ``i`` (None when it has no line id)."""
    if "line_label" in df.columns and not _missing(df["line_label"].iloc[i]):
        lab = " ".join(str(df["line_label"].iloc[i]).split())
        if XYZ_LINE_HEADER.match(lab):
            return lab
        if "line" not in df.columns:
            raise InputError(f"{p}: column 'line_label', row {i + 1}: {lab!r} is not a Geosoft"
                             " line header (e.g. 'Line 10', 'Tie 100', 'L1010.1')")
    if "line" not in df.columns or _missing(df["line"].iloc[i]):
        return None
    kind = df["line_type"].iloc[i] if "line_type" in df.columns else None
    kind = "line" if _missing(kind) else str(kind).strip().lower()
    if kind not in XYZ_LINE_TYPES:
        raise InputError(f"{p}: column 'line_type', row {i + 1}: {kind!r} is not a Geosoft line"
                         f" type; use one of {', '.join(XYZ_LINE_TYPES)}")
    word = kind.capitalize()
    v = df["line"].iloc[i]
    if isinstance(v, str):
        t = " ".join(v.split())
        if XYZ_LINE_HEADER.match(t):
            return t
    elif isinstance(v, int | np.integer):
        t = str(int(v))
    else:
        try:
            f = float(v)
        except (TypeError, ValueError):
            f = float("nan")
        t = (str(int(f)) if f.is_integer() else repr(f)) if np.isfinite(f) else str(v)
    if re.fullmatch(r"-?\d+(\.\d+)?(:\d+)?", t):
        return f"{word} {t}"
    raise InputError(f"{p}: column 'line', row {i + 1}: {v!r} is not a Geosoft line number or"
                     " line name (e.g. 10, 1010.1, L10, T100)")


def _missing(v: object) -> bool:
    """True for None, NaN, NaT, pd.NA."""
    try:
        return bool(pd.isna(v))
    except (TypeError, ValueError):
        return False
