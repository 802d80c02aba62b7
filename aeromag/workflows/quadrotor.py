"""``aeromag simulate --quadrotor``: the navigation study's flights as canonical logs and truth."""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import InputError
from ..io import atomic_path, write_csv, write_json
from ..synthetic.quadrotor import SCENARIOS, simulate_quadrotor

__all__ = ["write_quadrotor_files"]


def write_quadrotor_files(out_dir: str | os.PathLike[str], *, seed: int = 0,
                          duration_s: float = 60.0) -> dict[str, Path]:
    """Write the quadrotor hover and rectangle flights with their truth.

    Parameters
    ----------
    out_dir : path-like
        Output folder (created when missing).
    seed : int
        Random seed.
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
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a folder; give -o a folder")
    if not duration_s > 1.0:
        raise InputError(f"quadrotor flight duration must exceed 1 s, got {duration_s}")
    flights = {s: simulate_quadrotor(s, duration_s=duration_s, seed=seed) for s in SCENARIOS}
    out.mkdir(parents=True, exist_ok=True)
    paths: dict[str, Path] = {}
    for s in flights:
        paths[f"quadrotor_{s}"] = out / f"quadrotor_{s}.csv"
        paths[f"quadrotor_{s}_truth"] = out / f"quadrotor_{s}_truth.csv"
    paths["quadrotor_truth"] = out / "quadrotor_truth.json"
    with (atomic_path(paths["quadrotor_hover"]) as h, atomic_path(paths["quadrotor_rectangle"])
          as r, atomic_path(paths["quadrotor_hover_truth"]) as ht,
          atomic_path(paths["quadrotor_rectangle_truth"]) as rt,
          atomic_path(paths["quadrotor_truth"]) as tj):
        for (log_p, truth_p), fl in zip(((h, ht), (r, rt)), flights.values(), strict=True):
            write_csv(fl.log, log_p)
            write_csv(fl.truth, truth_p)
        write_json({s: fl.info for s, fl in flights.items()}, tj)
    return paths
