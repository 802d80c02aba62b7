"""Speed of the track check: leg assignment (evidence + Viterbi) and the whole check_track.

Run by hand: ``python benchmarks/bench_track.py [--hours H]``.  A simulated lawn-mower mission
(10 Hz) is repeated to the requested length; a 1 kHz copy shows the block decoding (the
evidence is decoded at no more than 10 Hz).  Prints seconds and samples per second.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pandas as pd

from aeromag._core.geodesy import geodetic_to_ned
from aeromag.synthetic.mission import simulate_mission
from aeromag.track import check_track
from aeromag.track.legs import LegModel, decode_legs, leg_evidence, motion_velocity


def _session(hours: float) -> tuple[pd.DataFrame, pd.DataFrame]:
    df, plan, _ = simulate_mission(seed=0)
    span = float(df["time"].iloc[-1]) + 0.1
    reps = max(1, int(np.ceil(hours * 3600.0 / span)))
    parts = [df.assign(time=df["time"] + k * span) for k in range(reps)]
    return pd.concat(parts, ignore_index=True), plan


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--hours", type=float, default=1.0, help="log length, hours at 10 Hz")
    args = ap.parse_args()
    log, plan = _session(args.hours)
    o = tuple(float(plan[c].iloc[0]) for c in ("lat", "lon", "alt"))
    wps = geodetic_to_ned(plan["lat"], plan["lon"], plan["alt"], o)
    ned = geodetic_to_ned(log["lat"], log["lon"], log["alt"], o)
    t = log["time"].to_numpy()
    m = LegModel()
    t0 = time.perf_counter()
    ev = leg_evidence(ned, motion_velocity(t, ned), wps, m)
    t1 = time.perf_counter()
    decode_legs(ev, t, m)
    t2 = time.perf_counter()
    check_track(log, plan)
    t3 = time.perf_counter()
    n = len(log)
    print(f"{n} samples at 10 Hz, {len(wps) - 1} legs")
    print(f"  evidence   {t1 - t0:7.2f} s  ({n / (t1 - t0):,.0f} samples/s)")
    print(f"  viterbi    {t2 - t1:7.2f} s  ({n / (t2 - t1):,.0f} samples/s)")
    print(f"  check_track{t3 - t2:7.2f} s  ({n / (t3 - t2):,.0f} samples/s)")
    # the same minutes at 1 kHz: decoded in 0.1 s blocks
    short = log[log["time"] < 600.0]
    tt = np.arange(float(short["time"].iloc[0]), float(short["time"].iloc[-1]), 0.001)
    hi = pd.DataFrame({"time": tt, **{c: np.interp(tt, short["time"], short[c])
                                      for c in ("lat", "lon", "alt")}})
    t0 = time.perf_counter()
    check_track(hi, plan)
    t1 = time.perf_counter()
    print(f"{len(hi)} samples at 1 kHz: check_track {t1 - t0:.2f} s"
          f" ({len(hi) / (t1 - t0):,.0f} samples/s)")


if __name__ == "__main__":
    main()
