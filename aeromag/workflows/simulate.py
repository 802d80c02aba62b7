"""``aeromag simulate``: write the synthetic flights, their plan and ground truth."""


import logging
import os
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..io import write_csv, write_json
from ..synthetic.calibration import simulate_calibration
from ..synthetic.currents import add_current_interference
from ..synthetic.faults import check_positive
from ..synthetic.survey import round_log, simulate_survey, survey_plan

log = logging.getLogger(__name__)


def write_simulation(
    out_dir: str | os.PathLike[str],
    *,
    seed: int = 0,
    faults: float | None = 0.0,
    rate_hz: float = 10.0,
    small: bool = False,
    currents: int = 0,
) -> dict[str, Path]:
    """Write a calibration flight, a survey, its plan and the ground truth.

    Parameters
    ----------
    out_dir : path-like
        Output folder (created when missing).
    seed : int
        Random seed.
    faults : float or None
        Fraction of segments (of each flight) carrying a fault, in [0, 1].
    rate_hz : float
        Sample rate [Hz].
    small : bool
        The shipped sample size: one calibration box of 20 s maneuvers (12 segments) and
        ten 160 m survey lines (enough segments for PCA screening); otherwise two boxes of
        25 s and eight 400 m lines.
    currents : int
        Current loops on the aircraft (:func:`aeromag.synthetic.add_current_interference`):
        both flights get their field in ``mag`` and log ``cur_1``... and ``volt_bus``; the same
        loops (field vectors) on both, other currents; 0: none.

    Returns
    -------
    dict of str to Path
        ``{"calibration": ..., "survey": ..., "plan": ..., "truth": ...}``: ``calibration.csv``,
        ``survey.csv``, ``plan.csv`` (survey waypoints) and ``truth.json``
        (``{"calibration": {...}, "survey": {...}}``), each written atomically.
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a folder; give -o a folder")
    check_positive(rate_hz=rate_hz)
    cal_kw: dict[str, Any] = {"n_boxes": 1, "maneuver_s": 20.0} if small else {}
    sur_kw: dict[str, Any] = {"n_lines": 10, "line_length_m": 160.0} if small else {}
    cal, cal_truth = simulate_calibration(seed=seed, rate_hz=rate_hz, faults=faults, **cal_kw)
    sur, sur_truth = simulate_survey(seed=seed, rate_hz=rate_hz, faults=faults, **sur_kw)
    if currents:
        cal, cal_truth = add_current_interference(cal, cal_truth, seed=seed, n_loops=currents)
        vectors = [loop["field_nT_per_A"] for loop in cal_truth["current_loops"]]
        sur, sur_truth = add_current_interference(sur, sur_truth, seed=seed + 1,
                                                  n_loops=currents, field_nT_per_A=vectors)
    plan = survey_plan(sur_truth).round({"lat": 9, "lon": 9, "alt": 3})
    out.mkdir(parents=True, exist_ok=True)
    paths = {
        "calibration": write_csv(round_log(cal), out / "calibration.csv"),
        "survey": write_csv(round_log(sur), out / "survey.csv"),
        "plan": write_csv(plan, out / "plan.csv"),
        "truth": write_json({"calibration": cal_truth, "survey": sur_truth}, out / "truth.json"),
    }
    log.info("wrote %s", ", ".join(str(p) for p in paths.values()))
    return paths

