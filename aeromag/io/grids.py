"""Grid files: netCDF (CF, EPSG) through xarray, GeoTIFF through rioxarray, Surfer ASCII.

Every writer is atomic (:func:`~aeromag.io.outputs.atomic_path`): inside a command's output set
the grid, its GRID.json and the transforms' grids appear together or not at all.

==========  ================================================================================
extension   format
==========  ================================================================================
``.nc``     netCDF-4 (h5netcdf engine): the Dataset as it is (``x``, ``y`` ascending, CF
            ``grid_mapping`` variable ``spatial_ref`` and attribute ``crs``), NaN blanks
``.tif``    GeoTIFF (rioxarray/rasterio): float32, north-up, nodata NaN, the EPSG code
``.grd``    Surfer 6 ASCII grid (``DSAA``), blanks 1.70141e38 (Surfer's blank value);
            it holds no CRS (GRID.json does)
==========  ================================================================================
"""

from __future__ import annotations

import io as _io
import os
from pathlib import Path

import numpy as np
import xarray as xr

from ..errors import InputError
from .outputs import atomic_path

__all__ = ["GRID_EXTENSIONS", "SURFER_BLANK", "check_grid_path", "read_grid", "write_grid"]

#: Grid file extensions and their formats.
GRID_EXTENSIONS = {".nc": "netcdf", ".tif": "geotiff", ".tiff": "geotiff", ".grd": "surfer"}
#: Surfer's blank value.
SURFER_BLANK = 1.70141e38


def check_grid_path(path: str | os.PathLike[str]) -> str:
    """The format of an output grid from its extension, or a one-line refusal."""
    p = Path(path)
    fmt = GRID_EXTENSIONS.get(p.suffix.lower())
    if fmt is None:
        raise InputError(f"-o {p}: unknown grid format {p.suffix or '(no extension)'!r}; use"
                         " .nc (netCDF), .tif (GeoTIFF) or .grd (Surfer ASCII)")
    return fmt


def _variable(ds: xr.Dataset) -> str:
    names = [n for n in ds.data_vars]
    if len(names) != 1:
        raise ValueError(f"a grid Dataset has one data variable, got {names}")
    return str(names[0])


def write_grid(ds: xr.Dataset, path: str | os.PathLike[str]) -> Path:
    """Write a grid Dataset (one data variable on ``y``, ``x``) atomically.

    Parameters
    ----------
    ds : xarray.Dataset
        The grid, as :func:`aeromag.survey.grids.grid_dataset` makes it.
    path : path-like
        ``.nc``, ``.tif`` or ``.grd``.

    Returns
    -------
    Path
    """
    target = Path(path)
    fmt = check_grid_path(target)
    name = _variable(ds)
    with atomic_path(target) as tmp:
        if fmt == "netcdf":
            enc = {name: {"zlib": True, "complevel": 4, "_FillValue": np.nan}}
            ds.to_netcdf(tmp, engine="h5netcdf", encoding=enc)
        elif fmt == "geotiff":
            _write_geotiff(ds, name, tmp)
        else:
            tmp.write_text(_surfer_text(ds[name]), encoding="ascii")
    return target


def _write_geotiff(ds: xr.Dataset, name: str, tmp: Path) -> None:
    import rioxarray  # noqa: F401 - registers the .rio accessor

    da = ds[name].astype("float32")
    da = da.isel(y=slice(None, None, -1))  # north-up rows, the GeoTIFF convention
    da = da.rio.set_spatial_dims(x_dim="x", y_dim="y")
    da = da.rio.write_crs(f"EPSG:{int(ds[name].attrs['crs'])}")
    da = da.rio.write_nodata(np.nan, encoded=False)
    da.attrs = {k: v for k, v in da.attrs.items() if isinstance(v, (str, int, float))}
    da.rio.to_raster(tmp, driver="GTiff", compress="deflate")


def _surfer_text(da: xr.DataArray) -> str:
    z = np.asarray(da.values, dtype=float)
    x, y = da["x"].values, da["y"].values
    good = z[np.isfinite(z)]
    zlo, zhi = (float(good.min()), float(good.max())) if good.size else (0.0, 0.0)
    buf = _io.StringIO()
    buf.write(f"DSAA\n{x.size} {y.size}\n{x[0]!r} {x[-1]!r}\n{y[0]!r} {y[-1]!r}\n"
              f"{zlo!r} {zhi!r}\n")
    np.savetxt(buf, np.where(np.isfinite(z), z, SURFER_BLANK), fmt="%.6g")
    return buf.getvalue()


def read_grid(path: str | os.PathLike[str]) -> xr.Dataset:
    """Read a netCDF grid written by :func:`write_grid` (loaded into memory, file closed).

    Parameters
    ----------
    path : path-like
        A ``.nc`` file.

    Returns
    -------
    xarray.Dataset
    """
    with xr.open_dataset(path, engine="h5netcdf") as ds:
        return ds.load()
