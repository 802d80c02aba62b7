"""File formats beyond plain CSV: Parquet, Geosoft XYZ, MagNav/SGL HDF5 and XYZ, UAV logs.

:func:`read_table` returns the raw table of a file as a :class:`pandas.DataFrame`, with the
canonical column names of ``shared/interface.md`` wherever the format defines them;
:func:`aeromag.io.read_log` then validates it exactly as it validates a CSV log.
:func:`write_table` writes CSV, Parquet or Geosoft XYZ atomically.

Formats (chosen by ``fmt`` or by the file's extension; ``.csv`` files are sniffed for the
native UAV layouts):

=============  ==================  ==========================================================
name           extensions          notes
=============  ==================  ==========================================================
``csv``        .csv .txt           the default (read by :mod:`aeromag.io`)
``parquet``    .parquet .pq        needs pyarrow (``aeromag[parquet]``)
``xyz``        .xyz                Geosoft XYZ: ``/`` comment lines (the last one before the
                                   data names the channels), ``Line N`` / ``Tie N`` headers,
                                   ``*`` for a missing value; SGL/MagNav channel names are
                                   mapped by the ``magnav`` preset
``hdf5``       .h5 .hdf5           MagNav.jl / SGL HDF5: one 1-D dataset per channel (``tt``,
                                   ``mag_1_uc``, ``flux_a_x`` ...), ``magnav`` preset; h5py
``magarrow``   (sniffed .csv)      Geometrics MagArrow native CSV
``magdrone``   (sniffed .csv)      SENSYS MagDrone R3 native CSV (fluxgate B1; ``magdrone_b2``
                                   takes B2)
=============  ==================  ==========================================================

Presets map native channel names and units onto canonical columns; see ``docs/formats.md``.
"""

from __future__ import annotations

import io as _io
import logging
import os
import re
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from .errors import InputError
from .io import FIELD_UNITS_TO_NT, atomic_path, write_csv

log = logging.getLogger(__name__)

#: Formats by file extension.
EXTENSIONS: dict[str, str] = {
    ".csv": "csv",
    ".txt": "csv",
    ".parquet": "parquet",
    ".pq": "parquet",
    ".xyz": "xyz",
    ".h5": "hdf5",
    ".hdf5": "hdf5",
}

FORMATS: tuple[str, ...] = ("csv", "parquet", "xyz", "hdf5", "magarrow", "magdrone",
                            "magdrone_b2")

#: MagNav.jl / SGL channel names -> canonical columns (first match wins, case-insensitive).
MAGNAV_PRESET: dict[str, tuple[str, ...]] = {
    "time": ("tt", "time"),
    "lat": ("lat",),
    "lon": ("lon", "long"),
    "alt": ("utm_z", "alt"),
    "mag": ("mag_1_uc",),
    "flux_x": ("flux_a_x",),
    "flux_y": ("flux_a_y",),
    "flux_z": ("flux_a_z",),
    "line": ("line",),
    "heading": ("ins_yaw", "heading"),
    "pitch": ("ins_pitch", "pitch"),
    "roll": ("ins_roll", "roll"),
}

_MISSING_XYZ = "*"


# --------------------------------------------------------------------------- detection
def detect_format(path: str | os.PathLike[str], fmt: str | None = None) -> str:
    """Return the format name of ``path``: ``fmt`` when given, else from extension and content.

    Parameters
    ----------
    path : path-like
        The file.
    fmt : str, optional
        Explicit format (one of :data:`FORMATS`).

    Returns
    -------
    str
        One of :data:`FORMATS`.
    """
    p = Path(path)
    if fmt:
        f = fmt.strip().lower().replace("-", "_")
        if f not in FORMATS:
            raise InputError(f"{p}: unknown format {fmt!r}; use one of {', '.join(FORMATS)}")
        return f
    f = EXTENSIONS.get(p.suffix.lower(), "csv")
    if f == "csv":
        f = sniff_csv(p) or "csv"
    return f


def sniff_csv(path: Path) -> str | None:
    """Recognise the native CSV of a MagArrow or MagDrone from the first 4 kB, else None."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096).decode("utf-8", errors="replace")
    except OSError:
        return None
    first = head.lstrip("\ufeff").split("\n", 1)[0]
    cells = [c.strip() for c in first.split(",")]
    if {"Counter", "Date", "Time", "Mag"} <= set(cells):
        return "magarrow"
    if re.search(r"^MagDrone", head, re.MULTILINE) or re.search(
        r"^Timestamp \[ms\];", head, re.MULTILINE
    ):
        return "magdrone"
    return None


# --------------------------------------------------------------------------- reading
def read_table(path: str | os.PathLike[str], fmt: str | None = None) -> pd.DataFrame:
    """Read the raw table of a log file in any supported format.

    Parameters
    ----------
    path : path-like
        The file.
    fmt : str, optional
        Format name (default from the extension; ``.csv`` files are sniffed for native UAV
        layouts).

    Returns
    -------
    DataFrame
        One row per sample; canonical column names where the format or its preset defines
        them (``time`` [s], ``mag``/``flux_*`` [nT], ``lat``/``lon`` [deg], ``alt`` [m]), other
        channels under their own names.  ``df.attrs["format"]`` holds the format name.
    """
    p = Path(path)
    if not p.exists():
        raise InputError(f"{p}: file not found")
    if p.is_dir():
        raise InputError(f"{p}: is a folder, not a log file")
    f = detect_format(p, fmt)
    if f == "csv":
        from .io import _read_csv

        df = _read_csv(p)
    elif f == "parquet":
        df = _read_parquet(p)
    elif f == "xyz":
        df = apply_preset(read_xyz(p), MAGNAV_PRESET)
    elif f == "hdf5":
        df = apply_preset(_read_hdf5(p), MAGNAV_PRESET)
    elif f == "magarrow":
        df = read_magarrow(p)
    else:
        df = read_magdrone(p, sensor=2 if f == "magdrone_b2" else 1)
    df.attrs["format"] = f
    return df


def apply_preset(df: pd.DataFrame, preset: Mapping[str, Sequence[str]]) -> pd.DataFrame:
    """Add canonical columns as copies of the first matching native channel.

    A canonical column already in the table is left alone; matching is case-insensitive.  The
    native channels are kept, so a ``--col`` map naming them still works.

    Parameters
    ----------
    df : DataFrame
        Raw table.
    preset : mapping
        ``{canonical: (candidate native names, ...)}``.

    Returns
    -------
    DataFrame
        The same frame with canonical columns added.
    """
    lower = {str(c).lower(): c for c in df.columns}
    for canon, candidates in preset.items():
        if canon in df.columns:
            continue
        for cand in candidates:
            src = lower.get(cand.lower())
            if src is not None:
                df[canon] = df[src]
                break
    return df


def _read_parquet(path: Path) -> pd.DataFrame:
    try:
        import pyarrow.parquet as pq
    except ImportError:  # pragma: no cover - pyarrow is a test dependency
        raise InputError(
            f"{path}: reading Parquet needs pyarrow: pip install 'aeromag[parquet]'") from None
    try:
        return pq.read_table(path).to_pandas()
    except Exception as exc:  # noqa: BLE001 - any pyarrow failure is a bad file
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputError(f"{path}: cannot read as Parquet ({msg}); is it a Parquet file?") from None


def _read_hdf5(path: Path) -> pd.DataFrame:
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
    return pd.DataFrame({k: v for k, v in arrays.items() if len(v) == n})


def read_xyz(path: str | os.PathLike[str]) -> pd.DataFrame:
    """Read a Geosoft XYZ file (line-based ASCII).

    ``/`` lines are comments; the last comment line before the first data row names the
    channels (leading ``/`` removed).  ``Line N`` and ``Tie N`` lines start a flight line or a
    tie line: their number goes into the ``line`` column, and when the file has tie lines a
    ``line_type`` column holds ``line`` or ``tie``.  ``*`` is a missing value.

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
    try:
        text = p.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise InputError(f"{p}: cannot read ({exc})") from None
    lines = text.splitlines()
    names: list[str] | None = None
    data: list[str] = []
    line_no: list[float] = []
    line_kind: list[str] = []
    counts: list[int] = []
    cur_n = 0
    has_headers = False
    # Header lines are few; data lines are collected in bulk (one join + one parser call).
    for raw in lines:
        s = raw.strip()
        if not s:
            continue
        c0 = s[0]
        if c0 == "/":
            if not data:
                cand = s.lstrip("/").split()
                if cand:
                    names = cand
            continue
        if c0 in "LlTt":
            m = re.match(r"^(line|tie)\s+([-+0-9.eE]+)\s*$", s, re.IGNORECASE)
            if m:
                if has_headers:
                    counts.append(cur_n)
                has_headers = True
                cur_n = 0
                line_no.append(float(m.group(2)))
                line_kind.append(m.group(1).lower())
                continue
        data.append(s)
        cur_n += 1
    if has_headers:
        counts.append(cur_n)
    if not data:
        raise InputError(f"{p}: no data rows in this XYZ file")
    if names is None:
        raise InputError(f"{p}: no channel-name line ('/ name1 name2 ...') before the data")
    try:
        df = pd.read_csv(_io.StringIO("\n".join(data)), sep=r"\s+", header=None, names=names,
                         na_values=[_MISSING_XYZ], keep_default_na=False, engine="c")
    except (pd.errors.ParserError, ValueError) as exc:
        msg = str(exc).strip().splitlines()[-1]
        raise InputError(f"{p}: cannot parse the XYZ data ({msg}); every row needs"
                         f" {len(names)} values separated by blanks") from None
    if has_headers:
        if len(counts) and sum(counts) != len(df):  # pragma: no cover - defensive
            raise InputError(f"{p}: XYZ line headers and data rows disagree")
        if "line" not in df.columns:
            ln = np.repeat(np.asarray(line_no), counts)
            df["line"] = ln.astype(np.int64) if np.all(ln == np.round(ln)) else ln
        if "tie" in line_kind and "line_type" not in df.columns:
            df["line_type"] = np.repeat(np.asarray(line_kind, dtype=object), counts)
    return df


def _parse_datetime_seconds(date: pd.Series, clock: pd.Series, source: str) -> np.ndarray:
    """``Date`` + ``Time`` columns -> seconds since 1970-01-01 UTC (float64)."""
    stamp = date.astype(str).str.strip() + " " + clock.astype(str).str.strip()
    dt = pd.to_datetime(stamp, format="mixed", errors="coerce", utc=True)
    bad = dt.isna().to_numpy()
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"{source}: columns 'Date'/'Time', line {i + 2}: cannot read"
                         f" {stamp.iloc[i]!r} as a date and time")
    ns = dt.to_numpy(dtype="datetime64[ns]").astype(np.int64)
    # Whole seconds and the fraction separately: exact to the nanosecond before the float cast.
    return (ns // 1_000_000_000).astype(np.float64) + (ns % 1_000_000_000) / 1e9


def _interp_sparse(t: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Linear interpolation in time over the finite samples (NaN outside their span)."""
    ok = np.isfinite(values)
    if ok.sum() < 2:
        return values
    out = np.interp(t, t[ok], values[ok])
    out[(t < t[ok][0]) | (t > t[ok][-1])] = np.nan
    return out


def read_magarrow(path: str | os.PathLike[str]) -> pd.DataFrame:
    """Read the native CSV of a Geometrics MagArrow.

    Canonical columns: ``time`` = ``Date`` + ``Time`` (UTC) in seconds since 1970-01-01;
    ``mag`` = ``Mag`` [nT] (NaN where ``MagValid`` is 0); ``lat``/``lon`` = ``Latitude`` /
    ``Longitude`` [deg] (the instrument interpolates them to every row); ``alt`` = height above
    the WGS84 ellipsoid [m] = ``Altitude`` (above mean sea level, from the GGA sentence) +
    ``HeightOverEllipsoid`` (which holds the GGA geoid separation), interpolated in time between
    the GNSS rows.  The IMU channels (``CompassX/Y/Z`` raw counts, gyroscope, accelerometer)
    are logged on sparse rows only and stay NaN elsewhere; the compass is not a calibrated
    fluxgate in nT, so no ``flux_*`` columns are made (map them with ``--col`` and ``--units``
    if yours is calibrated).

    Parameters
    ----------
    path : path-like
        The MagArrow CSV.

    Returns
    -------
    DataFrame
    """
    p = Path(path)
    try:
        # index_col=False: the rows end with a delimiter more than the header has.
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", pd.errors.ParserWarning)
            df = pd.read_csv(p, skipinitialspace=True, low_memory=False, index_col=False)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        msg = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
        raise InputError(f"{p}: cannot parse the MagArrow CSV ({msg})") from None
    df.columns = [str(c).strip() for c in df.columns]
    missing = [c for c in ("Date", "Time", "Mag") if c not in df.columns]
    if missing:
        raise InputError(f"{p}: not a MagArrow log: missing column(s) {', '.join(missing)}")
    t = _parse_datetime_seconds(df["Date"], df["Time"], str(p))
    out = df.drop(columns=["Date", "Time"])
    out.insert(0, "time", t)
    mag = pd.to_numeric(out.pop("Mag"), errors="coerce").to_numpy(dtype=np.float64)
    if "MagValid" in out.columns:
        valid = pd.to_numeric(out["MagValid"], errors="coerce").to_numpy()
        invalid = valid == 0
        if invalid.any():
            log.info("%s: %d sample(s) with MagValid=0 set to NaN", p, int(invalid.sum()))
            mag = np.where(invalid, np.nan, mag)
    out.insert(1, "mag", mag)
    rename = {"Latitude": "lat", "Longitude": "lon"}
    out = out.rename(columns={k: v for k, v in rename.items() if k in out.columns})
    if "Altitude" in out.columns:
        msl = pd.to_numeric(out["Altitude"], errors="coerce").to_numpy(dtype=np.float64)
        sep = (pd.to_numeric(out["HeightOverEllipsoid"], errors="coerce").to_numpy(np.float64)
               if "HeightOverEllipsoid" in out.columns else np.zeros(len(out)))
        alt = _interp_sparse(t, msl + sep)
        if np.isfinite(alt).any():
            out["alt"] = alt
    out.attrs["units"] = {"time": "s", "mag": "nT", "lat": "deg", "lon": "deg", "alt": "m"}
    return out


_MAGDRONE_UNIT = re.compile(r"^\s*(.*?)\s*\[(.*)\]\s*$")


def read_magdrone(path: str | os.PathLike[str], *, sensor: int = 1) -> pd.DataFrame:
    """Read the native CSV of a SENSYS MagDrone R3 (metadata header, then a ``;`` table).

    The metadata lines before the ``Timestamp [ms];...`` header are kept in
    ``df.attrs["metadata"]``.  Canonical columns: ``time`` = ``Timestamp [ms]`` / 1000 [s since
    the logger started]; ``flux_x/y/z`` = fluxgate ``B1x/B1y/B1z`` (``sensor=2``: ``B2``),
    converted to nT from the unit in the header (the R3 writes nT); the other fluxgate stays
    as ``B2x``... (or ``B1x``...).  There is no scalar ``mag``: the pipeline then uses the
    fluxgate magnitude.  GPS columns hold 0 on rows without a fix; there ``lat``/``lon``
    [deg] are interpolated in time between fixes (Quality > 0), and ``Altitude`` (above mean
    sea level: the file holds no geoid separation) becomes ``alt_msl`` [m], not ``alt``.

    Parameters
    ----------
    path : path-like
        The MagDrone CSV.
    sensor : {1, 2}
        Fluxgate mapped to ``flux_x/y/z``.

    Returns
    -------
    DataFrame
    """
    p = Path(path)
    if sensor not in (1, 2):
        raise InputError(f"{p}: MagDrone fluxgate {sensor} does not exist; use 1 or 2")
    meta: list[str] = []
    header_at = None
    with open(p, encoding="utf-8", errors="replace") as fh:
        for i, line in enumerate(fh):
            if line.lstrip().startswith("Timestamp"):
                header_at = i
                break
            if line.strip():
                meta.append(line.strip())
            if i > 500:
                break
    if header_at is None:
        raise InputError(f"{p}: no 'Timestamp [ms];...' header line: not a MagDrone R3 log")
    try:
        raw = pd.read_csv(p, sep=";", skiprows=header_at, skipinitialspace=True,
                          low_memory=False)
    except (pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        msg = str(exc).strip().splitlines()[-1]
        raise InputError(f"{p}: cannot parse the MagDrone table ({msg})") from None
    raw = raw.loc[:, [c for c in raw.columns if not str(c).startswith("Unnamed")]]
    names: dict[str, str] = {}
    units: dict[str, str] = {}
    for c in raw.columns:
        m = _MAGDRONE_UNIT.match(str(c))
        base, unit = (m.group(1), m.group(2)) if m else (str(c).strip(), "")
        if base in names.values():  # e.g. 'GPSTime' and 'GPSTime [hh:mm:ss.sss]'
            base = f"{base}_{unit}".replace(":", "").replace(".", "")
        names[c] = base
        units[base] = unit
    df = raw.rename(columns=names)
    if "Timestamp" not in df.columns:
        raise InputError(f"{p}: no 'Timestamp' column in the MagDrone table")
    t = pd.to_numeric(df.pop("Timestamp"), errors="coerce").to_numpy(np.float64)
    tu = units.get("Timestamp", "ms").lower()
    t = t / {"ms": 1e3, "s": 1.0, "us": 1e6}.get(tu, 1e3)
    df.insert(0, "time", t)
    out_units = {"time": "s"}
    for axis in "xyz":
        src = f"B{sensor}{axis}"
        if src not in df.columns:
            raise InputError(f"{p}: MagDrone column {src!r} not found; columns: "
                             + ", ".join(map(str, df.columns)))
        unit = units.get(src, "nT") or "nT"
        factor = FIELD_UNITS_TO_NT.get(unit.strip().lower())
        if factor is None:
            raise InputError(f"{p}: column {src!r} has unknown unit {unit!r}; expected nT")
        df[f"flux_{axis}"] = pd.to_numeric(df.pop(src), errors="coerce") * factor
        out_units[f"flux_{axis}"] = "nT"
    if "Latitude" in df.columns and "Longitude" in df.columns:
        lat = pd.to_numeric(df.pop("Latitude"), errors="coerce").to_numpy(np.float64)
        lon = pd.to_numeric(df.pop("Longitude"), errors="coerce").to_numpy(np.float64)
        q = (pd.to_numeric(df["Quality"], errors="coerce").to_numpy(np.float64)
             if "Quality" in df.columns else np.where((lat != 0) | (lon != 0), 1.0, 0.0))
        fix = q > 0
        df["lat"] = _interp_sparse(t, np.where(fix, lat, np.nan))
        df["lon"] = _interp_sparse(t, np.where(fix, lon, np.nan))
        if "Altitude" in df.columns:
            alt = pd.to_numeric(df.pop("Altitude"), errors="coerce").to_numpy(np.float64)
            df["alt_msl"] = _interp_sparse(t, np.where(fix, alt, np.nan))
        out_units.update(lat="deg", lon="deg", alt_msl="m")
    df.attrs["metadata"] = meta
    df.attrs["units"] = {**units, **out_units}
    return df


# --------------------------------------------------------------------------- writing
def write_table(df: pd.DataFrame, path: str | os.PathLike[str], fmt: str | None = None) -> Path:
    """Write a table atomically as CSV, Parquet or Geosoft XYZ.

    Parameters
    ----------
    df : DataFrame
        The table (index not written).
    path : path-like
        Destination.
    fmt : {"csv", "parquet", "xyz"}, optional
        Default from the extension.

    Returns
    -------
    Path
        The written path.
    """
    p = Path(path)
    f = (fmt or EXTENSIONS.get(p.suffix.lower(), "csv")).lower()
    if f == "csv":
        return write_csv(df, p)
    if f == "parquet":
        import pyarrow as pa
        import pyarrow.parquet as pq

        table = pa.Table.from_pandas(df, preserve_index=False)
        with atomic_path(p) as tmp:
            pq.write_table(table, tmp)
        return p
    if f == "xyz":
        return write_xyz(df, p)
    raise InputError(f"{p}: cannot write format {f!r}; use csv, parquet or xyz")


def write_xyz(df: pd.DataFrame, path: str | os.PathLike[str], *,
              title: str = "aeromag Geosoft XYZ export") -> Path:
    """Write a Geosoft XYZ file atomically.

    A ``/`` title line, a ``/`` line of channel names, then the rows; when the table has a
    ``line`` column a ``Line N`` header (``Tie N`` where ``line_type`` is ``tie``) starts every
    run of equal line numbers, and the ``line``/``line_type`` columns themselves are not
    repeated on the rows.  Numbers are written in their shortest round-trip form, missing
    values as ``*``, booleans as ``true``/``false``: reading the file back gives every value
    exactly.

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
    p = Path(path)
    has_line = "line" in df.columns
    body = df.drop(columns=[c for c in ("line", "line_type") if c in df.columns])
    for c in body.columns:
        if any(ch.isspace() for ch in str(c)) or not str(c):
            raise InputError(f"{p}: channel name {c!r} has blanks; XYZ names must not")
    bool_cols = [c for c in body.columns if pd.api.types.is_bool_dtype(body[c].dtype)]
    if bool_cols:
        body = body.copy(deep=False)
        for c in bool_cols:
            body[c] = np.where(body[c].to_numpy(), "true", "false")
    text = body.to_csv(sep=" ", header=False, index=False, na_rep=_MISSING_XYZ,
                       lineterminator="\n")
    rows = text.splitlines()
    out: list[str] = [f"/ {title}", "/ " + " ".join(map(str, body.columns))]
    if has_line:
        ln = df["line"].to_numpy()
        kind = (df["line_type"].astype(str).str.lower().to_numpy() if "line_type" in df.columns
                else np.full(len(df), "line", dtype=object))
        starts = np.flatnonzero(np.r_[True, (ln[1:] != ln[:-1]) | (kind[1:] != kind[:-1])])
        stops = np.r_[starts[1:], len(df)]
        for a, b in zip(starts, stops, strict=True):
            word = "Tie" if kind[a] == "tie" else "Line"
            v = ln[a]
            label = (str(int(v)) if float(v) == int(v) else repr(float(v))) if np.isfinite(
                float(v)) else "0"
            out.append(f"{word} {label}")
            out.extend(rows[a:b])
    else:
        out.extend(rows)
    with atomic_path(p) as tmp:
        tmp.write_text("\n".join(out) + "\n", encoding="utf-8")
    return p
