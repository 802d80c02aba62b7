"""Monte-Carlo studies of the particle-filter library whose numbers go in docs/detect.md.

1. Growth model (methods M5): RMSE and run time of the bootstrap, genetic, unscented and
   unscented-genetic filters on the same runs (Q = 10 with N = 100 and 200; Q = 20 with
   N = 500; R = 1, T = 100).
2. Stirred-tank reactor: threshold from 200 fault-free runs (a percentile of the runs' maxima
   of S_k), its false-alarm rate on 200 independent fault-free runs, then 200 runs of each
   fault: detection rate, false alarms before the onset, detection delays and the bank's
   isolation.

Usage: python benchmarks/study_pf.py [--runs 200] [--growth-runs 100] [--percentile 100]
       [--skip-cstr] [--skip-growth] [--out FILE]
Prints a JSON summary (also written to benchmarks/study_pf.json unless --no-write).
"""

from __future__ import annotations

import argparse
import json
import time
from collections import Counter
from pathlib import Path

import numpy as np

from aeromag._core.particles import ParticleFilter
from aeromag.detection.benchmark_models import (
    cstr_detect_isolate,
    cstr_threshold,
    growth_model,
)
from aeromag.synthetic.benchmarks import simulate_cstr, simulate_growth

VARIANTS = {"PF": ("bootstrap", "systematic"), "GPF": ("bootstrap", "genetic"),
            "UPF": ("unscented", "systematic"), "UGPF": ("unscented", "genetic")}
STUDY = {(10.0, 100): {"PF": 2.67, "GPF": 2.25}, (10.0, 200): {"PF": 2.18, "GPF": 1.98},
         (20.0, 500): {"PF": 4.35, "GPF": 2.79}}


def growth_study(n_runs: int) -> list[dict]:
    rows = []
    for (q, n), published in STUDY.items():
        xs, ys = simulate_growth(T=100, Q=q, R=1.0, seed=7, n_runs=n_runs)
        md = growth_model(Q=q, R=1.0)
        for name, (prop, scheme) in VARIANTS.items():
            res = ParticleFilter(md, n, proposal=prop, scheme=scheme, batch=n_runs,
                                 seed=1).run(ys)
            rmse = np.sqrt(np.mean((res.state[..., 0] - xs) ** 2, axis=1))
            t0 = time.perf_counter()
            for s in range(5):        # time of one run, unbatched
                ParticleFilter(md, n, proposal=prop, scheme=scheme, seed=s).run(ys[s])
            per_run = (time.perf_counter() - t0) / 5
            rows.append({"Q": q, "N": n, "filter": name, "rmse_mean": float(rmse.mean()),
                         "rmse_median": float(np.median(rmse)),
                         "rmse_se": float(rmse.std(ddof=1) / np.sqrt(n_runs)),
                         "time_per_run_s": per_run, "published_rmse": published.get(name)})
            print(rows[-1], flush=True)
    return rows


def cstr_study(n_runs: int, n_particles: int = 300, window: int = 10,
               percentile: float = 99.0, fit: str = "empirical") -> dict:
    t0 = time.perf_counter()
    free = simulate_cstr(None, n_runs=n_runs, seed=100)
    th, _ = cstr_threshold(free.y, n_particles=n_particles, window=window,
                           percentile=percentile, seed=0, fit=fit)
    other = simulate_cstr(None, n_runs=n_runs, seed=101)
    _, stat2 = cstr_threshold(other.y, n_particles=n_particles, window=window, seed=1)
    far = float(np.mean(np.nanmax(stat2, axis=1) > th.value))
    out = {"runs": n_runs, "particles": n_particles, "window": window,
           "percentile": percentile, "fit": fit, "threshold": th.value,
           "false_alarm_rate_same_runs": th.false_alarm_rate,
           "false_alarm_rate_independent_runs": far, "faults": {}}
    print(out, flush=True)
    for k, fault in enumerate(("sensor_bias", "setpoint", "feed_flow")):
        run = simulate_cstr(fault, n_runs=n_runs, seed=200 + k)
        st = cstr_detect_isolate(run.y, run.time_min, run.onset_min, th.value,
                                 n_particles=n_particles, window=window, seed=10 + k)
        d = st.delay_min[np.isfinite(st.delay_min)]
        out["faults"][fault] = {
            "detected": float(st.detected.mean()),
            "false_alarm_before_onset": float(st.false_alarm.mean()),
            "delay_min_median": float(np.median(d)) if d.size else None,
            "delay_min_p95": float(np.percentile(d, 95)) if d.size else None,
            "delay_min_max": float(d.max()) if d.size else None,
            "isolated": dict(Counter(st.isolated)),
            "isolated_correctly": float(np.mean([s == fault for s in st.isolated])),
        }
        print(fault, out["faults"][fault], flush=True)
    out["elapsed_s"] = time.perf_counter() - t0
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--growth-runs", type=int, default=100)
    ap.add_argument("--percentile", type=float, default=100.0,
                    help="percentile of the fault-free runs' maxima of S_k (100: the largest)")
    ap.add_argument("--fit", default="empirical", choices=("empirical", "gumbel"),
                    help="percentile of the maxima themselves, or of a Gumbel law fitted to them")
    ap.add_argument("--skip-cstr", action="store_true")
    ap.add_argument("--skip-growth", action="store_true")
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--out", default=None, help="JSON summary path (default beside the script)")
    a = ap.parse_args()
    summary = {}
    if not a.skip_growth:
        summary["growth"] = growth_study(a.growth_runs)
    if not a.skip_cstr:
        summary["cstr"] = cstr_study(a.runs, percentile=a.percentile, fit=a.fit)
    text = json.dumps(summary, indent=2)
    print(text)
    if not a.no_write:
        Path(a.out or Path(__file__).with_suffix(".json")).write_text(text + "\n")


if __name__ == "__main__":
    main()
