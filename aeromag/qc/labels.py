"""Per-sample labels of a compensated log: segment ids and the screening's kept flags."""

from __future__ import annotations

import numpy as np
import pandas as pd

__all__ = ["kept_mask", "segment_labels"]


def segment_labels(data: pd.DataFrame, *, copy: bool = True) -> np.ndarray:
    """Segment id per sample (``segment`` column; -1 where absent or empty).

    Parameters
    ----------
    data : DataFrame
        Compensated log.
    copy : bool
        False returns the integer column's own array when it has one, in its own dtype (the
        report reads ``segment`` as int32: no 16 MB int64 copy at 2e6 rows); the caller must
        then not modify it.

    Returns
    -------
    ndarray of int64 (or the column's own signed integer dtype when ``copy=False``), shape (n,)
    """
    if "segment" not in data.columns:
        return np.full(len(data), -1, dtype=np.int64)
    col = data["segment"]
    if pd.api.types.is_integer_dtype(col.dtype) and not col.hasnans:
        # The usual case (``aeromag compensate`` writes integers): one int64 array, not the
        # float64 copy, the where() and the cast (3 full-length arrays, 48 MB at 2e6 rows).
        if not copy and col.dtype.kind == "i":
            return col.to_numpy(copy=False)
        return col.to_numpy(dtype=np.int64, copy=copy)
    s = pd.to_numeric(data["segment"], errors="coerce").to_numpy(dtype=np.float64)
    return np.where(np.isfinite(s), s, -1).astype(np.int64)


def kept_mask(data: pd.DataFrame) -> np.ndarray:
    """Whether each sample's segment was kept by the screening (``segment_kept``; all True
    when the column is absent).

    Parameters
    ----------
    data : DataFrame
        Compensated log (``segment_kept`` written ``true``/``false`` or boolean).

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    if "segment_kept" not in data.columns:
        return np.ones(len(data), dtype=bool)
    k = data["segment_kept"]
    if k.dtype == object or pd.api.types.is_string_dtype(k):
        return k.astype(str).str.strip().str.lower().isin(["true", "1", "yes"]).to_numpy()
    return k.fillna(False).to_numpy(dtype=bool)
