"""Grid transforms of a total-field anomaly grid, through harmonica's FFT filters.

``rtp`` (reduction to the pole), ``dz`` (first vertical derivative), ``tilt`` (tilt angle) and
``up:H`` (upward continuation by H metres).

Signs follow the industry's maps (Oasis montaj's 1VD, GMT ``grdfft -D``, Miller & Singh 1994),
not harmonica's upward z: ``dz`` is the derivative downward, ``-dT/dz_up`` (positive over a
positive anomaly, where the field grows towards its source), and the tilt angle is
``atan(dz / |grad_h T|)``, +90 deg over a source at the pole, 0 over its edges.  harmonica's
``derivative_upward`` (and the ``tilt_angle`` built on it) is the opposite sign.

As harmonica documents, a grid is padded with :func:`xrft.pad` before the FFT and cut back
with :func:`xrft.unpad` after; blank (NaN) cells are filled with their nearest value for the
transform and blanked again in the result.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import xarray as xr

from ..errors import InputError
from .gridding import missing_extra

__all__ = ["MIN_RTP_INCLINATION_DEG", "Transform", "apply_transform", "parse_transforms"]

#: Reduction to the pole is refused below this |inclination| [deg]: the filter's amplitude
#: grows as 1/sin(I)^2 along the declination and blows up noise near the magnetic equator.
MIN_RTP_INCLINATION_DEG = 15.0


@dataclass(frozen=True)
class Transform:
    """One requested grid transform.

    Attributes
    ----------
    kind : str
        ``rtp``, ``dz``, ``tilt`` or ``up``.
    height_m : float or None
        Upward-continuation height [m] (``up`` only).
    """

    kind: str
    height_m: float | None = None

    @property
    def suffix(self) -> str:
        """Name suffix of the result (``rtp``, ``dz``, ``tilt``, ``up500``)."""
        if self.kind == "up":
            return f"up{self.height_m:g}"
        return self.kind


def parse_transforms(text: str | None) -> list[Transform]:
    """Parse ``rtp,dz,tilt,up:H`` into transforms.

    Parameters
    ----------
    text : str or None
        Comma-separated names; ``up:H`` with H in metres (> 0).

    Returns
    -------
    list of Transform

    Raises
    ------
    InputError
        An unknown name or a bad height.
    """
    out: list[Transform] = []
    for item in (text or "").split(","):
        item = item.strip().lower()
        if not item:
            continue
        name, _, arg = item.partition(":")
        if name in ("rtp", "dz", "tilt") and not arg:
            out.append(Transform(name))
        elif name == "up":
            try:
                h = float(arg)
            except ValueError:
                h = float("nan")
            if not (np.isfinite(h) and h > 0):
                raise InputError(f"--transform {item}: write up:H with H the height in metres"
                                 " (> 0), e.g. up:500")
            out.append(Transform("up", h))
        else:
            raise InputError(f"--transform {item}: unknown transform; use rtp, dz, tilt or up:H")
    return out


def _filled(grid: xr.DataArray) -> tuple[xr.DataArray, np.ndarray]:
    """The grid with NaN cells set to their nearest value, and the NaN mask."""
    from scipy.ndimage import distance_transform_edt

    values = grid.values
    blank = ~np.isfinite(values)
    if blank.all():
        raise InputError("the grid has no values to transform")
    if blank.any():
        idx = distance_transform_edt(blank, return_distances=False, return_indices=True)
        values = values[tuple(idx)]
    return grid.copy(data=values), blank


def apply_transform(grid: xr.DataArray, transform: Transform, *,
                    inclination_deg: float | None = None,
                    declination_deg: float | None = None) -> xr.DataArray:
    """Apply one transform to a grid (dims ``y``, ``x``; regular spacing in metres).

    Parameters
    ----------
    grid : xarray.DataArray
        Total-field anomaly [nT], NaN where blank.
    transform : Transform
        What to compute.
    inclination_deg, declination_deg : float, optional
        Direction of the main field [deg] (inclination positive down, declination east of
        north), needed by ``rtp``; the magnetisation is assumed induced (along the field).

    Returns
    -------
    xarray.DataArray
        The transformed grid (``rtp`` and ``up`` [nT], ``dz`` [nT/m], positive down: over a
        positive anomaly; ``tilt`` [deg], positive over the source), blank where the input is.

    Raises
    ------
    InputError
        ``rtp`` without a field direction, or at |inclination| below
        :data:`MIN_RTP_INCLINATION_DEG`.
    """
    try:
        import xrft
    except ImportError:
        raise missing_extra("xrft") from None

    if transform.kind == "rtp":
        if inclination_deg is None or declination_deg is None:
            raise InputError("--transform rtp needs the field's direction: give --field-dir"
                             " INC,DEC (degrees) or --date for the IGRF")
        if abs(inclination_deg) < MIN_RTP_INCLINATION_DEG:
            raise InputError(
                f"--transform rtp: the field's inclination is {inclination_deg:.1f} deg;"
                f" reduction to the pole is unstable below |I| = {MIN_RTP_INCLINATION_DEG:g}"
                " deg (the filter amplifies noise along the declination): use dz, tilt or"
                " an analytic signal instead")
    filled, blank = _filled(grid)
    mean = float(filled.mean())
    work = filled - mean
    pad = {d: max(work.sizes[d] // 3, 1) for d in work.dims}
    with warnings.catch_warnings():
        # xrft and harmonica's own deprecation notices (Dataset.drop, ifft's lag), not the
        # user's: harmonica passes the lag it means
        warnings.simplefilter("ignore", FutureWarning)
        out, units = _filter(xrft.pad(work, pad), transform, inclination_deg, declination_deg)
        out = xrft.unpad(out, pad)
    if transform.kind in ("rtp", "up"):
        out = out + mean
    # xrft's unpad keeps the padded coordinates' floating values: put the grid's back exactly
    return xr.DataArray(np.where(blank, np.nan, np.asarray(out.values, dtype=float)),
                        coords=grid.coords, dims=grid.dims,
                        name=f"{grid.name or 'grid'}_{transform.suffix}",
                        attrs={**grid.attrs, "units": units, "grid_transform": transform.suffix})


def _filter(padded: xr.DataArray, transform: Transform, inc: float | None,
            dec: float | None) -> tuple[xr.DataArray, str]:
    try:
        import harmonica as hm
    except ImportError:
        raise missing_extra("harmonica") from None

    if transform.kind == "rtp":
        return hm.reduction_to_pole(padded, inclination=inc, declination=dec), "nT"
    if transform.kind in ("dz", "tilt"):
        # harmonica's derivative is upward (negative over a positive anomaly): the maps'
        # vertical derivative and Miller & Singh's tilt take it downward
        down = -hm.derivative_upward(padded)
        if transform.kind == "dz":
            return down, "nT/m"
        horiz = np.hypot(hm.derivative_easting(padded), hm.derivative_northing(padded))
        return np.degrees(np.arctan2(down, horiz)), "degree"
    return hm.upward_continuation(padded, transform.height_m), "nT"
