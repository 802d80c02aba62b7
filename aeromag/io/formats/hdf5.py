"""MagNav.jl / SGL HDF5 logs: one 1-D dataset per channel (h5py)."""

from __future__ import annotations

import logging
from pathlib import Path

import pandas as pd

from ...errors import InputError
from ..rows import ROWS_ATTR, rows_numbered

log = logging.getLogger(__name__)

def read_hdf5(path: Path) -> pd.DataFrame:
    """Read the 1-D datasets of an HDF5 file (the length most of them share) as columns."""
    try:
        import h5py
    except ImportError:  # pragma: no cover
        raise InputError(f"{path}: reading HDF5 needs h5py: pip install 'aeromag[hdf5]'") from None
    try:
        with h5py.File(path, "r") as h5:
            arrays = {}
            for name, ds in h5.items():
                if isinstance(ds, h5py.Dataset) and ds.ndim == 1 and ds.shape[0] > 1:
                    arrays[name] = ds[()]
    except OSError as exc:
        raise InputError(f"{path}: cannot read as HDF5 ({exc}); is it an HDF5 file?") from None
    if not arrays:
        raise InputError(f"{path}: no 1-D channel datasets in this HDF5 file")
    lengths = pd.Series({k: len(v) for k, v in arrays.items()})
    n = int(lengths.mode().iloc[0])
    skipped = sorted(k for k, v in arrays.items() if len(v) != n)
    if skipped:
        log.info("%s: skipped HDF5 datasets of another length: %s", path, ", ".join(skipped))
    df = pd.DataFrame({k: v for k, v in arrays.items() if len(v) == n})
    df.attrs[ROWS_ATTR] = rows_numbered("sample")
    return df


#: Geosoft line types: the header words Oasis montaj writes, and the letters of compact line
#: names (``L1010.1``), as Geosoft's gxpy ``create_line_name`` spells them.
