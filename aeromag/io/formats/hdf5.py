"""MagNav.jl / SGL HDF5 logs: one 1-D dataset per channel (h5py)."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pandas as pd

from ...errors import InputError
from ..columns import SCALARS_ATTR
from ..messages import clean
from ..rows import ROWS_ATTR, rows_numbered

log = logging.getLogger(__name__)

def read_hdf5(path: Path) -> pd.DataFrame:
    """Read the 1-D datasets of an HDF5 file (the length most of them share) as columns."""
    try:
        import h5py
    except ImportError:  # pragma: no cover
        raise InputError(f"{path}: reading HDF5 needs h5py: pip install 'aeromag[hdf5]'") from None
    arrays: dict[str, np.ndarray] = {}
    other: list[str] = []
    scalars: list[str] = []
    unreadable: list[str] = []  # links to nothing: named in a warning, never lost silently
    groups: list[str] = []
    try:
        with h5py.File(path, "r") as h5:
            for name in list(h5.keys()):
                try:
                    ds = h5.get(name)
                except Exception:  # noqa: BLE001 - an object h5py cannot open
                    ds = None
                if ds is None:  # a soft or external link to nothing, or a damaged object
                    unreadable.append(name)
                    continue
                if not isinstance(ds, h5py.Dataset):
                    groups.append(name)  # a group: not a channel
                    continue
                if ds.ndim == 0 or (ds.ndim == 1 and ds.shape[0] <= 1):
                    scalars.append(name)  # metadata (MagNav's dt, N ...), not a channel
                    continue
                if ds.ndim != 1:
                    other.append(f"{clean(name)!r} is {ds.ndim}-D (shape"
                                 f" {'x'.join(map(str, ds.shape))})")
                    continue
                try:
                    arrays[name] = np.asarray(ds[()])
                except Exception as exc:  # noqa: BLE001 - a damaged chunk, a missing filter
                    msg = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
                    raise InputError(
                        f"{clean(path)}: dataset {clean(name)!r} cannot be read"
                        f" ({clean(msg) or type(exc).__name__}): the file is damaged there;"
                        " export the log again, or remove that dataset") from None
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - h5py raises many types on a damaged file
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputError(f"{clean(path)}: cannot read as HDF5 ({clean(msg)}); is it an HDF5"
                         " file, complete and undamaged?") from None
    if not arrays:
        raise InputError(f"{clean(path)}: no 1-D channel datasets in this HDF5 file (one 1-D"
                         " dataset per channel expected, as MagNav.jl writes them)")
    lengths = pd.Series({k: len(v) for k, v in arrays.items()})
    n = int(lengths.mode().iloc[0])
    other += [f"{clean(k)!r} has {len(v)} samples" for k, v in arrays.items() if len(v) != n]
    if other:
        more = f" (and {len(other) - 1} more)" if len(other) > 1 else ""
        raise InputError(
            f"{clean(path)}: dataset {other[0]}{more}"
            f" while the channels have {n} samples each; every channel must be one 1-D dataset"
            " of the same length: fix or remove that dataset")
    for k, v in arrays.items():
        if v.dtype.kind == "S":  # fixed-length byte strings: text channels
            try:
                arrays[k] = np.char.decode(v, "utf-8").astype(object)
            except UnicodeDecodeError:
                raise InputError(f"{clean(path)}: dataset {clean(k)!r} holds bytes that are not"
                                 " UTF-8 text; fix or remove that dataset") from None
    if unreadable:
        log.warning("%s: dataset(s) %s cannot be opened (a link to a missing object, or a"
                    " damaged header): left out of the table; repair or re-export the file if"
                    " you need them", clean(path), ", ".join(repr(clean(k)) for k in unreadable))
    if groups:
        log.info("%s: %d group(s) skipped, not channels: %s", clean(path), len(groups),
                 ", ".join(repr(clean(k)) for k in groups[:10]))
    df = pd.DataFrame(arrays)
    df.attrs[ROWS_ATTR] = rows_numbered("sample")
    if scalars:
        names = ", ".join(repr(clean(k)) for k in scalars[:10])
        more = f" and {len(scalars) - 10} more" if len(scalars) > 10 else ""
        log.info("%s: %d scalar dataset(s) skipped, not channels: %s%s", clean(path),
                 len(scalars), names, more)
        df.attrs[SCALARS_ATTR] = tuple(scalars)
    return df


def check_scalar_channels(df: pd.DataFrame, wanted: dict[str, tuple[str, ...]],
                          source: str) -> None:
    """Refuse a canonical column that only a skipped scalar dataset could have given.

    A scalar dataset (shape ``()`` or one value) is metadata, not a channel; when the table
    lacks a canonical column that a scalar dataset is named after (itself, or a preset name
    of it), the file holds that channel as one number and reading on would report the column
    missing, or silently use another.  The skipped names are in ``df.attrs``.

    Parameters
    ----------
    df : DataFrame
        The table after the preset (canonical names added).
    wanted : mapping
        ``{canonical: (native names, ...)}``: the preset.
    source : str
        File name quoted in the error.
    """
    scalars = df.attrs.get(SCALARS_ATTR) or ()
    lower = {k.lower(): k for k in scalars}
    for canon, natives in wanted.items():
        if canon in df.columns:
            continue
        for name in (canon, *natives):
            if name.lower() in lower:
                k = lower[name.lower()]
                raise InputError(
                    f"{clean(source)}: dataset {clean(k)!r} (the {canon!r} channel) is a scalar"
                    " (one value, shape ()), not one value per sample; write it as a 1-D dataset"
                    " as long as the others, or map another channel with columns=...")


#: Geosoft line types: the header words Oasis montaj writes, and the letters of compact line
#: names (``L1010.1``), as Geosoft's gxpy ``create_line_name`` spells them.
