"""In ONE run, at each size: (a) the CSV I/O floor, (b) ``aeromag compensate`` end to end,
(b') ``aeromag compensate --model`` end to end, (c) the numerics in memory (self-calibration:
fit + screening + apply); plus the chunked ``--model`` path.  Reports samples/s, (b)/(a)
and peak memory (each measurement in a fresh process; peak RSS from ``getrusage``).

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
        import aeromag.qc  # lazily imported by the pipeline: imports are not numerics
        df = read_log(SRC, required=("time", "flux_x", "flux_y", "flux_z"))
        T0 = time.perf_counter()
        compensate(df)
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
        T0 = time.perf_counter()
    """) + textwrap.dedent(CHILD[kind]) + textwrap.dedent("""
        dt = time.perf_counter() - T0
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
        print(json.dumps({"s": dt, "rss": rss}))
    """)
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    if p.returncode:
        raise RuntimeError(p.stderr[-2000:])
    return json.loads(p.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", nargs="+", type=float, default=[1e5, 1e6, 1e7])
    ap.add_argument("--dir", type=Path, default=Path("/tmp/aeromag-bench"))
    args = ap.parse_args()
    args.dir.mkdir(parents=True, exist_ok=True)
    rows = []
    for n in (int(s) for s in args.sizes):
        src = write_log(n, args.dir / f"log_{n}.csv")
        model = args.dir / "model.json"
        if not model.exists():
            from aeromag.compensate import calibrate_file

            calibrate_file(write_log(100_000, args.dir / "log_100000.csv"), model)
        data_mb = 9 * 8 * n / 1e6  # nine float64 columns in memory
        r = {k: run(k, src, args.dir / f"out_{k}_{n}.csv", model) for k in CHILD}
        rows.append((n, src.stat().st_size / 1e6, data_mb, r))
        print(json.dumps({"n": n, **{k: v for k, v in r.items()}}), flush=True)
    print("\n| rows | CSV MB | (a) I/O floor s | (b) compensate s | (b)/(a) | (b) peak MB (x data)"
          " | (b') compensate --model s | (b')/(a) | (b') peak MB | (c) numerics s"
          " | (c) samples/s | chunked --model s | chunked peak MB |")
    print("|" + "---|" * 13)
    for n, mb, data_mb, r in rows:
        a, b, bm, c, d = (r[k] for k in ("io", "compensate", "compensate_model", "numerics",
                                         "chunked"))
        print(f"| {n:.0e} | {mb:.0f} | {a['s']:.2f} | {b['s']:.2f} | {b['s'] / a['s']:.2f} "
              f"| {b['rss'] / 1e6:.0f} ({b['rss'] / 1e6 / data_mb:.1f}x)"
              f" | {bm['s']:.2f} | {bm['s'] / a['s']:.2f} | {bm['rss'] / 1e6:.0f}"
              f" | {c['s']:.2f} | {n / c['s'] / 1e6:.2f} M | {d['s']:.2f} "
              f"| {d['rss'] / 1e6:.0f} |")


if __name__ == "__main__":
    main()
