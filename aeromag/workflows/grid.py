"""``aeromag grid``, file in, files out: a levelled log to GRID.nc/.tif/.grd and GRID.json.

Read the log (any format of :mod:`aeromag.io`, compressed CSV too, with a column map), grid
one column (:func:`aeromag.survey.grids.grid`), write the grid, one grid per transform
(``GRID_rtp.nc`` ...), GRID.json and, on request, the map (PNG) as one set: all or none.
"""

from __future__ import annotations

import datetime as _dt
import json
import logging
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import InputError
from ..io import atomic_path, json_path_for, read_log, write_json
from ..io.grids import check_grid_path, write_grid
from ..io.outputs import check_outputs
from ..survey.gridding import DEFAULT_TENSION
from ..survey.grids import (
    GRID_COLUMNS,
    GRID_VALUE_COLUMNS,
    GridResult,
    grid,
    survey_positions,
    value_column,
)
from ..survey.transforms import parse_transforms

log = logging.getLogger(__name__)

__all__ = ["GridFiles", "field_direction", "grid_file", "transform_path"]


@dataclass(frozen=True)
class GridFiles:
    """What ``grid_file`` wrote.

    Attributes
    ----------
    result : GridResult
        The grid and its summary.
    grid_path, json_path : Path
        The grid and GRID.json.
    transform_paths : dict
        Transform suffix -> its grid file.
    map_path : Path or None
        The map (PNG), when asked.
    report : dict
        GRID.json's contents.
    """

    result: GridResult
    grid_path: Path
    json_path: Path
    transform_paths: dict[str, Path]
    map_path: Path | None
    report: dict


def transform_path(out: str | os.PathLike[str], suffix: str) -> Path:
    """``GRID_rtp.nc`` for ``GRID.nc`` and ``rtp``."""
    p = Path(out)
    return p.with_name(f"{p.stem}_{suffix}{p.suffix}")


def _parse_field_dir(text: str) -> tuple[float, float]:
    try:
        inc, dec = (float(v) for v in text.split(","))
    except ValueError:
        raise InputError(f"--field-dir {text}: write INC,DEC in degrees, e.g. -52.5,6.3"
                         ) from None
    if not (-90 <= inc <= 90 and np.isfinite(dec)):
        raise InputError(f"--field-dir {text}: the inclination must be in [-90, 90] degrees")
    return inc, dec


def field_direction(df: pd.DataFrame, field_dir: str | None, date: str | None,
                    source: str) -> tuple[tuple[float, float] | None, dict | None]:
    """The main field's (inclination, declination) [deg] for ``rtp``, and where it came from.

    ``field_dir`` (``INC,DEC``) when given; else the IGRF at the survey's mean position and
    height on ``date`` (YYYY-MM-DD) or, without it, on the median date of a ``time`` column in
    UTC seconds since 1970; else None.
    """
    if field_dir:
        inc, dec = _parse_field_dir(field_dir)
        return (inc, dec), {"source": "given", "inclination_deg": inc, "declination_deg": dec}
    if date is None and "time" in df.columns:
        t = pd.to_numeric(df["time"], errors="coerce").to_numpy(float)
        t = t[np.isfinite(t)]
        if t.size and np.median(t) > 3.2e8:  # epoch seconds (after 1980), not time of day
            date = _dt.datetime.fromtimestamp(float(np.median(t)), _dt.UTC
                                              ).date().isoformat()
    if date is None or not {"lat", "lon"} <= set(df.columns):
        return None, None
    from ..compass.reference import igrf_field

    lat = float(np.nanmean(df["lat"].to_numpy(float)))
    lon = float(np.nanmean(df["lon"].to_numpy(float)))
    alt = float(np.nanmedian(df["alt"].to_numpy(float))) if "alt" in df.columns else 0.0
    ref = igrf_field([lat], [lon], alt if np.isfinite(alt) else 0.0, date)
    n, e, d = ref.ned_nT[0]
    inc = float(np.degrees(np.arctan2(d, np.hypot(n, e))))
    dec = float(np.degrees(np.arctan2(e, n)))
    return (inc, dec), {"source": "IGRF-14", "date": date, "lat": lat, "lon": lon,
                        "inclination_deg": inc, "declination_deg": dec}


def grid_json_path(grid_path: str | os.PathLike[str]) -> Path:
    """GRID.json: the grid's path with the suffix ``.json`` (interface.md), ``g.nc`` -> ``g.json``.

    Unlike a log's report (:func:`aeromag.io.json_path_for`, ``OUT.parquet.json``), the grid's
    report is named as the contract fixes it for every grid format.
    """
    return Path(grid_path).with_suffix(".json")


def refuse_foreign_report(json_path: Path, out: Path) -> None:
    """Refuse a GRID.json that would replace another command's report.

    ``aeromag level ... -o lev.csv`` writes ``lev.json``; ``aeromag grid lev.csv -o lev.nc``
    would write ``lev.json`` too (GRID with the suffix ``.json``) and silently replace the
    level report, which also holds the CRS the grid reads.  Only an earlier grid report
    (one with ``cell_m`` and ``method``) may be replaced.

    Raises
    ------
    InputError
        When ``json_path`` exists and is not a grid report.
    """
    if not json_path.is_file():
        return
    try:
        doc = json.loads(json_path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        doc = None
    if isinstance(doc, dict) and "cell_m" in doc and "method" in doc:
        return
    raise InputError(f"-o {out}: its report {json_path} exists and is not a grid report (the"
                     " report of another output, e.g. the level run's); give another -o name,"
                     f" e.g. -o {out.with_name(out.stem + '_grid' + out.suffix)}")


def _crs_beside(path: Path) -> int | None:
    """The ``crs`` of the level run's OUT.json beside a levelled log, if there is one."""
    doc = json_path_for(path)
    if doc == path or not doc.is_file():
        return None
    try:
        crs = json.loads(doc.read_text(encoding="utf-8")).get("crs")
    except (OSError, ValueError, AttributeError):
        return None
    return int(crs) if isinstance(crs, int) and not isinstance(crs, bool) else None


def grid_file(
    log_path: str | os.PathLike[str], out_path: str | os.PathLike[str], *,
    value: str | None = None, cell_m: float | None = None, blank_m: float | None = None,
    crs: int | None = None, tension: float = DEFAULT_TENSION, transforms: str | None = None,
    field_dir: str | None = None, date: str | None = None,
    columns: Mapping[str, str] | None = None, fmt: str | None = None,
    map_path: str | os.PathLike[str] | None = None, max_bytes: int | None = None,
    progress: Callable[[int, int, str], None] | None = None,
) -> GridFiles:
    """Grid one column of a levelled log and write the grid files and GRID.json as a set.

    Parameters
    ----------
    log_path : path-like
        The log (``x_m``/``y_m`` or ``lat``/``lon``, the value column, ``line`` if any).
    out_path : path-like
        ``GRID.nc`` (netCDF), ``GRID.tif`` (GeoTIFF) or ``GRID.grd`` (Surfer ASCII);
        GRID.json beside it.
    value, cell_m, blank_m, crs, tension
        See :func:`aeromag.survey.grids.grid` (column, m, m, EPSG, -).
    transforms : str, optional
        ``rtp,dz,tilt,up:H``: one more grid per transform, ``GRID_rtp.nc`` ...
    field_dir : str, optional
        ``INC,DEC`` [deg] of the main field for ``rtp`` (default from the IGRF).
    date : str, optional
        YYYY-MM-DD for the IGRF field direction (default the log's ``time``).
    columns : mapping, optional
        Column map ``{name: source}`` (e.g. ``{"tmi": "total_field_anomaly_nt"}``).
    fmt : str, optional
        Log format (default from the extension).
    map_path : path-like, optional
        Also write the anomaly map there (PNG).
    max_bytes : int, optional
        Memory the solve may use.
    progress : callable, optional
        ``progress(done, total, step)`` as the steps (reading, gridding, writing, map) start.

    Returns
    -------
    GridFiles
    """
    src, out = Path(log_path), Path(out_path)
    check_grid_path(out)
    steps = parse_transforms(transforms)
    refuse_foreign_report(grid_json_path(out), out)
    outs = [out, grid_json_path(out)] + [transform_path(out, t.suffix) for t in steps]
    if map_path is not None:
        outs.append(Path(map_path))
    check_outputs(src, *outs)
    n_steps = 4 if map_path is not None else 3

    def report_step(done: int, step: str) -> None:
        if progress is not None:
            progress(done, n_steps, step)

    report_step(0, "reading")
    # Only the columns the grid uses: a levelled log has 15 or more (1e7 samples: 3.5 GB
    # read whole); the value candidates not taken are dropped once the value is chosen.
    # lat, lon, alt only when they may serve: no CRS known for x_m/y_m (no level report
    # beside the log, no --crs), a re-projection asked, or rtp's field direction.
    beside = _crs_beside(src)
    geo = beside is None or crs is not None or any(t.kind == "rtp" for t in steps)
    wanted = (value,) if value is not None else GRID_VALUE_COLUMNS
    cmap = dict(columns) if columns else None
    lean = [c for c in GRID_COLUMNS if geo or c not in ("lat", "lon", "alt")]
    df = read_log(src, columns=cmap, required=(), fmt=fmt, min_rows=3,
                  usecols=[*lean, *wanted])
    if not any(c in df.columns for c in wanted):  # the refusal names every column of the log
        df = read_log(src, columns=cmap, required=(), fmt=fmt, min_rows=3)
    elif not geo and not {"x_m", "y_m"} <= set(df.columns):  # positions from lat/lon, then
        df = read_log(src, columns=cmap, required=(), fmt=fmt, min_rows=3,
                      usecols=[*GRID_COLUMNS, *wanted])
    if value is None and any(c in df.columns for c in wanted):
        chosen = value_column(list(df.columns), None, str(src))
        for c in GRID_VALUE_COLUMNS:
            if c != chosen and c in df.columns:
                del df[c]
    if beside is not None:
        df.attrs["crs"] = beside
    direction, dir_info = (None, None)
    if any(t.kind == "rtp" for t in steps):
        direction, dir_info = field_direction(df, field_dir, date, str(src))
    report_step(1, "gridding")
    res = grid(df, value=value, cell_m=cell_m, blank_m=blank_m, crs=crs, tension=tension,
               transforms=steps, field_direction=direction, max_bytes=max_bytes)
    s = res.summary
    ds = res.dataset
    report = {
        "source": str(src), "value": res.value, "crs": res.crs, "cell_m": s.cell_m,
        "method": s.method, "n_points": s.n_points, "blank_m": s.blank_m,
        "tension": s.tension, "tension_length_m": s.tension_length_m,
        "n_blocks": s.n_blocks, "shape": list(s.shape),
        "x_m": [float(ds.x[0]), float(ds.x[-1])], "y_m": [float(ds.y[0]), float(ds.y[-1])],
        "line_spacing_m": s.line_spacing_m, "iterations": s.iterations,
        "residual": s.residual, "misfit_rms_nT": s.misfit_rms_nT, "n_blank": s.n_blank,
        "levels": s.levels, "stats": s.stats,
        "transforms": {k: str(transform_path(out, k).name) for k in res.transforms},
        "field_direction": dir_info, "output": out.name,
    }
    report_step(2, "writing")
    write_grid(ds, out)
    tpaths = {}
    for k, tds in res.transforms.items():
        tpaths[k] = write_grid(tds, transform_path(out, k))
    mp = None
    if map_path is not None:
        report_step(3, "map")
        from ..plot.grid_map import figure_png, plot_grid_map

        x, y, _ = survey_positions(df, res.crs, str(src))
        line = df["line"].to_numpy() if "line" in df.columns else None
        fig = plot_grid_map(ds, lines=(x, y), line_id=line)
        mp = Path(map_path)
        with atomic_path(mp) as tmp:  # in the set: appears with the grid or not at all
            tmp.write_bytes(figure_png(fig))
        report["map"] = mp.name
    jpath = write_json(report, grid_json_path(out))
    report_step(n_steps, "done")
    return GridFiles(res, out, jpath, tpaths, mp, report)
