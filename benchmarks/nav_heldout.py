"""Held-out GNSS scores of ``aeromag navigate`` on the real PX4 optical-flow flight.

``benchmarks/nav_real_flight.py`` scores ``--gps use`` against the very fixes the filter
fused, which is not an independent check.  Here GNSS fixes are withheld from the filter
(position and velocity blanked in the log) and the estimate is scored only on the withheld
ones:

- ``alt2``: every 2nd fix withheld (5 Hz log: a withheld fix is 0.2 s from a fused one, so
  this still flatters when the receiver's error is correlated over seconds);
- ``blk10``: alternate 10-s blocks withheld (dead reckoning on flow for up to 10 s);
- ``outage``: the 30-s outage 247.6:277.6 s, all its fixes scored.

Per case: horizontal rms to the withheld fixes, the fraction of withheld fixes (per axis n, e)
whose error is inside the filter's own ``nav_std_*`` (a calibrated filter: about 68 % once
the GNSS's own scatter is included; ``cov1`` uses ``nav_std`` alone, ``cov1+g`` adds the
configured GNSS sigma in quadrature), the fused GNSS position's NIS per dof, the adaptive
variance scale the GNSS position ended with; with and without ``gps_walk_m_rt_s``.

Usage: ``python benchmarks/nav_heldout.py [--csv PATH]``.  About 1 minute.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np
import pandas as pd

from aeromag._core.geodesy import geodetic_to_ned
from aeromag.nav import NavConfig
from aeromag.workflows.navigate import navigate_frame

CSV = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real" / "flights" / (
    "px4_optical_flow.csv")
GNSS_COLS = ["lat", "lon", "alt", "vel_n", "vel_e", "vel_d"]


def withheld_rows(df: pd.DataFrame, case: str) -> np.ndarray:
    """Rows of the GNSS fixes withheld in ``case`` (``alt2``, ``blk10`` or ``outage``)."""
    t = df["time"].to_numpy(float)
    fix = np.flatnonzero(df[["lat", "lon", "alt"]].notna().all(axis=1).to_numpy())
    if case == "alt2":
        return fix[1::2]
    if case == "blk10":
        k = np.floor((t[fix] - t[fix[0]]) / 10.0).astype(int)
        return fix[k % 2 == 1]
    return fix[(t[fix] >= 247.6) & (t[fix] < 277.6)]


def score(df: pd.DataFrame, case: str, walk: float) -> dict[str, float]:
    """Run with the fixes of ``case`` withheld; errors and coverage on them."""
    held = withheld_rows(df, case)
    d = df.copy()
    d.loc[d.index[held], GNSS_COLS] = np.nan
    cfg = NavConfig(gps_walk_m_rt_s=walk)
    res = navigate_frame(d, gps="use", config=cfg, source="px4_optical_flow.csv")
    org = tuple(res.report.gps["origin"])
    g = geodetic_to_ned(df["lat"].to_numpy(float)[held], df["lon"].to_numpy(float)[held],
                        df["alt"].to_numpy(float)[held], org)
    e = res.data[["nav_n_m", "nav_e_m"]].to_numpy(float)[held] - g[:, :2]
    sd = res.data[["nav_std_n_m", "nav_std_e_m"]].to_numpy(float)[held]
    sg = cfg.gps_cep_m / 1.1774
    st = res.report.innovations["gps_pos"]
    return {"n": held.size,
            "rms": float(np.sqrt(np.mean(np.sum(e**2, axis=1)))),
            "end": float(np.linalg.norm(e[-1])),
            "cov1": float(np.mean(np.abs(e) <= sd)),
            "cov1g": float(np.mean(np.abs(e) <= np.sqrt(sd**2 + sg**2))),
            "cov3g": float(np.mean(np.abs(e) <= 3 * np.sqrt(sd**2 + sg**2))),
            "std": float(np.median(np.hypot(sd[:, 0], sd[:, 1]))),
            "nis": st["mean_nis_per_dof"], "down": st["n_downweighted"],
            "fused": st["n_fused"],
            "scale": res.report.settings["noise_used"].get("gps_pos_variance_scale",
                                                              float("nan"))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--csv", default=str(CSV))
    a = ap.parse_args()
    logging.basicConfig(level=logging.ERROR)
    df = pd.read_csv(a.csv)
    print(f"{'case':<8}{'walk':>5}{'n':>5}{'rms m':>7}{'end m':>7}{'cov1':>6}{'cov1+g':>7}"
          f"{'cov3+g':>7}{'med std':>8}{'gpsNIS':>7}{'down':>5}{'scale':>7}")
    for case in ("alt2", "blk10", "outage"):
        for walk in (0.3, 0.0):
            s = score(df, case, walk)
            print(f"{case:<8}{walk:>5.1f}{s['n']:>5}{s['rms']:>7.2f}{s['end']:>7.2f}"
                  f"{s['cov1']:>6.2f}{s['cov1g']:>7.2f}{s['cov3g']:>7.2f}{s['std']:>8.2f}"
                  f"{s['nis']:>7.2f}{s['down']:>5}{s['scale']:>7.2f}")


if __name__ == "__main__":
    main()
