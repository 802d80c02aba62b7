"""Geosoft XYZ: reading and writing, line headers included."""

from __future__ import annotations

import io as _io
import logging
import os
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from ...errors import InputError
from ..columns import (
    check_unique_names,
)
from ..csv import check_text_file, not_utf8_message
from ..csv_write import check_no_binary
from ..messages import clean
from ..outputs import atomic_path, display_path
from ..rows import ROWS_ATTR, row_location, rows_in_runs

log = logging.getLogger(__name__)

_MISSING_XYZ = "*"


XYZ_LINE_TYPES: tuple[str, ...] = ("line", "tie", "trend", "base", "test", "random", "special")
_XYZ_LINE_LETTERS: dict[str, str] = {"l": "line", "t": "tie", "b": "base", "s": "test",
                                     "r": "trend", "d": "random", "p": "special"}

#: A line header: ``Line 10``, ``LINE 10.1`` (number.version), ``Line 10:16`` (:flight),
#: ``Tie 100``, ``Trend 5``, ``Base 1``, ``Test 2``, ``Random 3``, ``Special 4`` (any case), a
#: compact line name ``L1010.1`` / ``T100``, or ``Line *`` (rows without a line id).
XYZ_LINE_HEADER = re.compile(
    r"^(?:(?P<word>line|tie|trend|base|test|random|special)\s+(?P<num>-?\d+|\*)"
    r"|(?P<letter>[ltbsrdp])(?P<cnum>\d+))"
    r"(?:\.(?P<ver>\d+))?(?::(?P<flt>\d+))?$",
    re.IGNORECASE,
)

#: Geosoft's dummy (missing) value of floating-point channels, when written as a number.
GEOSOFT_DUMMY = -1.0e32

#: Unit words: a ``/`` line made only of these is a units row, never the channel names.
_UNIT_WORDS = frozenset({
    "-", "s", "sec", "ms", "us", "m", "km", "ft", "deg", "degrees", "rad", "nt", "ut",
    "\u00b5t", "\u03bct", "pt", "mt", "g", "mg", "gauss", "nt/m", "m/s", "m/s2", "m/s^2",
    "deg/s", "kpa", "hpa", "pa", "a", "v", "hz", "c", "degc", "%", "none", "counts",
})

_NAME_TOKEN = re.compile(r"^[A-Za-z_][^\s]*$")


def _line_key(m: re.Match[str]) -> tuple[str, int, int, int | None] | None:
    """(type, number, version, flight) of a line header; None for ``Line *``."""
    if m.group("word"):
        kind, num = m.group("word").lower(), m.group("num")
    else:
        kind, num = _XYZ_LINE_LETTERS[m.group("letter").lower()], m.group("cnum")
    if num == "*":
        return None
    flight = m.group("flt")
    return kind, int(num), int(m.group("ver") or 0), int(flight) if flight else None


def _line_ids(keys: Sequence[tuple[str, int, int, int | None] | None]
              ) -> tuple[dict[tuple[str, int, int, int | None], int], bool]:
    """Integer ids of the line labels of a file; also whether some label lost its number.

    A flight line keeps its number; then the other types (tie, trend, ...) keep theirs, in file
    order, while it is free.  A label whose number is taken (``Tie 100`` beside ``Line 100``,
    ``L1010.2`` beside ``L1010.1``, the same line on another flight) gets ``B + 1``, ``B + 2``,
    ... in file order, ``B`` being the smallest power of ten above every number in the file,
    so that such ids never collide with, nor pass for, a line number of the file.
    """
    order = list(dict.fromkeys(k for k in keys if k is not None))
    ids: dict[tuple[str, int, int, int | None], int] = {}
    taken: set[int] = set()
    for lines_first in (True, False):
        for k in order:
            if k in ids or (k[0] == "line") != lines_first:
                continue
            if k[1] not in taken:
                ids[k] = k[1]
                taken.add(k[1])
    rest = [k for k in order if k not in ids]
    if rest:
        top = max(abs(k[1]) for k in order)
        base = 10 ** len(str(top))
        if base + len(rest) >= 2**63:  # keep ids int64: just above every number instead
            base = top + 1
        for j, k in enumerate(rest, start=1):
            ids[k] = base + j
    return ids, bool(rest)


def _xyz_channel_names(p: Path, comments: Sequence[tuple[int, str]], n_values: int,
                       where: str) -> list[str]:
    """Pick the channel-name line among the ``/`` lines before the data.

    ``//`` lines (Oasis ``//Flight 1``, ``//Date ...``) and underlines (``/=====``) are never
    names; among the others, the line with as many names as the first data row has values is
    taken, preferring one made of name-like words and never a units row (``/ s deg m nT``)
    after such a line; of several, the last one before the data.  ``n_values`` is the number
    of values most data rows have, ``where`` the first such row (for the message).
    """
    cands: list[tuple[int, list[str]]] = []
    for ln, text in comments:
        if text.startswith("//"):
            continue
        tokens = text[1:].split()
        if not tokens or all(set(t) <= set("=-_*~+#") for t in tokens):
            continue
        cands.append((ln, tokens))
    if not cands:
        raise InputError(f"{p}: no channel-name line ('/ name1 name2 ...') before the data")
    fit = [(ln, t) for ln, t in cands if len(t) == n_values]
    # A units row follows the names it annotates: one after another fitting line is skipped.
    fit = [(ln, t) for k, (ln, t) in enumerate(fit)
           if k == 0 or not all(x.lower() in _UNIT_WORDS or x[:1] in "[(" for x in t)]
    named = [(ln, t) for ln, t in fit if all(_NAME_TOKEN.match(x) for x in t)]
    pick = named or fit
    if not pick:
        ln, t = cands[-1]
        raise InputError(
            f"{p}: {where}: {n_values} values, but no '/' line before the data names"
            f" {n_values} channels (line {ln} names {len(t)}: {' '.join(t[:8])}"
            f"{' ...' if len(t) > 8 else ''}); every data row needs one value per channel")
    return pick[-1][1]


def _xyz_field_counts(blob: bytes) -> np.ndarray:
    """Blank-separated fields on each line of ``blob`` (lines stripped, ``\\n``-joined).

    Vectorised: a field starts at a byte that is neither a blank (space, tab: the parser's
    separators) nor a newline, after one that is.
    """
    raw = np.frombuffer(blob, dtype=np.uint8)
    nl = raw == 10
    gap = raw == 32
    gap |= raw == 9
    gap |= nl
    start = np.empty_like(gap)
    start[0] = not gap[0]
    np.logical_not(gap[1:], out=start[1:])
    start[1:] &= gap[:-1]
    line_starts = np.empty(int(nl.sum()) + 1, dtype=np.int64)
    line_starts[0] = 0
    line_starts[1:] = np.flatnonzero(nl) + 1
    return np.add.reduceat(start.view(np.uint8), line_starts, dtype=np.int64)


#: Largest line, version or flight number accepted in a line header (ids stay int64).
MAX_LINE_NUMBER = 2**62


def read_xyz(path: str | os.PathLike[str], *, allow_truncated: bool = False) -> pd.DataFrame:
    """Read a Geosoft XYZ file (line-based ASCII).

    ``/`` lines are comments.  The channel names are on the ``/`` line before the data whose
    word count matches the values of the data rows (``//`` lines, ``/====`` underlines and
    units rows are never names; see :func:`_xyz_channel_names`).  Every data row must have
    one value per channel: a row with more or fewer is an error naming its line (columns are
    never shifted), except a last row cut short when ``allow_truncated`` (dropped, with a
    warning).  ``*`` and Geosoft's numeric dummy -1e32 are missing values.  A UTF-8 BOM is
    ignored; bytes that are not UTF-8 are an error naming the line (never replaced).

    Line headers (:data:`XYZ_LINE_HEADER`: ``Line 10``, ``LINE 10.1``, ``L1010.1``, ``Tie 100``,
    ``T100``, ``Line 10:16``, ``Trend``/``Base``/``Test``/``Random``/``Special N``) start a line;
    the rows that follow get an integer id in ``line`` (the line number; see
    :func:`_line_ids` when two labels share a number), ``line_type`` (``line``, ``tie``, ...;
    when the file has other types than flight lines) and ``line_label`` (the header as written;
    when the number alone does not tell the lines apart: versions, flights, shared numbers).
    Rows before the first header, or after ``Line *``, have no line (NaN).  A channel already
    named ``line`` (any case) is kept and no header ids are added.

    Parameters
    ----------
    path : path-like
        The file.

    Returns
    -------
    DataFrame
        The channels (numbers as float64 where every value parses).
    """
    p = Path(path)
    check_text_file(p, "Geosoft XYZ file")
    try:
        text = p.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise InputError(not_utf8_message(p)) from None
    except OSError as exc:
        raise InputError(f"{p}: cannot read ({exc.strerror or exc})") from None
    lines = text.split("\n") if "\n" in text or "\r" not in text else text.split("\r")
    del text
    comments: list[tuple[int, str]] = []
    data: list[str] = []
    run_rows: list[int] = []
    run_lines: list[int] = []
    seg_keys: list[tuple[str, int, int, int | None] | None] = [None]
    seg_labels: list[str | None] = [None]
    seg_start: list[int] = [0]
    last = -2
    # Header lines are few; data lines are collected in bulk (one join + one parser call).
    for ln, raw in enumerate(lines, start=1):
        s = raw.strip()
        if not s:
            continue
        c0 = s[0]
        if c0 == "/":
            if not data:
                comments.append((ln, s))
            continue
        if c0.isalpha():
            m = XYZ_LINE_HEADER.match(s)
            if m:
                key = _line_key(m)
                if key is not None and max(abs(key[1]), key[2], key[3] or 0) > MAX_LINE_NUMBER:
                    raise InputError(
                        f"{p}: line {ln}: line header {clean(s[:60])!r} has a number beyond"
                        f" 2**62; fix the header (a line number, .version and :flight of at most"
                        " 18 digits)")
                seg_keys.append(key)
                seg_labels.append(" ".join(s.split()))
                seg_start.append(len(data))
                continue
        if ln != last + 1:
            run_rows.append(len(data))
            run_lines.append(ln)
        last = ln
        data.append(s)
    del lines
    if not data:
        raise InputError(f"{p}: no data rows in this XYZ file; is it the right file?")
    rows = rows_in_runs(run_rows, run_lines)
    blob = "\n".join(data).encode("utf-8")
    n_rows = len(data)
    del data
    counts = _xyz_field_counts(blob)
    # The channel count is the values most rows have (a short or long row is reported below).
    typical = int(np.argmax(np.bincount(counts)))
    first = int(np.argmax(counts == typical))
    names = _xyz_channel_names(p, comments, typical, row_location(rows, first))
    check_unique_names(names, str(p), what="channel-name line")
    wrong = np.flatnonzero(counts != len(names))
    if (allow_truncated and wrong.size == 1 and wrong[0] == n_rows - 1
            and counts[-1] < len(names) and n_rows > 1):
        log.warning("%s: %s: the last row is cut short (%d of %d values: the file ended in the"
                    " middle of a row); dropped it", p, row_location(rows, n_rows - 1),
                    int(counts[-1]), len(names))
        blob = blob[: blob.rfind(b"\n")]
        n_rows -= 1
        wrong = wrong[:0]
    if wrong.size:
        i = int(wrong[0])
        last = " (the last row: the file is cut short? allow_truncated=True drops it)" if (
            i == n_rows - 1 and counts[i] < len(names)) else ""
        raise InputError(
            f"{p}: {row_location(rows, i)}: {int(counts[i])} values but {len(names)} channels"
            f" ({' '.join(names[:8])}{' ...' if len(names) > 8 else ''}){last}; every data row"
            " needs one value per channel ('*' for a missing one)")
    try:
        df = pd.read_csv(_io.BytesIO(blob), sep=r"\s+", header=None, names=names,
                         index_col=False, na_values=[_MISSING_XYZ], keep_default_na=False,
                         engine="c", encoding="utf-8")
    except (pd.errors.ParserError, ValueError, OverflowError) as exc:
        msg = str(exc).strip().splitlines()[-1]
        raise InputError(f"{p}: cannot parse the XYZ data ({msg}); every row needs"
                         f" {len(names)} values separated by blanks") from None
    del blob
    if len(df) != n_rows:  # pragma: no cover - defensive: the counts were checked
        raise InputError(f"{p}: the XYZ data rows could not be read one per line")
    for c in df.columns:
        if df[c].dtype == np.float64:
            dummy = df[c].to_numpy() == GEOSOFT_DUMMY
            if dummy.any():
                log.info("%s: %d Geosoft dummy value(s) -1e32 in %r read as missing", p,
                         int(dummy.sum()), c)
                df[c] = np.where(dummy, np.nan, df[c].to_numpy())
    if len(seg_keys) > 1:
        _add_line_columns(df, names, seg_keys, seg_labels, seg_start, n_rows)
    df.attrs[ROWS_ATTR] = rows
    return df


def _add_line_columns(df: pd.DataFrame, names: Sequence[str],
                      seg_keys: Sequence[tuple[str, int, int, int | None] | None],
                      seg_labels: Sequence[str | None], seg_start: Sequence[int],
                      n_rows: int) -> None:
    """``line`` / ``line_type`` / ``line_label`` of the rows from the XYZ line headers."""
    counts = np.diff(np.r_[np.asarray(seg_start, dtype=np.int64), n_rows])
    ids, renumbered = _line_ids(seg_keys)
    lower = {n.lower() for n in names}
    present = [k for k, c in zip(seg_keys, counts, strict=True) if c and k is not None]
    missing = any(k is None and c for k, c in zip(seg_keys, counts, strict=True))
    if "line" not in lower:
        if missing:  # float with NaN, as pandas reads an integer column with blanks
            seg_id = np.array([np.nan if k is None else ids[k] for k in seg_keys], np.float64)
        else:
            seg_id = np.array([0 if k is None else ids[k] for k in seg_keys], np.int64)
        df["line"] = np.repeat(seg_id, counts)
    if any(k[0] != "line" for k in present) and "line_type" not in lower:
        kinds = np.array([None if k is None else k[0] for k in seg_keys], dtype=object)
        df["line_type"] = np.repeat(kinds, counts)
    if (renumbered or any(k[2] or k[3] is not None for k in present)) and (
            "line_label" not in lower):
        labels = np.array([None if k is None else lab
                           for k, lab in zip(seg_keys, seg_labels, strict=True)], dtype=object)
        df["line_label"] = np.repeat(labels, counts)
    if renumbered:
        moved = [f"{lab} -> {ids[k]}" for k, lab in dict.fromkeys(
            zip(seg_keys, seg_labels, strict=True)) if k is not None and ids[k] != k[1]]
        log.info("line numbers shared by several line labels; new ids (kept in line_label):"
                 " %s%s", ", ".join(moved[:5]), " ..." if len(moved) > 5 else "")


def write_xyz(df: pd.DataFrame, path: str | os.PathLike[str], *,
              title: str = "aeromag Geosoft XYZ export") -> Path:
    """Write a Geosoft XYZ file atomically.

    A ``/`` title line, a ``/`` line of channel names, then the rows.  When the table has a
    ``line`` (or ``line_label``) column, a line header starts every run of rows with the same
    line, and the ``line``/``line_type``/``line_label`` columns are not repeated on the rows:

    * ``line_label`` (as :func:`read_xyz` makes it), when it holds a valid header such as
      ``Tie 100`` or ``L1010.1``, is written as it is;
    * else ``line``: a number is written ``Line 10`` (``Tie``, ``Trend``, ... from
      ``line_type``), ``Line 1010.1`` for a non-integer number; a text id is written as it is
      when it is a Geosoft line name (``L10``, ``T100``, ``Line 10:16``) or a number;
    * rows without a line id at the start of the table are written before the first header
      (no line, as read back); later ones under ``Line *`` (read back as missing).

    Oasis montaj imports rows under a line header only, so a table without ``line`` gets
    headers too (:func:`_stand_in_lines`): ``Line N`` from its integer ``segment`` column
    (the fitting segments of ``aeromag compensate``; ``-1``, no segment, reads back as a turn
    as it is), else one ``Line 0`` before all rows.  The ``segment`` channel stays in the rows.

    Numbers are written in their shortest round-trip form, missing values as ``*``, booleans
    as ``1``/``0`` (Oasis channels are numbers; ``true`` would not import), date-times in ISO
    8601 (UTC, ``T`` separator): reading the file back gives every value exactly (a boolean
    as the integer 1 or 0).  Text that XYZ cannot hold (blanks, empty, ``*``, a first
    column starting with ``/``) is an error naming its column and row.

    Parameters
    ----------
    df : DataFrame
        The table.
    path : path-like
        Destination.
    title : str
        Text of the first comment line.

    Returns
    -------
    Path
    """
    p = display_path(path)  # the output named in errors (never a temporary)
    dest = Path(path)
    line_cols = [c for c in ("line", "line_type", "line_label") if c in df.columns]
    lines = df
    if "line" not in df.columns and "line_label" not in df.columns:
        line_cols = []
        lines = _stand_in_lines(df)
    check_no_binary(df, p)
    body = df.drop(columns=line_cols)
    names = [str(c) for c in body.columns]
    for c in names:
        if not c or any(ch.isspace() for ch in c):
            raise InputError(f"{p}: channel name {c!r} has blanks or is empty; XYZ names must"
                             " be single words")
    check_unique_names(names, str(p), what="table")
    body = _xyz_ready(body, p)
    text = body.to_csv(sep=" ", header=False, index=False, na_rep=_MISSING_XYZ,
                       lineterminator="\n")
    rows = text.split("\n")[:-1]
    del text
    _check_xyz_rows(body, rows, p)
    out: list[str] = [f"/ {title}", "/ " + " ".join(names)]
    for a, b, header in _xyz_line_runs(lines, p):
        if header is not None:
            out.append(header)
        out.extend(rows[a:b])
    with atomic_path(dest) as tmp:
        tmp.write_text("\n".join(out) + "\n", encoding="utf-8")
    return dest


def _stand_in_lines(df: pd.DataFrame) -> pd.DataFrame:
    """The ``line`` of the headers of a table that has none: its segments, or one line 0.

    ``segment`` is used when it holds integers (missing ones are rows without a line);
    anything else (text, fractions) is no line number, and the table becomes ``Line 0``.
    """
    seg = df["segment"] if "segment" in df.columns else None
    if seg is not None and pd.api.types.is_numeric_dtype(seg.dtype) and not (
            pd.api.types.is_bool_dtype(seg.dtype)):
        v = seg.to_numpy(dtype=np.float64, na_value=np.nan)
        fin = v[np.isfinite(v)]
        if fin.size and np.array_equal(fin, np.rint(fin)) and np.abs(fin).max() < 2.0**53:
            return pd.DataFrame({"line": seg.astype("Int64")}, index=df.index)
    return pd.DataFrame({"line": np.zeros(len(df), dtype=np.int64)}, index=df.index)


def _xyz_ready(body: pd.DataFrame, p: Path) -> pd.DataFrame:
    """Booleans as ``1``/``0``, date-times as ISO 8601; text XYZ cannot hold refused."""
    conv: dict[str, object] = {}
    for j, c in enumerate(body.columns):
        s = body[c]
        if pd.api.types.is_bool_dtype(s.dtype):
            conv[c] = np.where(s.to_numpy(dtype=bool, na_value=False), "1", "0")
            if s.isna().any():
                conv[c] = np.where(s.isna().to_numpy(), None, conv[c])
        elif pd.api.types.is_datetime64_any_dtype(s.dtype):
            utc = isinstance(s.dtype, pd.DatetimeTZDtype)
            v = (s.dt.tz_convert("UTC").dt.tz_localize(None) if utc else s).to_numpy()
            iso = np.datetime_as_string(v, unit=np.datetime_data(v.dtype)[0]).astype(object)
            if utc:
                iso = iso + "Z"
            iso[np.isnat(v)] = None
            conv[c] = iso
        elif pd.api.types.is_timedelta64_dtype(s.dtype):
            raise InputError(f"{p}: column {c!r} holds durations; XYZ has no such type: convert"
                             " it to seconds first")
        elif not pd.api.types.is_numeric_dtype(s.dtype):
            txt = s[s.notna()].astype(str)
            bad = txt.str.contains(r"\s", regex=True) | (txt == "") | (txt == _MISSING_XYZ)
            if j == 0:
                bad |= txt.str.startswith("/")
            if bad.any():
                where = int(np.flatnonzero(s.notna().to_numpy())[np.argmax(bad.to_numpy())])
                raise InputError(
                    f"{p}: column {c!r}, row {where + 1}: text {txt[bad].iloc[0]!r} cannot be"
                    " written to Geosoft XYZ (no blanks, not empty, not '*' which means"
                    " missing, not starting with '/' in the first column); change the value"
                    " or drop the column")
    if conv:
        body = body.assign(**{str(k): v for k, v in conv.items()})
    return body


def _check_xyz_rows(body: pd.DataFrame, rows: Sequence[str], p: Path) -> None:
    """A row of text that would read back as a line header (only possible with 1-2 channels
    and text in the first) is refused."""
    if not rows or body.shape[1] > 2 or pd.api.types.is_numeric_dtype(body.iloc[:, 0].dtype):
        return
    for i, r in enumerate(rows):
        if XYZ_LINE_HEADER.match(r):
            raise InputError(f"{p}: row {i + 1}: {r!r} would read back as a line header;"
                             " put a numeric channel first")


def _xyz_line_runs(df: pd.DataFrame, p: Path) -> list[tuple[int, int, str | None]]:
    """(first row, end row, header text or None) of every run of rows on the same line."""
    n = len(df)
    if n == 0:
        return []
    key_cols = [c for c in ("line", "line_type", "line_label") if c in df.columns]
    change = np.zeros(n, dtype=bool)
    change[0] = True
    for c in key_cols:
        s = df[c]
        prev = s.shift(1)
        diff = (s.ne(prev) & ~(s.isna() & prev.isna())).to_numpy(dtype=bool, na_value=True)
        change[1:] |= diff[1:]
    starts = np.flatnonzero(change)
    stops = np.r_[starts[1:], n]
    out = []
    for a, b in zip(starts.tolist(), stops.tolist(), strict=True):
        header = _xyz_header_of(df, a, p)
        if header is None and a > 0:
            header = "Line *"
        out.append((a, b, header))
    return out


def _xyz_header_of(df: pd.DataFrame, i: int, p: Path) -> str | None:
    """The line header of row ``i`` (None when it has no line id)."""
    if "line_label" in df.columns and not _missing(df["line_label"].iloc[i]):
        lab = " ".join(str(df["line_label"].iloc[i]).split())
        if XYZ_LINE_HEADER.match(lab):
            return lab
        if "line" not in df.columns:
            raise InputError(f"{p}: column 'line_label', row {i + 1}: {lab!r} is not a Geosoft"
                             " line header (e.g. 'Line 10', 'Tie 100', 'L1010.1')")
    if "line" not in df.columns or _missing(df["line"].iloc[i]):
        return None
    kind = df["line_type"].iloc[i] if "line_type" in df.columns else None
    kind = "line" if _missing(kind) else str(kind).strip().lower()
    if kind not in XYZ_LINE_TYPES:
        raise InputError(f"{p}: column 'line_type', row {i + 1}: {kind!r} is not a Geosoft line"
                         f" type; use one of {', '.join(XYZ_LINE_TYPES)}")
    word = kind.capitalize()
    v = df["line"].iloc[i]
    if isinstance(v, str):
        t = " ".join(v.split())
        if XYZ_LINE_HEADER.match(t):
            return t
    elif isinstance(v, int | np.integer):
        t = str(int(v))
    else:
        try:
            f = float(v)
        except (TypeError, ValueError):
            f = float("nan")
        t = (str(int(f)) if f.is_integer() else repr(f)) if np.isfinite(f) else str(v)
    if re.fullmatch(r"-?\d+(\.\d+)?(:\d+)?", t):
        return f"{word} {t}"
    raise InputError(f"{p}: column 'line', row {i + 1}: {v!r} is not a Geosoft line number or"
                     " line name (e.g. 10, 1010.1, L10, T100)")


def _missing(v: object) -> bool:
    """True for None, NaN, NaT, pd.NA."""
    try:
        return bool(pd.isna(v))
    except (TypeError, ValueError):
        return False
