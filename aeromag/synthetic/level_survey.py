"""A levelling survey with ground truth: lines, ties, lag, diurnal, IGRF and line errors.

Independent of :mod:`aeromag.survey` (a true oracle): the aircraft flies parametric tracks
(straight lines with curved run-ins and a slow cross-track wander, lines in alternating
directions, then the ties), the anomaly is the total-field anomaly of buried dipoles, the
main field is IGRF-14 evaluated with ``ppigrf`` at the exact positions and times, the
diurnal variation is a sum of slow sinusoids seen identically by a base station (with its own
noise and level), the magnetometer lags the position, and each line carries a level error (a
shift and an end-to-end trend; ties a shift).

The reading at time t is ``IGRF(p(t - lag), t) + anomaly(p(t - lag)) + diurnal(t) +
line_error + noise``, ``p`` the track; the truth columns are at ``p(t)``.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from .physics import dipole_field_ned, local_to_geodetic

__all__ = ["LevelSurveyScenario", "level_survey_anomaly", "simulate_level_survey"]


@dataclass
class LevelSurveyScenario:
    """Parameters of the simulated levelling survey.

    Attributes
    ----------
    origin : (lat, lon, alt)
        South-west corner of the block [deg, deg, m above the ellipsoid].
    start_utc : str
        Start of the survey (ISO, UTC).
    n_lines, line_spacing_m, line_length_m : int, float, float
        Flight lines (east-west).
    n_ties : int
        Tie lines (north-south), spread over the block.
    speed_m_s, rate_hz : float
        Ground speed and sample rate.
    height_m : float
        Survey height above the origin [m]; ties fly ``tie_dh_m`` higher.
    lag_s : float
        Magnetometer lag [s].
    diurnal_nT : float
        Amplitude of the diurnal variation [nT].
    shift_nT, trend_nT, tie_shift_nT : float
        Std of the line shifts, of the lines' end-to-end trends and of the tie shifts [nT].
    noise_nT : float
        White magnetometer noise [nT].
    base_noise_nT : float
        Base-station noise [nT].
    base_level_nT : float
        The base station's mean field [nT].
    """

    origin: tuple[float, float, float] = (-20.0, 140.0, 200.0)
    start_utc: str = "2014-11-02T01:00:00"
    n_lines: int = 16
    line_spacing_m: float = 200.0
    line_length_m: float = 4000.0
    n_ties: int = 4
    speed_m_s: float = 50.0
    rate_hz: float = 10.0
    height_m: float = 80.0
    tie_dh_m: float = 5.0
    lag_s: float = 0.4
    diurnal_nT: float = 30.0
    shift_nT: float = 6.0
    trend_nT: float = 4.0
    tie_shift_nT: float = 2.0
    noise_nT: float = 0.03
    base_noise_nT: float = 0.05
    base_level_nT: float = 50500.0


def _dipoles(rng: np.random.Generator, sc: LevelSurveyScenario, n: int = 12
             ) -> tuple[np.ndarray, np.ndarray]:
    """Buried dipoles (NED positions, m, and moments, A m^2) under the block."""
    wx = sc.line_length_m
    wy = sc.line_spacing_m * (sc.n_lines - 1)
    east = rng.uniform(0.1 * wx, 0.9 * wx, n)
    north = rng.uniform(0.1 * wy, 0.9 * wy, n)
    depth = rng.uniform(250.0, 700.0, n)
    mom = rng.normal(0.0, 1.0, (n, 3)) * (depth[:, None] / 400.0) ** 3 * 4e7
    return np.column_stack([north, east, depth]), mom


def _dipole_anomaly(src_ned: np.ndarray, mom: np.ndarray, east: np.ndarray, north: np.ndarray,
                    up: np.ndarray, dirn: np.ndarray) -> np.ndarray:
    """Total-field anomaly [nT] of the dipoles at local east, north, up [m].

    Projected on the unit main-field directions ``dirn`` (NED, one row per point).
    """
    pts = np.column_stack([north, east, -up])
    b = sum(dipole_field_ned(pts, s, m) for s, m in zip(src_ned, mom, strict=True))
    return np.einsum("ij,ij->i", b, dirn)


def level_survey_anomaly(truth: dict[str, Any], east_m: Any, north_m: Any, up_m: Any,
                         when_utc: str | None = None) -> np.ndarray:
    """The simulated survey's true total-field anomaly at arbitrary points.

    The same dipoles and formula as the ``truth_anomaly`` column of
    :func:`simulate_level_survey` (which is this function at the samples), so a grid can be
    compared with the true field on its nodes.

    Parameters
    ----------
    truth : dict
        The truth returned by :func:`simulate_level_survey` (its ``dipoles`` and
        ``scenario``).
    east_m, north_m, up_m : array_like
        Points in the simulator's local east-north-up frame at ``scenario["origin"]`` [m]
        (:func:`~aeromag.synthetic.physics.geodetic_to_local` maps latitude, longitude and
        height into it; the lines fly at ``up = scenario["height_m"]``).
    when_utc : str, optional
        ISO UTC time of the main field whose direction projects the anomaly (default the
        survey's start; the direction changes by < 1e-4 degree over a survey).

    Returns
    -------
    ndarray
        Total-field anomaly [nT], the shape of the broadcast inputs.
    """
    import ppigrf

    sc = truth["scenario"]
    e, n, u = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (east_m, north_m, up_m)))
    shape = e.shape
    e, n, u = e.ravel(), n.ravel(), u.ravel()
    origin = tuple(float(v) for v in sc["origin"])
    lat, lon, alt = local_to_geodetic(e, n, u, origin)
    when = _dt.datetime.fromisoformat(when_utc or sc["start_utc"]).replace(tzinfo=None)
    be, bn, bu = ppigrf.igrf(lon, lat, alt / 1000.0, when)
    ned = np.column_stack([np.ravel(bn), np.ravel(be), -np.ravel(bu)])
    dirn = ned / np.linalg.norm(ned, axis=1)[:, None]
    src = np.asarray(truth["dipoles"]["ned_m"], dtype=float)
    mom = np.asarray(truth["dipoles"]["moment_Am2"], dtype=float)
    return _dipole_anomaly(src, mom, e, n, u, dirn).reshape(shape)


def _track(sc: LevelSurveyScenario, rng: np.random.Generator) -> list[dict[str, Any]]:
    """Parametric tracks: one dict per line (start time, direction, fixed coordinate...)."""
    tracks = []
    t = 0.0
    turn_s = 60.0
    run_in_s = 15.0
    for i in range(sc.n_lines):
        forward = i % 2 == 0
        length = sc.line_length_m
        tracks.append({"line": 100 + 10 * i, "type": "line", "t0": t, "axis": "east",
                       "fixed": i * sc.line_spacing_m, "start": 0.0 if forward else length,
                       "sign": 1.0 if forward else -1.0, "length": length,
                       "run_in_s": run_in_s, "phase": rng.uniform(0, 2 * np.pi, 3)})
        t += (length + 2 * run_in_s * sc.speed_m_s) / sc.speed_m_s + turn_s
    wy = sc.line_spacing_m * (sc.n_lines - 1)
    xs = np.linspace(0.1, 0.9, sc.n_ties) * sc.line_length_m
    for j, xt in enumerate(xs):
        forward = j % 2 == 0
        tracks.append({"line": 9000 + 10 * j, "type": "tie", "t0": t, "axis": "north",
                       "fixed": float(xt), "start": -100.0 if forward else wy + 100.0,
                       "sign": 1.0 if forward else -1.0, "length": wy + 200.0,
                       "run_in_s": run_in_s, "phase": rng.uniform(0, 2 * np.pi, 3)})
        t += (wy + 200.0 + 2 * run_in_s * sc.speed_m_s) / sc.speed_m_s + turn_s
    return tracks


def _position(tr: dict[str, Any], tau: np.ndarray, sc: LevelSurveyScenario
              ) -> tuple[np.ndarray, np.ndarray]:
    """East, north [m] of a track at tau seconds after its start (run-in included)."""
    v = sc.speed_m_s
    tin = tr["run_in_s"]
    along = tr["start"] + tr["sign"] * (v * (tau - tin))
    total = tr["length"] / v + 2 * tin
    # Curved run-in and run-out: up to 150 m off the line, joining it tangentially.
    ramp_in = np.clip(1.0 - tau / tin, 0.0, None) ** 2
    ramp_out = np.clip((tau - (total - tin)) / tin, 0.0, None) ** 2
    wander = sum(4.0 * np.sin(2 * np.pi * tau / p + ph)
                 for p, ph in zip((37.0, 71.0, 113.0), tr["phase"], strict=True))
    cross = tr["fixed"] + 150.0 * (ramp_in + ramp_out) + wander
    if tr["axis"] == "east":
        return along, cross
    return cross, along


def _diurnal(rng: np.random.Generator, amp: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    periods = rng.uniform(20.0, 180.0, 4) * 60.0
    w = rng.uniform(0.3, 1.0, 4)
    return periods, amp * w / w.sum(), rng.uniform(0, 2 * np.pi, 4)


def simulate_level_survey(seed: int = 0, scenario: LevelSurveyScenario | None = None,
                          **overrides: Any
                          ) -> tuple[pd.DataFrame, pd.DataFrame, dict[str, Any]]:
    """Simulate a survey with ties, its base-station record and the truth.

    Parameters
    ----------
    seed : int
        Random seed.
    scenario : LevelSurveyScenario, optional
        Parameters (default scenario); ``overrides`` replace fields.
    **overrides
        Scenario fields.

    Returns
    -------
    survey : DataFrame
        ``time`` (UTC s since 1970), ``lat``, ``lon``, ``alt``, ``line``, ``mag`` [nT] and
        ``truth_anomaly``, ``truth_diurnal``, ``truth_igrf``, ``truth_line_error`` [nT].
    base : DataFrame
        ``time``, ``mag`` at 1 Hz over the survey and 10 minutes either side.
    truth : dict
        The scenario, the lag, the line errors, the dipoles.
    """
    sc = scenario or LevelSurveyScenario()
    if overrides:
        sc = LevelSurveyScenario(**{**sc.__dict__, **overrides})
    rng = np.random.default_rng(seed)
    src_ned, mom = _dipoles(rng, sc)
    tracks = _track(sc, rng)
    start = _dt.datetime.fromisoformat(sc.start_utc).replace(tzinfo=_dt.UTC)
    t_start = start.timestamp()
    per, amp, ph = _diurnal(rng, sc.diurnal_nT)
    import ppigrf

    lat0, lon0, h0 = sc.origin
    rows = []
    errors = {}
    for tr in tracks:
        total = tr["length"] / sc.speed_m_s + 2 * tr["run_in_s"]
        tau = np.arange(0.0, total, 1.0 / sc.rate_hz)
        up = np.full(tau.size, sc.height_m + (sc.tie_dh_m if tr["type"] == "tie" else 0.0))
        up = up + 2.0 * np.sin(2 * np.pi * tau / 53.0 + tr["phase"][0])
        if tr["type"] == "line":
            shift = rng.normal(0, sc.shift_nT)
            trend = rng.normal(0, sc.trend_nT)
        else:
            shift, trend = rng.normal(0, sc.tie_shift_nT), 0.0
        errors[tr["line"]] = {"type": tr["type"], "shift_nT": shift, "trend_nT": trend}
        e_now, n_now = _position(tr, tau, sc)
        e_lag, n_lag = _position(tr, tau - sc.lag_s, sc)
        up_lag = np.interp(tau - sc.lag_s, tau, up)
        frac = np.clip(tau / total, 0, 1) - 0.5
        rows.append(dict(t=t_start + tr["t0"] + tau, e=e_now, n=n_now, u=up, el=e_lag,
                         nl=n_lag, ul=up_lag, line=np.full(tau.size, tr["line"], float),
                         err=shift + trend * frac))
    cat = {k: np.concatenate([r[k] for r in rows]) for k in rows[0]}
    lat, lon, alt = local_to_geodetic(cat["e"], cat["n"], cat["u"], (lat0, lon0, h0))
    lat_l, lon_l, alt_l = local_to_geodetic(cat["el"], cat["nl"], cat["ul"], (lat0, lon0, h0))
    # Main field (IGRF-14, exact) at the start and end of the survey, linear in time between.
    t = cat["t"]
    ends = [_dt.datetime.fromtimestamp(v, _dt.UTC).replace(tzinfo=None)
            for v in (t[0], t[-1])]

    def igrf_at(la: np.ndarray, lo: np.ndarray, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        # Exact at every 20th sample of each track (and its last), linear between (the main
        # field changes by < 1e-4 nT of curvature over 100 m); linear in time between the
        # survey's start and end.
        node = np.zeros(t.size, dtype=bool)
        node[::20] = True
        node[np.flatnonzero(np.diff(cat["line"]))] = True
        node[np.flatnonzero(np.diff(cat["line"])) + 1] = True
        node[-1] = True
        idx = np.flatnonzero(node)
        out = []
        for when in ends:
            e, n, u = ppigrf.igrf(lo[idx], la[idx], h[idx] / 1000.0, when)
            v = np.column_stack([np.ravel(n), np.ravel(e), -np.ravel(u)])
            out.append(np.column_stack([np.interp(np.arange(t.size), idx, v[:, k])
                                        for k in range(3)]))
        w = ((t - t[0]) / max(t[-1] - t[0], 1.0))[:, None]
        ned = (1 - w) * out[0] + w * out[1]
        return np.linalg.norm(ned, axis=1), ned

    f_now, ned_now = igrf_at(lat, lon, alt)
    f_lag, ned_lag = igrf_at(lat_l, lon_l, alt_l)
    unit = ned_lag / f_lag[:, None]

    an_lag = _dipole_anomaly(src_ned, mom, cat["el"], cat["nl"], cat["ul"], unit)
    an_now = _dipole_anomaly(src_ned, mom, cat["e"], cat["n"], cat["u"],
                             ned_now / f_now[:, None])

    def diurnal(tt: np.ndarray) -> np.ndarray:
        arg = 2 * np.pi * np.outer(tt - t_start, 1.0 / per) + ph
        return np.sin(arg) @ amp

    d = diurnal(t)
    mag = f_lag + an_lag + d + cat["err"] + rng.normal(0, sc.noise_nT, t.size)
    survey = pd.DataFrame({"time": t, "lat": lat, "lon": lon, "alt": alt, "line": cat["line"],
                           "mag": mag, "truth_anomaly": an_now,
                           "truth_diurnal": d - d.mean(), "truth_igrf": f_now,
                           "truth_line_error": cat["err"]})
    bt = np.arange(np.floor(t[0]) - 600.0, t[-1] + 600.0, 1.0)
    base = pd.DataFrame({"time": bt, "mag": sc.base_level_nT + diurnal(bt)
                         + rng.normal(0, sc.base_noise_nT, bt.size)})
    truth = {"seed": seed, "scenario": {k: (list(v) if isinstance(v, tuple) else v)
                                         for k, v in sc.__dict__.items()},
             "lag_s": sc.lag_s, "line_errors": {str(k): v for k, v in errors.items()},
             "ties": [tr["line"] for tr in tracks if tr["type"] == "tie"],
             "diurnal_mean_nT": float(d.mean()),
             "dipoles": {"ned_m": src_ned.tolist(), "moment_Am2": mom.tolist()}}
    return survey, base, truth
