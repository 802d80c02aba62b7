"""Every compensation plot runs headless and writes a non-empty PNG."""

from __future__ import annotations

import pytest

from aeromag.compensation.pipeline import compensate
from aeromag.errors import InputError
from aeromag.plot import compensation as pc
from aeromag.qc import compute_qc
from aeromag.synthetic import simulate_calibration


@pytest.fixture(scope="module")
def res():
    df, _ = simulate_calibration(seed=6, n_boxes=1, faults={4: "noise_burst"})
    r = compensate(df)
    return r, compute_qc(r, fit=False)


PNG = b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("name", ["pca", "ev", "ts", "psd", "terms", "fom", "map"])
def test_plot_writes_png(res, tmp_path, name):
    r, q = res
    path = tmp_path / f"{name}.png"
    calls = {
        "pca": lambda: pc.plot_pca_scores(r.report, path=path),
        "ev": lambda: pc.plot_explained_variance(r.report, path=path),
        "ts": lambda: pc.plot_timeseries(r.data, path=path),
        "psd": lambda: pc.plot_psd(r.data, band_hz=(0.1, 0.9), path=path),
        "terms": lambda: pc.plot_term_contributions(r.data, r.report, path=path),
        "fom": lambda: pc.plot_fom(q.fom, path=path),
        "map": lambda: pc.plot_map(r.data, path=path),
    }
    fig = calls[name]()
    assert fig.axes
    data = path.read_bytes()
    assert data.startswith(PNG) and len(data) > 5000


def test_draws_into_given_axes(res):
    r, _ = res
    fig, ax = pc.new_figure()
    assert pc.plot_pca_scores(r.report, ax=ax) is fig
    assert ax.get_title().endswith("1 dropped")


def test_term_contributions_sum_to_mag_tl(res):
    r, _ = res
    parts = pc.term_contributions(r.data, r.report["terms"], r.report["coef"])
    assert list(parts.columns) == ["permanent", "induced", "eddy"]
    assert ((parts.sum(axis=1) - r.data["mag_tl"]).abs().max()) < 1e-9


def test_missing_inputs_raise(res):
    r, _ = res
    with pytest.raises(InputError):
        pc.plot_pca_scores({"segments": [{"id": 0, "scores": None}]})
    with pytest.raises(InputError):
        pc.plot_map(r.data.drop(columns=["lat"]))
