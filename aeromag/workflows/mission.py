"""Files of the multirotor mission simulator (``aeromag simulate``'s ``mission*`` files)."""

from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import Any

from ..synthetic.mission import simulate_mission
from ._sim_files import sim_folder, write_sim_set

__all__ = ["write_mission_files"]

log = logging.getLogger(__name__)


#: Decimals written per column: instrument precision (lat/lon 9 ~ 0.1 mm, fields 0.01 nT).
_DECIMALS = {"time": 3, "lat": 9, "lon": 9, "alt": 4, "heading": 4, "pitch": 4, "roll": 4,
             "flux_x": 2, "flux_y": 2, "flux_z": 2,
             "gyro_x": 7, "gyro_y": 7, "gyro_z": 7, "mag_heading": 4, "truth_xtrack_m": 4,
             "truth_heading": 4, "truth_dpsi_deg": 4, "truth_disturbance_nT": 2,
             "truth_mag_heading": 4}


def write_mission_files(out_dir: str | os.PathLike[str], *, seed: int = 0, small: bool = False,
                        **kwargs: Any) -> dict[str, Path]:
    """Simulate a mission and write ``mission.csv``, ``mission_plan.csv``, ``mission_truth.json``.

    Parameters
    ----------
    out_dir : path-like
        Output folder (created when missing).
    seed : int
        Random seed.
    small : bool
        The shipped sample size: 250 m lines instead of 450 m (the disturbances still start
        12 s into their legs and are detected well before the end).
    **kwargs
        Passed to :func:`simulate_mission`.

    Returns
    -------
    dict
        ``{"mission": Path, "plan": Path, "truth": Path}``.
    """
    out = sim_folder(out_dir)
    if small:
        kwargs.setdefault("line_m", 250.0)
    df, plan, truth = simulate_mission(seed=seed, **kwargs)
    df = df.round({c: d for c, d in _DECIMALS.items() if c in df.columns})
    plan = plan.round({"lat": 9, "lon": 9, "alt": 4})
    paths = write_sim_set(out, {"mission": ("mission.csv", df), "plan": ("mission_plan.csv", plan),
                                "truth": ("mission_truth.json", truth)})
    log.info("wrote %s", ", ".join(str(p) for p in paths.values()))
    return paths
