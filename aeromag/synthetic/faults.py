"""Faults on chosen segments and the assembly of a simulated log with its truth."""


import logging
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from ..errors import InputError
from .physics import (
    FAULT_KINDS,
    FIELD_SCALE_NT,
    TERM_NAMES,
    EarthField,
    band_noise,
    body_field,
    local_to_geodetic,
    stretch_ids,
    tl_terms,
)

log = logging.getLogger(__name__)


def resolve_faults(
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


def assemble(
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


def common_truth(
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
    """The truth fields every simulated flight records.

    Kind, seed, rate [Hz], Earth field [nT], coefficients, noise levels [nT, m] and origin
    [deg, deg, m], as JSON-ready values.
    """
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


def check_positive(**values: float) -> None:
    """Refuse (InputError) any value that is not a finite number > 0, naming it."""
    for name, v in values.items():
        if not np.isfinite(v) or v <= 0:
            raise InputError(f"{name}: must be a positive number, got {v!r}")


def check_nonneg(**values: float) -> None:
    """Refuse (InputError) any value that is not a finite number >= 0, naming it."""
    for name, v in values.items():
        if not np.isfinite(v) or v < 0:
            raise InputError(f"{name}: must be zero or positive, got {v!r}")


