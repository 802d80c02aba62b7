"""Reading a compensated log for the report: only its columns, with a low peak.

:func:`read_columns` reads a plain CSV with pyarrow straight into numpy arrays
(:func:`_read_csv_fast`) and everything else (or anything that reader is not sure of) in
validated row batches (:func:`_read_batches`); both give the same frame.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..errors import InputError
from ..io.outputs import register_input
from ..io.stream import iter_log_batches
from ._csv_halves import (
    _FAST_BLOCK,
    _ByteRange,
    _fill,
    _fits_int32,
    _NotPlain,
    _SecondHalf,
    _split_point,
    _Widen,
)

__all__ = ["read_columns"]

log = logging.getLogger(__name__)

#: Columns only drawn or used for manoeuvre detection: single precision is ample (7
#: digits: 0.005 nT of a 50000 nT fluxgate, 0.3 m of latitude), and halves their memory.
_FLOAT32 = ("flux_x", "flux_y", "flux_z", "heading", "pitch", "roll", "lat", "lon", "alt")

#: Columns the report uses (others in the log are not read).
_COLUMNS = ("time", "mag", "mag_tl", "mag_comp", "segment", "segment_kept", "line", "flux_x",
            "flux_y", "flux_z", "heading", "pitch", "roll", "lat", "lon", "alt",
            "truth_mag_tl", "maneuver")


#: Rows per batch when reading a compensated log: pyarrow's CSV reader needs tens of times
#: its block in transient memory, so small blocks (about 1 MB) keep the peak down.
_BATCH_ROWS = 4_000


def read_columns(src: Path) -> pd.DataFrame:
    """The columns of a compensated log the report uses (:data:`_COLUMNS`).

    A plain CSV (comma-separated header on its first line, numeric columns) is read by
    :func:`_read_csv_fast`; anything else, or anything that reader does not accept (a bad
    value, a truncated row, ISO times, a non-finite time ...), by :func:`_read_batches`,
    which validates every batch as :func:`aeromag.io.read_log` does and words the error.
    Both give the same frame.

    Parameters
    ----------
    src : Path
        The compensated log.

    Returns
    -------
    DataFrame
        The columns of :data:`_COLUMNS` the log has (``attrs["source"]`` names the file).
    """
    data = None
    with _system_pool():
        if src.suffix.lower() == ".csv":
            try:
                data = _read_csv_fast(src)
                register_input(src, "input log")
            except _NotPlain as exc:
                log.debug("%s: read through the validating reader (%s)", src, exc)
        if data is None:
            data = _read_batches(src)
    return _time_in_order(data, src)


def _time_in_order(data: pd.DataFrame, src: Path) -> pd.DataFrame:
    """Refuse a log whose ``time`` is not strictly increasing, as ``compensate`` does.

    The check is :func:`aeromag.io.log.read_log`'s own (exact duplicate rows dropped with a
    warning, then the row where time goes back named), so the report's error is the
    compensation's: one line naming the file, the column and the row, instead of a sampling
    rate estimated from shuffled times.
    """
    if "time" not in data.columns:
        return data
    t = data["time"].to_numpy(dtype=np.float64)
    if len(t) < 2 or bool((t[1:] > t[:-1]).all()):
        return data
    from ..io.log import clean_time
    from ..io.rows import rows_after_header, rows_numbered

    suffix = src.suffix.lower()
    rows = (rows_after_header(src, 1) if suffix == ".csv"
            else rows_numbered("row") if suffix in (".parquet", ".pq") else None)
    attrs = dict(data.attrs)
    data = clean_time(data, str(src), rows)
    data.attrs.update(attrs)
    return data


def _read_csv_fast(src: Path) -> pd.DataFrame | None:
    """The report's columns of a plain CSV (:func:`_parse_plain`).

    An :data:`_INT32` column holding a value beyond int32 is read again as int64.
    """
    wide: frozenset[str] = frozenset()
    while True:
        try:
            return _parse_plain(src, wide)
        except _Widen as exc:
            log.debug("%s: column %s beyond int32; read again as int64", src, exc.args[0])
            wide |= {exc.args[0]}


def _parse_plain(src: Path, wide: frozenset[str]) -> pd.DataFrame | None:
    """The report's columns of a plain CSV, parsed by pyarrow straight into numpy arrays.

    No pandas frame per batch and no per-batch validation: each float column is written into
    one array allocated for a bound of the rows (single precision for :data:`_FLOAT32`), and
    the checks :func:`aeromag.io.read_log` makes on these columns (finite time within range,
    no infinite value, plausible line ids) run on the arrays.  Any doubt raises
    :class:`_NotPlain`, and the validating reader reads the file and words the error.
    :data:`_INT32` columns not in ``wide`` are int32 (:class:`_Widen` if a value is beyond).

    A log of :data:`_SPLIT_MIN_BYTES` and more is parsed in two halves at once, the second
    on a thread (:class:`_SecondHalf`), when two cores are free: 2e6 rows (636 MB) in
    about half the 4.5 s of one reader here.
    """
    import pyarrow as pa
    import pyarrow.csv as pacsv

    from ..io.columns import MAX_ID, NUMERIC_COLUMNS
    from ..io.log import MAX_TIME_S
    from ..io.messages import check_input_file

    check_input_file(src)
    with open(src, "rb") as fh:
        head = fh.readline(1 << 16)
        first = fh.readline(1 << 16)
        raw = fh.read(1 << 16)
    sample = raw.split(b"\n")[:-1]
    try:
        header = head.decode("utf-8").rstrip("\r\n").split(",")
        fields = first.decode("utf-8").rstrip("\r\n").split(",")
    except UnicodeDecodeError:
        raise _NotPlain("not UTF-8") from None
    if (len(header) < 2 or len(set(header)) != len(header) or len(fields) != len(header)
            or "time" not in header or any(h != h.strip() or not h or '"' in h
                                           for h in header)):
        raise _NotPlain("not a plain comma-separated header")
    try:
        float(fields[header.index("time")])
    except ValueError:
        raise _NotPlain("time is not a number (ISO 8601 times?)") from None
    want = [c for c in header if c in _COLUMNS]
    types = {c: pa.float64() for c in want if c in NUMERIC_COLUMNS}
    # Rows bound: the data bytes over half the shortest row seen (never under a row of empty
    # fields).  Pages never written are never resident, so a generous bound costs no memory
    # (counting the newlines of a 636 MB file cost 0.4-0.7 s); a file that beats it goes to
    # the validating reader.
    shortest = min([len(first), *(len(r) + 1 for r in sample if r.strip())])
    cap = (src.stat().st_size - len(head)) // max(len(header), shortest // 2) + 1
    store = _Store(cap)
    split = None if b'"' in first + raw else _split_point(src, len(head))
    first_half = _ByteRange(src, 0, split)
    try:
        reader = pacsv.open_csv(
            first_half, read_options=pacsv.ReadOptions(block_size=_FAST_BLOCK),
            convert_options=pacsv.ConvertOptions(column_types=types, include_columns=want,
                                                 strings_can_be_null=True))
        schema = reader.schema
        for c in want:
            store.arrays[c] = np.empty(store.cap, dtype=_arrow_dtype(c, schema.field(c).type,
                                                                  wide))
        second = None
        if split is not None:
            second = _SecondHalf(src, len(head), split, header, want,
                                 {c: schema.field(c).type for c in want}, store)
        try:
            n0 = _fill(reader, want, store, 0, None if second is None else second.stop)
        except BaseException:
            if second is not None:  # stop it, and raise what stopped it, if anything did
                second.stop.set()
                second.check(None)
            raise
        if second is not None:
            n0 = second.check(n0)
        store.n = n0
    except (pa.ArrowInvalid, UnicodeDecodeError, ValueError, OSError) as exc:
        raise _NotPlain(str(exc).splitlines()[0] if str(exc) else type(exc).__name__) from None
    finally:
        first_half.close()
    n = store.n
    if not n:
        raise _NotPlain("no rows")
    t = store.arrays.get("time")
    if t is None or t.dtype != np.float64:
        raise _NotPlain("time is not a float column")
    t = t[:n]
    if not (np.isfinite(t).all() and (np.abs(t) <= MAX_TIME_S).all()):
        raise _NotPlain("time not finite or out of range")
    if "line" in store.arrays:
        ln = store.arrays["line"][:n]
        if (np.abs(ln[np.isfinite(ln)]) > MAX_ID).any():
            raise _NotPlain("line id out of range")
    del reader, second
    from .._core.libc import trim_heap

    trim_heap()  # the readers' freed blocks, before the columns are copied to their rows
    return store.frame(src, want)


def _arrow_dtype(c: str, typ: Any, wide: frozenset[str]) -> type:
    """The array type of column ``c`` parsed as Arrow type ``typ`` (:func:`_dtype_for`'s).

    :data:`_INT32` columns in ``wide`` are int64; a type :func:`_dtype_for` keeps as batch
    arrays (text, null, uint64) raises :class:`_NotPlain`.
    """
    try:
        dt = _dtype_for(c, np.dtype(typ.to_pandas_dtype()))
    except (NotImplementedError, TypeError):
        dt = None
    if dt is None:
        raise _NotPlain(f"column {c} of type {typ}")
    return np.int64 if dt is np.int32 and c in wide else dt


def _read_batches(src: Path) -> pd.DataFrame:
    """The columns of a compensated log the report uses, read in validated row batches.

    Only :data:`_COLUMNS` are read.  Float columns are written batch by batch into arrays
    allocated once for an upper bound of the rows (no list of batches, no concatenation:
    the peak is the columns themselves plus one small batch); the others are joined at the
    end.
    """
    store = _Store(_row_capacity(src))
    order: list[str] = []
    for b in iter_log_batches(src, None, columns=list(_COLUMNS), batch_rows=_BATCH_ROWS):
        if not order:
            order = list(b.columns)
        store.reserve(len(b))
        for c in b.columns:
            x = b[c].to_numpy()
            if not store.put(c, x):
                store.to_parts(c)
                store.put(c, x)
        store.n += len(b)
    if not store.n:
        raise InputError(f"{src}: no rows")
    return store.frame(src, order)


#: Float columns kept in single precision when every value is exactly a float32 (line
#: numbers: 8 MB less at 2e6 rows); otherwise float64 as read.
_LOSSLESS_FLOAT32 = ("line",)


def _narrowed(c: str, x: np.ndarray) -> np.ndarray:
    """``x`` (a float64 column) as float32 if no value changes, else a copy of ``x``."""
    if x.dtype == np.float64:
        y = x.astype(np.float32)
        if np.array_equal(y, x, equal_nan=True):
            return y
        del y
    return x.copy()


#: Integer columns stored as int32 while their values fit (``segment``: ids of a few
#: thousand; 8 MB instead of 16 at 2e6 rows; :func:`aeromag.qc.segment_labels` returns int64).
_INT32 = ("segment",)


class _Store:
    """A log's columns, written batch by batch into arrays allocated once for a row bound.

    Float columns go into float64 arrays (float32 for :data:`_FLOAT32`), integer and boolean
    columns into arrays of their kind (:data:`_INT32` as int32 while the values fit, int64
    else): no list of batch arrays and no concatenation, so the peak is the columns plus one
    batch, and no small long-lived blocks are left among the reader's transient ones in the
    C heap (they kept its freed space from being reused).  A column of another kind (object,
    nullable ...) is kept as batch arrays joined at the end.  Pages of the arrays beyond the
    rows read are never written, hence never resident.

    Parameters
    ----------
    cap : int
        Bound of the rows [rows] (grown by :meth:`reserve` if beaten).
    """

    def __init__(self, cap: int) -> None:
        self.cap = max(1, int(cap))
        self.n = 0
        self.arrays: dict[str, np.ndarray] = {}
        self.parts: dict[str, list[np.ndarray]] = {}

    def reserve(self, k: int) -> None:
        """Grow the arrays when ``k`` more rows do not fit the bound (not expected)."""
        if self.n + k > self.cap:
            self.cap = max(2 * self.cap, self.n + k)
            self.arrays = {c: _grown(x, self.n, self.cap) for c, x in self.arrays.items()}

    def put(self, c: str, x: np.ndarray) -> bool:
        """Write batch ``x`` of column ``c`` at row :attr:`n`; False when not of its kind."""
        n, k = self.n, len(x)
        if c in self.parts:
            self.parts[c].append(x)
            return True
        a = self.arrays.get(c)
        if a is None:
            dt = _dtype_for(c, x.dtype)
            if dt is None or n:
                self.parts[c] = [x]
                return True
            a = self.arrays[c] = np.empty(self.cap, dtype=dt)
        elif a.dtype.kind != "f" and x.dtype.kind != a.dtype.kind \
                and not (a.dtype.kind == "i" and x.dtype.kind == "u"):
            return False
        if a.dtype == np.int32 and k and not _fits_int32(x):
            a = self.arrays[c] = _grown(a, n, self.cap, np.int64)
        a[n:n + k] = x
        return True

    def to_parts(self, c: str) -> None:
        """Keep column ``c`` as batch arrays from now on (a batch of another kind came)."""
        self.parts[c] = [self.arrays.pop(c)[:self.n].copy()]

    def frame(self, src: Path, order: list[str]) -> pd.DataFrame:
        """The table of the columns in ``order`` (``attrs["source"]`` names the file).

        The arrays are handed over (popped), so the frame holds the only reference to each.
        An array allocated for more rows than were read is copied to its rows, one column at
        a time: numpy asks for transparent huge pages on large arrays, so the 2 MB page
        holding the last row read was resident in full, about 1 MB a column beyond the data
        (2e6 rows, 17 columns: 20 MiB less resident for the rest of the report).
        """
        cols: dict[str, np.ndarray] = {}
        for c in order:
            if c in self.arrays:
                a = self.arrays.pop(c)
                cols[c] = _narrowed(c, a[:self.n]) if c in _LOSSLESS_FLOAT32 \
                    else a[:self.n].copy() if len(a) > self.n else a
                del a
            else:
                chunks = self.parts.pop(c)
                cols[c] = chunks[0] if len(chunks) == 1 else np.concatenate(chunks)
        data = pd.DataFrame(cols, copy=False)
        data.attrs["source"] = str(src)
        return data


def _dtype_for(c: str, dt: np.dtype) -> type | None:
    """The array type column ``c`` is stored in, from its first batch's (None: batch list)."""
    if dt.kind == "f":
        return np.float32 if c in _FLOAT32 else np.float64
    if dt.kind == "i" or (dt.kind == "u" and dt.itemsize < 8):
        return np.int32 if c in _INT32 else np.int64
    if dt.kind == "b":
        return np.bool_
    return None


def _grown(x: np.ndarray, n: int, cap: int, dtype: type | None = None) -> np.ndarray:
    """A new array of ``cap`` rows (of ``dtype``, default ``x``'s) starting with ``x[:n]``."""
    out = np.empty(cap, dtype=dtype or x.dtype)
    out[:n] = x[:n]
    return out


def _row_capacity(src: Path) -> int:
    """An upper bound of the data rows of a log: Parquet's row count, else newlines + 1."""
    if src.suffix.lower() in (".parquet", ".pq"):
        try:
            import pyarrow.parquet as pq

            return max(1, int(pq.ParquetFile(src).metadata.num_rows))
        except Exception:  # noqa: BLE001 - the reader reports a bad file in its own words
            return 1 << 16
    n = 1
    try:
        with open(src, "rb") as fh:
            while chunk := fh.read(1 << 23):
                n += chunk.count(b"\n")
    except OSError:
        return 1 << 16
    return n


@contextmanager
def _system_pool() -> Iterator[None]:
    """Read with pyarrow's system (C heap) memory pool, then give the freed memory back.

    pyarrow's default pool (mimalloc) kept ~33 MB of the reader's freed blocks resident
    after the read of a 2e6-row log, whatever ``release_unused`` asked; the C heap's free
    pages are returned by ``malloc_trim`` (:func:`aeromag._core.libc.trim_heap`).  The
    previous default pool is restored afterwards (the frame holds no pyarrow memory).
    """
    try:
        import pyarrow as pa
    except ImportError:  # pragma: no cover - pyarrow is a dependency
        yield
        return
    from .._core.libc import trim_heap

    before = pa.default_memory_pool()
    pool = pa.system_memory_pool()
    pa.set_memory_pool(pool)
    try:
        yield
    finally:
        pa.set_memory_pool(before)
        pool.release_unused()
        before.release_unused()
        trim_heap()
