"""Manoeuvre windows clipped at survey-line boundaries (a manoeuvre never spans two lines)."""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

if TYPE_CHECKING:
    from .maneuver_result import ManeuverResult

log = logging.getLogger(__name__)


def clip_to_lines(res: ManeuverResult, line: pd.Series | np.ndarray,
                  t: np.ndarray, fs: float) -> ManeuverResult:
    """Clip every manoeuvre to the longest part of it that lies on one line.

    A detected window can run a second or two into the neighbouring line (the energy windows
    and the block-rate detection blur its edges); that line may be a dropped segment (a
    fault), whose samples would then enter the manoeuvre's peak-to-peak.  The samples of a
    manoeuvre outside its longest single-line part lose their manoeuvre label.

    Parameters
    ----------
    res : ManeuverResult
        Detected manoeuvres (modified copy returned; ``res`` itself is not changed).
    line : Series or ndarray, shape (n,)
        Line of each sample (any values; missing values form no line of their own).
    t : ndarray, shape (n,)
        Times [s].
    fs : float
        Sampling rate [Hz].

    Returns
    -------
    ManeuverResult
        With ``labels`` ``maneuver``/``maneuver_id`` and ``table`` ``t_start``, ``t_end``,
        ``n``, ``duration_s`` clipped.
    """
    mid = res.labels["maneuver_id"].to_numpy()
    n = len(mid)
    if n == 0:
        return res
    # Pieces: maximal runs of one (manoeuvre, line), missing lines forming runs of their own,
    # in one vectorised pass (a Python loop over 840 crossing manoeuvres cost 0.02 s per 1e6
    # rows).
    brk = np.empty(n, dtype=bool)
    brk[0] = True
    np.not_equal(mid[1:], mid[:-1], out=brk[1:])
    brk[1:] |= _line_changes(line)
    p0 = np.flatnonzero(brk)
    p1 = np.r_[p0[1:], n]
    pm = mid[p0]
    inm = pm >= 0
    p0, p1, pm = p0[inm], p1[inm], pm[inm]
    # The manoeuvre run of each piece (a new run where the id changes or a gap precedes it).
    new_run = np.r_[True, (pm[1:] != pm[:-1]) | (p0[1:] != p1[:-1])]
    run = np.cumsum(new_run) - 1
    n_pieces = np.bincount(run)
    multi = n_pieces[run] > 1
    if not multi.any():
        return res
    p0, p1, pm, run = p0[multi], p1[multi], pm[multi], run[multi]
    # The longest piece of each crossing run, the first of equals (as argmax).
    order = np.lexsort((p0, -(p1 - p0), run))
    _, first = np.unique(run[order], return_index=True)
    best = order[first]
    ks, ke, span_ids = p0[best], p1[best], pm[best]
    lose = np.ones(len(p0), dtype=bool)
    lose[best] = False
    # Copy-on-write (pandas 3) or not, the new columns below replace the old ones in this
    # shallow copy only: no deep copy of the five label columns (40 MB at 1e6 rows).
    labels = res.labels.copy(deep=False)
    table = res.table.copy()
    # The pieces are disjoint: the running sum of +1/-1 marks is 0 or 1, an int8 (two int64
    # temporaries of 16 MB at 2e6 rows fewer); the labels keep their own dtypes.
    mark = np.zeros(n + 1, dtype=np.int8)
    np.add.at(mark, p0[lose], 1)
    np.add.at(mark, p1[lose], -1)
    clear = np.cumsum(mark[:-1], dtype=np.int8).view(bool)
    del mark
    new_mid = mid.copy()
    new_mid[clear] = -1
    man = np.array(labels["maneuver"].cat.codes)
    man[clear] = 0
    del clear
    n_clipped = int((p1[lose] - p0[lose]).sum())
    # Table edits through numpy, written back once (a .loc assignment per manoeuvre cost 2 s
    # on a 1e6-row log with 2,500 manoeuvres).
    tid = table["id"].to_numpy()
    srt = np.argsort(tid, kind="stable")
    r = srt[np.searchsorted(tid[srt], span_ids)]
    t_start = table["t_start"].to_numpy(dtype=float, copy=True)
    t_end = table["t_end"].to_numpy(dtype=float, copy=True)
    t_start[r], t_end[r] = t[ks], t[ke - 1]
    n_rows = None
    if "n" in table.columns:
        n_rows = table["n"].to_numpy(copy=True)
        n_rows[r] = ke - ks
    table["t_start"], table["t_end"] = t_start, t_end
    if n_rows is not None:
        table["n"] = n_rows
    if "duration_s" in table.columns:
        table["duration_s"] = t_end - t_start + 1.0 / fs
    log.info("%d manoeuvre(s) clipped to one line (%d samples on another line relabelled)",
             len(span_ids), n_clipped)
    labels["maneuver_id"] = new_mid
    labels["maneuver"] = pd.Categorical.from_codes(man, categories=labels["maneuver"].cat
                                                   .categories)
    return type(res)(labels, table, res.legs, res.method, res.heading_offset_deg,
                     list(res.notes))


def _line_changes(line: pd.Series | np.ndarray) -> np.ndarray:
    """``line[i + 1]`` differs from ``line[i]``, missing values equal to each other, shape (n-1,).

    A numeric column is compared directly (no hashing of 1e6 values); anything else through
    :func:`pandas.factorize` (None, NaN and NaT all missing).
    """
    v = np.asarray(line)
    if v.dtype.kind in "biu":
        return v[1:] != v[:-1]
    if v.dtype.kind == "f":
        nan = np.isnan(v)
        return (v[1:] != v[:-1]) & ~(nan[1:] & nan[:-1])
    codes = pd.factorize(pd.Series(v), use_na_sentinel=True)[0]
    return codes[1:] != codes[:-1]
