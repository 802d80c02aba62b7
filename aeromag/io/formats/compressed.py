"""Compressed CSV logs (``.csv.xz``, ``.csv.gz``, ``.csv.bz2``), as archives publish them.

The file is decompressed as a stream (Python's ``lzma``/``gzip``/``bz2``) into pyarrow's CSV
reader; no decompressed copy is written to disk.
"""

from __future__ import annotations

import bz2
import gzip
import lzma
from pathlib import Path

import pandas as pd

from ...errors import InputError
from ..messages import clean
from ..rows import ROWS_ATTR, rows_numbered

#: Compressed-file extensions and their openers.
OPENERS = {".xz": lzma.open, ".gz": gzip.open, ".bz2": bz2.open}


def read_compressed_csv(path: Path) -> pd.DataFrame:
    """Read a compressed CSV (comma-separated, one header line) into a table.

    Parameters
    ----------
    path : Path
        ``NAME.csv.xz``, ``.gz`` or ``.bz2``.

    Returns
    -------
    DataFrame
        Columns as pyarrow typed them; ``df.attrs[ROWS_ATTR]`` numbers the data rows.

    Raises
    ------
    InputError
        Not a file of that compression, or not a CSV inside.
    """
    import pyarrow as pa
    import pyarrow.csv as pacsv

    opener = OPENERS[Path(path).suffix.lower()]
    try:
        with opener(path, "rb") as fh:
            table = pacsv.read_csv(fh)
    except (OSError, EOFError, lzma.LZMAError) as exc:
        raise InputError(f"{clean(path)}: not a readable {Path(path).suffix} file ({exc});"
                         " is it the right file?") from None
    except pa.ArrowInvalid as exc:
        raise InputError(f"{clean(path)}: not a CSV inside the compression ({exc})") from None
    df = table.to_pandas()  # a name used twice is refused by read_log (check_unique_names)
    df.attrs[ROWS_ATTR] = rows_numbered("row")
    return df
