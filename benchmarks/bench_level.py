"""Speed and peak memory of ``aeromag level`` on the full Osborne survey (990,987 samples).

Run by hand: ``python benchmarks/bench_level.py [--decorrugate] [--keep DIR]``.  The survey
(../shared/data/real/survey/osborne-magnetic.csv.xz, Geoscience Australia P1029 via
Fatiando a Terra, CC-BY 4.0) is decompressed once into a CSV with the canonical names
(line, lon, lat, alt, tmi0) and cached in DIR (default /tmp/aeromag_bench_level); then the
command runs in a child process exactly as a user types it::

    aeromag level osborne.csv --value tmi0 --no-igrf -o osborne_lev.csv

and the script prints the wall time and the child's peak resident memory (ru_maxrss), and
the step times of the library call (``am.level`` on the table already read).  The goal for
``level`` + ``grid`` together is < 1 min and < 2 GB on this machine.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd

SRC = (Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real" / "survey"
       / "osborne-magnetic.csv.xz")


def _csv(folder: Path) -> Path:
    out = folder / "osborne.csv"
    if not out.exists():
        df = pd.read_csv(SRC).rename(columns={
            "flight_line": "line", "longitude": "lon", "latitude": "lat",
            "height_orthometric_m": "alt", "total_field_anomaly_nt": "tmi0"})
        folder.mkdir(parents=True, exist_ok=True)
        df.to_csv(out, index=False)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--decorrugate", action="store_true", help="also micro-level")
    ap.add_argument("--keep", type=Path, default=Path("/tmp/aeromag_bench_level"))
    args = ap.parse_args()
    if not SRC.exists():
        sys.exit(f"the Osborne survey is not at {SRC}")
    csv = _csv(args.keep)
    out = args.keep / "osborne_lev.csv"
    cmd = [sys.executable, "-m", "aeromag", "level", str(csv), "--value", "tmi0", "--no-igrf",
           "-o", str(out)] + (["--decorrugate"] if args.decorrugate else [])
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0
    if r.returncode:
        sys.exit(r.stderr)
    rep = json.loads(out.with_suffix(".json").read_text())
    print(r.stdout.strip())
    print(f"aeromag level (CLI, read + level + write): {wall:.1f} s wall, peak RSS {peak:.0f} MiB")
    print(f"  crossings {rep['n_crossovers']}, mistie std {rep['mistie_std_nT']}, robust "
          f"{rep['mistie_robust_std_nT']}")
    import aeromag as am

    df = pd.read_csv(csv)
    steps: list[tuple[str, float]] = []
    last = [time.perf_counter()]

    def progress(done: int, total: int, step: str) -> None:
        now = time.perf_counter()
        steps.append((step, now - last[0]))
        last[0] = now

    t0 = time.perf_counter()
    am.level(df, value="tmi0", igrf=False, decorrugate=args.decorrugate, progress=progress)
    print(f"am.level on the table: {time.perf_counter() - t0:.1f} s; time before each step: "
          + ", ".join(f"{s} {d:.2f} s" for s, d in steps))


if __name__ == "__main__":
    main()
