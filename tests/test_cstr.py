"""The stirred-tank reactor benchmark: simulator physics, filter model, detection, isolation.

A reduced Monte-Carlo study (fewer runs than the 200 of docs/detect.md, which come from
benchmarks/study_pf.py) keeps this affordable; every run of a set is filtered at once.
"""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from aeromag.detection.benchmark_models import (
    CSTR_HYPOTHESES,
    cstr_detect_isolate,
    cstr_model,
    cstr_threshold,
)
from aeromag.synthetic.benchmarks import CSTRParams, cstr_rhs, simulate_cstr

QUIET = CSTRParams(meas_sd=np.zeros(4), feed_T_sd=0.0, feed_C_sd=0.0)


def test_operating_point_is_a_steady_state():
    p = CSTRParams()
    x = np.array([p.C_A, p.T, p.T_C, p.h])
    d = cstr_rhs(x, p.Q_C, p.Q, p.Q_F, p.T_F, p.C_AF, p)
    # relative to each state's own rate scale (C_A turns over ~26 times a minute)
    scale = np.array([p.k0 * np.exp(-p.E_R / p.T) * p.C_A, 200.0, 68.0, 1.0])
    assert np.all(np.abs(d) / scale < 0.01), d / scale


@pytest.mark.parametrize("fault,check", [
    ("setpoint", lambda x, y: abs(x[1] - (402.35 + 3.0)) < 0.3),
    ("sensor_bias", lambda x, y: abs(x[1] - (402.35 - 4.0)) < 0.3 and abs(y[0] - 402.35) < 0.3),
    ("feed_flow", lambda x, y: abs(x[3] - (0.6 + 10.0 / 500.0)) < 2e-3),
])
def test_faults_move_the_closed_loop_as_the_controllers_say(fault, check):
    run = simulate_cstr(fault, duration_min=25.0, params=QUIET, seed=0)
    x, y = run.x[0, -1], run.y[0, -1]
    assert check(x, y), (x, y)
    free = simulate_cstr(None, duration_min=25.0, params=QUIET, seed=0)
    # the published operating point, to its printed precision (C_A 0.037 is 0.0372)
    np.testing.assert_allclose(free.x[0, -1], [0.037, 402.35, 345.44, 0.6], rtol=1e-2)


def test_filter_model_and_simulator_agree_without_noise():
    # two independent implementations of the same equations and controllers
    run = simulate_cstr("feed_flow", duration_min=3.0, onset_min=0.0, params=QUIET, seed=0)
    md = cstr_model("feed_flow")
    z = md.x0[None, :].copy()
    for k in range(1, run.time_min.size + 1):
        z = md.f(z, k, None)
    np.testing.assert_allclose(z[0, :4], run.x[0, -1], rtol=2e-3)


def test_hypothesis_models_differ_only_after_onset():
    onset = np.array([5, 50])
    md = cstr_model("sensor_bias", onset_step=onset)
    z = np.tile(md.x0, (2, 1, 1))
    np.testing.assert_allclose(md.h(z, 10)[0, 0, 0] - md.h(z, 10)[1, 0, 0], 4.0)
    assert set(CSTR_HYPOTHESES) == {"nominal", "setpoint", "sensor_bias", "feed_flow"}


@pytest.fixture(scope="module")
def threshold():
    free = simulate_cstr(None, n_runs=100, seed=10)
    th, stat = cstr_threshold(free.y, n_particles=200, window=10, percentile=99.0, seed=0)
    return th, stat


def test_threshold_from_fault_free_runs_and_false_alarm_rate(threshold):
    th, stat = threshold
    mx = np.nanmax(stat, axis=1)
    assert th.value == pytest.approx(np.percentile(mx, 99.0))
    assert th.false_alarm_rate <= 0.01
    # independent fault-free runs: at most 2 of 100 alarm (expected about 1)
    other = simulate_cstr(None, n_runs=100, seed=11)
    _, stat2 = cstr_threshold(other.y, n_particles=200, window=10, seed=5)
    far = np.mean(np.nanmax(stat2, axis=1) > th.value)
    assert far <= 0.02, far


def test_sensor_bias_detected_and_isolated(threshold):
    th, _ = threshold
    run = simulate_cstr("sensor_bias", n_runs=40, seed=20)
    st = cstr_detect_isolate(run.y, run.time_min, run.onset_min, th.value, n_particles=200,
                             window=10, seed=3)
    assert st.detected.mean() >= 0.95
    assert st.false_alarm.mean() <= 1 / 40
    assert np.nanmax(st.delay_min) < 1.0          # minutes after the onset
    iso = Counter(st.isolated)
    assert iso["sensor_bias"] / 40 >= 0.9, iso
    assert st.bank_stat is not None and st.bank_stat.shape[0] == 4
