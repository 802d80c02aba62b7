"""Reading and writing survey logs, column maps, units and atomic output.

A survey log is a :class:`pandas.DataFrame` with the canonical columns of
``shared/interface.md`` (``time`` [s], ``lat``/``lon`` [deg], ``alt`` [m], ``flux_x/y/z`` [nT],
``mag`` [nT], ``line``, ``heading``/``pitch``/``roll`` [deg], ``mag_heading`` [deg], ``leg``).
Logs named otherwise are read through a column map (``{"mag": "mag_1_uc"}``); units other than
nT are converted only when asked (``{"flux": "uT"}``), never guessed.

Every output file is written atomically: to a temporary file beside the target, then renamed,
so that a failure never leaves a half-written file behind.
"""

from __future__ import annotations

import bisect
import contextlib
import json
import logging
import math
import os
import re
import tempfile
import tomllib
import warnings
from collections.abc import Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .errors import InputError

log = logging.getLogger(__name__)

#: Canonical column names and their units.
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
}

#: Columns whose values must be numeric when present.
NUMERIC_COLUMNS: tuple[str, ...] = tuple(CANONICAL_COLUMNS)

FLUX_COLUMNS: tuple[str, str, str] = ("flux_x", "flux_y", "flux_z")

#: Factors that convert a magnetic field unit to nT.
FIELD_UNITS_TO_NT: dict[str, float] = {
    "pt": 1.0e-3,
    "nt": 1.0,
    "ut": 1.0e3,
    "\u00b5t": 1.0e3,  # micro sign (U+00B5)
    "\u03bct": 1.0e3,  # Greek small letter mu (U+03BC): both are written for microtesla
    "mt": 1.0e6,
    "g": 1.0e5,
    "gauss": 1.0e5,
    "mg": 1.0e2,
    "t": 1.0e9,
}

#: Unit groups: a key of ``units`` may name a group or a single column.
UNIT_GROUPS: dict[str, tuple[str, ...]] = {
    "flux": FLUX_COLUMNS,
    "mag": ("mag",),
}


# --------------------------------------------------------------------------- column maps
def parse_column_map(items: Iterable[str], *, option: str = "--col") -> dict[str, str]:
    """Parse ``NAME=SOURCE`` strings into a column map.

    Parameters
    ----------
    items : iterable of str
        Strings such as ``"mag=mag_1_uc"``; ``NAME`` is the canonical column, ``SOURCE`` the
        column name in the file.
    option : str
        Option name quoted in error messages.

    Returns
    -------
    dict
        ``{canonical_name: source_name}``.
    """
    out: dict[str, str] = {}
    for item in items:
        if "=" not in item:
            raise InputError(f"{option} {item!r}: expected NAME=VALUE, e.g. {option} mag=mag_1_uc")
        name, _, source = item.partition("=")
        name, source = name.strip(), source.strip()
        if not name or not source:
            raise InputError(f"{option} {item!r}: expected NAME=VALUE with both parts non-empty")
        out[name] = source
    return out


def read_map_file(path: str | os.PathLike[str]) -> tuple[dict[str, str], dict[str, str]]:
    """Read a TOML column-map file.

    The file holds a ``[columns]`` table (canonical name = source column) and an optional
    ``[units]`` table (column or group = unit), for example::

        [columns]
        mag = "mag_1_uc"
        flux_x = "flux_b_x"

        [units]
        flux = "uT"

    Parameters
    ----------
    path : path-like
        The TOML file.

    Returns
    -------
    columns, units : dict, dict
    """
    p = Path(path)
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"{p}: column-map file not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{p}: not a valid TOML column map ({exc})") from None
    cols = data.get("columns", {})
    units = data.get("units", {})
    if not isinstance(cols, dict) or not isinstance(units, dict):
        raise InputError(f"{p}: [columns] and [units] must be tables of NAME = \"VALUE\"")
    return {str(k): str(v) for k, v in cols.items()}, {str(k): str(v) for k, v in units.items()}


def unit_factor(unit: str, *, what: str = "--units") -> float:
    """Return the factor that converts a field unit to nT.

    Parameters
    ----------
    unit : str
        One of ``pT``, ``nT``, ``uT`` (``µT``, with either the micro sign U+00B5 or the
        Greek mu U+03BC), ``mT``, ``G`` (``gauss``), ``mG``, ``T`` (case-insensitive).
    what : str
        Context quoted in the error message.

    Returns
    -------
    float
        Multiply values in ``unit`` by this to get nT.
    """
    key = unit.strip().lower()
    if key not in FIELD_UNITS_TO_NT:
        known = ", ".join(["pT", "nT", "uT", "mT", "G", "mG", "T"])
        raise InputError(f"{what}: unknown field unit {unit!r}; use one of {known}")
    return FIELD_UNITS_TO_NT[key]


# --------------------------------------------------------------------------- atomic output
def _current_umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


_UMASK = _current_umask()


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success.

    On any exception the temporary file is removed and ``path`` is left untouched, so no
    partial output is ever left behind.

    Parameters
    ----------
    path : path-like
        Final destination.
    """
    target = Path(path)
    if target.parent and not target.parent.exists():
        target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    os.close(fd)
    tmp = Path(tmp_name)
    # mkstemp creates the file 0600; give the output the permissions a plain open() would.
    os.chmod(tmp, 0o666 & ~_UMASK)
    try:
        yield tmp
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise


def _csv_ready(df: pd.DataFrame) -> pd.DataFrame:
    """Return a frame whose boolean columns are spelled ``true``/``false``."""
    bool_cols = [c for c in df.columns if pd.api.types.is_bool_dtype(df[c].dtype)]
    if not bool_cols:
        return df
    out = df.copy(deep=False)
    for c in bool_cols:
        vals = df[c].to_numpy()
        out[c] = np.where(vals, "true", "false")
    return out


def write_csv(df: pd.DataFrame, path: str | os.PathLike[str]) -> Path:
    """Write a log to CSV atomically; booleans are written ``true``/``false``.

    Uses pyarrow's CSV writer when available, formatting slices of rows on several threads
    (numbers in their shortest round-trip form, missing values empty), pandas otherwise.
    The output is byte-identical whatever the number of threads.

    Parameters
    ----------
    df : DataFrame
        The table to write (index not written).
    path : path-like
        Destination CSV.

    Returns
    -------
    Path
        The written path.
    """
    target = Path(path)
    with atomic_path(target) as tmp:
        if not _write_csv_arrow(df, tmp):
            _csv_ready(df).to_csv(tmp, index=False, lineterminator="\n")
    return target


def _csv_header(columns: Iterable[Any]) -> str:
    """The header row, quoted only where a name needs it (as pandas writes it)."""
    import csv
    import io as _io

    buf = _io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow([str(c) for c in columns])
    return buf.getvalue()


def _floats_as_pandas_text(table: Any) -> Any:
    """Format float columns as pandas does: shortest round trip, integral values with ``.0``.

    Arrow writes ``1.0`` as ``1``; read back, a float column whose values are all integral
    would turn into integers.  Only such columns are rewritten (a column with any fractional
    value reads back as float anyway), which keeps the writer fast on measurement data: a
    column is ruled out by its first fractional value, usually within the first few rows.
    """
    import pyarrow as pa
    import pyarrow.compute as pc

    for i, f in enumerate(table.schema):
        if not pa.types.is_floating(f.type):
            continue
        if not _all_integral(table.column(i)):
            continue
        txt = pc.cast(table.column(i), pa.string())
        has_point = pc.match_substring_regex(txt, "[.eEnN]")
        txt = pc.if_else(has_point, txt, pc.binary_join_element_wise(txt, ".0", ""))
        table = table.set_column(i, f.name, txt)
    return table


def _all_integral(column: Any) -> bool:
    """True when every finite value of an Arrow float column is a whole number."""
    for chunk in column.chunks:
        vals = chunk.to_numpy(zero_copy_only=False)
        # Look at a small head first: measurement columns are ruled out at once.
        for part in (vals[:256], vals[256:]):
            fin = part[np.isfinite(part)]
            if fin.size and not np.all(fin == np.floor(fin)):
                return False
    return True


#: Rows formatted per task by the CSV writer (small slices keep each text buffer in cache).
WRITE_SLICE_ROWS = 8192


def _writer_threads() -> int:
    """Threads used to format CSV text (pyarrow's CPU count, so ``pa.set_cpu_count`` rules)."""
    import pyarrow as pa

    env = os.environ.get("AEROMAG_WRITE_THREADS")
    n = int(env) if env else pa.cpu_count()
    return max(1, min(n, 16))


def write_arrow_csv(table: Any, fh: Any, quoting: str = "none",
                    slice_rows: int = WRITE_SLICE_ROWS) -> None:
    """Write an Arrow table as CSV rows (no header) to a binary file, formatting in parallel.

    pyarrow's CSV writer formats on one thread.  The table is cut into slices of
    ``slice_rows`` rows (zero-copy), each formatted to text on a thread pool (pyarrow releases
    the GIL) and written in order, with at most two slices per thread in flight: the output is
    byte-identical to one ``pyarrow.csv.write_csv`` call and memory stays bounded.

    Parameters
    ----------
    table : pyarrow.Table
        The rows to write.
    fh : binary file
        Open destination.
    quoting : str
        pyarrow quoting style (``"none"`` raises ``ArrowInvalid`` on a value needing quotes).
    slice_rows : int
        Rows per formatting task.
    """
    import pyarrow as pa
    import pyarrow.csv as pacsv

    opts = pacsv.WriteOptions(include_header=False, quoting_style=quoting)
    n = table.num_rows
    threads = _writer_threads()
    if threads == 1 or n <= 2 * slice_rows:
        pacsv.write_csv(table, fh, opts)
        return

    def fmt(offset: int) -> Any:
        sink = pa.BufferOutputStream()
        pacsv.write_csv(table.slice(offset, slice_rows), sink, opts)
        return sink.getvalue()

    from collections import deque
    from concurrent.futures import ThreadPoolExecutor

    offsets = iter(range(0, n, slice_rows))
    with ThreadPoolExecutor(threads, thread_name_prefix="aeromag-csv") as pool:
        pending: deque = deque()
        for off in offsets:
            pending.append(pool.submit(fmt, off))
            if len(pending) >= 2 * threads:
                break
        while pending:
            fh.write(pending.popleft().result())
            nxt = next(offsets, None)
            if nxt is not None:
                pending.append(pool.submit(fmt, nxt))


#: Bytes of the input read per block when its lines are copied into the output.
PASSTHROUGH_BLOCK_BYTES = 2 << 20


def _line_blocks(fin: Any) -> Iterator[bytes]:
    """Blocks of whole lines (about :data:`PASSTHROUGH_BLOCK_BYTES` each) of a binary file; the
    last line gets a ``\\n`` when the file does not end with one."""
    carry = b""
    while True:
        block = fin.read(PASSTHROUGH_BLOCK_BYTES)
        if not block:
            if carry:
                yield carry if carry.endswith(b"\n") else carry + b"\n"
            return
        data = carry + block
        cut = data.rfind(b"\n")
        if cut < 0:
            carry = data
            continue
        yield data[: cut + 1]
        carry = data[cut + 1:]


def write_csv_passthrough(
    source: str | os.PathLike[str], source_columns: Sequence[str], extra: pd.DataFrame,
    dest: str | os.PathLike[str],
) -> bool:
    """Write ``source``'s lines verbatim with ``extra``'s columns appended to each.

    The columns a log came with are copied as the text they were read from (no reformatting,
    no precision lost), and only the added columns are formatted, in parallel: 4 columns
    formatted instead of 13 on a typical log, so about 3x less writing work.  The source is
    streamed block by block (memory bounded).  Used by the pipeline only for a plain CSV read
    without column map, unit conversion or dropped rows.

    Parameters
    ----------
    source : path-like
        The CSV the log was read from.
    source_columns : sequence of str
        Its column names as read (the header must be exactly these, comma-separated).
    extra : DataFrame
        Columns to append, one row per data line of ``source``.
    dest : path-like
        Output file (written from scratch; on False its content is undefined and the caller
        writes it another way).

    Returns
    -------
    bool
        False (and nothing promised) when the source is not plain enough: quotes, blank lines,
        mixed line endings, a different header or row count.
    """
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.csv as pacsv

    try:
        table = _floats_as_pandas_text(pa.Table.from_pandas(extra, preserve_index=False))
    except (pa.ArrowException, TypeError, ValueError):
        return False
    if any(pa.types.is_temporal(f.type) or pa.types.is_nested(f.type) for f in table.schema):
        return False
    n = table.num_rows
    opts = pacsv.WriteOptions(include_header=False, quoting_style="none")

    def join(lines: bytes, row: int, k: int) -> Any:
        """One block: its k source lines, each followed by its row of ``table``."""
        raw = np.frombuffer(lines, dtype=np.uint8)
        nl = np.flatnonzero(raw == 10)
        starts = np.r_[0, nl[:-1] + 1]
        cr = raw[np.maximum(nl - 1, 0)] == 13
        if cr.any() and not cr.all():
            return None
        drop = 2 if cr.all() else 1
        if np.any(nl - starts < drop + 1):  # a blank line: the readers skip those
            return None
        src_lines = pa.Array.from_buffers(
            pa.binary(), k, [None, pa.py_buffer(np.r_[0, nl + 1].astype(np.int32)),
                             pa.py_buffer(lines)])
        sink = pa.BufferOutputStream()
        try:
            pacsv.write_csv(table.slice(row, k), sink, opts)
        except pa.ArrowInvalid:  # text that needs quoting
            return None
        ext = sink.getvalue()
        enl = np.flatnonzero(np.frombuffer(ext, dtype=np.uint8) == 10)
        if len(enl) != k:
            return None
        ext_lines = pa.Array.from_buffers(
            pa.binary(), k, [None, pa.py_buffer(np.r_[0, enl + 1].astype(np.int32)), ext])
        joined = pc.binary_join_element_wise(pc.binary_slice(src_lines, 0, -drop), ext_lines,
                                             b",")
        off = np.frombuffer(joined.buffers()[1], dtype=np.int32, count=k + 1,
                            offset=4 * joined.offset)
        return memoryview(joined.buffers()[2])[off[0]:off[-1]]

    from collections import deque
    from concurrent.futures import ThreadPoolExecutor

    threads = _writer_threads()
    row = 0
    with open(source, "rb") as fin, open(dest, "wb") as fout, \
            ThreadPoolExecutor(threads, thread_name_prefix="aeromag-csv") as pool:
        header = fin.readline()
        head = header.rstrip(b"\r\n")
        try:
            names = head.decode("utf-8").split(",")
        except UnicodeDecodeError:
            return False
        if names != list(source_columns) or b'"' in head:
            return False
        fout.write(head + b"," + _csv_header(extra.columns).encode("utf-8"))
        pending: deque = deque()
        # Blocks are joined on the pool, written here in order, at most 2 per thread ahead.
        for lines in _line_blocks(fin):
            k = lines.count(b"\n")
            if b'"' in lines or row + k > n:
                return False
            pending.append(pool.submit(join, lines, row, k))
            row += k
            while len(pending) > 2 * threads:
                out = pending.popleft().result()
                if out is None:
                    return False
                fout.write(out)
        while pending:
            out = pending.popleft().result()
            if out is None:
                return False
            fout.write(out)
    return row == n


def _write_csv_arrow(df: pd.DataFrame, dest: Path) -> bool:
    """Write ``df`` with pyarrow; return False (nothing written) when pyarrow cannot."""
    try:
        import pyarrow as pa
    except ImportError:  # pragma: no cover - pyarrow is optional
        return False
    try:
        table = pa.Table.from_pandas(df, preserve_index=False)
    except (pa.ArrowException, TypeError, ValueError):
        return False
    if any(pa.types.is_temporal(f.type) or pa.types.is_nested(f.type) for f in table.schema):
        return False
    table = _floats_as_pandas_text(table)
    header = _csv_header(df.columns).encode("utf-8")
    with open(dest, "wb") as fh:
        fh.write(header)
        try:
            write_arrow_csv(table, fh, "none")
        except pa.ArrowInvalid:  # a string needs quoting
            fh.seek(len(header))
            fh.truncate()
            write_arrow_csv(table, fh, "needed")
    return True


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return _clean_float(float(obj))
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def _clean_float(x: float) -> float | None:
    return None if (math.isnan(x) or math.isinf(x)) else x


def _jsonable(obj: Any) -> Any:
    """Replace NaN/inf by None recursively (JSON has no NaN)."""
    if isinstance(obj, float):
        return _clean_float(obj)
    if isinstance(obj, np.floating):
        return _clean_float(float(obj))
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    return obj


def write_json(obj: Any, path: str | os.PathLike[str]) -> Path:
    """Write a JSON document atomically (NaN and inf written as ``null``).

    Parameters
    ----------
    obj : object
        JSON-serialisable data (numpy scalars and arrays are converted).
    path : path-like
        Destination file.

    Returns
    -------
    Path
        The written path.
    """
    target = Path(path)
    text = json.dumps(_jsonable(obj), indent=2, default=_json_default, allow_nan=False)
    with atomic_path(target) as tmp:
        tmp.write_text(text + "\n", encoding="utf-8")
    return target


def json_path_for(csv_path: str | os.PathLike[str]) -> Path:
    """Return ``OUT.json`` for ``OUT.csv`` (the report path of an output log)."""
    return Path(csv_path).with_suffix(".json")


# --------------------------------------------------------------------------- row locations
#: ``df.attrs`` key where a reader notes where its data rows are in the file, so that an error
#: can name the file line (see :func:`row_location`); :func:`read_log` removes it.
ROWS_ATTR = "_rows"


def rows_after_header(path: str | os.PathLike[str], header_line: int) -> dict[str, Any]:
    """Row locations of a delimited table: the data rows are the non-blank lines after the
    header on line ``header_line`` (1-based), as the CSV readers skip blank lines."""
    return {"kind": "lines", "path": os.fspath(path), "header_line": int(header_line)}


def rows_in_runs(row_starts: Sequence[int], line_starts: Sequence[int]) -> dict[str, Any]:
    """Row locations as runs of consecutive lines: data row ``row_starts[k] + j`` is on file
    line ``line_starts[k] + j`` (both sorted, 0-based rows, 1-based lines)."""
    return {"kind": "runs", "rows": [int(r) for r in row_starts],
            "lines": [int(x) for x in line_starts]}


def rows_numbered(unit: str) -> dict[str, Any]:
    """Row locations of a format without text lines: ``"row"`` (Parquet) or ``"sample"`` (HDF5)."""
    return {"kind": "index", "unit": unit}


def row_location(rows: Mapping[str, Any] | None, i: int) -> str:
    """Say where data row ``i`` (0-based) of a table is, for an error message.

    Parameters
    ----------
    rows : mapping or None
        A row description from :func:`rows_after_header`, :func:`rows_in_runs` or
        :func:`rows_numbered`.
    i : int
        0-based data row.

    Returns
    -------
    str
        ``"line 17"`` (1-based line of the file), ``"sample 5 (index 4)"``, or ``"data row 5"``
        when the file line cannot be told.
    """
    kind = rows.get("kind") if rows else None
    if kind == "runs" and rows is not None:
        k = bisect.bisect_right(rows["rows"], i) - 1
        if k >= 0:
            return f"line {rows['lines'][k] + i - rows['rows'][k]}"
    elif kind == "lines" and rows is not None:
        ln = _nth_data_line(rows["path"], rows["header_line"], i)
        if ln is not None:
            return f"line {ln}"
    elif kind == "index" and rows is not None:
        return f"{rows['unit']} {i + 1} (index {i})"
    return f"data row {i + 1}"


def _text_lines(path: str | os.PathLike[str]) -> Iterator[tuple[int, str]]:
    """(1-based number, text) of the lines of a file, ending at ``\\n``, ``\\r\\n`` or a lone
    ``\\r`` as the CSV readers count them; the bytes are kept (latin-1), decode them yourself."""
    with open(path, encoding="latin-1", newline=None) as fh:
        yield from enumerate(fh, start=1)


def _nth_data_line(path: str, header_line: int, i: int) -> int | None:
    """1-based line of the ``i``-th non-blank line after line ``header_line``, or None.

    Reads the file up to that line; only called to word an error.
    """
    try:
        k = -1
        for ln, text in _text_lines(path):
            if ln <= header_line or not text.strip():
                continue
            k += 1
            if k == i:
                return ln
    except OSError:
        return None
    return None


def plain_number(x: Any) -> str:
    """A number as plain text for messages: ``0.1``, ``1601300273.001`` (not ``np.float64(..)``)."""
    try:
        v = float(x)
    except (TypeError, ValueError):
        return repr(x)
    return str(int(v)) if v.is_integer() and abs(v) < 1e15 else repr(v)


def numeric_values(s: pd.Series, source: str, column: str, rows: Mapping[str, Any] | None,
                   remedy: str = "fix the value or map another column with --col") -> np.ndarray:
    """float64 values of a column; empty cells are NaN, any other unparseable cell an error.

    Parameters
    ----------
    s : Series
        The column as read.
    source : str
        File name quoted in the error.
    column : str
        Column name quoted in the error (as the file spells it).
    rows : mapping or None
        Where the rows are in the file (see :func:`row_location`).
    remedy : str
        What to do, ending the message.

    Returns
    -------
    ndarray of float64
    """
    if pd.api.types.is_numeric_dtype(s.dtype) and not pd.api.types.is_bool_dtype(s.dtype):
        return s.to_numpy(dtype=np.float64, na_value=np.nan)
    conv = pd.to_numeric(s, errors="coerce")
    bad = (conv.isna() & s.notna()).to_numpy()
    if bad.any():
        bad = bad & (s.astype(str).str.strip() != "").to_numpy()
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(
            f"{source}: column {column!r}, {row_location(rows, i)}: value {str(s.iloc[i])!r}"
            f" is not a number; {remedy}"
        )
    return conv.to_numpy(dtype=np.float64, na_value=np.nan)


# --------------------------------------------------------------------------- reading
#: Name given to the field after the last header column while reading (a trailing delimiter).
_EXTRA_FIELD = "\x00extra"
#: Prefix of the names given to header cells that are empty.
_UNNAMED_FIELD = "\x00unnamed"


def _read_table(path: Path, fmt: str | None) -> pd.DataFrame:
    """Read a raw table from ``path`` (CSV by default; other formats via ``formats``)."""
    fmt = (fmt or "").lower() or None
    suffix = path.suffix.lower()
    if fmt not in (None, "csv") or suffix not in (".csv", ".txt", ""):
        # Other formats live in their own module; imported lazily so CSV needs nothing more.
        from . import formats

        return formats.read_table_rows(path, fmt)
    if fmt is None and path.is_file():
        from . import formats

        if formats.sniff_csv(path) is not None:  # a MagArrow / MagDrone native log
            return formats.read_table_rows(path, None)
    return _read_csv(path)


def _csv_header_fields(path: Path) -> tuple[list[str], int] | None:
    """The header of a CSV as the readers split it, and its 1-based line number.

    Quotes are honoured and blanks around names removed; leading blank lines are skipped (as
    the readers skip them).  Only the first line(s) are read.

    Returns
    -------
    (names, line) or None
        None when the header cannot be decoded (the readers then word the error).
    """
    return _first_fields(path, 0)


def _first_data_fields(path: Path, header_line: int) -> tuple[list[str], int] | None:
    """Fields of the first non-blank line after the header, and its 1-based line number."""
    return _first_fields(path, header_line)


def _first_fields(path: Path, after: int) -> tuple[list[str], int] | None:
    """CSV fields of the first non-blank line after line ``after`` (None: none or undecodable)."""
    import csv

    try:
        for ln, text in _text_lines(path):
            if ln > after + 1000:
                return None
            if ln <= after or not text.strip():
                continue
            line = text.encode("latin-1").decode("utf-8").removeprefix("\ufeff")
            fields = next(csv.reader([line.rstrip("\n")], skipinitialspace=True))
            return ([c.strip() for c in fields] if after == 0 else fields), ln
    except (OSError, UnicodeDecodeError, csv.Error, StopIteration):
        return None
    return None


def check_unique_names(names: Sequence[str], source: str, *, what: str = "header") -> None:
    """Raise :class:`InputError` naming the first column name that appears twice.

    Parameters
    ----------
    names : sequence of str
        Column names in file order (empty names are not checked).
    source : str
        File name quoted in the error.
    what : str
        Where the names come from, for the message.
    """
    seen: dict[str, int] = {}
    for j, name in enumerate(names):
        if not name:
            continue
        if name in seen:
            raise InputError(
                f"{source}: column {name!r} appears twice in the {what} (columns {seen[name] + 1}"
                f" and {j + 1}); rename one of them (e.g. {name}_2) so that each column has its"
                " own name, then pick one with --col if needed")
        seen[name] = j


def _read_csv(path: Path, spare_fields: int = 1) -> pd.DataFrame:
    """Read a CSV table (pyarrow's multi-threaded reader when available, else pandas).

    The header is checked first (a name used twice is an error).  A row may end with up to
    ``spare_fields`` empty fields more than the header (loggers that end every row with the
    delimiter): they are dropped; a value there is an error naming the line.  An empty header
    cell is accepted only for an empty column.  Both readers give the same table.
    """
    if path.is_dir():
        raise InputError(f"{path}: is a folder, not a log file")
    if not path.exists():
        raise InputError(f"{path}: file not found")
    head = _csv_header_fields(path)
    names, header_line = head if head is not None else (None, 1)
    if names is not None:
        check_unique_names(names, str(path))
    df = None
    plain = False
    if names is None or all(names):
        df = _read_csv_arrow(path)
        plain = df is not None  # pyarrow checked that every row has the header's field count
    if df is None:
        df, plain = _read_csv_other(path, names, header_line, spare_fields)
    raw_names = [str(c) for c in df.columns]
    df.columns = [c.strip() for c in raw_names]
    if plain and raw_names == list(df.columns):
        df.attrs["_plain_csv_columns"] = raw_names
    df.attrs[ROWS_ATTR] = rows_after_header(path, header_line)
    return df


def _read_csv_other(path: Path, names: list[str] | None, header_line: int,
                    spare_fields: int = 1) -> tuple[pd.DataFrame, bool]:
    """Read a CSV that pyarrow's plain read could not take; returns (table, plain).

    Rows never shift: the table is read with ``spare_fields`` more columns than the header
    (never with leading columns taken as the index).  A row may end with up to that many empty
    fields more than the header (loggers that end every row with the delimiter): they are
    dropped.  A row whose extra field holds a value, or with still more fields, is an error
    naming its line.  An empty header cell is accepted for an empty column only.  ``plain``
    is True when every row has exactly the header's field count (checked on the bytes,
    vectorised), so that an output may copy the lines.
    """
    if names is None:
        return _read_csv_pandas(path, None, 0, header_line), False
    n = len(names)
    cols = [name if name else f"{_UNNAMED_FIELD}{j}" for j, name in enumerate(names)]
    cols += [f"{_EXTRA_FIELD}{k}" for k in range(spare_fields)]
    first = _first_data_fields(path, header_line)
    if first is not None and len(first[0]) > len(cols):
        # (pandas would take this row's length as the table's and cut the fields beyond cols)
        raise InputError(
            f"{path}: line {first[1]}: {len(first[0])} fields but the header names {n} columns;"
            " fix that row (or the header, or check the delimiter)")
    df = None
    if header_line == 1 and (not all(names) or (first is not None
                                                 and len(first[0]) == len(cols))):
        df = _read_csv_arrow(path, cols)  # every row as long: pyarrow can read it
    if df is None:
        df = _read_csv_pandas(path, cols, n, header_line)
    rows = rows_after_header(path, header_line)
    spare = [c for c in df.columns if str(c).startswith("\x00")]
    for c in spare:
        filled = _filled(df[c])
        if not filled.any():
            continue
        i = int(np.flatnonzero(filled)[0])
        where, value = row_location(rows, i), str(df[c].iloc[i]).strip()
        if str(c).startswith(_EXTRA_FIELD):
            raise InputError(
                f"{path}: {where}: more fields than the {n} columns of the header (value"
                f" {value!r} has no column); remove the extra value or add its name to the"
                " header")
        j = int(str(c)[len(_UNNAMED_FIELD):])
        raise InputError(
            f"{path}: column {j + 1} has no name in the header but holds values ({where}:"
            f" {value!r}); give it a name in the header")
    df = df.drop(columns=spare)
    plain = header_line == 1 and all(names) and _rows_have_fields(path, n)
    return df, plain


def _filled(s: pd.Series) -> np.ndarray:
    """Cells that hold something (not missing, not only blanks)."""
    filled = s.notna().to_numpy()
    if filled.any() and not pd.api.types.is_numeric_dtype(s.dtype):
        filled = filled & (s.astype(str).str.strip() != "").to_numpy()
    return filled


def _read_csv_pandas(path: Path, cols: list[str] | None, n_header: int = 0,
                     header_line: int = 1) -> pd.DataFrame:
    """pandas' reader (text columns, quoting, ragged rows); errors worded for the user.

    With ``cols`` the header line is skipped and the rows are read into exactly these columns
    (shorter rows padded with missing values, longer ones an error naming the line).
    """
    # index_col=False: pandas never turns leading columns into the index (which would shift
    # every column when the rows have more fields than the header).
    kw: dict[str, Any] = {"index_col": False}
    if cols is not None:
        kw.update(header=None, skiprows=header_line, names=cols)
    try:
        with warnings.catch_warnings():
            # "Length of header or names does not match length of data": fields were cut.
            warnings.simplefilter("error", pd.errors.ParserWarning)
            return pd.read_csv(path, skipinitialspace=True, low_memory=False, **kw)
    except pd.errors.ParserWarning:
        raise InputError(f"{path}: the rows have more fields than the header names columns;"
                         " fix the header or the rows (or check the delimiter)") from None
    except FileNotFoundError:
        raise InputError(f"{path}: file not found") from None
    except pd.errors.EmptyDataError:
        if cols is not None:  # a header and no data row
            return pd.DataFrame({c: pd.Series(dtype=np.float64) for c in cols})
        raise InputError(
            f"{path}: the file is empty; expected a CSV log with a header row") from None
    except (pd.errors.ParserError, UnicodeDecodeError) as exc:
        msg = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
        m = re.search(r"Expected \d+ fields in line (\d+), saw (\d+)", msg)
        if m and n_header:
            raise InputError(
                f"{path}: line {m.group(1)}: {m.group(2)} fields but the header names"
                f" {n_header} columns; fix that row (or check the delimiter)") from None
        raise InputError(
            f"{path}: cannot parse as CSV ({msg}); check the delimiter and quoting") from None


def _rows_have_fields(path: Path, n_fields: int) -> bool:
    """True when every line after the header has exactly ``n_fields`` comma-separated fields,
    with no quote and no blank line (block by block, vectorised)."""
    want = n_fields - 1
    try:
        with open(path, "rb") as fh:
            fh.readline()
            for lines in _line_blocks(fh):
                raw = np.frombuffer(lines, dtype=np.uint8)
                if (raw == 34).any():
                    return False
                nl = np.flatnonzero(raw == 10)
                starts = np.r_[0, nl[:-1] + 1]
                cr = raw[np.maximum(nl - 1, 0)] == 13
                if np.any(nl - starts <= cr):  # a blank line
                    return False
                commas = np.flatnonzero(raw == 44)
                per_line = np.diff(np.r_[0, np.searchsorted(commas, nl)])
                if np.any(per_line != want):
                    return False
    except OSError:
        return False
    return True


def _read_csv_streaming(path: Path) -> Any:
    """The prefetched table of this file (see :mod:`aeromag.warm`), else a streamed read."""
    from . import warm

    table = warm.take_prefetched(path)
    return table if table is not None else warm.read_csv_table(path)


def _read_csv_arrow(path: Path, names: list[str] | None = None) -> pd.DataFrame | None:
    """Read with pyarrow; None when pyarrow is missing or the table needs pandas' rules.

    ``names`` replaces the header row (read with exactly these columns, header skipped).
    """
    try:
        import pyarrow as pa
        import pyarrow.csv as pacsv
    except ImportError:  # pragma: no cover - pyarrow is optional
        return None
    if not path.exists():
        raise InputError(f"{path}: file not found")
    if path.stat().st_size == 0:
        raise InputError(f"{path}: the file is empty; expected a CSV log with a header row")
    if names is not None:
        try:
            table = pacsv.read_csv(path, read_options=pacsv.ReadOptions(column_names=names,
                                                                        skip_rows=1))
        except (pa.ArrowInvalid, OSError):
            return None
        return _arrow_numeric_frame(table)
    table = _read_csv_streaming(path)
    if isinstance(table, dict):  # numpy columns of a large all-numeric log
        return pd.DataFrame(table, copy=False)
    try:
        if table is None:
            table = pacsv.read_csv(path)
    except pa.ArrowInvalid as exc:
        text = str(exc).strip()
        if "Empty CSV file" in text:
            raise InputError(
                f"{path}: the file is empty; expected a CSV log with a header row") from None
        # Ragged rows, bad quoting, invalid UTF-8: let pandas decide and word the error.
        return None
    return _arrow_numeric_frame(table)


def _arrow_numeric_frame(table: Any) -> pd.DataFrame | None:
    """An all-numeric Arrow table as a DataFrame; None when a column holds text or dates."""
    import pyarrow as pa

    if any(not (pa.types.is_floating(f.type) or pa.types.is_integer(f.type)
                or pa.types.is_boolean(f.type) or pa.types.is_null(f.type))
           for f in table.schema):
        # Text or dates somewhere: pandas' type inference (skipinitialspace, no date parsing)
        # keeps the exact behaviour for those columns.
        return None
    nulls = [i for i, f in enumerate(table.schema) if pa.types.is_null(f.type)]
    for i in nulls:  # an all-empty column is float NaN, as pandas reads it
        table = table.set_column(i, table.schema[i].name,
                                 table.column(i).cast(pa.float64()))
    # Column by column, freeing each Arrow column once converted; then hand the parser's
    # buffers back to the system (at 1e6 rows the process keeps ~100 MB, not ~360 MB).
    df = table.to_pandas(split_blocks=True, self_destruct=True)
    del table
    pa.default_memory_pool().release_unused()
    return df


def apply_column_map(
    df: pd.DataFrame, columns: Mapping[str, str] | None, *, source: str = "<log>"
) -> pd.DataFrame:
    """Rename source columns to canonical names.

    Parameters
    ----------
    df : DataFrame
        Raw table.
    columns : mapping or None
        ``{canonical_name: source_name}``.
    source : str
        File name quoted in errors.

    Returns
    -------
    DataFrame
        The table with mapped columns renamed (unmapped columns kept as they are).
    """
    if not columns:
        return df
    rename: dict[str, str] = {}
    for name, src in columns.items():
        if src not in df.columns:
            avail = ", ".join(map(str, df.columns[:20]))
            raise InputError(
                f"{source}: column {src!r} (mapped to {name!r}) not found; columns are: {avail}"
            )
        rename[src] = name
    # A canonical name that is also an existing, unmapped column would collide: drop the old one.
    clash = [name for src, name in rename.items() if name in df.columns and name != src]
    out = df.drop(columns=[c for c in clash if c not in rename])
    return out.rename(columns=rename)


def _to_numeric(df: pd.DataFrame, cols: Sequence[str], source: str,
                rows: Mapping[str, Any] | None = None) -> pd.DataFrame:
    """Convert ``cols`` to float, naming the first unparseable cell (and its line) in the error.

    A ``time`` column of date-times (ISO 8601 text, or datetime / duration values from Parquet)
    becomes float seconds since 1970-01-01 UTC (see :func:`datetime_seconds`).
    """
    for c in cols:
        s = df[c]
        if isinstance(s, pd.DataFrame):  # a name used twice
            raise InputError(f"{source}: column {c!r} appears more than once; rename the copies"
                             " so that each column has its own name")
        if c == "time" and _is_datetime_like(s):
            df[c] = datetime_seconds(s, source, rows)
            df.attrs["_time_converted"] = True
            continue
        if pd.api.types.is_numeric_dtype(s.dtype) and not pd.api.types.is_bool_dtype(s.dtype):
            if s.dtype != np.float64 and c not in ("line", "leg"):
                df[c] = s.astype(np.float64)
            continue
        df[c] = numeric_values(s, source, c, rows)
    return df


#: ISO 8601 date and time at the start of a text value (``2024-01-01T00:00:00``, with a space too).
_ISO_DATETIME = re.compile(r"^\s*[+-]?\d{4}-\d{2}-\d{2}[T ]\d{2}:\d{2}")


def _is_datetime_like(s: pd.Series) -> bool:
    """A datetime / duration column, or text whose first value is an ISO 8601 date-time."""
    if pd.api.types.is_datetime64_any_dtype(s.dtype) or pd.api.types.is_timedelta64_dtype(
            s.dtype):
        return True
    if pd.api.types.is_numeric_dtype(s.dtype) or pd.api.types.is_bool_dtype(s.dtype):
        return False
    first = s.first_valid_index()
    return first is not None and isinstance(s.loc[first], str) and bool(
        _ISO_DATETIME.match(s.loc[first]))


#: Ticks per second of the datetime64 / timedelta64 units.
_TICKS_PER_S = {"s": 1, "ms": 10**3, "us": 10**6, "ns": 10**9}


def datetime_seconds(s: pd.Series, source: str = "<log>",
                     rows: Mapping[str, Any] | None = None) -> np.ndarray:
    """Date-times as float seconds since 1970-01-01 UTC; durations as float seconds.

    Accepts datetime64 of any resolution (s, ms, us, ns), time-zone aware (converted to UTC)
    or naive (taken as UTC), timedelta64, and ISO 8601 text (``2024-01-01T00:00:00.1``, with
    an optional ``Z`` or ``+02:00`` offset; naive text is taken as UTC).  The whole seconds and
    the fraction are converted separately, so nothing below the stored resolution is lost
    before the float cast (float64 keeps about 0.2 us at today's epoch seconds).  Missing
    values become NaN; a text value that is not a date-time is an error naming its line.

    Parameters
    ----------
    s : Series
        The column.
    source : str
        File name quoted in errors.
    rows : mapping, optional
        Where the rows are in the file (see :func:`row_location`).

    Returns
    -------
    ndarray of float64
        Seconds.
    """
    if pd.api.types.is_timedelta64_dtype(s.dtype):
        arr = s.to_numpy()
    else:
        if not pd.api.types.is_datetime64_any_dtype(s.dtype):
            parsed = pd.to_datetime(s, format="ISO8601", utc=True, errors="coerce")
            bad = parsed.isna().to_numpy() & _filled(s)
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                raise InputError(
                    f"{source}: column 'time', {row_location(rows, i)}: value"
                    f" {str(s.iloc[i])!r} is not an ISO 8601 date-time like the rows before it;"
                    " fix the value")
            s = parsed
        if isinstance(s.dtype, pd.DatetimeTZDtype):
            s = s.dt.tz_convert("UTC").dt.tz_localize(None)
        arr = s.to_numpy()
    unit, count = np.datetime_data(arr.dtype)
    if unit not in _TICKS_PER_S or count != 1:
        kind = "m8" if arr.dtype.kind == "m" else "M8"
        arr, unit = arr.astype(f"{kind}[ns]"), "ns"
    per = _TICKS_PER_S[unit]
    ticks = arr.view(np.int64)
    out = (ticks // per).astype(np.float64) + (ticks % per) / per
    out[np.isnat(arr)] = np.nan
    log.info("%s: column 'time' holds %s: converted to seconds%s", source,
             "durations" if arr.dtype.kind == "m" else "date-times",
             "" if arr.dtype.kind == "m" else " since 1970-01-01 UTC")
    return out


def convert_units(
    df: pd.DataFrame, units: Mapping[str, str] | None, *, source: str = "<log>"
) -> pd.DataFrame:
    """Convert field columns to nT as requested (never guessed).

    Parameters
    ----------
    df : DataFrame
        Log with canonical names.
    units : mapping or None
        ``{column_or_group: unit}``; groups are ``flux`` (the three fluxgate axes) and ``mag``.
    source : str
        File name quoted in errors.

    Returns
    -------
    DataFrame
        The same frame, converted in place.
    """
    if not units:
        return df
    for key, unit in units.items():
        factor = unit_factor(unit, what=f"{source}: --units {key}={unit}")
        cols = UNIT_GROUPS.get(key, (key,))
        present = [c for c in cols if c in df.columns]
        if not present:
            raise InputError(f"{source}: --units {key}={unit}: no column {key!r} in the log")
        for c in present:
            if CANONICAL_COLUMNS.get(c, "nT") != "nT":
                raise InputError(f"{source}: --units {key}: column {c!r} is not a field in nT")
            df[c] = df[c].astype(np.float64) * factor
    return df


def read_log(
    path: str | os.PathLike[str],
    *,
    columns: Mapping[str, str] | None = None,
    units: Mapping[str, str] | None = None,
    required: Sequence[str] = ("time",),
    fmt: str | None = None,
    min_rows: int = 2,
) -> pd.DataFrame:
    """Read a survey log into canonical columns and validate it.

    Steps: read the table (CSV by default; a column name used twice is an error), rename
    through ``columns``, check that the ``required`` columns exist, convert canonical columns
    to numbers (an unparseable cell is an error naming its column and its line in the file, or
    its row / sample for Parquet / HDF5; a ``time`` of ISO 8601 or datetime values becomes
    seconds since 1970-01-01 UTC), convert units when asked, drop exact duplicate rows and
    check that ``time`` is strictly increasing.  All other rows and columns are kept.

    Parameters
    ----------
    path : path-like
        The log file.
    columns : mapping, optional
        Column map ``{canonical_name: source_name}``.
    units : mapping, optional
        Unit conversions ``{column_or_group: unit}`` (``flux`` or ``mag`` groups, or a column).
    required : sequence of str
        Canonical columns that must be present.
    fmt : str, optional
        Format name; inferred from the extension when omitted.
    min_rows : int
        Fewest data rows accepted.

    Returns
    -------
    DataFrame
        The log; ``df.attrs["source"]`` holds the path.
    """
    p = Path(path)
    source = str(p)
    if not p.exists():
        raise InputError(f"{source}: file not found")
    df = _read_table(p, fmt)
    rows = df.attrs.pop(ROWS_ATTR, None)
    check_unique_names([str(c) for c in df.columns], source, what="table")
    df = apply_column_map(df, columns, source=source)
    missing = [c for c in required if c not in df.columns]
    if missing:
        avail = ", ".join(map(str, df.columns[:20]))
        raise InputError(
            f"{source}: missing column(s) {', '.join(missing)}; columns are: {avail};"
            " map them with --col NAME=SOURCE"
        )
    if len(df) < min_rows:
        raise InputError(f"{source}: only {len(df)} data row(s); need at least {min_rows}")
    present = [c for c in NUMERIC_COLUMNS if c in df.columns]
    df = _to_numeric(df, present, source, rows)
    df = convert_units(df, units, source=source)
    n_read = len(df)
    plain = df.attrs.pop("_plain_csv_columns", None)
    if df.attrs.pop("_time_converted", False):
        plain = None  # the time column is no longer the file's text
    if "time" in df.columns:
        df = _clean_time(df, source, rows)
    if len(df) < min_rows:
        raise InputError(f"{source}: only {len(df)} usable row(s); need at least {min_rows}")
    df.attrs.pop("_plain_csv_columns", None)
    df.attrs["source"] = source
    if plain is not None and not columns and not units and len(df) == n_read:
        # Every row and column is exactly as in the file: outputs may copy its lines.
        df.attrs["passthrough_csv"] = {"path": source, "columns": plain}
    return df


def _clean_time(df: pd.DataFrame, source: str,
                rows: Mapping[str, Any] | None = None) -> pd.DataFrame:
    """Drop exact duplicate rows; require a finite, strictly increasing ``time``."""
    t = df["time"].to_numpy(dtype=np.float64)
    bad = ~np.isfinite(t)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"{source}: column 'time', {row_location(rows, i)}: empty or"
                         " non-finite time; fix or remove the row")
    dup = np.zeros(len(df), dtype=bool)
    same_t = np.r_[False, t[1:] == t[:-1]]
    if same_t.any():
        # Only rows identical to their predecessor in every column are dropped.
        prev = df.shift(1)
        eq = (df.eq(prev) | (df.isna() & prev.isna())).all(axis=1).to_numpy()
        dup = same_t & eq
        if dup.any():
            log.warning("%s: dropped %d exact duplicate row(s)", source, int(dup.sum()))
            df = df.loc[~dup].reset_index(drop=True)
            t = t[~dup]
    dt = np.diff(t)
    if (dt <= 0).any():
        i = int(np.flatnonzero(dt <= 0)[0]) + 1
        # Report the line in the original file.
        orig = int(np.flatnonzero(~dup)[i]) if dup.any() else i
        raise InputError(
            f"{source}: column 'time', {row_location(rows, orig)}: time {plain_number(t[i])} is"
            f" not after {plain_number(t[i - 1])}; time must be strictly increasing (sort the log"
            " or fix the row)"
        )
    return df
