"""One verdict from any number of detectors (track deviation, heading, particle filter, ...)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from ..errors import InputError
from .alarms import Alarms

__all__ = ["COMBINE_RULES", "alarm_mask", "combine_alarms"]

#: Accepted combination rules.
COMBINE_RULES = ("or", "and")


def alarm_mask(alarm: Alarms | np.ndarray) -> np.ndarray:
    """The per-sample alarm of a detector result or of a boolean array.

    Parameters
    ----------
    alarm : Alarms or ndarray of bool

    Returns
    -------
    ndarray of bool
    """
    return np.asarray(alarm.alarm if isinstance(alarm, Alarms) else alarm, dtype=bool)


def combine_alarms(
    alarms: Sequence[Alarms | np.ndarray | None],
    groups: np.ndarray,
    how: str = "or",
) -> np.ndarray:
    """Combine the alarms of any number of detectors into one verdict.

    ``or``: a sample alarms when any detector alarms.  ``and`` (confirmation): a sample alarms
    when any detector alarms *and* every detector has already alarmed in the same group (leg
    pass) at or before that sample (detectors rarely fire at the same instant, so a sample-wise
    AND would almost never alarm).  With one detector both rules give its alarm.  Samples whose
    group is negative (on no leg) never alarm.

    Parameters
    ----------
    alarms : sequence of Alarms, ndarray of bool or None
        One entry per detector, all of the log's length; ``None`` (a detector that could not
        run) is left out.
    groups : ndarray of int, shape (n,)
        Group of each sample (leg or leg pass; -1 for none).
    how : {"or", "and"}
        Combination rule.

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    how = str(how).lower()
    if how not in COMBINE_RULES:
        raise InputError(f"how={how!r}: use 'or' or 'and'")
    g = np.asarray(groups)
    on = g >= 0
    masks = [alarm_mask(a) for a in alarms if a is not None]
    if not masks:
        return np.zeros(len(g), dtype=bool)
    either = np.logical_or.reduce(masks) & on
    if how == "or" or len(masks) == 1:
        return either
    # Latch each detector from its first alarm in the group: cumulative max within groups.
    gs = pd.Series(g)
    seen = [pd.Series(m).groupby(gs).cummax().to_numpy(dtype=bool) for m in masks]
    return either & np.logical_and.reduce(seen)
