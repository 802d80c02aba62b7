"""In ONE run, at each size: (a) the CSV I/O floor, (b) ``aeromag compensate`` end to end,
(b') ``aeromag compensate --model`` end to end, (c) the numerics in memory (self-calibration:
fit + screening + apply); plus the chunked ``--model`` path.  Reports samples/s, (b)/(a)
and peak memory (each measurement in a fresh process; peak RSS from ``VmHWM``).

Run: ``python benchmarks/bench_io.py --sizes 1e5 1e6 1e7 --dir /tmp/aeromag-bench``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import textwrap
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _data import write_log  # noqa: E402

CHILD = {
    "io": """
        import pyarrow.csv as c
        t = c.read_csv(SRC)
        c.write_csv(t, OUT)
    """,
    "io_threads": """
        # The floor with aeromag's writer (8192-row slices formatted on pyarrow's threads),
        # inlined so that it imports pyarrow only.
        import pyarrow as pa
        import pyarrow.csv as c
        from concurrent.futures import ThreadPoolExecutor
        t = c.read_csv(SRC)
        o = c.WriteOptions(include_header=False, quoting_style="none")
        def fmt(off):
            sink = pa.BufferOutputStream()
            c.write_csv(t.slice(off, 8192), sink, o)
            return sink.getvalue()
        with open(OUT, "wb") as fh, ThreadPoolExecutor(pa.cpu_count()) as ex:
            fh.write((",".join(t.column_names) + "\\n").encode())
            for b in ex.map(fmt, range(0, t.num_rows, 8192)):
                fh.write(b)
    """,
    "baseline": """
        import pyarrow.csv, scipy.signal, sklearn.decomposition, sklearn.covariance
        import aeromag.cli, aeromag.compensate, aeromag.qc, aeromag.chunked
    """,
    "compensate": """
        from aeromag.cli import main
        sys.argv = ["aeromag", "compensate", SRC, "-o", OUT]
        try:
            main()
        except SystemExit as e:
            assert not e.code, e.code
    """,
    "compensate_model": """
        from aeromag.cli import main
        sys.argv = ["aeromag", "compensate", SRC, "--model", MODEL, "-o", OUT]
        try:
            main()
        except SystemExit as e:
            assert not e.code, e.code
    """,
    "numerics": """
        from aeromag.io import read_log
        from aeromag.compensate import compensate
        import aeromag.qc, scipy.signal, sklearn.decomposition, sklearn.covariance  # imports
        df = read_log(SRC, required=("time", "flux_x", "flux_y", "flux_z"))
        T0 = time.perf_counter()
        compensate(df)
    """,
    "numerics_model": """
        from aeromag.io import read_log
        from aeromag.compensate import compensate
        from aeromag.tolles_lawson import TLModel
        import aeromag.qc, scipy.signal  # imports are not numerics
        df = read_log(SRC, required=("time", "flux_x", "flux_y", "flux_z"))
        m = TLModel.load(MODEL)
        T0 = time.perf_counter()
        compensate(df, model=m)
    """,
    "batch_model": """
        # aeromag batch --model over BATCH_FILES hard links of the log, one worker: the time
        # per file, imports paid once (the batch path of issue 4).
        import os, shutil
        from aeromag.cli import main
        d = OUT + ".in"
        shutil.rmtree(d, ignore_errors=True)
        os.makedirs(d)
        for i in range(BATCH_FILES):
            os.link(SRC, os.path.join(d, f"log{i}.csv"))
        sys.argv = ["aeromag", "batch", d, "--model", MODEL, "-o", OUT + ".out", "--workers",
                    "1", "--force", "--no-progress"]
        try:
            main()
        except SystemExit as e:
            assert not e.code, e.code
        T0 += (time.perf_counter() - T0) * (1 - 1 / BATCH_FILES)  # report per file
        shutil.rmtree(d)
        shutil.rmtree(OUT + ".out")
    """,
    "chunked": """
        from aeromag.chunked import apply_model_chunked
        apply_model_chunked(SRC, OUT, MODEL, chunk_rows=500_000)
    """,
}


def run(kind: str, src: Path, out: Path, model: Path | None) -> dict:
    code = textwrap.dedent(f"""
        import json, resource, sys, time
        SRC, OUT, MODEL = {str(src)!r}, {str(out)!r}, {str(model)!r}
        BATCH_FILES = 4
        T0 = time.perf_counter()
    """) + textwrap.dedent(CHILD[kind]) + textwrap.dedent("""
        dt = time.perf_counter() - T0
        # Peak RSS of this address space (VmHWM): getrusage's ru_maxrss survives execve on
        # Linux, so it would report the parent's peak whenever that was larger.
        with open("/proc/self/status") as fh:
            rss = next(int(ln.split()[1]) for ln in fh if ln.startswith("VmHWM:")) * 1024
        print(json.dumps({"s": dt, "rss": rss}))
    """)
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    if p.returncode:
        raise RuntimeError(p.stderr[-2000:])
    return json.loads(p.stdout.strip().splitlines()[-1])


def median_run(kind: str, src: Path, out: Path, model: Path, repeat: int) -> dict:
    """Median time (and the largest peak memory) of ``repeat`` fresh-process runs."""
    runs = [run(kind, src, out, model) for _ in range(repeat)]
    ts = sorted(r["s"] for r in runs)
    return {"s": ts[len(ts) // 2], "s_min": ts[0], "s_max": ts[-1],
            "rss": max(r["rss"] for r in runs)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", nargs="+", type=float, default=[1e5, 1e6, 1e7])
    ap.add_argument("--dir", type=Path, default=Path("/tmp/aeromag-bench"))
    ap.add_argument("--repeat", type=int, default=3,
                    help="runs per measurement; the median time is reported")
    args = ap.parse_args()
    args.dir.mkdir(parents=True, exist_ok=True)
    rows = []
    model = args.dir / "model.json"
    if not model.exists():
        from aeromag.compensate import calibrate_file

        calibrate_file(write_log(100_000, args.dir / "log_100000.csv"), model)
    base = median_run("baseline", model, args.dir / "unused", model, 1)["rss"]
    for n in (int(s) for s in args.sizes):
        src = write_log(n, args.dir / f"log_{n}.csv")
        data_mb = 9 * 8 * n / 1e6  # nine float64 columns in memory
        rep = 1 if n >= 5_000_000 else args.repeat
        r = {k: median_run(k, src, args.dir / f"out_{k}_{n}.csv", model, rep)
             for k in CHILD if k != "baseline"}
        rows.append((n, src.stat().st_size / 1e6, data_mb, r))
        print(json.dumps({"n": n, **r}), flush=True)
    print(f"\nlibrary baseline (imports only): {base / 1e6:.0f} MB peak RSS")
    print("\n| rows | CSV MB | (a) I/O floor s | (a') floor, threaded writer s"
          " | (b) compensate s | (b)/(a) | (b') --model s | (b')/(a)"
          " | (b'') batch --model, per file s | (b'')/(a) | chunked --model s |")
    print("|" + "---|" * 11)
    for n, mb, _, r in rows:
        a, a2, b, bm, bb, d = (r[k]["s"] for k in ("io", "io_threads", "compensate",
                                                  "compensate_model", "batch_model", "chunked"))
        print(f"| {n:.0e} | {mb:.0f} | {a:.2f} | {a2:.2f} | {b:.2f} | {b / a:.2f}"
              f" | {bm:.2f} | {bm / a:.2f} | {bb:.2f} | {bb / a:.2f} | {d:.2f} |")
    print("\n| rows | (c) fit + apply s | samples/s | (c') apply s | samples/s |")
    print("|" + "---|" * 5)
    for n, _, _, r in rows:
        c, cm = r["numerics"]["s"], r["numerics_model"]["s"]
        print(f"| {n:.0e} | {c:.3f} | {n / c / 1e6:.2f} M | {cm:.3f} | {n / cm / 1e6:.2f} M |")
    print("\nPeak RSS in MB; in brackets, above the library baseline as a multiple of the data"
          " (nine float64 columns).")
    print("\n| rows | data MB | (a) floor | (b) compensate | (b') --model | (b'') batch"
          " --model | chunked --model |")
    print("|" + "---|" * 7)
    for n, _, data_mb, r in rows:
        cells = []
        for k in ("io", "compensate", "compensate_model", "batch_model", "chunked"):
            rss = r[k]["rss"]
            cells.append(f"{rss / 1e6:.0f} ({(rss - base) / 1e6 / data_mb:.1f}x)")
        print(f"| {n:.0e} | {data_mb:.0f} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
