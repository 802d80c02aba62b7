"""Time the compensation numerics (fit + apply) in memory at 1e5, 1e6, 1e7 samples.

Run: ``python benchmarks/bench_compensate.py [--sizes 1e5 1e6 1e7]``.  Not a test.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _data import make_log  # noqa: E402

from aeromag.compensate import CompensationConfig, compensate  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", nargs="+", type=float, default=[1e5, 1e6, 1e7])
    args = ap.parse_args()
    cfg = CompensationConfig()
    compensate(make_log(20_000), cfg)  # warm-up (imports, caches)
    print(f"{'samples':>10} {'fit+apply s':>12} {'apply s':>9} {'Msamples/s':>11}")
    for n in (int(s) for s in args.sizes):
        df = make_log(n)
        t0 = time.perf_counter()
        res = compensate(df, cfg)
        t1 = time.perf_counter()
        compensate(df, cfg, model=res.model)
        t2 = time.perf_counter()
        print(f"{n:>10} {t1 - t0:>12.2f} {t2 - t1:>9.2f} {n / (t1 - t0) / 1e6:>11.2f}",
              flush=True)


if __name__ == "__main__":
    main()
