"""Row batches of a log for the chunked mode (``--chunk-rows``), validated like :func:`read_log`.

CSV is streamed with pyarrow's reader, Parquet by row groups; other formats are read whole
(with their own reader) and cut into batches.  :func:`iter_batches` gives the raw table (source
column names); :func:`iter_log_batches` gives canonical, validated batches through the very
functions :func:`aeromag.io.read_log` uses (column map, numbers and date-times, magnitudes,
units), so that the chunked mode accepts and refuses what the in-memory mode does: a BOM,
leading blank lines, quoted headers, ISO 8601 or Parquet datetime times, a trailing delimiter;
a row shorter than the header, text, true/false or binary data where numbers are needed, bytes
that are not UTF-8 (each an error naming the line).  Exact duplicate rows are found by
:func:`duplicate_rows` (a scan) and dropped by every pass, as ``read_log`` drops them.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..errors import InputError
from .columns import (
    ISO_DATETIME,
    NUMERIC_COLUMNS,
    apply_column_map,
    check_unique_names,
    convert_units,
    to_numeric,
)
from .csv import (
    EXTRA_FIELD,
    check_text_file,
    csv_header_fields,
    first_data_fields,
    not_utf8_message,
    short_row,
    truncated_row_message,
)
from .formats import check_delimiter, detect_format, read_table_rows
from .formats.parquet import check_flat_schema, parquet_error
from .messages import check_input_file, clean
from .outputs import recorded_warnings, register_input
from .rows import ROWS_ATTR, row_location, rows_after_header, rows_numbered, shift_rows

log = logging.getLogger(__name__)


def iter_batches(path: Path, fmt: str | None, columns: list[str] | None = None,
                 batch_rows: int = 250_000, *, allow_truncated: bool = False
                 ) -> Iterator[pd.DataFrame]:
    """Yield the raw table of ``path`` in consecutive row batches (source column names).

    Each batch carries ``attrs[ROWS_ATTR]``: where its rows are in the file.

    Parameters
    ----------
    path : Path
        The log.
    fmt : str, optional
        Format; CSV and Parquet are streamed, others read whole.
    columns : list of str, optional
        Source columns to read (all when None).
    batch_rows : int
        Approximate rows per batch.
    allow_truncated : bool
        Drop a last row cut short (with a warning) instead of refusing the file.
    """
    path = Path(path)
    check_input_file(path)
    register_input(path, "input log")
    f = detect_format(path, fmt)
    if f == "csv":
        check_delimiter(path)
        yield from _csv_batches(path, columns, batch_rows, allow_truncated)
    elif f == "parquet":
        yield from _parquet_batches(path, columns, batch_rows)
    else:
        df = read_table_rows(path, f, allow_truncated=allow_truncated)
        rows = df.attrs.pop(ROWS_ATTR, None)
        if columns is not None:
            df = df[[c for c in columns if c in df.columns]]
        for a in range(0, max(len(df), 1), batch_rows):
            b = df.iloc[a:a + batch_rows].reset_index(drop=True)
            b.attrs[ROWS_ATTR] = shift_rows(rows, a)
            yield b


def _csv_batches(path: Path, columns: list[str] | None, batch_rows: int,
                 allow_truncated: bool) -> Iterator[pd.DataFrame]:
    import pyarrow as pa
    import pyarrow.csv as pacsv

    check_text_file(path)
    head = csv_header_fields(path)
    if head is None:
        raise InputError(not_utf8_message(path))
    header, header_line = head
    check_unique_names(header, str(path))
    n = len(header)
    first = first_data_fields(path, header_line)
    # ISO 8601 times are text: read as text, converted by to_numeric as read_log does.
    iso_time = (first is not None and "time" in header and len(first[0]) > header.index("time")
                and bool(ISO_DATETIME.match(first[0][header.index("time")])))
    types = {c: (pa.string() if c == "time" and iso_time else pa.float64())
             for c in header if c in NUMERIC_COLUMNS}
    avg = max(16, path.stat().st_size // max(1, _count_lines_estimate(path)))
    block = int(min(max(avg * batch_rows, 1 << 20), 1 << 30))
    # A logger that ends every row with the delimiter: read the empty extra field under a
    # name of its own, check it stays empty, drop it (as read_log does).
    extra = first is not None and len(first[0]) == n + 1 and not first[0][-1].strip()
    names = header + ([EXTRA_FIELD] if extra else [])
    ro = pacsv.ReadOptions(block_size=block, column_names=names, skip_rows=header_line)
    keep = None if columns is None else [c for c in names if c in columns or c == EXTRA_FIELD]
    co = pacsv.ConvertOptions(column_types=types, include_columns=keep,
                              strings_can_be_null=True)
    skipped: list[tuple[int, str]] = []

    def invalid(row: Any) -> str:
        if allow_truncated and row.actual_columns < row.expected_columns:
            skipped.append((row.actual_columns, row.text))
            return "skip"
        return "error"

    po = pacsv.ParseOptions(invalid_row_handler=invalid)
    rows = rows_after_header(path, header_line)
    done = 0
    try:
        reader = pacsv.open_csv(path, read_options=ro, convert_options=co, parse_options=po)
        for rb in reader:
            df = rb.to_pandas()
            if extra:
                bad = df[EXTRA_FIELD].notna().to_numpy()
                if bad.any():
                    i = int(np.flatnonzero(bad)[0])
                    raise InputError(
                        f"{clean(path)}: {row_location(rows, done + i)}: more fields than the"
                        f" {n} columns of the header (value {df[EXTRA_FIELD].iloc[i]!r} has"
                        " no column); remove the extra value or add its name to the header")
                df = df.drop(columns=EXTRA_FIELD)
            df.attrs[ROWS_ATTR] = shift_rows(rows, done)
            done += len(df)
            yield df
    except (pa.ArrowInvalid, UnicodeDecodeError, ValueError) as exc:
        raise InputError(_diagnose_csv(path, header_line, n, exc)) from None
    if skipped:
        short = short_row(path, header_line, n)
        if short is None or not short[2] or len(skipped) > 1:
            raise InputError(_diagnose_csv(path, header_line, n, None))
        msg = (f"{path}: line {short[0]}: the last row is cut short ({short[1]} of {n} fields:"
               " the log ended in the middle of a row); dropped it")
        if msg not in recorded_warnings():  # once, not once per pass of the chunked mode
            log.warning("%s", msg)


def _diagnose_csv(path: Path, header_line: int, n: int, exc: BaseException | None) -> str:
    """The one-line error for a CSV the streaming reader refused, naming the line."""
    short = short_row(path, header_line, n)
    if short is not None:
        return truncated_row_message(path, short[0], short[1], n, short[2])
    msg = str(exc).strip().splitlines()[0] if exc is not None and str(exc).strip() else ""
    if "UTF8" in msg or "UTF-8" in msg or isinstance(exc, UnicodeDecodeError):
        return not_utf8_message(path)
    # A value that is not a number, or a long row: read_log words it with the exact line.
    from .log import read_log

    try:
        read_log(path)
    except InputError as err:
        return str(err)
    return (f"{clean(path)}: cannot read as CSV ({clean(msg)[:200]}); fix the row, or check the"
            " delimiter and quoting")


def _parquet_batches(path: Path, columns: list[str] | None, batch_rows: int
                     ) -> Iterator[pd.DataFrame]:
    import pyarrow.parquet as pq

    done = 0
    try:
        pf = pq.ParquetFile(path, page_checksum_verification=True)
        check_flat_schema(path, pf.schema_arrow)
        have = set(pf.schema_arrow.names)
        cols = None if columns is None else [c for c in columns if c in have]
        for rb in pf.iter_batches(batch_size=batch_rows, columns=cols):
            df = rb.to_pandas()
            df.attrs[ROWS_ATTR] = shift_rows(rows_numbered("row"), done)
            done += len(df)
            yield df
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - any pyarrow failure is a bad file
        raise InputError(parquet_error(path, exc)) from None


def canonical_batch(df: pd.DataFrame, source: str, *, columns: Mapping[str, str] | None = None,
                    units: Mapping[str, str] | None = None) -> pd.DataFrame:
    """One raw batch into canonical, validated columns, exactly as :func:`read_log` does it.

    Parameters
    ----------
    df : DataFrame
        A batch of :func:`iter_batches` (its ``attrs[ROWS_ATTR]`` names the file lines).
    source : str
        File name quoted in errors.
    columns, units : mapping, optional
        Column map and unit conversions.

    Returns
    -------
    DataFrame
    """
    rows = df.attrs.pop(ROWS_ATTR, None)
    df = apply_column_map(df, columns, source=source) if columns else df
    present = [c for c in NUMERIC_COLUMNS if c in df.columns]
    df = to_numeric(df, present, source, rows)
    df.attrs.pop("_plain_csv_columns", None)
    df = convert_units(df, units, source=source, rows=rows)
    df.attrs.pop("_time_converted", None)
    if "time" in df.columns:
        from .log import check_time_values

        check_time_values(df["time"].to_numpy(np.float64), source, rows)
    return df


def iter_log_batches(path: Path, fmt: str | None, columns: Sequence[str] | None = None, *,
                     colmap: Mapping[str, str] | None = None,
                     units: Mapping[str, str] | None = None, batch_rows: int = 250_000,
                     drop: np.ndarray | None = None, allow_truncated: bool | None = None
                     ) -> Iterator[pd.DataFrame]:
    """Canonical, validated batches of a log (see :func:`canonical_batch`).

    Parameters
    ----------
    path : Path
        The log.
    fmt : str, optional
        Format.
    columns : sequence of str, optional
        Canonical columns to read (all when None).
    colmap, units : mapping, optional
        Column map ``{canonical: source}`` and unit conversions.
    batch_rows : int
        Approximate rows per batch.
    drop : ndarray of int, optional
        Sorted 0-based rows of the file to leave out (the exact duplicates of
        :func:`duplicate_rows`).
    allow_truncated : bool, optional
        As :func:`aeromag.io.read_log` (default from :func:`aeromag.io.log.reading_options`).
    """
    from .log import allow_truncated_default

    cm = dict(colmap or {})
    src_cols = None if columns is None else [cm.get(c, c) for c in columns]
    # A batch of some columns is mapped by the entries for those columns only (read_log's map,
    # applied to the columns read: the others are checked on the full first batch).
    cm_read = cm if columns is None else {k: v for k, v in cm.items() if k in columns}
    drop = np.zeros(0, dtype=np.int64) if drop is None else np.asarray(drop, dtype=np.int64)
    start = 0
    for raw in iter_batches(Path(path), fmt, src_cols, batch_rows,
                            allow_truncated=allow_truncated_default(allow_truncated)):
        k = len(raw)
        b = canonical_batch(raw, str(path), columns=cm_read, units=units)
        if drop.size:
            lo, hi = np.searchsorted(drop, [start, start + k])
            if hi > lo:
                b = b.drop(index=drop[lo:hi] - start).reset_index(drop=True)
        start += k
        yield b


def duplicate_rows(path: Path, fmt: str | None, candidates: np.ndarray, *,
                   colmap: Mapping[str, str] | None = None,
                   units: Mapping[str, str] | None = None, batch_rows: int = 250_000
                   ) -> np.ndarray:
    """Which of the ``candidates`` rows (same time as the row before) are exact duplicates.

    A row identical to the one before it in every column is dropped by :func:`read_log`; the
    chunked mode finds them with this scan (only run when a time repeats).

    Parameters
    ----------
    path : Path
        The log.
    fmt : str, optional
        Format.
    candidates : ndarray of int
        Sorted 0-based rows whose time equals the previous row's.
    colmap, units : mapping, optional
        As :func:`iter_log_batches`.
    batch_rows : int
        Rows per batch.

    Returns
    -------
    ndarray of int
        The candidates that are exact duplicates.
    """
    cand = np.asarray(candidates, dtype=np.int64)
    out: list[np.ndarray] = []
    prev: pd.DataFrame | None = None
    start = 0
    for b in iter_log_batches(path, fmt, colmap=colmap, units=units, batch_rows=batch_rows):
        k = len(b)
        lo, hi = np.searchsorted(cand, [start, start + k])
        if hi > lo:
            ext = b if prev is None else pd.concat([prev, b], ignore_index=True)
            at = cand[lo:hi] - start + (0 if prev is None else 1)
            ok = at >= 1
            at, rows = at[ok], cand[lo:hi][ok]
            cur = ext.iloc[at].reset_index(drop=True)
            before = ext.iloc[at - 1].reset_index(drop=True)
            same = ((cur == before) | (cur.isna() & before.isna())).all(axis=1).to_numpy()
            out.append(rows[same])
        prev = b.iloc[-1:] if k else prev
        start += k
    return np.concatenate(out) if out else np.zeros(0, dtype=np.int64)


def locate_row(path: Path, fmt: str | None, i: int) -> str:
    """Where data row ``i`` (0-based) of a log is, worded as :func:`read_log` words it."""
    f = detect_format(path, fmt)
    if f == "csv":
        head = csv_header_fields(Path(path))
        rows = rows_after_header(path, head[1] if head else 1)
    elif f == "parquet":
        rows = rows_numbered("row")
    else:
        rows = read_table_rows(path, f).attrs.get(ROWS_ATTR)
    return row_location(rows, i)


def _count_lines_estimate(path: Path) -> int:
    with open(path, "rb") as fh:
        head = fh.read(1 << 20)
    n = head.count(b"\n")
    size = path.stat().st_size
    return max(1, int(n * size / max(1, len(head))))
