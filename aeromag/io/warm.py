"""Overlap the command line's start-up with reading the log.

``pandas`` and ``scipy.signal`` take about a second to import, scikit-learn more.  The
command line first starts parsing the CSV on a thread with pyarrow alone
(:func:`prefetch_csv`; the parser releases the GIL), then imports the pipeline on the main
thread while it parses.  Library code never depends on this: :func:`aeromag.io.read_log`
takes a prefetched table only for the very same, unchanged file.

Imports themselves all happen on the calling thread: the prefetch thread only parses
(``pyarrow`` and ``numpy`` are imported before it starts).  Two threads importing the same
package at once can hand one of them a partially initialised module (seen with scikit-learn
on a cold bytecode cache), so nothing here imports in the background.

This module imports nothing heavy at import time.
"""

from __future__ import annotations

import logging
import os
import threading
from concurrent.futures import Future
from typing import Any

log = logging.getLogger(__name__)


#: Bytes of CSV text parsed per block by the streaming reader.
READ_BLOCK_BYTES = 4 << 20

_prefetched: dict[str, tuple[tuple[int, int], Future]] = {}
_lock = threading.Lock()


def read_csv_table(path: str | os.PathLike[str], block_bytes: int | None = None) -> Any:
    """Read a CSV into a pyarrow Table with the streaming reader, or None when it cannot.

    As fast as ``pyarrow.csv.read_csv`` here, with about half its peak memory (the whole text
    is never held: at 1e6 rows 190 MB against 330 MB).  Column types come from the first
    block; a later block that does not fit them (an integer column with a decimal further
    down, text after empty cells) returns None, and the caller reads the file whole.

    Parameters
    ----------
    path : path-like
        CSV file.
    block_bytes : int, optional
        Bytes parsed per block (default :data:`READ_BLOCK_BYTES`).

    Returns
    -------
    pyarrow.Table, dict or None
        A table, or for files of :data:`COLUMNS_MIN_BYTES` and more the ``{column: ndarray}``
        of :func:`read_csv_columns`.
    """
    import pyarrow as pa
    import pyarrow.csv as pacsv

    try:
        if os.path.getsize(path) >= COLUMNS_MIN_BYTES:
            cols = read_csv_columns(path, block_bytes)
            if cols is not None:
                return cols
        reader = pacsv.open_csv(os.fspath(path), read_options=pacsv.ReadOptions(
            block_size=int(block_bytes or READ_BLOCK_BYTES)))
        return pa.Table.from_batches(list(reader), schema=reader.schema)
    except (pa.ArrowInvalid, UnicodeDecodeError, ValueError, StopIteration, OSError):
        return None


#: Files at least this large are read straight into numpy columns (see
#: :func:`read_csv_columns`); smaller ones through an Arrow table, which is faster there.
COLUMNS_MIN_BYTES = 256 << 20


def read_csv_columns(path: str | os.PathLike[str], block_bytes: int | None = None
                     ) -> dict[str, Any] | None:
    """Read an all-numeric CSV straight into numpy columns, block by block.

    Each parsed block is copied into preallocated float64 / int64 / bool arrays and dropped,
    so the peak is the columns plus one block: at 1e7 rows 0.84 GB against 1.49 GB through an
    Arrow table and ``to_pandas``.  (Untouched room at the end of the arrays, from a
    generous row estimate, is never resident.)

    Parameters
    ----------
    path : path-like
        CSV file.
    block_bytes : int, optional
        Bytes parsed per block.

    Returns
    -------
    dict or None
        ``{column: ndarray}`` in file order; None when a column is not numeric or boolean,
        an integer or boolean column has an empty cell, or a block does not fit the types of
        the first (the caller then reads another way).
    """
    import numpy as np
    import pyarrow as pa
    import pyarrow.csv as pacsv

    size = os.path.getsize(path)
    block = int(block_bytes or READ_BLOCK_BYTES)
    reader = pacsv.open_csv(os.fspath(path), read_options=pacsv.ReadOptions(block_size=block))
    kinds = []
    for f in reader.schema:
        if pa.types.is_floating(f.type):
            kinds.append(np.float64)
        elif pa.types.is_integer(f.type):
            kinds.append(np.int64)
        elif pa.types.is_boolean(f.type):
            kinds.append(np.bool_)
        else:
            return None
    names = reader.schema.names
    cols: list[Any] | None = None
    n = 0
    for batch in reader:
        k = batch.num_rows
        if cols is None:
            est = int(size / max(block, 1) * 1.1 * max(k, 1)) + 1024
            cols = [np.empty(est, dtype=kd) for kd in kinds]
        if n + k > len(cols[0]):  # the estimate was short: grow (rare)
            cols = [np.concatenate([c[:n], np.empty(max(n, k), dtype=c.dtype)]) for c in cols]
        for j, (kd, col) in enumerate(zip(kinds, batch.columns, strict=True)):
            if col.null_count and kd is not np.float64:
                return None
            cols[j][n:n + k] = col.to_numpy(zero_copy_only=False)
        n += k
    if cols is None:
        return None
    return {name: c[:n] for name, c in zip(names, cols, strict=True)}


def _stamp(path: str) -> tuple[int, int]:
    st = os.stat(path)
    return st.st_size, st.st_mtime_ns


def prefetch_csv(path: str | os.PathLike[str]) -> None:
    """Start reading a CSV log on a daemon thread (see :func:`take_prefetched`).

    Parameters
    ----------
    path : path-like
        The log; nothing happens when it is not a readable ``.csv`` file.
    """
    key = os.path.abspath(os.fspath(path))
    if not key.lower().endswith(".csv") or not os.path.isfile(key):
        return
    try:
        stamp = _stamp(key)
    except OSError:
        return
    # Everything the parsing thread uses is imported here, on the calling thread (see above).
    import numpy  # noqa: F401
    import pyarrow  # noqa: F401
    import pyarrow.csv  # noqa: F401

    fut: Future = Future()

    def run() -> None:
        try:
            fut.set_result(read_csv_table(key))
        except BaseException as exc:  # noqa: BLE001 - handed to whoever takes it
            fut.set_exception(exc)

    with _lock:
        _prefetched[key] = (stamp, fut)
    threading.Thread(target=run, name="aeromag-prefetch", daemon=True).start()


def take_prefetched(path: str | os.PathLike[str]) -> Any:
    """The table prefetched for ``path`` (waiting for it), or None.

    None when nothing was prefetched, when the file changed since (size or modification
    time), or when the prefetch could not read it; each prefetch is taken once.

    Parameters
    ----------
    path : path-like
        The log.

    Returns
    -------
    pyarrow.Table or None
    """
    key = os.path.abspath(os.fspath(path))
    with _lock:
        entry = _prefetched.pop(key, None)
    if entry is None:
        return None
    stamp, fut = entry
    try:
        table = fut.result()
        return table if _stamp(key) == stamp else None
    except Exception:  # noqa: BLE001 - the caller reads the file itself and reports
        return None
