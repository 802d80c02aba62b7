"""Speed of the navigation filter: IMU samples per second on a 10-minute 250 Hz log.

The log is the quadrotor simulator's (the rectangle, then hover, with every sensor of the
study: IMU 250 Hz, magnetometer 50 Hz, flow, rangefinder and barometer 10 Hz, GNSS 5 Hz;
building it is not timed).  Cases:

- ``full``: :meth:`aeromag.nav.NavFilter.run` with the defaults (every IMU sample propagated,
  GNSS first fix only, flow, range, gravity, magnetometer fused);
- ``gps``: the same with every GNSS fix fused;
- ``imu-step``: IMU samples combined into 20 ms steps (``--imu-step 0.02``);
- ``navigate``: :func:`aeromag.nav.navigate` end to end on the DataFrame (column checks,
  GNSS to NED, the filter, the output columns).

Usage: ``python benchmarks/bench_navigate.py [--minutes 10] [--repeat 2]``.  Best of
``--repeat`` runs; wall-clock and this process's CPU time (the better guide on a shared
machine).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from aeromag._core.geodesy import geodetic_to_ned
from aeromag.nav import NavConfig, NavFilter, NavInputs, navigate
from aeromag.synthetic.quadrotor import FIELD_NED_NT, simulate_quadrotor


def _best(fn, repeat: int) -> tuple[float, float]:
    wall = cpu = np.inf
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall = min(wall, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
    return wall, cpu


def _inputs(log, all_fixes: bool) -> NavInputs:
    g = log[["lat", "lon", "alt"]].to_numpy()
    fix = np.isfinite(g).all(axis=1)
    i_fix = int(np.flatnonzero(fix)[0])
    ned = np.full((len(log), 3), np.nan)
    ned[fix] = geodetic_to_ned(g[fix, 0], g[fix, 1], g[fix, 2], tuple(g[i_fix]))
    use = fix.copy() if all_fixes else (np.arange(len(log)) == i_fix)
    return NavInputs(
        time_s=log.time.to_numpy(), gyro=log[["gyro_x", "gyro_y", "gyro_z"]].to_numpy(),
        acc=log[["acc_x", "acc_y", "acc_z"]].to_numpy(),
        flow=log[["flow_x", "flow_y"]].to_numpy(), flow_quality=log.flow_quality.to_numpy(),
        range_m=log.range_m.to_numpy(), baro_alt=log.baro_alt.to_numpy(),
        flux=log[["flux_x", "flux_y", "flux_z"]].to_numpy(), gps_ned=ned,
        gps_vel=log[["vel_n", "vel_e", "vel_d"]].to_numpy(), gps_use=use)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    fl = simulate_quadrotor("rectangle", duration_s=60.0 * args.minutes, seed=0,
                            fine_hz=1000.0)
    log = fl.log
    n_imu = int(np.isfinite(log["gyro_x"].to_numpy()).sum())
    ref = np.array(FIELD_NED_NT)
    inp1, inp_all = _inputs(log, False), _inputs(log, True)
    cases = {
        "full": lambda: NavFilter(NavConfig(), ref).run(inp1),
        "gps": lambda: NavFilter(NavConfig(), ref).run(inp_all),
        "imu-step": lambda: NavFilter(NavConfig(max_imu_step_s=0.02), ref).run(inp1),
        "navigate": lambda: navigate(log, gps="none", mag_reference_ned_nT=ref),
    }
    print(f"log: {args.minutes:g} min, {len(log)} rows, {n_imu} IMU samples (250 Hz)")
    print(f"{'case':10s} {'wall s':>8s} {'cpu s':>8s} {'IMU samples/s (cpu)':>20s}"
          f" {'1 h log, s (cpu)':>17s}")
    for name, fn in cases.items():
        wall, cpu = _best(fn, args.repeat)
        rate = n_imu / cpu
        print(f"{name:10s} {wall:8.2f} {cpu:8.2f} {rate:20.0f} {3600 * 250 / rate:17.0f}")


if __name__ == "__main__":
    main()
