"""Reading a compensated log for the report: only its columns, with a low peak.

:func:`read_columns` reads a plain CSV with pyarrow straight into numpy arrays
(:func:`_read_csv_fast`) and everything else (or anything that reader is not sure of) in
validated row batches (:func:`_read_batches`); both give the same frame.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import InputError
from ..io.stream import iter_log_batches

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
    if src.suffix.lower() == ".csv":
        try:
            data = _read_csv_fast(src)
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


class _NotPlain(Exception):
    """The fast reader declines a file (the validating reader then reads it)."""


#: Block of the fast CSV reader [bytes]: pyarrow's transient memory grows with it (1 MB:
#: ~50 MB above the columns on a 2e6-row log; 4 MB: ~170 MB) while larger blocks are no faster.
_FAST_BLOCK = 1 << 20


def _read_csv_fast(src: Path) -> pd.DataFrame | None:
    """The report's columns of a plain CSV, parsed by pyarrow straight into numpy arrays.

    No pandas frame per batch and no per-batch validation: each float column is written into
    one array allocated for a bound of the rows (single precision for :data:`_FLOAT32`), and
    the checks :func:`aeromag.io.read_log` makes on these columns (finite time within range,
    no infinite value, plausible line ids) run on the arrays.  Any doubt raises
    :class:`_NotPlain`, and the validating reader reads the file and words the error.
    """
    import pyarrow as pa
    import pyarrow.csv as pacsv

    from ..io.columns import MAX_ID, NUMERIC_COLUMNS
    from ..io.log import MAX_TIME_S
    from ..io.messages import check_input_file
    from ..io.outputs import register_input

    check_input_file(src)
    with open(src, "rb") as fh:
        head = fh.readline(1 << 16)
        first = fh.readline(1 << 16)
        sample = fh.read(1 << 16).split(b"\n")[:-1]
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
    floats: dict[str, np.ndarray] = {}
    parts: dict[str, list[np.ndarray]] = {c: [] for c in want}
    n = 0
    try:
        reader = pacsv.open_csv(
            src, read_options=pacsv.ReadOptions(block_size=_FAST_BLOCK),
            convert_options=pacsv.ConvertOptions(column_types=types, include_columns=want,
                                                 strings_can_be_null=True))
        for rb in reader:
            k = rb.num_rows
            if n + k > cap:
                raise _NotPlain("more rows than lines")
            for j, c in enumerate(want):
                col = rb.column(j)
                typ = col.type
                if pa.types.is_floating(typ):
                    x = col.to_numpy(zero_copy_only=False)
                    if np.isinf(x).any():
                        raise _NotPlain(f"infinite value in {c}")
                    if c not in floats:
                        if n:
                            raise _NotPlain(f"{c} changed type")
                        floats[c] = np.empty(cap, dtype=np.float32 if c in _FLOAT32
                                             else np.float64)
                        del parts[c]
                    floats[c][n:n + k] = x
                elif (pa.types.is_integer(typ) or pa.types.is_boolean(typ)) \
                        and col.null_count == 0 and c in parts:
                    parts[c].append(col.to_numpy(zero_copy_only=False))
                else:
                    raise _NotPlain(f"column {c} of type {typ}")
            n += k
    except (pa.ArrowInvalid, UnicodeDecodeError, ValueError, OSError) as exc:
        raise _NotPlain(str(exc).splitlines()[0] if str(exc) else type(exc).__name__) from None
    finally:
        _release_arrow_memory()
    if not n:
        raise _NotPlain("no rows")
    t = floats.get("time")
    if t is None:
        raise _NotPlain("time is not a float column")
    t = t[:n]
    if not (np.isfinite(t).all() and (np.abs(t) <= MAX_TIME_S).all()):
        raise _NotPlain("time not finite or out of range")
    if "line" in floats:
        ln = floats["line"][:n]
        if (np.abs(ln[np.isfinite(ln)]) > MAX_ID).any():
            raise _NotPlain("line id out of range")
    register_input(src, "input log")
    return _frame(src, want, n, floats, parts)


def _read_batches(src: Path) -> pd.DataFrame:
    """The columns of a compensated log the report uses, read in validated row batches.

    Only :data:`_COLUMNS` are read.  Float columns are written batch by batch into arrays
    allocated once for an upper bound of the rows (no list of batches, no concatenation:
    the peak is the columns themselves plus one small batch); the others are joined at the
    end.
    """
    cap = _row_capacity(src)
    floats: dict[str, np.ndarray] = {}
    parts: dict[str, list[np.ndarray]] = {}
    n = 0
    order: list[str] = []
    for b in iter_log_batches(src, None, columns=list(_COLUMNS), batch_rows=_BATCH_ROWS):
        k = len(b)
        if not order:
            order = list(b.columns)
        if n + k > cap:  # the bound was too small (not expected): grow
            cap = max(2 * cap, n + k)
            floats = {c: np.resize(x, cap) for c, x in floats.items()}
        for c in b.columns:
            x = b[c].to_numpy()
            if c not in floats and c not in parts:
                if x.dtype.kind == "f" and n == 0:
                    dt = np.float32 if c in _FLOAT32 else np.float64
                    floats[c] = np.empty(cap, dtype=dt)
                else:
                    parts[c] = []
            if c in floats:
                floats[c][n:n + k] = x
            else:
                parts[c].append(x)
        n += k
    _release_arrow_memory()
    if not n:
        raise InputError(f"{src}: no rows")
    return _frame(src, order, n, floats, parts)


def _frame(src: Path, order: list[str], n: int, floats: dict[str, np.ndarray],
           parts: dict[str, list[np.ndarray]]) -> pd.DataFrame:
    """The table of the columns in ``order``: float arrays cut to ``n`` rows, others joined.

    The arrays are handed over (popped), so the frame holds the only reference to each.
    """
    cols: dict[str, np.ndarray] = {}
    for c in order:
        if c in floats:
            cols[c] = floats.pop(c)[:n]
        else:
            chunks = parts.pop(c)
            cols[c] = chunks[0] if len(chunks) == 1 else np.concatenate(chunks)
    data = pd.DataFrame(cols, copy=False)
    data.attrs["source"] = str(src)
    return data


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


def _release_arrow_memory() -> None:
    """Give pyarrow's freed reading buffers back to the system."""
    try:
        import pyarrow as pa

        pa.default_memory_pool().release_unused()
    except (ImportError, AttributeError):  # pragma: no cover - older pyarrow
        pass
