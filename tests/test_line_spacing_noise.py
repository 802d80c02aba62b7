"""The grid's line-spacing estimate on tracks whose positions are noisy against their step
(a slow UAV: 0.3-2 m steps with 0.5-3 m of GNSS noise): turns are judged over a baseline
long enough to see through the noise, so a line is not cut into hundreds of pieces."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from aeromag.survey.gridding import estimate_line_spacing


@settings(max_examples=25, deadline=None)
@given(spacing=st.floats(40.0, 400.0), step=st.floats(0.3, 12.0), noise=st.floats(0.0, 3.0),
       angle=st.floats(0.0, 180.0), n_lines=st.integers(4, 9), seed=st.integers(0, 10_000),
       with_line=st.booleans())
def test_spacing_through_position_noise(spacing, step, noise, angle, n_lines, seed, with_line):
    rng = np.random.default_rng(seed)
    length = 40.0 * spacing
    n = int(length / step)
    a = np.radians(angle)
    ux, uy, nx, ny = np.cos(a), np.sin(a), -np.sin(a), np.cos(a)
    xs, ys, ls = [], [], []
    for k in range(n_lines):
        s = np.linspace(0.0, length, n)[:: 1 if k % 2 == 0 else -1]  # back and forth
        xs.append(s * ux + k * spacing * nx + rng.normal(0, noise, n))
        ys.append(s * uy + k * spacing * ny + rng.normal(0, noise, n))
        ls.append(np.full(n, 100 + k))
    x, y, line = np.concatenate(xs), np.concatenate(ys), np.concatenate(ls)
    est = estimate_line_spacing(x, y, line if with_line else None)
    assert abs(est - spacing) <= 0.03 * spacing + 2.0 * noise
