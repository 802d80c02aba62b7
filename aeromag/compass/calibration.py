"""Online 12-parameter calibration of a vector magnetometer, the compass heading, excitation.

The calibrated field is ``flux_cal = D @ flux + e`` (soft-iron matrix ``D``, 3 x 3, and
hard-iron offset ``e``, nT), estimated sample by sample by recursive least squares with a
forgetting factor (:mod:`aeromag._core.rls`) against the expected Earth field rotated into
body axes by the attitude, ``b_ref = C_nb.T m``.  Each body axis ``i`` is one output of a
regression on the shared regressor ``[flux / F0, 1]``: ``b_ref_i / F0 = D_i . flux / F0 +
e_i / F0`` (``F0`` the reference intensity, so the regressor is of order one and ``P_0 =
alpha I`` means the same whatever the field).  The calibrated field of sample k uses the
estimate from the samples before it (strictly causal, the a-priori estimate): the heading of
a sample then never depends on that sample's own reference field, which is built from the
attitude heading it is compared with.  (With the a-posteriori estimate and a short memory the
fit would reproduce the reference and the heading error would look smaller than it is.)
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from .._core.angles import wrap360_deg, wrap_deg
from .._core.rls import RecursiveLeastSquares, check_forgetting
from .._core.rotations import rotate_body_to_ned, rotate_ned_to_body
from .._core.sequential import SequentialResult, Step
from ..errors import InputError
from .heading_stats import HeadingErrorStats, heading_error_stats

log = logging.getLogger(__name__)

__all__ = ["CompassCalibration", "CompassResult", "ExcitationWindow", "STATE_NAMES",
           "attitude_at_samples",
           "compass_heading",
           "excitation_windows", "EXCITATION_THRESHOLD",
           "calibrate_compass", "convergence_time", "reference_in_body"]

#: Number of parameters: D (9, row-major) and e (3).
N_PARAMS = 12

#: Minimum excitation (see :func:`excitation_windows`) of a window whose estimate can be
#: trusted.  Set from the study's simulator (roll, pitch and heading oscillating together):
#: +-10 deg gives 0.0056, +-15 deg 0.0125, +-20 deg 0.022, +-40 deg 0.088.  The study found
#: +-10 deg not enough and +-20-55 deg enough; at +-15 deg the offset is still wrong by
#: several uT after 15 s (notebooks/compass.ipynb), so the line is drawn between 15 and 20.
EXCITATION_THRESHOLD = 0.015


def compass_heading(flux_cal_nT: np.ndarray, pitch_deg: np.ndarray, roll_deg: np.ndarray,
                    declination_deg: np.ndarray | float = 0.0) -> np.ndarray:
    """True heading from a calibrated body-frame field, tilt-compensated.

    The field is levelled with roll and pitch (yaw left out): in that frame it is
    ``(H cos(Dec - psi), H sin(Dec - psi), Z)``, so the magnetic heading is
    ``-atan2(b_y, b_x)`` and the true heading adds the declination.

    Parameters
    ----------
    flux_cal_nT : ndarray, shape (n, 3)
        Calibrated field in body axes [nT].
    pitch_deg, roll_deg : ndarray, shape (n,)
        Attitude [deg].
    declination_deg : float or ndarray, shape (n,)
        Declination [deg, east of true north].

    Returns
    -------
    ndarray, shape (n,)
        True heading [deg] in [0, 360).
    """
    lvl = rotate_body_to_ned(flux_cal_nT, np.deg2rad(roll_deg), np.deg2rad(pitch_deg), 0.0)
    psi_m = -np.rad2deg(np.arctan2(lvl[:, 1], lvl[:, 0]))
    return wrap360_deg(psi_m + np.asarray(declination_deg, dtype=np.float64))


@dataclass
class ExcitationWindow:
    """Attitude excitation of one window of the flight.

    Attributes
    ----------
    start_time, end_time : float
        Window [s].
    n : int
        Samples in the window.
    roll_range_deg, pitch_range_deg, heading_range_deg : float
        Peak-to-peak attitude [deg] (heading unwrapped).
    excitation : float
        Square root of the smallest eigenvalue of the covariance of the reference field's
        direction in body axes (dimensionless): how well the window determines all 12
        parameters (0: a plane of directions, some parameters not determined).
    sufficient : bool
        ``excitation >= threshold``.
    """

    start_time: float
    end_time: float
    n: int
    roll_range_deg: float
    pitch_range_deg: float
    heading_range_deg: float
    excitation: float
    sufficient: bool

    def to_dict(self) -> dict[str, float | int | bool]:
        """JSON-ready dict."""
        return dict(self.__dict__)

    @classmethod
    def from_dict(cls, d: dict[str, float | int | bool]) -> ExcitationWindow:
        """Read a window written by :meth:`to_dict`."""
        return cls(**d)


def excitation_windows(time_s: np.ndarray, heading_deg: np.ndarray, pitch_deg: np.ndarray,
                       roll_deg: np.ndarray, ref_body_nT: np.ndarray, *,
                       window_s: float = 5.0, threshold: float = EXCITATION_THRESHOLD,
                       ) -> list[ExcitationWindow]:
    """Excitation indicator per window: attitude ranges and the spread of field directions.

    The 12 parameters are determined only if the measured field directions span a volume:
    field vectors of constant magnitude lie on a sphere, and a small patch of it (small
    manoeuvres) is nearly flat, leaving the combination of the matrix and the offset
    along its normal undetermined.  The indicator is the square root of the smallest
    eigenvalue of the covariance of the unit reference vector in body axes over the
    window; it grows as the square of the manoeuvre amplitude.

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Times [s].
    heading_deg, pitch_deg, roll_deg : ndarray, shape (n,)
        Attitude [deg].
    ref_body_nT : ndarray, shape (n, 3)
        Reference field in body axes [nT].
    window_s : float
        Window length [s].
    threshold : float
        Minimum excitation of a sufficient window.

    Returns
    -------
    list of ExcitationWindow
    """
    t = np.asarray(time_s, dtype=np.float64)
    n = len(t)
    if not n:
        return []
    u = ref_body_nT / np.linalg.norm(ref_body_nT, axis=1, keepdims=True)
    ok = np.isfinite(u).all(axis=1)
    hdg = np.full(n, np.nan)
    h = np.asarray(heading_deg, dtype=np.float64)
    fin = np.isfinite(h)
    hdg[fin] = np.rad2deg(np.unwrap(np.deg2rad(h[fin])))  # a NaN row must not stop unwrap
    edges = np.arange(t[0], t[-1] + window_s, window_s)
    bounds = np.searchsorted(t, edges)
    a, b = bounds[:-1], bounds[1:]
    use = (b - a >= 4) & (a < n)
    a, b = a[use], b[use]
    if not len(a):
        return []
    # Moments per window, all windows at once: sums over [a, b) by reduceat when the windows
    # follow each other (the usual case), else from cumulative sums.
    uz = np.where(ok[:, None], u, 0.0)
    iu, ju = np.triu_indices(3)
    cols = np.empty((n, 10))
    cols[:, 0] = ok
    cols[:, 1:4] = uz
    np.multiply(uz[:, iu], uz[:, ju], out=cols[:, 4:])
    contiguous = bool(np.array_equal(a[1:], b[:-1]))
    if contiguous:
        idx = np.r_[a, b[-1]] if b[-1] < n else a
        s = np.add.reduceat(cols, idx, axis=0)[:len(a)]
    else:
        c = np.vstack([np.zeros((1, cols.shape[1])), np.cumsum(cols, axis=0)])
        s = c[b] - c[a]
    del cols
    cnt = s[:, 0]
    s2 = np.empty((len(a), 3, 3))
    s2[:, iu, ju] = s[:, 4:]
    s2[:, ju, iu] = s[:, 4:]
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = s[:, 1:4] / cnt[:, None]
        cov = (s2 - cnt[:, None, None] * mean[:, :, None] * mean[:, None, :]) \
            / (cnt - 1)[:, None, None]
    good = cnt > 3
    exc = np.zeros(len(a))
    if good.any():
        exc[good] = np.sqrt(np.clip(np.linalg.eigvalsh(cov[good])[:, 0], 0.0, None))

    def ranges(x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        starts = bounds[:-1][use]
        # reduceat runs from each start to the next one; windows are consecutive, so cut at
        # the window ends explicitly by reducing over [a, b) with a gap-free index list.
        idx = np.r_[starts, b[-1]] if b[-1] < n else starts
        hi = np.fmax.reduceat(x, idx)[:len(starts)]
        lo = np.fmin.reduceat(x, idx)[:len(starts)]
        r = hi - lo
        return np.where(np.isfinite(r), r, 0.0)

    if contiguous:
        rr, pr, hr = ranges(roll_deg), ranges(pitch_deg), ranges(hdg)
    else:  # some windows skipped (fewer than 4 samples): one window at a time
        def one(x: np.ndarray) -> np.ndarray:
            x = np.asarray(x, dtype=np.float64)
            out = np.zeros(len(a))
            for i, (lo_, hi_) in enumerate(zip(a, b, strict=True)):
                v = x[lo_:hi_]
                v = v[np.isfinite(v)]
                out[i] = v.max() - v.min() if v.size else 0.0
            return out

        rr, pr, hr = one(roll_deg), one(pitch_deg), one(hdg)
    return [ExcitationWindow(start_time=float(t[a[i]]), end_time=float(t[b[i] - 1]),
                             n=int(b[i] - a[i]), roll_range_deg=float(rr[i]),
                             pitch_range_deg=float(pr[i]), heading_range_deg=float(hr[i]),
                             excitation=float(exc[i]), sufficient=bool(exc[i] >= threshold))
            for i in range(len(a))]


#: Names of the calibration's state, in :class:`CompassCalibration`'s order: ``D``
#: row-major (dimensionless), then ``e`` [nT].
STATE_NAMES = tuple(f"D_{r}{c}" for r in "xyz" for c in "xyz") + ("e_x_nT", "e_y_nT",
                                                                   "e_z_nT")


@dataclass
class CompassResult:
    """What :func:`calibrate_compass` returns: the filter's run and the compass's own fields.

    Attributes
    ----------
    fit : SequentialResult
        :meth:`CompassCalibration.run`: state ``D`` (row-major) and ``e`` [nT] after each
        sample (:data:`STATE_NAMES`), their std, the a-priori innovation
        ``b_ref - flux_cal`` [nT], consistency in ``innovations["field"]``.
    flux_cal_nT : ndarray, shape (n, 3)
        Calibrated field, each sample with the estimate from the samples before it [nT].
    mag_heading_cal : ndarray, shape (n,)
        Tilt-compensated heading of ``flux_cal_nT`` plus the declination [deg].
    heading_err_deg : ndarray, shape (n,)
        ``mag_heading_cal - heading``, wrapped [deg].
    metrics : HeadingErrorStats
        :func:`heading_error_stats` of ``heading_err_deg``.
    excitation : list of ExcitationWindow
    """

    fit: SequentialResult
    flux_cal_nT: np.ndarray
    mag_heading_cal: np.ndarray
    heading_err_deg: np.ndarray
    metrics: HeadingErrorStats
    excitation: list[ExcitationWindow] = field(default_factory=list)

    @property
    def matrix_history(self) -> np.ndarray:
        """``D`` after each sample, shape (n, 3, 3)."""
        return self.fit.state[:, :9].reshape(-1, 3, 3)

    @property
    def offset_history_nT(self) -> np.ndarray:
        """``e`` after each sample [nT], shape (n, 3)."""
        return self.fit.state[:, 9:]

    @property
    def matrix(self) -> np.ndarray:
        """Final ``D`` (3 x 3)."""
        return self.fit.info["matrix"]

    @property
    def offset_nT(self) -> np.ndarray:
        """Final ``e`` [nT]."""
        return self.fit.info["offset_nT"]

    @property
    def skipped(self) -> np.ndarray:
        """Samples not used (flux, attitude or reference not finite)."""
        return self.fit.info["skipped"]


class CompassCalibration:
    """Online hard- and soft-iron calibration (12 parameters) by RLS with forgetting.

    The sequential-filter convention (:mod:`aeromag._core.sequential`): the measurement
    ``y`` is the expected Earth field in body axes, the input ``u`` the measured field.

    Parameters
    ----------
    forgetting : float
        lambda, 0 < lambda <= 1 (1: plain RLS; the study: 0.96-0.975).
    alpha : float
        Prior covariance scale of the normalised parameters (``P_0 = alpha I``).
    field_scale_nT : float
        ``F0``, the scale of the regressor [nT] (set it to the reference intensity).
    noise_nT : float
        One-sigma mismatch per axis between the measured and the expected field [nT]
        (sensor noise and attitude error): scales the reported std, NIS and
        log-likelihood only, not the estimate.
    """

    def __init__(self, forgetting: float = 0.975, *, alpha: float = 1e4,
                 field_scale_nT: float = 50000.0, noise_nT: float = 200.0) -> None:
        self.forgetting = check_forgetting(forgetting)
        self.alpha = float(alpha)
        self.f0 = float(field_scale_nT)
        theta0 = np.vstack([np.eye(3), np.zeros((1, 3))])  # D = I, e = 0
        self.rls = RecursiveLeastSquares(4, 3, forgetting=self.forgetting, alpha=self.alpha,
                                         theta0=theta0, noise_std=float(noise_nT) / self.f0)
        self.state_names = STATE_NAMES

    @property
    def matrix(self) -> np.ndarray:
        """Current ``D`` (3 x 3)."""
        return self.rls.theta[:3].T.copy()

    @property
    def offset_nT(self) -> np.ndarray:
        """Current ``e`` [nT]."""
        return self.rls.theta[3] * self.f0

    def _regressor(self, flux_nT: np.ndarray) -> np.ndarray:
        f = np.atleast_2d(np.asarray(flux_nT, dtype=np.float64)) / self.f0
        return np.column_stack([f, np.ones(len(f))])

    def _to_domain(self, flat: np.ndarray) -> np.ndarray:
        """RLS state(s) ``Theta.reshape(-1)`` (normalised, (..., 12)) to ``[D row-major, e nT]``."""
        th = flat.reshape(*flat.shape[:-1], 4, 3)
        d = np.swapaxes(th[..., :3, :], -1, -2).reshape(*flat.shape[:-1], 9)
        return np.concatenate([d, th[..., 3, :] * self.f0], axis=-1)

    def step(self, y: np.ndarray, u: np.ndarray | None = None) -> Step:
        """One sample: update with the expected field ``y`` and the measured field ``u``.

        Parameters
        ----------
        y : ndarray, shape (3,)
            Expected Earth field in body axes [nT].
        u : ndarray, shape (3,)
            Measured field in body axes [nT] (required).

        Returns
        -------
        Step
            State ``[D row-major, e nT]`` and its std after the sample; innovation
            ``y - (D @ u + e)`` with the estimate before the sample [nT] (NaN when the
            sample is not usable, ``used`` False).
        """
        if u is None:
            raise ValueError("CompassCalibration.step needs the measured field u")
        st = self.rls.step(np.asarray(y, dtype=np.float64) / self.f0, self._regressor(u)[0])
        return Step(self._to_domain(st.state), self._to_domain(st.std),
                    st.innovation * self.f0, st.loglik - 3.0 * np.log(self.f0), st.used)

    def run(self, ys: np.ndarray, us: np.ndarray | None = None) -> SequentialResult:
        """Calibrate a whole log (vectorised; continues from the current state).

        Parameters
        ----------
        ys : ndarray, shape (n, 3)
            Expected Earth field in body axes [nT] (NaN where the attitude is missing).
        us : ndarray, shape (n, 3)
            Measured field in body axes [nT] (required).

        Returns
        -------
        SequentialResult
            State ``[D row-major, e nT]`` (:data:`STATE_NAMES`) and std after each sample,
            the a-priori innovation [nT], ``innovations["field"]``; ``info``:
            ``flux_cal_nT`` (the a-priori calibrated field, NaN where the flux is not
            finite), ``skipped``, ``matrix``, ``offset_nT`` (final), ``forgetting``,
            ``alpha``.
        """
        if us is None:
            raise ValueError("CompassCalibration.run needs the measured field us")
        phi = self._regressor(us)
        before = self.rls.theta.copy()
        res = self.rls.run(np.asarray(ys, dtype=np.float64) / self.f0, phi)
        th = res.state.reshape(-1, 4, 3)  # after each sample
        cal = np.empty((len(phi), 3))  # with the estimate before each sample
        if len(phi):
            cal[0] = phi[0] @ before
            cal[1:] = np.einsum("ki,kij->kj", phi[1:], th[:-1])
        cal *= self.f0
        cal[~np.isfinite(phi).all(axis=1)] = np.nan
        info = {"flux_cal_nT": cal, "skipped": res.info["skipped"], "matrix": self.matrix,
                "offset_nT": self.offset_nT, "forgetting": self.forgetting,
                "alpha": self.alpha}
        return SequentialResult(
            time_s=res.time_s, state=self._to_domain(res.state),
            std=self._to_domain(res.std), state_names=STATE_NAMES,
            loglik=res.loglik - 3.0 * np.log(self.f0), innovation=res.innovation * self.f0,
            innovations={"field": res.innovations["y"]}, info=info)


#: Longest interval [s] between two attitude samples across which the attitude is
#: interpolated to a magnetometer row of a multi-rate log (flight controllers log attitude
#: at 10-250 Hz; a longer interval is a gap, and its magnetometer rows stay unused).
ATTITUDE_MAX_GAP_S = 0.25


def attitude_at_samples(time_s: np.ndarray, heading_deg: np.ndarray, pitch_deg: np.ndarray,
                        roll_deg: np.ndarray, want: np.ndarray, *,
                        max_gap_s: float = ATTITUDE_MAX_GAP_S,
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Attitude at the rows of a multi-rate log that have a magnetometer sample but no attitude.

    A log whose sensors are sampled at different rates has one row per sample time of any
    sensor, a sensor's columns empty on the others' rows (interface.md).  The attitude of a
    row in ``want`` without a complete attitude is interpolated linearly in time between the
    attitude samples just before and just after it (heading unwrapped, so 359 -> 1 deg passes
    through 0), when those are at most ``max_gap_s`` apart; otherwise it stays NaN (the row is
    skipped by the calibration and counted).

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Row times [s], increasing.
    heading_deg, pitch_deg, roll_deg : ndarray, shape (n,)
        Attitude [deg], NaN where the row has none.
    want : ndarray of bool, shape (n,)
        Rows that need an attitude (those with a magnetometer sample).
    max_gap_s : float
        Longest interval between the bracketing attitude samples [s].

    Returns
    -------
    heading, pitch, roll : ndarray, shape (n,)
        Attitude [deg], heading in [0, 360) where interpolated.
    filled : ndarray of bool, shape (n,)
        Rows whose attitude was interpolated.
    """
    t = np.asarray(time_s, dtype=np.float64)
    h, p, r = (np.array(x, dtype=np.float64) for x in (heading_deg, pitch_deg, roll_deg))
    have = np.isfinite(h) & np.isfinite(p) & np.isfinite(r) & np.isfinite(t)
    need = np.asarray(want, dtype=bool) & ~have & np.isfinite(t)
    filled = np.zeros(len(t), dtype=bool)
    if not need.any() or have.sum() < 2:
        return h, p, r, filled
    ta = t[have]
    k = np.searchsorted(ta, t[need])  # attitude sample after (or at) each wanted row
    inside = (k > 0) & (k < len(ta))
    ks = np.clip(k, 1, len(ta) - 1)
    inside &= (ta[ks] - ta[ks - 1]) <= max_gap_s
    rows = np.flatnonzero(need)[inside]
    tq = t[rows]
    hu = np.rad2deg(np.unwrap(np.deg2rad(h[have])))
    h[rows] = wrap360_deg(np.interp(tq, ta, hu))
    p[rows] = np.interp(tq, ta, p[have])
    r[rows] = np.interp(tq, ta, r[have])
    filled[rows] = True
    return h, p, r, filled


def reference_in_body(ref_ned_nT: np.ndarray, heading_deg: np.ndarray, pitch_deg: np.ndarray,
                      roll_deg: np.ndarray) -> np.ndarray:
    """Expected Earth field in body axes, ``C_nb.T m``.

    Parameters
    ----------
    ref_ned_nT : ndarray, shape (3,) or (n, 3)
        Reference field in NED [nT].
    heading_deg, pitch_deg, roll_deg : ndarray, shape (n,)
        Attitude (true heading) [deg].

    Returns
    -------
    ndarray, shape (n, 3)
        [nT]; NaN where the attitude is not finite.
    """
    return rotate_ned_to_body(ref_ned_nT, np.deg2rad(roll_deg), np.deg2rad(pitch_deg),
                              np.deg2rad(heading_deg))


def calibrate_compass(flux_nT: np.ndarray, heading_deg: np.ndarray, pitch_deg: np.ndarray,
                      roll_deg: np.ndarray, ref_ned_nT: np.ndarray, *,
                      time_s: np.ndarray | None = None, forgetting: float = 0.975,
                      alpha: float = 1e4, window_s: float = 5.0) -> CompassResult:
    """Calibrate a log end to end: estimate, calibrated field, heading, its error, excitation.

    Parameters
    ----------
    flux_nT : ndarray, shape (n, 3)
        Measured field in body axes [nT].
    heading_deg, pitch_deg, roll_deg : ndarray, shape (n,)
        Attitude [deg]; heading true.
    ref_ned_nT : ndarray, shape (3,) or (n, 3)
        Reference Earth field in NED [nT].
    time_s : ndarray, shape (n,), optional
        Times [s] (for the excitation windows; sample index / 50 when omitted).
    forgetting, alpha : float
        See :class:`CompassCalibration`.
    window_s : float
        Excitation window [s].

    Returns
    -------
    CompassResult
        The filter's :class:`SequentialResult` (``fit``, times ``time_s``) and the
        calibrated field, heading, heading error, its metrics and the excitation windows.

    Raises
    ------
    InputError
        Fewer usable samples than parameters.
    """
    flux = np.asarray(flux_nT, dtype=np.float64)
    ref = np.asarray(ref_ned_nT, dtype=np.float64)
    b_ref = reference_in_body(ref, heading_deg, pitch_deg, roll_deg)
    usable = np.isfinite(flux).all(axis=1) & np.isfinite(b_ref).all(axis=1)
    if usable.sum() < N_PARAMS:
        raise InputError(f"only {int(usable.sum())} samples with flux_x/y/z, heading, pitch "
                         f"and roll: the calibration needs at least {N_PARAMS} (12 "
                         "parameters); give a longer log")
    f0 = float(np.nanmean(np.linalg.norm(np.atleast_2d(ref), axis=1)))
    cal = CompassCalibration(forgetting, alpha=alpha, field_scale_nT=f0)
    fit = cal.run(b_ref, flux)
    flux_cal = fit.info.pop("flux_cal_nT")
    decl = np.rad2deg(np.arctan2(np.atleast_2d(ref)[:, 1], np.atleast_2d(ref)[:, 0]))
    hdg = compass_heading(flux_cal, pitch_deg, roll_deg,
                          decl if decl.size > 1 else float(decl[0]))
    err = wrap_deg(hdg - np.asarray(heading_deg, dtype=np.float64))
    t = np.arange(len(flux)) / 50.0 if time_s is None else np.asarray(time_s, dtype=float)
    fit.time_s = t
    return CompassResult(
        fit=fit, flux_cal_nT=flux_cal, mag_heading_cal=hdg, heading_err_deg=err,
        metrics=heading_error_stats(err),
        excitation=excitation_windows(t, heading_deg, pitch_deg, roll_deg, b_ref,
                                      window_s=window_s))


def convergence_time(time_s: np.ndarray, err_deg: np.ndarray, start_s: float, *,
                     threshold_deg: float = 1.0, window_s: float = 1.0,
                     step_s: float = 0.1) -> float:
    """Time after ``start_s`` from which the running RMS heading error stays below a level.

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Times [s].
    err_deg : ndarray, shape (n,)
        Heading error [deg].
    start_s : float
        Start (e.g. the interference switch) [s].
    threshold_deg : float
        Level of the RMS over ``window_s`` [deg].
    window_s, step_s : float
        Length and step of the sliding window [s].

    Returns
    -------
    float
        Seconds from ``start_s`` to the end of the last window above the level (0 when none
        is); ``inf`` when the last window is above it (never converged).
    """
    t = np.asarray(time_s, dtype=np.float64)
    e = np.asarray(err_deg, dtype=np.float64)
    starts = np.arange(start_s, t[-1] - window_s + 1e-9, step_s)
    lo = np.searchsorted(t, starts)
    hi = np.searchsorted(t, starts + window_s)
    c2 = np.concatenate([[0.0], np.cumsum(np.where(np.isfinite(e), e * e, 0.0))])
    cnt = np.concatenate([[0], np.cumsum(np.isfinite(e))])
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = np.sqrt((c2[hi] - c2[lo]) / (cnt[hi] - cnt[lo]))
    above = np.flatnonzero(~(rms < threshold_deg))
    if not above.size:
        return 0.0
    if above[-1] == len(rms) - 1:
        return float("inf")
    return float(starts[above[-1]] + window_s - start_s)
