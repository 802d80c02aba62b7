"""Speed and memory of ``aeromag grid`` on the full Osborne survey, and the solve's growth.

Run by hand: ``python benchmarks/bench_grid.py [--cells 100,70,50] [--holdout]``.  Each cell
size runs ``aeromag grid`` (the command, as a user runs it: read the 990,987-sample
``.csv.xz``, project, block-median, solve, blank, write GRID.nc and GRID.json) in a fresh
process; the process's own timings and its peak resident memory (``ru_maxrss``) are printed,
with the cells and the conjugate-gradient iterations of the finest level.  ``--holdout`` also
grids the survey with every tenth east-west line held out and predicts those lines (rms
against the data) by minimum curvature and by SciPy's cubic interpolation of the same
block-median data.

Data: Geoscience Australia, Osborne magnetic survey (P1029), via Fatiando a Terra (CC-BY 4.0),
``../shared/data/real/survey/osborne-magnetic.csv.xz``.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

OSBORNE = (Path(__file__).resolve().parents[2] / "shared" / "data" / "real" / "survey"
           / "osborne-magnetic.csv.xz")
COLS = ["--col", "lat=latitude", "--col", "lon=longitude", "--col", "line=flight_line",
        "--col", "tmi=total_field_anomaly_nt"]
TIES = {5816, 5817, 5818, 5819, *range(10149, 10167)}


def _child(cell: float) -> None:
    """One ``aeromag grid`` run in this process; prints a JSON line."""
    t0 = time.perf_counter()
    from typer.testing import CliRunner

    from aeromag.cli import app

    t1 = time.perf_counter()
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "osborne.nc"
        r = CliRunner().invoke(app, ["grid", str(OSBORNE), "-o", str(out), "--cell",
                                     str(cell), *COLS])
        t2 = time.perf_counter()
        if r.exit_code != 0:
            raise SystemExit(r.output)
        doc = json.loads(out.with_suffix(".json").read_text())
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(json.dumps({"cell_m": cell, "import_s": t1 - t0, "grid_s": t2 - t1, "rss_mib": rss,
                      "cells": doc["shape"][0] * doc["shape"][1],
                      "iterations": doc["iterations"], "levels": doc["levels"]}))


def _holdout(cell: float) -> None:
    """Every tenth east-west line held out: minimum curvature against cubic interpolation."""
    import pandas as pd
    import verde as vd
    from scipy.interpolate import RegularGridInterpolator, griddata

    from aeromag._core.geodesy import project
    from aeromag.survey.gridding import default_cell, estimate_line_spacing, minimum_curvature

    df = pd.read_csv(OSBORNE)
    x, y = project(df.latitude.to_numpy(), df.longitude.to_numpy(), 32754)
    v = df.total_field_anomaly_nt.to_numpy(float)
    line = df.flight_line.to_numpy()
    lines = np.array(sorted(set(np.unique(line)) - TIES))
    test = np.isin(line, lines[5::10])
    t0 = time.perf_counter()
    # the tension acts at the default cell, as `aeromag grid` does (tension_length_m)
    length = default_cell(estimate_line_spacing(x[~test], y[~test], line[~test]))
    xg, yg, g, s = minimum_curvature(x[~test], y[~test], v[~test], cell_m=cell,
                                     tension_length_m=length)
    t1 = time.perf_counter()
    p_mc = RegularGridInterpolator((yg, xg), g)(np.column_stack([y[test], x[test]]))
    (bx, by), bv = vd.BlockReduce("median", spacing=cell).filter((x[~test], y[~test]),
                                                                 v[~test])
    t2 = time.perf_counter()
    p_cu = griddata((bx, by), bv, (x[test], y[test]), method="cubic")
    t3 = time.perf_counter()
    ok = np.isfinite(p_cu) & np.isfinite(p_mc)
    for name, p, dt in (("minimum curvature T=0.25", p_mc, t1 - t0),
                        ("scipy cubic (block medians)", p_cu, t3 - t2)):
        rms = float(np.sqrt(np.mean((p[ok] - v[test][ok]) ** 2)))
        print(f"  held-out {name:28s} rms {rms:6.1f} nT  ({dt:5.1f} s)")
    print(f"  {int(ok.sum()):,} held-out samples on {len(lines[5::10])} lines,"
          f" std {float(v[test][ok].std()):.0f} nT")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--cells", default="100,70,50", help="cell sizes, metres")
    ap.add_argument("--holdout", action="store_true", help="also the held-out-line check")
    ap.add_argument("--child", type=float, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if not OSBORNE.is_file():
        raise SystemExit(f"{OSBORNE} is absent (../shared/data/real)")
    if args.child:
        _child(args.child)
        return
    print("aeromag grid on the Osborne survey (990,987 samples), one process per cell size")
    rows = []
    for cell in (float(c) for c in args.cells.split(",")):
        r = subprocess.run([sys.executable, __file__, "--child", str(cell)],
                           capture_output=True, text=True, check=True)
        d = json.loads(r.stdout.strip().splitlines()[-1])
        rows.append(d)
        fine = d["levels"][-1]
        print(f"  {cell:5.0f} m  {d['cells']:9,d} cells  grid {d['grid_s']:5.1f} s"
              f" (+{d['import_s']:.1f} s imports)  peak {d['rss_mib']:6.0f} MiB"
              f"  solve {sum(lv['seconds'] for lv in d['levels']):5.1f} s (finest level"
              f" {fine['seconds']:.1f} s, {fine['iterations']} CG it.)")
    if len(rows) > 1:
        a, b = rows[0], rows[-1]
        sa, sb = (sum(lv["seconds"] for lv in r["levels"]) for r in (a, b))
        k = np.log(sb / sa) / np.log(b["cells"] / a["cells"])
        print(f"  solve time ~ cells^{k:.2f} between {a['cells']:,} and {b['cells']:,} cells")
    if args.holdout:
        _holdout(50.0)


if __name__ == "__main__":
    main()
