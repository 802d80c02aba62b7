"""Where the data rows of a table are in its file, to name the line of a bad value."""

from __future__ import annotations

import bisect
import os
from collections.abc import Iterator, Mapping, Sequence
from typing import Any

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


def shift_rows(rows: Mapping[str, Any] | None, offset: int) -> dict[str, Any] | None:
    """The row description of a batch that starts at data row ``offset`` of ``rows``."""
    if rows is None:
        return None
    out = dict(rows)
    out["offset"] = int(rows.get("offset", 0)) + int(offset)
    return out


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
    if rows is not None:
        i += int(rows.get("offset", 0))
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


def text_lines(path: str | os.PathLike[str]) -> Iterator[tuple[int, str]]:
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
        for ln, text in text_lines(path):
            if ln <= header_line or not text.strip():
                continue
            k += 1
            if k == i:
                return ln
    except OSError:
        return None
    return None
