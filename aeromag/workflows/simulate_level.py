"""``aeromag simulate --survey``: a levelling survey with ties, its base station and truth.

Files: ``level_survey.csv`` (time UTC s since 1970, lat, lon, alt, line, mag and the truth
columns ``truth_anomaly``, ``truth_diurnal``, ``truth_igrf``, ``truth_line_error``),
``level_base.csv`` (time, mag at 1 Hz) and ``level_truth.json`` (lag, line errors, ties,
dipoles).  ``aeromag level level_survey.csv --base level_base.csv --lag auto -o OUT.csv``
processes them.
"""

from __future__ import annotations

import os
from pathlib import Path

from ..synthetic.level_survey import simulate_level_survey
from ._sim_files import sim_folder, write_sim_set

__all__ = ["write_level_simulation"]


def write_level_simulation(out_dir: str | os.PathLike[str], *, seed: int = 0,
                           small: bool = False) -> dict[str, Path]:
    """Write the levelling survey, its base record and its truth.

    Parameters
    ----------
    out_dir : path-like
        Output folder (created).
    seed : int
        Random seed.
    small : bool
        A small block (8 lines of 2 km, 5 ties): the shipped sample.

    Returns
    -------
    dict of str to Path
        ``level_survey``, ``level_base``, ``level_truth``.
    """
    out = sim_folder(out_dir)
    kw = {"n_lines": 8, "line_length_m": 2000.0, "n_ties": 5, "rate_hz": 5.0} if small else {}
    survey, base, truth = simulate_level_survey(seed, **kw)
    # Written to the sensors' resolution: 1e-7 deg (1 cm), 1 mm, 1 pT; the base to 0.01 nT.
    survey = survey.round({"time": 3, "lat": 7, "lon": 7, "alt": 3, "mag": 3,
                           "truth_anomaly": 3, "truth_diurnal": 3, "truth_igrf": 3,
                           "truth_line_error": 3})
    base = base.round({"time": 3, "mag": 2})
    return write_sim_set(out, {"level_survey": ("level_survey.csv", survey),
                               "level_base": ("level_base.csv", base),
                               "level_truth": ("level_truth.json", truth)})
