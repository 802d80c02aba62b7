"""Anti-aliased decimation of high-rate logs before fitting, one continuous stretch at a time.

UAV magnetometers log at 200 Hz - 1 kHz while the Tolles-Lawson fit only looks at the
compensation band (default 0.1-0.9 Hz).  Band-passing every term at the full rate costs
34 IIR passes per sample; the fit needs only the band, so the design matrix (built at the full
rate) and the scalar are reduced to a rate that keeps the band exact to well below the noise,
the band-pass and normal equations run at that rate, and the fitted coefficients are applied to
every original sample.  What is decimated must be *linear* in the recorded samples' model: the
terms and the target, never the fluxgate they are built from (see
:mod:`aeromag.compensation.decimation`).

The target rate
---------------
The decimated rate is the highest integer fraction ``fs / q`` of the log's rate that is still at
least :data:`BAND_FACTOR` (80) times the band's upper edge and at least :data:`MIN_RATE_HZ`
(2 Hz); a log below twice that is left alone (``q = 1``).  With the default band (0.1-0.9 Hz)
the fitting rate is at least 72 Hz: 1 kHz is fitted at 76.9 Hz (``q = 13``), 200 Hz at 100 Hz,
and logs below 144 Hz (10 Hz, 100 Hz) are never decimated.

* The 80x was chosen when the eddy terms' derivatives were central differences on the
  decimated series (a gain error ``x**2 / 6``, ``x = 2 pi f / rate``).  The derivatives are now
  taken at the full rate, so that reason is gone; on 1 kHz flights with heading steps and
  97 Hz vibration a fit at 20x (18 Hz, ``q = 55``) was as accurate (coefficient rms error
  0.009-0.011 against 0.011-0.013 at 80x) and 10x (9 Hz) a little worse (0.012-0.014).  The
  rule is kept at 80x until that is checked on more flights (docs/compensation.md).
* The anti-aliasing filter (:func:`anti_alias_taps`, run by :func:`scipy.signal.resample_poly`)
  is a droop-corrected three-stage CIC: three boxcars of ``q`` samples, whose nulls sit on the
  multiples of ``fs / q`` (what folds onto the band), and a three-tap correction of their
  in-band droop; ``5 q - 2`` taps, zero-phase.  Gain in the band: 1 - 6e-7 at 0.9 Hz for
  ``q = 13`` at 1 kHz, 1 - 1e-5 for ``q = 27``, 1 - 2e-4 for ``q = 55``.  What would fold into the
  band (``k fs / q +- band_hz[1]``) is attenuated by at least 115 dB for ``q = 13``, 84 dB for
  ``q = 2`` (200 Hz) and 77 dB for ``q = 55``.  It replaced a ``20 q + 1``-tap Kaiser-windowed
  sinc (1 +- 0.001 in the band, 72 dB), which cost 20 multiply-adds per input sample and row
  against 5 here: on a 1.2e6-row 1 kHz log, building and decimating the 17 rows took 0.52 s of
  CPU with it and 0.17 s now, less than the 0.5 s the full-rate fit costs, so decimating now
  pays.  Coefficients are the same within 0.001 (docs/compensation.md).
* The FIR reaches fewer than ``2.5 q`` samples (3 decimated samples, 0.04 s at the 77 Hz of a
  1 kHz log) to each side, far less than the filter edges the fit trims from every segment
  piece.

Decimated sample ``i`` of a stretch that starts at original sample ``a`` *is* original sample
``a + i * q`` (the FIR is zero-phase), so its time, segment and stretch labels are those of
that sample: the caller takes them with the returned indices.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence

import numpy as np

from .parallel import parallel_map
from .runs import run_bounds

__all__ = ["BAND_FACTOR", "MIN_RATE_HZ", "anti_alias_taps", "decimate_built",
           "decimate_stretches", "decimation_factor"]

log = logging.getLogger(__name__)

#: The decimated rate is at least this multiple of the band's upper edge.
BAND_FACTOR = 80.0
#: ... and at least this rate [Hz].
MIN_RATE_HZ = 2.0


def decimation_factor(fs_hz: float, band_hz: tuple[float, float], *,
                      band_factor: float = BAND_FACTOR, min_rate_hz: float = MIN_RATE_HZ) -> int:
    """Integer decimation factor that keeps ``band_hz`` exact for fitting (1 = none).

    Parameters
    ----------
    fs_hz : float
        Sampling rate of the log [Hz].
    band_hz : (float, float)
        The compensation band [Hz]; only its upper edge matters.
    band_factor : float
        The decimated rate is at least this many times ``band_hz[1]``.
    min_rate_hz : float
        ... and at least this rate [Hz].

    Returns
    -------
    int
        ``q >= 1``: the largest integer with ``fs_hz / q >= max(band_factor * band_hz[1],
        min_rate_hz)``.
    """
    target = max(float(band_factor) * float(band_hz[1]), float(min_rate_hz))
    if not (np.isfinite(fs_hz) and fs_hz > 0 and target > 0):
        return 1
    return max(1, int(math.floor(fs_hz / target * (1 + 1e-12))))


def anti_alias_taps(q: int) -> np.ndarray:
    """The anti-aliasing FIR for decimation by ``q``: a droop-corrected three-stage CIC filter.

    Three boxcars of ``q`` samples in cascade (the third of ``q + 1`` when ``q`` is even, so the
    filter has an odd length and is zero-phase) put their nulls at the multiples of the
    decimated rate ``fs / q``: exactly the frequencies that fold onto the band near 0 Hz.
    Their gain falls as ``1 - c (pi f / fs)**2`` near 0 Hz; a three-tap correction with taps
    ``q`` samples apart, ``(-e, 1 + 2 e, -e)`` with ``e = c / (4 q**2)``, cancels that term
    (its gain is 1 at every multiple of ``fs / q``, so it leaves the nulls where they are).
    ``5 q - 2`` taps (``5 q - 1`` for an even ``q``): 5 multiply-adds per input sample against
    20 for a ``20 q + 1``-tap windowed sinc (see the module docstring for the numbers).

    Parameters
    ----------
    q : int
        Decimation factor (>= 1).

    Returns
    -------
    ndarray, shape (5 q - 2,) or (5 q - 1,)
        Symmetric taps summing to 1 (dimensionless).
    """
    q = int(q)
    box = np.full(q, 1.0 / q)
    r = q if q % 2 else q + 1
    cic = np.convolve(np.convolve(box, box), np.full(r, 1.0 / r))
    c = (2.0 * (q * q - 1) + (r * r - 1)) / 6.0  # gain 1 - c (pi f / fs)**2 + O(f**4)
    e = c / (4.0 * q * q)
    fix = np.zeros(2 * q + 1)
    fix[[0, q, 2 * q]] = (-e, 1.0 + 2.0 * e, -e)
    return np.convolve(cic, fix)


def _stretch_index(stretch: np.ndarray, q: int) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
    """The checked factor, the stretches' bounds and the kept indices (every ``q``-th sample).

    Shared by :func:`decimate_stretches` and :func:`decimate_built`, so both keep the same
    samples. Returns ``(q, starts, stops, index)``; raises ValueError for ``q < 1``.
    """
    q = int(q)
    if q < 1:
        raise ValueError(f"decimation factor {q}: must be >= 1")
    starts, stops, _ = run_bounds(np.asarray(stretch))
    idx = np.concatenate([np.arange(a, b, q, dtype=np.int64)
                          for a, b in zip(starts.tolist(), stops.tolist(), strict=True)]
                         or [np.zeros(0, dtype=np.int64)])
    return q, starts, stops, idx


def decimate_stretches(
    series: Sequence[np.ndarray], stretch: np.ndarray, q: int,
) -> tuple[list[np.ndarray], np.ndarray]:
    """Anti-alias and keep every ``q``-th sample of each continuous stretch on its own.

    No filter ever runs across a stretch boundary (a time gap or an invalid sample): each
    stretch ``[a, b)`` gives ``ceil((b - a) / q)`` samples, at the original indices
    ``a, a + q, a + 2q, ...``.  Each stretch is extended past its ends by its odd (point)
    reflection before filtering (``padtype="antireflect"``, the extension ``sosfiltfilt``
    uses), so value and slope run on across the ends and they do not ring: on a 60 s stretch
    of 3000 nT attitude swings at 1 kHz (measured with the earlier 20 q + 1-tap FIR) the end
    samples are within 0.6 nT, against 14 nT with a linear detrend and 25,000 nT with zero
    padding.  With :func:`anti_alias_taps` (``q = 13``, swings of 3000 and 1500 nT at 5.3 and
    3.1 s periods) the 5 end samples are within 0.04 nT and the rest within 2e-5 nT.

    Parameters
    ----------
    series : sequence of ndarray, each shape (n,)
        Finite samples inside every stretch (e.g. the three fluxgate axes and the scalar) [any
        unit, kept].
    stretch : ndarray of int, shape (n,)
        Stretch labels; negative = not in a stretch (dropped).
    q : int
        Decimation factor (>= 1; 1 returns the samples of the stretches unfiltered).

    Returns
    -------
    decimated : list of ndarray, each shape (m,)
        The decimated series, stretch after stretch.
    index : ndarray of int64, shape (m,)
        Original index of each decimated sample (take times and labels with it).
    """
    q, starts, stops, idx = _stretch_index(stretch, q)
    if q == 1:
        return [np.asarray(x, dtype=np.float64)[idx] for x in series], idx
    from scipy.signal import resample_poly

    taps = anti_alias_taps(q)
    out = []
    for x in series:
        xa = np.asarray(x, dtype=np.float64)
        y = np.empty(len(idx))
        k = 0
        for a, b in zip(starts.tolist(), stops.tolist(), strict=True):
            m = -(-(b - a) // q)
            if b - a < 2:  # nothing to filter: the sample itself
                y[k:k + m] = xa[a:b:q]
            else:
                y[k:k + m] = resample_poly(xa[a:b], 1, q, window=taps, padtype="antireflect")
            k += m
        out.append(y)
    log.debug("decimated %d series by %d: %d -> %d samples in %d stretch(es)",
              len(out), q, int((stops - starts).sum()), len(idx), len(starts))
    return out, idx


#: Full-rate samples built and filtered per block by :func:`decimate_built` (with 18 rows,
#: 9.4 MB of float64 a block, whatever the log's length).
BUILD_BLOCK = 65_536


def decimate_built(
    build: Callable[[int, int, int, int], np.ndarray], n_rows: int, stretch: np.ndarray,
    q: int, *, block: int = BUILD_BLOCK,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`decimate_stretches` of rows that are built block by block at the full rate.

    The same filter, padding and indices as :func:`decimate_stretches` (identical to rounding),
    but the full-rate rows never exist for more than one block of a stretch at a time: each
    block of ``block`` output-aligned samples is built with ``3 q`` samples of context on
    either side (more than the FIR's half-length, below ``2.5 q``), filtered, and only the decimated
    samples whose FIR lies wholly inside the built samples (or reaches a real stretch end,
    where the padding is the whole stretch's) are kept.

    Parameters
    ----------
    build : callable
        ``build(lo, hi, a, b)`` returns the rows for the original samples ``[lo, hi)`` of the
        stretch ``[a, b)`` (``a <= lo < hi <= b``), shape ``(n_rows, hi - lo)``; anything that
        needs neighbours (derivatives) takes them from inside ``[a, b)`` only.
    n_rows : int
        Number of rows ``build`` returns.
    stretch : ndarray of int, shape (n,)
        Stretch labels; negative = not in a stretch (dropped).
    q : int
        Decimation factor (>= 1; 1 returns the built rows at every sample of the stretches).
    block : int
        Full-rate samples built per block (rounded down to a multiple of ``q``).

    Returns
    -------
    decimated : ndarray, shape (n_rows, m)
        The decimated rows, stretch after stretch.
    index : ndarray of int64, shape (m,)
        Original index of each decimated sample.
    """
    q, starts, stops, idx = _stretch_index(stretch, q)
    out = np.empty((int(n_rows), len(idx)))
    if q > 1:
        from scipy.signal import resample_poly

        taps = anti_alias_taps(q)
    ov = 3 * q  # > the FIR's half-length (< 2.5 q), a multiple of q
    step = max(4 * ov, int(block) // q * q)  # the end padding sees as much as the stretch's
    jobs = []  # (lo, hi, a, b, first output column)
    k = 0
    for a, b in zip(starts.tolist(), stops.tolist(), strict=True):
        jobs += [(lo, min(b, lo + step), a, b, k + (lo - a) // q) for lo in range(a, b, step)]
        k += -(-(b - a) // q)

    def run(job: tuple[int, int, int, int, int]) -> None:
        lo, hi, a, b, col = job
        nj = -(-(hi - lo) // q)
        if q == 1 or b - a < 2:  # nothing to filter: the samples themselves
            out[:, col:col + nj] = build(lo, hi, a, b)[:, ::q]
            return
        wlo, whi = max(a, lo - ov), min(b, hi + ov)  # lo - a is a multiple of q
        y = resample_poly(build(wlo, whi, a, b), 1, q, axis=1, window=taps,
                          padtype="antireflect")
        j0 = (lo - wlo) // q
        out[:, col:col + nj] = y[:, j0:j0 + nj]

    # Blocks on the filter pool (resample_poly and most of numpy release the GIL); each
    # writes its own columns of ``out``.
    if len(idx) * n_rows >= 100_000:
        parallel_map(run, jobs)
    else:
        for job in jobs:
            run(job)
    log.debug("decimated %d built rows by %d: %d -> %d samples in %d stretch(es)",
              n_rows, q, int((stops - starts).sum()), len(idx), len(starts))
    return out, idx
