"""Parsing a plain CSV log in two halves at once, for the report's reader.

pyarrow's streaming CSV reader parses on one core; a log of :data:`_SPLIT_MIN_BYTES` and more
is parsed as two byte ranges, the second on a thread (:class:`_SecondHalf`), both writing
into the same preallocated columns (:func:`_fill`).  Used by
:mod:`aeromag.workflows._report_read`; the thread only parses (everything it uses is
imported before it starts).
"""

from __future__ import annotations

import io
import os
import threading
from pathlib import Path
from typing import Any

import numpy as np

__all__: list[str] = []


class _NotPlain(Exception):
    """The fast reader declines a file (the validating reader then reads it)."""


#: Block of the fast CSV reader [bytes]: pyarrow's transient memory grows with it (on a
#: 2e6-row log with the system pool, peak above the end of the read: 512 kB ~52 MB, 1 MB
#: ~70 MB; 4 MB: ~170 MB with mimalloc) while larger blocks are no faster.
_FAST_BLOCK = 1 << 19


def _fits_int32(x: np.ndarray) -> bool:
    """Whether every value of the integer array ``x`` fits in int32."""
    i = np.iinfo(np.int32)
    return (x.dtype.kind == "i" and x.dtype.itemsize <= 4) \
        or bool(x.min() >= i.min and x.max() <= i.max)


#: Logs at least this large are parsed in two halves on two threads when two cores are
#: free: pyarrow's streaming CSV reader parses on one core (4.5 s for 636 MB here), and
#: the two halves write into the same preallocated columns.
_SPLIT_MIN_BYTES = 32 << 20


def _cores() -> int:
    """Cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def _split_point(src: Path, data_start: int) -> int | None:
    """The byte offset of the first row of the log's second half, or None (one reader).

    The first line break after the middle of the data; None for a small log, a single
    core, or no line break in the 64 kB after the middle.
    """
    size = src.stat().st_size
    if size - data_start < _SPLIT_MIN_BYTES or _cores() < 2:
        return None
    mid = data_start + (size - data_start) // 2
    with open(src, "rb") as fh:
        fh.seek(mid)
        i = fh.read(1 << 16).find(b"\n")
    if i < 0 or mid + i + 1 >= size:
        return None
    return mid + i + 1


class _ByteRange(io.RawIOBase):
    """Bytes ``[start, stop)`` of a file as a readable stream (``stop`` None: to the end)."""

    def __init__(self, path: Path, start: int, stop: int | None) -> None:
        super().__init__()
        self._fh = open(path, "rb")  # noqa: SIM115 - closed by close()
        self._fh.seek(start)
        self._left = None if stop is None else stop - start

    def readable(self) -> bool:
        return True

    def readinto(self, buf: Any) -> int:
        view = memoryview(buf).cast("B")
        k = len(view) if self._left is None else min(len(view), self._left)
        if k <= 0:
            return 0
        got = self._fh.readinto(view[:k]) or 0
        if self._left is not None:
            self._left -= got
        return got

    def close(self) -> None:
        self._fh.close()
        super().close()


def _count_lines(src: Path, start: int, stop: int) -> int:
    """Line breaks in bytes ``[start, stop)`` of ``src`` (read in 4 MB pieces)."""
    buf = bytearray(4 << 20)
    n = 0
    with open(src, "rb") as fh:
        fh.seek(start)
        left = stop - start
        while left > 0:
            got = fh.readinto(memoryview(buf)[:min(len(buf), left)])
            if not got:
                break
            n += buf.count(b"\n", 0, got)
            left -= got
    return n


#: Why a half stops when the other failed.
_STOPPED = "the other half of the log was not plain"


class _Widen(_NotPlain):
    """An ``int32`` column (:data:`_INT32`) holds a value beyond it: read again as int64."""


def _fill(reader: Any, want: list[str], store: Any, row0: int,
          stop: threading.Event | None) -> int:
    """Write the batches of ``reader`` into ``store``'s arrays from row ``row0``; rows read.

    ``stop`` set (the other half failed) ends the read with :class:`_NotPlain`.
    """
    import pyarrow as pa

    n = row0
    arrays = [store.arrays[c] for c in want]
    for rb in reader:
        if stop is not None and stop.is_set():
            raise _NotPlain(_STOPPED)
        k = rb.num_rows
        if n + k > store.cap:
            raise _NotPlain("more rows than lines")
        for j, (c, a) in enumerate(zip(want, arrays, strict=True)):
            col = rb.column(j)
            typ = col.type
            if pa.types.is_floating(typ):
                x = col.to_numpy(zero_copy_only=False)
                if np.isinf(x).any():
                    raise _NotPlain(f"infinite value in {c}")
            elif (pa.types.is_integer(typ) or pa.types.is_boolean(typ)) \
                    and col.null_count == 0:
                x = col.to_numpy(zero_copy_only=False)
                if a.dtype == np.int32 and k and not _fits_int32(x):
                    raise _Widen(c)
            else:
                raise _NotPlain(f"column {c} of type {typ}")
            a[n:n + k] = x
        n += k
    return n - row0


class _SecondHalf:
    """Parse bytes ``[split, end)`` of a log on a thread into ``store`` (see :func:`_fill`).

    The rows of the first half are counted first (its line breaks), so the second half's
    rows go straight to their place; :meth:`check` refuses the read (:class:`_NotPlain`)
    when the first half parsed another number of rows (blank lines, quoted line breaks).
    The thread only parses: everything it uses is imported before it starts.
    """

    def __init__(self, src: Path, data_start: int, split: int, header: list[str],
                 want: list[str], types: dict[str, Any], store: Any) -> None:
        import pyarrow.csv as pacsv

        self.stop = threading.Event()
        self._exc: BaseException | None = None
        self._first = self._rows = 0
        opts = (pacsv.ReadOptions(block_size=_FAST_BLOCK, column_names=header),
                pacsv.ConvertOptions(column_types=types, include_columns=want,
                                     strings_can_be_null=True))

        def run() -> None:
            try:
                self._first = _count_lines(src, data_start, split)
                with _ByteRange(src, split, None) as rest:
                    reader = pacsv.open_csv(rest, read_options=opts[0],
                                            convert_options=opts[1])
                    self._rows = _fill(reader, want, store, self._first, self.stop)
            except BaseException as exc:  # noqa: BLE001 - raised by check() on the caller
                self._exc = exc
                self.stop.set()

        self._thread = threading.Thread(target=run, name="aeromag-read-half", daemon=True)
        self._thread.start()

    def check(self, first_rows: int | None) -> int:
        """All the rows read, given the first half's; raises what the thread raised.

        Waits for the thread.  ``first_rows`` None (the first half failed): only raises
        the thread's own error, if any.
        """
        self._thread.join()
        if self._exc is not None and not (isinstance(self._exc, _NotPlain)
                                          and self._exc.args == (_STOPPED,)):
            raise self._exc
        if first_rows is None:
            return 0
        if first_rows != self._first:
            raise _NotPlain(f"{first_rows} rows parsed in the first half of the log but"
                            f" {self._first} line breaks")
        return self._first + self._rows
