"""Synthetic survey logs for the benchmarks (10 Hz, manoeuvres, 16-term interference)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

COEF16 = np.array([30, -20, 15, 40, -10, 8, 25, -5, 2, -1, 0.5, 1.5, -2, 0.8, -0.6, 1.0])


def make_log(n: int, fs: float = 10.0, seed: int = 0) -> pd.DataFrame:
    """A log of ``n`` samples: time [s], flux_x/y/z [nT], mag [nT], line, lat/lon/alt."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    psi = np.deg2rad((t // 60 % 4) * 90 + 5 * np.sin(2 * np.pi * t / 7.1))
    th = np.deg2rad(5 * np.sin(2 * np.pi * t / 5.3 + 1.0))
    ph = np.deg2rad(10 * np.sin(2 * np.pi * t / 3.1))
    inc = np.deg2rad(65.0)
    b = 50000.0 * np.array([np.cos(inc), 0.05, np.sin(inc)])
    cps, sps, cth, sth, cph, sph = np.cos(psi), np.sin(psi), np.cos(th), np.sin(th), np.cos(ph), \
        np.sin(ph)
    bx = cth * cps * b[0] + cth * sps * b[1] - sth * b[2]
    by = (sph * sth * cps - cph * sps) * b[0] + (sph * sth * sps + cph * cps) * b[1] \
        + sph * cth * b[2]
    bz = (cph * sth * cps + sph * sps) * b[0] + (cph * sth * sps - sph * cps) * b[1] \
        + cph * cth * b[2]
    B = np.column_stack([bx, by, bz])
    from aeromag.tolles_lawson import design_matrix

    h = design_matrix(B, t) @ COEF16
    mag = np.linalg.norm(B, axis=1) + h + rng.normal(0, 0.02, n)
    B += rng.normal(0, 0.5, (n, 3))
    return pd.DataFrame({"time": t, "lat": 45 + t * 1e-6, "lon": -75 + t * 1e-6,
                         "alt": 300 + rng.normal(0, 0.1, n), "flux_x": B[:, 0],
                         "flux_y": B[:, 1], "flux_z": B[:, 2], "mag": mag,
                         "line": (t // 60).astype(np.int64)})


def write_log(n: int, path: Path) -> Path:
    """Write ``make_log(n)`` to CSV (in blocks, so 1e7 rows fit)."""
    from aeromag.io import write_csv

    if path.exists():
        return path
    if n <= 2_000_000:
        return write_csv(make_log(n), path)
    import pyarrow as pa
    import pyarrow.csv as pacsv

    from aeromag.io import _floats_as_pandas_text

    block = 1_000_000
    with open(path, "wb") as fh:
        for i, a in enumerate(range(0, n, block)):
            df = make_log(min(block, n - a), seed=i)
            df["time"] += a / 10.0
            df["line"] += a // 600
            tb = _floats_as_pandas_text(pa.Table.from_pandas(df, preserve_index=False))
            if i == 0:
                fh.write((",".join(df.columns) + "\n").encode())
            pacsv.write_csv(tb, fh, pacsv.WriteOptions(include_header=False,
                                                       quoting_style="none"))
    return path
