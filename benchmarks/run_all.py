"""aeromag's speed where users feel it, in one run, every measurement in a fresh process.

At each size of a synthetic 10 Hz log (9 columns, 60 s lines):

* ``aeromag calibrate LOG -o M.json`` against deinterf's default Tolles-Lawson fit of the same
  file (pandas' pyarrow reader, ``TollesLawsonRegressor().fit``, coefficients saved): the speed-up;
* ``aeromag compensate LOG --model M.json -o OUT.csv`` against pyarrow reading and writing the
  same CSV (``pyarrow.csv.read_csv`` + ``write_csv``, the I/O floor): the ratio;
* what the libraries alone cost: the packages each command imports, the CSV read as aeromag
  reads it and (for ``--model``) the output written, with no work at all.  It splits each ratio
  into the part no implementation on these libraries can avoid and the part that is aeromag's;

and ``aeromag calibrate`` of 1 kHz logs (1.2e6 and 1.2e7 rows: 20 minutes and 3.3 hours of
flight), with and without ``--no-decimate``.  Times are wall clock of the whole child process
(Python start-up, imports, reading, work, writing); peak memory is the child's ``VmHWM``,
also given as a multiple of the data in memory (9 float64 columns).  Plus the start-up of
``aeromag --help`` and which heavy packages each command imported.

Run::

    python benchmarks/run_all.py --quick     # 1e5 and 1e6 rows, 1.2e6 at 1 kHz (~3 min)
    python benchmarks/run_all.py             # + 1e7 rows and 1.2e7 at 1 kHz (~20 min)

Generated logs are cached in ``--dir`` (default ``$TMPDIR/aeromag-bench-v3``).  deinterf is
not a dependency of aeromag: install it to compare (``pip install -e ".[bench]"``); without
it those columns say n/a.  Not a test: speed is never asserted.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _data import COLUMNS, write_log  # noqa: E402

MARK = "@@BENCH "
HEAVY = ("pandas", "scipy.signal", "sklearn", "matplotlib", "pyproj", "deinterf")

_EPILOGUE = f"""
import json as _j, sys as _s
with open("/proc/self/status") as _fh:
    _hwm = next(int(l.split()[1]) for l in _fh if l.startswith("VmHWM:")) * 1024
print({MARK!r} + _j.dumps({{"rss": _hwm, "code": _CODE,
      "mods": [m for m in {HEAVY!r} if m in _s.modules]}}), file=_s.stderr)
"""

_AEROMAG = """
import runpy, sys
sys.argv = ["aeromag"] + ARGV
_CODE = 0
try:
    runpy.run_module("aeromag", run_name="__main__", alter_sys=True)
except SystemExit as e:
    _CODE = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
"""

_FLOOR = """
import pyarrow.csv as c
c.write_csv(c.read_csv(SRC), OUT)
_CODE = 0
"""

#: What the libraries alone cost on the ``--model`` path: the packages ``compensate --model``
#: imports, the CSV read as aeromag reads it (pyarrow's streaming reader, then pandas), and the
#: 13-column output written by pyarrow; no compensation, no metrics.  Any implementation built
#: on these libraries pays at least this much.
_LIBFLOOR = """
import numpy as np, pandas as pd, pyarrow as pa, pyarrow.csv as c, scipy.signal
r = c.open_csv(SRC)
df = pa.Table.from_batches(list(r), schema=r.schema).to_pandas()
x = df["mag"].to_numpy()
out = df.assign(mag_tl=x * 0.0, mag_comp=x, segment=np.zeros(len(df), np.int64),
                segment_kept=np.ones(len(df), bool))
c.write_csv(pa.Table.from_pandas(out, preserve_index=False), OUT)
_CODE = 0
"""

#: The same for ``calibrate``: its packages (scikit-learn's PCA and robust covariance for the
#: screening included) and the CSV read; no fit, no screening, no QC, no JSON.
_CALFLOOR = """
import numpy as np, pandas as pd, pyarrow as pa, pyarrow.csv as c, scipy.signal
import sklearn.decomposition, sklearn.covariance
r = c.open_csv(SRC)
df = pa.Table.from_batches(list(r), schema=r.schema).to_pandas()
_CODE = 0
"""

_BASELINE = """
import pyarrow.csv, scipy.signal, sklearn.decomposition, sklearn.covariance
import aeromag.compensation, aeromag.qc, aeromag.io, aeromag.workflows.compensate
_CODE = 0
"""

_DEINTERF = """
import json
import numpy as np
import pandas as pd
from deinterf.compensator.tmi.linear import Terms
try:  # the name on deinterf's main branch
    from deinterf.compensator.tmi.linear import TollesLawsonRegressor
except ImportError:  # deinterf 1.2.0 as published on PyPI
    from deinterf.compensator.tmi.linear import TollesLawson as TollesLawsonRegressor
from deinterf.foundation.sensors import MagVector, Tmi
from deinterf.utils.data_ioc import DataIoC
df = pd.read_csv(SRC, engine="pyarrow")
fs = int(round(1.0 / float(np.median(np.diff(df["time"].to_numpy()[:10000])))))
x = DataIoC().add(MagVector(bx=df["flux_x"], by=df["flux_y"], bz=df["flux_z"]))
tl = TollesLawsonRegressor(terms=Terms.Terms_16, sampling_rate=fs).fit(x, Tmi(tmi=df["mag"]))
with open(OUT, "w") as fh:
    json.dump({"coef": np.ravel(tl.model_.coef_).tolist()}, fh)
_CODE = 0
"""


def child(body: str, timeout: float, **names: object) -> dict:
    """Run ``body`` in a fresh interpreter; wall time [s], peak RSS [B], heavy modules."""
    head = "".join(f"{k} = {v!r}\n" for k, v in names.items())
    code = head + textwrap.dedent(body) + _EPILOGUE
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    try:
        p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"s": float("nan"), "rss": float("nan"), "error": f"timed out after {timeout} s"}
    dt = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    line = next((ln for ln in p.stderr.splitlines() if ln.startswith(MARK)), None)
    if p.returncode or line is None:
        return {"s": dt, "cpu": cpu, "rss": float("nan"), "error": p.stderr.strip()[-600:]}
    r = json.loads(line[len(MARK):])
    if r["code"]:
        return {"s": dt, "cpu": cpu, "rss": r["rss"], "error": p.stderr.strip()[-600:]}
    return {"s": dt, "cpu": cpu, "rss": r["rss"], "mods": r["mods"]}


def best(n_runs: int, body: str, timeout: float, **names: object) -> dict:
    """The fastest of ``n_runs`` fresh-process runs (the largest peak memory)."""
    runs = [child(body, timeout, **names) for _ in range(n_runs)]
    ok = [r for r in runs if "error" not in r]
    if not ok:
        return runs[0]
    r = dict(min(ok, key=lambda r: r["s"]))
    r["rss"] = max(x["rss"] for x in ok)
    return r


def aeromag(argv: list[str], repeat: int, timeout: float) -> dict:
    return best(repeat, _AEROMAG, timeout, ARGV=[str(a) for a in argv])


#: deinterf's peak memory per row of a 9-column log (1.68 GB at 1e6 rows, measured).
DEINTERF_BYTES_PER_ROW = 1700


def mem_available() -> float:
    """Bytes of memory available now (``MemAvailable``), or inf when unknown."""
    try:
        with open("/proc/meminfo") as fh:
            return next(int(ln.split()[1]) * 1024 for ln in fh if ln.startswith("MemAvailable"))
    except (OSError, StopIteration):
        return float("inf")


def deinterf_fits(n: int) -> bool:
    """Whether deinterf's fit of ``n`` rows fits in the memory available now (with room)."""
    need = DEINTERF_BYTES_PER_ROW * n
    if mem_available() < 1.5 * need:
        print(f"deinterf at {n:.0e} rows needs about {need / 1e9:.0f} GB; only"
              f" {mem_available() / 1e9:.0f} GB available: not run", file=sys.stderr)
        return False
    return True


def have_deinterf() -> bool:
    p = subprocess.run([sys.executable, "-c", "import deinterf"], capture_output=True)
    return p.returncode == 0


def fmt_s(r: dict) -> str:
    """Wall-clock seconds (CPU seconds of the process in brackets)."""
    if r is None:
        return "n/a"
    return "fail" if "error" in r else f"{r['s']:.2f} ({r['cpu']:.2f})"


BASE_MB = 0.0  # peak of the libraries imported, nothing read (set in main)


def fmt_mb(r: dict, data_mb: float, base: bool = True) -> str:
    """Peak MB (its multiple of the data; above the library baseline, in brackets)."""
    if r is None or "error" in r:
        return "n/a"
    mb = r["rss"] / 1e6
    above = f"; {(mb - BASE_MB) / data_mb:.1f}x" if base else ""
    return f"{mb:.0f} ({mb / data_mb:.1f}x{above})"


def ratio(a: dict | None, b: dict | None) -> str:
    """Wall-clock ratio (CPU-time ratio in brackets: steadier on a shared machine)."""
    if a is None or b is None or "error" in a or "error" in b:
        return "n/a"
    return f"{a['s'] / b['s']:.2f} ({a['cpu'] / b['cpu']:.2f})"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true",
                    help="1e5 and 1e6 rows at 10 Hz, 1.2e6 at 1 kHz only")
    ap.add_argument("--dir", type=Path,
                    default=Path(tempfile.gettempdir()) / "aeromag-bench-v3",
                    help="cache of generated logs and outputs")
    ap.add_argument("--repeat", type=int, default=1,
                    help="fresh-process runs per measurement below 5e6 rows; the fastest counts")
    ap.add_argument("--timeout", type=float, default=1800.0, help="seconds per measurement")
    ap.add_argument("--no-deinterf", action="store_true", help="skip the deinterf runs")
    ap.add_argument("--sizes", nargs="+", type=float, help="10 Hz rows (overrides the mode)")
    ap.add_argument("--khz-sizes", nargs="+", type=float, help="1 kHz rows (overrides)")
    args = ap.parse_args()
    d = args.dir
    d.mkdir(parents=True, exist_ok=True)
    sizes = [100_000, 1_000_000] + ([] if args.quick else [10_000_000])
    khz = [1_200_000] + ([] if args.quick else [12_000_000])
    if args.sizes:
        sizes = sorted(int(x) for x in args.sizes)
    if args.khz_sizes:
        khz = sorted(int(x) for x in args.khz_sizes)
    deinterf = not args.no_deinterf and have_deinterf()
    if not deinterf:
        print("deinterf is not installed (pip install -e '.[bench]'): its columns say n/a",
              file=sys.stderr)
    width = 8 * len(COLUMNS)  # bytes per row in memory: 9 float64 columns

    def log(msg: str) -> None:
        print(msg, file=sys.stderr, flush=True)

    t_start = time.perf_counter()
    load0 = os.getloadavg()
    help_r = aeromag(["--help"], 3, args.timeout)
    global BASE_MB
    base_r = child(_BASELINE, args.timeout)
    BASE_MB = base_r["rss"] / 1e6
    log(f"aeromag --help: {json.dumps(help_r)}")
    # One model for every --model run: calibrated on the 1e5-row log.
    model = d / f"model_{sizes[0]}.json"
    rows10 = []
    for n in sizes:
        src = write_log(n, d / f"log10_{n}.csv", fs=10.0)
        rep = args.repeat if n < 5_000_000 else 1
        r: dict[str, dict | None] = {}
        r["calibrate"] = aeromag(["calibrate", src, "-o", d / f"model_{n}.json"], rep,
                                 args.timeout)
        r["deinterf"] = (best(rep, _DEINTERF, args.timeout, SRC=str(src),
                              OUT=str(d / f"deinterf_{n}.json"))
                         if deinterf and deinterf_fits(n) else None)
        if not model.exists():
            raise SystemExit(f"no model from the calibration of {src}: {r['calibrate']}")
        r["floor"] = best(rep, _FLOOR, args.timeout, SRC=str(src), OUT=str(d / "floor.csv"))
        r["model"] = aeromag(["compensate", src, "--model", model, "-o", d / "comp.csv"],
                             rep, args.timeout)
        r["libfloor"] = best(rep, _LIBFLOOR, args.timeout, SRC=str(src),
                             OUT=str(d / "floor.csv"))
        r["calfloor"] = best(rep, _CALFLOOR, args.timeout, SRC=str(src))
        for p in (d / "floor.csv", d / "comp.csv", d / "comp.json"):
            p.unlink(missing_ok=True)
        rows10.append((n, src.stat().st_size / 1e6, n * width / 1e6, r))
        log(f"10 Hz {n}: {json.dumps(r)}")
    rows1k = []
    for n in khz:
        src = write_log(n, d / f"log1k_{n}.csv", fs=1000.0)
        rep = args.repeat if n < 5_000_000 else 1
        r = {"calibrate": aeromag(["calibrate", src, "-o", d / f"model1k_{n}.json"], rep,
                                  args.timeout)}
        r["full"] = (aeromag(["calibrate", src, "-o", d / f"model1k_full_{n}.json",
                              "--no-decimate"], 1, args.timeout) if _has_no_decimate()
                     else None)
        r["deinterf"] = (best(1, _DEINTERF, args.timeout, SRC=str(src),
                              OUT=str(d / f"deinterf1k_{n}.json"))
                         if deinterf and deinterf_fits(n) else None)
        rows1k.append((n, src.stat().st_size / 1e6, n * width / 1e6, r))
        log(f"1 kHz {n}: {json.dumps(r)}")

    print(f"\nmachine: {os.cpu_count()} cores; python {sys.version.split()[0]};"
          f" total {time.perf_counter() - t_start:.0f} s")
    print(f"aeromag --help: {fmt_s(help_r)} s, peak {fmt_mb(help_r, 1.0).split()[0]} MB,"
          f" imported {', '.join(help_r.get('mods', [])) or 'none of ' + ', '.join(HEAVY)}")
    print(f"load average before: {load0}, after: {os.getloadavg()}")
    print("\n10 Hz logs: wall-clock s of the whole process (its CPU s in brackets)\n")
    print("| rows | CSV MB | calibrate | deinterf fit | speed-up | pyarrow read+write"
          " | compensate --model | ratio to floor |")
    print("|---|---|---|---|---|---|---|---|")
    for n, mb, _, r in rows10:
        print(f"| {n:.0e} | {mb:.0f} | {fmt_s(r['calibrate'])} | {fmt_s(r['deinterf'])}"
              f" | {ratio(r['deinterf'], r['calibrate'])} | {fmt_s(r['floor'])}"
              f" | {fmt_s(r['model'])} | {ratio(r['model'], r['floor'])} |")
    print("\nWhat the libraries alone cost (their imports, the read as aeromag reads it and,"
          " for --model, the 13-column write; no work): wall-clock s (CPU s)\n")
    print("| rows | libraries, --model path | compensate --model / libraries | --model"
          " libraries / floor | libraries + read, calibrate | deinterf / that"
          " (the largest speed-up with zero fit work) |")
    print("|---|---|---|---|---|---|")
    for n, _, _, r in rows10:
        print(f"| {n:.0e} | {fmt_s(r['libfloor'])} | {ratio(r['model'], r['libfloor'])}"
              f" | {ratio(r['libfloor'], r['floor'])} | {fmt_s(r['calfloor'])}"
              f" | {ratio(r['deinterf'], r['calfloor'])} |")
    print("\n1 kHz logs: wall-clock s of the whole process (its CPU s in brackets)\n")
    print("| rows | CSV MB | calibrate | calibrate --no-decimate | deinterf fit | speed-up |")
    print("|---|---|---|---|---|---|")
    for n, mb, _, r in rows1k:
        print(f"| {n:.1e} | {mb:.0f} | {fmt_s(r['calibrate'])} | {fmt_s(r['full'])}"
              f" | {fmt_s(r['deinterf'])} | {ratio(r['deinterf'], r['calibrate'])} |")
    print(f"\nPeak memory [MB] (multiple of the data in memory, 9 float64 columns; above the"
          f" {BASE_MB:.0f} MB of the libraries imported with nothing read)\n")
    print("| log | rows | data MB | calibrate | deinterf fit | pyarrow read+write"
          " | compensate --model |")
    print("|---|---|---|---|---|---|---|")
    for n, _, dmb, r in rows10:
        print(f"| 10 Hz | {n:.0e} | {dmb:.0f} | {fmt_mb(r['calibrate'], dmb)}"
              f" | {fmt_mb(r['deinterf'], dmb, False)} | {fmt_mb(r['floor'], dmb, False)}"
              f" | {fmt_mb(r['model'], dmb)} |")
    for n, _, dmb, r in rows1k:
        print(f"| 1 kHz | {n:.1e} | {dmb:.0f} | {fmt_mb(r['calibrate'], dmb)}"
              f" | {fmt_mb(r['deinterf'], dmb, False)} | | |")
    print("\nHeavy packages imported")
    for name, r in [("calibrate", rows10[0][3]["calibrate"]),
                    ("compensate --model", rows10[0][3]["model"])]:
        print(f"- {name}: {', '.join(r.get('mods', [])) if r else 'n/a'}")
    fails = [(n, k, v["error"]) for n, _, _, r in rows10 + rows1k for k, v in r.items()
             if v is not None and "error" in v]
    for n, k, e in fails:
        print(f"\nFAILED {k} at {n} rows:\n{e}", file=sys.stderr)


_FLAGS: dict[str, bool] = {}


def _help_has(flag: str, command: str) -> bool:
    if flag not in _FLAGS:
        p = subprocess.run([sys.executable, "-m", "aeromag", command, "--help"],
                           capture_output=True, text=True, env=dict(os.environ, COLUMNS="200"))
        _FLAGS[flag] = flag in p.stdout
    return _FLAGS[flag]


def _has_no_decimate() -> bool:
    return _help_has("--no-decimate", "calibrate")


if __name__ == "__main__":
    main()
