"""``aeromag detect``, file in, files out: the particle-filter detector on a log."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..detection.alarms import Alarms
from ..detection.heading import CalmWindow
from ..detection.particle import DEFAULT_PARTICLES, DEFAULT_WINDOW, particle_detector
from ..detection.report import DetectReport
from ..errors import InputError
from ..io import atomic_path, json_path_for, read_log, write_csv, write_json
from .compensate import check_outputs

__all__ = ["detect_file", "detect_report", "pf_track_detector"]


def detect_report(res: Alarms, source: str) -> DetectReport:
    """The report of a detector run.

    See :meth:`~aeromag.detection.report.DetectReport.from_alarms`.

    Parameters
    ----------
    res : Alarms
        Output of :func:`aeromag.detection.particle.particle_detector`.
    source : str
        Input file name.

    Returns
    -------
    DetectReport
        Its ``to_dict()`` is OUT.json: ``input``, ``threshold``, ``window``, ``particles``,
        ``events`` (``start_time``, ``end_time``, ``n``), ``events_note`` (what an event
        means), ``n_alarms``, ``n_samples``, ``n_stat`` and ``settings`` (everything else
        the detector measured).
    """
    return DetectReport.from_alarms(res, source)


def detect_file(
    log_path: str | os.PathLike[str],
    out_path: str | os.PathLike[str],
    *,
    n_particles: int = DEFAULT_PARTICLES,
    window: int = DEFAULT_WINDOW,
    threshold: float | None = None,
    calm_window: CalmWindow = None,
    declination_deg: float = 0.0,
    seed: int = 0,
    columns: dict[str, str] | None = None,
    units: dict[str, str] | None = None,
    fmt: str | None = None,
    **kwargs: Any,
) -> DetectReport:
    """Read a log, run the particle-filter detector, write OUT.csv and OUT.json atomically.

    Parameters
    ----------
    log_path : path-like
        Log with ``time`` and the gyro and compass columns of
        :func:`aeromag.detection.particle.prepare_pf_inputs`.
    out_path : path-like
        Output CSV (the log plus ``pf_stat`` and ``pf_alarm``); the report goes to the same
        path with suffix ``.json``.
    n_particles, window : int
        Particles and ``M`` (compass samples).
    threshold : float, optional
        Threshold on ``S_k``; default from the calm window.
    calm_window : float, (float, float), str or None
        Calm reference window (default the first 30 s).
    declination_deg : float
        Declination for a fluxgate heading, degrees east.
    seed : int
        Random seed.
    columns, units : dict, optional
        Column map and unit conversions.
    fmt : str, optional
        Log format (default from the extension).
    **kwargs
        Passed to :func:`~aeromag.detection.particle.particle_detector`.

    Returns
    -------
    DetectReport
        The report (``to_dict()`` is what OUT.json holds).
    """
    out = Path(out_path)
    out_json = json_path_for(out)
    check_outputs(log_path, out, out_json)
    units, gyro_scale = _gyro_units(units, str(log_path))
    df = read_log(log_path, columns=columns, units=units, required=("time",), fmt=fmt)
    if gyro_scale != 1.0:
        for c in ("gyro_x", "gyro_y", "gyro_z"):
            if c in df:
                df[c] = df[c].to_numpy(dtype=np.float64) * gyro_scale
    res = particle_detector(df, n_particles=n_particles, window=window, threshold=threshold,
                            calm_window=calm_window, declination_deg=declination_deg,
                            seed=seed, source=str(log_path), **kwargs)
    data = df.copy()
    data["pf_stat"] = np.round(res.stat, 6)
    data["pf_alarm"] = res.alarm
    report = detect_report(res, str(log_path))
    with atomic_path(out) as tmp_csv, atomic_path(out_json) as tmp_json:
        write_csv(data, tmp_csv)
        doc = report.to_dict()
        write_json(doc, tmp_json)
    report.warnings = doc["warnings"]   # with those the command logged, as in the file
    return report


_GYRO_UNITS = {"rad/s": 1.0, "deg/s": float(np.pi / 180.0), "dps": float(np.pi / 180.0)}


def _gyro_units(units: dict[str, str] | None,
                source: str) -> tuple[dict[str, str] | None, float]:
    """Take ``units={'gyro': 'deg/s'}`` (or ``gyro_x/y/z``) out of ``units``.

    Parameters
    ----------
    units : dict or None
        Unit map (column or group -> unit).
    source : str
        File name quoted in errors.

    Returns
    -------
    (dict or None, float)
        The map without the gyro entries (field units only, for ``read_log``) and the factor
        that converts the gyro columns to rad/s.
    """
    if not units:
        return units, 1.0
    rest, scale = {}, 1.0
    for k, v in units.items():
        if k in ("gyro", "gyro_x", "gyro_y", "gyro_z"):
            key = v.strip().lower().replace("°", "deg")
            if key not in _GYRO_UNITS:
                raise InputError(f"{source}: units={{'{k}': '{v}'}}: unknown gyro unit; use "
                                 "rad/s or deg/s")
            scale = _GYRO_UNITS[key]
        else:
            rest[k] = v
    return (rest or None), scale


def pf_track_detector(*, calm_window: CalmWindow = None, declination_deg: float = 0.0,
                      n_particles: int = DEFAULT_PARTICLES, window: int = DEFAULT_WINDOW,
                      seed: int = 0, source: str = "<log>",
                      ) -> Callable[[pd.DataFrame], Alarms]:
    """The particle-filter detector as ``aeromag track --pf`` runs it on the log it read.

    Parameters
    ----------
    calm_window : float, (float, float), str or None
        Calm reference window (the heading detector's, default the first 30 s).
    declination_deg : float
        Declination for a fluxgate heading, degrees east.
    n_particles, window, seed : int
        As :func:`~aeromag.detection.particle.particle_detector`.
    source : str
        File name quoted in errors.

    Returns
    -------
    callable
        ``detector(df) -> Alarms`` (name ``"pf"``: ``track`` adds ``pf_alarm`` and combines
        it into ``alarm``).
    """
    def detector(df: pd.DataFrame) -> Alarms:
        return particle_detector(df, n_particles=n_particles, window=window,
                                 calm_window=calm_window, declination_deg=declination_deg,
                                 seed=seed, source=source)

    return detector
