"""A survey log to a grid: positions, the value column, the cell, the grid as ``xarray.Dataset``.

:func:`grid` is ``am.grid``: it takes a levelled log (``x_m``, ``y_m``, or ``lat``, ``lon``
projected to UTM), picks the value column (``tmi_mlev``, else ``tmi_lev``, else ``tmi``),
estimates the line spacing for the default cell (a fifth of it) and the default blanking
distance, runs :func:`~aeromag.survey.gridding.minimum_curvature` and returns the grid as a
Dataset with CF metadata (like verde's grids) and its :class:`GridSummary`.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
import xarray as xr

from .._core.geodesy import project, utm_epsg
from ..errors import InputError
from .gridding import (
    DEFAULT_TENSION,
    GridSummary,
    default_cell,
    estimate_line_spacing,
    minimum_curvature,
)
from .transforms import Transform, apply_transform

log = logging.getLogger(__name__)

__all__ = ["BLANK_LINE_SPACINGS", "GRID_COLUMNS", "GRID_VALUE_COLUMNS", "GridResult",
           "check_projected_crs", "grid", "grid_dataset", "survey_positions", "value_column"]

#: The value columns ``grid`` takes by default, in order of preference (interface.md).
GRID_VALUE_COLUMNS: tuple[str, ...] = ("tmi_mlev", "tmi_lev", "tmi")
#: The columns ``grid`` may use besides the value (positions, line, and for ``rtp``'s field
#: direction the time and height): what ``aeromag grid`` reads of a log.
GRID_COLUMNS: tuple[str, ...] = ("x_m", "y_m", "lat", "lon", "line", "time", "alt")
#: Default blanking distance, in line spacings: keeps the cells between adjacent lines (half a
#: spacing from both) and one missing line, blanks wider gaps and the outside.
BLANK_LINE_SPACINGS = 1.5


@dataclass(frozen=True)
class GridResult:
    """A grid and what made it (``ds, summary = am.grid(...)`` unpacks it).

    Attributes
    ----------
    dataset : xarray.Dataset
        The grid: one data variable named after the column [nT], coordinates ``x``, ``y``
        (cell centres, ascending, metres), the CRS as attribute ``crs`` (EPSG code) and as CF
        grid-mapping variable ``spatial_ref``.
    summary : GridSummary
        Cell, tension, iterations, misfit, statistics.
    crs : int
        EPSG code of the projected coordinates.
    value : str
        The gridded column.
    transforms : dict
        Transform suffix (``rtp``, ``dz``, ``tilt``, ``up500``) -> Dataset of that grid.
    field_direction : tuple of float or None
        (inclination, declination) [deg] used by ``rtp``.
    """

    dataset: xr.Dataset
    summary: GridSummary
    crs: int
    value: str
    transforms: dict[str, xr.Dataset]
    field_direction: tuple[float, float] | None = None

    def __iter__(self) -> Iterator[Any]:
        return iter((self.dataset, self.summary))

    def _repr_html_(self) -> str:  # Jupyter shows the Dataset
        return self.dataset._repr_html_()


def value_column(columns: Sequence[str], value: str | None, source: str = "<log>") -> str:
    """The column to grid: ``value`` when given, else ``tmi_mlev``, ``tmi_lev``, ``tmi``.

    Raises
    ------
    InputError
        Naming the missing column and the columns there are.
    """
    cols = [str(c) for c in columns]
    if value is not None:
        if value not in cols:
            raise InputError(f"{source}: no column {value!r} to grid (--value); columns are:"
                             f" {', '.join(cols[:20])}")
        return value
    for c in GRID_VALUE_COLUMNS:
        if c in cols:
            return c
    raise InputError(f"{source}: no tmi_mlev, tmi_lev or tmi column to grid; name one with"
                     f" --value COL (columns are: {', '.join(cols[:20])})")


def survey_positions(df: pd.DataFrame, crs: int | None = None, source: str = "<log>"
                     ) -> tuple[np.ndarray, np.ndarray, int]:
    """Projected positions of a log: ``x_m``, ``y_m`` when it has them, else ``lat``/``lon``.

    Parameters
    ----------
    df : DataFrame
        The log.
    crs : int, optional
        EPSG code.  ``x_m``/``y_m`` are taken as they are, in ``crs`` or ``df.attrs["crs"]``
        (or the UTM zone of the survey's centre when the log has lat/lon too); a ``crs`` other
        than ``df.attrs["crs"]`` re-projects lat/lon.  Without ``x_m``/``y_m``, lat/lon are
        projected to ``crs`` (default the UTM zone of the survey's centre).
    source : str
        Name of the log for messages.

    Returns
    -------
    x_m, y_m : ndarray
        Easting, northing [m].
    crs : int
        EPSG code.
    """
    has_ll = {"lat", "lon"} <= set(df.columns)
    known = df.attrs.get("crs")
    if {"x_m", "y_m"} <= set(df.columns) and not (
            crs is not None and known is not None and int(crs) != int(known) and has_ll):
        epsg = crs if crs is not None else known
        if epsg is None and has_ll:
            epsg = _utm(df, source)
        if epsg is None:
            raise InputError(f"{source}: x_m/y_m without a CRS: give --crs EPSG (the level"
                             " run's OUT.json has it)")
        check_projected_crs(int(epsg))
        return (df["x_m"].to_numpy(float), df["y_m"].to_numpy(float), int(epsg))
    if not {"lat", "lon"} <= set(df.columns):
        raise InputError(f"{source}: no positions: the log needs x_m and y_m, or lat and lon"
                         " (map them with --col lat=SOURCE --col lon=SOURCE)")
    epsg = check_projected_crs(int(crs)) if crs is not None else _utm(df, source)
    lat, lon = df["lat"].to_numpy(float), df["lon"].to_numpy(float)
    ok = np.isfinite(lat) & np.isfinite(lon)
    x = np.full(lat.shape, np.nan)
    y = np.full(lat.shape, np.nan)
    try:
        x[ok], y[ok] = project(lat[ok], lon[ok], epsg)
    except Exception as exc:  # noqa: BLE001 - pyproj's errors are the user's CRS
        raise InputError(f"--crs {epsg}: cannot project to it ({exc}); give a projected"
                         " EPSG code, e.g. a UTM zone") from None
    return x, y, epsg


def check_projected_crs(epsg: int) -> int:
    """Refuse an EPSG code that is not a projected CRS in metres (the grid's cells are metres).

    Parameters
    ----------
    epsg : int
        EPSG code.

    Returns
    -------
    int
        The code.

    Raises
    ------
    InputError
        An unknown code, a geographic CRS (degrees) or a projection in other units (feet).
    """
    from pyproj import CRS
    from pyproj.exceptions import CRSError

    try:
        crs = CRS.from_epsg(int(epsg))
    except CRSError:
        raise InputError(f"--crs {epsg}: not an EPSG code pyproj knows; give a projected EPSG"
                         " code in metres, e.g. a UTM zone (326NN north, 327NN south)") from None
    units = {a.unit_name for a in crs.axis_info[:2]}
    if not crs.is_projected or not units <= {"metre", "meter"}:
        kind = "projected" if crs.is_projected else "geographic"
        raise InputError(f"--crs {epsg}: {crs.name} is {kind} in {', '.join(sorted(units))},"
                         " not metres; give a projected EPSG code in metres, e.g. a UTM zone"
                         " (326NN north, 327NN south)")
    return int(epsg)


def _utm(df: pd.DataFrame, source: str) -> int:
    lat, lon = df["lat"].to_numpy(float), df["lon"].to_numpy(float)
    ok = np.isfinite(lat) & np.isfinite(lon)
    if not ok.any():
        raise InputError(f"{source}: no finite lat/lon positions")
    return int(utm_epsg(lat[ok], lon[ok]))


def grid_dataset(x_m: np.ndarray, y_m: np.ndarray, values: np.ndarray, name: str, crs: int,
                 units: str = "nT", attrs: dict | None = None) -> xr.Dataset:
    """A grid as an ``xarray.Dataset`` with CF metadata and the CRS.

    Parameters
    ----------
    x_m, y_m : ndarray
        Cell centres, ascending [m].
    values : ndarray
        ``(len(y), len(x))`` values, NaN where blank.
    name : str
        Name of the data variable.
    crs : int
        EPSG code.
    units : str
        Units of the values.
    attrs : dict, optional
        More attributes of the data variable.

    Returns
    -------
    xarray.Dataset
    """
    from pyproj import CRS

    cf = CRS.from_epsg(int(crs)).to_cf()
    cf["spatial_ref"] = cf.get("crs_wkt", "")
    cf["epsg_code"] = f"EPSG:{int(crs)}"
    var_attrs = {"units": units, "long_name": name, "crs": int(crs),
                 "grid_mapping": "spatial_ref", **(attrs or {})}
    x_attrs = {"standard_name": "projection_x_coordinate", "long_name": "easting",
               "units": "m", "axis": "X"}
    y_attrs = {"standard_name": "projection_y_coordinate", "long_name": "northing",
               "units": "m", "axis": "Y"}
    ds = xr.Dataset(
        {name: (("y", "x"), np.asarray(values, dtype=float), var_attrs)},
        coords={"x": ("x", np.asarray(x_m, float), x_attrs),
                "y": ("y", np.asarray(y_m, float), y_attrs),
                "spatial_ref": ((), np.int32(0), cf)},
        attrs={"Conventions": "CF-1.8", "crs": int(crs)},
    )
    return ds


def grid(
    data: pd.DataFrame, *, value: str | None = None, cell_m: float | None = None,
    blank_m: float | None = None, crs: int | None = None, tension: float = DEFAULT_TENSION,
    transforms: Sequence[Transform] = (), field_direction: tuple[float, float] | None = None,
    max_bytes: int | None = None,
) -> GridResult:
    """Grid one column of a levelled survey log by minimum curvature with tension.

    Parameters
    ----------
    data : DataFrame
        The log: ``x_m``, ``y_m`` [m] (or ``lat``, ``lon`` [deg]), the value column and,
        when it has one, ``line`` (used for the line spacing).
    value : str, optional
        Column to grid (default ``tmi_mlev``, else ``tmi_lev``, else ``tmi``).
    cell_m : float, optional
        Cell [m] (default a fifth of the median line spacing).
    blank_m : float, optional
        Cells farther than this from every sample are NaN [m] (default 1.5 line spacings;
        ``float('inf')`` blanks nothing).
    crs : int, optional
        EPSG code of the projection (default the UTM zone of the survey's centre).
    tension : float
        Tension T in [0, 1) (default 0.25).
    transforms : sequence of Transform
        Grid transforms to compute (see :func:`~aeromag.survey.transforms.parse_transforms`).
    field_direction : (float, float), optional
        Main-field inclination and declination [deg], for ``rtp``.
    max_bytes : int, optional
        Memory the solve may use (default half the physical memory).

    Returns
    -------
    GridResult
    """
    source = str(data.attrs.get("source", "<log>"))
    col = value_column(list(data.columns), value, source)
    x, y, epsg = survey_positions(data, crs, source)
    v = pd.to_numeric(data[col], errors="coerce").to_numpy(float)
    ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(v)
    if ok.sum() < 3:
        raise InputError(f"{source}: only {int(ok.sum())} sample(s) with a position and a"
                         f" {col} value: nothing to grid")
    line = data["line"].to_numpy() if "line" in data.columns else None
    if not ok.all():  # (no copy of complete samples)
        x, y, v = x[ok], y[ok], v[ok]
        line = line[ok] if line is not None else None
    del ok
    spacing = None
    try:
        spacing = estimate_line_spacing(x, y, line)
    except InputError as exc:
        if cell_m is None or blank_m is None:
            raise InputError(f"{source}: {exc}") from None
    # the tension acts at the default cell whatever the cell asked for (GMT's grid units at
    # the default cell); without a line spacing, at the cell itself
    tension_length = default_cell(spacing) if spacing is not None else None
    cell = float(cell_m) if cell_m is not None else default_cell(spacing)
    if blank_m is None:
        blank: float | None = BLANK_LINE_SPACINGS * spacing
    else:
        blank = None if not np.isfinite(blank_m) else float(blank_m)
    xg, yg, g, summary = minimum_curvature(x, y, v, cell_m=cell, tension=tension,
                                           blank_m=blank, line_spacing_m=spacing,
                                           max_bytes=max_bytes,
                                           tension_length_m=tension_length)
    ds = grid_dataset(xg, yg, g, col, epsg, attrs={"method": "minimum curvature with tension",
                                                   "tension": float(tension)})
    out: dict[str, xr.Dataset] = {}
    inc, dec = field_direction if field_direction is not None else (None, None)
    for t in transforms:
        da = apply_transform(ds[col], t, inclination_deg=inc, declination_deg=dec)
        out[t.suffix] = grid_dataset(xg, yg, da.values, str(da.name), epsg,
                                     units=da.attrs["units"],
                                     attrs={"grid_transform": t.suffix})
    return GridResult(ds, summary, epsg, col, out, field_direction)
