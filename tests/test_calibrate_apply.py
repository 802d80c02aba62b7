"""Calibrate on a simulated calibration flight, apply to a simulated survey (ground truth)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import signal

from aeromag.compensation.fit import fit_model
from aeromag.synthetic.calibration import simulate_calibration
from aeromag.synthetic.survey import simulate_survey
from aeromag.workflows.compensate import compensate


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_calibrate_then_apply_on_survey(seed):
    cal, cal_truth = simulate_calibration(seed=seed, faults=0.2)
    survey, truth = simulate_survey(seed=seed + 50)
    model = fit_model(cal).model
    res = compensate(survey, model=model)
    assert res.report.metrics.improvement_ratio >= 10
    err = (res.data["mag_comp"] - survey["truth_mag_clean"]).to_numpy()
    line = survey["line"].to_numpy()
    err = err - pd.Series(err).groupby(line).transform("mean").to_numpy()
    # The floor: the sensor's white noise through the same final low-pass ("filter leakage").
    fs = res.report.sampling_rate_hz
    sos = signal.butter(4, 0.9, fs=fs, output="sos")
    floor = np.std(signal.sosfiltfilt(
        sos, np.random.default_rng(0).normal(0, truth["noise_nT"], 200_000)))
    assert np.nanstd(err) <= 2 * floor
    # The interference itself is recovered to a small fraction of its size.
    d = res.data["mag_tl"].to_numpy() - survey["truth_mag_tl"].to_numpy()
    assert np.std(d - d.mean()) < 0.05 * np.std(survey["truth_mag_tl"])
