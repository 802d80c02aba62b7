"""Online Tolles-Lawson compensation: the TL model estimated sample by sample, causally.

For interference that changes during a flight (thrust, a payload switched on, a battery
swap), the coefficients are re-estimated at every sample by recursive least squares with a
forgetting factor (:mod:`aeromag._core.rls`), the same terms and term order as the batch fit
(:mod:`aeromag.compensation.terms`).  Everything that feeds the estimate is causal:

- the derivatives of the direction cosines never cross a time gap.  Two choices
  (``derivative``): ``"central"`` (default) is the batch fit's own derivative
  (:func:`aeromag.compensation.terms.time_derivative`, central differences), so sample k's
  row is complete when sample k+1 arrives: the estimate at any time uses only the samples
  received so far, and the interference of sample k is known one sample later (a latency of
  one sample, 0.1 s at 10 Hz).  ``"backward"`` is strictly causal with no latency
  (``(c_k - c_(k-1)) / (t_k - t_(k-1))``), but a backward difference lags by half a sample:
  at 0.8 Hz and 10 Hz its eddy terms are off by a quarter, which biases the coefficients
  (measured in ``docs/online.md``: about 4x the batch residual on the simulator).
  ``"midpoint"`` is strictly causal without that lag: fit row k describes the half-sample
  midpoint ``t_(k-1/2)`` (target, permanent and induced terms the means of samples k-1 and
  k, eddy terms the mean cosine times the difference over the step), and ``mag_tl`` uses
  the second-order backward difference (1.3-1.7x the post-jump batch residual in
  ``docs/online.md``, against 1.0-1.3x for ``"central"``, which stays the default);
- the target ``mag`` and every term are band-passed by the same causal Butterworth filter
  (``sosfilt``, not the zero-phase ``sosfiltfilt`` of the batch fit), started in steady
  state on the first sample of each stretch, so that the Earth field's level gives no
  transient; the filter's phase lag is the same on both sides of ``mag = A theta``, so the
  coefficients are not biased by it;
- the interference of sample k is ``mag_tl_k = A_k theta_s(k-1)``: unfiltered terms times
  the estimate from the samples before k (a-priori), low-passed causally
  (``coef_lowpass_hz``, a second-order Butterworth): the unfiltered terms carry the large
  level of the direction cosines, and the sample-to-sample jitter of the estimate in its
  poorly determined directions would otherwise come back into the band as noise.

Only the final low-pass of ``mag_comp`` (the pipeline's zero-phase filter, off with
``--no-filter``) and the reported band-pass metrics (the batch pipeline's zero-phase
definition on ``mag - mag_tl``, for comparison with it) look at both sides of a sample;
neither feeds the estimate.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np

from .._core.filters import butter_sos
from .._core.rls import RecursiveLeastSquares, check_forgetting
from .._core.sequential import InnovationStats, SequentialResult, Step
from ..errors import InputError
from .online_convergence import (
    NIS_THRESHOLD,
    OnlineTLResult,
    convergence_spans,
    running_mean_square,
)
from .terms import (
    FIELD_SCALE_NT,
    direction_cosines,
    parse_terms,
    terms_from_cosines,
    time_derivative,
)

log = logging.getLogger(__name__)

__all__ = ["OnlineTL", "OnlineTLResult", "causal_derivative", "new_stretch_starts",
           "DERIVATIVES", "LATENCY_SAMPLES"]

#: The derivative options of :class:`OnlineTL` (see the module docstring).
DERIVATIVES = ("midpoint", "central", "backward")
#: Latency of ``mag_tl`` in samples for each option (midpoint: the fit rows are centred half a
#: sample back, but no row waits for a later sample).
LATENCY_SAMPLES = {"midpoint": 0, "central": 1, "backward": 0}


def bdf2_derivative(values: np.ndarray, time_s: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Second-order backward-difference derivative, never across a stretch start.

    ``v'_k = (2h1+h2)/(h1(h1+h2)) (v_k - v_(k-1)) - h1/(h2(h1+h2)) (v_(k-1) - v_(k-2))``
    with ``h1 = t_k - t_(k-1)``, ``h2 = t_(k-1) - t_(k-2)`` (``(3v_k - 4v_(k-1) + v_(k-2))
    / 2h`` at a constant step): exact for a parabola, so it has no half-sample lag, and it
    uses no later sample.  On the second sample of a stretch the backward difference; on its
    first, 0.

    Parameters
    ----------
    values : ndarray, shape (n, m)
        Samples.
    time_s : ndarray, shape (n,)
        Strictly increasing times [s].
    starts : ndarray of bool, shape (n,)
        True where a stretch starts.

    Returns
    -------
    ndarray, shape (n, m)
        [unit of values per second].
    """
    v = np.asarray(values, dtype=np.float64)
    t = np.asarray(time_s, dtype=np.float64)
    st = np.asarray(starts, dtype=bool)
    out = causal_derivative(v, t, st)
    if len(t) > 2:
        h1 = (t[2:] - t[1:-1])[:, None]
        h2 = (t[1:-1] - t[:-2])[:, None]
        d1 = v[2:] - v[1:-1]
        d2 = v[1:-1] - v[:-2]
        bdf = (2 * h1 + h2) / (h1 * (h1 + h2)) * d1 - h1 / (h2 * (h1 + h2)) * d2
        ok = ~st[2:] & ~st[1:-1]
        out[2:][ok] = bdf[ok]
    return out


def causal_derivative(values: np.ndarray, time_s: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Backward-difference time derivative, never across a stretch start.

    Parameters
    ----------
    values : ndarray, shape (n,) or (n, m)
        Samples.
    time_s : ndarray, shape (n,)
        Strictly increasing times [s].
    starts : ndarray of bool, shape (n,)
        True where a stretch starts (its derivative is 0).

    Returns
    -------
    ndarray
        ``(v_k - v_(k-1)) / (t_k - t_(k-1))`` [unit of values per second].
    """
    v = np.asarray(values, dtype=np.float64)
    t = np.asarray(time_s, dtype=np.float64)
    out = np.zeros_like(v)
    if len(t) > 1:
        dt = np.diff(t)
        d = np.diff(v, axis=0)
        out[1:] = d / (dt if v.ndim == 1 else dt[:, None])
    out[np.asarray(starts, dtype=bool)] = 0.0
    return out


def new_stretch_starts(time_s: np.ndarray, valid: np.ndarray, max_gap_s: float) -> np.ndarray:
    """Where a stretch starts: the first valid sample after an invalid one or a time gap.

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Times [s].
    valid : ndarray of bool, shape (n,)
        Usable samples.
    max_gap_s : float
        Longest time step inside a stretch [s].

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    t = np.asarray(time_s, dtype=np.float64)
    v = np.asarray(valid, dtype=bool)
    starts = np.zeros(len(t), dtype=bool)
    if not len(t):
        return starts
    prev_ok = np.r_[False, v[:-1]]
    gap = np.r_[True, np.diff(t) > max_gap_s]
    starts = v & (~prev_ok | gap)
    return starts


class OnlineTL:
    """Tolles-Lawson coefficients estimated online (causal RLS with forgetting).

    Parameters
    ----------
    fs_hz : float
        Sampling rate [Hz] (for the band-pass design).
    terms : str or sequence of str
        Term set (:func:`parse_terms`), default the 16 terms.
    forgetting : float
        lambda, 0 < lambda <= 1; the memory is about ``1 / (1 - lambda)`` samples (0.999 at
        10 Hz: 100 s).
    band_hz : (float, float)
        Causal band-pass before the estimate [Hz].
    order : int
        Butterworth order.
    alpha : float
        Prior covariance scale ``P_0 = alpha I`` [nT^2]; its inverse is the constant ridge
        weight that bounds the covariance (see :mod:`aeromag._core.rls`).
    max_gap_s : float, optional
        Longest time step inside a stretch [s]; default 5 sample intervals.
    derivative : {"central", "midpoint", "backward"}
        Derivative of the direction cosines (see the module docstring).
    coef_lowpass_hz : float or None
        Cut-off of the causal low-pass on the coefficients used for ``mag_tl`` [Hz];
        default a fifth of the band's lower edge; None: the raw estimate.
    coef_std : bool
        Report the std of every coefficient after every sample (``SequentialResult.std``;
        one 16 x 16 inverse per sample, about half the speed of :meth:`run`); when False
        ``std`` has no rows (``mag_tl_std`` is computed either way).

    Notes
    -----
    State carried between calls of :meth:`run` / :meth:`step`: the estimator, the filter
    states of ``mag`` and of every term, and the last direction cosines and time, so that
    feeding a log in pieces gives exactly the result of feeding it whole.
    """

    def __init__(self, fs_hz: float, terms: str | Sequence[str] = "16", *,
                 forgetting: float = 0.999, band_hz: tuple[float, float] = (0.1, 0.9),
                 order: int = 4, alpha: float = 1e4, max_gap_s: float | None = None,
                 derivative: str = "central", coef_lowpass_hz: float | None = -1.0,
                 coef_std: bool = True) -> None:
        self.fs_hz = float(fs_hz)
        if not (np.isfinite(self.fs_hz) and self.fs_hz > 0):
            raise InputError(f"sampling rate must be positive, got {fs_hz!r} Hz")
        self.terms = parse_terms(terms)
        self.forgetting = check_forgetting(forgetting)
        self.band_hz = (float(band_hz[0]), float(band_hz[1]))
        self.order = int(order)
        self.alpha = float(alpha)
        self.max_gap_s = 5.0 / self.fs_hz if max_gap_s is None else float(max_gap_s)
        if derivative not in DERIVATIVES:
            raise InputError(f"derivative must be one of {', '.join(DERIVATIVES)}, got "
                             f"{derivative!r}")
        self.derivative = derivative
        self.coef_std = bool(coef_std)
        self.sos = butter_sos("bandpass", self.band_hz, self.fs_hz, self.order)
        from scipy.signal import sosfilt_zi

        self._zi_unit = sosfilt_zi(self.sos)  # (sections, 2): steady state for input 1
        if coef_lowpass_hz is not None and coef_lowpass_hz < 0:
            coef_lowpass_hz = self.band_hz[0] / 5.0
        self.coef_lowpass_hz = coef_lowpass_hz
        self._sos_coef = None if coef_lowpass_hz is None else butter_sos(
            "lowpass", coef_lowpass_hz, self.fs_hz, 2, option="coef_lowpass_hz")
        self._zi_coef: np.ndarray | None = None
        self.rls = RecursiveLeastSquares(len(self.terms), 1, forgetting=self.forgetting,
                                         alpha=self.alpha)
        self._zi: np.ndarray | None = None  # (sections, 2, p + 1)
        self._scale_state: tuple[float, float] | None = None  # running residual scale
        self._scale_prev = float("nan")
        self.last_mag_tl = float("nan")
        self.last_mag_tl_std = float("nan")
        self._last_cos: np.ndarray | None = None
        self._last_t: float | None = None
        self._ended_valid = False  # the previous call's last sample was usable
        # midpoint: the previous call's last two usable samples (t, flux, mag, starts)
        self._tail: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None

    @property
    def coef(self) -> np.ndarray:
        """Current coefficients [nT; eddy nT*s]."""
        return self.rls.theta[:, 0].copy()

    def _design(self, flux: np.ndarray, t: np.ndarray, starts: np.ndarray) -> np.ndarray:
        cos, bt = direction_cosines(flux)
        cont = bool(len(t) and not starts[0] and self._last_cos is not None)
        if cont:
            # Continue the previous call's stretch: its last sample is the predecessor.
            c_ext = np.vstack([self._last_cos[None, :], cos])
            t_ext = np.r_[self._last_t, t]
            s_ext = np.r_[False, starts]
        else:
            c_ext, t_ext, s_ext = cos, t, starts
        if self.derivative == "central":
            dcos = time_derivative(c_ext, t_ext, np.cumsum(s_ext))
        else:
            dcos = causal_derivative(c_ext, t_ext, s_ext)
        if cont:
            dcos = dcos[1:]
        return terms_from_cosines(cos, dcos, bt / FIELD_SCALE_NT, self.terms)

    def _midpoint_design(self, flux: np.ndarray, t: np.ndarray, mag: np.ndarray,
                         starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Fit rows at the half-sample midpoints and output rows at the samples.

        Fit row k (target and terms) describes ``t_(k-1/2)``: the permanent and induced terms
        and ``mag`` are the means of samples k-1 and k (exact: they need no derivative, and
        ``mag`` is linear in them), the eddy terms are the mean cosine times
        ``(c_k - c_(k-1)) / (t_k - t_(k-1))``, which is the central difference about the
        midpoint.  The first row of a stretch is its sample itself with derivative 0.  Output
        rows use the second-order backward difference (:func:`bdf2_derivative`).
        """
        tail = self._tail
        cont = bool(len(t) and not starts[0] and tail is not None)
        m = len(tail[0]) if cont else 0
        if cont:
            t = np.r_[tail[0], t]
            flux = np.vstack([tail[1], flux])
            mag = np.r_[tail[2], mag]
            starts = np.r_[tail[3], starts]
        # the last two usable samples, for the next call (a one-sample call keeps one of
        # the previous call's)
        self._tail = (t[-2:].copy(), flux[-2:].copy(), mag[-2:].copy(), starts[-2:].copy())
        cos, bt = direction_cosines(flux)
        sc = bt / FIELD_SCALE_NT
        first = starts.copy()
        first[0] = True  # (a continued piece: row 0 is a tail sample, dropped below)
        prev = np.r_[0, np.arange(len(t) - 1)]
        dt = np.where(first, 1.0, t - t[prev])
        fs = first[:, None]
        c_mid = np.where(fs, cos, 0.5 * (cos + cos[prev]))
        d_mid = np.where(fs, 0.0, (cos - cos[prev]) / dt[:, None])
        s_mid = np.where(first, sc, 0.5 * (sc + sc[prev]))
        fit = np.empty((len(t), len(self.terms) + 1))
        terms_from_cosines(c_mid, d_mid, s_mid, self.terms, out=fit[:, :-1])
        still = [j for j, name in enumerate(self.terms) if "'" not in name]
        if still:
            a0 = terms_from_cosines(cos, np.zeros_like(cos), sc,
                                    [self.terms[j] for j in still])
            fit[:, still] = np.where(fs, a0, 0.5 * (a0 + a0[prev]))
        fit[:, -1] = np.where(first, mag, 0.5 * (mag + mag[prev]))
        dcos = bdf2_derivative(cos, t, starts)
        out = terms_from_cosines(cos, dcos, sc, self.terms)
        return fit[m:], out[m:]

    def run(self, ys: np.ndarray, us: np.ndarray | None = None) -> SequentialResult:
        """Process many samples (vectorised; continues from the current state).

        Parameters
        ----------
        ys : ndarray, shape (N,)
            Scalar magnetometer [nT].
        us : ndarray, shape (N, 4)
            Time [s] (strictly increasing) and the body-frame fluxgate ``flux_x, flux_y,
            flux_z`` [nT], one row per sample (required).

        Returns
        -------
        SequentialResult
            ``state``: the coefficients after each sample (``state_names`` the terms) [nT;
            eddy nT*s], ``std`` their one-sigma uncertainty (RLS covariance times the
            running a-priori residual scale); ``innovation`` (N, 1): the band-passed
            a-priori residual [nT]; ``innovations["mag"]`` with the NIS against that
            scale; ``info``: ``mag_tl`` (interference of each sample with the estimate
            before it, NaN where unusable) [nT], ``mag_tl_std`` (its predicted one-sigma
            uncertainty, see :func:`mag_tl_uncertainty`) [nT], ``residual_scale_nT`` (N),
            ``skipped``, ``coef`` (final), ``forgetting``.
        """
        if us is None:
            raise ValueError("OnlineTL.run needs us = (time, flux_x, flux_y, flux_z)")
        u = np.asarray(us, dtype=np.float64).reshape(-1, 4)
        return self._run(u[:, 0], u[:, 1:], ys)

    def _run(self, time_s: np.ndarray, flux_nT: np.ndarray, mag_nT: np.ndarray
             ) -> SequentialResult:
        from scipy.signal import sosfilt

        t = np.asarray(time_s, dtype=np.float64)
        flux = np.asarray(flux_nT, dtype=np.float64).reshape(len(t), 3)
        mag = np.asarray(mag_nT, dtype=np.float64).reshape(len(t))
        p = len(self.terms)
        n = len(t)
        bt2 = np.einsum("ij,ij->i", flux, flux)
        valid = np.isfinite(bt2) & (bt2 > 0) & np.isfinite(mag) & np.isfinite(t)
        starts = new_stretch_starts(t, valid, self.max_gap_s)
        if n and valid[0] and self._ended_valid and self._zi is not None \
                and 0 < t[0] - self._last_t <= self.max_gap_s:
            starts[0] = False  # continues the previous call's stretch
        idx = np.flatnonzero(valid)
        all_ok = len(idx) == n
        X = np.empty((n, p + 1))  # the fit rows: terms and mag, one row per sample
        if self.derivative == "midpoint":
            A = np.full((n, p), np.nan)  # output rows
            X[:] = np.nan
            if idx.size:
                X[idx], A[idx] = self._midpoint_design(flux[idx], t[idx], mag[idx],
                                                       starts[idx])
        else:
            if all_ok:
                X[:, :p] = self._design(flux, t, starts)
            else:
                X[:, :p] = np.nan
                X[idx, :p] = self._design(flux[idx], t[idx], starts[idx])
            X[:, p] = mag
            A = X[:, :p]
        # Causal band-pass per stretch, started in steady state (or carried over).
        Xf = np.empty_like(X) if all_ok else np.full_like(X, np.nan)
        bounds = np.flatnonzero(starts[idx]) if idx.size else np.zeros(0, dtype=int)
        pieces = np.split(idx, bounds[bounds > 0]) if idx.size else []
        zi = self._zi
        for k, rows in enumerate(pieces):
            # A piece runs from one stretch start to the next: consecutive rows (an unusable
            # sample always starts a new stretch after it).
            sl = slice(rows[0], rows[-1] + 1)
            x = X[sl]
            if k > 0 or starts[rows[0]] or zi is None:
                zi = self._zi_unit[:, :, None] * x[0][None, None, :]
            Xf[sl], zi = sosfilt(self.sos, x, axis=0, zi=zi)
        self._zi = zi
        if idx.size:
            self._last_cos = direction_cosines(flux[idx[-1]][None, :])[0][0]
            self._last_t = float(t[idx[-1]])
        if n:
            self._ended_valid = bool(valid[-1])
        before = self.rls.theta[:, 0].copy()
        # The output rows A predict mag_tl: their prior variance comes with the estimate.
        res = self.rls.run(Xf[:, p], Xf[:, :p], std=self.coef_std,
                           predict=np.where(np.isfinite(A), A, 0.0))
        hist = res.state
        prior = np.empty_like(hist)
        if n:
            prior[0] = before
            prior[1:] = hist[:-1]
        if self._sos_coef is not None and n:
            from scipy.signal import sosfilt_zi

            if self._zi_coef is None:
                self._zi_coef = sosfilt_zi(self._sos_coef)[:, :, None] * prior[0][None, None, :]
            prior, self._zi_coef = sosfilt(self._sos_coef, prior, axis=0, zi=self._zi_coef)
        mag_tl = np.einsum("ij,ij->i", A, prior)  # NaN rows of A give NaN (not usable)
        # The a-priori residual scale: its running mean square, standardised by the RLS
        # prior variance, over one memory (causal: sample k uses the residuals before k).
        e = res.innovation[:, 0]
        z2 = e * e / (1.0 + res.info["prior_var"])
        scale2, self._scale_state = running_mean_square(z2, self.forgetting,
                                                        self._scale_state)
        prior_scale2 = np.r_[self._scale_prev, scale2[:-1]] if n else scale2
        if n:
            self._scale_prev = scale2[-1]
        mag_tl_std = np.sqrt(prior_scale2 * res.info["predict_var"])
        mag_tl_std[~np.isfinite(mag_tl)] = np.nan
        nis = z2 / prior_scale2
        used = ~res.info["skipped"] & np.isfinite(nis)
        stats = InnovationStats(dof=1, n_fused=int(used.sum()),
                                n_gated=int(res.info["skipped"].sum()),
                                nis_sum=float(nis[used].sum()))
        scale = np.sqrt(scale2)
        info = {"mag_tl": mag_tl, "mag_tl_std": mag_tl_std, "residual_scale_nT": scale,
                "prior_var": res.info["prior_var"], "z2": z2,
                "skipped": res.info["skipped"], "coef": self.coef,
                "forgetting": self.forgetting}
        return SequentialResult(
            time_s=t, state=hist, std=res.std * scale[:, None] if self.coef_std else res.std,
            state_names=self.terms,
            loglik=-0.5 * (np.log(2 * np.pi * prior_scale2 * (1 + res.info["prior_var"]))
                           + nis),
            innovation=res.innovation, innovations={"mag": stats}, info=info)

    def step(self, y: float, u: np.ndarray | None = None) -> Step:
        """Process one sample.

        Parameters
        ----------
        y : float
            Scalar magnetometer [nT].
        u : ndarray, shape (4,)
            Time [s] and the fluxgate ``flux_x, flux_y, flux_z`` [nT] (required).

        Returns
        -------
        Step
            Coefficients after the sample and their std, the band-passed a-priori residual
            (innovation, shape (1,)), its log-likelihood, ``used``.  The sample's
            ``mag_tl`` (with the estimate before it) is :attr:`last_mag_tl`.
        """
        if u is None:
            raise ValueError("OnlineTL.step needs u = (time, flux_x, flux_y, flux_z)")
        r = self.run(np.array([y], dtype=float), np.asarray(u, dtype=float).reshape(1, 4))
        self.last_mag_tl = float(r.info["mag_tl"][0])
        self.last_mag_tl_std = float(r.info["mag_tl_std"][0])
        return Step(r.state[0], r.std[0], r.innovation[0], float(r.loglik[0]),
                    not bool(r.info["skipped"][0]))


    def compensate(self, time_s: np.ndarray, flux_nT: np.ndarray, mag_nT: np.ndarray, *,
                   threshold: float = NIS_THRESHOLD) -> OnlineTLResult:
        """Run a whole log and check where the output was issued before convergence.

        Parameters
        ----------
        time_s : ndarray, shape (N,)
            Strictly increasing times [s].
        flux_nT : ndarray, shape (N, 3)
            Body-frame fluxgate [nT].
        mag_nT : ndarray, shape (N,)
            Scalar magnetometer [nT].
        threshold : float
            Windowed NIS ratio of :func:`convergence_spans`.

        Returns
        -------
        OnlineTLResult
        """
        t = np.asarray(time_s, dtype=np.float64)
        fit = self.run(mag_nT, np.column_stack([t, np.asarray(flux_nT, dtype=np.float64)
                                                .reshape(len(t), 3)]))
        ratio, conv, spans = convergence_spans(t, fit.info["z2"], self.forgetting,
                                               threshold=threshold)
        return OnlineTLResult(fit=fit, mag_tl=fit.info["mag_tl"],
                              mag_tl_std=fit.info["mag_tl_std"], nis_ratio=ratio,
                              converged=conv, spans=spans)
