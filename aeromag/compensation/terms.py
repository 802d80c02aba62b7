"""The Tolles-Lawson (TL) aircraft-interference model: terms and design matrix.

Direction cosines ``cx, cy, cz`` are the fluxgate vector over its magnitude ``|B|``; ``'`` is
the time derivative (``np.gradient`` against real time, never across a time gap).  ``|B|``
enters the induced and eddy terms as ``s = |B| / 50000 nT`` so every coefficient is in nT
(eddy coefficients in nT*s) and model files are portable.  Term order (interface.md):

1. permanent: ``cx, cy, cz``
2. induced (times s): ``cx*cx, cx*cy, cx*cz, cy*cy, cy*cz``
3. eddy (times s): ``cx*cx', cx*cy', cx*cz', cy*cx', cy*cy', cy*cz', cz*cx', cz*cy'``

The other term sets users know from MagNav.jl are available too (``induced_6/5/3``,
``eddy_9/8/3``, ``bias``); ``16`` (permanent + induced_5 + eddy_8) is the default.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np

from ..conventions import EDDY_8, FIELD_SCALE_NT, INDUCED_5, PERMANENT, TERMS_16
from ..errors import ConfigError

log = logging.getLogger(__name__)


# The 16 terms of interface.md and the |B| scale are the package's conventions (one
# definition, in aeromag.conventions); the other groups are built from them.
INDUCED_6 = INDUCED_5 + ("cz*cz",)
INDUCED_3 = ("cx*cx", "cy*cy", "cz*cz")
EDDY_9 = EDDY_8 + ("cz*cz'",)
EDDY_3 = ("cx*cx'", "cy*cy'", "cz*cz'")
BIAS = ("bias",)

_GROUPS: dict[str, tuple[str, ...]] = {
    "permanent": PERMANENT,
    "p": PERMANENT,
    "induced": INDUCED_6,
    "i": INDUCED_6,
    "induced_6": INDUCED_6,
    "i6": INDUCED_6,
    "induced_5": INDUCED_5,
    "i5": INDUCED_5,
    "induced_3": INDUCED_3,
    "i3": INDUCED_3,
    "eddy": EDDY_9,
    "e": EDDY_9,
    "eddy_9": EDDY_9,
    "e9": EDDY_9,
    "eddy_8": EDDY_8,
    "e8": EDDY_8,
    "eddy_3": EDDY_3,
    "e3": EDDY_3,
    "bias": BIAS,
    "b": BIAS,
}
# MagNav.jl's spellings without the underscore (``induced5``, ``eddy8``...) too.
_GROUPS.update({k.replace("_", ""): v for k, v in list(_GROUPS.items()) if "_" in k})
_PRESETS: dict[str, tuple[str, ...]] = {
    "16": TERMS_16,
    "18": PERMANENT + INDUCED_6 + EDDY_9,
    "9": PERMANENT + INDUCED_3 + EDDY_3,
    "3": PERMANENT,
    "8": PERMANENT + INDUCED_5,
}
ALL_TERMS = set(PERMANENT + INDUCED_6 + EDDY_9 + BIAS)
AXIS = {"cx": 0, "cy": 1, "cz": 2}


def parse_terms(spec: str | Sequence[str]) -> tuple[str, ...]:
    """Resolve a term-set specification into an ordered tuple of term names.

    Parameters
    ----------
    spec : str or sequence of str
        ``"16"`` (default set), ``"18"``, ``"9"``, ``"8"``, ``"3"``, or a comma-separated list of
        MagNav.jl-style groups (``permanent``/``p``, ``induced``/``induced_6``/``induced_5``/
        ``induced_3`` (``i``, ``i6``, ``i5``, ``i3``), ``eddy``/``eddy_9``/``eddy_8``/``eddy_3``
        (``e``, ``e9``, ``e8``, ``e3``), ``bias``/``b``; MagNav's ``induced5``, ``eddy8``
        and ``:induced_5`` spellings too) and/or single term names (``"cx*cy'"``).

    Returns
    -------
    tuple of str
        Term names in canonical order (permanent, induced, eddy, bias), without duplicates.
    """
    items: list[str]
    if isinstance(spec, str):
        key = spec.strip().lower()
        if key in _PRESETS:
            return _PRESETS[key]
        items = [s.strip() for s in spec.split(",") if s.strip()]
    else:
        items = [str(s).strip() for s in spec]
    if not items:
        raise ConfigError("terms", spec, "empty term set; use 16 or a list like"
                          " permanent,induced_5,eddy_8")
    chosen: set[str] = set()
    for it in items:
        k = it.lower().lstrip(":")
        if k in _GROUPS:
            chosen.update(_GROUPS[k])
        elif it in ALL_TERMS:
            chosen.add(it)
        elif k in _PRESETS:
            chosen.update(_PRESETS[k])
        else:
            raise ConfigError(
                "terms", spec, f"unknown term or group {it!r}; use 16, 18, 9, or groups"
                " permanent, induced[_6|_5|_3], eddy[_9|_8|_3], bias")
    order = PERMANENT + INDUCED_6 + EDDY_9 + BIAS
    return tuple(t for t in order if t in chosen)


def direction_cosines(flux_nT: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Direction cosines and magnitude of the fluxgate vector.

    Parameters
    ----------
    flux_nT : ndarray, shape (n, 3)
        Body-frame fluxgate vector [nT].

    Returns
    -------
    cosines : ndarray, shape (n, 3)
        ``flux / |flux|`` [dimensionless].
    magnitude_nT : ndarray, shape (n,)
        ``|flux|`` [nT].
    """
    flux = np.asarray(flux_nT, dtype=np.float64)
    bt = np.sqrt(np.einsum("ij,ij->i", flux, flux))
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = flux / bt[:, None]
    return cos, bt


def stretch_starts(time_s: np.ndarray, stretch: np.ndarray | None) -> np.ndarray:
    """Boolean mask of samples that start a new continuous stretch.

    Parameters
    ----------
    time_s : ndarray, shape (n,)
        Sample times [s].
    stretch : ndarray of int, shape (n,), optional
        Stretch label per sample; a change of label starts a stretch.  ``None`` means one
        stretch.

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    n = len(time_s)
    starts = np.zeros(n, dtype=bool)
    if n:
        starts[0] = True
    if stretch is not None and n > 1:
        starts[1:] = stretch[1:] != stretch[:-1]
    return starts


def time_derivative(
    values: np.ndarray, time_s: np.ndarray, stretch: np.ndarray | None = None
) -> np.ndarray:
    """Time derivative by ``np.gradient`` against real time, never across a stretch boundary.

    Identical (to rounding) to calling ``np.gradient(values[k], time_s[k], axis=0)`` on every
    stretch ``k`` separately (second-order central differences inside, first-order one-sided
    differences at the ends; a one-sample stretch gets 0), but vectorised over the whole log.

    Parameters
    ----------
    values : ndarray, shape (n,) or (n, m)
        Samples.
    time_s : ndarray, shape (n,)
        Strictly increasing times [s].
    stretch : ndarray of int, shape (n,), optional
        Stretch label per sample (see :func:`stretch_starts`).

    Returns
    -------
    ndarray
        d(values)/dt [unit of values per second], same shape as ``values``.
    """
    f = np.asarray(values, dtype=np.float64)
    t = np.asarray(time_s, dtype=np.float64)
    n = len(t)
    step = PREDICT_BLOCK
    if n <= 2 * step:
        return _time_derivative(f, t, stretch)
    # Block by block with one sample of context each side: the same arithmetic on the same
    # values, but the temporaries stay in cache (5x faster at 1e6 samples).
    out = np.empty_like(f)
    for a in range(0, n, step):
        b = min(n, a + step)
        lo, hi = max(0, a - 1), min(n, b + 1)
        d = _time_derivative(f[lo:hi], t[lo:hi], None if stretch is None else stretch[lo:hi])
        out[a:b] = d[a - lo:a - lo + (b - a)]
    return out


def time_derivative_rows(
    values: np.ndarray, time_s: np.ndarray, stretch: np.ndarray
) -> np.ndarray:
    """:func:`time_derivative` of many short series at once (one per row).

    Bitwise the same arithmetic as :func:`time_derivative` applied to each row on its own.

    Parameters
    ----------
    values : ndarray, shape (q, m, c)
        Samples, ``c`` channels per sample.
    time_s : ndarray, shape (q, m)
        Strictly increasing times [s] inside each stretch of a row.
    stretch : ndarray of int, shape (q, m)
        Stretch label per sample; derivatives never cross a change of label.

    Returns
    -------
    ndarray, shape (q, m, c)
        d(values)/dt [unit of values per second].
    """
    f = np.asarray(values, dtype=np.float64)
    t = np.asarray(time_s, dtype=np.float64)
    out = np.zeros_like(f)
    m = f.shape[1]
    if m < 2:
        return out
    h = np.diff(t, axis=1)  # h[:, i] = t[:, i+1] - t[:, i]
    change = stretch[:, 1:] != stretch[:, :-1]
    starts = np.ones(t.shape, dtype=bool)
    starts[:, 1:] = change
    ends = np.ones(t.shape, dtype=bool)
    ends[:, :-1] = change
    with np.errstate(divide="ignore", invalid="ignore"):  # across a change: overwritten
        if m > 2:
            hs = h[:, :-1, None]
            hd = h[:, 1:, None]
            out[:, 1:-1] = (hs * hs * f[:, 2:] + (hd * hd - hs * hs) * f[:, 1:-1]
                            - hd * hd * f[:, :-2]) / (hs * hd * (hd + hs))
        out[starts & ends] = 0.0
        r, c = np.nonzero(starts & ~ends)  # forward difference
        out[r, c] = (f[r, c + 1] - f[r, c]) / h[r, c][:, None]
        r, c = np.nonzero(ends & ~starts)  # backward difference
        out[r, c] = (f[r, c] - f[r, c - 1]) / h[r, c - 1][:, None]
    return out


def _time_derivative(f: np.ndarray, t: np.ndarray, stretch: np.ndarray | None) -> np.ndarray:
    n = len(t)
    out = np.zeros_like(f)
    if n < 2:
        return out
    starts = stretch_starts(t, stretch)
    ends = np.r_[starts[1:], True]
    f2 = f if f.ndim == 2 else f[:, None]
    o2 = out if out.ndim == 2 else out[:, None]
    h = np.diff(t)  # h[i] = t[i+1] - t[i]
    df = np.diff(f2, axis=0)
    # Central non-uniform differences everywhere inside (slices, no gathers); the samples at
    # stretch ends are overwritten below with one-sided differences (or 0).
    if n > 2:
        hs = h[:-1, None]
        hd = h[1:, None]
        o2[1:-1] = (hs * hs * f2[2:] + (hd * hd - hs * hs) * f2[1:-1] - hd * hd * f2[:-2]) / (
            hs * hd * (hd + hs)
        )
    o2[starts & ends] = 0.0
    # Stretch starts with a successor in the same stretch: forward difference.
    first = np.flatnonzero(starts & ~ends)
    if first.size:
        o2[first] = df[first] / h[first][:, None]
    # Stretch ends with a predecessor in the same stretch: backward difference.
    last = np.flatnonzero(ends & ~starts)
    if last.size:
        o2[last] = df[last - 1] / h[last - 1][:, None]
    return out


def _term_column(
    name: str, cos: np.ndarray, dcos: np.ndarray, scale: np.ndarray
) -> np.ndarray:
    if name == "bias":
        return np.ones(len(cos))
    if "*" not in name:
        return cos[:, AXIS[name]]
    a, b = name.split("*")
    if b.endswith("'"):
        return scale * cos[:, AXIS[a]] * dcos[:, AXIS[b[:-1]]]
    return scale * cos[:, AXIS[a]] * cos[:, AXIS[b]]


def design_matrix(
    flux_nT: np.ndarray,
    time_s: np.ndarray,
    terms: Sequence[str] = TERMS_16,
    *,
    stretch: np.ndarray | None = None,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Build the TL design matrix ``A`` (one column per term).

    Parameters
    ----------
    flux_nT : ndarray, shape (n, 3)
        Body-frame fluxgate vector [nT].
    time_s : ndarray, shape (n,)
        Sample times [s], strictly increasing.
    terms : sequence of str
        Term names (see :func:`parse_terms`); default the 16 terms of interface.md.
    stretch : ndarray of int, shape (n,), optional
        Continuous-stretch label per sample; derivatives never run across a change of label.
    out : ndarray, shape (n, len(terms)), optional
        Preallocated output.

    Returns
    -------
    ndarray, shape (n, len(terms))
        Permanent columns dimensionless, induced columns in units of ``|B|/50000 nT``, eddy
        columns in 1/s times that scale, so that ``A @ coef`` is in nT.
    """
    cos, bt = direction_cosines(flux_nT)
    need_d = any(t.endswith("'") for t in terms)
    dcos = time_derivative(cos, time_s, stretch) if need_d else cos
    return terms_from_cosines(cos, dcos, bt / FIELD_SCALE_NT, terms, out=out)


def terms_from_cosines(
    cos: np.ndarray, dcos: np.ndarray, scale: np.ndarray, terms: Sequence[str] = TERMS_16,
    *, out: np.ndarray | None = None,
) -> np.ndarray:
    """TL design matrix from direction cosines, their derivatives and the field scale.

    Parameters
    ----------
    cos : ndarray, shape (n, 3)
        Direction cosines [dimensionless].
    dcos : ndarray, shape (n, 3)
        Their time derivatives [1/s].
    scale : ndarray, shape (n,)
        ``|B| / 50000 nT`` [dimensionless].
    terms : sequence of str
        Term names.
    out : ndarray, shape (n, len(terms)), optional
        Preallocated output.

    Returns
    -------
    ndarray, shape (n, len(terms))
    """
    A = out if out is not None else np.empty((len(cos), len(terms)), dtype=np.float64)
    for j, name in enumerate(terms):
        A[:, j] = _term_column(name, cos, dcos, scale)
    return A


#: Samples per block when evaluating a model: the block's cosines, derivatives and terms
#: stay in cache, and memory does not grow with the log.
PREDICT_BLOCK = 16384
