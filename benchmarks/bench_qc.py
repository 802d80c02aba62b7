"""Speed of the default QC: manoeuvre detection, FOM, fit diagnostics; and ``aeromag report``.

Run ``python benchmarks/bench_qc.py`` (add ``--report`` for the report on a 2e6-row log, which
runs in a subprocess so its peak memory (VmHWM) is its own).  Prints seconds per 1e6 rows.

The calibration log is the project's simulator (:func:`aeromag.synthetic.simulate_calibration`)
with as many boxes as fill the requested rows (10 Hz, turns cut).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

warnings.simplefilter("ignore", DeprecationWarning)


def calibration(rows: int, seed: int = 1):
    """A simulated calibration flight of about ``rows`` samples (10 Hz, 3000 rows a box)."""
    from aeromag.synthetic import simulate_calibration

    df, _ = simulate_calibration(seed=seed, n_boxes=max(1, round(rows / 3000)))
    return df


def best(fn, repeat: int = 5) -> float:
    """Best CPU time of ``repeat`` calls [s] (process time: the machine is shared, and the
    detection runs on one thread, so this is its wall time on an idle machine)."""
    out = []
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        out.append(time.process_time() - t0)
    return min(out)


def bench_detection(rows: int) -> None:
    from aeromag.qc import detect_maneuvers

    df = calibration(rows)
    n = len(df)
    flux_only = df.drop(columns=["heading", "pitch", "roll"])
    r = detect_maneuvers(df)
    print(f"manoeuvre detection, {n} rows at 10 Hz ({len(r.table)} manoeuvres, "
          f"{len(r.complete_boxes)} complete boxes), CPU s per 1e6 rows:")
    for name, d in (("attitude", df), ("fluxgate", flux_only)):
        tw = best(lambda d=d: detect_maneuvers(d))
        tf = best(lambda d=d: detect_maneuvers(d, rate_hz=None), repeat=2)
        print(f"  {name:9s} {tw / n * 1e6:.3f} (working rate 2 Hz, the default)"
              f"   {tf / n * 1e6:.3f} (full rate)")


def bench_qc(rows: int) -> None:
    from aeromag.compensation.pipeline import run_compensation as compensate
    from aeromag.qc import compute_qc

    df = calibration(rows)
    n = len(df)
    res = compensate(df)
    tq = best(lambda: compute_qc(res), repeat=1)
    print(f"compute_qc (FOM, manoeuvres, VIF, LOSO-CV), {n} rows: {tq:.3f} s = "
          f"{tq / n * 1e6:.3f} s per 1e6 rows")


def bench_report(rows: int, workdir: str | None = None) -> None:
    """``aeromag report`` on a compensated log of ``rows`` rows: wall time and peak memory.

    The compensated log is cached in ``workdir`` (default: a temporary folder)."""
    from aeromag.workflows.compensate import compensate_file

    with tempfile.TemporaryDirectory() as tmp:
        d = Path(workdir or tmp)
        d.mkdir(parents=True, exist_ok=True)
        out = d / f"out_{rows}.csv"
        if not out.exists():
            cal = d / f"cal_{rows}.csv"
            calibration(rows).to_csv(cal, index=False)
            compensate_file(cal, out)
            cal.unlink()
        code = ("import sys, warnings, time; warnings.simplefilter('ignore');"
                "t=time.perf_counter();"
                "from aeromag.cli import app;"
                f"sys.argv=['aeromag','report',{str(out)!r},'-o',{str(d / 'rep')!r}];"
                "\ntry:\n    app()\nexcept SystemExit:\n    pass\n"
                "print('WALL', time.perf_counter()-t);"
                "print('HWM', open('/proc/self/status').read().split('VmHWM:')[1].split()[0])")
        t0 = time.process_time()
        p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           env=dict(os.environ, NO_COLOR="1"))
        wall = hwm = float("nan")
        for line in p.stdout.splitlines():
            if line.startswith("WALL"):
                wall = float(line.split()[1])
            if line.startswith("HWM"):
                hwm = int(line.split()[1]) / 1024
        if p.returncode or wall != wall:
            print(p.stdout[-2000:], p.stderr[-2000:])
        del t0
        size = out.stat().st_size / 1e6
        print(f"aeromag report, {rows} rows ({size:.0f} MB CSV): {wall:.1f} s wall (imports"
              f" included), peak {hwm:.0f} MB (VmHWM)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=1_000_000)
    ap.add_argument("--qc", action="store_true", help="also time compute_qc on a compensation")
    ap.add_argument("--report", action="store_true", help="also time 'aeromag report'")
    ap.add_argument("--report-rows", type=int, default=2_000_000)
    ap.add_argument("--workdir", help="cache the compensated report log here")
    ap.add_argument("--no-detection", action="store_true")
    a = ap.parse_args()
    if not a.no_detection:
        bench_detection(a.rows)
    if a.qc:
        bench_qc(a.rows)
    if a.report:
        bench_report(a.report_rows, a.workdir)


if __name__ == "__main__":
    main()
