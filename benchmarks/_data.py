"""Synthetic logs for the benchmarks: box headings, attitude oscillations, 16-term interference.

Independent of aeromag's fitting code (the 16 terms are written out here, as in
``interface.md``), so the benchmark data do not move when the package does.  Files are written
block by block with pyarrow and cached: a file that exists is reused.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

COEF16 = np.array([30, -20, 15, 40, -10, 8, 25, -5, 2, -1, 0.5, 1.5, -2, 0.8, -0.6, 1.0])
COLUMNS = ("time", "lat", "lon", "alt", "flux_x", "flux_y", "flux_z", "mag", "line")
LINE_S = 60.0  # one line (segment) per 60 s heading leg
TURN_S = 10.0  # ... whose last 10 s turn smoothly by 90 deg to the next heading


def _terms16(b: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The 16 TL terms of a body-frame field ``b`` [nT] sampled at times ``t`` [s]."""
    bt = np.linalg.norm(b, axis=1)
    c = b / bt[:, None]
    d = np.gradient(c, t, axis=0)
    s = bt / 50000.0
    cx, cy, cz = c.T
    dx, dy, dz = d.T
    return np.column_stack([
        cx, cy, cz,
        s * cx * cx, s * cx * cy, s * cx * cz, s * cy * cy, s * cy * cz,
        s * cx * dx, s * cx * dy, s * cx * dz, s * cy * dx, s * cy * dy, s * cy * dz,
        s * cz * dx, s * cz * dy,
    ])


def make_log(n: int, fs: float = 10.0, seed: int = 0, t0: float = 0.0) -> pd.DataFrame:
    """A log of ``n`` samples at ``fs`` Hz starting at ``t0`` s.

    Columns: ``time`` [s], ``lat``/``lon`` [deg], ``alt`` [m], ``flux_x/y/z`` [nT], ``mag``
    [nT], ``line`` (one per 60 s leg; legs on the four cardinal headings with yaw, pitch and
    roll oscillations of 7.1, 5.3 and 3.1 s periods, each ending in a smooth 10 s turn).
    """
    rng = np.random.default_rng(seed)
    t = t0 + np.arange(n) / fs
    # Each leg ends with a smooth 90 deg turn of TURN_S (an aircraft cannot turn in one
    # sample: a step would put a one-sample eddy-current spike of ~1e3 nT into mag at 1 kHz).
    into = np.clip((t % LINE_S - (LINE_S - TURN_S)) / TURN_S, 0.0, 1.0)
    turn = 0.5 - 0.5 * np.cos(np.pi * into)
    psi = np.deg2rad((t // LINE_S % 4 + turn) * 90 + 5 * np.sin(2 * np.pi * t / 7.1))
    th = np.deg2rad(5 * np.sin(2 * np.pi * t / 5.3 + 1.0))
    ph = np.deg2rad(10 * np.sin(2 * np.pi * t / 3.1))
    inc = np.deg2rad(65.0)
    b = 50000.0 * np.array([np.cos(inc), 0.05, np.sin(inc)])
    cps, sps, cth, sth, cph, sph = (np.cos(psi), np.sin(psi), np.cos(th), np.sin(th),
                                    np.cos(ph), np.sin(ph))
    bx = cth * cps * b[0] + cth * sps * b[1] - sth * b[2]
    by = ((sph * sth * cps - cph * sps) * b[0] + (sph * sth * sps + cph * cps) * b[1]
          + sph * cth * b[2])
    bz = ((cph * sth * cps + sph * sps) * b[0] + (cph * sth * sps - sph * cps) * b[1]
          + cph * cth * b[2])
    B = np.column_stack([bx, by, bz])
    h = _terms16(B, t) @ COEF16
    mag = np.linalg.norm(B, axis=1) + h + rng.normal(0, 0.02, n)
    B += rng.normal(0, 0.5, (n, 3))
    return pd.DataFrame({"time": np.round(t, 6), "lat": 45 + t * 1e-6, "lon": -75 + t * 1e-6,
                         "alt": 300 + rng.normal(0, 0.1, n), "flux_x": B[:, 0],
                         "flux_y": B[:, 1], "flux_z": B[:, 2], "mag": mag,
                         "line": (t // LINE_S).astype(np.int64)})


def write_log(n: int, path: Path, fs: float = 10.0, block: int = 1_000_000) -> Path:
    """Write ``n`` rows of :func:`make_log` to CSV in blocks (cached: reused when present)."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    path = Path(path)
    if path.exists():
        return path
    tmp = path.with_suffix(".part")
    opts = pacsv.WriteOptions(include_header=False, quoting_style="none")
    with open(tmp, "wb") as fh:
        fh.write((",".join(COLUMNS) + "\n").encode())
        for i, a in enumerate(range(0, n, block)):
            df = make_log(min(block, n - a), fs=fs, seed=i, t0=a / fs)
            pacsv.write_csv(pa.Table.from_pandas(df, preserve_index=False), fh, opts)
    tmp.rename(path)
    return path
