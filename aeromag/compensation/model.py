"""A fitted Tolles-Lawson model (:class:`TLModel`) and its evaluation ``A @ coef``."""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from .report_types import CompensationReport
from .terms import (
    ALL_TERMS,
    AXIS,
    FIELD_SCALE_NT,
    PREDICT_BLOCK,
    direction_cosines,
    time_derivative,
)

log = logging.getLogger(__name__)


def predict_interference(
    flux_nT: np.ndarray, time_s: np.ndarray, terms: Sequence[str], coef: np.ndarray, *,
    stretch: np.ndarray | None = None, scale_nT: float = FIELD_SCALE_NT,
    block: int | None = None,
) -> np.ndarray:
    """Evaluate ``A @ coef``: the modelled interference [nT], block by block.

    Gives the same values (to rounding) as ``design_matrix(...) @ coef`` without ever holding
    the n x k design matrix: each block of ``block`` samples is evaluated with one sample of
    context on each side, so the derivatives inside a block are exactly those of the whole
    log (``np.gradient`` per stretch).

    Parameters
    ----------
    flux_nT : ndarray, shape (n, 3)
        Body-frame fluxgate [nT].
    time_s : ndarray, shape (n,)
        Times [s], strictly increasing.
    terms : sequence of str
        Term names.
    coef : ndarray, shape (len(terms),)
        Coefficients [nT; eddy terms nT*s].
    stretch : ndarray of int, shape (n,), optional
        Continuous-stretch labels; derivatives never cross a change.
    scale_nT : float
        The model's field scale [nT] (induced and eddy columns are in ``|B| / scale_nT``).
    block : int, optional
        Samples per block (default :data:`PREDICT_BLOCK`).

    Returns
    -------
    ndarray, shape (n,)
        Interference [nT].
    """
    flux = np.asarray(flux_nT, dtype=np.float64)
    t = np.asarray(time_s, dtype=np.float64)
    perm, ind, eddy, bias = coefficient_forms(terms, coef)
    n = len(t)
    out = np.empty(n)
    step = int(block or PREDICT_BLOCK)
    need_d = bool(np.any(eddy))

    def run(a: int) -> None:
        b = min(n, a + step)
        lo, hi = max(0, a - 1), min(n, b + 1)  # one sample of context for the derivative
        cos, bt = direction_cosines(flux[lo:hi])
        k = slice(a - lo, a - lo + (b - a))
        c = cos[k]
        # A @ coef as quadratic forms: c.p + |B|/s (c^T M c + c^T N c').
        quad = np.einsum("ij,ij->i", c @ ind, c)
        if need_d:
            dcos = time_derivative(cos, t[lo:hi], None if stretch is None else stretch[lo:hi])
            quad += np.einsum("ij,ij->i", c @ eddy, dcos[k])
        r = out[a:b]
        np.multiply(bt[k], quad, out=r)
        r /= scale_nT
        r += c @ perm
        if bias:
            r += bias

    for a in range(0, n, step):
        run(a)
    return out


def coefficient_forms(
    terms: Sequence[str], coef: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Write the TL model as a vector and two 3 x 3 forms.

    ``A @ coef`` equals ``c.p + (|B|/scale) (c^T M c + c^T N c') + bias``.

    Parameters
    ----------
    terms : sequence of str
        Term names (see :func:`parse_terms`).
    coef : ndarray, shape (len(terms),)
        Coefficients.

    Returns
    -------
    p : ndarray, shape (3,)
        Permanent coefficients [nT].
    M : ndarray, shape (3, 3)
        Induced coefficients, ``M[i, j]`` for term ``ci*cj`` [nT].
    N : ndarray, shape (3, 3)
        Eddy-current coefficients, ``N[i, j]`` for term ``ci*cj'`` [nT s].
    bias : float
        Constant term [nT].
    """
    c = np.asarray(coef, dtype=np.float64)
    if c.shape != (len(terms),):
        raise InputError(f"{len(terms)} terms but {c.size} coefficients")
    p = np.zeros(3)
    M = np.zeros((3, 3))
    N = np.zeros((3, 3))
    bias = 0.0
    for name, v in zip(terms, c, strict=True):
        if name == "bias":
            bias += float(v)
        elif "*" not in name:
            p[AXIS[name]] += v
        else:
            a, b = name.split("*")
            if b.endswith("'"):
                N[AXIS[a], AXIS[b[:-1]]] += v
            else:
                M[AXIS[a], AXIS[b]] += v
    return p, M, N, bias


#: Keys of a model file that are the model itself (the others are its fit report).
MODEL_KEYS = ("terms", "coef", "scale_nT", "extended")


@dataclass
class ModelMeta:
    """Where a model comes from: the file it was read from and the fit report it carries.

    A model file (``MODEL.json``, written by ``aeromag calibrate``) is the calibration's
    report (:class:`~aeromag.compensation.report_types.CompensationReport`); the model is its
    ``terms``, ``coef``, ``scale_nT`` and ``extended``.  The rest is typed as the report it
    is, not kept as a bag of keys.  The model's ``terms`` and ``coef`` are :class:`TLModel`'s
    alone: a report read from a file holds none (a fitted model's report holds the same).

    Attributes
    ----------
    path : str or None
        The file the model was read from, as the workflow that read it names it (never
        written into it; the applied report's ``model_source``, ``given`` without one).
    report : CompensationReport or None
        The fit report: the fit's own for a model fitted here (the result's report, so the
        metrics, ``segmentation`` and ``qc`` added to it are the model's too), or the model
        file read back (:meth:`CompensationReport.from_dict`: keys it does not know are in
        its ``extra``); None for a model built from coefficients alone.
    """

    path: str | None = None
    report: CompensationReport | None = None

    @property
    def mag_from_fluxgate(self) -> bool | None:
        """Whether the model was fitted on the fluxgate magnitude (None: not recorded)."""
        return None if self.report is None else self.report.mag_from_fluxgate

    def to_dict(self) -> dict[str, Any]:
        """The model file's keys beside the model's own (:data:`MODEL_KEYS`).

        Returns
        -------
        dict
            The report's document without :data:`MODEL_KEYS` (empty without a report).
        """
        if self.report is None:
            return {}
        return {k: v for k, v in self.report.to_dict().items() if k not in MODEL_KEYS}

    @classmethod
    def from_dict(cls, d: dict[str, Any], path: str | None = None) -> ModelMeta:
        """The metadata of a model document (its keys but :data:`MODEL_KEYS`).

        Parameters
        ----------
        d : dict
            The model document (its :data:`MODEL_KEYS` are the model's, not read here).
        path : str, optional
            The file it was read from.

        Returns
        -------
        ModelMeta
            ``report`` None when the document holds nothing beyond the model.
        """
        rest = {k: v for k, v in d.items() if k not in MODEL_KEYS}
        return cls(path, CompensationReport.from_dict(rest) if rest else None)


@dataclass
class TLModel:
    """A fitted Tolles-Lawson model: term names and coefficients (a property of the aircraft).

    Attributes
    ----------
    terms : tuple of str
        Term names in order.
    coef : ndarray
        Coefficients [nT; eddy terms nT*s], same order.
    scale_nT : float
        The ``|B|`` scale of the induced/eddy terms (50000 nT).
    meta : ModelMeta
        Provenance and fit report (:class:`ModelMeta`; a dict given here, a model file's
        other keys, is read by :meth:`ModelMeta.from_dict`).
    extended : ExtendedModel or None
        The reference, extras and network of an extended fit
        (:mod:`aeromag.compensation.extended`); saved under ``extended``.
    """

    terms: tuple[str, ...]
    coef: np.ndarray
    scale_nT: float = FIELD_SCALE_NT
    meta: ModelMeta = field(default_factory=ModelMeta)
    extended: Any = None

    def __post_init__(self) -> None:
        self.terms = tuple(self.terms)
        self.coef = np.asarray(self.coef, dtype=np.float64)
        if isinstance(self.meta, dict):
            self.meta = ModelMeta.from_dict(self.meta)
        if self.coef.shape != (len(self.terms),):
            raise InputError(
                f"model has {len(self.terms)} terms but {self.coef.size} coefficients"
            )

    def predict(
        self, flux_nT: np.ndarray, time_s: np.ndarray, stretch: np.ndarray | None = None
    ) -> np.ndarray:
        """Modelled aircraft interference ``A @ coef`` [nT] (unfiltered, no re-centring).

        Parameters
        ----------
        flux_nT : ndarray, shape (n, 3)
            Body-frame fluxgate [nT].
        time_s : ndarray, shape (n,)
            Times [s].
        stretch : ndarray of int, optional
            Continuous-stretch labels (derivatives never cross a change).

        Returns
        -------
        ndarray, shape (n,)
            Interference [nT].
        """
        return predict_interference(flux_nT, time_s, self.terms, self.coef,
                                    stretch=stretch, scale_nT=self.scale_nT)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary (``terms``, ``coef``, ``scale_nT`` and the report)."""
        d = self.meta.to_dict()
        d.update(
            {
                "terms": list(self.terms),
                "coef": [float(c) for c in self.coef],
                "scale_nT": float(self.scale_nT),
            }
        )
        if self.extended is not None:
            d["extended"] = self.extended.to_dict()
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any], *, source: str = "<model>") -> TLModel:
        """Build a model from a dictionary as written by :meth:`to_dict`."""
        try:
            terms = tuple(str(t) for t in d["terms"])
            coef = np.asarray([float(c) for c in d["coef"]], dtype=np.float64)
        except (KeyError, TypeError, ValueError):
            raise InputError(
                f"{source}: not a model file (needs 'terms' and 'coef' lists);"
                " write one with 'aeromag calibrate'"
            ) from None
        unknown = [t for t in terms if t not in ALL_TERMS]
        if unknown:
            raise InputError(f"{source}: unknown term(s) {', '.join(unknown)} in the model")
        if len(coef) != len(terms):
            raise InputError(f"{source}: {len(terms)} terms but {len(coef)} coefficients")
        if not np.all(np.isfinite(coef)):
            raise InputError(f"{source}: the model has non-finite coefficients")
        meta = ModelMeta.from_dict(d)
        ext = None
        if d.get("extended") is not None:
            from .extended import ExtendedModel

            ext = ExtendedModel.from_dict(d["extended"], len(terms), source)
        return cls(terms, coef, float(d.get("scale_nT", FIELD_SCALE_NT)), meta, ext)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> TLModel:
        """Read a model JSON file (as written by ``aeromag calibrate``).

        The file is read with a size limit and validated against the model schema by
        :func:`aeromag.io.model_file.read_model_document` (term names and count, finite
        coefficients, positive ``scale_nT``, bounded nesting).
        """
        from ..io.model_file import read_model_document

        return cls.from_dict(read_model_document(path), source=str(Path(path)))

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the model JSON atomically."""
        from ..io import write_json

        return write_json(self.to_dict(), path)

