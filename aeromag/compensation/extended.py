"""Compensation beyond the 16 terms: a reference field as the target, extra regressors, a network.

``--reference COL`` fits the interference against ``mag - COL`` over the full band (a reference
holds the low frequencies that a band-passed self-fit cannot see) with an intercept; ``--extra
COL,...`` adds logged channels (aircraft currents, voltages) as regressors beside the TL terms,
band-passed like them in a self-fit, over the full band with a reference.  Both are fitted from
per-segment normal equations (:class:`~aeromag.compensation.normal.SegmentStats`) on standardised
columns, with a regularisation chosen by cross-validation over contiguous blocks of segments
(blocks of time, never shuffled samples: neighbouring samples are correlated, and a shuffled
split would reward over-fitting).  The held-out error of each block is the error of the fit made
without it; the report gives it with and without the extras and the increase when each extra is
left out.  ``--estimator mlp`` adds a small network (scikit-learn's ``MLPRegressor``) that
corrects the linear prediction from the TL terms and the extras (MagNav.jl's "model 2b"), trained
with early stopping on a later block of time and kept only when it lowers the error on the last
block, which it never saw; it is saved as plain arrays (:class:`MLPCorrection`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from ..errors import FitError, InputError
from .network import MLPCorrection, train_mlp
from .normal import SegmentStats
from .report_types import ExtendedSummary, HeldOut

log = logging.getLogger(__name__)

__all__ = ["ExtendedFit", "ExtendedInputs", "ExtendedModel", "MLPCorrection", "cv_linear",
           "extended_inputs", "fold_blocks", "reference_normal_equations", "sub_stats",
           "train_mlp"]

#: Relative ridge parameters tried by the cross-validation (times each column's variance).
RIDGE_GRID = np.r_[1e-12, np.logspace(-9, 1, 21)]
#: Most blocks of the cross-validation.
MAX_FOLDS = 10


@dataclass
class ExtendedInputs:
    """The columns the extended fit reads from a log (:func:`extended_inputs`).

    Attributes
    ----------
    names : tuple of str
        Extras kept (constant or all-NaN ones dropped).
    values : ndarray, shape (e, n)
        Their values (NaN where missing).
    reference : ndarray or None, shape (n,)
        The reference field [nT].
    usable : ndarray of bool, shape (n,)
        Rows with every extra and the reference finite.
    dropped : tuple of str
        Extras dropped (constant or empty), each with a warning.
    """

    names: tuple[str, ...]
    values: np.ndarray
    reference: np.ndarray | None
    usable: np.ndarray
    dropped: tuple[str, ...] = ()


def _numeric(df: pd.DataFrame, col: str, source: str, what: str) -> np.ndarray:
    if pd.api.types.is_float_dtype(df[col].dtype) or pd.api.types.is_integer_dtype(
            df[col].dtype):
        return df[col].to_numpy(dtype=np.float64, na_value=np.nan)
    try:
        return pd.to_numeric(df[col], errors="raise").to_numpy(dtype=np.float64)
    except (ValueError, TypeError):
        raise InputError(f"{source}: column {col} ({what}) is not numeric; give a numeric "
                         "column") from None


def require_columns(df: pd.DataFrame, names: tuple[str, ...], source: str, what: str) -> None:
    """Refuse a log that lacks columns the run needs, naming them all in one line.

    Parameters
    ----------
    df : DataFrame
        The log.
    names : tuple of str
        Columns needed.
    source : str
        File name quoted in the message.
    what : str
        Why they are needed (``"--extra"``, ``"the model's extras"``).

    Raises
    ------
    InputError
        When any is missing.
    """
    missing = [c for c in names if c not in df.columns]
    if missing:
        more = "..." if df.shape[1] > 12 else ""
        raise InputError(f"{source}: no column {', '.join(missing)} ({what}); the log has "
                         f"{', '.join(map(str, df.columns[:12]))}{more}; map one with --col "
                         "NAME=SOURCE")


def extended_inputs(df: pd.DataFrame, extras: tuple[str, ...], reference: str | None,
                    source: str) -> ExtendedInputs:
    """Read the extras and the reference of a fit; drop constant or empty extras with a warning.

    Parameters
    ----------
    df : DataFrame
        The log.
    extras : tuple of str
        Extra regressor columns.
    reference : str or None
        Reference field column [nT].
    source : str
        File name for messages.

    Returns
    -------
    ExtendedInputs

    Raises
    ------
    InputError
        A missing or non-numeric column; a reference with no finite value.
    """
    require_columns(df, extras, source, "--extra")
    if reference is not None:
        require_columns(df, (reference,), source, "--reference")
    kept, vals, dropped = [], [], []
    n = len(df)
    for c in extras:
        v = _numeric(df, c, source, "--extra")
        lo, hi = (np.nanmin(v), np.nanmax(v)) if np.isfinite(v).any() else (np.nan, np.nan)
        if not lo < hi:
            log.warning("%s: --extra %s is %s: dropped from the fit", source, c,
                        "empty (no finite value)" if np.isnan(lo) else "constant")
            dropped.append(c)
            continue
        kept.append(c)
        vals.append(v)
    values = np.empty((len(vals), n))
    usable = np.ones(n, dtype=bool)
    for j, v in enumerate(vals):
        values[j] = v
        usable &= np.isfinite(v)
    del vals
    ref = None
    if reference is not None:
        ref = _numeric(df, reference, source, "--reference")
        if not np.isfinite(ref).any():
            raise InputError(f"{source}: --reference {reference} has no finite value; give a "
                             "column holding the reference field in nT")
        usable &= np.isfinite(ref)
    bad = int(n - usable.sum())
    if bad:
        cols = ", ".join(kept + ([reference] if reference else []))
        log.warning("%s: %d of %d rows have no value in %s: left out of the fit", source, bad,
                    n, cols)
    return ExtendedInputs(tuple(kept), values, ref, usable, tuple(dropped))


def sub_stats(stats: SegmentStats, cols: np.ndarray | list[int]) -> SegmentStats:
    """The normal equations of a subset of the columns (the same segments and target).

    Parameters
    ----------
    stats : SegmentStats
        Per-segment normal equations.
    cols : array of int
        Columns kept, in order.

    Returns
    -------
    SegmentStats
    """
    c = np.asarray(cols, dtype=np.int64)
    return SegmentStats(stats.ids, stats.n, stats.gram[:, c][:, :, c], stats.rhs[:, c],
                        stats.yy, stats.too_short, stats.min_samples)


def reference_normal_equations(design: np.ndarray, target: np.ndarray, segment: np.ndarray,
                               ids: np.ndarray) -> SegmentStats:
    """Per-segment normal equations over the full band (no filter), for the segments ``ids``.

    Parameters
    ----------
    design : ndarray, shape (m, k)
        Regressors of the usable rows (an intercept column first).
    target : ndarray, shape (m,)
        ``mag - reference`` on those rows [nT].
    segment : ndarray of int, shape (m,)
        Their segment ids.
    ids : ndarray of int
        Segments to sum (e.g. those the screening kept), ascending.

    Returns
    -------
    SegmentStats
        One entry per id of ``ids`` that has rows.
    """
    order = np.argsort(segment, kind="stable")
    s = segment[order]
    starts = np.searchsorted(s, ids, side="left")
    stops = np.searchsorted(s, ids, side="right")
    has = stops > starts
    ids, starts, stops = ids[has], starts[has], stops[has]
    k = design.shape[1]
    gram = np.empty((len(ids), k, k))
    rhs = np.empty((len(ids), k))
    yy = np.empty(len(ids))
    for j, (a, b) in enumerate(zip(starts, stops, strict=True)):
        rows = order[a:b]
        A = design[rows]
        y = target[rows]
        gram[j] = A.T @ A
        rhs[j] = A.T @ y
        yy[j] = y @ y
    return SegmentStats(ids, (stops - starts).astype(np.int64), gram, rhs, yy, {}, 0)


def fold_blocks(n_segments: int, n_folds: int = MAX_FOLDS) -> list[np.ndarray]:
    """Contiguous blocks of segments (in time order) for the cross-validation.

    Parameters
    ----------
    n_segments : int
        Segments in the fit.
    n_folds : int
        Most blocks.

    Returns
    -------
    list of ndarray of int
        Segment positions of each block (at least 2 blocks; empty list with one segment).
    """
    k = min(int(n_folds), int(n_segments))
    if k < 2:
        return []
    return [b for b in np.array_split(np.arange(n_segments), k) if len(b)]


def _standardise(G: np.ndarray, b: np.ndarray, n: float, intercept: bool,
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Centred, standardised normal equations (Gs, bs, mean, scale) of the non-intercept columns."""
    if intercept:
        mean = G[0, 1:] / n
        y_mean = b[0] / n
        Gc = G[1:, 1:] - n * np.outer(mean, mean)
        bc = b[1:] - n * mean * y_mean
    else:
        mean = np.zeros(G.shape[0])
        Gc, bc = G, b
    var = np.maximum(np.diag(Gc) / n, 1e-300)
    scale = np.sqrt(var)
    Gs = Gc / np.outer(scale, scale)
    bs = bc / scale
    return Gs, bs, mean, scale


def _pls_coef(Gs: np.ndarray, bs: np.ndarray, n_comp: int) -> np.ndarray:
    """PLS1 coefficients from centred cross products (the kernel algorithm of Dayal & MacGregor)."""
    k = len(bs)
    R = np.zeros((k, n_comp))
    P = np.zeros((k, n_comp))
    q = np.zeros(n_comp)
    xy = bs.copy()
    for a in range(n_comp):
        norm = np.linalg.norm(xy)
        if not norm > 0:
            R, q = R[:, :a], q[:a]
            break
        w = xy / norm
        r = w - R[:, :a] @ (P[:, :a].T @ w)
        tt = float(r @ Gs @ r)
        if not tt > 0:
            R, q = R[:, :a], q[:a]
            break
        p = Gs @ r / tt
        q[a] = float(r @ xy) / tt
        xy = xy - p * q[a] * tt
        R[:, a], P[:, a] = r, p
    return R @ q


def _solve(G: np.ndarray, b: np.ndarray, n: float, intercept: bool, estimator: str,
           param: float) -> np.ndarray:
    """Coefficients of the raw columns for one regularisation ``param``."""
    Gs, bs, mean, scale = _standardise(G, b, n, intercept)
    k = len(bs)
    if estimator == "pls":
        beta_s = _pls_coef(Gs, bs, int(param))
    else:
        try:
            beta_s = np.linalg.solve(Gs + param * n * np.eye(k), bs)
        except np.linalg.LinAlgError:
            beta_s = np.linalg.lstsq(Gs + param * n * np.eye(k), bs, rcond=None)[0]
    beta = beta_s / scale
    if not intercept:
        return beta
    c0 = b[0] / n - mean @ beta
    return np.r_[c0, beta]


@dataclass
class CVResult:
    """A cross-validated linear fit.

    Attributes
    ----------
    coef : ndarray
        Coefficients of the raw columns (intercept first when fitted) on all segments.
    param : float
        Chosen regularisation (relative ridge, or PLS components).
    cv_std_nT : float
        Held-out residual std: each block predicted by the fit without it, pooled [nT].
    grid : list of (float, float)
        (parameter, held-out std) tried.
    """

    coef: np.ndarray
    param: float
    cv_std_nT: float
    grid: list[tuple[float, float]] = field(default_factory=list)


def cv_linear(stats: SegmentStats, *, intercept: bool, estimator: str = "ridge",
              folds: list[np.ndarray] | None = None, param: float | None = None) -> CVResult:
    """Fit by ridge or PLS with the regularisation chosen by blocked cross-validation.

    Parameters
    ----------
    stats : SegmentStats
        Per-segment normal equations, segments in time order (column 0 the intercept when
        ``intercept``).
    intercept : bool
        Column 0 is an unpenalised intercept (a fit against a reference).
    estimator : str
        ``"ridge"`` (the relative ridge of :data:`RIDGE_GRID`, times each column's variance:
        a ridge on standardised columns) or ``"pls"`` (1 to k components).
    folds : list of ndarray, optional
        Blocks of segment positions (default :func:`fold_blocks`).
    param : float, optional
        Use this parameter instead of choosing one (its held-out error is still measured).

    Returns
    -------
    CVResult
    """
    m = len(stats.ids)
    folds = fold_blocks(m) if folds is None else folds
    k = stats.gram.shape[1] - (1 if intercept else 0)
    if param is not None:
        grid = [float(param)]
    elif estimator == "pls":
        grid = [float(a) for a in range(1, k + 1)]
    else:
        grid = [float(a) for a in RIDGE_GRID]
    G = stats.gram.sum(axis=0)
    b = stats.rhs.sum(axis=0)
    n = float(stats.n.sum())
    scores: list[tuple[float, float]] = []
    if folds:
        # Each block's sums once (the blocks are contiguous runs of segments).
        fG = np.stack([stats.gram[f].sum(axis=0) for f in folds])
        fb = np.stack([stats.rhs[f].sum(axis=0) for f in folds])
        fy = np.array([stats.yy[f].sum() for f in folds])
        fn = np.array([float(stats.n[f].sum()) for f in folds])
        n_out = float(fn.sum())
        for p in grid:
            sse = 0.0
            for j in range(len(folds)):
                c = _solve(G - fG[j], b - fb[j], n - fn[j], intercept, estimator, p)
                sse += float(fy[j] - 2 * c @ fb[j] + c @ fG[j] @ c)
            scores.append((p, float(np.sqrt(max(sse, 0.0) / n_out))))
        best, cv = min(scores, key=lambda s: s[1])
    else:  # one segment: no held-out block; the least regularisation, said
        best, cv = grid[0] if estimator == "ridge" else grid[-1], float("nan")
        log.warning("one segment only: the regularisation of the extended fit is not "
                    "cross-validated (%s %g) and no held-out error is measured", estimator, best)
    coef = _solve(G, b, n, intercept, estimator, best)
    if not np.all(np.isfinite(coef)):
        raise FitError("the extended fit gave non-finite coefficients; check the --extra and "
                       "--reference columns")
    return CVResult(coef, best, cv, scores)


# --------------------------------------------------------------------------- the saved model
@dataclass
class ExtendedModel:
    """What a model holds beyond the TL coefficients (saved under ``extended`` in the JSON).

    Attributes
    ----------
    reference : str or None
        Reference column the model was fitted against (None: band-passed self-fit).
    extras : tuple of str
        Extra regressor columns the model needs.
    extra_coef : ndarray
        Their coefficients [nT per unit of the column].
    extra_center, extra_scale : ndarray
        Their calibration mean and std (units of the column); the model adds
        ``extra_coef * (x - extra_center)``.
    intercept_nT : float
        Constant of a fit against a reference [nT] (0 for a self-fit).
    estimator : str
        ``ridge``, ``pls`` or ``mlp``.
    param : float
        The regularisation chosen (relative ridge, or PLS components).
    mlp : MLPCorrection or None
        The network's correction, when kept.
    record : dict
        Held-out figures and choices (the report's ``extended`` block).
    """

    reference: str | None
    extras: tuple[str, ...]
    extra_coef: np.ndarray
    extra_center: np.ndarray
    extra_scale: np.ndarray
    intercept_nT: float = 0.0
    estimator: str = "ridge"
    param: float = 0.0
    mlp: MLPCorrection | None = None
    record: dict[str, Any] = field(default_factory=dict)

    def predict(self, df: pd.DataFrame, tl_design: Any, source: str) -> np.ndarray:
        """The model's part beyond ``A @ coef`` on a log [nT] (NaN where an extra is missing).

        Parameters
        ----------
        df : DataFrame
            The log (one row per sample of the TL prediction).
        tl_design : callable
            Returns the (n, k) TL design matrix (only called for the network).
        source : str
            File name for messages.

        Returns
        -------
        ndarray, shape (n,)
        """
        require_columns(df, self.extras, source, "extras the model was fitted with")
        out = np.full(len(df), self.intercept_nT)
        cols = [_numeric(df, c, source, "an extra of the model") for c in self.extras]
        for x, coef, center in zip(cols, self.extra_coef, self.extra_center, strict=True):
            out += coef * (x - center)
        if self.mlp is not None:
            out += self.mlp.predict(np.column_stack([tl_design(), *cols]))
        return out

    def summary(self) -> ExtendedSummary:
        """The report's ``extended`` block: the fit's record and the model's part.

        Returns
        -------
        ExtendedSummary
            In the order of the record's origin: a fit's record starts with its
            ``reference``; a model file's record (:meth:`from_dict`) holds none, and its
            block writes the reference after the record.
        """
        rec = dict(self.record)
        fitted = next(iter(rec), None) == "reference"
        rec.pop("reference", None)
        known = {k: rec.pop(k) for k in ("rows_left_out", "dropped_extras", "mlp_training",
                                         "n_fit_samples") if k in rec}
        held = HeldOut.from_dict(rec.pop("held_out", None))
        return ExtendedSummary(
            reference=self.reference, **known, held_out=held,
            estimator=self.estimator, param=float(self.param),
            intercept_nT=float(self.intercept_nT),
            extras=[{"name": c, "coef_nT_per_unit": float(v), "center": float(m),
                     "scale": float(s)} for c, v, m, s in
                    zip(self.extras, self.extra_coef, self.extra_center, self.extra_scale,
                        strict=True)],
            mlp=None if self.mlp is None else self.mlp.to_dict(), fitted=fitted, extra=rec)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary (the model file's ``extended``: :meth:`summary`'s block)."""
        return self.summary().to_dict()

    @classmethod
    def from_dict(cls, d: Any, n_terms: int, source: str) -> ExtendedModel:
        """Read and check the ``extended`` block of a model file."""
        bad = f"{source}: the model's 'extended' block is malformed"
        if not isinstance(d, dict):
            raise InputError(f"{bad}; write the model again with 'aeromag calibrate'")
        ref = d.get("reference")
        if ref is not None and not isinstance(ref, str):
            raise InputError(f"{bad} (reference); write the model again with 'aeromag calibrate'")
        ex = d.get("extras", [])
        try:
            names = tuple(str(e["name"]) for e in ex)
            vals = np.array([[float(e["coef_nT_per_unit"]), float(e["center"]),
                              float(e["scale"])] for e in ex]).reshape(-1, 3)
            icpt = float(d.get("intercept_nT", 0.0))
            param = float(d.get("param", 0.0))
        except (KeyError, TypeError, ValueError, OverflowError):
            raise InputError(f"{bad} (extras); write the model again with 'aeromag calibrate'"
                             ) from None
        if not (np.isfinite(vals).all() and np.isfinite(icpt)):
            raise InputError(f"{bad}: non-finite numbers; write the model again")
        est = str(d.get("estimator", "ridge"))
        mlp = d.get("mlp")
        net = None if mlp is None else MLPCorrection.from_dict(mlp, n_terms + len(names), source)
        record = {k: v for k, v in d.items() if k not in (
            "reference", "estimator", "param", "intercept_nT", "extras", "mlp")}
        return cls(ref, names, vals[:, 0], vals[:, 1], vals[:, 2], icpt, est, param, net, record)


@dataclass
class ExtendedFit:
    """The extended fit's result, for the fit report (:func:`aeromag.compensation.fit`).

    Attributes
    ----------
    model : ExtendedModel
        What the model file saves.
    tl_coef : ndarray
        The TL coefficients of the extended fit (the fitted terms).
    """

    model: ExtendedModel
    tl_coef: np.ndarray
