"""The levelling chain on a survey table: lag, diurnal, IGRF, crossings, levelling, micro.

``level_survey`` runs the steps in the usual order (Reeves 2005; Oasis montaj): lag
correction, diurnal correction from a base station, IGRF removal, tie-line levelling and,
on request, micro-levelling; it returns a :class:`LevelResult` (the table with the columns of
``interface.md`` added, and each step's typed result).  Files are read and written by
:mod:`aeromag.workflows.level`.
"""

from __future__ import annotations

import datetime as _dt
import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from .._core.summary import summary_line, summary_table
from ..errors import InputError
from .crossings import Crossings, MistieStd, find_crossings
from .decorrugation import DecorrugationResult, decorrugate
from .diurnal import BaseRecord, DiurnalResult, diurnal_correction
from .geometry import SurveyGeometry, build_geometry
from .igrf import IGRFResult, igrf_total_intensity, parse_date
from .lag import LagEstimate, apply_lag, estimate_lag
from .levelling import METHODS, LevellingResult, level_network, robust_std

log = logging.getLogger(__name__)

__all__ = ["LevelResult", "level_survey", "value_column"]

#: ``time`` below this is seconds since midnight (needs ``--date``), s.
_MIDNIGHT_MAX_S = 2 * 86400.0


@dataclass
class LevelResult:
    """A levelled survey.

    Attributes
    ----------
    data : DataFrame
        The survey with ``x_m``, ``y_m``, ``line_type``, ``igrf``, ``diurnal``, ``tmi``,
        ``tmi_lev`` (and ``tmi_mlev``) added (holding the steps' arrays, e.g.
        ``geometry.x_m``, not copies of them; the input table is never changed).
    value : str
        The column levelled.
    geometry : SurveyGeometry
    lag_s : float
        Lag applied [s].
    lag_estimate : LagEstimate or None
        With ``lag="auto"``.
    igrf : IGRFResult or None
    diurnal : DiurnalResult or None
    crossings : Crossings or None
        Line-tie crossings (in ``tmi``).
    levelling : LevellingResult or None
        None with ``method="none"``.
    decorrugation : DecorrugationResult or None
    warnings : list of str
    """

    data: pd.DataFrame
    value: str
    geometry: SurveyGeometry
    lag_s: float
    lag_estimate: LagEstimate | None
    igrf: IGRFResult | None
    diurnal: DiurnalResult | None
    crossings: Crossings | None
    levelling: LevellingResult | None
    decorrugation: DecorrugationResult | None
    warnings: list[str] = field(default_factory=list)

    @property
    def mistie_std_nT(self) -> MistieStd:
        """Std of the crossings' misties before and after levelling [nT]."""
        return _std_pair(self, np.std)

    @property
    def mistie_robust_std_nT(self) -> MistieStd:
        """Robust std (1.4826 MAD) of the misties before and after levelling [nT]."""
        return _std_pair(self, robust_std)

    def to_report(self) -> dict[str, Any]:
        """The OUT.json content (``interface.md``, section Survey processing)."""
        cx = self.crossings
        lev = self.levelling
        crossovers = []
        if cx is not None:
            after = lev.mistie_lev_nT if lev is not None else cx.mistie_nT
            wt = lev.weight if lev is not None else np.ones(cx.n)
            for i in range(cx.n):
                crossovers.append({
                    "line": _num(cx.line[i]), "tie": _num(cx.tie[i]),
                    "x_m": float(cx.x_m[i]), "y_m": float(cx.y_m[i]),
                    "mistie_nT": float(cx.mistie_nT[i]), "mistie_lev_nT": float(after[i]),
                    "dh_m": _f(cx.dh_m[i]), "gradient_nT_m": float(cx.gradient_nT_m[i]),
                    "weight": float(wt[i])})
        return {
            "value": self.value,
            "crs": self.geometry.crs,
            "lag_s": self.lag_s,
            "lag_estimate": self.lag_estimate.to_dict() if self.lag_estimate else None,
            "igrf": self.igrf.to_dict() if self.igrf else None,
            "diurnal": self.diurnal.to_dict() if self.diurnal else None,
            "ties": {"source": self.geometry.tie_source,
                     "lines": sorted({_num(v) for v in self.geometry.piece_line[
                         self.geometry.piece_is_tie]})},
            "line_spacing_m": _f(self.geometry.line_spacing_m),
            "levelling": ({"method": lev.method, "passes": [p.to_dict() for p in lev.passes],
                           "n_unlevelled_pieces": lev.n_unlevelled,
                           "n_networks": lev.n_networks,
                           "n_parameters_effective": _f(lev.n_parameters_effective),
                           "dof": _f(lev.dof),
                           "n_rejected": lev.passes[-1].n_rejected if lev.passes else 0}
                          if lev is not None else {"method": "none"}),
            "decorrugation": self.decorrugation.to_dict() if self.decorrugation else None,
            "n_crossovers": 0 if cx is None else cx.n,
            "mistie_std_nT": self.mistie_std_nT.to_dict(),
            "mistie_robust_std_nT": self.mistie_robust_std_nT.to_dict(),
            "crossovers": crossovers,
            "lines": self._lines(),
        }

    def summary_rows(self) -> list[tuple[str, str]]:
        """(label, value) pairs of the short description (``repr`` and notebooks)."""
        g = self.geometry
        n_ties = len({float(v) for v in g.piece_line[g.piece_is_tie]})
        n_lines = len({float(v) for v in g.piece_line}) - n_ties
        rows = [("samples", str(len(self.data))), ("lines / ties", f"{n_lines} / {n_ties}"),
                ("value", self.value), ("crs", f"EPSG:{g.crs}")]
        est = self.lag_estimate
        rows.append(("lag_s", f"{self.lag_s:.3f}" + (f" +- {est.std_s:.3f} (auto)" if est
                                                      else "")))
        rows.append(("igrf", self.igrf.model if self.igrf is not None else "not removed"))
        rows.append(("diurnal", f"datum {self.diurnal.datum_nT:.1f} nT"
                     if self.diurnal is not None else "not removed"))
        ms, mr = self.mistie_std_nT, self.mistie_robust_std_nT
        if self.crossings is not None:
            rows.append(("crossings", str(self.crossings.n)))
        if ms.before is not None:
            rows.append(("mistie_std_nT", f"{ms.before:.3g} -> {ms.after:.3g}"))
            rows.append(("mistie_robust_std_nT", f"{mr.before:.3g} -> {mr.after:.3g}"))
        lev = self.levelling
        rows.append(("levelling", "none" if lev is None else
                     f"{lev.method}, {lev.n_parameters_effective:.1f} effective parameters, "
                     f"{lev.dof:.1f} dof"))
        if self.decorrugation is not None:
            rows.append(("decorrugation", f"bound {self.decorrugation.limit_nT:.3g} nT"))
        rows += [("warning", w) for w in self.warnings]
        return rows

    def __repr__(self) -> str:
        """One line: the summary's rows, warnings counted."""
        return summary_line(type(self).__name__, self.summary_rows())

    def _repr_html_(self) -> str:
        """A small HTML table of the same summary (Jupyter)."""
        return summary_table(type(self).__name__, self.summary_rows())

    def _lines(self) -> list[dict[str, Any]]:
        g = self.geometry
        lev, dec = self.levelling, self.decorrugation
        out: list[dict[str, Any]] = []
        corr = self.data["tmi_lev"].to_numpy() - self.data["tmi"].to_numpy()
        on = g.piece >= 0
        num_of = pd.Series(g.piece_line[g.piece[on]])
        c_on = pd.Series(corr[on])
        n_all = num_of.value_counts()
        stats = c_on.groupby(num_of.to_numpy()).agg(["mean", "std", "count"])
        for num in np.unique(g.piece_line):
            ks = np.flatnonzero(g.piece_line == num)
            st = stats.loc[num] if num in stats.index else None
            ok = st is not None and st["count"] > 0
            row: dict[str, Any] = {
                "line": _num(num), "type": "tie" if g.piece_is_tie[ks[0]] else "line",
                "n": int(n_all.get(num, 0)), "n_pieces": int(ks.size),
                "correction_mean_nT": float(st["mean"]) if ok else None,
                "correction_std_nT": float(np.nan_to_num(st["std"] * np.sqrt(
                    (st["count"] - 1) / st["count"]))) if ok else None,
            }
            if lev is not None:
                row["pieces"] = [{"knots_m": lev.knots_m[k].tolist(),
                                  "correction_nT": lev.values_nT[k].tolist()} for k in ks]
            if dec is not None:
                row["mlev_std_removed_nT"] = dec.std_removed_nT.get(float(num))
                row["mlev_scale"] = dec.scale.get(float(num))
            out.append(row)
        return out


def _num(v: float) -> int | float:
    v = float(v)
    return int(v) if v.is_integer() else v


def _f(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None


def _std_pair(res: LevelResult, fn: Callable[[np.ndarray], float]) -> MistieStd:
    cx = res.crossings
    if cx is None or cx.n == 0:
        return MistieStd()
    after = res.levelling.mistie_lev_nT if res.levelling is not None else cx.mistie_nT
    return MistieStd(before=float(fn(cx.mistie_nT)), after=float(fn(after)))


def _text_column(codes: np.ndarray, names: Sequence[str], index: pd.Index) -> pd.Series:
    """``names[codes]`` as the text column pandas makes of Python strings, without them.

    pandas turns an object array of 1e7 strings into its Arrow-backed ``str`` in 1.6 s and
    900 MB; taking from the three names in Arrow is 0.1 s and the column's own size.
    """
    obj = np.array(list(names), dtype=object)
    dtype = pd.Series(obj).dtype  # what pandas makes of strings (``str`` on pandas 3)
    if isinstance(dtype, pd.StringDtype) and dtype.storage == "pyarrow":
        import pyarrow as pa

        taken = pa.array(list(names), pa.large_string()).take(pa.array(codes))
        return pd.Series(pd.array(taken, dtype=dtype), index=index, copy=False)
    return pd.Series(obj[codes], index=index)


def _add(df: pd.DataFrame, name: str, values: np.ndarray) -> None:
    """A new column holding ``values`` itself (``df[name] = array`` would copy it)."""
    df[name] = pd.Series(values, index=df.index, copy=False)


def value_column(df: pd.DataFrame, value: str | None, source: str) -> str:
    """The column to level: ``value``, else ``mag_comp``, else ``mag``.

    Parameters
    ----------
    df : DataFrame
        The survey.
    value : str or None
        Asked column.
    source : str
        Name for messages.

    Returns
    -------
    str
    """
    if value is not None:
        if value not in df.columns:
            raise InputError(f"{source}: --value {value}: no such column")
        return value
    for c in ("mag_comp", "mag"):
        if c in df.columns:
            return c
    raise InputError(f"{source}: no mag_comp or mag column to level; name the total-field "
                     "column with --value COL")


def _times(df: pd.DataFrame, date: str | None, source: str) -> np.ndarray | None:
    d = parse_date(date) if date is not None else None
    if "time" not in df.columns:
        return None
    t = df["time"].to_numpy(dtype=np.float64)
    fin = t[np.isfinite(t)]
    if fin.size == 0:
        return None
    if fin.max() < _MIDNIGHT_MAX_S:
        if d is None:
            raise InputError(f"{source}: column time looks like seconds since midnight "
                             f"(max {fin.max():.0f} s); give the UTC date with --date "
                             "YYYY-MM-DD")
        epoch = (_dt.datetime(d.year, d.month, d.day) - _dt.datetime(1970, 1, 1)).total_seconds()
        return t + epoch
    if d is not None:
        day = _dt.datetime.fromtimestamp(float(fin[0]), _dt.UTC).date()
        if abs((day - d).days) > 1:
            raise InputError(f"{source}: --date {d} disagrees with the log's own time "
                             f"({day}); drop --date (time is UTC seconds since 1970)")
    return t


def _lag_value(lag: float | str) -> float | str:
    if isinstance(lag, str):
        if lag.strip().lower() == "auto":
            return "auto"
        try:
            return float(lag)
        except ValueError:
            raise InputError(f"--lag {lag}: give seconds (e.g. --lag 0.4) or auto") from None
    return float(lag)


def level_survey(df: pd.DataFrame, *, value: str | None = None, base: BaseRecord | None = None,
                 date: str | None = None, lag: float | str = 0.0, igrf: bool = True,
                 ties: str | Sequence[float] = "auto", method: str = "trend",
                 decorrugate_lines: bool = False, crs: int | None = None,
                 base_datum_nT: float | None = None, allow_base_gaps: bool = False,
                 decorrugation_limit_nT: float | None = None,
                 progress: Callable[[int, int, str], None] | None = None,
                 source: str | None = None) -> LevelResult:
    """Level a survey: lag, diurnal, IGRF, tie-line levelling, micro-levelling.

    Parameters
    ----------
    df : DataFrame
        The survey: ``lat``, ``lon`` [deg], ``alt`` [m, for the IGRF], ``line``, a total
        field [nT] and ``time`` [UTC s since 1970, or since midnight with ``date``].
    value : str, optional
        Column to level (default ``mag_comp``, else ``mag``).
    base : BaseRecord, optional
        Base-station record (none: no diurnal correction, with a warning).
    date : str, optional
        ``YYYY-MM-DD``: the UTC date of a ``time`` in seconds since midnight.
    lag : float or "auto"
        Magnetometer lag [s].
    igrf : bool
        Remove the IGRF (False: the value is already an anomaly).
    ties : "auto" or sequence of float
        Tie lines: ``auto`` (a ``line_type`` column, else the direction rule) or numbers.
    method : {"none", "shift", "trend", "smooth"}
        Levelling method.
    decorrugate_lines : bool
        Also micro-level (``tmi_mlev``).
    crs : int, optional
        EPSG code of the projection (default: UTM zone of the centre).
    base_datum_nT : float, optional
        Base datum [nT] (default: the base's mean over the survey).
    allow_base_gaps : bool
        Samples outside the base's coverage get an empty diurnal (else an error).
    decorrugation_limit_nT : float, optional
        Bound of the micro-levelling correction [nT] (default 3 x the robust mistie std
        after levelling, at least 0.1 nT).
    progress : callable, optional
        ``progress(done, total, step)``.
    source : str, optional
        Name for messages.

    Returns
    -------
    LevelResult
    """
    src = source or str(df.attrs.get("source", "<survey>"))
    warnings: list[str] = []
    steps = 6
    report = progress or (lambda done, total, step: None)
    if method not in METHODS:
        raise InputError(f"--level {method}: use one of {', '.join(METHODS)}")
    if "line" not in df.columns:
        raise InputError(f"{src}: no line column; the levelling needs the flight-line number "
                         "of each sample (map it with --col line=NAME)")
    col = value_column(df, value, src)
    lag_v = _lag_value(lag)
    t = _times(df, date, src)
    report(0, steps, "geometry")
    line_type = df["line_type"].to_numpy() if "line_type" in df.columns and ties == "auto" \
        else None
    tie_list = None if isinstance(ties, str) else list(ties)
    if isinstance(ties, str) and ties != "auto":
        raise InputError(f"--ties {ties}: give auto or tie-line numbers ID,ID,...")
    for c in ("lat", "lon"):
        if c not in df.columns:
            raise InputError(f"{src}: missing column {c} (the sample positions)")
    geom = build_geometry(df["lat"].to_numpy(float), df["lon"].to_numpy(float),
                          df["line"].to_numpy(float), crs=crs, line_type=line_type,
                          ties=tie_list, source=src)
    v = df[col].to_numpy(dtype=np.float64)
    if not np.isfinite(v).any():
        raise InputError(f"{src}: column {col} holds no number")
    report(1, steps, "diurnal")
    dres = None
    diurnal = np.zeros(v.size)
    if base is not None:
        if t is None:
            raise InputError(f"{src}: --base needs a time column (UTC) to match the base "
                             "record; drop --base for a log without time")
        dres = diurnal_correction(t, base, datum_nT=base_datum_nT,
                                  allow_uncovered=allow_base_gaps)
        diurnal = dres.diurnal_nT
        warnings += dres.warnings
    else:
        msg = f"{src}: no base station (--base): no diurnal correction"
        if t is None:
            msg += " (the log has no time)"
        log.warning(msg)
        warnings.append(msg)
    report(2, steps, "IGRF")
    ires = None
    igrf_v = np.zeros(v.size)
    if igrf:
        if "alt" not in df.columns:
            raise InputError(f"{src}: no alt column (height above the ellipsoid, m) for the "
                             "IGRF; map it with --col alt=NAME, or --no-igrf when the value "
                             "is already an anomaly")
        if t is None and date is None:
            msg = (f"{src}: the log has no time and no --date: no IGRF removed (give --date, "
                   "or --no-igrf when the value is already an anomaly)")
            log.warning(msg)
            warnings.append(msg)
        else:
            when: np.ndarray | float
            if t is not None:
                when = t
            else:
                d = parse_date(date)
                when = (_dt.datetime(d.year, d.month, d.day, 12)
                        - _dt.datetime(1970, 1, 1)).total_seconds()
            ires = igrf_total_intensity(df["lat"].to_numpy(float), df["lon"].to_numpy(float),
                                        df["alt"].to_numpy(float), when)
            igrf_v = ires.igrf_nT
    report(3, steps, "lag")
    lag_est = None
    vd = v - diurnal
    if lag_v == "auto":
        if t is None:
            raise InputError(f"{src}: --lag auto needs a time column")
        lag_est = estimate_lag(geom, t, vd - igrf_v, source=src)
        lag_s = lag_est.lag_s
        log.info("%s: lag %.3f +- %.3f s from %d line pairs", src, lag_s, lag_est.std_s,
                 lag_est.n_pairs)
    else:
        lag_s = float(lag_v)
    if lag_s != 0:
        if t is None:
            raise InputError(f"{src}: --lag {lag_s:g} needs a time column")
        vd = apply_lag(t, vd, geom.piece, lag_s)
    vd -= igrf_v  # in place: vd is this function's own array (v - diurnal, or lagged)
    tmi = vd
    del vd
    # The table shares the input's columns (copy on write: the caller's frame is never
    # changed) and the new columns' arrays (no second copy of each).
    out = df.copy(deep=False)
    _add(out, "x_m", geom.x_m)
    _add(out, "y_m", geom.y_m)
    codes = np.zeros(v.size, dtype=np.int8)  # "", "line", "tie"
    on = geom.piece >= 0
    codes[on] = np.where(geom.is_tie[on], 2, 1)
    out["line_type"] = _text_column(codes, ("", "line", "tie"), out.index)
    del codes
    _add(out, "igrf", igrf_v if ires is not None else np.full(v.size, np.nan))
    _add(out, "diurnal", diurnal if dres is not None else np.full(v.size, np.nan))
    _add(out, "tmi", tmi)
    report(4, steps, "crossings")
    h = df["alt"].to_numpy(float) if "alt" in df.columns else None
    cx = None
    lres = None
    if method != "none" or decorrugate_lines:
        if not geom.piece_is_tie.any():
            raise InputError(f"{src}: the survey has no tie lines (ties {geom.tie_source}): it "
                             "cannot be tie-line levelled; give them (--ties ID,... or a "
                             "line_type column), or skip the levelling with --level none")
        cx = find_crossings(geom, tmi, h)
    report(5, steps, "levelling")
    if method != "none":
        counts = np.bincount(geom.piece[geom.piece >= 0], minlength=geom.n_pieces)
        lres = level_network(cx, geom.n_pieces, geom.piece_is_tie, method=method,
                             piece_samples=counts, source=src)
        lev = lres.correction(geom.piece, geom.along_m)
        lev += tmi  # tmi + correction, without a third array
        _add(out, "tmi_lev", lev)
        n_used = lres.dof + lres.n_parameters_effective
        if np.isfinite(lres.dof) and lres.dof < max(5.0, 0.25 * n_used):
            msg = (f"{src}: levelling fits {lres.n_parameters_effective:.1f} effective "
                   f"parameters to {n_used:.0f} crossings ({lres.dof:.1f} degrees of "
                   "freedom): the levelled misties show the fit, not the level error left; "
                   "fly more tie lines, or level with fewer parameters (--level shift)")
            log.warning(msg)
            warnings.append(msg)
    else:
        out["tmi_lev"] = tmi
    dec = None
    if decorrugate_lines:
        after = lres.mistie_lev_nT if lres is not None else cx.mistie_nT
        if decorrugation_limit_nT is None:
            decorrugation_limit_nT = max(3.0 * robust_std(after), 0.1)
        # the crossing check: the levelled misties, weighted as the levelling's last pass did
        dec = decorrugate(geom, out["tmi_lev"].to_numpy(), limit_nT=decorrugation_limit_nT,
                          crossings=cx, mistie_nT=after,
                          crossing_weight=lres.weight if lres is not None else None)
        _add(out, "tmi_mlev", out["tmi_lev"].to_numpy() - dec.correction_nT)
    report(6, steps, "done")
    return LevelResult(out, col, geom, lag_s, lag_est, ires, dres, cx, lres, dec, warnings)
