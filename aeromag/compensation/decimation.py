"""The arrays a fit sees: a high-rate log's design matrix, built at the full rate, decimated.

:func:`fit_arrays` hands the fit (:func:`aeromag.compensation.fit.fit_outcome`) the TL terms and
the centred scalar of a high-rate log reduced by
:func:`aeromag._core.decimate.decimation_factor`.  The terms are built at the *full* rate, from
the recorded fluxgate, with the same direction cosines, ``|B|`` scaling and derivatives the
apply step uses, and only then anti-aliased and decimated per continuous stretch, together with
the scalar.  The decimation is linear, so it commutes with the linear model ``mag = A @ coef``
and with the band-pass that follows: the decimated normal equations are those of the full-rate
fit, restricted to the band, whatever the fluxgate does out of band (heading steps within one
sample, rotor vibration).  Decimating the fluxgate first and building the non-linear terms from
it would not be (low-passing after the terms is not low-passing before them).  The fitted
coefficients are then applied to every original sample by the apply step.  A 10 Hz log is
returned as it is.  See docs/compensation.md, "High-rate logs".
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np

from .._core.decimate import decimate_built, decimation_factor
from .config import CompensationConfig
from .prepare import Prepared, _every
from .terms import FIELD_SCALE_NT, direction_cosines, terms_from_cosines, time_derivative

log = logging.getLogger(__name__)


def fit_arrays(
    prep: Prepared, cfg: CompensationConfig, terms: tuple[str, ...],
) -> tuple[Prepared, int, np.ndarray | None]:
    """The samples and design matrix the fit uses, decimated per stretch when the rate allows.

    Parameters
    ----------
    prep : Prepared
        The whole log (:func:`aeromag.compensation.prepare.prepare`).
    cfg : CompensationConfig
        ``cfg.decimate`` (False: never) and ``cfg.band_hz`` (the band to keep).
    terms : tuple of str
        The fitted terms (no ``bias``).

    Returns
    -------
    fit_prep : Prepared
        ``prep`` itself (factor 1), or every ``q``-th sample of each continuous stretch, with
        those samples' real times, stretch and segment labels, at the rate ``prep.fs / q``
        [Hz].  Its ``flux`` and ``mag`` are the recorded values at those samples, *not*
        anti-aliased: fit with ``design``, never with them.
    q : int
        The decimation factor (1 = none).
    design : ndarray, shape (len(terms) + 1, m), or None
        None for factor 1; else the terms (built at the full rate, columns as
        :func:`aeromag.compensation.terms.design_matrix`: dimensionless, ``|B|/50000 nT``,
        1/s times that) and, in the last row, the scalar minus its median [nT], anti-aliased
        and decimated per stretch (:func:`aeromag._core.decimate.decimate_built`).
    """
    q = decimation_factor(prep.fs, cfg.band_hz) if cfg.decimate else 1
    if q < 2:
        return prep, 1, None
    # Per continuous stretch, never across a gap.  Not per segment piece: the FIR reaches
    # only 3 decimated samples, far inside the edges the fit trims from every piece, while
    # restarting it at every segment boundary adds edge errors that ring through the fit's
    # band-pass (on a 1 kHz simulated calibration, rms coefficient error 0.048 nT against
    # 0.011 nT per stretch and 0.013 nT at the full rate).
    k = len(terms)
    flux, t, mag = prep.flux, prep.time, prep.mag
    inside = prep.stretch >= 0
    y_level = float(np.median(mag[inside][:: _every(mag)]))  # centring only
    need_d = any(name.endswith("'") for name in terms)

    def build(lo: int, hi: int, a: int, b: int) -> np.ndarray:
        # One sample of context on either side (inside the stretch): the derivatives are
        # those of the whole stretch, as when the model is applied.
        clo, chi = max(a, lo - 1), min(b, hi + 1)
        cos, bt = direction_cosines(flux[clo:chi])
        dcos = time_derivative(cos, t[clo:chi]) if need_d else cos
        s = slice(lo - clo, lo - clo + (hi - lo))
        out = np.empty((k + 1, hi - lo))
        terms_from_cosines(cos[s], dcos[s], bt[s] / FIELD_SCALE_NT, terms, out=out[:k].T)
        np.subtract(mag[lo:hi], y_level, out=out[k])
        return out

    design, idx = decimate_built(build, k + 1, prep.stretch, q)
    ones = np.ones(len(idx), dtype=bool)
    out = dataclasses.replace(
        prep, time=t[idx], flux=flux[idx], mag=mag[idx],
        flux_ok=ones, valid=ones, stretch=prep.stretch[idx], segment=prep.segment[idx],
        fs=prep.fs / q)
    log.info("%s: fitting at %.4g Hz (the full-rate terms anti-aliased per stretch, every"
             " %d-th sample): %d of %d samples", prep.source, out.fs, q, len(idx), len(t))
    return out, q, design
