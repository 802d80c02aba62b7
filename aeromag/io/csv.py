"""The one CSV reader of aeromag (the writer is :mod:`aeromag.io.csv_write`).

The reader (:func:`read_csv_table`) checks the header, takes pyarrow's multi-threaded parser
when the table is all-numeric and falls back to pandas for text, quoting and ragged rows; both
give the same table.  The writer (:func:`write_csv`) formats numbers in their shortest
round-trip form, booleans ``true``/``false``, atomically.
"""

from __future__ import annotations

import logging
import re
import warnings
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..errors import InputError
from .columns import ColumnNames, check_unique_names, filled_cells
from .messages import clean
from .rows import ROWS_ATTR, row_location, rows_after_header, text_lines

log = logging.getLogger(__name__)

# --------------------------------------------------------------------------- reading
#: Bytes of the head of a file checked for binary data (NUL bytes).
TEXT_CHECK_BYTES = 1 << 16


def check_text_file(path: Path, what: str = "CSV log") -> None:
    """Refuse a file that is binary (NUL bytes in its first 64 kB) or empty.

    Parameters
    ----------
    path : Path
        The file.
    what : str
        What it should be, for the message.
    """
    try:
        with open(path, "rb") as fh:
            head = fh.read(TEXT_CHECK_BYTES)
    except OSError as exc:
        raise InputError(f"{clean(path)}: cannot read ({exc.strerror or exc})") from None
    if not head.strip(b" \t\r\n\x00"):
        raise InputError(f"{clean(path)}: the file is empty; expected a {what} with a header row")
    nul = head.find(b"\x00")
    if nul >= 0:
        ln = head.count(b"\n", 0, nul) + 1
        raise InputError(
            f"{clean(path)}: line {ln}: binary data (a NUL byte at byte {nul}), not a text"
            f" {what}; is it the right file? (other formats are chosen by the extension:"
            " .parquet, .h5, .xyz)")


def first_undecodable_line(path: Path, encoding: str = "utf-8") -> tuple[int, bytes] | None:
    """1-based number and bytes of the first line of ``path`` that is not valid ``encoding``."""
    import codecs

    dec = codecs.getincrementaldecoder(encoding)()
    try:
        with open(path, "rb") as fh:
            for ln, raw in enumerate(fh, start=1):
                try:
                    dec.decode(raw)
                except UnicodeDecodeError as exc:
                    return ln, raw[max(0, exc.start - 10): exc.end + 10]
    except OSError:
        return None
    return None


def not_utf8_message(path: Path) -> str:
    """The error for a text file with bytes that are not UTF-8, naming the first such line."""
    bad = first_undecodable_line(path)
    where = f"line {bad[0]}: " if bad else ""
    near = f" (near {bad[1]!r})" if bad else ""
    return (f"{clean(path)}: {where}bytes that are not UTF-8 text{near}; save the file as UTF-8"
            " (e.g. iconv -f latin1 -t utf-8 IN > OUT) or fix that line")


def truncated_row_message(path: Path, line: int, fields: int, n_header: int, last: bool) -> str:
    """The error for a row with fewer fields than the header."""
    if last:
        return (f"{clean(path)}: line {line}: the last row has {fields} of the header's"
                f" {n_header} fields: the log is cut short in the middle of a row; restore the"
                " complete file, or read it with allow_truncated=True to drop that row (a"
                " warning is recorded in the report)")
    return (f"{clean(path)}: line {line}: {fields} fields but the header names {n_header}"
            " columns; fix that row (or check the delimiter)")


def short_row(path: Path, header_line: int, n_fields: int, delimiter: str = ","
              ) -> tuple[int, int, bool] | None:
    """The first data line with fewer than ``n_fields`` fields (``delimiter``-separated).

    Blank lines are skipped (as the readers skip them); quoted fields are honoured.

    Returns
    -------
    (line, fields, is_last) or None
        1-based line number, its field count, and whether it is the last data line.
    """
    import csv
    import io as _io

    first: tuple[int, int] | None = None
    last_data = 0
    ln0 = 0  # lines before the current block
    try:
        with open(path, "rb") as fh:
            for block in _line_blocks(fh):
                raw = np.frombuffer(block, dtype=np.uint8)
                nl = np.flatnonzero(raw == 10)
                starts = np.r_[0, nl[:-1] + 1]
                numbers = ln0 + 1 + np.arange(len(nl))
                ln0 += len(nl)
                blank = _blank_lines(block, starts, nl)
                data = (numbers > header_line) & ~blank
                if not data.any():
                    continue
                last_data = int(numbers[data][-1])
                if first is not None:
                    continue
                if 34 in raw:  # quotes: let the csv module count
                    text = block.decode("utf-8", errors="replace")
                    try:
                        counts = np.array([len(r) for r in csv.reader(_io.StringIO(text),
                                                                       delimiter=delimiter)])
                    except csv.Error:  # a field running past the csv module's limit
                        counts = np.zeros(0)
                    if len(counts) != len(nl):
                        stray = open_quote_line(path, header_line)
                        if stray is not None:
                            raise InputError(stray_quote_message(path, stray))
                        continue  # a quoted newline: cannot count per line, trust the parser
                else:
                    commas = np.flatnonzero(raw == ord(delimiter))
                    counts = np.diff(np.r_[0, np.searchsorted(commas, nl)]) + 1
                bad = np.flatnonzero(data & (counts < n_fields))
                if bad.size:
                    first = int(numbers[bad[0]]), int(counts[bad[0]])
    except OSError:
        return None
    if first is None:
        return None
    return first[0], first[1], first[0] == last_data


def quote_spans(path: Path, after: int = 0) -> list[tuple[int, int | None]]:
    """Quoted fields that run over more than one line: ``(opening line, closing line)``.

    Quotes are paired in file order from line ``after + 1`` (a doubled quote ``""`` inside a
    quoted field counts two, so it keeps the pairing); the closing line is None for a quote
    that is never closed.  Lines are 1-based.
    """
    spans: list[tuple[int, int | None]] = []
    open_at: int | None = None
    try:
        with open(path, "rb") as fh:
            for ln, raw in enumerate(fh, start=1):
                if ln > after and raw.count(b'"') % 2:
                    if open_at is None:
                        open_at = ln
                    else:
                        spans.append((open_at, ln))
                        open_at = None
    except OSError:
        return spans
    if open_at is not None:
        spans.append((open_at, None))
    return spans


def open_quote_line(path: Path, after: int = 0) -> int | None:
    """1-based line of a double quote that opens a field and is never closed (None: none)."""
    spans = quote_spans(path, after)
    return spans[-1][0] if spans and spans[-1][1] is None else None


def stray_quote_message(path: Path, line: int, closed_at: int | None = None) -> str:
    """The error for a quote that opens a field and never closes (the rest of the file would
    be one field), or closes only on a later line ``closed_at``."""
    runs = ("is never closed, so the rest of the file would be one value" if closed_at is None
            else f"closes only on line {closed_at}, so lines {line}-{closed_at} would be one row")
    return (f"{clean(path)}: line {line}: a double quote (\") opens a field that {runs}; remove"
            " the stray quote or close it on that line")


def spanning_quote_message(path: Path, line: int, after: int = 0) -> str | None:
    """The stray-quote error when the bad row ending on ``line`` is a quoted field run over
    several lines (None when no quoted field ends there)."""
    for start, end in quote_spans(path, after):
        if end == line or (end is None and start <= line):
            return stray_quote_message(path, start, end)
    return None


def _blank_lines(block: bytes, starts: np.ndarray, nl: np.ndarray) -> np.ndarray:
    """Lines made only of blanks (and a carriage return)."""
    raw = np.frombuffer(block, dtype=np.uint8)
    nonblank = ~np.isin(raw, (32, 9, 13, 10))
    cum = np.r_[0, np.cumsum(nonblank)]
    return (cum[nl] - cum[starts]) == 0


#: Name given to the field after the last header column while reading (a trailing delimiter).
EXTRA_FIELD = "\x00extra"
#: Prefix of the names given to header cells that are empty.
UNNAMED_FIELD = "\x00unnamed"


def csv_header_fields(path: Path) -> tuple[list[str], int] | None:
    """The header of a CSV as the readers split it, and its 1-based line number.

    Quotes are honoured and blanks around names removed; leading blank lines are skipped (as
    the readers skip them).  Only the first line(s) are read.

    Returns
    -------
    (names, line) or None
        None when the header cannot be decoded (the readers then word the error).
    """
    return _first_fields(path, 0)


def first_data_fields(path: Path, header_line: int) -> tuple[list[str], int] | None:
    """Fields of the first non-blank line after the header, and its 1-based line number."""
    return _first_fields(path, header_line)


def _first_fields(path: Path, after: int) -> tuple[list[str], int] | None:
    """CSV fields of the first non-blank line after line ``after`` (None: none or undecodable)."""
    import csv

    try:
        for ln, text in text_lines(path):
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


def read_csv(path: Path, spare_fields: int = 1, *, allow_truncated: bool = False,
             usecols: Sequence[str] | None = None,
             dtypes: Mapping[str, Any] | None = None) -> pd.DataFrame:
    """Read a CSV table (pyarrow's multi-threaded reader when available, else pandas).

    The file must be UTF-8 text (a binary file, or bytes that are not UTF-8, are an error
    naming the line: never replaced by placeholder characters).  The header is checked first
    (a name used twice is an error).  A row may end with up to ``spare_fields`` empty fields
    more than the header (loggers that end every row with the delimiter): they are dropped; a
    value there is an error naming the line.  A row with fewer fields than the header is an
    error naming the line; the last row of a log cut short in the middle of a row is dropped
    instead when ``allow_truncated`` (a warning says so).  An empty header cell is accepted
    only for an empty column.  Both readers give the same table.

    Parameters
    ----------
    path : Path
        The CSV file.
    spare_fields : int
        Empty fields a row may have after the header's last column.
    allow_truncated : bool
        Drop a last row that is cut short (with a warning) instead of refusing the file.
    usecols : sequence of str, optional
        Read only these columns (source names; those the file lacks are ignored): pyarrow
        parses no other column (``include_columns``).  Default: every column.
    dtypes : mapping, optional
        ``{column: numpy float dtype}`` pyarrow parses these columns into (e.g. float32 for
        columns only drawn); the other readers' columns are converted by the caller.

    Returns
    -------
    DataFrame
        The raw table (source column names); ``df.attrs[ROWS_ATTR]`` tells where its rows
        are in the file.
    """
    path = Path(path)
    if path.is_dir():
        raise InputError(f"{path}: is a folder, not a log file; give the log file itself")
    if not path.exists():
        raise InputError(f"{path}: file not found; check the path")
    check_text_file(path)
    head = csv_header_fields(path)
    if head is None and first_undecodable_line(path) is not None:
        raise InputError(not_utf8_message(path))
    names, header_line = head if head is not None else (None, 1)
    if names is not None:
        check_unique_names(names, str(path))
    df = None
    plain = False
    include = None
    if usecols is not None and names is not None:
        want = set(usecols)
        include = [c for c in names if c in want]
    if names is None or all(names):
        df = read_csv_arrow(path, include=include, dtypes=dtypes)
        plain = df is not None  # pyarrow checked that every row has the header's field count
    if df is None:
        df, plain = _read_csv_other(path, names, header_line, spare_fields, allow_truncated)
    raw_names = [str(c) for c in df.columns]
    df.columns = [c.strip() for c in raw_names]
    if usecols is not None:
        want = set(usecols)
        df = df[[c for c in df.columns if c in want]]
        plain = False  # not every column of the file: outputs never copy its lines
    if plain and raw_names == list(df.columns):
        df.attrs["_plain_csv_columns"] = ColumnNames(raw_names)  # cheap to deep-copy
    df.attrs[ROWS_ATTR] = rows_after_header(path, header_line)
    return df


def _read_csv_other(path: Path, names: list[str] | None, header_line: int,
                    spare_fields: int = 1, allow_truncated: bool = False
                    ) -> tuple[pd.DataFrame, bool]:
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
    cols = [name if name else f"{UNNAMED_FIELD}{j}" for j, name in enumerate(names)]
    cols += [f"{EXTRA_FIELD}{k}" for k in range(spare_fields)]
    first = first_data_fields(path, header_line)
    if first is not None and len(first[0]) > len(cols):
        # (pandas would take this row's length as the table's and cut the fields beyond cols)
        raise InputError(
            f"{path}: line {first[1]}: {len(first[0])} fields but the header names {n} columns;"
            " fix that row (or the header, or check the delimiter)")
    df = None
    if header_line == 1 and (not all(names) or (first is not None
                                                 and len(first[0]) == len(cols))):
        df = read_csv_arrow(path, cols)  # every row as long: pyarrow can read it
    if df is None:
        df = _read_csv_pandas(path, cols, n, header_line)
    rows = rows_after_header(path, header_line)
    spare = [c for c in df.columns if str(c).startswith("\x00")]
    for c in spare:
        filled = filled_cells(df[c])
        if not filled.any():
            continue
        i = int(np.flatnonzero(filled)[0])
        where, value = row_location(rows, i), str(df[c].iloc[i]).strip()
        if str(c).startswith(EXTRA_FIELD):
            raise InputError(
                f"{path}: {where}: more fields than the {n} columns of the header (value"
                f" {value!r} has no column); remove the extra value or add its name to the"
                " header")
        j = int(str(c)[len(UNNAMED_FIELD):])
        raise InputError(
            f"{path}: column {j + 1} has no name in the header but holds values ({where}:"
            f" {value!r}); give it a name in the header")
    df = df.drop(columns=spare)
    short = short_row(path, header_line, n)
    if short is not None:
        ln, k, last = short
        if not (last and allow_truncated):
            raise InputError(truncated_row_message(path, ln, k, n, last))
        df = df.iloc[:-1].reset_index(drop=True)
        log.warning("%s: line %d: the last row is cut short (%d of %d fields: the log ended"
                    " in the middle of a row); dropped it", path, ln, k, n)
        return df, False
    plain = header_line == 1 and all(names) and _rows_have_fields(path, n)
    return df, plain


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
        raise InputError(f"{path}: file not found; check the path") from None
    except pd.errors.EmptyDataError:
        if cols is not None:  # a header and no data row
            return pd.DataFrame({c: pd.Series(dtype=np.float64) for c in cols})
        raise InputError(
            f"{path}: the file is empty; expected a CSV log with a header row") from None
    except UnicodeDecodeError:
        raise InputError(not_utf8_message(path)) from None
    except (pd.errors.ParserError, ValueError, OverflowError) as exc:
        msg = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
        m = re.search(r"Expected \d+ fields in line (\d+), saw (\d+)", msg)
        spanning = spanning_quote_message(path, int(m.group(1))) if m else None
        if spanning is not None:
            raise InputError(spanning) from None
        if m and n_header:
            raise InputError(
                f"{path}: line {m.group(1)}: {m.group(2)} fields but the header names"
                f" {n_header} columns; fix that row (or check the delimiter)") from None
        stray = open_quote_line(path) if "inside string" in msg else None
        if stray is not None:
            raise InputError(stray_quote_message(path, stray)) from None
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


def read_csv_arrow(path: Path, names: list[str] | None = None, *,
                    include: list[str] | None = None,
                    dtypes: Mapping[str, Any] | None = None) -> pd.DataFrame | None:
    """Read with pyarrow's multithreaded reader; None when the table needs pandas' rules.

    ``names`` replaces the header row (read with exactly these columns, header skipped);
    ``include`` names the only columns parsed (``include_columns``).
    """
    try:
        import pyarrow as pa
        import pyarrow.csv as pacsv
    except ImportError:  # pragma: no cover - pyarrow is optional
        return None
    if not path.exists():
        raise InputError(f"{path}: file not found; check the path")
    if path.stat().st_size == 0:
        raise InputError(f"{path}: the file is empty; expected a CSV log with a header row")
    if names is not None:
        try:
            table = pacsv.read_csv(path, read_options=pacsv.ReadOptions(column_names=names,
                                                                        skip_rows=1))
        except (pa.ArrowInvalid, OSError):
            return None
        return _arrow_numeric_frame(table)
    types = {c: pa.from_numpy_dtype(np.dtype(dt)) for c, dt in (dtypes or {}).items()
             if include is None or c in include}
    convert = pacsv.ConvertOptions(column_types=types,
                                   **({} if include is None else {"include_columns": include}))
    try:
        table = _read_arrow_table(path, convert)
    except pa.ArrowInvalid as exc:
        text = str(exc).strip()
        if "Empty CSV file" in text:
            raise InputError(
                f"{path}: the file is empty; expected a CSV log with a header row") from None
        # Ragged rows, bad quoting, invalid UTF-8: let pandas decide and word the error.
        return None
    return _arrow_numeric_frame(table)


def _read_arrow_table(path: Path, convert: Any) -> Any:
    """The table of a CSV, parsed block by block by pyarrow's streaming reader.

    ``pyarrow.csv.open_csv`` never holds the whole text: a quarter of ``read_csv``'s peak
    (2e6 rows, 17 of 24 columns: 374 MB against 1288 MB).  It takes the column types from the
    first block; when a later block does not fit them (an integer column with a decimal
    further down) the file is read again by ``read_csv``, which infers them from every block.
    """
    import pyarrow as pa
    import pyarrow.csv as pacsv

    try:
        reader = pacsv.open_csv(path, convert_options=convert)
        return pa.Table.from_batches(list(reader), schema=reader.schema)
    except pa.ArrowInvalid as exc:
        if "Empty CSV file" in str(exc):
            raise
        return pacsv.read_csv(path, convert_options=convert)


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
    # Column by column, freeing each Arrow column once converted.
    try:
        df = table.to_pandas(split_blocks=True, self_destruct=True)
    except UnicodeDecodeError:  # column names that are not UTF-8: pandas words the error
        return None
    return df


#: Bytes of the input read per block when its lines are copied into the output.
PASSTHROUGH_BLOCK_BYTES = 2 << 20


def line_arrays(fin: Any, block_bytes: int | None = None) -> Iterator[np.ndarray]:
    """Blocks of whole lines of a binary file as uint8 arrays, read without copying.

    As :func:`_line_blocks` (about ``block_bytes`` per block, a ``\\n`` added to a last line
    without one), but each block is read straight into its own buffer after the previous
    block's partial line: no concatenation and no slicing copy of the block (two 2 MB copies
    per block, 0.1-0.4 s CPU per 1e6 rows of a 9-column log, on the writer's main thread).
    """
    size = int(block_bytes or PASSTHROUGH_BLOCK_BYTES)
    carry = b""
    while True:
        buf = bytearray(len(carry) + size)
        buf[: len(carry)] = carry
        got = fin.readinto(memoryview(buf)[len(carry):])
        end = len(carry) + (got or 0)
        if not got:
            if carry:
                yield np.frombuffer(carry if carry.endswith(b"\n") else carry + b"\n",
                                    dtype=np.uint8)
            return
        cut = buf.rfind(b"\n", 0, end)
        if cut < 0:
            carry = bytes(buf[:end])
            continue
        carry = bytes(buf[cut + 1: end])
        yield np.frombuffer(buf, dtype=np.uint8, count=cut + 1)


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
