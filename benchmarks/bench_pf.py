"""Speed of the particle filter: particles x steps per second, and the detector on a log.

1. The library on the growth model (one state) for each proposal and renewal scheme,
   N = 500 and 5000, unbatched.
2. ``particle_detector`` on a 10-minute 50 Hz log (30 000 rows: gyro_z and mag_heading)
   with 500 particles, for the default unscented-genetic filter and the bootstrap.

Usage: python benchmarks/bench_pf.py [--quick] [--detector-only]

Wall time on a shared machine depends on its load; the CPU time of the process is given too.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import pandas as pd

from aeromag._core.particles import ParticleFilter
from aeromag.detection.benchmark_models import growth_model
from aeromag.detection.particle import particle_detector
from aeromag.synthetic.benchmarks import simulate_growth


def log_50hz(minutes: float = 10.0, fs: float = 50.0, seed: int = 0) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, minutes * 60.0, 1.0 / fs)
    rate = 0.3 * np.sin(2 * np.pi * t / 40.0)
    psi = np.cumsum(rate) / fs
    mag = np.rad2deg(psi) + 2.0 * rng.standard_normal(t.size)
    return pd.DataFrame({"time": t, "gyro_z": rate, "mag_heading": np.mod(mag, 360.0)})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="2-minute log")
    ap.add_argument("--detector-only", action="store_true", help="skip the library part")
    a = ap.parse_args()
    out: dict = {"library": [], "detector": []}
    _, y = simulate_growth(T=400, seed=0)
    md = growth_model()
    for n in () if a.detector_only else (500, 5000):
        for prop in ("bootstrap", "unscented"):
            for scheme in ("systematic", "genetic"):
                pf = ParticleFilter(md, n, proposal=prop, scheme=scheme, seed=0)
                t0 = time.perf_counter()
                pf.run(y)
                dt = time.perf_counter() - t0
                row = {"N": n, "proposal": prop, "scheme": scheme, "steps": y.size,
                       "seconds": dt, "particle_steps_per_s": n * y.size / dt}
                out["library"].append(row)
                print(row, flush=True)
    df = log_50hz(2.0 if a.quick else 10.0)
    for prop, scheme in (("unscented", "genetic"), ("bootstrap", "systematic")):
        t0, c0 = time.perf_counter(), time.process_time()
        res = particle_detector(df, n_particles=500, proposal=prop, scheme=scheme)
        dt, cpu = time.perf_counter() - t0, time.process_time() - c0
        row = {"rows": len(df), "particles": 500, "proposal": prop, "scheme": scheme,
               "seconds": dt, "cpu_seconds": cpu, "particle_steps_per_s": 500 * len(df) / dt,
               "alarms": int(res.alarm.sum())}
        out["detector"].append(row)
        print(row, flush=True)
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
