"""Estimators against bad input (alight.estimation.guards): refused without a NaN state, nothing blocked
by a measurement from the future, bounded work for any gap."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from alight.cameras import CameraMount, MountedCamera
from alight.errors import EstimationError, MeasurementError
from alight.estimation import PLATFORM_ESTIMATORS, EgoEkf, PlatformEkf, PlatformEstimator, SduKalmanFilter
from alight.types import PlatformMeasurement

COV = np.diag([0.05**2] * 3)


def platform_estimator(name: str) -> PlatformEstimator:
    """The registry's block ``name`` at the parameters it flies with, without a camera."""
    return PLATFORM_ESTIMATORS[name].build_default(MountedCamera(camera=None, mount=CameraMount.downward()))


def truth(t: float) -> np.ndarray:
    return np.array([1.5 * t, 0.0, 0.5])


def meas(t: float, p: np.ndarray | None = None, cov: np.ndarray = COV) -> PlatformMeasurement:
    return PlatformMeasurement(t, truth(t) if p is None else p, cov)


def raw(t: float, p: object, cov: object) -> PlatformMeasurement:
    """A measurement past PlatformMeasurement's own checks, as a faulty upstream block could make."""
    m = object.__new__(PlatformMeasurement)
    for k, v in {"t": t, "p_WP": np.asarray(p, float), "cov_p_WP": np.asarray(cov, float)}.items():
        object.__setattr__(m, k, v)
    for k in ("yaw", "yaw_var", "n_WP", "cov_n_WP"):  # the optional fields, as __init__ would leave them
        object.__setattr__(m, k, None)
    return m


def track(est: object, t_end: float, t0: float = 0.0, clock: bool = True) -> float:
    t = t0
    while t < t_end:
        t = round(t + 0.1, 10)
        if clock:
            est.predict(t)  # type: ignore[attr-defined]
        est.update(meas(t))  # type: ignore[attr-defined]
    return t


@pytest.mark.parametrize("name", sorted(PLATFORM_ESTIMATORS))
@pytest.mark.parametrize(
    "bad",
    [
        raw(2.05, [1e12, 0, 0], COV),
        raw(2.05, [3.0, 0, 0.5], -COV),
        raw(2.05, [3.0, 0, 0.5], COV + np.array([[0, 1.0, 0], [0, 0, 0], [0, 0, 0]])),
        raw(1e300, [3.0, 0, 0.5], COV),
    ],
    ids=["far", "negative_cov", "asymmetric_cov", "time_1e300"],
)
def test_absurd_measurements_raise_and_change_nothing(name: str, bad: PlatformMeasurement) -> None:
    est = platform_estimator(name)
    t = track(est, 2.0)
    before = est.state(t)
    with pytest.raises(MeasurementError):
        est.update(bad)
    after = est.state(t)
    assert np.array_equal(before.p_WP, after.p_WP) and np.array_equal(before.cov_p_WP, after.cov_p_WP)


@pytest.mark.parametrize("name", sorted(PLATFORM_ESTIMATORS))
def test_a_measurement_from_the_future_is_refused_against_the_clock(name: str) -> None:
    est = platform_estimator(name)
    t = track(est, 2.0)
    assert est.update(meas(t + 1000.0)) is False
    t_end = track(est, 4.0, t)
    assert np.linalg.norm(est.state(t_end).p_WP - truth(t_end)) < 0.3


@pytest.mark.parametrize("cls", [PlatformEkf, SduKalmanFilter])
def test_without_a_clock_a_future_stamp_blocks_only_a_few_measurements(cls: type) -> None:
    est = cls()
    t = track(est, 2.0, clock=False)
    # where the platform is, but stamped 1000 s late: without a clock the EKF takes it (nothing says it
    # is wrong yet); the SDU filter's gate refuses it (its prediction has moved 1.5 km in 1000 s)
    assert est.update(meas(t + 1000.0, truth(t))) is (cls is PlatformEkf)
    used = [est.update(meas(round(t + 0.1 * k, 10))) for k in range(1, 21)]
    assert sum(used) >= 15  # the run of "too old" ones restarts the filter after 5
    t_end = round(t + 2.0, 10)
    assert np.linalg.norm(est.state(t_end).p_WP - truth(t_end)) < 0.5


@pytest.mark.parametrize("name", sorted(PLATFORM_ESTIMATORS))
def test_a_huge_gap_costs_bounded_work_and_stays_finite(name: str) -> None:
    est = platform_estimator(name)
    t = track(est, 2.0)
    t0 = time.perf_counter()
    s = est.state(t + 1e7)  # took 76 s in PlatformEkf before the horizon
    assert time.perf_counter() - t0 < 1.0
    assert np.isfinite(s.p_WP).all() and np.isfinite(s.cov_p_WP).all()
    with pytest.raises(EstimationError):
        est.state(1e300)


def test_sdu_gate_refuses_a_50_m_outlier_and_restarts_after_a_run() -> None:
    est = SduKalmanFilter()
    t = track(est, 3.0)
    t = round(t + 0.1, 10)
    est.predict(t)
    assert est.update(meas(t, truth(t) + [50.0, 0, 0])) is False and est.n_gated == 1
    assert np.linalg.norm(est.state(t).p_WP - truth(t)) < 0.3  # 13.5 m before the gate
    # a platform that really moved: five in a row restart the track there
    for _ in range(6):
        t = round(t + 0.1, 10)
        est.predict(t)
        est.update(meas(t, truth(t) + [50.0, 0, 0]))
    assert np.linalg.norm(est.state(t).p_WP - (truth(t) + [50.0, 0, 0])) < 1.0


def _ego() -> EgoEkf:
    ekf = EgoEkf()
    ekf.initialize(0.0, np.zeros(3), np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
    ts = 0.005 * np.arange(1, 21)
    ekf.predict_imu_many(ts, np.tile([0.0, 0.0, 9.81], (20, 1)), np.zeros((20, 3)))
    return ekf


@pytest.mark.parametrize(
    ("p", "q"),
    [
        (np.zeros(3), np.zeros(4)),
        (np.zeros(3), np.array([math.nan, 0, 0, 1])),
        (np.array([1e12, 0, 0]), np.array([0.0, 0, 0, 1])),
    ],
    ids=["zero_quaternion", "nan_quaternion", "position_1e12"],
)
def test_ego_refuses_odometry_that_is_not_a_pose(p: np.ndarray, q: np.ndarray) -> None:
    ekf = _ego()
    before = ekf.nominal
    with pytest.raises(EstimationError):
        ekf.update_odometry(ekf.t, p, q)
    assert np.array_equal(before, ekf.nominal)


def test_ego_gates_a_jump_and_restarts_after_a_run() -> None:
    ekf = _ego()
    q = np.array([0.0, 0.0, 0.0, 1.0])
    assert ekf.update_odometry(ekf.t, np.array([500.0, 0, 0]), q) is False and ekf.n_odometry_gated == 1
    assert np.linalg.norm(ekf.state().p_WB) < 0.1
    for _ in range(ekf.config.odometry_reset_after):
        ekf.update_odometry(ekf.t, np.array([500.0, 0, 0]), q)
    assert ekf.n_odometry_resets == 1 and abs(ekf.state().p_WB[0] - 500.0) < 1e-6
    # the estimate's own drift corrected, not a jump of the odometry's frame: nothing to hand on
    assert not ekf.reset_delta_p_WB.any() and ekf.n_relocalizations == 0


def test_ego_relocalizes_at_an_announced_jump_and_adds_them_up() -> None:
    ekf = _ego()
    q = np.array([0.0, 0.0, 0.0, 1.0])
    p0 = ekf.state().p_WB.copy()
    for jump in ([3.0, 0.0, 0.0], [3.0, -2.0, 1.0]):  # positions the odometry jumps to
        ekf.relocalize(ekf.t, p0 + np.array(jump), q)
        assert np.allclose(ekf.state().p_WB, p0 + np.array(jump))  # at once, no gate
    assert ekf.n_relocalizations == 2 and ekf.n_odometry_gated == 0
    assert np.allclose(ekf.reset_delta_p_WB, [3.0, -2.0, 1.0])  # 3 m along x, then (0, -2, 1) more
    with pytest.raises(EstimationError):
        ekf.relocalize(ekf.t, np.array([np.nan, 0.0, 0.0]), q)
    with pytest.raises(EstimationError):
        ekf.relocalize(ekf.t, np.zeros(3), np.zeros(4))
    assert np.allclose(ekf.reset_delta_p_WB, [3.0, -2.0, 1.0])  # a refused message changes nothing


def test_ego_refuses_odometry_from_the_future() -> None:
    ekf = _ego()
    t = ekf.t
    assert ekf.update_odometry(t + 1000.0, np.zeros(3), np.array([0.0, 0, 0, 1])) is False
    assert ekf.t == t


def test_predict_imu_many_checks_its_arrays() -> None:
    ekf = _ego()
    before = ekf.nominal
    with pytest.raises(MeasurementError, match="n=10 samples"):
        ekf.predict_imu_many(ekf.t + 0.005 * np.arange(1, 11), np.zeros((3, 3)), np.zeros((3, 3)))
    with pytest.raises(MeasurementError):
        ekf.predict_imu_many(ekf.t + 0.005 * np.arange(1, 4), np.zeros((3, 3)), np.zeros((3, 3)), n=5)
    assert np.array_equal(before, ekf.nominal)
