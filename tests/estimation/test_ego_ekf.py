"""Tests of the ego error-state EKF: Jacobians by finite differences, exact cases, NEES consistency."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

from alight.errors import EstimationError
from alight.estimation.ego_ekf import (
    EgoEkf,
    EgoEkfConfig,
    _mahalanobis2_3,
    ego_error_jacobian,
    ego_inject,
    ego_step,
    odometry_jacobian,
    odometry_residual,
    so3_left_jacobian_inv,
    so3_right_jacobian,
)
from alight.numerics.rotation import quat_exp, quat_log, quat_mul, quat_to_R
from alight.types import GRAVITY_MPS2, quat_to_rotmat

G_W = np.array([0.0, 0.0, -GRAVITY_MPS2])


# ---------------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------------


def random_nominal(rng: np.random.Generator) -> np.ndarray:
    x = np.zeros(16)
    x[0:3] = rng.normal(0, 3, 3)
    x[3:6] = rng.normal(0, 2, 3)
    x[6:10] = Rotation.random(random_state=rng).as_quat()
    x[10:13] = rng.normal(0, 0.2, 3)
    x[13:16] = rng.normal(0, 0.05, 3)
    return x


def boxplus(x: np.ndarray, dx: np.ndarray) -> np.ndarray:
    y = x.copy()
    ego_inject(y, dx)
    return y


def boxminus(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Error state ``d`` with ``a = b [+] d`` (quaternion helpers: checked against SciPy above, and
    several times faster than SciPy objects for single rotations)."""
    d = np.empty(15)
    d[0:6] = a[0:6] - b[0:6]
    qe = np.empty(4)
    quat_mul(b[6:10] * np.array([-1.0, -1.0, -1.0, 1.0]), a[6:10], qe)
    quat_log(qe / np.linalg.norm(qe), d[6:9])
    d[9:15] = a[10:16] - b[10:16]
    return d


def numeric_jacobian(fun, x: np.ndarray, n_in: int, eps: float = 1e-6) -> np.ndarray:
    """Central differences of ``fun(dx) -> (m,)`` at dx = 0."""
    cols = []
    for j in range(n_in):
        d = np.zeros(n_in)
        d[j] = eps
        cols.append((fun(d) - fun(-d)) / (2 * eps))
    return np.array(cols).T


# ---------------------------------------------------------------------------------------------------
# SO(3) helpers
# ---------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("angle", [0.0, 1e-6, 1e-3, 0.3, 2.0, 3.1])
def test_quaternion_helpers_match_scipy(angle: float) -> None:
    rng = np.random.default_rng(1)
    axis = rng.normal(size=3)
    phi = angle * axis / np.linalg.norm(axis)
    q = np.empty(4)
    quat_exp(phi, q)
    ref = Rotation.from_rotvec(phi)
    assert np.allclose(q, ref.as_quat(), atol=1e-12) or np.allclose(q, -ref.as_quat(), atol=1e-12)
    R = np.empty((3, 3))
    quat_to_R(q, R)
    assert np.allclose(R, ref.as_matrix(), atol=1e-12)
    assert np.allclose(R, quat_to_rotmat(q), atol=1e-12)
    back = np.empty(3)
    quat_log(q, back)
    assert np.allclose(back, phi, atol=1e-10)


@pytest.mark.parametrize("angle", [0.0, 5e-5, 1e-3, 0.5, 2.5])
def test_so3_jacobians_by_finite_differences(angle: float) -> None:
    rng = np.random.default_rng(2)
    axis = rng.normal(size=3)
    phi = angle * axis / np.linalg.norm(axis)
    R0 = Rotation.from_rotvec(phi)

    def right(d: np.ndarray) -> np.ndarray:  # Exp(phi)^-1 Exp(phi + d) = Exp(J_r d)
        return (R0.inv() * Rotation.from_rotvec(phi + d)).as_rotvec()

    def left_inv(d: np.ndarray) -> np.ndarray:  # Log(Exp(d) Exp(phi))
        return (Rotation.from_rotvec(d) * R0).as_rotvec()

    Jr = np.empty((3, 3))
    so3_right_jacobian(phi, Jr)
    Jli = np.empty((3, 3))
    so3_left_jacobian_inv(phi, Jli)
    assert np.allclose(Jr, numeric_jacobian(right, phi, 3), atol=1e-8)
    assert np.allclose(Jli, numeric_jacobian(left_inv, phi, 3), atol=1e-8)


# ---------------------------------------------------------------------------------------------------
# Jacobians of the filter
# ---------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("dt", [0.005, 0.05, 0.3])
def test_process_jacobian_by_finite_differences(dt: float) -> None:
    rng = np.random.default_rng(3)
    for _ in range(10):
        x = random_nominal(rng)
        f = rng.normal(0, 3, 3) + np.array([0, 0, 9.81])
        w = rng.normal(0, 1.5, 3)
        x1 = np.empty(16)
        ego_step(x, f, w, dt, GRAVITY_MPS2, x1)

        def fun(dx: np.ndarray, x=x, f=f, w=w, x1=x1) -> np.ndarray:
            out = np.empty(16)
            ego_step(boxplus(x, dx), f, w, dt, GRAVITY_MPS2, out)
            return boxminus(out, x1)

        F = np.empty((15, 15))
        ego_error_jacobian(x, f, w, dt, F)
        Fn = numeric_jacobian(fun, x, 15)
        assert np.allclose(F, Fn, atol=1e-7 * max(1.0, np.abs(Fn).max())), np.abs(F - Fn).max()


@pytest.mark.parametrize("with_velocity", [False, True])
def test_odometry_jacobian_by_finite_differences(with_velocity: bool) -> None:
    rng = np.random.default_rng(4)
    m = 9 if with_velocity else 6
    for _ in range(10):
        x = random_nominal(rng)
        z = np.zeros(10)
        z[0:3] = x[0:3] + rng.normal(0, 0.3, 3)
        # attitude residuals up to ~0.8 rad, where J_l^{-1} differs clearly from the identity
        z[3:7] = (Rotation.from_quat(x[6:10]) * Rotation.from_rotvec(rng.normal(0, 0.5, 3))).as_quat()
        z[7:10] = x[3:6] + rng.normal(0, 0.3, 3)

        def fun(dx: np.ndarray, x=x, z=z) -> np.ndarray:
            r = np.empty(m)
            odometry_residual(boxplus(x, dx), z, m, r)
            return r

        r = np.empty(m)
        odometry_residual(x, z, m, r)
        H = np.empty((m, 15))
        odometry_jacobian(r, m, H)
        assert np.allclose(-H, numeric_jacobian(fun, x, 15), atol=1e-7)


# ---------------------------------------------------------------------------------------------------
# exact cases
# ---------------------------------------------------------------------------------------------------


def test_hover_and_constant_rate_are_exact() -> None:
    """At rest with the gravity reaction measured, nothing moves; a constant rate turns by rate * t."""
    ekf = EgoEkf()
    q0 = Rotation.from_rotvec([0.1, -0.2, 0.7])
    ekf.initialize(0.0, [1.0, 2.0, 3.0], [0.0, 0.0, 0.0], q0.as_quat())
    w = np.array([0.3, -0.2, 0.5])
    for k in range(1, 201):
        # the specific force of a body at rest, in the body frame at that moment
        Rk = q0 * Rotation.from_rotvec(w * k * 0.005)
        ekf.predict_imu(k * 0.005, Rk.inv().apply(-G_W), w)
    s = ekf.state()
    assert np.allclose(s.p_WB, [1, 2, 3], atol=2e-4)
    assert np.allclose(s.v_WB, 0, atol=5e-4)
    expected = q0 * Rotation.from_rotvec(w * 1.0)
    assert (Rotation.from_quat(s.q_WB).inv() * expected).magnitude() < 1e-12
    assert np.allclose(s.w_WB_B, w)


def test_integration_is_second_order() -> None:
    """Dead reckoning on a smooth noise-free trajectory: halving the IMU period quarters the error."""
    errs = []
    for rate in (100.0, 200.0, 400.0):
        traj = SmoothTrajectory()
        ts = np.arange(0.0, 2.0 + 1e-9, 1.0 / rate)
        p, v, q, f, w, _ = traj.sample(ts)
        ekf = EgoEkf()
        ekf.initialize(0.0, p[0], v[0], q[0])
        for k in range(1, len(ts)):
            ekf.predict_imu(ts[k], f[k], w[k])
        errs.append(np.linalg.norm(ekf.state().p_WB - p[-1]))
    assert errs[0] / errs[1] > 3.5 and errs[1] / errs[2] > 3.5, errs


def test_state_outputs_follow_the_imu_model() -> None:
    ekf = EgoEkf()
    q = Rotation.from_rotvec([0.2, 0.1, -0.4])
    b_a = np.array([0.1, -0.05, 0.2])
    b_g = np.array([0.01, 0.02, -0.03])
    ekf.initialize(0.0, np.zeros(3), np.zeros(3), q.as_quat(), b_a=b_a, b_g=b_g)
    f = np.array([0.5, -0.3, 10.2])
    w = np.array([0.0, 0.0, 0.0])
    ekf.predict_imu(0.0, f, w)  # at the filter time: refreshes the sample, no motion
    s = ekf.state()
    assert np.allclose(s.w_WB_B, w - b_g)
    assert np.allclose(s.a_WB, q.apply(f - b_a) + G_W)
    assert np.allclose(s.p_WB, 0) and np.allclose(s.v_WB, 0)


# ---------------------------------------------------------------------------------------------------
# input handling
# ---------------------------------------------------------------------------------------------------


def test_non_finite_inputs_raise_and_leave_the_filter_untouched() -> None:
    ekf = EgoEkf()
    ekf.initialize(0.0, np.zeros(3), np.zeros(3), [0, 0, 0, 1])
    ekf.predict_imu(0.005, [0, 0, 9.81], [0, 0, 0.1])
    x0, P0 = ekf.nominal, ekf.covariance
    with pytest.raises(EstimationError):
        ekf.predict_imu(0.01, [0, np.nan, 9.81], [0, 0, 0.1])
    with pytest.raises(EstimationError):
        ekf.predict_imu(0.01, [0, 0, 9.81], [0, 0, np.inf])
    with pytest.raises(EstimationError):
        ekf.predict_imu(math.nan, [0, 0, 9.81], [0, 0, 0])
    with pytest.raises(EstimationError):
        ekf.update_odometry(0.01, [0, np.nan, 0], [0, 0, 0, 1])
    with pytest.raises(EstimationError):
        ekf.update_odometry(0.005, [0, 0, 0], [0, 0, 0, 1], cov_p=np.full((3, 3), np.nan))
    with pytest.raises(EstimationError):
        ekf.predict_imu(0.0, [0, 0, 9.81], [0, 0, 0])  # backwards in time
    with pytest.raises(EstimationError):
        ekf.predict_imu(0.01, [0, 0], [0, 0, 0])
    assert np.array_equal(ekf.nominal, x0) and np.array_equal(ekf.covariance, P0)
    assert ekf.t == 0.005


def test_stale_odometry_is_rejected_and_slight_lag_compensated() -> None:
    cfg = EgoEkfConfig(max_odometry_lag=0.02)
    ekf = EgoEkf(cfg)
    v = np.array([2.0, 0.0, 0.0])
    ekf.initialize(0.0, np.zeros(3), v, [0, 0, 0, 1])
    for k in range(1, 21):
        ekf.predict_imu(k * 0.005, [0, 0, GRAVITY_MPS2], [0, 0, 0])
    assert not ekf.update_odometry(0.05, [0.1, 0, 0], [0, 0, 0, 1])  # 50 ms old
    assert ekf.n_odometry_rejected == 1
    # 10 ms old, taken where the body was then: moved forward by v * lag, so the residual is ~0
    p_before = ekf.state().p_WB.copy()
    assert ekf.update_odometry(0.09, p_before - v * 0.01, [0, 0, 0, 1])
    assert np.allclose(ekf.state().p_WB, p_before, atol=1e-9)


def test_odometry_ahead_of_the_imu_propagates_first() -> None:
    ekf = EgoEkf()
    ekf.initialize(0.0, np.zeros(3), [1.0, 0, 0], [0, 0, 0, 1])
    # no IMU yet: the velocity is held, so an odometry at t = 0.1 agreeing with it changes nothing
    assert ekf.update_odometry(0.1, [0.1, 0, 0], [0, 0, 0, 1])
    assert ekf.t == pytest.approx(0.1)
    assert np.allclose(ekf.state().p_WB, [0.1, 0, 0], atol=1e-9)


# ---------------------------------------------------------------------------------------------------
# NEES consistency on simulated data with matching noise
# ---------------------------------------------------------------------------------------------------


class SmoothTrajectory:
    """A smooth 3D trajectory with rotation, sampled analytically (ZYX Euler angles)."""

    def __init__(self, phase: float = 0.0) -> None:
        self.ph = phase

    def sample(self, t: np.ndarray):
        ph = self.ph
        # position and its derivatives
        A = np.array([2.0, 1.5, 0.5])
        W = np.array([0.5, 0.7, 0.9])
        P0 = np.array([0.0, 0.3, 0.0]) + ph
        arg = np.outer(t, W) + P0
        p = A * np.sin(arg) + np.array([0.0, 0.0, 1.5])
        v = A * W * np.cos(arg)
        a = -A * W**2 * np.sin(arg)
        # yaw psi, pitch th, roll phi and their rates
        psi = 0.4 * t + 0.3 * np.sin(0.6 * t + ph)
        dpsi = 0.4 + 0.18 * np.cos(0.6 * t + ph)
        th = 0.15 * np.sin(0.8 * t + 0.2 + ph)
        dth = 0.12 * np.cos(0.8 * t + 0.2 + ph)
        phi = 0.2 * np.sin(1.0 * t + ph)
        dphi = 0.2 * np.cos(1.0 * t + ph)
        rot = Rotation.from_euler("ZYX", np.column_stack([psi, th, phi]))
        w = np.column_stack(
            [
                dphi - dpsi * np.sin(th),
                dth * np.cos(phi) + dpsi * np.cos(th) * np.sin(phi),
                -dth * np.sin(phi) + dpsi * np.cos(th) * np.cos(phi),
            ]
        )
        f = rot.inv().apply(a - G_W)
        return p, v, rot.as_quat(), f, w, rot


def test_truth_generator_body_rates_match_attitude() -> None:
    """The analytic body rates are R^T dR/dt of the analytic attitude (checks the test's own truth)."""
    traj = SmoothTrajectory(0.7)
    t = np.array([0.3, 1.7, 4.2])
    h = 1e-5
    _, _, _, _, w, R = traj.sample(t)
    _, _, _, _, _, Rp = traj.sample(t + h)
    _, _, _, _, _, Rm = traj.sample(t - h)
    w_num = ((Rm.inv() * Rp).as_rotvec()) / (2 * h)
    assert np.allclose(w, w_num, atol=1e-7)


NEES_CONFIG = EgoEkfConfig(
    accel_noise_density=0.05,
    gyro_noise_density=5e-3,
    accel_bias_random_walk=0.01,
    gyro_bias_random_walk=1e-3,
    init_position_std=0.1,
    init_velocity_std=0.1,
    init_attitude_std=0.05,
    init_accel_bias_std=0.1,
    init_gyro_bias_std=0.01,
    odometry_position_std=0.03,
    odometry_attitude_std=0.02,
    odometry_velocity_std=0.05,
)


def run_nees(
    truth_cfg: EgoEkfConfig,
    filter_cfg: EgoEkfConfig,
    runs: int,
    duration: float,
    seed: int,
    with_velocity: bool = False,
) -> np.ndarray:
    """NEES (runs, updates) of the filter after each odometry update; the data follow ``truth_cfg``."""
    cfg = truth_cfg
    rng = np.random.default_rng(seed)
    imu_rate, odo_every = 200.0, 5
    dt = 1.0 / imu_rate
    ts = np.arange(0.0, duration + 1e-9, dt)
    n = len(ts)
    L0 = np.linalg.cholesky(cfg.initial_covariance())
    nees = []
    for _ in range(runs):
        traj = SmoothTrajectory(phase=rng.uniform(0, 2 * np.pi))
        p, v, q, f, w, rot = traj.sample(ts)
        # biases: random walks starting from the prior
        b_a = rng.normal(0, cfg.init_accel_bias_std, 3) + np.cumsum(
            np.vstack([np.zeros(3), rng.normal(0, cfg.accel_bias_random_walk * math.sqrt(dt), (n - 1, 3))]),
            axis=0,
        )
        b_g = rng.normal(0, cfg.init_gyro_bias_std, 3) + np.cumsum(
            np.vstack([np.zeros(3), rng.normal(0, cfg.gyro_bias_random_walk * math.sqrt(dt), (n - 1, 3))]),
            axis=0,
        )
        f_m = f + b_a + rng.normal(0, cfg.accel_noise_density / math.sqrt(dt), (n, 3))
        w_m = w + b_g + rng.normal(0, cfg.gyro_noise_density / math.sqrt(dt), (n, 3))
        # odometry: R_meas = R Exp(n_theta), as the filter models it
        z_p = p + rng.normal(0, cfg.odometry_position_std, (n, 3))
        z_q = (rot * Rotation.from_rotvec(rng.normal(0, cfg.odometry_attitude_std, (n, 3)))).as_quat()
        z_v = v + rng.normal(0, cfg.odometry_velocity_std, (n, 3))
        # the initial estimate is the truth displaced by a draw from the initial covariance
        truth0 = np.concatenate([p[0], v[0], q[0], b_a[0], b_g[0]])
        e0 = boxplus(truth0, L0 @ rng.normal(size=15))
        ekf = EgoEkf(filter_cfg)
        ekf.initialize(0.0, e0[0:3], e0[3:6], e0[6:10], b_a=e0[10:13], b_g=e0[13:16])
        run_nees = []
        for k in range(1, n):
            ekf.predict_imu(ts[k], f_m[k], w_m[k])
            if k % odo_every == 0:
                assert ekf.update_odometry(ts[k], z_p[k], z_q[k], z_v[k] if with_velocity else None)
                truth = np.concatenate([p[k], v[k], q[k], b_a[k], b_g[k]])
                e = boxminus(truth, ekf.nominal)
                run_nees.append(e @ np.linalg.solve(ekf.covariance, e))
        nees.append(run_nees)
    return np.array(nees)


@pytest.mark.parametrize("with_velocity", [False, True])
def test_nees_is_consistent(with_velocity: bool) -> None:
    """Average NEES over Monte-Carlo runs lies inside the chi-square 95 % interval at most times."""
    runs = 24
    avg = run_nees(NEES_CONFIG, NEES_CONFIG, runs, 6.0, 20240601, with_velocity).mean(axis=0)
    lo, hi = chi2.ppf([0.025, 0.975], runs * 15) / runs
    inside = np.mean((avg > lo) & (avg < hi))
    # a consistent filter has ~95 % of the times inside; time correlation widens the spread a little
    assert inside > 0.85, (inside, avg.mean(), lo, hi)
    assert lo < avg.mean() < hi, (avg.mean(), lo, hi)


@pytest.mark.parametrize("with_velocity", [False, True])
def test_update_matches_the_information_form(with_velocity: bool) -> None:
    """With the optimal gain the Joseph form equals P+ = (P^-1 + H^T R^-1 H)^-1 and the correction is
    P+ H^T R^-1 r. The attitude residual is zero and P has no attitude cross-terms, so the correction
    of the attitude is zero and the reset Jacobian is the identity."""
    rng = np.random.default_rng(5)
    ekf = EgoEkf()
    x = random_nominal(rng)
    A = rng.normal(size=(15, 15))
    P = A @ A.T * 0.01 + np.eye(15) * 0.01
    P[6:9, :] = 0.0
    P[:, 6:9] = 0.0
    P[6:9, 6:9] = np.diag([1e-3, 2e-3, 3e-3])
    ekf.initialize(0.0, x[0:3], x[3:6], x[6:10], b_a=x[10:13], b_g=x[13:16], covariance=P)
    z_p = x[0:3] + rng.normal(0, 0.1, 3)
    z_v = x[3:6] + rng.normal(0, 0.1, 3) if with_velocity else None
    cov_p = np.diag([0.01, 0.02, 0.03])
    cov_v = np.diag([0.02, 0.01, 0.04])
    ekf.update_odometry(0.0, z_p, x[6:10], z_v, cov_p=cov_p, cov_theta=np.eye(3) * 1e-4, cov_v=cov_v)
    m = 9 if with_velocity else 6
    H = np.zeros((m, 15))
    H[0:3, 0:3] = np.eye(3)
    H[3:6, 6:9] = np.eye(3)
    R = np.zeros((m, m))
    R[0:3, 0:3] = cov_p
    R[3:6, 3:6] = np.eye(3) * 1e-4
    r = np.zeros(m)
    r[0:3] = z_p - x[0:3]
    if with_velocity:
        H[6:9, 3:6] = np.eye(3)
        R[6:9, 6:9] = cov_v
        r[6:9] = z_v - x[3:6]
    P_post = np.linalg.inv(np.linalg.inv(P) + H.T @ np.linalg.solve(R, H))
    dx = P_post @ H.T @ np.linalg.solve(R, r)
    assert np.allclose(ekf.covariance, P_post, atol=1e-12)
    assert np.allclose(boxminus(ekf.nominal, x), dx, atol=1e-12)
    assert ekf.last_nis == pytest.approx(r @ np.linalg.solve(H @ P @ H.T + R, r))


def test_predict_imu_many_equals_one_call_per_sample() -> None:
    rng = np.random.default_rng(3)
    a, b = EgoEkf(), EgoEkf()
    q0 = np.array([0.0, 0.0, 0.0, 1.0])
    for f in (a, b):
        f.initialize(0.0, np.zeros(3), np.zeros(3), q0)
    ts = 0.005 * np.arange(1, 41)
    fs = np.array([0.0, 0.0, 9.81]) + 0.3 * rng.standard_normal((40, 3))
    ws = 0.2 * rng.standard_normal((40, 3))
    for t, f_B, w_B in zip(ts, fs, ws, strict=True):
        a.predict_imu(t, f_B, w_B)
    b.predict_imu_many(ts[:25], fs[:25], ws[:25])
    b.predict_imu_many(ts[25:], fs[25:], ws[25:])
    np.testing.assert_array_equal(a.nominal, b.nominal)
    np.testing.assert_array_equal(a.covariance, b.covariance)
    assert a.t == b.t
    bad = fs[:3].copy()
    bad[1, 0] = np.nan
    with pytest.raises(EstimationError):
        b.predict_imu_many(ts[-1] + 0.005 * np.arange(1, 4), bad, ws[:3])
    assert b.t == ts[-1] + 0.005  # the sample before the bad one was applied, nothing after


def test_predict_imu_many_rejects_time_going_backwards() -> None:
    f = EgoEkf()
    f.initialize(0.0, np.zeros(3), np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
    ts = np.array([0.005, 0.010, 0.007, 0.015])
    fs = np.tile([0.0, 0.0, 9.81], (4, 1))
    with pytest.raises(EstimationError, match="before the filter time"):
        f.predict_imu_many(ts, fs, np.zeros((4, 3)))
    assert f.t == 0.010  # the two good samples were applied


def test_odometry_gate_distance_matches_a_linear_solve() -> None:
    """The gate's e^T S^-1 e (Python floats, by the adjugate) against numpy's solve; None when singular."""
    rng = np.random.default_rng(3)
    for _ in range(200):
        A = rng.normal(size=(3, 3))
        S = A @ A.T + np.diag(rng.uniform(1e-4, 1.0, 3))
        e = rng.normal(size=3) * rng.uniform(0.01, 10.0)
        expected = float(e @ np.linalg.solve(S, e))
        assert _mahalanobis2_3(S.tolist(), e.tolist()) == pytest.approx(expected, rel=1e-9)
    assert _mahalanobis2_3([[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 0.0, 1.0]], [1.0, 0.0, 0.0]) is None
