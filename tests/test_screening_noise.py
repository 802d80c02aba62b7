"""The screening's in-band noise floor, on a box calibration built here with numpy only.

An independent reviewer's 12-line box (4 headings x pitch, roll and yaw; no faults) lost its
E and W yaw lines to the residual-excess test: on those headings the yaw swings the track
north-south through the anomaly, which leaves them 0.022-0.027 nT of in-band residual against
a median of 0.008 nT, a ratio above ``min_excess`` (1.5) and above the 0.01 nT floor, though
the model error against truth is below 0.005 nT on every line.  The generator below mimics the
reviewer's (it shares nothing with :mod:`aeromag.synthetic`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from aeromag.compensation import CompensationReport
from aeromag.compensation.config import CompensationConfig
from aeromag.workflows.compensate import compensate

_F, _INC, _DEC = 48000.0, np.radians(63.0), np.radians(2.0)
_EARTH = _F * np.array([np.cos(_INC) * np.cos(_DEC), np.cos(_INC) * np.sin(_DEC), np.sin(_INC)])
#: Tolles-Lawson coefficients: 3 permanent, 5 induced, 8 eddy [nT; nT s].
_COEF = np.array([30, -20, 15, 50, 10, -5, 40, 8, 2, 1, -1, 0.5, 1.5, -0.8, 0.7, 1.2])


def _body_field(yaw: np.ndarray, pitch: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """The Earth field in the body frame (NED -> body, ZYX), shape (n, 3) [nT]."""
    cy, sy, cp, sp, cr, sr = (np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch),
                              np.cos(roll), np.sin(roll))
    rot = np.array([[cp * cy, cp * sy, -sp],
                    [sr * sp * cy - cr * sy, sr * sp * sy + cr * cy, sr * cp],
                    [cr * sp * cy + sr * sy, cr * sp * sy - sr * cy, cr * cp]])
    return np.einsum("ijn,j->ni", rot, _EARTH)


def _tl(flux: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The 16-term interference of ``_COEF`` on the noise-free body field [nT]."""
    b = np.linalg.norm(flux, axis=1)
    c = flux / b[:, None]
    d = np.gradient(c, t, axis=0)
    s = b / 50000.0
    cx, cy, cz = c.T
    cols = [cx, cy, cz, s * cx * cx, s * cx * cy, s * cx * cz, s * cy * cy, s * cy * cz,
            s * cx * d[:, 0], s * cx * d[:, 1], s * cx * d[:, 2], s * cy * d[:, 0],
            s * cy * d[:, 1], s * cy * d[:, 2], s * cz * d[:, 0], s * cz * d[:, 1]]
    return np.column_stack(cols) @ _COEF


def box_flight(seed: int, *, noise_nT: float = 0.02, fault_line: int | None = None,
               fault_nT: float = 2.0, fs: float = 10.0, seg_s: float = 30.0) -> pd.DataFrame:
    """A 12-line box: headings 0/90/180/270 deg, each with pitch, roll and yaw swings.

    Swings of 6 s period (5 deg pitch, 10 deg roll or yaw; 0.5 deg on the other axes),
    5 m/s over a 3 nT east-west striking anomaly of 400 m wavelength, scalar white noise
    ``noise_nT``, fluxgate noise 0.5 nT per axis.  ``fault_line`` gets an interference burst
    (a 0.4 Hz tone of ``fault_nT`` amplitude plus white noise of half that) on the scalar.
    """
    rng = np.random.default_rng(seed)
    n = int(seg_s * fs)
    parts, t0 = [], 0.0
    for head in (0, 90, 180, 270):
        for man in ("pitch", "roll", "yaw"):
            tt = t0 + np.arange(n) / fs
            ph = 2 * np.pi * tt / 6.0
            yaw = np.radians(head) + (np.radians(10) * np.sin(ph) if man == "yaw" else 0.0)
            pitch = np.radians(5 if man == "pitch" else 0.5) * np.sin(ph)
            roll = (np.radians(10) * np.sin(ph) if man == "roll"
                    else np.radians(0.5) * np.sin(1.3 * ph))
            parts.append(pd.DataFrame({"time": tt, "line": len(parts),
                                       "yaw": np.broadcast_to(yaw, tt.shape), "pitch": pitch,
                                       "roll": roll}))
            t0 = tt[-1] + 1 / fs
    df = pd.concat(parts, ignore_index=True)
    yaw, pitch, roll = (df[c].to_numpy() for c in ("yaw", "pitch", "roll"))
    flux = _body_field(yaw, pitch, roll)
    t = df["time"].to_numpy()
    north = np.cumsum(5.0 / fs * np.cos(yaw))
    east = np.cumsum(5.0 / fs * np.sin(yaw))
    mag = (np.linalg.norm(flux, axis=1) + _tl(flux, t) + 3 * np.sin(2 * np.pi * north / 400)
           + rng.normal(0, noise_nT, len(t)))
    if fault_line is not None:
        sel = df["line"].to_numpy() == fault_line
        mag[sel] += (fault_nT * np.sin(2 * np.pi * 0.4 * t[sel])
                     + rng.normal(0, fault_nT / 2, sel.sum()))
    flux = flux + rng.normal(0, 0.5, flux.shape)
    return pd.DataFrame({
        "time": t + 1.7e9, "line": df["line"], "lat": 46.8 + north / 111320,
        "lon": 7.15 + east / (111320 * np.cos(np.radians(46.8))), "alt": 700.0,
        "heading": np.degrees(yaw) % 360, "pitch": np.degrees(pitch),
        "roll": np.degrees(roll), "flux_x": flux[:, 0], "flux_y": flux[:, 1],
        "flux_z": flux[:, 2], "mag": mag,
    })


def _headline(rep: CompensationReport) -> tuple[float, float]:
    return rep.metrics.kept_improvement_ratio, rep.metrics.all_improvement_ratio


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_clean_box_keeps_every_line(seed):
    """No fault, so no segment is dropped and the headline is that of every sample.

    Without the noise floor (``noise_factor=0``, the rule before it) the E and W yaw lines
    5 and 11 are dropped, 2.2-3.0 times the median's residual, 0.010-0.015 nT above it.
    """
    df = box_flight(seed)
    before = compensate(df, CompensationConfig(noise_factor=0.0)).report
    assert before.screening.dropped == [5, 11]
    rep = compensate(df).report
    assert rep.screening.dropped == []
    kept, every = _headline(rep)
    assert kept == pytest.approx(every)


@pytest.mark.parametrize(("seed", "line", "amp"), [(1, 4, 1.0), (2, 11, 1.0), (3, 7, 3.0)])
def test_box_with_an_interference_burst_drops_that_line_only(seed, line, amp):
    """A 1-3 nT interference burst on one line is a fault, far above the noise floor."""
    rep = compensate(box_flight(seed, fault_line=line, fault_nT=amp)).report
    assert rep.screening.dropped == [line]
    kept, every = _headline(rep)
    assert kept > 5 * every


def test_the_floor_is_three_band_noise_sigmas_or_the_nT_floor():
    """``pool_floor_nT``: max(min_excess_nT, noise_factor * in-band noise)."""
    from aeromag.compensation.screening import band_noise_level, material, pool_floor_nT

    assert pool_floor_nT(0.008, min_excess_nT=0.01, noise_factor=3.0) == pytest.approx(0.024)
    assert pool_floor_nT(0.001, min_excess_nT=0.01, noise_factor=3.0) == pytest.approx(0.01)
    r_own = np.array([0.008] * 10 + [0.05, 0.016])
    ref = np.ones(12, dtype=bool)
    ref[10] = False
    assert band_noise_level(r_own, ref) == pytest.approx(0.008)
    # 10 segments at 0.008 nT, one 0.02 nT above the median (inside 3 sigma), one 0.5 nT.
    r_pool = np.array([0.008] * 10 + [0.5, 0.028])
    own = np.array([0.002] * 10 + [0.4, 0.02])
    kw = dict(min_excess=1.5, min_excess_nT=0.01, gross_excess=10.0)
    assert material(r_pool, own, ref, **kw).tolist() == [False] * 10 + [True, True]
    assert material(r_pool, own, ref, **kw, noise_nT=0.008, noise_factor=3.0).tolist() == (
        [False] * 10 + [True, False])


def test_noise_factor_must_not_be_negative():
    from aeromag.errors import ConfigError

    with pytest.raises(ConfigError, match="noise_factor"):
        CompensationConfig(noise_factor=-1.0)
