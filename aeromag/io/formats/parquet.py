"""Parquet logs (pyarrow)."""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from ...errors import InputError
from ..messages import clean
from ..outputs import atomic_path
from ..rows import ROWS_ATTR, rows_numbered

log = logging.getLogger(__name__)

#: Rows per row group written (pyarrow's default largest row group).
ROW_GROUP = 1024 * 1024

def read_parquet(path: Path, usecols: Sequence[str] | None = None) -> pd.DataFrame:
    """Read a Parquet file; a named pandas index (``df.set_index("time")``) becomes a column.

    Types are kept; a datetime ``time`` is turned into seconds by :func:`aeromag.io.read_log`.
    ``usecols``: read only these columns (those the file lacks are ignored); the others are
    not read at all.
    """
    try:
        import pyarrow.parquet as pq
    except ImportError:  # pragma: no cover - pyarrow is a test dependency
        raise InputError(
            f"{path}: reading Parquet needs pyarrow: pip install 'aeromag[parquet]'") from None
    try:
        schema = pq.read_schema(path)
    except Exception as exc:  # noqa: BLE001 - any pyarrow failure is a bad file
        raise InputError(parquet_error(path, exc)) from None
    check_flat_schema(path, schema)  # before reading: a name used twice fails the read
    try:
        names = None if usecols is None else [n for n in schema.names if n in set(usecols)]
        # pre_buffer=False: no copy of the whole file's bytes ahead of decoding (pyarrow's
        # default, meant for object stores: 1e7 samples read 1.6x faster with 0.6 GB less)
        table = pq.read_table(path, columns=names, page_checksum_verification=True,
                              pre_buffer=False)
    except Exception as exc:  # noqa: BLE001 - any pyarrow failure is a bad file
        raise InputError(parquet_error(path, exc)) from None
    try:
        # one block per column, each Arrow column freed as it is converted: the peak is the
        # table's size plus a column, not twice (or, consolidating, three times) the table
        df = table.to_pandas(split_blocks=True, self_destruct=True)
        del table
    except Exception as exc:  # noqa: BLE001 - any pyarrow failure is a bad file
        raise InputError(parquet_error(path, exc)) from None
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


def check_flat_schema(path: str | os.PathLike[str], schema: object) -> None:
    """Refuse a Parquet schema with a nested column (list, struct, map) or a name used twice.

    A log is a flat table: a nested cell has no CSV form that keeps its values (the in-memory
    and the chunked paths would otherwise write it differently, or not at all).

    Parameters
    ----------
    path : path-like
        The file, for the message.
    schema : pyarrow.Schema
        Its Arrow schema.
    """
    import pyarrow as pa

    seen: set[str] = set()
    for field in schema:  # type: ignore[attr-defined]
        if field.name in seen:
            raise InputError(f"{clean(path)}: column {clean(field.name)!r} appears more than"
                             " once; rename the copies so that each column has its own name")
        seen.add(field.name)
        t = field.type
        if pa.types.is_dictionary(t):
            t = t.value_type
        if pa.types.is_nested(t):
            raise InputError(
                f"{clean(path)}: column {clean(field.name)!r} is nested ({clean(t)}), not one"
                " value per row; flatten it into plain columns (or drop it) before aeromag"
                " reads the log")


def parquet_error(path: str | os.PathLike[str], exc: BaseException) -> str:
    """The one-line error for a Parquet file pyarrow cannot read."""
    msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return (f"{clean(path)}: cannot read as Parquet ({clean(msg)[:200]}); is it a Parquet file,"
            " complete and undamaged?")


def write_parquet(df: pd.DataFrame, path: str | os.PathLike[str]) -> Path:
    """Write a table as Parquet atomically (index not written).

    Parameters
    ----------
    df : DataFrame
        The table.
    path : path-like
        Destination.

    Returns
    -------
    Path
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    p = Path(path)
    # Converted and written one row group at a time (pyarrow's default row-group length):
    # the same file as one write of the whole table, without a second copy of the table.
    schema = pa.Schema.from_pandas(df, preserve_index=False)
    with atomic_path(p) as tmp, pq.ParquetWriter(tmp, schema, write_page_checksum=True) as w:
        for a in range(0, max(len(df), 1), ROW_GROUP):
            w.write_table(pa.Table.from_pandas(df.iloc[a:a + ROW_GROUP], schema=schema,
                                               preserve_index=False))
    return p
