"""Synthetic flights with ground truth: a calibration flight, a survey and its plan.

The simulator is the project's ground truth for testing the compensation, the segment
screening and the track checks.  It is written independently of the fitting code (it does not
import :mod:`aeromag.tolles_lawson`): the aircraft interference is computed here from the
*true* body-frame field with the 16-term Tolles-Lawson convention of ``interface.md``.

Physics
-------
* The Earth field is fixed in the local north-east-down (NED) frame (:class:`EarthField`).
* Attitude is heading ``psi``, pitch ``theta``, roll ``phi`` [deg], aerospace ZYX; the body
  field is ``B_body = C_bn @ B_ned`` with ``C_bn = Rx(phi) Ry(theta) Rz(psi)``.
* Geology (survey only): buried dipoles 30-120 m below ground; the scalar sees the exact
  ``|B_earth + B_anomaly|``, the fluxgate the anomaly vector in the body frame.
* Diurnal: a few nT of slow variation (periods > 10 min), added to the scalar.
* Aircraft interference ``h = terms @ coef`` (nT), the 16 terms computed from the true body
  field, derivatives by :func:`numpy.gradient` against time per continuous stretch.
* Sensors: scalar ``mag`` = clean field + ``h`` + faults + white noise; fluxgate
  ``flux_x/y/z`` = true body field + fluxgate faults + white noise.
* Faults on chosen segments (``line`` ids): ``noise_burst``, ``onboard_source``,
  ``flux_bias``, ``scalar_drift`` (see :data:`FAULT_KINDS`).

Positions are built in metres in a local east-north-up tangent plane at ``origin`` and
converted to WGS84 latitude, longitude and ellipsoidal height with :mod:`pyproj` (topocentric
pipeline), whole arrays at a time.

Random numbers come from independent streams (geometry/attitude, sensor noise, faults), so
adding faults to a flight leaves everything else identical for the same seed.
"""

from __future__ import annotations

import functools
import logging
import os
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyproj

from .errors import InputError
from .io import write_csv, write_json

log = logging.getLogger(__name__)

#: |B| is scaled by this before entering induced and eddy terms [nT].
FIELD_SCALE_NT = 50000.0

#: The 16 Tolles-Lawson terms of ``interface.md``, in order.
TERM_NAMES: tuple[str, ...] = (
    "cx", "cy", "cz",
    "cx*cx", "cx*cy", "cx*cz", "cy*cy", "cy*cz",
    "cx*cx'", "cx*cy'", "cx*cz'", "cy*cx'", "cy*cy'", "cy*cz'", "cz*cx'", "cz*cy'",
)  # fmt: skip

#: Fault kinds, see :func:`simulate_calibration`.
FAULT_KINDS: tuple[str, ...] = ("noise_burst", "onboard_source", "flux_bias", "scalar_drift")

#: Default take-off point / local-frame origin: (lat [deg], lon [deg], alt [m, ellipsoidal]).
DEFAULT_ORIGIN: tuple[float, float, float] = (46.80, 7.15, 600.0)

#: Calibration manoeuvres in flight order on each heading and their amplitudes [deg].
MANOEUVRES: tuple[str, ...] = ("pitch", "roll", "yaw")
MANOEUVRE_AMPLITUDE_DEG: dict[str, float] = {"pitch": 5.0, "roll": 10.0, "yaw": 5.0}

#: Nominal calibration headings [deg]; ``truth_heading_leg`` is the index (N=0, E=1, S=2, W=3).
CAL_HEADINGS_DEG: tuple[float, ...] = (0.0, 90.0, 180.0, 270.0)

_MU0_4PI_NT = 100.0  # mu0 / (4 pi) in nT * m / A (1e-7 T m / A)


# --------------------------------------------------------------------------- physics
@dataclass(frozen=True)
class EarthField:
    """The main (core) field, fixed in the local north-east-down frame.

    Parameters
    ----------
    intensity_nT : float
        Total intensity F [nT].
    inclination_deg : float
        Inclination I [deg], positive down.
    declination_deg : float
        Declination D [deg], positive east of true north.
    """

    intensity_nT: float = 50000.0
    inclination_deg: float = 65.0
    declination_deg: float = 3.0

    @property
    def ned(self) -> np.ndarray:
        """The field vector ``(B_north, B_east, B_down)`` [nT], shape (3,)."""
        inc = np.deg2rad(self.inclination_deg)
        dec = np.deg2rad(self.declination_deg)
        return self.intensity_nT * np.array(
            [np.cos(inc) * np.cos(dec), np.cos(inc) * np.sin(dec), np.sin(inc)]
        )

    def to_dict(self) -> dict[str, float]:
        """Return the parameters as a JSON-ready dict (nT, deg)."""
        return {k: float(v) for k, v in asdict(self).items()}


def default_aircraft_coef() -> np.ndarray:
    """Return the 16 Tolles-Lawson coefficients of a typical multirotor.

    Permanent terms of tens of nT, induced terms of tens of nT and eddy terms of a few nT*s,
    so that attitude manoeuvres of +-5-10 deg give several nT peak-to-peak of interference.

    Returns
    -------
    ndarray, shape (16,)
        Coefficients in the order of :data:`TERM_NAMES`: permanent [nT], induced [nT],
        eddy [nT*s].
    """
    permanent = [28.0, -16.0, 34.0]
    induced = [45.0, -12.0, 18.0, 30.0, -9.0]
    eddy = [3.0, -1.5, 2.0, 1.2, -2.5, 1.0, -1.8, 2.2]
    return np.array(permanent + induced + eddy, dtype=float)


def ned_to_body_dcm(heading_deg: Any, pitch_deg: Any, roll_deg: Any) -> np.ndarray:
    """Direction cosine matrices from NED to body (aerospace ZYX), vectorised.

    Parameters
    ----------
    heading_deg, pitch_deg, roll_deg : array_like, shape (n,)
        Heading ``psi``, pitch ``theta`` and roll ``phi`` [deg].

    Returns
    -------
    ndarray, shape (n, 3, 3)
        ``C_bn = Rx(phi) @ Ry(theta) @ Rz(psi)``; ``v_body = C_bn @ v_ned``.
    """
    psi = np.deg2rad(np.atleast_1d(np.asarray(heading_deg, dtype=float)))
    th = np.deg2rad(np.atleast_1d(np.asarray(pitch_deg, dtype=float)))
    ph = np.deg2rad(np.atleast_1d(np.asarray(roll_deg, dtype=float)))
    psi, th, ph = np.broadcast_arrays(psi, th, ph)
    cps, sps = np.cos(psi), np.sin(psi)
    cth, sth = np.cos(th), np.sin(th)
    cph, sph = np.cos(ph), np.sin(ph)
    c = np.empty(psi.shape + (3, 3))
    c[..., 0, 0] = cth * cps
    c[..., 0, 1] = cth * sps
    c[..., 0, 2] = -sth
    c[..., 1, 0] = sph * sth * cps - cph * sps
    c[..., 1, 1] = sph * sth * sps + cph * cps
    c[..., 1, 2] = sph * cth
    c[..., 2, 0] = cph * sth * cps + sph * sps
    c[..., 2, 1] = cph * sth * sps - sph * cps
    c[..., 2, 2] = cph * cth
    return c


def body_field(b_ned: Any, heading_deg: Any, pitch_deg: Any, roll_deg: Any) -> np.ndarray:
    """Rotate NED field vectors into the body frame.

    Parameters
    ----------
    b_ned : array_like, shape (3,) or (n, 3)
        Field in NED [nT]; one vector for all samples or one per sample.
    heading_deg, pitch_deg, roll_deg : array_like, shape (n,)
        Attitude [deg].

    Returns
    -------
    ndarray, shape (n, 3)
        Body-frame field ``(x forward, y right, z down)`` [nT].
    """
    c = ned_to_body_dcm(heading_deg, pitch_deg, roll_deg)
    b = np.asarray(b_ned, dtype=float)
    if b.ndim == 1:
        return np.einsum("nij,j->ni", c, b)
    return np.einsum("nij,nj->ni", c, b)


def stretch_ids(time: Any, gap_factor: float = 1.5) -> np.ndarray:
    """Label continuous stretches of a log: a time step above ``gap_factor`` x median starts one.

    Parameters
    ----------
    time : array_like, shape (n,)
        Sample times [s], increasing.
    gap_factor : float
        A step longer than this multiple of the median step is a gap.

    Returns
    -------
    ndarray of int, shape (n,)
        Stretch index per sample, from 0.
    """
    t = np.asarray(time, dtype=float)
    if t.size < 2:
        return np.zeros(t.size, dtype=int)
    dt = np.diff(t)
    gap = dt > gap_factor * np.median(dt)
    return np.concatenate([[0], np.cumsum(gap)]).astype(int)


def gradient_by_stretch(values: Any, time: Any, stretch: Any | None = None) -> np.ndarray:
    """Time derivative by :func:`numpy.gradient`, never across a time gap.

    Parameters
    ----------
    values : array_like, shape (n,) or (n, k)
        Signals (any unit u).
    time : array_like, shape (n,)
        Sample times [s].
    stretch : array_like of int, shape (n,), optional
        Continuous-stretch labels (contiguous); from :func:`stretch_ids` when omitted.

    Returns
    -------
    ndarray
        d(values)/dt [u/s], same shape as ``values``; 0 on single-sample stretches.
    """
    x = np.asarray(values, dtype=float)
    t = np.asarray(time, dtype=float)
    s = stretch_ids(t) if stretch is None else np.asarray(stretch)
    out = np.zeros_like(x)
    bounds = np.flatnonzero(np.diff(s) != 0) + 1
    for lo, hi in zip(np.r_[0, bounds], np.r_[bounds, len(t)], strict=True):
        if hi - lo >= 2:
            out[lo:hi] = np.gradient(x[lo:hi], t[lo:hi], axis=0)
    return out


def tl_terms(b_body: Any, time: Any, stretch: Any | None = None) -> np.ndarray:
    """The 16 Tolles-Lawson terms of ``interface.md`` from a body-frame field.

    Parameters
    ----------
    b_body : array_like, shape (n, 3)
        Body-frame field [nT] (the simulator passes the true field).
    time : array_like, shape (n,)
        Sample times [s]; derivatives never cross a time gap.
    stretch : array_like of int, optional
        Continuous-stretch labels; from :func:`stretch_ids` when omitted.

    Returns
    -------
    ndarray, shape (n, 16)
        Columns in the order of :data:`TERM_NAMES`: cosines [1], induced [1], eddy [1/s].
    """
    b = np.asarray(b_body, dtype=float)
    bt = np.linalg.norm(b, axis=1)
    c = b / bt[:, None]
    d = gradient_by_stretch(c, time, stretch)
    s = bt / FIELD_SCALE_NT
    cx, cy, cz = c.T
    dx, dy, dz = d.T
    cols = [
        cx, cy, cz,
        s * cx * cx, s * cx * cy, s * cx * cz, s * cy * cy, s * cy * cz,
        s * cx * dx, s * cx * dy, s * cx * dz,
        s * cy * dx, s * cy * dy, s * cy * dz,
        s * cz * dx, s * cz * dy,
    ]  # fmt: skip
    return np.column_stack(cols)


def tl_interference(
    b_body: Any, time: Any, coef: Any | None = None, stretch: Any | None = None
) -> np.ndarray:
    """Aircraft interference ``h = terms @ coef``.

    Parameters
    ----------
    b_body : array_like, shape (n, 3)
        True body-frame field [nT].
    time : array_like, shape (n,)
        Sample times [s].
    coef : array_like, shape (16,), optional
        Coefficients (nT; eddy nT*s); :func:`default_aircraft_coef` when omitted.
    stretch : array_like of int, optional
        Continuous-stretch labels.

    Returns
    -------
    ndarray, shape (n,)
        Interference on the scalar magnetometer [nT].
    """
    k = default_aircraft_coef() if coef is None else _check_coef(coef)
    return tl_terms(b_body, time, stretch) @ k


def dipole_field_ned(points_ned: Any, source_ned: Any, moment_ned: Any) -> np.ndarray:
    """Field of a point dipole at many points.

    Parameters
    ----------
    points_ned : array_like, shape (n, 3)
        Observation points, local north/east/down [m].
    source_ned : array_like, shape (3,)
        Dipole position, north/east/down [m].
    moment_ned : array_like, shape (3,)
        Dipole moment [A*m^2] in NED.

    Returns
    -------
    ndarray, shape (n, 3)
        Field in NED [nT]: ``mu0/4pi (3 (m.r^) r^ - m) / r^3``.
    """
    r = np.asarray(points_ned, dtype=float) - np.asarray(source_ned, dtype=float)
    m = np.asarray(moment_ned, dtype=float)
    rn = np.linalg.norm(r, axis=1)
    rhat = r / rn[:, None]
    mr = rhat @ m
    return _MU0_4PI_NT * (3.0 * mr[:, None] * rhat - m) / rn[:, None] ** 3


# --------------------------------------------------------------------------- geodesy
@functools.lru_cache(maxsize=8)
def local_transformer(origin: tuple[float, float, float]) -> pyproj.Transformer:
    """A transformer between WGS84 geodetic and a local east-north-up tangent plane.

    Parameters
    ----------
    origin : (lat, lon, alt)
        Origin of the local frame: latitude, longitude [deg], ellipsoidal height [m].

    Returns
    -------
    pyproj.Transformer
        Forward: ``(lat [deg], lon [deg], alt [m]) -> (east, north, up) [m]``;
        ``direction="INVERSE"`` goes back.
    """
    lat0, lon0, h0 = (float(v) for v in origin)
    pipeline = (
        "+proj=pipeline +step +proj=axisswap +order=2,1 "
        "+step +proj=unitconvert +xy_in=deg +xy_out=rad "
        "+step +proj=cart +ellps=WGS84 "
        f"+step +proj=topocentric +ellps=WGS84 +lat_0={lat0!r} +lon_0={lon0!r} +h_0={h0!r}"
    )
    return pyproj.Transformer.from_pipeline(pipeline)


def local_to_geodetic(
    east: Any, north: Any, up: Any, origin: tuple[float, float, float] = DEFAULT_ORIGIN
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Convert local east/north/up [m] to WGS84 latitude, longitude [deg] and height [m].

    Parameters
    ----------
    east, north, up : array_like
        Local tangent-plane coordinates at ``origin`` [m].
    origin : (lat, lon, alt)
        Origin [deg, deg, m].

    Returns
    -------
    lat, lon, alt : ndarray
        [deg], [deg], [m above the ellipsoid].
    """
    tr = local_transformer(tuple(float(v) for v in origin))
    lat, lon, alt = tr.transform(
        np.asarray(east, dtype=float),
        np.asarray(north, dtype=float),
        np.asarray(up, dtype=float),
        direction="INVERSE",
    )
    return np.asarray(lat), np.asarray(lon), np.asarray(alt)


def geodetic_to_local(
    lat: Any, lon: Any, alt: Any, origin: tuple[float, float, float] = DEFAULT_ORIGIN
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Convert WGS84 latitude, longitude [deg], height [m] to local east/north/up [m].

    Parameters
    ----------
    lat, lon, alt : array_like
        [deg], [deg], [m above the ellipsoid].
    origin : (lat, lon, alt)
        Origin of the local frame [deg, deg, m].

    Returns
    -------
    east, north, up : ndarray
        [m].
    """
    tr = local_transformer(tuple(float(v) for v in origin))
    e, n, u = tr.transform(
        np.asarray(lat, dtype=float), np.asarray(lon, dtype=float), np.asarray(alt, dtype=float)
    )
    return np.asarray(e), np.asarray(n), np.asarray(u)


# --------------------------------------------------------------------------- helpers
def _check_coef(coef: Any) -> np.ndarray:
    k = np.asarray(coef, dtype=float).ravel()
    if k.shape != (16,) or not np.all(np.isfinite(k)):
        raise InputError(f"coef: expected 16 finite numbers in the order {', '.join(TERM_NAMES)}")
    return k


def _streams(seed: int, flight: int) -> tuple[np.random.Generator, ...]:
    """Independent generators: (geometry/attitude, sensor noise, faults)."""
    ss = np.random.SeedSequence([int(seed), flight])
    return tuple(np.random.default_rng(s) for s in ss.spawn(3))


def band_noise(
    rng: np.random.Generator, n: int, rate_hz: float, f_lo: float, f_hi: float, rms: float
) -> np.ndarray:
    """Band-limited Gaussian noise by spectral synthesis.

    Parameters
    ----------
    rng : numpy.random.Generator
        Random source.
    n : int
        Number of samples.
    rate_hz : float
        Sample rate [Hz].
    f_lo, f_hi : float
        Pass band [Hz].
    rms : float
        Standard deviation of the result (any unit u).

    Returns
    -------
    ndarray, shape (n,)
        Zero-mean noise [u] with spectrum confined to ``[f_lo, f_hi]`` (zeros when no
        frequency bin falls in the band).
    """
    f = np.fft.rfftfreq(n, 1.0 / rate_hz)
    band = (f >= f_lo) & (f <= f_hi) & (f > 0)
    spec = (rng.normal(size=f.size) + 1j * rng.normal(size=f.size)) * band
    x = np.fft.irfft(spec, n)
    sd = x.std()
    return x * (rms / sd) if sd > 0 else np.zeros(n)


def _taper(n: int, ramp: int) -> np.ndarray:
    """A window rising from 0 to 1 over ``ramp`` samples at each end (raised cosine)."""
    w = np.ones(n)
    r = max(1, min(ramp, n // 2))
    up = 0.5 - 0.5 * np.cos(np.pi * np.arange(r) / r)
    w[:r] = up
    w[n - r :] = up[::-1]
    return w


def _diurnal(rng: np.random.Generator, time: np.ndarray, amplitude_nT: float) -> tuple[
    np.ndarray, list[dict[str, float]]
]:
    """Slow diurnal variation: three sinusoids with periods of 15-120 min."""
    periods = rng.uniform(15.0, 120.0, 3) * 60.0
    weights = rng.uniform(0.3, 1.0, 3)
    amps = amplitude_nT * weights / weights.sum()
    phases = rng.uniform(0.0, 2 * np.pi, 3)
    arg = 2 * np.pi * np.outer(time, 1.0 / periods) + phases
    comps = [
        {"period_s": float(p), "amplitude_nT": float(a), "phase_rad": float(ph)}
        for p, a, ph in zip(periods, amps, phases, strict=True)
    ]
    return np.sin(arg) @ amps, comps


def _resolve_faults(
    faults: float | Mapping[int, str] | None, segments: np.ndarray, rng: np.random.Generator
) -> dict[int, str]:
    """Turn the ``faults`` argument into ``{segment_id: kind}``."""
    if faults is None:
        return {}
    if isinstance(faults, Mapping):
        known = set(int(s) for s in segments)
        out: dict[int, str] = {}
        for seg, kind in faults.items():
            if kind not in FAULT_KINDS:
                raise InputError(
                    f"faults: unknown kind {kind!r}; use one of {', '.join(FAULT_KINDS)}"
                )
            if int(seg) not in known:
                raise InputError(
                    f"faults: segment {seg!r} does not exist; segments are "
                    f"{int(segments.min())}..{int(segments.max())}"
                )
            out[int(seg)] = str(kind)
        return dict(sorted(out.items()))
    frac = float(faults)
    if not 0.0 <= frac <= 1.0:
        raise InputError(f"faults: fraction {frac!r} must be between 0 and 1")
    n = int(round(frac * len(segments)))
    if frac > 0 and n == 0:
        n = 1
    if n == 0:
        return {}
    chosen = np.sort(rng.choice(segments, size=n, replace=False))
    start = int(rng.integers(len(FAULT_KINDS)))
    return {int(s): FAULT_KINDS[(start + i) % len(FAULT_KINDS)] for i, s in enumerate(chosen)}


def _apply_faults(
    plan: dict[int, str],
    line: np.ndarray,
    time: np.ndarray,
    cos: np.ndarray,
    scale: np.ndarray,
    rate_hz: float,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
    """Fault effects: (scalar effect [nT], fluxgate bias [nT] (n, 3), kind per sample, records)."""
    n = len(line)
    scalar = np.zeros(n)
    flux = np.zeros((n, 3))
    kind_col = np.full(n, "", dtype=object)
    records: list[dict[str, Any]] = []
    for seg, kind in plan.items():
        idx = np.flatnonzero(line == seg)
        m = idx.size
        params: dict[str, Any]
        if kind == "noise_burst":
            sd = float(rng.uniform(1.0, 3.0))
            scalar[idx] = rng.normal(0.0, sd, m)
            params = {"std_nT": sd}
        elif kind == "onboard_source":
            # A source near the scalar sensor only: |B + b| ~ |B| + c.b for |b| << |B|.
            direction = rng.normal(size=3)
            direction /= np.linalg.norm(direction)
            perm = direction * rng.uniform(10.0, 40.0)
            effect = cos[idx] @ perm
            params = {"permanent_nT": perm.tolist(), "induced_nT": None}
            if rng.random() < 0.5:
                a = rng.normal(0.0, 8.0, (3, 3))
                a = 0.5 * (a + a.T)
                effect = effect + scale[idx] * np.einsum("ni,ij,nj->n", cos[idx], a, cos[idx])
                params["induced_nT"] = a.tolist()
            scalar[idx] = effect
        elif kind == "flux_bias":
            axis = int(rng.integers(3))
            bias = float(rng.choice([-1.0, 1.0]) * rng.uniform(100.0, 2000.0))
            flux[idx, axis] = bias
            params = {"axis": "xyz"[axis], "bias_nT": bias}
        else:  # scalar_drift
            walk_nt = float(rng.uniform(1.0, 4.0))
            inband_nt = float(rng.uniform(0.5, 2.0))
            walk = np.cumsum(rng.normal(size=m))
            walk -= walk[0]
            walk *= walk_nt / max(np.abs(walk).max(), 1e-12)
            inband = band_noise(rng, m, rate_hz, 0.1, 0.9, inband_nt)
            scalar[idx] = walk + inband
            params = {"walk_peak_nT": walk_nt, "inband_rms_nT": inband_nt}
        kind_col[idx] = kind
        t = time[idx]
        params.update({"t_start": float(t[0]), "t_end": float(t[-1])})
        records.append({"segment": int(seg), "kind": kind, "params": params})
        log.debug("fault %s on segment %d: %s", kind, seg, params)
    return scalar, flux, kind_col, records


def _assemble(
    *,
    time: np.ndarray,
    line: np.ndarray,
    enu: np.ndarray,
    heading: np.ndarray,
    pitch: np.ndarray,
    roll: np.ndarray,
    anomaly_ned: np.ndarray,
    diurnal: np.ndarray,
    earth: EarthField,
    coef: np.ndarray,
    noise_nT: float,
    flux_noise_nT: float,
    pos_noise_m: float,
    origin: tuple[float, float, float],
    rate_hz: float,
    fault_plan: dict[int, str],
    rng_noise: np.random.Generator,
    rng_fault: np.random.Generator,
) -> tuple[pd.DataFrame, list[dict[str, Any]]]:
    """Sensors, interference, faults and geodesy for one flight."""
    n = len(time)
    b_ned = earth.ned + anomaly_ned
    b_body = body_field(b_ned, heading, pitch, roll)
    bt = np.linalg.norm(b_ned, axis=1)
    anomaly = bt - earth.intensity_nT
    stretch = stretch_ids(time)
    h = tl_terms(b_body, time, stretch) @ coef
    clean = bt + diurnal
    noise = rng_noise.normal(0.0, noise_nT, n)
    flux_noise = rng_noise.normal(0.0, flux_noise_nT, (n, 3))
    pos_noise = rng_noise.normal(0.0, pos_noise_m, (n, 3))
    cos = b_body / np.linalg.norm(b_body, axis=1)[:, None]
    f_scalar, f_flux, f_kind, records = _apply_faults(
        fault_plan, line, time, cos, bt / FIELD_SCALE_NT, rate_hz, rng_fault
    )
    mag = clean + h + f_scalar + noise
    flux = b_body + f_flux + flux_noise
    meas = enu + pos_noise
    lat, lon, alt = local_to_geodetic(meas[:, 0], meas[:, 1], meas[:, 2], origin)
    df = pd.DataFrame(
        {
            "time": time,
            "line": line.astype(int),
            "lat": lat,
            "lon": lon,
            "alt": alt,
            "heading": np.mod(heading, 360.0),
            "pitch": pitch,
            "roll": roll,
            "flux_x": flux[:, 0],
            "flux_y": flux[:, 1],
            "flux_z": flux[:, 2],
            "mag": mag,
            "truth_mag_tl": h,
            "truth_mag_clean": clean,
            "truth_anomaly": anomaly,
            "truth_diurnal": diurnal,
            "truth_fault": f_kind.astype(str),
            "truth_fault_nT": f_scalar,
        }
    )
    return df, records


def _common_truth(
    kind: str,
    *,
    seed: int,
    rate_hz: float,
    earth: EarthField,
    coef: np.ndarray,
    noise_nT: float,
    flux_noise_nT: float,
    pos_noise_m: float,
    origin: tuple[float, float, float],
) -> dict[str, Any]:
    return {
        "flight": kind,
        "seed": int(seed),
        "rate_hz": float(rate_hz),
        "terms": list(TERM_NAMES),
        "coef": [float(c) for c in coef],
        "field_scale_nT": FIELD_SCALE_NT,
        "earth": earth.to_dict(),
        "earth_ned_nT": earth.ned.tolist(),
        "noise_nT": float(noise_nT),
        "flux_noise_nT": float(flux_noise_nT),
        "pos_noise_m": float(pos_noise_m),
        "origin": {"lat": float(origin[0]), "lon": float(origin[1]), "alt": float(origin[2])},
        "attitude_convention": "heading/pitch/roll deg, aerospace ZYX, "
        "C_bn = Rx(roll) Ry(pitch) Rz(heading)",
    }


def _check_positive(**values: float) -> None:
    for name, v in values.items():
        if not np.isfinite(v) or v <= 0:
            raise InputError(f"{name}: must be a positive number, got {v!r}")


def _check_nonneg(**values: float) -> None:
    for name, v in values.items():
        if not np.isfinite(v) or v < 0:
            raise InputError(f"{name}: must be zero or positive, got {v!r}")


# --------------------------------------------------------------------------- flights
def simulate_calibration(
    *,
    seed: int = 0,
    rate_hz: float = 10.0,
    n_boxes: int = 2,
    manoeuvre_s: float = 25.0,
    noise_nT: float = 0.02,
    flux_noise_nT: float = 0.5,
    earth: EarthField | None = None,
    coef: Any | None = None,
    faults: float | Mapping[int, str] | None = None,
    cut_turns: bool = True,
    origin: tuple[float, float, float] = DEFAULT_ORIGIN,
    speed_mps: float = 8.0,
    height_m: float = 100.0,
    turn_s: float = 20.0,
    turbulence_deg: float = 0.3,
    trim_pitch_deg: float = -3.0,
    diurnal_nT: float = 3.0,
    pos_noise_m: float = 0.02,
) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Simulate a calibration flight: boxes on the four cardinal headings with manoeuvres.

    Each box flies north, east, south and west (a square); on each heading the aircraft makes
    a pitch (+-5 deg), a roll (+-10 deg) and a yaw (+-5 deg) oscillation of ``manoeuvre_s``
    seconds each (a few cycles at a random period of 2.5-8 s, tapered at the ends), with small
    turbulence on all axes.  Each manoeuvre is its own ``line`` (``12 * n_boxes`` segments,
    ids from 0).  No geology (a calibration is flown high over quiet ground).

    Parameters
    ----------
    seed : int
        Random seed; the same seed gives the same flight.
    rate_hz : float
        Sample rate [Hz].
    n_boxes : int
        Number of boxes (four headings each).
    manoeuvre_s : float
        Duration of each manoeuvre [s].
    noise_nT : float
        Scalar magnetometer white noise [nT rms].
    flux_noise_nT : float
        Fluxgate white noise per axis [nT rms].
    earth : EarthField, optional
        Main field; ``EarthField()`` when omitted.
    coef : array_like, shape (16,), optional
        Aircraft TL coefficients [nT, nT*s]; :func:`default_aircraft_coef` when omitted.
    faults : float or dict or None
        None: no faults; a fraction in [0, 1]: that share of segments chosen at random, kinds
        cycled over :data:`FAULT_KINDS`; a dict ``{segment_id: kind}``.
    cut_turns : bool
        Cut the turns between headings out of the log (a time gap of ``turn_s``); otherwise
        keep them: the aircraft hovers at the corner and yaws by 90 deg over ``turn_s``
        (``line`` -1, ``truth_maneuver`` "turn", ``truth_heading_leg`` -1).
    origin : (lat, lon, alt)
        Take-off point and local-frame origin [deg, deg, m above the ellipsoid].
    speed_mps : float
        Ground speed along each leg [m/s].
    height_m : float
        Flight height above the origin [m].
    turn_s : float
        Duration of each cut turn [s].
    turbulence_deg : float
        Turbulence on heading, pitch and roll [deg rms], 0.05-1.5 Hz.
    trim_pitch_deg : float
        Mean pitch in forward flight [deg] (nose down is negative).
    diurnal_nT : float
        Diurnal amplitude scale [nT].
    pos_noise_m : float
        RTK position noise per axis [m rms].

    Returns
    -------
    log : DataFrame
        ``time`` [s], ``line``, ``lat``/``lon`` [deg], ``alt`` [m], ``heading``/``pitch``/
        ``roll`` [deg], ``flux_x/y/z`` [nT], ``mag`` [nT], ``truth_mag_tl`` [nT],
        ``truth_mag_clean`` [nT], ``truth_anomaly`` [nT], ``truth_diurnal`` [nT],
        ``truth_fault`` (kind or ""), ``truth_fault_nT`` (fault effect on ``mag``, nT),
        ``truth_maneuver`` ("pitch"/"roll"/"yaw"), ``truth_heading_leg`` (N=0, E=1, S=2, W=3).
    truth : dict
        JSON-ready ground truth: terms, coef, earth field, noise levels, rate, seed, faults
        (``[{"segment", "kind", "params"}]``), segments and diurnal components.
    """
    _check_positive(rate_hz=rate_hz, manoeuvre_s=manoeuvre_s, speed_mps=speed_mps)
    _check_nonneg(noise_nT=noise_nT, flux_noise_nT=flux_noise_nT, turn_s=turn_s,
                  turbulence_deg=turbulence_deg, pos_noise_m=pos_noise_m)
    if int(n_boxes) < 1:
        raise InputError(f"n_boxes: must be at least 1, got {n_boxes!r}")
    earth = earth or EarthField()
    k = default_aircraft_coef() if coef is None else _check_coef(coef)
    rng, rng_noise, rng_fault = _streams(seed, 1)
    m = int(round(manoeuvre_s * rate_hz))
    if m < 20:
        raise InputError(f"manoeuvre_s: {manoeuvre_s} s at {rate_hz} Hz gives under 20 samples")
    n_leg = len(MANOEUVRES) * m
    gap = float(turn_s) if cut_turns else 0.0

    times, lines, enus, hdgs, pits, rols, mans, legs = [], [], [], [], [], [], [], []
    segments: list[dict[str, Any]] = []
    t0 = 0.0
    pos = np.array([0.0, 0.0, float(height_m)])  # east, north, up
    seg = 0
    ramp = int(round(2.0 * rate_hz))
    for box in range(int(n_boxes)):
        for leg, hdg in enumerate(CAL_HEADINGS_DEG):
            last = box == int(n_boxes) - 1 and leg == len(CAL_HEADINGS_DEG) - 1
            tau = np.arange(n_leg) / rate_hz
            t = t0 + tau
            direction = np.array([np.sin(np.deg2rad(hdg)), np.cos(np.deg2rad(hdg)), 0.0])
            enus.append(pos + np.outer(tau * speed_mps, direction))
            att = {
                ax: band_noise(rng, n_leg, rate_hz, 0.05, 1.5, turbulence_deg)
                for ax in MANOEUVRES
            }
            man_col = np.empty(n_leg, dtype=object)
            line_col = np.empty(n_leg, dtype=int)
            for j, man in enumerate(MANOEUVRES):
                sl = slice(j * m, (j + 1) * m)
                period = float(rng.uniform(2.5, 8.0))
                phase = float(rng.uniform(0, 2 * np.pi))
                amp = MANOEUVRE_AMPLITUDE_DEG[man]
                att[man][sl] += (
                    amp * _taper(m, ramp) * np.sin(2 * np.pi * tau[:m] / period + phase)
                )
                man_col[sl] = man
                line_col[sl] = seg
                segments.append({
                    "line": seg, "maneuver": man, "heading_deg": hdg, "heading_leg": leg,
                    "period_s": period, "amplitude_deg": amp,
                    "t_start": float(t[sl][0]), "t_end": float(t[sl][-1]),
                })  # fmt: skip
                seg += 1
            times.append(t)
            lines.append(line_col)
            hdgs.append(hdg + att["yaw"])
            pits.append(trim_pitch_deg + att["pitch"])
            rols.append(att["roll"])
            mans.append(man_col)
            legs.append(np.full(n_leg, leg))
            pos = enus[-1][-1] + direction * speed_mps / rate_hz
            t0 = t[-1] + 1.0 / rate_hz + gap
            if not cut_turns and turn_s > 0 and not last:
                # Kept turn: hover at the corner and yaw smoothly by +90 deg (line -1).
                nt = max(2, int(round(turn_s * rate_hz)))
                frac = 0.5 - 0.5 * np.cos(np.pi * np.arange(nt) / nt)
                times.append(t0 + np.arange(nt) / rate_hz)
                lines.append(np.full(nt, -1))
                enus.append(np.repeat(pos[None, :], nt, axis=0))
                hdgs.append(hdg + 90.0 * frac + band_noise(rng, nt, rate_hz, 0.05, 1.5,
                                                             turbulence_deg))
                pits.append(band_noise(rng, nt, rate_hz, 0.05, 1.5, turbulence_deg))
                rols.append(band_noise(rng, nt, rate_hz, 0.05, 1.5, turbulence_deg))
                mans.append(np.full(nt, "turn", dtype=object))
                legs.append(np.full(nt, -1))
                t0 += nt / rate_hz

    time = np.concatenate(times)
    diurnal, diurnal_comps = _diurnal(rng, time, diurnal_nT)
    line = np.concatenate(lines)
    plan = _resolve_faults(faults, np.unique(line[line >= 0]), rng_fault)
    df, records = _assemble(
        time=time, line=line, enu=np.concatenate(enus), heading=np.concatenate(hdgs),
        pitch=np.concatenate(pits), roll=np.concatenate(rols),
        anomaly_ned=np.zeros((len(time), 3)), diurnal=diurnal, earth=earth, coef=k,
        noise_nT=noise_nT, flux_noise_nT=flux_noise_nT, pos_noise_m=pos_noise_m,
        origin=origin, rate_hz=rate_hz, fault_plan=plan, rng_noise=rng_noise,
        rng_fault=rng_fault,
    )  # fmt: skip
    df["truth_maneuver"] = np.concatenate(mans).astype(str)
    df["truth_heading_leg"] = np.concatenate(legs).astype(int)
    truth = _common_truth(
        "calibration", seed=seed, rate_hz=rate_hz, earth=earth, coef=k, noise_nT=noise_nT,
        flux_noise_nT=flux_noise_nT, pos_noise_m=pos_noise_m, origin=origin,
    )  # fmt: skip
    truth.update({
        "n_boxes": int(n_boxes), "manoeuvre_s": float(manoeuvre_s), "cut_turns": bool(cut_turns),
        "turn_s": float(gap), "speed_mps": float(speed_mps), "height_m": float(height_m),
        "headings_deg": list(CAL_HEADINGS_DEG), "faults": records, "segments": segments,
        "diurnal": diurnal_comps,
    })  # fmt: skip
    log.info("calibration: %d samples, %d segments, %d faults", len(df), seg, len(records))
    return df, truth


def simulate_survey(
    *,
    seed: int = 0,
    rate_hz: float = 10.0,
    n_lines: int = 8,
    line_length_m: float = 400.0,
    spacing_m: float = 25.0,
    speed_mps: float = 8.0,
    line_azimuth_deg: float = 0.0,
    height_m: float = 50.0,
    noise_nT: float = 0.02,
    flux_noise_nT: float = 0.5,
    earth: EarthField | None = None,
    coef: Any | None = None,
    faults: float | Mapping[int, str] | None = None,
    origin: tuple[float, float, float] = DEFAULT_ORIGIN,
    n_dipoles: int = 5,
    gust_deg: float = 2.0,
    yaw_wobble_deg: float = 1.0,
    trim_pitch_deg: float = -3.0,
    diurnal_nT: float = 3.0,
    wander_m: float = 0.1,
    pos_noise_m: float = 0.02,
    turn_s: float = 15.0,
) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Simulate a survey: parallel lines flown alternately in opposite directions.

    Line ``k`` (``line`` id ``k``) starts at ``k * spacing_m`` to the right of the first line;
    even lines fly along ``line_azimuth_deg``, odd lines the opposite way; the first line starts
    at the origin.  Turns between lines are cut out (a time gap).  A multirotor in gusty wind:
    pitch/roll wobble of ``gust_deg`` rms at 0.1-1 Hz and ``yaw_wobble_deg`` of yaw, enough
    in-band attitude motion for the survey to be self-compensated.  Geology (``n_dipoles``
    buried dipoles, 30-120 m deep, peaks of 5-30 nT), diurnal, a small smooth cross-track and
    vertical wander and RTK noise on the positions.

    Parameters
    ----------
    seed : int
        Random seed.
    rate_hz : float
        Sample rate [Hz].
    n_lines : int
        Number of survey lines.
    line_length_m : float
        Line length [m]; the first and last sample of each line are at its ends.
    spacing_m : float
        Line spacing [m].
    speed_mps : float
        Ground speed [m/s] (adjusted slightly so that a line holds a whole number of samples).
    line_azimuth_deg : float
        Direction of the even lines [deg from north].
    height_m : float
        Flight height above the origin (ground) [m].
    noise_nT, flux_noise_nT : float
        Scalar and per-axis fluxgate white noise [nT rms].
    earth : EarthField, optional
        Main field.
    coef : array_like, shape (16,), optional
        Aircraft TL coefficients [nT, nT*s].
    faults : float or dict or None
        As in :func:`simulate_calibration` (segments are survey lines).
    origin : (lat, lon, alt)
        Take-off point / local-frame origin [deg, deg, m above the ellipsoid].
    n_dipoles : int
        Number of buried dipoles.
    gust_deg : float
        Pitch and roll wobble [deg rms], 0.1-1 Hz.
    yaw_wobble_deg : float
        Yaw wobble [deg rms], 0.05-0.5 Hz.
    trim_pitch_deg : float
        Mean pitch in forward flight [deg].
    diurnal_nT : float
        Diurnal amplitude scale [nT].
    wander_m : float
        Smooth cross-track wander [m rms] (half of it vertically), 0.01-0.2 Hz.
    pos_noise_m : float
        RTK position noise per axis [m rms].
    turn_s : float
        Duration of each cut turn [s] (plus the transit between lines).

    Returns
    -------
    log : DataFrame
        The columns of :func:`simulate_calibration` without ``truth_maneuver`` and
        ``truth_heading_leg``.
    truth : dict
        JSON-ready ground truth as for the calibration, plus ``plan`` (waypoints
        ``{"lat", "lon", "alt"}`` in flight order: start and end of each line), ``lines`` and
        ``dipoles``.
    """
    _check_positive(rate_hz=rate_hz, line_length_m=line_length_m, spacing_m=spacing_m,
                    speed_mps=speed_mps, height_m=height_m)
    _check_nonneg(noise_nT=noise_nT, flux_noise_nT=flux_noise_nT, gust_deg=gust_deg,
                  yaw_wobble_deg=yaw_wobble_deg, wander_m=wander_m, pos_noise_m=pos_noise_m,
                  turn_s=turn_s)
    if int(n_lines) < 1:
        raise InputError(f"n_lines: must be at least 1, got {n_lines!r}")
    earth = earth or EarthField()
    k = default_aircraft_coef() if coef is None else _check_coef(coef)
    rng, rng_noise, rng_fault = _streams(seed, 2)
    n = int(round(line_length_m / speed_mps * rate_hz)) + 1
    if n < 20:
        raise InputError(f"line_length_m: {line_length_m} m at {speed_mps} m/s is too short")
    az = np.deg2rad(line_azimuth_deg)
    along = np.array([np.sin(az), np.cos(az), 0.0])  # east, north, up
    right = np.array([np.cos(az), -np.sin(az), 0.0])
    up = np.array([0.0, 0.0, 1.0])
    s_along = np.linspace(0.0, line_length_m, n)
    tau = np.arange(n) / rate_hz
    gap = float(turn_s + spacing_m / speed_mps)

    times, lines, enus, hdgs, pits, rols = [], [], [], [], [], []
    waypoints_enu: list[np.ndarray] = []
    line_info: list[dict[str, Any]] = []
    t0 = 0.0
    for i in range(int(n_lines)):
        base = i * spacing_m * right + float(height_m) * up
        a, b = (base, base + line_length_m * along)
        if i % 2:
            a, b = b, a
        hdg = np.rad2deg(az) + (180.0 if i % 2 else 0.0)
        u = (b - a) / line_length_m
        xt = band_noise(rng, n, rate_hz, 0.01, 0.2, wander_m) * _taper(n, int(rate_hz * 3))
        zt = band_noise(rng, n, rate_hz, 0.01, 0.2, 0.5 * wander_m) * _taper(n, int(rate_hz * 3))
        enus.append(a + np.outer(s_along, u) + np.outer(xt, right) + np.outer(zt, up))
        hdgs.append(hdg + band_noise(rng, n, rate_hz, 0.05, 0.5, yaw_wobble_deg))
        pits.append(trim_pitch_deg + band_noise(rng, n, rate_hz, 0.1, 1.0, gust_deg))
        rols.append(band_noise(rng, n, rate_hz, 0.1, 1.0, gust_deg))
        t = t0 + tau
        times.append(t)
        lines.append(np.full(n, i))
        waypoints_enu += [a, b]
        line_info.append({"line": i, "heading_deg": float(np.mod(hdg, 360.0)),
                          "t_start": float(t[0]), "t_end": float(t[-1])})
        t0 = t[-1] + 1.0 / rate_hz + gap

    time = np.concatenate(times)
    enu = np.concatenate(enus)
    line = np.concatenate(lines)

    # Geology: dipoles under the survey area (plus a margin), moments mostly induced.
    wp = np.array(waypoints_enu)
    lo, hi = wp[:, :2].min(axis=0) - 50.0, wp[:, :2].max(axis=0) + 50.0
    e_unit = earth.ned / np.linalg.norm(earth.ned)
    sensor_ned = np.column_stack([enu[:, 1], enu[:, 0], -enu[:, 2]])
    anomaly_ned = np.zeros_like(sensor_ned)
    dipoles: list[dict[str, Any]] = []
    for _ in range(int(n_dipoles)):
        east, north = rng.uniform(lo, hi)
        depth = float(rng.uniform(30.0, 120.0))
        peak = float(rng.uniform(5.0, 30.0)) * rng.choice([-1.0, 1.0], p=[0.2, 0.8])
        rem = rng.normal(size=3)
        direction = e_unit + 0.5 * rem / np.linalg.norm(rem)
        direction /= np.linalg.norm(direction)
        moment = peak * (depth + height_m) ** 3 / (2.0 * _MU0_4PI_NT) * direction
        src = np.array([north, east, depth])
        anomaly_ned += dipole_field_ned(sensor_ned, src, moment)
        dipoles.append({"north_m": float(north), "east_m": float(east), "depth_m": depth,
                        "moment_ned_Am2": moment.tolist(), "nominal_peak_nT": float(peak)})

    diurnal, diurnal_comps = _diurnal(rng, time, diurnal_nT)
    plan = _resolve_faults(faults, np.unique(line), rng_fault)
    df, records = _assemble(
        time=time, line=line, enu=enu, heading=np.concatenate(hdgs),
        pitch=np.concatenate(pits), roll=np.concatenate(rols), anomaly_ned=anomaly_ned,
        diurnal=diurnal, earth=earth, coef=k, noise_nT=noise_nT, flux_noise_nT=flux_noise_nT,
        pos_noise_m=pos_noise_m, origin=origin, rate_hz=rate_hz, fault_plan=plan,
        rng_noise=rng_noise, rng_fault=rng_fault,
    )  # fmt: skip
    lat, lon, alt = local_to_geodetic(wp[:, 0], wp[:, 1], wp[:, 2], origin)
    truth = _common_truth(
        "survey", seed=seed, rate_hz=rate_hz, earth=earth, coef=k, noise_nT=noise_nT,
        flux_noise_nT=flux_noise_nT, pos_noise_m=pos_noise_m, origin=origin,
    )  # fmt: skip
    truth.update({
        "n_lines": int(n_lines), "line_length_m": float(line_length_m),
        "spacing_m": float(spacing_m), "speed_mps": float(line_length_m / ((n - 1) / rate_hz)),
        "line_azimuth_deg": float(line_azimuth_deg), "height_m": float(height_m),
        "turn_s": gap, "wander_m": float(wander_m), "faults": records, "lines": line_info,
        "dipoles": dipoles, "diurnal": diurnal_comps,
        "plan": [{"lat": float(a), "lon": float(b), "alt": float(c)}
                 for a, b, c in zip(lat, lon, alt, strict=True)],
        "plan_enu_m": wp.tolist(),
    })  # fmt: skip
    log.info("survey: %d samples, %d lines, %d faults", len(df), n_lines, len(records))
    return df, truth


def survey_plan(truth: Mapping[str, Any]) -> pd.DataFrame:
    """The survey's mission plan as a table.

    Parameters
    ----------
    truth : mapping
        The truth dict of :func:`simulate_survey`.

    Returns
    -------
    DataFrame
        Waypoints in flight order: ``lat``, ``lon`` [deg], ``alt`` [m above the ellipsoid];
        waypoints ``2k`` and ``2k+1`` are the start and end of survey line ``k``.
    """
    if "plan" not in truth:
        raise InputError("truth: no 'plan' (only survey truths carry one)")
    return pd.DataFrame.from_records(list(truth["plan"]), columns=["lat", "lon", "alt"])


#: Decimals written per column by :func:`write_simulation`.
ROUNDING: dict[str, int] = {
    "time": 3, "lat": 9, "lon": 9, "alt": 3, "heading": 4, "pitch": 4, "roll": 4,
    "flux_x": 4, "flux_y": 4, "flux_z": 4, "mag": 4, "truth_mag_tl": 4,
    "truth_mag_clean": 4, "truth_anomaly": 4, "truth_diurnal": 4, "truth_fault_nT": 4,
}  # fmt: skip


def round_log(df: pd.DataFrame) -> pd.DataFrame:
    """Round a simulated log for writing (see :data:`ROUNDING`; lat/lon 9 decimals ~0.1 mm).

    Parameters
    ----------
    df : DataFrame
        A simulated log.

    Returns
    -------
    DataFrame
        A rounded copy.
    """
    return df.round({k: v for k, v in ROUNDING.items() if k in df.columns})


def write_simulation(
    out_dir: str | os.PathLike[str],
    *,
    seed: int = 0,
    faults: float | None = 0.0,
    rate_hz: float = 10.0,
    small: bool = False,
) -> dict[str, Path]:
    """Write a calibration flight, a survey, its plan and the ground truth.

    Parameters
    ----------
    out_dir : path-like
        Output folder (created when missing).
    seed : int
        Random seed.
    faults : float or None
        Fraction of segments (of each flight) carrying a fault, in [0, 1].
    rate_hz : float
        Sample rate [Hz].
    small : bool
        The shipped sample size: one calibration box of 20 s manoeuvres (12 segments) and
        ten 160 m survey lines (enough segments for PCA screening); otherwise two boxes of
        25 s and eight 400 m lines.

    Returns
    -------
    dict of str to Path
        ``{"calibration": ..., "survey": ..., "plan": ..., "truth": ...}``: ``calibration.csv``,
        ``survey.csv``, ``plan.csv`` (survey waypoints) and ``truth.json``
        (``{"calibration": {...}, "survey": {...}}``), each written atomically.
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a folder; give -o a folder")
    _check_positive(rate_hz=rate_hz)
    cal_kw: dict[str, Any] = {"n_boxes": 1, "manoeuvre_s": 20.0} if small else {}
    sur_kw: dict[str, Any] = {"n_lines": 10, "line_length_m": 160.0} if small else {}
    cal, cal_truth = simulate_calibration(seed=seed, rate_hz=rate_hz, faults=faults, **cal_kw)
    sur, sur_truth = simulate_survey(seed=seed, rate_hz=rate_hz, faults=faults, **sur_kw)
    plan = survey_plan(sur_truth).round({"lat": 9, "lon": 9, "alt": 3})
    out.mkdir(parents=True, exist_ok=True)
    paths = {
        "calibration": write_csv(round_log(cal), out / "calibration.csv"),
        "survey": write_csv(round_log(sur), out / "survey.csv"),
        "plan": write_csv(plan, out / "plan.csv"),
        "truth": write_json({"calibration": cal_truth, "survey": sur_truth}, out / "truth.json"),
    }
    log.info("wrote %s", ", ".join(str(p) for p in paths.values()))
    return paths


__all__ = [
    "CAL_HEADINGS_DEG",
    "DEFAULT_ORIGIN",
    "FAULT_KINDS",
    "FIELD_SCALE_NT",
    "MANOEUVRES",
    "TERM_NAMES",
    "EarthField",
    "band_noise",
    "body_field",
    "default_aircraft_coef",
    "dipole_field_ned",
    "geodetic_to_local",
    "gradient_by_stretch",
    "local_to_geodetic",
    "local_transformer",
    "ned_to_body_dcm",
    "round_log",
    "simulate_calibration",
    "simulate_survey",
    "stretch_ids",
    "survey_plan",
    "tl_interference",
    "tl_terms",
    "write_simulation",
]
