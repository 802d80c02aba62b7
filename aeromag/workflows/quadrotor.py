"""``aeromag simulate --quadrotor``: the navigation study's flights as canonical logs and truth."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..synthetic.quadrotor import SCENARIOS, simulate_quadrotor
from ._sim_files import sim_folder, write_sim_set

__all__ = ["write_quadrotor_files"]


def write_quadrotor_files(out_dir: str | os.PathLike[str], *, seed: int = 0,
                          duration_s: float = 60.0) -> dict[str, Path]:
    """Write the quadrotor hover and rectangle flights with their truth.

    Parameters
    ----------
    out_dir, seed
        Output folder and random seed, as in
        :func:`aeromag.workflows.mission.write_mission_files`.
    duration_s : float
        Length of each flight, s.

    Returns
    -------
    dict of str to Path
        ``quadrotor_hover`` / ``quadrotor_rectangle`` (the multi-rate logs, canonical
        columns), ``..._truth`` (truth at every row: NED from the take-off point, velocity,
        attitude in degrees, geodetic position) and ``quadrotor_truth`` (JSON: site, date,
        Earth field, true sensor biases and error figures of each flight), written as a set.
    """
    out = sim_folder(out_dir)
    if not duration_s > 1.0:
        raise InputError(f"quadrotor flight duration must exceed 1 s, got {duration_s}")
    flights = {s: simulate_quadrotor(s, duration_s=duration_s, seed=seed) for s in SCENARIOS}
    files: dict[str, tuple[str, Any]] = {}
    for s, fl in flights.items():
        files[f"quadrotor_{s}"] = (f"quadrotor_{s}.csv", fl.log)
        files[f"quadrotor_{s}_truth"] = (f"quadrotor_{s}_truth.csv", fl.truth)
    files["quadrotor_truth"] = ("quadrotor_truth.json", {s: fl.info for s, fl in flights.items()})
    paths = write_sim_set(out, files)
    return paths
