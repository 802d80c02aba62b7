"""Speed and peak memory of ``aeromag report`` on a 2e6-row compensated calibration log.

Run ``python benchmarks/bench_report.py`` (``--rows N``, ``--workdir DIR`` to cache the logs,
default ``/tmp/aeromag-bench-report``).  It builds, once:

1. ``cal_N.csv``: a simulated 10 Hz box calibration flight of about N rows
   (:func:`aeromag.synthetic.simulate_calibration`, 3000 rows a box);
2. ``model_N.json``: ``aeromag calibrate cal_N.csv -o model_N.json``;
3. ``out_N.csv`` + ``out_N.json``: ``aeromag compensate cal_N.csv --model model_N.json``;

then times ``aeromag report out_N.csv -o DIR`` in a child process (``--repeat`` times) and
prints its wall time, CPU time (user + sys: the machine is shared, so wall time alone says
little) and peak resident memory (the child's ``ru_maxrss``, the same as ``VmHWM`` and
``/usr/bin/time -v``'s "Maximum resident set size").
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import time
import warnings
from pathlib import Path

warnings.simplefilter("ignore", DeprecationWarning)


def _aeromag(*args: str) -> list[str]:
    return [sys.executable, "-m", "aeromag", *args]


def build(rows: int, workdir: Path) -> Path:
    """The compensated log of ``rows`` rows in ``workdir`` (built when missing)."""
    workdir.mkdir(parents=True, exist_ok=True)
    cal, model = workdir / f"cal_{rows}.csv", workdir / f"model_{rows}.json"
    out = workdir / f"out_{rows}.csv"
    if not cal.exists():
        from aeromag.synthetic import simulate_calibration

        t0 = time.perf_counter()
        df, _ = simulate_calibration(seed=1, n_boxes=max(1, round(rows / 3000)))
        df.to_csv(cal.with_suffix(".tmp"), index=False)
        os.replace(cal.with_suffix(".tmp"), cal)
        print(f"simulated {len(df)} rows -> {cal} ({time.perf_counter() - t0:.0f} s)")
        del df
    if not model.exists():
        subprocess.run(_aeromag("calibrate", str(cal), "-o", str(model)), check=True)
    if not out.exists():
        subprocess.run(_aeromag("compensate", str(cal), "--model", str(model), "-o", str(out)),
                       check=True)
    return out


def time_report(out: Path, rep: Path) -> tuple[float, float, float]:
    """Wall [s], CPU (user + sys) [s] and peak RSS [MB] of one ``aeromag report``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    p = subprocess.run(_aeromag("report", str(out), "-o", str(rep)), capture_output=True,
                       text=True, env=dict(os.environ, NO_COLOR="1"))
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode:
        sys.exit(f"aeromag report failed:\n{p.stdout[-2000:]}\n{p.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    # ru_maxrss of RUSAGE_CHILDREN is the largest child so far: run each repeat after the
    # builders, and report the largest (the builders are not timed in the same process).
    return wall, cpu, after.ru_maxrss / 1024


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=2_000_000)
    ap.add_argument("--workdir", default="/tmp/aeromag-bench-report")
    ap.add_argument("--repeat", type=int, default=1)
    a = ap.parse_args()
    work = Path(a.workdir)
    out = build(a.rows, work)
    # The builders ran in other children: measure in a fresh grandchild so its peak is its own.
    if os.environ.get("_AEROMAG_BENCH_CHILD") != "1":
        for _ in range(a.repeat):
            subprocess.run([sys.executable, __file__, "--rows", str(a.rows), "--workdir",
                            str(work)], check=True, env=dict(os.environ,
                                                             _AEROMAG_BENCH_CHILD="1"))
        return
    wall, cpu, peak = time_report(out, work / "rep")
    size = out.stat().st_size / 1e6
    print(f"aeromag report, {a.rows} rows ({size:.0f} MB CSV): {wall:.1f} s wall,"
          f" {cpu:.1f} s CPU (user+sys), peak RSS {peak:.0f} MB;"
          f" load average {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
