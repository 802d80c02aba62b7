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

from ..errors import InputError
from ..io import atomic_path, write_csv, write_json
from ..synthetic.compass import simulate_compass
from ..synthetic.online_tl import simulate_online_tl

__all__ = ["write_online_simulation", "TAIYUAN"]

#: The study's site (Taiyuan): lat [deg], lon [deg], alt [m].
TAIYUAN = (37.87, 112.55, 800.0)


def write_online_simulation(out_dir: str | os.PathLike[str], *, seed: int = 0,
                            small: bool = False) -> dict[str, Path]:
    """Write the compass-calibration and online-TL logs with their truth.

    Parameters
    ----------
    out_dir : path-like
        Output folder (created when missing).
    seed : int
        Random seed.
    small : bool
        A 10-minute survey instead of 40 minutes.

    Returns
    -------
    dict of str to Path
        ``compass``, ``compass_truth``, ``online_tl``, ``online_tl_truth``.
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a folder; give -o a folder")
    comp, comp_truth = simulate_compass(seed=seed)
    comp["lat"], comp["lon"], comp["alt"] = TAIYUAN
    comp_truth["site"] = {"lat": TAIYUAN[0], "lon": TAIYUAN[1], "alt_m": TAIYUAN[2],
                          "date": "2017-07-01"}
    kw = {"duration_s": 600.0, "jump_s": 300.0} if small else {"duration_s": 2400.0}
    tl, tl_truth = simulate_online_tl(seed=seed, **kw)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"compass": out / "compass.csv", "compass_truth": out / "compass_truth.json",
             "online_tl": out / "online_tl.csv", "online_tl_truth": out / "online_tl_truth.json"}
    with atomic_path(paths["compass"]) as a, atomic_path(paths["compass_truth"]) as b, \
            atomic_path(paths["online_tl"]) as c, atomic_path(paths["online_tl_truth"]) as d:
        write_csv(comp, a)
        write_json(comp_truth, b)
        write_csv(tl, c)
        write_json(tl_truth, d)
    return paths
