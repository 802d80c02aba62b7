"""The result of the manoeuvre detection: :class:`ManeuverResult` and its label names.

One level below its users (:mod:`aeromag.qc.maneuvers` builds it, :mod:`aeromag.qc._lines`,
:mod:`aeromag.qc.fom` and :mod:`aeromag.qc.quality` read it), so that none imports another
for its type.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

__all__ = ["CARDINALS", "LABEL_DTYPES", "MANEUVERS", "ManeuverResult", "complete_boxes"]

#: Cardinal headings in order of ``heading_leg`` (N=0, E=1, S=2, W=3).
CARDINALS: tuple[str, ...] = ("N", "E", "S", "W")
#: Manoeuvre names in customary flight order (also the order of the body rotation axes used:
#: pitch = body y, roll = body x, yaw = body z).
MANEUVERS: tuple[str, ...] = ("pitch", "roll", "yaw")
#: dtypes of the per-sample labels (:attr:`ManeuverResult.labels`): -1 to 3 for the cardinal,
#: run and visit numbers far below 2**31 (a 2e6-row log has ~2,700 legs): 28 bytes a row
#: fewer than int64 (66 -> 28 MB at 2e6 rows).
LABEL_DTYPES: dict[str, Any] = {"heading_leg": np.int8, "leg_id": np.int32, "box": np.int32,
                                "maneuver_id": np.int32}


@dataclass
class ManeuverResult:
    """Heading legs and manoeuvres of a flight.

    Attributes
    ----------
    labels : DataFrame
        One row per input sample (same index): ``heading_leg`` (0-3, -1 outside legs;
        int8), ``leg_id`` (run number, -1; int32), ``box`` (visit number of that heading, -1;
        int32), ``maneuver`` ("pitch"/"roll"/"yaw" or ""; categorical), ``maneuver_id`` (row
        of ``table``, -1; int32) (:data:`LABEL_DTYPES`).
    table : DataFrame
        One row per manoeuvre: ``id``, ``box``, ``heading_leg``, ``heading`` (N/E/S/W),
        ``maneuver``, ``t_start``/``t_end`` [s], ``duration_s`` [s], ``n`` (samples),
        ``rms_deg`` (rms angle of the manoeuvre axis, deg; NaN from a column), ``ambiguous``.
    legs : DataFrame
        One row per heading leg: ``leg_id``, ``box``, ``heading_leg``, ``heading``,
        ``t_start``/``t_end`` [s], ``mean_heading_deg``.
    method : str
        ``"attitude"``, ``"fluxgate"`` or ``"column:<name>"``.
    heading_offset_deg : float
        Common offset of the flown headings from the cardinals [deg].
    notes : list of str
        Anything the user should know (ambiguities, incomplete boxes).
    """

    labels: pd.DataFrame
    table: pd.DataFrame
    legs: pd.DataFrame
    method: str
    heading_offset_deg: float = 0.0
    notes: list[str] = field(default_factory=list)

    @property
    def complete_boxes(self) -> list[int]:
        """Boxes with all 12 (heading, manoeuvre) pairs."""
        return complete_boxes(self.table)


def complete_boxes(table: pd.DataFrame) -> list[int]:
    """Boxes of a manoeuvre table that hold all 12 (heading, manoeuvre) pairs.

    Parameters
    ----------
    table : DataFrame
        ``box``, ``heading_leg`` (0-3) and ``maneuver`` (pitch/roll/yaw) per manoeuvre.

    Returns
    -------
    list of int
        Box numbers, ascending.
    """
    if table.empty:
        return []
    code = pd.Categorical(table["maneuver"], categories=MANEUVERS).codes.astype(np.int64)
    box = table["box"].to_numpy(dtype=np.int64)
    ok = code >= 0
    pair = np.unique(box[ok] * 12 + table["heading_leg"].to_numpy(dtype=np.int64)[ok] * 3
                     + code[ok])
    boxes, count = np.unique(pair // 12, return_counts=True)
    return [int(b) for b in boxes[count == 12]]
