"""Synthetic flights with ground truth: a calibration flight, a survey and its plan.

The simulator is the project's ground truth for testing the compensation, the segment
screening and the track checks.  It is written independently of the fitting code (it does not
import :mod:`aeromag.compensation`): the aircraft interference is computed here from the
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
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import pyproj

from .._core.rotations import dcm_body_to_ned
from ..errors import InputError

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

#: Calibration maneuvers in flight order on each heading and their amplitudes [deg].
MANEUVERS: tuple[str, ...] = ("pitch", "roll", "yaw")
MANEUVER_AMPLITUDE_DEG: dict[str, float] = {"pitch": 5.0, "roll": 10.0, "yaw": 5.0}
#: The old spellings (kept for one release).
MANOEUVRES = MANEUVERS
MANOEUVRE_AMPLITUDE_DEG = MANEUVER_AMPLITUDE_DEG

#: Nominal calibration headings [deg]; ``truth_heading_leg`` is the index (N=0, E=1, S=2, W=3).
CAL_HEADINGS_DEG: tuple[float, ...] = (0.0, 90.0, 180.0, 270.0)

MU0_4PI_NT = 100.0  # mu0 / (4 pi) in nT * m / A (1e-7 T m / A)


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
    so that attitude maneuvers of +-5-10 deg give several nT peak-to-peak of interference.

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
        ``C_bn = Rx(phi) @ Ry(theta) @ Rz(psi)``; ``v_body = C_bn @ v_ned``: the transpose of
        :func:`aeromag._core.rotations.dcm_body_to_ned`.
    """
    psi = np.deg2rad(np.atleast_1d(np.asarray(heading_deg, dtype=float)))
    th = np.deg2rad(np.atleast_1d(np.asarray(pitch_deg, dtype=float)))
    ph = np.deg2rad(np.atleast_1d(np.asarray(roll_deg, dtype=float)))
    psi, th, ph = np.broadcast_arrays(psi, th, ph)
    return np.swapaxes(dcm_body_to_ned(ph, th, psi), -1, -2)


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
    return MU0_4PI_NT * (3.0 * mr[:, None] * rhat - m) / rn[:, None] ** 3


# --------------------------------------------------------------------------- geodesy
# Deliberately not aeromag._core.geodesy: the simulator places the aircraft with pyproj's
# topocentric pipeline, an implementation independent of the ECEF/NED code the track check
# uses, so that the track tests compare two methods (they agree to 1e-13 deg, 4e-9 m).
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


def flight_setup(seed: int, flight: int, earth: EarthField | None, coef: Any | None,
                  ) -> tuple[EarthField, np.ndarray, np.random.Generator, np.random.Generator,
                             np.random.Generator]:
    """The main field, checked TL coefficients and the three streams of one flight.

    Shared by the calibration and survey simulators: ``EarthField()`` when ``earth`` is None,
    :func:`default_aircraft_coef` when ``coef`` is None, then :func:`_streams`.
    """
    k = default_aircraft_coef() if coef is None else _check_coef(coef)
    rng, rng_noise, rng_fault = _streams(seed, flight)
    return earth or EarthField(), k, rng, rng_noise, rng_fault


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


def taper(n: int, ramp: int) -> np.ndarray:
    """A window rising from 0 to 1 over ``ramp`` samples at each end (raised cosine)."""
    w = np.ones(n)
    r = max(1, min(ramp, n // 2))
    up = 0.5 - 0.5 * np.cos(np.pi * np.arange(r) / r)
    w[:r] = up
    w[n - r :] = up[::-1]
    return w


def diurnal_field(rng: np.random.Generator, time: np.ndarray, amplitude_nT: float) -> tuple[
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


