"""The navigation study's figures on the quadrotor simulator (numbers for docs/navigate.md).

For each scenario (60 s hover at 2 m, 60 s rectangle at 1.5 m/s), over ``--seeds`` runs:
mean horizontal position error (displacement since the start), mean horizontal velocity
error, the IMU-only error at 60 s, for the study's 12-state model and the default with
accelerometer biases; then the NEES (time-mean of the average over runs at 1 Hz epochs
after 2 s) for position, velocity and attitude, against the two-sided chi-square 95 % band.

Usage: ``python benchmarks/study_navigate.py [--seeds 3]``.
"""

from __future__ import annotations

import argparse
import logging

import numpy as np
from scipy.stats import chi2

from aeromag._core.geodesy import geodetic_to_ned
from aeromag.nav import NavConfig, NavFilter, NavInputs, navigate
from aeromag.synthetic.quadrotor import FIELD_NED_NT, simulate_quadrotor

REF = np.array(FIELD_NED_NT)


def _errors(fl, d):
    t = fl.truth
    k0 = int(np.flatnonzero(np.isfinite(fl.log["gyro_x"].to_numpy()))[0])
    est = d[["nav_n_m", "nav_e_m"]].to_numpy()
    tru = t[["n_m", "e_m"]].to_numpy()
    e_pos = np.hypot(*((est - est[k0]) - (tru - tru[k0])).T)
    e_vel = np.hypot(*(d[["nav_vn", "nav_ve"]].to_numpy() - t[["vn_ms", "ve_ms"]].to_numpy()).T)
    return e_pos, e_vel


def _nees(fl, accel_bias: bool) -> dict[str, np.ndarray]:
    L, T = fl.log, fl.truth
    g = L[["lat", "lon", "alt"]].to_numpy()
    fix = np.isfinite(g).all(axis=1)
    i_fix = int(np.flatnonzero(fix)[0])
    origin = tuple(g[i_fix])
    ned = np.full((len(L), 3), np.nan)
    ned[fix] = geodetic_to_ned(g[fix, 0], g[fix, 1], g[fix, 2], origin)
    inp = NavInputs(
        time_s=L.time.to_numpy(), gyro=L[["gyro_x", "gyro_y", "gyro_z"]].to_numpy(),
        acc=L[["acc_x", "acc_y", "acc_z"]].to_numpy(), flow=L[["flow_x", "flow_y"]].to_numpy(),
        flow_quality=L.flow_quality.to_numpy(), range_m=L.range_m.to_numpy(),
        baro_alt=L.baro_alt.to_numpy(), flux=L[["flux_x", "flux_y", "flux_z"]].to_numpy(),
        gps_ned=ned, gps_use=np.arange(len(L)) == i_fix)
    res = NavFilter(NavConfig(accel_bias=accel_bias), REF).run(inp, keep_cov=True)
    tru = np.c_[geodetic_to_ned(T.lat.to_numpy(), T.lon.to_numpy(), T.alt.to_numpy(), origin),
                T[["vn_ms", "ve_ms", "vd_ms"]].to_numpy(),
                np.deg2rad(T[["roll_deg", "pitch_deg", "yaw_deg"]].to_numpy())]
    idx = res.info["cov_index"]
    te = res.time_s[idx]
    keep = np.r_[True, np.diff(np.floor(te)) > 0] & (te > 2.0)
    e = res.state[idx[keep], :9] - tru[idx[keep]]
    e[:, 6:9] = np.mod(e[:, 6:9] + np.pi, 2 * np.pi) - np.pi
    out = {}
    for name, sel in (("position", [0, 1, 2]), ("velocity", [3, 4, 5]),
                      ("attitude", [6, 7, 8]), ("all 9", list(range(9)))):
        P = res.info["cov"][keep][:, sel][:, :, sel]
        ee = e[:, sel]
        out[name] = np.einsum("ki,ki->k", ee, np.linalg.solve(P, ee[..., None])[..., 0])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    args = ap.parse_args()
    logging.basicConfig(level=logging.ERROR)
    for scenario in ("hover", "rectangle"):
        for ab in (False, True):
            rows = []
            for seed in range(args.seeds):
                fl = simulate_quadrotor(scenario, seed=seed)
                cfg = NavConfig(accel_bias=ab)
                d = navigate(fl.log, gps="none", mag_reference_ned_nT=REF, config=cfg).data
                ep, ev = _errors(fl, d)
                di = navigate(fl.log, gps="none", mag_reference_ned_nT=REF, config=cfg,
                              sensors=()).data
                ei, _ = _errors(fl, di)
                # The IMU alone with its gyro biases known (removed): the accelerometer's
                # 0.05 m/s² bias and noise only, the case of the study's "about 90 m".
                lg = fl.log.copy()
                for j, c in enumerate(("gyro_x", "gyro_y", "gyro_z")):
                    lg[c] = lg[c] - fl.info["gyro_bias_rads"][j]
                fl_b = type(fl)(log=lg, truth=fl.truth, info=fl.info)
                db = navigate(lg, gps="none", mag_reference_ned_nT=REF, config=cfg,
                              sensors=()).data
                eb, _ = _errors(fl_b, db)
                rows.append((ep.mean(), ev.mean(), ep[-1], ei[-1], eb[-1]))
            r = np.array(rows)
            print(f"{scenario:9s} accel_bias={ab!s:5s}: pos {r[:, 0].mean():.3f} m "
                  f"(runs {np.round(r[:, 0], 3)}), vel {r[:, 1].mean():.3f} m/s, pos at 60 s "
                  f"{r[:, 2].mean():.3f} m, IMU-only at 60 s {r[:, 3].mean():.1f} m "
                  f"(ratio to mean error {r[:, 3].mean() / r[:, 0].mean():.0f}x); IMU-only with"
                  f" the gyro biases removed {r[:, 4].mean():.1f} m "
                  f"({r[:, 4].mean() / r[:, 0].mean():.0f}x)")
    for scenario in ("hover", "rectangle"):
        for ab in (False, True):
            runs = [_nees(simulate_quadrotor(scenario, seed=100 + s), ab)
                    for s in range(max(args.seeds, 5))]
            M = len(runs)
            for name in runs[0]:
                dof = {"all 9": 9}.get(name, 3)
                n = min(len(q[name]) for q in runs)
                anees = np.mean([q[name][:n] for q in runs], axis=0)
                lo, hi = chi2.ppf(0.025, dof * M) / M, chi2.ppf(0.975, dof * M) / M
                print(f"NEES {scenario:9s} accel_bias={ab!s:5s} {name:9s}: {anees.mean():6.2f}"
                      f" (dof {dof}; band {lo:.2f}-{hi:.2f}; {M} runs)")


if __name__ == "__main__":
    main()
