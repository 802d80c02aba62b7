"""Row batches of a log for the chunked mode (``--chunk-rows``).

CSV is streamed with pyarrow's reader, Parquet by row groups; other formats are read whole
and cut into batches.  Each batch is the raw table (source column names), as
:func:`aeromag.io.read_log` would read it before validation.
"""

from __future__ import annotations

import csv
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import InputError
from .columns import NUMERIC_COLUMNS, check_unique_names
from .csv import _EXTRA_FIELD, _first_data_fields
from .formats import detect_format, read_table


def iter_batches(path: Path, fmt: str | None, columns: list[str] | None = None,
                 batch_rows: int = 250_000) -> Iterator[pd.DataFrame]:
    """Yield the raw table of ``path`` in consecutive row batches (source column names).

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
    """
    f = detect_format(path, fmt)
    if f == "csv":
        import pyarrow as pa
        import pyarrow.csv as pacsv

        header = _csv_header_names(path)
        check_unique_names([c.strip() for c in header], str(path))
        types = {c: pa.float64() for c in header if c.strip() in NUMERIC_COLUMNS}
        avg = max(16, path.stat().st_size // max(1, _count_lines_estimate(path)))
        block = int(min(max(avg * batch_rows, 1 << 20), 1 << 30))
        # A logger that ends every row with the delimiter: read the empty extra field under a
        # name of its own, check it stays empty, drop it (as read_log does).
        extra = _trailing_field(path, len(header))
        names = header + ([_EXTRA_FIELD] if extra else [])
        ro = pacsv.ReadOptions(block_size=block, column_names=names, skip_rows=1)
        keep = None if columns is None else list(columns) + ([_EXTRA_FIELD] if extra else [])
        co = pacsv.ConvertOptions(column_types=types, include_columns=keep)
        try:
            reader = pacsv.open_csv(path, read_options=ro, convert_options=co)
            for rb in reader:
                df = rb.to_pandas()
                if extra:
                    bad = df[_EXTRA_FIELD].notna().to_numpy()
                    if bad.any():
                        raise InputError(
                            f"{path}: a row has a value after the last column of the header"
                            f" (data row {int(np.flatnonzero(bad)[0]) + 1} of a chunk); fix"
                            " the row, or run without --chunk-rows for the exact line")
                    df = df.drop(columns=_EXTRA_FIELD)
                df.columns = [str(c).strip() for c in df.columns]
                yield df
        except pa.ArrowInvalid as exc:
            msg = str(exc).strip().splitlines()[0]
            raise InputError(f"{path}: cannot read as CSV ({msg}); fix the value or run"
                             " without --chunk-rows for the exact line") from None
    elif f == "parquet":
        import pyarrow.parquet as pq

        pf = pq.ParquetFile(path)
        for rb in pf.iter_batches(batch_size=batch_rows, columns=columns):
            yield rb.to_pandas()
    else:
        df = read_table(path, f)
        if columns is not None:
            df = df[[c for c in columns if c in df.columns]]
        for a in range(0, len(df), batch_rows):
            yield df.iloc[a:a + batch_rows].reset_index(drop=True)


def _trailing_field(path: Path, n_header: int) -> bool:
    """Whether the first data row has one field more than the header, and it is empty."""
    first = _first_data_fields(path, 1)
    return first is not None and len(first[0]) == n_header + 1 and not first[0][-1].strip()


def _csv_header_names(path: Path) -> list[str]:
    with open(path, encoding="utf-8", errors="replace") as fh:
        first = fh.readline()
    if not first.strip():
        raise InputError(f"{path}: the file is empty; expected a CSV log with a header row")
    return [c.strip() for c in next(csv.reader([first]))]


def _count_lines_estimate(path: Path) -> int:
    with open(path, "rb") as fh:
        head = fh.read(1 << 20)
    n = head.count(b"\n")
    size = path.stat().st_size
    return max(1, int(n * size / max(1, len(head))))
