"""QC wired into compensate/calibrate: the qc block, --plot, and the result's plot methods."""

from __future__ import annotations

import json

import pytest
from matplotlib.figure import Figure
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.synthetic import simulate_calibration
from aeromag.workflows.compensate import compensate

runner = CliRunner()


@pytest.fixture(scope="module")
def cal(tmp_path_factory):
    d = tmp_path_factory.mktemp("wiring")
    df, _ = simulate_calibration(seed=4, n_boxes=1, faults={3: "noise_burst"})
    df.to_csv(d / "cal.csv", index=False)
    return d, df


def test_calibrate_reports_fom_and_fit_diagnostics_and_plots(cal, tmp_path):
    d, _ = cal
    r = runner.invoke(app, ["calibrate", str(d / "cal.csv"), "-o", str(tmp_path / "m.json"),
                            "--plot", str(tmp_path / "rep")])
    assert r.exit_code == 0, r.output
    m = json.loads((tmp_path / "m.json").read_text())
    fom = m["qc"]["fom"]
    assert fom["n_maneuvers"] == 12
    assert fom["fom_after_nT"] < 0.5 * fom["fom_before_nT"]
    assert set(m["fit"]["vif"]) == set(m["terms"])
    assert m["fit"]["cv_residual_std_nT"] >= m["fit"]["residual_std_nT"] * 0.5
    assert all("cv_residual_std" in s for s in m["segments"] if s.get("residual_std"))
    html = (tmp_path / "rep" / "report.html").read_text()
    assert html.count("data:image/png;base64,") >= 5
    assert 3 in m["screening"]["dropped"]


def test_compensate_plot_option_and_no_fom_by_default(cal, tmp_path):
    d, _ = cal
    out = tmp_path / "c.csv"
    r = runner.invoke(app, ["compensate", str(d / "cal.csv"), "-o", str(out), "--plot",
                            str(tmp_path / "rep2")])
    assert r.exit_code == 0, r.output
    rep = json.loads(out.with_suffix(".json").read_text())
    assert rep["qc"]["fom"]["applicable"] is False and rep["qc"]["fom"]["fom_after_nT"] is None
    assert "not computed for this run" in rep["qc"]["fom"]["reason"]
    assert (tmp_path / "rep2" / "pca_scores.png").stat().st_size > 1000
    r = runner.invoke(app, ["compensate", str(d / "cal.csv"), "-o", str(out), "--fom"])
    assert json.loads(out.with_suffix(".json").read_text())["qc"]["fom"]["n_maneuvers"] == 12


def test_plot_functions_take_the_result_and_return_figures(cal, tmp_path):
    import aeromag as am

    _, df = cal
    res = compensate(df)
    for name in ("plot_pca_scores", "plot_explained_variance", "plot_timeseries", "plot_psd",
                 "plot_term_contributions", "plot_fom", "plot_map", "plot_residuals"):
        fig = getattr(am.plot, name)(res)
        assert isinstance(fig, Figure), name
        assert fig._repr_png_().startswith(b"\x89PNG"), name  # shows itself in Jupyter
    assert am.compute_qc(res).metrics.improvement_ratio > 1
    page = am.write_report(res, tmp_path / "r")
    assert page.exists()
