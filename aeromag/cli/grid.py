"""``aeromag grid``: a levelled log to a minimum-curvature grid (netCDF, GeoTIFF, Surfer).

The command's rows are added to the one option table (:mod:`aeromag.cli._options`) here, as
:mod:`aeromag.cli.online` does for ``compensate``; their names start with ``grid_`` so that
rows of other commands with the same flags (``level``'s ``--value``, ``--crs``) never clash.
"""

from __future__ import annotations

import inspect
from pathlib import Path

import typer

from ._app import setup_logging, user_errors
from ._options import OPTIONS, Option, Options, add_option, command
from ._progress import progress_bar

_GRID = frozenset({"grid"})
_REQUIRED = inspect.Parameter.empty  # no default: required

_ROWS = [
    Option("grid_log", (), Path, _REQUIRED, "Levelled log (CSV, .csv.xz, Parquet, ...): x_m, "
           "y_m (or lat, lon), the value column, line.", _GRID, metavar="LOG"),
    Option("grid_output", ("-o",), Path, _REQUIRED, "Output grid: .nc (netCDF), .tif "
           "(GeoTIFF) or .grd (Surfer ASCII); GRID.json beside it.", _GRID, metavar="GRID.nc"),
    Option("grid_value", ("--value",), str | None, None, "Column to grid (default tmi_mlev, "
           "else tmi_lev, else tmi).", _GRID, metavar="COL"),
    Option("grid_cell", ("--cell",), float | None, None, "Cell size, metres (default: a fifth "
           "of the median line spacing).", _GRID, metavar="M"),
    Option("grid_blank", ("--blank",), float | None, None, "Cells farther than M metres from "
           "every sample are empty (NaN) (default 1.5 line spacings; inf: none).", _GRID,
           metavar="M"),
    Option("grid_crs", ("--crs",), int | None, None, "Projected coordinate system, EPSG code "
           "(default: the UTM zone of the survey's centre, or the level run's OUT.json).",
           _GRID, metavar="EPSG"),
    Option("grid_tension", ("--tension",), float, 0.25, "Tension of the minimum-curvature "
           "surface, 0 (Briggs, smoothest) to <1 (no overshoot).", _GRID, metavar="T"),
    Option("grid_transform", ("--transform",), str | None, None, "Also write transformed "
           "grids GRID_NAME.ext: rtp (reduction to the pole), dz (first vertical derivative, down, "
           "nT/m, positive over highs), tilt (degrees, + over sources), up:H (upward "
           "continuation by H metres).", _GRID,
           metavar="rtp,dz,tilt,up:H"),
    Option("grid_field_dir", ("--field-dir",), str | None, None, "Main-field inclination and "
           "declination for rtp, degrees (default: IGRF at --date or the log's time).", _GRID,
           metavar="INC,DEC"),
    Option("grid_date", ("--date",), str | None, None, "UTC date of the survey for the IGRF "
           "field direction of rtp.", _GRID, metavar="YYYY-MM-DD"),
    Option("grid_map", ("--map",), Path | None, None, "Also write the anomaly map (shaded "
           "relief, flight lines, colour bar in nT) as PNG.", _GRID, metavar="MAP.png"),
    Option("grid_col", ("--col",), list[str] | None, None, "Column map, repeatable (e.g. "
           "tmi=total_field_anomaly_nt, lat=latitude, line=flight_line).", _GRID,
           metavar="NAME=SOURCE"),
    Option("grid_fmt", ("--format",), str | None, None, "Input format (default: from the "
           "extension).", _GRID, metavar="FORMAT"),
    Option("grid_verbose", ("-v", "--verbose"), bool, False, "Log progress details.", _GRID),
]
for _row in _ROWS:
    if _row.name not in {o.name for o in OPTIONS}:
        add_option(_row)


@command("grid")
def grid(opts: Options) -> None:
    """Grid one column of a levelled log by minimum curvature with tension.

    Blocks the samples to the cells (median, verde BlockReduce), solves the minimum-curvature
    surface with tension (Smith & Wessel 1990) coarse to fine, blanks cells far from every
    sample and writes GRID (.nc, .tif or .grd) and GRID.json (crs, cell_m, method, n_points,
    blank_m, tension, iterations, misfit, statistics); --transform adds GRID_rtp.nc, ...
    """
    setup_logging(opts.grid_verbose)
    from ..io import parse_column_map
    from ..workflows.grid import grid_file

    with user_errors(), progress_bar("grid") as progress:
        columns = parse_column_map(opts.grid_col or [], option="--col")
        res = grid_file(
            opts.grid_log, opts.grid_output, value=opts.grid_value, cell_m=opts.grid_cell,
            blank_m=opts.grid_blank, crs=opts.grid_crs, tension=opts.grid_tension,
            transforms=opts.grid_transform, field_dir=opts.grid_field_dir,
            date=opts.grid_date, columns=columns or None, fmt=opts.grid_fmt,
            map_path=opts.grid_map, progress=progress)
    s = res.result.summary
    ny, nx = s.shape
    extra = "".join(f", {p}" for p in res.transform_paths.values())
    if res.map_path is not None:
        extra += f", {res.map_path}"
    typer.echo(f"wrote {res.grid_path}{extra} and {res.json_path}: {res.result.value} on"
               f" {nx} x {ny} cells of {s.cell_m:g} m from {s.n_points:,} samples"
               f" ({s.n_blank:,} cells blank), misfit rms {s.misfit_rms_nT:.2f} nT")
