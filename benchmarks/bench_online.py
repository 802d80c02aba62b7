"""Speed of the online estimators (samples per second), 1e5 and 1e6 samples.

- ``rls-vector``: the RLS kernel alone, the 12-parameter vector form (4 x 4 covariance, three
  outputs), batched ``run``;
- ``compass``: :func:`aeromag.compass.calibrate_compass` end to end (reference rotated into
  body axes, the estimate, the calibrated field, heading, its error, excitation windows);
- ``online-tl``: :class:`aeromag.compensation.online.OnlineTL` (16 terms: design matrix,
  causal band-pass, RLS, coefficient low-pass, ``mag_tl``);
- ``rls-nostd``, ``tl-nostd``: the same without the per-sample parameter std
  (``std=False``, ``coef_std=False``: what ``compensate --online`` runs);
- ``rls-step``: the streaming step form, for comparison (2e4 samples).

Usage: ``python benchmarks/bench_online.py [--sizes 1e5 1e6] [--repeat 2]``.  The best of
``--repeat`` runs is reported.  Data come from the project's simulators (not timed).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from aeromag._core.rls import RecursiveLeastSquares
from aeromag.compass import calibrate_compass
from aeromag.compensation.online import OnlineTL
from aeromag.synthetic.compass import simulate_compass
from aeromag.synthetic.online_tl import simulate_online_tl


def _best(fn, repeat: int) -> tuple[float, float]:
    """Best wall-clock and best CPU time of ``repeat`` runs [s] (on a shared machine the CPU
    time of this process is the better guide: other processes do not inflate it)."""
    wall = cpu = np.inf
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall = min(wall, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
    return wall, cpu


def _row(name: str, n: int, times: tuple[float, float]) -> None:
    w, c = times
    print(f"{name:<12} {n:>9d} {w:>8.3f} {n / w:>12,.0f} {c:>8.3f} {n / c:>12,.0f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", nargs="+", type=float, default=[1e5, 1e6])
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    print(f"{'case':<12} {'samples':>9} {'wall s':>8} {'samples/s':>12} {'cpu s':>8} "
          f"{'per cpu s':>12}")
    for size in args.sizes:
        n = int(size)
        log, truth = simulate_compass(duration_s=n / 50.0, amplitude_deg=40.0)
        flux = log[["flux_x", "flux_y", "flux_z"]].to_numpy()
        b = log[["truth_bx", "truth_by", "truth_bz"]].to_numpy()
        phi = np.column_stack([flux / 54000.0, np.ones(n)])
        y = b / 54000.0
        cols = [log[c].to_numpy() for c in ("heading", "pitch", "roll")]
        ref = np.array(truth["earth_ned_nT"])
        tt = log["time"].to_numpy()
        cases = {
            "rls-vector": lambda phi=phi, y=y: RecursiveLeastSquares(
                4, 3, forgetting=0.975, alpha=1e4).run(y, phi),
            "rls-nostd": lambda phi=phi, y=y: RecursiveLeastSquares(
                4, 3, forgetting=0.975, alpha=1e4).run(y, phi, std=False),
            "compass": lambda flux=flux, cols=cols, ref=ref, tt=tt: calibrate_compass(
                flux, *cols, ref, time_s=tt, forgetting=0.975),
        }
        for name, fn in cases.items():
            _row(name, n, _best(fn, args.repeat))
        del log, flux, b, phi, y
        tl, _ = simulate_online_tl(duration_s=n / 10.0, jump_s=n / 20.0, line_s=120.0,
                                   oversample=1)  # timing only: no need for true rates
        t = tl["time"].to_numpy()
        fx = tl[["flux_x", "flux_y", "flux_z"]].to_numpy()
        mag = tl["mag"].to_numpy()
        u = np.column_stack([t, fx])
        _row("online-tl", n, _best(lambda u=u, mag=mag: OnlineTL(
            10.0, forgetting=0.999).run(mag, u), args.repeat))
        _row("tl-nostd", n, _best(lambda u=u, mag=mag: OnlineTL(
            10.0, forgetting=0.999, coef_std=False).run(mag, u), args.repeat))
    m = 20000
    phi = np.column_stack([np.random.default_rng(0).normal(size=(m, 3)), np.ones(m)])
    y = phi @ np.ones((4, 3))
    est = RecursiveLeastSquares(4, 3, forgetting=0.975, alpha=1e4)

    def steps() -> None:
        for p, q in zip(phi, y, strict=True):
            est.step(q, p)

    _row("rls-step", m, _best(steps, 1))


if __name__ == "__main__":
    main()
