"""Minimum-curvature gridding with tension (Smith & Wessel 1990) of a survey's samples.

The grid ``u`` (nodes at the cell centres, metres, ascending) minimises, in grid units,

    (1 - T) * sum(u_xx^2 + 2 u_xy^2 + u_yy^2) + T * sum(u_x^2 + u_y^2) + w * sum((A u - d)^2)

where ``d`` are the block-reduced data (:class:`verde.BlockReduce`, the median of the samples
of each cell), ``A`` bilinear interpolation of the nodes at the data's positions, ``T`` the
tension (0: Briggs' minimum curvature, the biharmonic equation; 1: harmonic, no overshoot) and
``w`` the weight of the data (large: the surface passes through them).  Its Euler-Lagrange
equation away from the data is Smith & Wessel's ``(1 - T) del^4 u - T del^2 u = 0`` with their
free-edge conditions.  The normal equations are a sparse symmetric positive-definite system,
solved coarse to fine: a direct solve on a coarse grid, then at each finer level (cell halved)
conjugate gradients (Jacobi-preconditioned) starting from the coarser solution, so that the
work grows about linearly with the number of cells.

Cells farther than ``blank_m`` from every sample are NaN (k-d trees of blocks of the samples).
"""

from __future__ import annotations

import logging
import math
import os
import time
from dataclasses import asdict, dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.interpolate import RegularGridInterpolator
from scipy.sparse.linalg import cg, spsolve
from scipy.spatial import cKDTree

from ..errors import FitError, InputError
from .geometry import position_noise_m

log = logging.getLogger(__name__)

__all__ = ["BLOCK_SAMPLES", "DEFAULT_TENSION", "GridSummary", "MEMORY_BYTES_PER_CELL",
           "check_grid_memory", "default_cell", "estimate_line_spacing", "far_from_samples",
           "grid_region", "minimum_curvature", "missing_extra"]

#: Default tension: GMT's recommendation for potential-field data (``surface -T0.25``).
DEFAULT_TENSION = 0.25
#: Weight of a datum against the curvature of one cell (grid units): the surface passes
#: within a small fraction of the data's spread of each datum (measured: rms misfit in GRID.json).
DATA_WEIGHT = 100.0
#: Bytes per grid cell the refusal counts (sparse normal matrix, its products, CG vectors):
#: benchmarks/bench_grid.py measures about 0.6 kB per added cell (the whole command's peak
#: 636 MiB at 161,008 cells, 917 MiB at 640,792); three times that, for the margin.
MEMORY_BYTES_PER_CELL = 2_000
#: Coarsest level solved directly (nodes).
_DIRECT_NODES = 6_000
#: Samples handled at a time where a whole-survey temporary would be the memory peak.
BLOCK_SAMPLES = 1_000_000


@dataclass(frozen=True)
class GridSummary:
    """What a gridding did, for GRID.json and the Python caller.

    Attributes
    ----------
    method : str
        ``minimum_curvature``.
    cell_m : float
        Cell size [m].
    tension : float
        Tension T (0-1).
    tension_length_m : float
        The cell at which the tension acts as in grid units [m] (see ``minimum_curvature``).
    n_points : int
        Samples gridded (finite positions and values).
    n_blocks : int
        Block-reduced data (cells holding samples).
    shape : tuple of int
        Grid shape (ny, nx).
    blank_m : float or None
        Blanking distance [m] (None: nothing blanked).
    line_spacing_m : float or None
        Median line spacing estimated from the data [m].
    levels : list of dict
        Per level, coarse to fine: ``cell_m``, ``nodes``, ``n_data``, ``iterations``,
        ``residual`` (relative residual of the normal equations at the end), ``seconds``
        (building and solving the level).
    iterations : int
        Conjugate-gradient iterations at the finest level.
    residual : float
        Relative residual of the finest level's solve.
    misfit_rms_nT : float
        Rms of grid (bilinear) minus block data at the data [nT].
    n_blank : int
        Cells blanked.
    stats : dict
        ``min``, ``max``, ``mean``, ``std`` of the unblanked cells [nT].
    """

    method: str
    cell_m: float
    tension: float
    tension_length_m: float
    n_points: int
    n_blocks: int
    shape: tuple[int, int]
    blank_m: float | None
    line_spacing_m: float | None
    levels: list[dict] = field(default_factory=list)
    iterations: int = 0
    residual: float = float("nan")
    misfit_rms_nT: float = float("nan")
    n_blank: int = 0
    stats: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """The summary as plain JSON-ready values."""
        d = asdict(self)
        d["shape"] = list(self.shape)
        return d


def missing_extra(module: str) -> InputError:
    """The one-line refusal when a package of the ``survey`` extra is not installed."""
    return InputError(f"gridding needs {module}: pip install 'aeromag[survey]'")


# --------------------------------------------------------------------------- line spacing
def _pieces(x: np.ndarray, y: np.ndarray, line: np.ndarray | None) -> np.ndarray:
    """Start index of each straight piece.

    A piece ends at a new line number, a jump of more than 5 median sample steps or a turn of
    more than 60 degrees. Headings are taken over a baseline of k samples, k such that the
    baseline is at least 10 times the positions' noise (estimated from their second
    differences): a slow UAV logging 0.5 m steps with 1 m of GNSS noise would otherwise see
    a "turn" at every other sample.
    """
    n = x.size
    # the median step, the noise and the baseline from a window of at most BLOCK_SAMPLES
    # samples in the middle of the log (one GNSS, one speed: no whole-log temporaries)
    w0 = max(0, n // 2 - BLOCK_SAMPLES // 2)
    xw, yw = x[w0:w0 + BLOCK_SAMPLES], y[w0:w0 + BLOCK_SAMPLES]
    med = float(np.median(np.hypot(np.diff(xw), np.diff(yw)))) if n > 1 else 0.0
    k = 1
    if xw.size > 2:
        sigma = position_noise_m(xw, yw)  # the one noise estimate (survey/geometry.py)
        # doubled until the median baseline is 10 sigma (the steps include the noise)
        while (2 * k < xw.size // 4 and float(np.median(np.hypot(xw[k:] - xw[:-k],
                                                                 yw[k:] - yw[:-k])))
               < 10.0 * sigma):
            k *= 2
    new = np.zeros(max(n - 1, 0), dtype=bool)
    for a in range(0, max(n - 1, 0), BLOCK_SAMPLES):  # in blocks that overlap by 2k samples
        b = min(a + BLOCK_SAMPLES, n - 1)
        new[a:b] = np.hypot(np.diff(x[a:b + 1]), np.diff(y[a:b + 1])) > 5.0 * max(med, 1e-9)
        lo, hi = max(a - k, 0), min(b + k + 1, n)
        xs, ys = x[lo:hi], y[lo:hi]
        if xs.size > 2 * k:
            ang = np.arctan2(ys[k:] - ys[:-k], xs[k:] - xs[:-k])  # heading of samples i..i+k
            turn = np.abs((ang[k:] - ang[:-k] + np.pi) % (2.0 * np.pi) - np.pi)  # wrapped
            # turn[i] compares the headings at lo+i and lo+i+k: it marks step lo+i+k
            idx = lo + k + np.flatnonzero(turn > np.radians(60.0))
            new[idx[(idx >= a) & (idx < b)]] = True
    if line is not None:
        new |= np.diff(line) != 0
    return np.concatenate([[0], np.flatnonzero(new) + 1])


def estimate_line_spacing(x_m: np.ndarray, y_m: np.ndarray,
                          line: np.ndarray | None = None) -> float:
    """Median spacing of the survey's lines [m], robust to ties, pieces and re-flights.

    Samples are cut into pieces (a new ``line`` number, a jump of more than 5 median sample
    steps or a turn of more than 60 degrees); the dominant direction is the peak of the
    length-weighted histogram of the pieces' directions (5 degree bins), pieces within 20
    degrees of it are the lines (ties and turns left out; their direction is their
    length-weighted mean), and the spacing is the median gap between the sorted across-line
    offsets of the lines, gaps under a fifth of that median (a line flown in two pieces, a
    re-flight) left out.

    Parameters
    ----------
    x_m, y_m : ndarray
        Projected positions in time order [m].
    line : ndarray, optional
        Line numbers.

    Returns
    -------
    float
        The spacing [m].

    Raises
    ------
    InputError
        When fewer than two lines can be told apart.
    """
    x, y = np.asarray(x_m, float), np.asarray(y_m, float)
    starts = _pieces(x, y, None if line is None else np.asarray(line))
    ends = np.concatenate([starts[1:], [x.size]])
    keep = ends - starts >= 3
    s, e = starts[keep], ends[keep] - 1
    dx, dy = x[e] - x[s], y[e] - y[s]
    length = np.hypot(dx, dy)
    ok = length > 0
    s, e, dx, dy, length = s[ok], e[ok], dx[ok], dy[ok], length[ok]
    if s.size < 2:
        raise InputError("cannot estimate the line spacing (fewer than two straight lines):"
                         " give --cell")
    ang = np.mod(np.arctan2(dy, dx), np.pi)
    # dominant direction: the length-weighted histogram peak of the doubled angles
    hist, edges = np.histogram(ang, bins=36, range=(0, np.pi), weights=length)
    k = int(np.argmax(hist))
    ref = 0.5 * (edges[k] + edges[k + 1])
    off = np.abs(np.angle(np.exp(2j * (ang - ref)))) / 2.0
    lines = off < np.radians(20.0)
    # the lines' direction: their length-weighted mean (doubled angles), not the bin's centre
    # (2.5 degrees off would add x sin 2.5 deg to the across-line offsets)
    ref = float(np.angle(np.sum(length[lines] * np.exp(2j * ang[lines])))) / 2.0
    # Fragments of turns (a slow multirotor's U-turn, cut by the turn test into pieces of a
    # few metres, some by chance parallel to the lines) are not lines: a piece shorter than a
    # tenth of the length-weighted median of the parallel pieces is left out.
    if lines.sum() >= 2:
        ln = length[lines]
        o = np.argsort(ln)
        cw = np.cumsum(ln[o])
        wmed = float(ln[o][np.searchsorted(cw, 0.5 * cw[-1])])
        lines &= length >= 0.1 * wmed
    if lines.sum() < 2:
        raise InputError("cannot estimate the line spacing (fewer than two parallel lines):"
                         " give --cell")
    nx_, ny_ = -math.sin(ref), math.cos(ref)
    mid = (s[lines] + e[lines]) // 2
    across = np.sort(x[mid] * nx_ + y[mid] * ny_)
    gaps = np.diff(across)
    gaps = gaps[gaps > 0]
    if gaps.size == 0:
        raise InputError("cannot estimate the line spacing (all lines on one track): give --cell")
    med = float(np.median(gaps))
    gaps = gaps[gaps > 0.2 * med]
    return float(np.median(gaps))


def default_cell(line_spacing_m: float) -> float:
    """The default cell: a fifth of the line spacing, rounded to 2 significant digits [m]."""
    c = line_spacing_m / 5.0
    return float(f"{c:.2g}")  # 3.9, not 3.9000000000000004 in GRID.json


# --------------------------------------------------------------------------- grid geometry
def grid_region(x_m: np.ndarray, y_m: np.ndarray, cell_m: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """Node coordinates (cell centres, multiples of the cell) covering the samples [m]."""
    x0, x1 = math.floor(np.min(x_m) / cell_m), math.ceil(np.max(x_m) / cell_m)
    y0, y1 = math.floor(np.min(y_m) / cell_m), math.ceil(np.max(y_m) / cell_m)
    return (np.arange(x0, x1 + 1) * cell_m, np.arange(y0, y1 + 1) * cell_m)


def _memory_budget() -> int:
    """Half the machine's physical memory [bytes]."""
    try:
        return int(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE") // 2)
    except (ValueError, OSError, AttributeError):  # pragma: no cover - not POSIX
        return 4 << 30


def check_grid_memory(x_m: np.ndarray, y_m: np.ndarray, cell_m: float,
                      max_bytes: int | None = None) -> tuple[int, int]:
    """Refuse a cell so small that the solve would not fit in memory.

    Parameters
    ----------
    x_m, y_m : ndarray
        Sample positions [m].
    cell_m : float
        Requested cell [m].
    max_bytes : int, optional
        Memory the solve may use (default: half the physical memory).

    Returns
    -------
    (ny, nx) : tuple of int
        The grid's shape.

    Raises
    ------
    InputError
        Naming the grid's size and the smallest cell that fits.
    """
    if not (cell_m > 0 and math.isfinite(cell_m)):
        raise InputError(f"--cell {cell_m}: the cell must be a positive number of metres")
    width = float(np.max(x_m) - np.min(x_m))
    height = float(np.max(y_m) - np.min(y_m))
    nx = int(math.ceil(width / cell_m)) + 2
    ny = int(math.ceil(height / cell_m)) + 2
    budget = _memory_budget() if max_bytes is None else int(max_bytes)
    need = nx * ny * MEMORY_BYTES_PER_CELL
    if need > budget:
        fit = math.sqrt(width * height * MEMORY_BYTES_PER_CELL / budget) * 1.05
        fit = max(fit, cell_m * 1.01)
        mag = 10.0 ** math.floor(math.log10(fit)) / 10.0
        fit = math.ceil(fit / mag) * mag
        raise InputError(
            f"--cell {cell_m:g}: a {nx} x {ny} grid ({nx * ny:,} cells) needs about"
            f" {need / 2**30:.1f} GiB, more than the {budget / 2**30:.1f} GiB available;"
            f" use --cell {fit:g} or larger")
    return ny, nx


# --------------------------------------------------------------------------- the solve
def _d1(n: int) -> sp.csr_matrix:
    return sp.diags([-np.ones(n - 1), np.ones(n - 1)], [0, 1], shape=(n - 1, n), format="csr")


def _d2(n: int) -> sp.csr_matrix:
    return sp.diags([np.ones(n - 2), -2 * np.ones(n - 2), np.ones(n - 2)], [0, 1, 2],
                    shape=(n - 2, n), format="csr")


def _smoothness(ny: int, nx: int, tension: float, scale: float = 1.0) -> sp.csr_matrix:
    """(1-T) (Dxx'Dxx + 2 Dxy'Dxy + Dyy'Dyy) + T s (Dx'Dx + Dy'Dy) on a ny x nx grid.

    ``s = (cell / tension length)^2`` makes the tension act at a fixed length in metres.
    """
    ix, iy = sp.identity(nx, format="csr"), sp.identity(ny, format="csr")
    d1x, d1y = _d1(nx), _d1(ny)
    d2x, d2y = _d2(nx), _d2(ny)
    # Kronecker products of 1-D operators: D'D of a kron is the kron of the D'D's.
    qx2, qy2 = (d2x.T @ d2x).tocsr(), (d2y.T @ d2y).tocsr()
    qx1, qy1 = (d1x.T @ d1x).tocsr(), (d1y.T @ d1y).tocsr()
    curv = sp.kron(iy, qx2) + sp.kron(qy2, ix) + 2.0 * sp.kron(qy1, qx1)
    q = (1.0 - tension) * curv
    if tension > 0:
        q = q + (tension * scale) * (sp.kron(iy, qx1) + sp.kron(qy1, ix))
    return q.tocsr()


def _bilinear(xc: np.ndarray, yc: np.ndarray, xg: np.ndarray, yg: np.ndarray
              ) -> sp.csr_matrix:
    """Bilinear interpolation from the nodes (xg, yg) to the points (xc, yc)."""
    h = xg[1] - xg[0] if xg.size > 1 else 1.0
    fx = np.clip((xc - xg[0]) / h, 0, xg.size - 1 - 1e-9)
    fy = np.clip((yc - yg[0]) / h, 0, yg.size - 1 - 1e-9)
    i, j = np.floor(fx).astype(np.int64), np.floor(fy).astype(np.int64)
    tx, ty = fx - i, fy - j
    nx = xg.size
    rows = np.repeat(np.arange(xc.size), 4)
    cols = np.stack([j * nx + i, j * nx + i + 1, (j + 1) * nx + i, (j + 1) * nx + i + 1], 1)
    w = np.stack([(1 - tx) * (1 - ty), tx * (1 - ty), (1 - tx) * ty, tx * ty], 1)
    return sp.csr_matrix((w.ravel(), (rows, cols.ravel())), shape=(xc.size, xg.size * yg.size))


def _block_mean(x: np.ndarray, y: np.ndarray, v: np.ndarray, xg: np.ndarray, yg: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean position and value of the points in each cell of a coarser level."""
    h = xg[1] - xg[0]
    i = np.clip(np.rint((x - xg[0]) / h).astype(np.int64), 0, xg.size - 1)
    j = np.clip(np.rint((y - yg[0]) / h).astype(np.int64), 0, yg.size - 1)
    key = j * xg.size + i
    uniq, inv, cnt = np.unique(key, return_inverse=True, return_counts=True)
    mean = [np.bincount(inv, weights=a) / cnt for a in (x, y, v)]
    return mean[0], mean[1], mean[2]


def _solve_level(xg: np.ndarray, yg: np.ndarray, xd: np.ndarray, yd: np.ndarray,
                 vd: np.ndarray, tension: float, u0: np.ndarray | None, rtol: float,
                 maxiter: int, tension_length_m: float) -> tuple[np.ndarray, dict]:
    t0 = time.perf_counter()
    ny, nx = yg.size, xg.size
    a = _bilinear(xd, yd, xg, yg)
    scale = (float(xg[1] - xg[0]) / tension_length_m) ** 2
    q = _smoothness(ny, nx, tension, scale) + DATA_WEIGHT * (a.T @ a)
    q = q.tocsr()
    b = DATA_WEIGHT * (a.T @ vd)
    info = {"cell_m": float(xg[1] - xg[0]), "nodes": int(nx * ny), "n_data": int(vd.size)}
    if u0 is None:
        u = spsolve(q.tocsc(), b)
        info.update(iterations=0)
    else:
        count = [0]

        def _count(_xk: np.ndarray) -> None:
            count[0] += 1

        m = sp.diags(1.0 / q.diagonal())
        u, status = cg(q, b, x0=u0, rtol=rtol, maxiter=maxiter, M=m, callback=_count)
        if status < 0:  # pragma: no cover - breakdown of CG on an SPD matrix
            raise FitError(f"minimum curvature: the solve broke down (status {status})")
        info.update(iterations=count[0])
    bnorm = float(np.linalg.norm(b)) or 1.0
    info["residual"] = float(np.linalg.norm(q @ u - b) / bnorm)
    info["seconds"] = round(time.perf_counter() - t0, 3)
    return u.reshape(ny, nx), info


def far_from_samples(x_m: np.ndarray, y_m: np.ndarray, xg: np.ndarray, yg: np.ndarray,
                     distance_m: float) -> np.ndarray:
    """Nodes farther than ``distance_m`` from every sample (the blanking mask).

    A k-d tree of one block of samples at a time, queried with the nodes not yet found near
    a sample: the memory is a block's tree and the nodes', not a tree of every sample.

    Parameters
    ----------
    x_m, y_m : ndarray
        Sample positions [m].
    xg, yg : ndarray
        Node coordinates [m].
    distance_m : float
        Blanking distance [m].

    Returns
    -------
    ndarray of bool, shape (len(yg), len(xg))
        True where no sample is within ``distance_m``.
    """
    gyy, gxx = np.meshgrid(yg, xg, indexing="ij")
    nodes = np.column_stack([gxx.ravel(), gyy.ravel()])
    del gyy, gxx
    far = np.ones(nodes.shape[0], dtype=bool)
    step = 4 * BLOCK_SAMPLES
    for a in range(0, x_m.size, step):
        todo = np.flatnonzero(far)
        if todo.size == 0:
            break
        tree = cKDTree(np.column_stack([x_m[a:a + step], y_m[a:a + step]]))
        dist, _ = tree.query(nodes[todo], k=1, distance_upper_bound=distance_m)
        far[todo[np.isfinite(dist)]] = False
    return far.reshape(yg.size, xg.size)


def minimum_curvature(
    x_m: np.ndarray, y_m: np.ndarray, values: np.ndarray, *, cell_m: float,
    tension: float = DEFAULT_TENSION, blank_m: float | None = None,
    block: str = "median", rtol: float = 1e-6, maxiter: int = 2000,
    line_spacing_m: float | None = None, max_bytes: int | None = None,
    tension_length_m: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, GridSummary]:
    """Grid scattered samples by minimum curvature with tension.

    Parameters
    ----------
    x_m, y_m : ndarray
        Projected positions [m].
    values : ndarray
        Values at the positions (e.g. total-field anomaly [nT]).
    cell_m : float
        Cell size [m].
    tension : float
        Tension T in [0, 1) (default 0.25, GMT's choice for potential fields).
    blank_m : float, optional
        Cells farther than this from every sample are NaN [m] (None: none blanked).
    block : {"median", "mean"}
        Reduction of the samples of each cell (verde ``BlockReduce``).
    rtol : float
        Relative residual at which the conjugate gradients of each level stop.
    maxiter : int
        Most conjugate-gradient iterations per level.
    line_spacing_m : float, optional
        Recorded in the summary.
    max_bytes : int, optional
        Memory the solve may use (default half the physical memory).
    tension_length_m : float, optional
        The cell at which the tension acts as GMT's does in grid units [m] (default
        ``cell_m``; ``am.grid`` passes the default cell, a fifth of the line spacing).  The
        tension term is scaled by ``(cell / tension_length_m)^2`` so that it is a fixed
        physical operator: a finer cell no longer stiffens the surface (before: T = 0.25 on
        lines 150 m apart, 7.6 nT rms at 30 m cells, 11.8 nT at 15 m), and every
        coarse-to-fine level solves the same problem.

    Returns
    -------
    x, y : ndarray
        Cell centres, ascending [m].
    grid : ndarray
        ``(len(y), len(x))`` values, NaN where blanked.
    summary : GridSummary

    Raises
    ------
    InputError
        Too few samples, a bad tension or cell, or a grid that would not fit in memory.
    """
    try:
        import verde as vd
    except ImportError:
        raise missing_extra("verde") from None

    x, y, v = (np.asarray(a, dtype=float) for a in (x_m, y_m, values))
    ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(v)
    if not ok.all():  # (no copy of complete samples)
        x, y, v = x[ok], y[ok], v[ok]
    del ok
    if x.size < 3:
        raise InputError(f"only {x.size} sample(s) with a position and a value: need 3 or more")
    if not 0.0 <= tension < 1.0:
        raise InputError(f"tension {tension}: must be in [0, 1)")
    if blank_m is not None and not blank_m > 0:  # 0, negative or NaN blanked every cell
        raise InputError(f"--blank {blank_m:g}: the blanking distance must be a positive"
                         " number of metres (inf: blank nothing)")
    check_grid_memory(x, y, cell_m, max_bytes)
    length = float(cell_m if tension_length_m is None else tension_length_m)
    if not (length > 0 and math.isfinite(length)):
        raise InputError(f"tension length {tension_length_m}: must be a positive number of"
                         " metres")
    xg, yg = grid_region(x, y, cell_m)
    if block not in ("median", "mean"):
        raise InputError(f"block reduction {block!r}: use 'median' or 'mean'")
    # block centres on the nodes (cells centred on them)
    region = (xg[0] - cell_m / 2, xg[-1] + cell_m / 2, yg[0] - cell_m / 2, yg[-1] + cell_m / 2)
    # verde hands the reduction to pandas' groupby aggregate: the name runs pandas' compiled
    # median (np.median runs a Python call per block: 40 s for the Osborne survey at 50 m)
    (xb, yb), vb = vd.BlockReduce(block, spacing=cell_m, region=region, adjust="region",
                                  drop_coords=True).filter((x, y), v)
    xb, yb, vb = (np.asarray(a, float).ravel() for a in (xb, yb, vb))
    shift = float(np.mean(vb))
    vb0 = vb - shift
    # levels: cell, 2 cell, 4 cell ... until the coarsest is small enough to solve directly
    cells = [cell_m]
    while True:
        gx, gy = grid_region(x, y, cells[-1])
        if gx.size * gy.size <= _DIRECT_NODES or min(gx.size, gy.size) < 8:
            break
        cells.append(cells[-1] * 2.0)
    u = None
    levels = []
    prev = None
    for c in reversed(cells):
        gx, gy = (xg, yg) if c == cell_m else grid_region(x, y, c)
        if c == cell_m:
            xd, yd, dv = xb, yb, vb0
        else:
            xd, yd, dv = _block_mean(xb, yb, vb0, gx, gy)
        u0 = None
        if prev is not None:
            px, py, pu = prev
            interp = RegularGridInterpolator((py, px), pu, bounds_error=False, fill_value=None)
            gyy, gxx = np.meshgrid(gy, gx, indexing="ij")
            u0 = interp(np.stack([gyy.ravel(), gxx.ravel()], 1))
            del gyy, gxx
        u, info = _solve_level(gx, gy, xd, yd, dv, tension, u0, rtol, maxiter, length)
        levels.append(info)
        log.debug("minimum curvature level %s", info)
        prev = (gx, gy, u)
    assert u is not None
    misfit = _bilinear(xb, yb, xg, yg) @ u.ravel() - vb0
    grid = u + shift
    n_blank = 0
    if blank_m is not None:
        far = far_from_samples(x, y, xg, yg, float(blank_m))
        grid[far] = np.nan
        n_blank = int(far.sum())
    good = grid[np.isfinite(grid)]
    stats = ({"min": float(good.min()), "max": float(good.max()), "mean": float(good.mean()),
              "std": float(good.std())} if good.size else {})
    summary = GridSummary(
        method="minimum_curvature", cell_m=float(cell_m), tension=float(tension),
        tension_length_m=length,
        n_points=int(x.size), n_blocks=int(vb.size), shape=(int(yg.size), int(xg.size)),
        blank_m=None if blank_m is None else float(blank_m),
        line_spacing_m=None if line_spacing_m is None else float(line_spacing_m),
        levels=levels, iterations=int(levels[-1]["iterations"]),
        residual=float(levels[-1]["residual"]),
        misfit_rms_nT=float(np.sqrt(np.mean(misfit ** 2))), n_blank=n_blank, stats=stats)
    return xg, yg, grid, summary
