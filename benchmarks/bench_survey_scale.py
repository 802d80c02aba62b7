"""How ``aeromag level`` and ``aeromag grid`` scale to a 1e7-sample survey: time and memory.

Run by hand: ``python benchmarks/bench_survey_scale.py [--sizes 1e6,3e6,1e7] [--profile N]``.

For each size a synthetic survey is written once (cached in ``--keep``, default
/tmp/aeromag_bench_scale) by a generator of this script, independent of aeromag: east-west
lines 200 m apart, north-south ties every 2 km, 10 Hz at 50 m/s (5 m per sample), each line
with a curved run-in and a few metres of cross-track wander, the block 1.5 times longer than
wide and as large as the sample count asks (1e7 samples: 390 lines of 117 km, 58 ties); the
field is 50,500 nT + a smooth random anomaly (a 50 m lattice of filtered noise, bilinear at the
samples, ~150 nT std) + a diurnal (sinusoids of 20-180 min) + a shift and a trend per line + 0.03
nT noise; time is UTC seconds since 1970 (the survey lasts n / 10 s, 11.6 days for 1e7).  Files:
``survey_N.parquet`` (time, lat, lon, alt, line, mag: float64) and ``base_N.csv`` (time, mag at
1 Hz).  Then the two commands run in a child process each, exactly as a user types them::

    aeromag level survey_N.parquet --base base_N.csv --decorrugate -o lev_N.parquet
    aeromag grid lev_N.parquet -o grid_N.nc --cell C        (C: about 640,000 cells)

(IGRF removed: the synthetic field has no IGRF in it, so ``tmi`` carries the IGRF's gradient
over the block; that changes nothing of the work.)  For each run the script prints the wall
time, the child's CPU (user + sys) and its peak resident memory (``os.wait4``'s
``ru_maxrss`` of that child alone), the input's size in memory (6 float64 columns, 48 bytes
per sample) and the peak above the import baseline as a multiple of it, and the load average.
The baseline is the peak RSS of a child that only imports what the command imports.

``--profile N`` instead runs ``aeromag level``'s steps in this process on survey_N and prints
each step's CPU time (``time.process_time``) and the peak RSS reached in it (VmHWM, reset
before each step through /proc/self/clear_refs).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

GEN_VERSION = 2
ORIGIN = (-20.0, 140.0)  # south-west corner of the block, deg (UTM zone 54 S)
STEP_M = 5.0  # 50 m/s at 10 Hz
RATE_HZ = 10.0
SPACING_M = 200.0
TIE_SPACING_M = 2000.0
T0 = 1_414_890_000.0  # 2014-11-02 01:00 UTC
TARGET_CELLS = 640_000
ROW_GROUP = 1024 * 1024
PAD_M = 1000.0  # the anomaly lattice reaches this far beyond the block (run-ins, turns)


# --------------------------------------------------------------------------- the generator
def _block(n: int) -> tuple[float, float, int, int]:
    """Width (north-south), length (east-west) [m], lines and ties for about n samples."""
    # samples = (lines * length + ties * width) / step, lines = width / spacing,
    # ties = length / tie spacing, length = 1.5 width
    area = n * STEP_M / (1.0 / SPACING_M + 1.0 / TIE_SPACING_M)
    width = math.sqrt(area / 1.5)
    length = 1.5 * width
    return width, length, int(round(width / SPACING_M)) + 1, int(length // TIE_SPACING_M)


def _anomaly_lattice(rng: np.random.Generator, width: float, length: float
                     ) -> tuple[np.ndarray, float]:
    """A smooth random anomaly on a 50 m lattice (noise filtered to ~1-10 km) [nT]."""
    h = 50.0
    ny, nx = int((width + 2 * PAD_M) / h) + 2, int((length + 2 * PAD_M) / h) + 2
    white = rng.standard_normal((ny, nx)).astype(np.float32)
    ky = np.fft.rfftfreq(nx, h)[None, :]
    kx = np.fft.fftfreq(ny, h)[:, None]
    k = np.hypot(kx, ky)
    spec = np.fft.rfft2(white) * (np.exp(-(k * 1500.0) ** 2) * (1.0 - np.exp(-(k * 8000.0) ** 2)))
    field = np.fft.irfft2(spec, s=(ny, nx)).astype(np.float32)
    field *= 150.0 / field.std()
    return field, h


def _bilinear(lat: np.ndarray, east: np.ndarray, north: np.ndarray, h: float) -> np.ndarray:
    fx, fy = (east + PAD_M) / h, (north + PAD_M) / h
    i, j = np.floor(fx).astype(np.int64), np.floor(fy).astype(np.int64)
    tx, ty = fx - i, fy - j
    return ((1 - tx) * (1 - ty) * lat[j, i] + tx * (1 - ty) * lat[j, i + 1]
            + (1 - tx) * ty * lat[j + 1, i] + tx * ty * lat[j + 1, i + 1])


def _diurnal(t: np.ndarray, rng_state: tuple) -> np.ndarray:
    periods, amps, phases = rng_state
    return sum(a * np.sin(2 * np.pi * t / p + ph) for p, a, ph in zip(periods, amps, phases,
                                                                      strict=True))


def generate(n: int, folder: Path, seed: int = 7) -> tuple[Path, Path, dict]:
    """Write survey_N.parquet and base_N.csv (cached); return their paths and the plan."""
    import pyarrow as pa
    import pyarrow.parquet as pq
    from pyproj import Transformer

    folder.mkdir(parents=True, exist_ok=True)
    tag = f"{n:.0e}".replace("+0", "").replace("+", "")
    survey, base = folder / f"survey_{tag}.parquet", folder / f"base_{tag}.csv"
    meta = folder / f"survey_{tag}.json"
    if survey.is_file() and base.is_file() and meta.is_file():
        plan = json.loads(meta.read_text())
        if plan.get("version") == GEN_VERSION:
            return survey, base, plan
    rng = np.random.default_rng(seed)
    width, length, n_lines, n_ties = _block(n)
    lattice, h = _anomaly_lattice(rng, width, length)
    diurnal = (rng.uniform(20.0, 180.0, 4) * 60.0, 30.0 * rng.dirichlet(np.ones(4)),
               rng.uniform(0, 2 * np.pi, 4))
    utm = Transformer.from_crs("EPSG:4326", "EPSG:32754", always_xy=True)
    e0, n0 = utm.transform(ORIGIN[1], ORIGIN[0])
    back = Transformer.from_crs("EPSG:32754", "EPSG:4326", always_xy=True)
    schema = pa.schema([(c, pa.float64()) for c in ("time", "lat", "lon", "alt", "line", "mag")])
    tracks = [("line", 1000 + i, i * SPACING_M) for i in range(n_lines)]
    tracks += [("tie", 9000 + j, (j + 0.5) * TIE_SPACING_M) for j in range(n_ties)]
    t = T0
    run_in = 15.0 * 50.0  # 15 s of run-in, m
    total = 0
    pending: list = []
    tmp = survey.with_suffix(".tmp")
    with pq.ParquetWriter(tmp, schema) as w:
        for k, (kind, num, fixed) in enumerate(tracks):
            span = length if kind == "line" else width
            s = np.arange(-run_in, span + run_in, STEP_M)
            forward = k % 2 == 0
            along = s if forward else span - s
            ph = rng.uniform(0, 2 * np.pi, 3)
            ramp = (np.clip(-s / run_in, 0, None) ** 2 + np.clip((s - span) / run_in, 0, None) ** 2)
            wander = sum(4.0 * np.sin(2 * np.pi * s / (p * 50.0) + q)
                         for p, q in zip((37.0, 71.0, 113.0), ph, strict=True))
            cross = fixed + 150.0 * ramp + wander
            east, north = (along, cross) if kind == "line" else (cross, along)
            tt = t + np.arange(s.size) / RATE_HZ
            shift = rng.normal(0, 6.0 if kind == "line" else 2.0)
            trend = rng.normal(0, 4.0) if kind == "line" else 0.0
            mag = (50_500.0 + _bilinear(lattice, east, north, h) + _diurnal(tt, diurnal)
                   + shift + trend * (s / span - 0.5) + rng.normal(0, 0.03, s.size))
            lon, lat = back.transform(e0 + east, n0 + north)
            alt = 280.0 + (5.0 if kind == "tie" else 0.0) + rng.normal(0, 1.0, s.size)
            pending.append(pa.table({"time": tt, "lat": np.asarray(lat),
                                     "lon": np.asarray(lon), "alt": alt,
                                     "line": np.full(s.size, float(num)), "mag": mag},
                                    schema=schema))
            total += s.size
            if sum(len(p) for p in pending) >= ROW_GROUP or k == len(tracks) - 1:
                # row groups of pyarrow's default length, as aeromag writes them
                w.write_table(pa.concat_tables(pending), row_group_size=ROW_GROUP)
                pending = []
            t = tt[-1] + 60.0  # a one-minute turn without samples
    tmp.replace(survey)
    tb = np.arange(np.floor(T0) - 600.0, t + 600.0, 1.0)
    bm = 50_480.0 + _diurnal(tb, diurnal) + rng.normal(0, 0.05, tb.size)
    with base.open("w") as f:
        f.write("time,mag\n")
        np.savetxt(f, np.column_stack([tb, bm]), fmt=["%.1f", "%.3f"], delimiter=",")
    plan = {"version": GEN_VERSION, "n": total, "lines": n_lines, "ties": n_ties,
            "width_m": width, "length_m": length}
    meta.write_text(json.dumps(plan))
    return survey, base, plan


# --------------------------------------------------------------------------- measuring
def measured(cmd: list[str]) -> dict:
    """``run_child`` with the child's own CPU and peak RSS (os.wait4)."""
    t0 = time.perf_counter()
    with open(os.devnull, "w") as null, subprocess.Popen(
            cmd, stdout=null, stderr=subprocess.PIPE, text=True) as p:
        err = p.stderr.read() if p.stderr else ""
        _, status, ru = os.wait4(p.pid, 0)
        p.returncode = os.waitstatus_to_exitcode(status)
    wall = time.perf_counter() - t0
    return {"wall_s": wall, "cpu_s": ru.ru_utime + ru.ru_stime, "peak_mib": ru.ru_maxrss / 1024,
            "rc": p.returncode, "stderr": err[-3000:]}


IMPORTS = {
    "level": "import aeromag.cli, aeromag.workflows.level, aeromag.survey.chain, "
             "pyarrow.parquet",
    "grid": "import aeromag.cli, aeromag.workflows.grid, aeromag.survey.grids, verde, "
            "h5netcdf, pyarrow.parquet",
}


def baseline(kind: str) -> float:
    """Peak RSS [MiB] of a child that only imports what the command imports."""
    return measured([sys.executable, "-c", IMPORTS[kind]])["peak_mib"]


def cell_for(plan: dict) -> float:
    """A cell (whole metres) giving about TARGET_CELLS cells over the block."""
    return float(round(math.sqrt(plan["width_m"] * plan["length_m"] / TARGET_CELLS)))


def bench(sizes: list[int], folder: Path, grid: bool) -> None:
    aeromag = [sys.executable, "-m", "aeromag"]
    base_mib = {k: baseline(k) for k in (("level", "grid") if grid else ("level",))}
    print("import baselines (peak RSS of the imports alone): "
          + ", ".join(f"{k} {v:.0f} MiB" for k, v in base_mib.items()))
    print("| samples | command | wall | CPU | peak RSS | above imports | data (6 x f64) |"
          " multiple | load avg |")
    print("|---|---|---|---|---|---|---|---|---|")
    for n in sizes:
        t0 = time.perf_counter()
        survey, base, plan = generate(n, folder)
        gen = time.perf_counter() - t0
        if gen > 1:
            print(f"(generated {plan['n']:,} samples in {gen:.0f} s: {plan['lines']} lines of"
                  f" {plan['length_m'] / 1e3:.0f} km, {plan['ties']} ties)")
        data_mib = plan["n"] * 6 * 8 / 2**20
        lev = survey.with_name(survey.stem.replace("survey", "lev") + ".parquet")
        runs = [("level", aeromag + ["level", str(survey), "--base", str(base), "--decorrugate",
                                     "-o", str(lev), "--no-progress"])]
        if grid:
            cell = cell_for(plan)
            gpath = lev.with_name(lev.stem.replace("lev", "grid") + ".nc")
            runs.append(("grid", aeromag + ["grid", str(lev), "-o", str(gpath), "--cell",
                                            f"{cell:g}"]))
        for kind, cmd in runs:
            load = os.getloadavg()[0]
            r = measured(cmd)
            if r["rc"]:
                raise SystemExit(f"{' '.join(cmd)} failed:\n{r['stderr']}")
            extra = ""
            if kind == "grid":
                doc = json.loads(gpath.with_suffix(".json").read_text())
                extra = (f" ({doc['shape'][0] * doc['shape'][1]:,} cells of {cell:g} m,"
                         f" {doc['n_blocks']:,} blocks)")
            above = r["peak_mib"] - base_mib[kind]
            print(f"| {plan['n']:,} | {kind}{extra} | {r['wall_s']:.1f} s | {r['cpu_s']:.1f} s |"
                  f" {r['peak_mib']:.0f} MiB | {above:.0f} MiB | {data_mib:.0f} MiB |"
                  f" {above / data_mib:.1f} | {load:.1f} |", flush=True)


# --------------------------------------------------------------------------- profiling
def _hwm_mib() -> tuple[float, float]:
    rss = hwm = float("nan")
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                rss = int(line.split()[1]) / 1024
            elif line.startswith("VmHWM:"):
                hwm = int(line.split()[1]) / 1024
    return rss, hwm


def _reset_hwm() -> None:
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    except OSError:  # pragma: no cover - not Linux
        pass


def profile(n: int, folder: Path) -> None:
    """``aeromag level``'s steps in this process: CPU and peak RSS per step."""
    import aeromag.survey.chain as chain_mod
    from aeromag.io import read_log
    from aeromag.workflows.level import base_record

    survey, base, plan = generate(n, folder)
    print(f"profile of aeromag level on {plan['n']:,} samples (CPU s, peak RSS MiB per step)")
    rows = []
    last = {"cpu": time.process_time(), "wall": time.perf_counter()}

    def mark(step: str) -> None:
        rss, hwm = _hwm_mib()
        cpu, wall = time.process_time(), time.perf_counter()
        rows.append((step, cpu - last["cpu"], wall - last["wall"], rss, hwm))
        last.update(cpu=cpu, wall=wall)
        _reset_hwm()

    _reset_hwm()
    mark("imports")
    df = read_log(survey, required=())
    mark("read")
    rec = base_record(str(base))
    names: list[str] = []

    def progress(done: int, total: int, step: str) -> None:
        mark(names[-1] if names else "checks")
        names.append(step)

    res = chain_mod.level_survey(df, base=rec, decorrugate_lines=True, progress=progress)
    rep = res.to_report()
    mark("report")
    from aeromag.io.formats import write_table

    write_table(res.data, folder / "profile_out.parquet", "parquet")
    mark("write")
    print(f"{'step':12s} {'CPU s':>7s} {'wall s':>7s} {'RSS after':>10s} {'peak in':>8s}")
    for step, cpu, wall, rss, hwm in rows:
        print(f"{step:12s} {cpu:7.2f} {wall:7.2f} {rss:10.0f} {hwm:8.0f}")
    print(f"crossings {rep['n_crossovers']}, mistie std {rep['mistie_std_nT']}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="1e6,3e6,1e7", help="sample counts, comma-separated")
    ap.add_argument("--keep", type=Path, default=Path("/tmp/aeromag_bench_scale"))
    ap.add_argument("--no-grid", action="store_true", help="only aeromag level")
    ap.add_argument("--profile", type=float, help="profile level's steps on this size")
    args = ap.parse_args()
    if args.profile:
        profile(int(args.profile), args.keep)
        return
    bench([int(float(s)) for s in args.sizes.split(",")], args.keep, not args.no_grid)


if __name__ == "__main__":
    main()
