"""aeromag navigate on the real PX4 optical-flow flight against a plain error-state EKF.

For ``--gps none``, ``use`` and a 30-s outage (247.6:277.6 s) it prints per sensor the
samples fused / down-weighted / rejected (and gated), the mean NIS per degree of freedom, and
the errors against the log's own GNSS (``tests.nav_reference.flight_metrics``: horizontal
velocity rms of 1-s means, position rms, 10-s displacement rms, the error at the end of the
outage), for aeromag and for the reference EKF of ``tests/nav_reference.py`` (PX4 EKF2
default noise, fixed gate).  Also the speed of aeromag's filter (rows per second).

Usage: ``python benchmarks/nav_real_flight.py [--csv PATH] [--no-reference]``.
Data: PX4 ECL EKF replay test data (BSD-3), ``shared/data/real/flights``.
"""

from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path

import numpy as np
import pandas as pd

try:
    from aeromag.workflows.navigate import navigate_frame
except ImportError:  # before issue 28
    from aeromag.nav import navigate as navigate_frame
from tests.nav_reference import flight_metrics, reference_ekf

CSV = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real" / "flights" / (
    "px4_optical_flow.csv")
MODES = (("none", "none"), ("use", "use"), ("outage", "247.6:277.6"))


def _gps_use(df: pd.DataFrame, mode: str) -> np.ndarray:
    fix = df[["lat", "lon", "alt"]].notna().all(axis=1).to_numpy()
    t = df["time"].to_numpy(float)
    if mode == "none":
        return np.zeros(len(df), bool)
    if mode == "use":
        return fix
    t0, t1 = (float(v) for v in mode.split(":"))
    return fix & ~((t >= t0) & (t < t1))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--csv", default=str(CSV))
    ap.add_argument("--no-reference", action="store_true")
    a = ap.parse_args()
    logging.basicConfig(level=logging.ERROR)
    df = pd.read_csv(a.csv)
    df.attrs["source"] = Path(a.csv).name
    print(f"{'case':<16}{'sensor':<9}{'fused':>7}{'down':>6}{'rej':>6}{'gated':>7}"
          f"{'NIS/dof':>9}")
    rows = []
    for label, mode in MODES:
        t0 = time.perf_counter()
        res = navigate_frame(df, gps=mode)
        el = time.perf_counter() - t0
        rep = res.report
        for k, s in rep.innovations.items():
            if s["n_fused"] + s["n_rejected"] + s["n_gated"] == 0:
                continue
            nis = s["mean_nis_per_dof"]
            print(f"{'aeromag ' + label:<16}{k:<9}{s['n_fused']:>7}{s.get('n_downweighted', 0):>6}"
                  f"{s['n_rejected']:>6}{s['n_gated']:>7}"
                  f"{(nis if nis is not None else float('nan')):>9.2f}")
        d = res.data
        m = flight_metrics(df, d[["nav_n_m", "nav_e_m", "nav_d_m"]].to_numpy(float),
                           d[["nav_vn", "nav_ve", "nav_vd"]].to_numpy(float))
        rows.append((f"aeromag {label}", m, len(df) / el))
        if not a.no_reference:
            decl = np.deg2rad(rep.reference_field["declination_deg"])
            t0 = time.perf_counter()
            ref = reference_ekf(df, _gps_use(df, mode), decl)
            el = time.perf_counter() - t0
            for k, s in ref.stats.items():
                if s.fused + s.rejected:
                    print(f"{'ref-EKF ' + label:<16}{k:<9}{s.fused:>7}{0:>6}{s.rejected:>6}"
                          f"{'':>7}{s.nis_per_dof:>9.2f}")
            rows.append((f"ref-EKF {label}", flight_metrics(df, ref.pos, ref.vel),
                         len(df) / el))
    print()
    print(f"{'case':<16}{'vel rms':>9}{'pos rms':>9}{'disp10':>9}{'outage':>9}{'rows/s':>9}")
    for name, m, sp in rows:
        print(f"{name:<16}{m['vel_rms']:>9.3f}{m['pos_rms']:>9.2f}{m['disp10_rms']:>9.2f}"
              f"{m['outage_end']:>9.2f}{sp:>9.0f}")


if __name__ == "__main__":
    main()
