"""The arrays a fit sees: a high-rate log decimated to a rate that keeps the band exact.

:func:`fit_arrays` hands the fit (:func:`aeromag.compensation.fit.fit_outcome`) a copy of the log
reduced by :func:`aeromag._core.decimate.decimation_factor` (the fitted coefficients are then
applied to every original sample by the apply step, which never sees the decimated arrays).
A 10 Hz log is returned as it is.  See docs/compensation.md, "High-rate logs".
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np

from .._core.decimate import decimate_stretches, decimation_factor
from .config import CompensationConfig
from .prepare import Prepared

log = logging.getLogger(__name__)

#: Largest change of the field's direction (a direction-cosine difference) that the
#: anti-aliasing filter may remove at a decimated sample; beyond it the attitude changed faster
#: than the fitting rate can represent (a heading step within one sample: a logging glitch),
#: and the products of cosines and their derivatives in the induced and eddy terms would no
#: longer match the full-rate ones, so every sample is fitted instead.  Flight, including
#: rotor vibration a magnetometer tolerates, stays far below it (fluxgate noise of 0.5 nT is
#: 1e-5).
MAX_DIRECTION_LOSS = 0.01


def fit_arrays(prep: Prepared, cfg: CompensationConfig) -> tuple[Prepared, int]:
    """The prepared log the fit uses, decimated per stretch when the rate allows.

    Parameters
    ----------
    prep : Prepared
        The whole log (:func:`aeromag.compensation.prepare.prepare`).
    cfg : CompensationConfig
        ``cfg.decimate`` (False: never) and ``cfg.band_hz`` (the band to keep).

    Returns
    -------
    fit_prep : Prepared
        ``prep`` itself (factor 1), or the fluxgate and scalar anti-aliased and kept every
        ``q``-th sample within each continuous stretch, with those samples' real times,
        stretch and segment labels, at the rate ``prep.fs / q`` [Hz].
    q : int
        The decimation factor (1 = none).
    """
    q = decimation_factor(prep.fs, cfg.band_hz) if cfg.decimate else 1
    if q < 2:
        return prep, 1
    # Per continuous stretch, never across a gap.  Not per segment piece: the FIR reaches
    # only 10 decimated samples, far inside the edges the fit trims from every piece, while
    # restarting it at every segment boundary adds edge errors that ring through the fit's
    # band-pass (on a 1 kHz simulated calibration, rms coefficient error 0.048 nT against
    # 0.011 nT per stretch and 0.013 nT at the full rate).
    f = prep.flux
    (fx, fy, fz, mag), idx = decimate_stretches([f[:, 0], f[:, 1], f[:, 2], prep.mag],
                                                prep.stretch, q)
    flux_dec = np.column_stack([fx, fy, fz])
    loss = _direction_loss(f[idx], flux_dec)
    worst = int(np.argmax(loss)) if loss.size else 0
    if loss.size and loss[worst] > MAX_DIRECTION_LOSS:
        log.warning(
            "%s: the fluxgate's direction changes faster than a fit at %.4g Hz represents"
            " (anti-aliasing would change a direction cosine by %.3g near t = %.6g s; a"
            " step within one sample?): fitting every sample, not decimated",
            prep.source, prep.fs / q, float(loss[worst]), float(prep.time[idx[worst]]))
        return prep, 1
    ones = np.ones(len(idx), dtype=bool)
    out = dataclasses.replace(
        prep, time=prep.time[idx], flux=flux_dec, mag=mag,
        flux_ok=ones, valid=ones, stretch=prep.stretch[idx], segment=prep.segment[idx],
        fs=prep.fs / q)
    log.info("%s: fitting at %.4g Hz (every %d-th sample, anti-aliased per stretch): %d of %d"
             " samples", prep.source, out.fs, q, len(idx), len(prep.time))
    return out, q


def _direction_loss(flux: np.ndarray, flux_dec: np.ndarray) -> np.ndarray:
    """Largest direction-cosine change the anti-aliasing removed, per decimated sample.

    Parameters
    ----------
    flux, flux_dec : ndarray, shape (m, 3)
        The fluxgate at the decimated samples, as recorded and anti-aliased [nT].

    Returns
    -------
    ndarray, shape (m,)
        ``max |c - c_dec|`` over the three axes (dimensionless).
    """
    c = flux / np.linalg.norm(flux, axis=1)[:, None]
    cd = flux_dec / np.linalg.norm(flux_dec, axis=1)[:, None]
    return np.abs(c - cd).max(axis=1)
