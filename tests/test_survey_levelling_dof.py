"""The levelling's effective parameters and degrees of freedom, and the warning when the
crossings barely outnumber what the corrections can absorb (the levelled misties then show
the fit, not the level error: reporting them alone would flatter the survey)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import aeromag as am
from aeromag.survey.diurnal import BaseRecord
from aeromag.synthetic.level_survey import simulate_level_survey


@pytest.fixture(scope="module")
def sim():
    df, base, truth = simulate_level_survey(0)
    return df, BaseRecord(base["time"].to_numpy(), base["mag"].to_numpy(), "base.csv")


def test_a_shift_per_line_and_tie_has_lines_plus_ties_minus_the_datum(sim):
    df, base = sim
    res = am.level(df, base=base, lag=0.4, method="shift")
    n_lines = int((res.data.groupby("line")["line_type"].first() == "line").sum())
    n_ties = int((res.data.groupby("line")["line_type"].first() == "tie").sum())
    lev = res.levelling
    # Hand count: one shift per line and per tie, one datum fixed (one network).
    assert lev.n_networks == 1
    assert lev.n_parameters_effective == pytest.approx(n_lines + n_ties - 1, abs=1e-3)
    used = lev.dof + lev.n_parameters_effective
    assert used == pytest.approx(np.count_nonzero(lev.weight > 1e-3), abs=1e-6)
    rep = res.to_report()["levelling"]
    assert rep["n_parameters_effective"] == pytest.approx(lev.n_parameters_effective)
    assert rep["dof"] == pytest.approx(lev.dof)
    assert not any("degrees of freedom" in w for w in res.warnings)


def _independent_survey(n_ties: int, seed: int = 5) -> pd.DataFrame:
    """Eight E-W lines 250 m apart and n_ties N-S ties over a smooth field (no time)."""
    rng = np.random.default_rng(seed)
    lat0, lon0 = 45.0, 7.0
    m_lat, m_lon = 111_132.0, 111_320.0 * np.cos(np.radians(lat0))
    rows = []
    field = lambda x, y: 40 * np.sin(x / 900.0) * np.cos(y / 700.0)  # noqa: E731
    for k in range(8):
        x = np.arange(0.0, 2400.0, 8.0)
        y = np.full_like(x, 250.0 * k)
        rows.append((x, y, 100 + 10 * k, rng.normal(0, 5) + rng.normal(0, 3) * x / 2400.0))
    for j in range(n_ties):
        y = np.arange(-100.0, 1900.0, 8.0)
        x = np.full_like(y, 300.0 + 1800.0 * j / max(n_ties - 1, 1))
        rows.append((x, y, 9000 + j, rng.normal(0, 2)))
    parts = []
    for x, y, line, err in rows:
        parts.append(pd.DataFrame({"lat": lat0 + y / m_lat, "lon": lon0 + x / m_lon,
                                   "alt": 300.0, "line": line,
                                   "mag": field(x, y) + err + rng.normal(0, 0.05, x.size)}))
    return pd.concat(parts, ignore_index=True)


def test_a_nearly_saturated_network_warns_and_a_well_tied_one_does_not():
    # The project simulator's small block with 3 ties: 8 lines with a trend each (24
    # crossings for 18 parameters); the robust passes reject a few, and what is left barely
    # exceeds the parameters. The shipped sample has 5 ties and does not warn.
    df, b, _ = simulate_level_survey(1, n_lines=8, line_length_m=2000.0, n_ties=3,
                                     rate_hz=5.0)
    base = BaseRecord(b["time"].to_numpy(), b["mag"].to_numpy(), "base.csv")
    few = am.level(df, base=base, lag=0.4)
    assert few.levelling.dof < 5
    assert any("degrees of freedom" in w and "--level shift" in w for w in few.warnings)
    shift = am.level(df, base=base, lag=0.4, method="shift")
    assert shift.levelling.dof > 10
    samples = Path(__file__).resolve().parents[1] / "data_samples"
    shipped = am.level(samples / "level_survey.csv", base=samples / "level_base.csv", lag=0.4)
    assert shipped.levelling.dof > 10
    assert not any("degrees of freedom" in w for w in shipped.warnings)
    many = am.level(_independent_survey(8), igrf=False, method="trend")
    assert many.levelling.dof > 20
    assert not any("degrees of freedom" in w for w in many.warnings)
