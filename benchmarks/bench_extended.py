"""Speed of ``calibrate`` with 10 extra regressors (issue 29): within 1.5x the time without.

Times :func:`aeromag.calibrate` (the library call ``aeromag calibrate`` runs, FOM off: the
manoeuvre detection does not depend on the extras) on the same synthetic log
(:mod:`benchmarks._data`: boxes, attitude oscillations, 16-term interference) with and without
10 extra columns (currents: load switches and band-limited noise, the interference of three of
them added to ``mag``).  Best of ``--repeat`` runs each, wall clock.

    PYTHONPATH=. python benchmarks/bench_extended.py --rows 1000000
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
from _data import make_log


def _extras(df, n_extra: int, seed: int = 1):
    rng = np.random.default_rng(seed)
    n = len(df)
    for j in range(n_extra):
        steps = np.repeat(rng.integers(-1, 2, n // 150 + 1), 150)[:n] * 2.0
        df[f"cur_{j + 1}"] = 10 + steps + np.convolve(rng.normal(0, 0.5, n), np.ones(5) / 5,
                                                      mode="same")
    for j in range(3):
        df["mag"] += 0.02 * df[f"cur_{j + 1}"]
    return df


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rows", type=int, default=1_000_000)
    ap.add_argument("--extras", type=int, default=10)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--files", action="store_true",
                    help="time 'aeromag calibrate' itself (calibrate_file: CSV read, FOM on, "
                    "model written) instead of the in-memory fit with the FOM off")
    a = ap.parse_args()
    import aeromag as am
    from aeromag.compensation.config import CompensationConfig

    df = _extras(make_log(a.rows), a.extras)
    names = tuple(f"cur_{j + 1}" for j in range(a.extras))
    am.calibrate(df.iloc[:20_000], CompensationConfig(fom=False, extras=names))  # warm-up
    tmp = Path(tempfile.mkdtemp(prefix="bench_extended_"))
    if a.files:
        from aeromag.workflows.compensate import calibrate_file

        df.to_csv(tmp / "cal.csv", index=False)
    fom = None if a.files else False
    cfgs = {"16 terms": CompensationConfig(fom=fom),
            f"16 terms + {a.extras} extras": CompensationConfig(fom=fom, extras=names)}
    times = {k: [] for k in cfgs}
    results = {}
    for _ in range(a.repeat):  # interleaved, so a change of the machine's load hits both
        for label, cfg in cfgs.items():
            t0 = time.perf_counter()
            results[label] = (calibrate_file(tmp / "cal.csv", tmp / "m.json", cfg) if a.files
                              else am.calibrate(df, cfg))
            times[label].append(time.perf_counter() - t0)
    for label, res in results.items():
        held = res.report.extended.held_out if res.report.extended is not None else None
        print(f"{label}: best {min(times[label]):.2f} s, median "
              f"{np.median(times[label]):.2f} s of {a.repeat}; residual std "
              f"{res.metrics.residual_std_nT:.4f} nT"
              + (f"; held-out {held.residual_std_nT:.4f} nT, TL only "
                 f"{held.tl_only_residual_std_nT:.4f} nT" if held else ""))
    times = {k: float(np.median(v)) for k, v in times.items()}
    r = times[f"16 terms + {a.extras} extras"] / times["16 terms"]
    print(f"{a.rows} rows{' (files, FOM on)' if a.files else ' (in memory, FOM off)'}: ratio "
          f"{r:.2f} (goal <= 1.5)")
    shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
