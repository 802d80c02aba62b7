"""``aeromag compass``: online vector-magnetometer calibration of a log, file in, files out."""

from __future__ import annotations

import logging
import os

import numpy as np
import pandas as pd

from .._core.rls import check_forgetting
from ..compass.calibration import CompassResult, attitude_at_samples, calibrate_compass
from ..compass.reference import ReferenceField, explicit_field, igrf_field
from ..compass.report import CompassHistory, CompassMetrics, CompassReport, ExcitationSummary
from ..errors import InputError
from ._frame_files import frame_to_files

log = logging.getLogger(__name__)

__all__ = ["compass_file", "compass_frame"]

_ATTITUDE = ("heading", "pitch", "roll")
_FLUX = ("flux_x", "flux_y", "flux_z")
#: Rows of the parameter history kept in OUT.json (a coarse step).
HISTORY_POINTS = 200


def reference_for(df: pd.DataFrame, src: str, *, date: str | None,
                  earth_field: tuple[float, float, float] | None) -> ReferenceField:
    """The reference field of a log: explicit, or IGRF at its positions and date.

    Parameters
    ----------
    df : DataFrame
        The log (``lat``, ``lon``, ``alt`` needed for IGRF).
    src : str
        File name for messages.
    date : str or None
        ``YYYY-MM-DD``.
    earth_field : (F nT, I deg, D deg) or None
        Explicit field.

    Returns
    -------
    ReferenceField
    """
    if earth_field is not None:
        if date is not None:
            log.warning("earth_field given: date=%r is not used", date)
        try:
            f, i, d = earth_field
        except (TypeError, ValueError):  # (F, I) or a bare number: say what goes where
            raise InputError(f"{src}: earth_field={earth_field!r} is not three "
                             "numbers; give earth_field=(F, I, D): the intensity in nT, the "
                             "inclination and the declination in degrees") from None
        return explicit_field(f, i, d)
    missing = [c for c in ("lat", "lon", "alt") if c not in df.columns]
    if missing:
        raise InputError(f"{src}: no {', '.join(missing)} column(s) for the IGRF reference "
                         "field; give earth_field=(F, I, D) (nT, degrees) or map the "
                         "position columns with columns=...")
    if date is None:
        raise InputError(f"{src}: the IGRF reference field needs the flight's date: give "
                         "date='YYYY-MM-DD', or earth_field=(F, I, D)")
    pos = df[["lat", "lon", "alt"]].to_numpy(dtype=np.float64)
    ok = np.isfinite(pos).all(axis=1)
    if not ok.any():
        raise InputError(f"{src}: columns lat, lon, alt hold no complete position; give "
                         "earth_field=(F, I, D)")
    if not ok.all():
        # Rows without a fix (other sensors' rows): the position of the last fix (the field
        # changes by < 1 nT over hundreds of metres); rows before the first fix take it.
        pos = pd.DataFrame(pos).ffill().bfill().to_numpy()
    try:
        return igrf_field(pos[:, 0], pos[:, 1], pos[:, 2], date)
    except InputError as exc:
        raise InputError(f"{src}: {exc}") from None


def compass_frame(df: pd.DataFrame, *, forgetting: float = 0.975, date: str | None = None,
                  earth_field: tuple[float, float, float] | None = None, alpha: float = 1e4,
                  window_s: float = 5.0, source: str | None = None
                  ) -> tuple[pd.DataFrame, CompassReport, CompassResult]:
    """Calibrate a log in memory: the output table and the report.

    Parameters
    ----------
    df : DataFrame
        Log with ``time``, ``flux_x/y/z`` [nT], ``heading``, ``pitch``, ``roll`` [deg] and
        either ``lat``, ``lon``, ``alt`` (with ``date``) or an explicit ``earth_field``.
    forgetting : float
        lambda, 0 < lambda <= 1.
    date : str, optional
        Flight date ``YYYY-MM-DD`` for IGRF.
    earth_field : (float, float, float), optional
        Intensity [nT], inclination [deg], declination [deg].
    alpha : float
        Prior covariance scale.
    window_s : float
        Excitation window [s].
    source : str, optional
        File name for messages.

    Returns
    -------
    data : DataFrame
        ``df`` plus ``flux_cal_x/y/z``, ``mag_heading_cal``, ``heading_err_deg``.
    report : CompassReport
        The report (``to_dict()`` is OUT.json).
    result : CompassResult
    """
    src = source or str(df.attrs.get("source", "<log>"))
    lam = check_forgetting(forgetting)
    missing = [c for c in _FLUX if c not in df.columns]
    if missing:
        raise InputError(f"{src}: missing column(s) {', '.join(missing)} (the vector "
                         "magnetometer, nT); map them with columns={'NAME': 'SOURCE'}")
    missing = [c for c in _ATTITUDE if c not in df.columns]
    if missing:
        raise InputError(f"{src}: missing attitude column(s) {', '.join(missing)} (degrees); "
                         "the calibration rotates the Earth field into body axes with them; "
                         "map them with columns={'NAME': 'SOURCE'}")
    ref = reference_for(df, src, date=date, earth_field=earth_field)
    flux = df[list(_FLUX)].to_numpy(dtype=np.float64)
    hdg, pitch, roll = (df[c].to_numpy(dtype=np.float64) for c in _ATTITUDE)
    t = df["time"].to_numpy(dtype=np.float64)
    # A multi-rate log: magnetometer rows carry no attitude; interpolate it to them between
    # the attitude samples on either side (never across a gap).
    hdg, pitch, roll, filled = attitude_at_samples(t, hdg, pitch, roll,
                                                   np.isfinite(flux).all(axis=1))
    if filled.any():
        log.info("%s: attitude interpolated to %d magnetometer rows without one (multi-rate "
                 "log)", src, int(filled.sum()))
    try:
        res = calibrate_compass(flux, hdg, pitch, roll, ref.ned_nT, time_s=t, forgetting=lam,
                                alpha=alpha, window_s=window_s)
    except InputError as exc:
        raise InputError(f"{src}: {exc}") from None
    out = df.copy()
    cal = res.flux_cal_nT
    out["flux_cal_x"], out["flux_cal_y"], out["flux_cal_z"] = cal[:, 0], cal[:, 1], cal[:, 2]
    out["mag_heading_cal"] = res.mag_heading_cal
    out["heading_err_deg"] = res.heading_err_deg
    n = len(t)
    step = max(1, n // HISTORY_POINTS)
    idx = np.arange(0, n, step)
    if idx[-1] != n - 1:
        idx = np.r_[idx, n - 1]
    exc = ExcitationSummary(window_s=window_s, windows=res.excitation)
    if exc.n_insufficient:
        log.warning("%s: %d of %d windows of %g s did not excite enough to trust the estimate "
                    "(manoeuvres too small); see 'excitation' in the report", src,
                    exc.n_insufficient, exc.n_windows, window_s)
    h = res.metrics
    report = CompassReport(
        input=src, matrix=res.matrix.tolist(), offset_nT=res.offset_nT.tolist(),
        forgetting=lam, alpha=alpha, reference=ref.info,
        metrics=CompassMetrics(rms_deg=h.rms_deg, mean_deg=h.mean_deg,
                               max_abs_deg=h.max_abs_deg, n_samples=n,
                               n_skipped=int(res.skipped.sum()),
                               n_attitude_interpolated=int(filled.sum())),
        excitation=exc,
        history=CompassHistory(time=t[idx].tolist(), matrix=res.matrix_history[idx].tolist(),
                               offset_nT=res.offset_history_nT[idx].tolist()))
    return out, report, res


def compass_file(log_path: str | os.PathLike[str], out_path: str | os.PathLike[str], *,
                 forgetting: float = 0.975, date: str | None = None,
                 earth_field: tuple[float, float, float] | None = None,
                 columns: dict[str, str] | None = None, units: dict[str, str] | None = None,
                 alpha: float = 1e4, window_s: float = 5.0, fmt: str | None = None,
                 ) -> CompassReport:
    """Read a log, calibrate its vector magnetometer online, write OUT.csv and OUT.json.

    Parameters
    ----------
    log_path : path-like
        The log.
    out_path : path-like
        Output CSV; the report goes to OUT.json.  Both are written or neither.
    forgetting, date, earth_field, alpha, window_s
        See :func:`compass_frame`.
    columns, units : dict, optional
        Column map and unit conversions.
    fmt : str, optional
        Log format (default from the extension).

    Returns
    -------
    CompassReport
        The report written to OUT.json (with the warnings the command logged).
    """
    return frame_to_files(
        log_path, out_path, forgetting,
        lambda df: compass_frame(df, forgetting=forgetting, date=date, earth_field=earth_field,
                                 alpha=alpha, window_s=window_s, source=str(log_path)),
        columns=columns, units=units, fmt=fmt)
