"""The QC measures the total field the compensation used (issue 15: fluxgate magnitude).

A log compensated with ``mag_from_fluxgate=True`` keeps its ``mag`` column, but the model was
fitted on ``|flux|`` and ``mag_tl`` is the interference of ``|flux|``: the QC's per-piece
residuals (and the FOM) must be computed on the fluxgate magnitude, not on ``mag``.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from aeromag.compensation import CompensationReport
from aeromag.compensation.config import CompensationConfig
from aeromag.compensation.pipeline import run_compensation as compensate
from aeromag.qc import compute_qc, kept_mask, segment_labels
from aeromag.qc.residuals import piece_residuals
from aeromag.qc.total_field import fluxgate_is_total_field, prepared_total_field
from aeromag.synthetic import simulate_calibration


@pytest.fixture(scope="module")
def fluxgate_result():
    df, _ = simulate_calibration(seed=3, n_boxes=1)
    # A scalar channel that the compensation must not use: offset and a slow drift.
    df["mag"] = df["mag"] + 300.0 + 5.0 * np.sin(df["time"].to_numpy() / 50.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = compensate(df, CompensationConfig(mag_from_fluxgate=True), source="flux.csv")
    assert res.report.mag_from_fluxgate is True
    return res


def test_qc_per_piece_residuals_are_of_the_fluxgate_magnitude(fluxgate_result):
    res = fluxgate_result
    data, cfg = res.data, res.config
    qc = compute_qc(res, fit=False, fom=False)
    flux = data[["flux_x", "flux_y", "flux_z"]].to_numpy(dtype=np.float64)
    bt = np.sqrt(np.einsum("ij,ij->i", flux, flux))
    t = data["time"].to_numpy(dtype=np.float64)
    tl = data["mag_tl"].to_numpy(dtype=np.float64)
    want = piece_residuals(t, bt, tl, segment_labels(data), kept_mask(data), cfg.band_hz,
                           cfg.order, trim_s=cfg.trim_s, max_gap_s=cfg.max_gap_s)
    got = qc.metrics.per_piece_rms
    assert got.kept.per_piece_rms_after_nT == pytest.approx(want.kept.residual_std_nT,
                                                            rel=1e-12)
    assert got.kept.per_piece_rms_before_nT == pytest.approx(want.kept.std_before_nT,
                                                             rel=1e-12)
    assert got.all.per_piece_rms_ratio == pytest.approx(want.all.improvement_ratio, rel=1e-12)
    for k, v in want.by_segment.items():
        assert qc.metrics.residual_std_by_segment_nT[str(k)] == pytest.approx(v, rel=1e-12)
    # ... and not those of the unused 'mag' column (the slow drift is out of band, the
    # residual mag - mag_tl then holds the fluxgate-vs-scalar interference difference).
    wrong = piece_residuals(t, data["mag"].to_numpy(dtype=np.float64), tl, segment_labels(data),
                            kept_mask(data), cfg.band_hz, cfg.order, trim_s=cfg.trim_s,
                            max_gap_s=cfg.max_gap_s)
    assert wrong.kept.residual_std_nT != pytest.approx(want.kept.residual_std_nT, rel=1e-3)


def test_prepared_total_field_follows_the_report():
    import pandas as pd

    d = pd.DataFrame({"time": np.arange(5.0), "mag": [1.0, np.nan, 3.0, 4.0, 5.0],
                      "flux_x": [3.0] * 5, "flux_y": [4.0] * 5, "flux_z": [0.0] * 5})
    cfg = CompensationConfig(max_interp_s=2.0)
    plain, flux = CompensationReport(), CompensationReport(mag_from_fluxgate=True)
    assert not fluxgate_is_total_field(d, plain)
    assert fluxgate_is_total_field(d, flux)
    assert fluxgate_is_total_field(d.drop(columns=["mag"]), plain)
    np.testing.assert_array_equal(prepared_total_field(d, flux, cfg), np.full(5, 5.0))
    np.testing.assert_array_equal(prepared_total_field(d, plain, cfg), [1.0, 2.0, 3.0, 4.0, 5.0])


def test_qc_fom_is_of_the_fluxgate_magnitude(fluxgate_result):
    from aeromag.qc.fom import fom_table

    res = fluxgate_result
    data, cfg = res.data, res.config
    qc = compute_qc(res, fit=False, fom=True)
    assert qc.fom is not None and len(qc.fom)
    flux = data[["flux_x", "flux_y", "flux_z"]].to_numpy(dtype=np.float64)
    bt = np.sqrt(np.einsum("ij,ij->i", flux, flux))
    kw = dict(band_hz=cfg.band_hz, order=cfg.order, max_gap_s=cfg.max_gap_s)
    want = fom_table(data, qc.maneuvers, total_field=bt, **kw)
    for c in ("ptp_before_nT", "ptp_after_nT"):
        np.testing.assert_allclose(qc.fom[c].to_numpy(), want[c].to_numpy(), rtol=1e-9)
    assert qc.fom.attrs["fields"]["before"] == "|flux|"
    on_mag = fom_table(data, qc.maneuvers, **kw)  # what the QC measured before
    assert not np.allclose(on_mag["ptp_after_nT"].to_numpy(), want["ptp_after_nT"].to_numpy(),
                           rtol=1e-3)
