"""The generic unscented Kalman filter: the Kalman filter on linear-Gaussian models, angle
handling, innovation statistics and divergence as a one-line error; the mechanisation."""

from __future__ import annotations

import numpy as np
import pytest

from aeromag._core.rotations import dcm_body_to_ned, euler_from_dcm
from aeromag.nav import DivergenceError, UnscentedKalmanFilter
from aeromag.nav.mechanization import GRAVITY, propagate, rotation_matrices


def _kalman(x, P, F, Q, H, R, zs):
    out = []
    for z in zs:
        x, P = F @ x, F @ P @ F.T + Q
        if np.all(np.isfinite(z)):
            S = H @ P @ H.T + R
            K = P @ H.T @ np.linalg.inv(S)
            x, P = x + K @ (z - H @ x), P - K @ S @ K.T
        out.append((x.copy(), P.copy()))
    return out


def test_ukf_run_equals_the_kalman_filter_on_a_linear_gaussian_model():
    rng = np.random.default_rng(7)
    dt = 0.1
    F = np.array([[1, dt, 0, 0], [0, 1, 0, 0], [0, 0, 1, dt], [0, 0, 0, 1.0]])
    Q = np.diag([1e-4, 1e-2, 1e-4, 1e-2])
    H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    R = np.diag([0.5, 0.3])
    x0, P0 = np.array([0.0, 1.0, 0.0, -0.5]), np.eye(4)
    zs = rng.normal(size=(60, 2))
    zs[10:15] = np.nan                      # predict-only rows
    ukf = UnscentedKalmanFilter(x0, P0, fx=lambda X: X @ F.T, Q=Q, hx=lambda X: X @ H.T, R=R)
    res = ukf.run(zs, keep_cov=True)
    ref = _kalman(x0, P0, F, Q, H, R, zs)
    for k, (x, P) in enumerate(ref):
        np.testing.assert_allclose(res.state[k], x, rtol=1e-9, atol=1e-10)
        np.testing.assert_allclose(res.info["cov"][k], P, rtol=1e-9, atol=1e-12)
    st = ukf.innovations["z"]
    assert st.n_fused == 55 and st.dof == 2 and st.mean_nis > 0


def test_angles_are_wrapped_and_averaged_circularly():
    # A heading near +-180°: measured at -179°, predicted at +179°: the innovation is -2°,
    # not +358°.
    ukf = UnscentedKalmanFilter(np.array([np.deg2rad(179.0)]), np.array([[np.deg2rad(5) ** 2]]),
                                fx=lambda X: X, hx=lambda X: X, R=np.array([[np.deg2rad(5) ** 2]]),
                                angle_idx=[0])
    nis = ukf.update(np.array([np.deg2rad(-179.0)]), angle_idx=[0])
    assert np.rad2deg(ukf.x[0]) == pytest.approx(180.0, abs=1e-6) or \
        np.rad2deg(ukf.x[0]) == pytest.approx(-180.0, abs=1e-6)
    assert nis == pytest.approx((2.0 / 5.0) ** 2 / 2.0, rel=1e-6)


def test_gate_rejects_outliers_and_counts_them():
    ukf = UnscentedKalmanFilter(np.zeros(1), np.eye(1), fx=lambda X: X, hx=lambda X: X,
                                R=np.eye(1), gate=9.0)
    assert np.isnan(ukf.update(np.array([100.0])))
    assert ukf.innovations["z"].n_rejected == 1 and ukf.x[0] == 0.0


def test_non_finite_covariance_is_a_one_line_divergence_error():
    ukf = UnscentedKalmanFilter(np.zeros(2), np.eye(2), fx=lambda X: X * np.inf)
    ukf.time_s = 12.5
    with np.errstate(invalid="ignore"):
        ukf.predict()
        with pytest.raises(DivergenceError, match=r"diverged at t = 12.500 s") as err:
            ukf.predict()
    assert "\n" not in str(err.value)


def test_mechanisation_against_closed_forms():
    # Constant rotation about z at 0.5 rad/s for 2 s, at rest (specific force -g): the yaw
    # advances by 1 rad; no velocity builds up; the batched scan equals one-by-one steps.
    N, dt = 500, 0.004
    gyro = np.tile([0.0, 0.0, 0.5], (N, 1))
    acc = np.tile([0.0, 0.0, -GRAVITY], (N, 1))
    X = np.zeros((3, 12))
    X[1, 6] = 0.01   # a tilted sigma point: its specific force leaks gravity sideways
    X[2, 9:12] = [0.0, 0.0, 0.1]   # a gyro-biased one turns slower
    W = np.array([0.5, 0.25, 0.25])
    end, (mean, var6) = propagate(X, gyro, acc, np.full(N, dt), weights=(W, W))
    assert end[0, 8] == pytest.approx(1.0, abs=1e-12)
    assert end[2, 8] == pytest.approx(0.8, abs=1e-12)
    np.testing.assert_allclose(end[0, 3:6], 0.0, atol=1e-12)
    one = X.copy()
    for k in range(N):
        one, _ = propagate(one, gyro[k:k + 1], acc[k:k + 1], np.array([dt]))
    np.testing.assert_allclose(end, one, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(mean[-1, :6], W @ end[:, :6], atol=1e-12)
    np.testing.assert_allclose(mean[-1, 8], W @ end[:, 8], atol=1e-3)   # chordal mean
    np.testing.assert_allclose(var6[-1], W @ (end[:, :6] - W @ end[:, :6]) ** 2, atol=1e-12)
    # Free fall: zero specific force, v = g t, d = g t^2 / 2.
    end2, _ = propagate(np.zeros((1, 12)), np.zeros((N, 3)), np.zeros((N, 3)), np.full(N, dt))
    T = N * dt
    assert end2[0, 5] == pytest.approx(GRAVITY * T, rel=1e-12)
    assert end2[0, 2] == pytest.approx(0.5 * GRAVITY * T**2, rel=1e-12)


def test_rotation_matrices_are_rotations_and_match_euler():
    rng = np.random.default_rng(3)
    w = rng.normal(size=(50, 3)) * 0.5
    w[0] = 0.0
    w[1] = [1e-9, 0, 0]
    R = rotation_matrices(w)
    np.testing.assert_allclose(np.einsum("kji,kjl->kil", R, R), np.broadcast_to(np.eye(3),
                               R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    # A pure yaw rotation vector equals the Euler DCM of that yaw.
    Rz = rotation_matrices(np.array([0.0, 0.0, 0.7]))
    np.testing.assert_allclose(Rz, dcm_body_to_ned(0.0, 0.0, 0.7), atol=1e-12)
    r, p, y = euler_from_dcm(Rz)
    assert y == pytest.approx(0.7)
