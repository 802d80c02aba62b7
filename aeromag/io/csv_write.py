"""The one CSV writer of aeromag.

Numbers in their shortest round-trip form (an integral float as ``x.0``), booleans
``true``/``false``, missing values empty, written atomically by pyarrow's CSV writer.
The reader is :mod:`aeromag.io.csv`.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..errors import InputError
from .csv import line_arrays
from .messages import clean
from .outputs import atomic_path, display_path


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


def check_no_binary(df: pd.DataFrame, target: Path) -> None:
    """Refuse a column of raw bytes (a Parquet binary column) for a text output.

    Parameters
    ----------
    df : DataFrame
        The table to write.
    target : Path
        The output, named in the message.
    """
    target = display_path(target)
    for c in df.columns:
        s = df[c]
        if s.dtype.kind not in "OS":
            continue
        vals = s.dropna()
        if len(vals) and isinstance(vals.iloc[0], bytes | bytearray | memoryview) or (
                s.dtype.kind == "S"):
            raise InputError(
                f"{clean(target)}: column {clean(c)!r} holds binary data (raw bytes), which a"
                " text file cannot hold; write -o OUT.parquet, or drop or decode the column")


def write_csv(df: pd.DataFrame, path: str | os.PathLike[str]) -> Path:
    """Write a log to CSV atomically; booleans are written ``true``/``false``.

    Uses pyarrow's CSV writer when available (numbers in their shortest round-trip form,
    missing values empty), pandas otherwise.

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
    check_no_binary(df, target)
    with atomic_path(target) as tmp:
        if not _write_csv_arrow(df, tmp):
            _csv_ready(df).to_csv(tmp, index=False, lineterminator="\n")
    return target


def csv_header(columns: Iterable[Any]) -> str:
    """The header row, quoted only where a name needs it (as pandas writes it)."""
    import csv
    import io as _io

    buf = _io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow([str(c) for c in columns])
    return buf.getvalue()


def floats_as_pandas_text(table: Any, columns: Iterable[str] | None = None) -> Any:
    """Format float columns as pandas does: shortest round trip, integral values with ``.0``.

    Arrow writes ``1.0`` as ``1``; read back, a float column whose values are all integral
    would turn into integers.  Every value is written on its own, whatever the others are, so
    that the same number is the same text in every output (in memory and chunk by chunk: a
    ``0.0`` never becomes ``0`` because the rest of a chunk happens to be integral).  Only
    float columns holding an integral value are rewritten (one vectorised scan), which keeps
    the writer fast on measurement data; ``columns``: rewrite exactly these float columns
    instead (those of a whole table, for a slice of it).
    """
    import pyarrow as pa
    import pyarrow.compute as pc

    chosen = None if columns is None else set(columns)
    for i, f in enumerate(table.schema):
        if not pa.types.is_floating(f.type):
            continue
        if not (_has_integral(table.column(i)) if chosen is None else f.name in chosen):
            continue
        txt = pc.cast(table.column(i), pa.string())
        has_point = pc.match_substring_regex(txt, "[.eEnN]")
        txt = pc.if_else(has_point, txt, pc.binary_join_element_wise(txt, ".0", ""))
        table = table.set_column(i, f.name, txt)
    return table


def _has_integral(column: Any) -> bool:
    """True when some finite value of an Arrow float column is a whole number."""
    for chunk in column.chunks:
        vals = chunk.to_numpy(zero_copy_only=False)
        with np.errstate(invalid="ignore"):
            if np.any(vals == np.floor(vals)):  # NaN and inf compare False / are excluded
                fin = vals[np.isfinite(vals)]
                if np.any(fin == np.floor(fin)):
                    return True
    return False


def write_arrow_csv(table: Any, fh: Any, quoting: str = "none") -> None:
    """Write an Arrow table as CSV rows (no header) to a binary file (``pyarrow.csv``).

    Parameters
    ----------
    table : pyarrow.Table
        The rows to write.
    fh : binary file
        Open destination.
    quoting : str
        pyarrow quoting style (``"none"`` raises ``ArrowInvalid`` on a value needing quotes).
    """
    import pyarrow.csv as pacsv

    pacsv.write_csv(table, fh, pacsv.WriteOptions(include_header=False, quoting_style=quoting))


def write_csv_passthrough(
    source: str | os.PathLike[str], source_columns: Sequence[str], extra: pd.DataFrame,
    dest: str | os.PathLike[str],
) -> bool:
    """Write ``source``'s lines verbatim with ``extra``'s columns appended to each.

    The columns a log came with are copied as the text they were read from (no reformatting,
    no precision lost), and only the added columns are formatted: 4 columns formatted
    instead of 13 on a typical log, so about 3x less writing work.  The source is
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
        table = floats_as_pandas_text(pa.Table.from_pandas(extra, preserve_index=False))
    except (pa.ArrowException, TypeError, ValueError):
        return False
    if any(pa.types.is_temporal(f.type) or pa.types.is_nested(f.type) for f in table.schema):
        return False
    n = table.num_rows
    opts = pacsv.WriteOptions(include_header=False, quoting_style="none")

    def join(raw: np.ndarray, row: int, k: int) -> Any:
        """One block (uint8 array of k whole lines), each line followed by its row of ``table``."""
        if np.any(raw == 34):  # a quote: the lines are not plain
            return None
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
                             pa.py_buffer(raw)])
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

    row = 0
    with open(source, "rb") as fin, open(dest, "wb") as fout:
        header = fin.readline()
        head = header.rstrip(b"\r\n")
        try:
            names = head.decode("utf-8").split(",")
        except UnicodeDecodeError:
            return False
        if names != list(source_columns) or b'"' in head:
            return False
        fout.write(head + b"," + csv_header(extra.columns).encode("utf-8"))
        for raw in line_arrays(fin):
            k = int(np.count_nonzero(raw == 10))  # (numpy: 3-4x faster than bytes.count)
            if row + k > n:
                return False
            out = join(raw, row, k)
            if out is None:
                return False
            fout.write(out)
            row += k
    return row == n


#: Rows converted to Arrow and written at a time: the memory is a slice's, not a second copy
#: of the whole table (1e7 samples x 14 columns: 1.1 GB).
CSV_SLICE_ROWS = 1 << 20


def _write_csv_arrow(df: pd.DataFrame, dest: Path) -> bool:
    """Write ``df`` with pyarrow; return False (nothing promised) when pyarrow cannot.

    One slice of rows at a time, each converted with the whole table's schema; every value is
    formatted on its own (:func:`floats_as_pandas_text`), so the file is the one a single
    conversion of the whole table writes.  A value needing quotes anywhere: the whole file is
    written again with quoting where needed.
    """
    try:
        import pyarrow as pa
    except ImportError:  # pragma: no cover - pyarrow is optional
        return False
    try:
        schema = pa.Schema.from_pandas(df, preserve_index=False)
    except (pa.ArrowException, TypeError, ValueError):
        return False
    if any(pa.types.is_temporal(f.type) or pa.types.is_nested(f.type) for f in schema):
        return False
    # which float columns become text is decided on the whole table (under quoting, text
    # is quoted: a slice must not decide otherwise than the whole)
    fails = (pa.ArrowException, TypeError, ValueError, KeyError)
    named = df.set_axis(schema.names, axis=1)  # the schema's (text) names, e.g. of 0, 1, ...
    try:
        as_text = [f.name for i, f in enumerate(schema) if pa.types.is_floating(f.type)
                   and _has_integral(pa.Table.from_pandas(
                       named.iloc[:, [i]], schema=pa.schema([f]), preserve_index=False
                   ).column(0))]
    except fails:
        return False
    header = csv_header(df.columns).encode("utf-8")
    with open(dest, "wb") as fh:
        for quoting in ("none", "needed"):
            fh.seek(0)
            fh.truncate()
            fh.write(header)
            try:
                for a in range(0, len(df), CSV_SLICE_ROWS):
                    try:
                        table = pa.Table.from_pandas(named.iloc[a:a + CSV_SLICE_ROWS],
                                                     schema=schema, preserve_index=False)
                    except fails:
                        return False
                    write_arrow_csv(floats_as_pandas_text(table, as_text), fh, quoting)
            except pa.ArrowInvalid:  # a string needs quoting
                if quoting == "needed":
                    raise
                continue
            return True
    return True
