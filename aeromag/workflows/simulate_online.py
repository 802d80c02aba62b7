"""``aeromag simulate --online``: the logs of the online estimators with their ground truth.

Files: ``compass.csv`` (the study's calibration manoeuvre, methods.md M3: +-40 deg, 30 s at
50 Hz, interference switched at 15 s; with ``lat``, ``lon``, ``alt`` of Taiyuan so that
``aeromag compass compass.csv --date 2017-07-01`` uses IGRF) and ``compass_truth.json``;
``online_tl.csv`` (a 40-minute survey whose TL coefficients jump at 600 s) and
``online_tl_truth.json``.  Both logs carry truth columns (``truth_*``).
"""

from __future__ import annotations

import os
from pathlib import Path

from ..synthetic.compass import simulate_compass
from ..synthetic.online_tl import simulate_online_tl
from ._sim_files import sim_folder, write_sim_set

__all__ = ["write_online_simulation", "TAIYUAN"]

#: The study's site (Taiyuan): lat [deg], lon [deg], alt [m].
TAIYUAN = (37.87, 112.55, 800.0)


def write_online_simulation(out_dir: str | os.PathLike[str], *, seed: int = 0,
                            small: bool = False) -> dict[str, Path]:
    """Write the compass-calibration and online-TL logs with their truth.

    Parameters
    ----------
    out_dir, seed
        Output folder and random seed, as in
        :func:`aeromag.workflows.mission.write_mission_files`.
    small : bool
        A 10-minute survey instead of 40 minutes.

    Returns
    -------
    dict of str to Path
        ``compass``, ``compass_truth``, ``online_tl``, ``online_tl_truth``.
    """
    out = sim_folder(out_dir)
    comp, comp_truth = simulate_compass(seed=seed)
    comp["lat"], comp["lon"], comp["alt"] = TAIYUAN
    comp_truth["site"] = {"lat": TAIYUAN[0], "lon": TAIYUAN[1], "alt_m": TAIYUAN[2],
                          "date": "2017-07-01"}
    kw = {"duration_s": 600.0, "jump_s": 300.0} if small else {"duration_s": 2400.0}
    tl, tl_truth = simulate_online_tl(seed=seed, **kw)
    return write_sim_set(out, {"compass": ("compass.csv", comp),
                               "compass_truth": ("compass_truth.json", comp_truth),
                               "online_tl": ("online_tl.csv", tl),
                               "online_tl_truth": ("online_tl_truth.json", tl_truth)})
