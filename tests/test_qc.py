"""QC metrics on the simulator: FOM vs truth, improvement, VIF, leave-one-segment-out CV."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from aeromag.compensation.config import CompensationConfig
from aeromag.compensation.normal import SegmentStats, segment_normal_equations
from aeromag.compensation.pipeline import run_compensation as compensate
from aeromag.compensation.prepare import prepare
from aeromag.compensation.result import CompensationResult
from aeromag.compensation.terms import TERMS_16
from aeromag.qc import (
    compute_qc,
    fom_summary,
    fom_table,
    fourth_difference_noise,
    loso_cv,
    quality_metrics,
    variance_inflation,
)
from aeromag.synthetic import simulate_calibration


@pytest.fixture(scope="module")
def cal_result():
    df, truth = simulate_calibration(seed=5, n_boxes=1)
    return compensate(df), truth


def test_fom_matches_truth_and_drops(cal_result):
    res, _ = cal_result
    q = compute_qc(res)
    fom = q.metrics.fom
    assert fom.complete_boxes == [0]
    assert fom.n_maneuvers == 12
    assert abs(fom.fom_before_nT - fom.fom_truth_nT) < 0.1 * fom.fom_truth_nT
    assert fom.fom_after_nT < 0.05 * fom.fom_before_nT
    assert len(fom.per_maneuver) == 12
    # The truth FOM with the true manoeuvre labels agrees with the detected intervals.
    tab = fom_table(res.data, band_hz=(0.1, 0.9), maneuver_column="truth_maneuver")
    assert fom_summary(tab).fom_truth_nT == pytest.approx(fom.fom_truth_nT, rel=0.1)


def test_metrics_block(cal_result):
    res, _ = cal_result
    m = quality_metrics(res.data, res.report).to_dict()
    assert m["improvement_ratio"] > 100 and m["all_data"]["improvement_ratio"] > 100
    assert m["residual_std_nT"] < 0.02
    assert set(m["residual_std_by_heading_nT"]) == {"N", "E", "S", "W"}
    assert len(m["residual_std_by_segment_nT"]) == 12
    fit = m["fit"]
    assert fit["condition_number_scaled"] == pytest.approx(
        res.report.fit.condition_number_scaled, rel=0.05)
    assert len(fit["vif"]) == 16 and min(fit["vif"].values()) >= 1 - 1e-9
    assert fit["cv_residual_std_nT"] >= fit["fit_residual_std_nT"]
    assert fit["cv_residual_std_nT"] < 0.1  # nT: the model generalises across segments
    assert m["noise"]["fourth_difference_before_nT"] == pytest.approx(0.02, rel=0.3)


def test_loso_equals_explicit_refit():
    rng = np.random.default_rng(0)
    m, k, n = 6, 3, 50
    A = rng.normal(size=(m, n, k))
    y = A @ np.array([1.0, -2.0, 0.5]) + rng.normal(0, 0.1, (m, n))
    stats = SegmentStats(np.arange(m), np.full(m, n), np.einsum("mni,mnj->mij", A, A),
                         np.einsum("mni,mn->mi", A, y), np.einsum("mn,mn->m", y, y), {})
    kept = np.ones(m, bool)
    cv = loso_cv(stats, kept)
    for j in range(m):
        o = np.delete(np.arange(m), j)
        c = np.linalg.lstsq(A[o].reshape(-1, k), y[o].ravel(), rcond=None)[0]
        assert cv["cv_residual_std_nT"][j] == pytest.approx(
            np.sqrt(np.mean((y[j] - A[j] @ c) ** 2)), rel=1e-8)


def test_vif_and_noise():
    rng = np.random.default_rng(1)
    X = rng.normal(size=(2000, 3))
    X[:, 2] = X[:, 0] + 0.1 * rng.normal(size=2000)
    v = variance_inflation(X.T @ X)
    assert v[1] == pytest.approx(1.0, abs=0.02) and v[0] > 50
    t = np.arange(5000) * 0.1
    x = rng.normal(0, 0.5, 5000) + np.sin(t / 20)
    assert fourth_difference_noise(x, t) == pytest.approx(0.5, rel=0.05)


def test_segment_stats_reuse(cal_result):
    res, _ = cal_result
    cfg = CompensationConfig()
    stats = segment_normal_equations(prepare(res.data, cfg), TERMS_16, cfg)
    assert len(stats.ids) == 12


def test_no_maneuvers_no_fom():
    t = np.arange(3000) * 0.1
    rng = np.random.default_rng(2)
    df = pd.DataFrame({"time": t, "mag": 50000 + rng.normal(0, 0.1, t.size),
                       "mag_comp": 50000 + rng.normal(0, 0.05, t.size)})
    q = compute_qc(CompensationResult(df, None, {}))
    assert q.metrics.fom.applicable is False and q.notes


def test_fourth_difference_noise_blocked_equals_direct():
    """Blocked moments give the std of all in-stretch fourth differences (gaps excluded)."""
    rng = np.random.default_rng(4)
    n = 200_003
    t = np.arange(n) * 0.1
    t[150_000:] += 30.0  # a gap: differences across it are left out
    x = rng.normal(0, 0.3, n) + np.sin(t / 50)
    x[70_000:70_010] = np.nan
    d4 = np.diff(np.nan_to_num(x), n=4)
    ok = np.isfinite(x)
    seg = np.cumsum(np.r_[True, ~(ok[1:] & ok[:-1] & (np.diff(t) <= 0.5))]) * ok
    same = (seg[4:] == seg[:-4]) & (seg[4:] > 0)
    want = np.std(d4[same]) / np.sqrt(70)
    assert fourth_difference_noise(x, t, 0.5) == pytest.approx(want, rel=1e-12)


def test_per_segment_residuals_agree_with_the_model_file_and_do_not_bleed():
    """Issue 15 item 3: a dropped faulty segment's filter must not leak into its kept
    neighbours; qc's per-segment residuals are the model file's; the headline is kept data."""
    df, _ = simulate_calibration(seed=4, n_boxes=1, faults={3: "noise_burst"})
    res = compensate(df)
    m = compute_qc(res, fit=False).metrics.to_dict()
    by_seg = m["residual_std_by_segment_nT"]
    for s in res.report.segments:
        assert by_seg[str(s.id)] == pytest.approx(s.residual_std, rel=1e-6), s.id
    assert 3 in res.report.screening.dropped
    assert by_seg["2"] < 0.02 and by_seg["4"] < 0.02  # the neighbours of the fault
    assert m["residual_std_nT"] < 0.02 < 0.1 < m["all_data"]["residual_std_nT"]
    assert m["improvement_ratio"] > 10 * m["all_data"]["improvement_ratio"]


def test_fom_only_for_complete_boxes():
    """Issue 15 item 4: no FOM headlined without a complete box; the JSON says why."""
    df, _ = simulate_calibration(seed=5, n_boxes=1)
    res = compensate(df)
    q = compute_qc(res, fit=False)
    tab = q.fom[~((q.fom["heading"] == "W") & (q.fom["maneuver"] == "yaw"))]
    s = fom_summary(tab)
    assert not s.applicable and s.fom_after_nT is None and s.fom_before_nT is None
    assert "W yaw" in s.reason and s.boxes[0].missing == ["W yaw"]
    assert s.per_maneuver == []
    # A survey flight: no manoeuvres, no FOM, and the reason.
    from aeromag.synthetic import simulate_survey

    sv, _ = simulate_survey(seed=1)
    fom = compute_qc(compensate(sv), fit=False).metrics.fom
    assert fom.applicable is False and fom.fom_after_nT is None
    assert "not applicable" in fom.reason
    # Not asked for (compensate without --fom): not applicable, not absent.
    fom = compute_qc(res, fit=False, fom=False).metrics.fom
    assert fom.applicable is False and "not computed" in fom.reason


def test_out_json_qc_block_is_compute_qc_of_mag_minus_mag_tl():
    """OUT.json's qc block is compute_qc's (band-passed mag - mag_tl per segment piece), not the
    old low-passed mag_comp per stretch; a saved model's per-segment residuals are its."""
    from aeromag.workflows.compensate import calibrate as wf_calibrate
    from aeromag.workflows.compensate import compensate as wf_compensate

    cal, _ = simulate_calibration(seed=5, n_boxes=1)
    model = wf_calibrate(cal).model
    sv, _ = simulate_calibration(seed=6, n_boxes=1)
    res = wf_compensate(sv, model=model)
    got = res.report.to_dict()["qc"]
    want = compute_qc(res, fit=False, fom=False).metrics
    assert got == want.to_dict()
    assert got["definition"] == res.report.metrics.definition
    for k in ("improvement_ratio", "residual_std_nT", "std_before_nT", "n_samples"):
        assert got[k] == getattr(res.report.metrics, k), k
    assert got["per_piece_rms"]["definition"].startswith("rms of mag and of mag - mag_tl")
    for e in res.report.segments:
        assert e.residual_std == got["residual_std_by_segment_nT"][str(e.id)]
    with pytest.raises(TypeError):
        quality_metrics(res.data, res.report, comp_bp=np.zeros(len(res.data)))


def test_fom_after_is_band_passed_mag_minus_mag_tl_not_mag_comp(cal_result):
    """The per-manoeuvre 'after' numbers are of mag - mag_tl band-passed once: a signal added
    to mag_comp alone (e.g. the final low-pass's doing) does not change them."""
    from aeromag._core.runs import run_bounds
    from aeromag.qc import detect_maneuvers
    from aeromag.qc.noise import band_passed

    res, _ = cal_result
    data = res.data.copy()
    t = data["time"].to_numpy(float)
    data["mag_comp"] = data["mag_comp"] + 50.0 * np.sin(2 * np.pi * 0.3 * t)
    man = detect_maneuvers(data)
    tab = fom_table(data, man, band_hz=(0.1, 0.9))
    assert tab.attrs["fields"] == {"before": "mag", "after": "mag - mag_tl",
                                   "truth": "truth_mag_tl"}
    r = (data["mag"] - data["mag_tl"]).to_numpy(float)
    from aeromag.qc.labels import kept_mask, segment_labels

    seg = segment_labels(data)
    dropped = np.where((seg >= 0) & ~kept_mask(data), seg, -1)  # each filtered on its own
    rf = band_passed(r, t, (0.1, 0.9), 4, None, split=dropped)
    a, b, ids = run_bounds(man.labels["maneuver_id"].to_numpy())
    for _, row in tab.iterrows():
        j = int(np.flatnonzero(ids == row["id"])[0])
        seg = rf[a[j]:b[j]]
        assert row["ptp_after_nT"] == pytest.approx(np.nanmax(seg) - np.nanmin(seg), rel=1e-12)
    assert tab["ptp_after_nT"].max() < 5.0  # not the 100 nT of the added mag_comp signal
    s = fom_summary(tab)
    assert s.fields["ptp_after_nT"] == "mag - mag_tl" and "peak-to-peak" in s.definition
