"""Sensors: IMU readings and noise statistics, odometry drift model, range-finder geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from alight.sim.platform import PlatformTruth
from alight.sim.sensors import (
    Imu,
    ImuConfig,
    Odometry,
    OdometryConfig,
    RangeFinder,
    RangeFinderConfig,
    range_to_surface,
)
from alight.types import GRAVITY_MPS2, quat_to_rotmat

Q_LEVEL = np.array([0.0, 0.0, 0.0, 1.0])
Z3 = np.zeros(3)
NOISELESS_IMU = ImuConfig(
    accel_noise_density=0.0, gyro_noise_density=0.0, accel_bias_random_walk=0.0, gyro_bias_random_walk=0.0
)


def _pad(x=0.0, y=0.0, h=0.5, yaw=0.0):
    return PlatformTruth(0.0, np.array([x, y, h]), Z3.copy(), Z3.copy(), yaw, 0.0)


def test_imu_at_hover_reads_gravity_plus_bias():
    imu = Imu(NOISELESS_IMU, np.random.default_rng(0))
    acc, gyr = imu.measure(Z3, Q_LEVEL, Z3)
    assert np.linalg.norm(imu.accel_bias) > 0  # a turn-on bias was drawn
    np.testing.assert_allclose(acc, np.array([0.0, 0.0, GRAVITY_MPS2]) + imu.accel_bias, atol=1e-15)
    np.testing.assert_allclose(gyr, imu.gyro_bias, atol=1e-15)


def test_imu_specific_force_is_rotated_into_body():
    imu = Imu(NOISELESS_IMU, np.random.default_rng(1))
    rot = Rotation.from_euler("xyz", [0.3, -0.5, 1.2])
    q = rot.as_quat()
    a_WB = np.array([1.0, -2.0, 0.5])
    w = np.array([0.1, 0.2, -0.3])
    acc, gyr = imu.measure(a_WB, q, w)
    expected = rot.inv().apply(a_WB - np.array([0.0, 0.0, -GRAVITY_MPS2]))
    np.testing.assert_allclose(acc - imu.accel_bias, expected, atol=1e-12)
    np.testing.assert_allclose(gyr - imu.gyro_bias, w, atol=1e-15)


def test_imu_noise_and_bias_walk_statistics():
    cfg = ImuConfig(accel_bias_init_std=0.0, gyro_bias_init_std=0.0)
    imu = Imu(cfg, np.random.default_rng(2))
    n = 40000
    acc, gyr = imu.measure_many(np.zeros((n, 3)), np.tile(Q_LEVEL, (n, 1)), np.zeros((n, 3)))
    # white noise: remove the (slow) bias walk by differencing, var(diff) = 2 sigma^2 + walk step^2
    sa = cfg.accel_noise_density * math.sqrt(cfg.rate_hz)
    sg = cfg.gyro_noise_density * math.sqrt(cfg.rate_hz)
    wa = cfg.accel_bias_random_walk / math.sqrt(cfg.rate_hz)
    wg = cfg.gyro_bias_random_walk / math.sqrt(cfg.rate_hz)
    np.testing.assert_allclose(np.diff(acc, axis=0).std(axis=0), math.sqrt(2 * sa**2 + wa**2), rtol=0.02)
    np.testing.assert_allclose(np.diff(gyr, axis=0).std(axis=0), math.sqrt(2 * sg**2 + wg**2), rtol=0.02)
    assert imu.accel_noise_std == pytest.approx(sa)
    # the bias walk alone (no white noise): increments of std rw / sqrt(rate)
    walk = Imu(ImuConfig(accel_noise_density=0.0, gyro_noise_density=0.0), np.random.default_rng(3))
    acc, gyr = walk.measure_many(np.zeros((n, 3)), np.tile(Q_LEVEL, (n, 1)), np.zeros((n, 3)))
    np.testing.assert_allclose(np.diff(acc, axis=0).std(axis=0), wa, rtol=0.02)
    np.testing.assert_allclose(np.diff(gyr, axis=0).std(axis=0), wg, rtol=0.02)


def test_imu_measure_many_equals_repeated_measure():
    rng_truth = np.random.default_rng(4)
    n = 700  # crosses the noise block boundary
    a = rng_truth.normal(size=(n, 3))
    q = Rotation.random(n, random_state=5).as_quat()
    w = rng_truth.normal(size=(n, 3))
    one = Imu(ImuConfig(), np.random.default_rng(6))
    many = Imu(ImuConfig(), np.random.default_rng(6))
    seq = [one.measure(a[i], q[i], w[i]) for i in range(n)]
    acc, gyr = many.measure_many(a[:300], q[:300], w[:300])
    acc2, gyr2 = many.measure_many(a[300:], q[300:], w[300:])
    np.testing.assert_allclose(np.vstack([acc, acc2]), np.array([s[0] for s in seq]), atol=1e-12)
    np.testing.assert_allclose(np.vstack([gyr, gyr2]), np.array([s[1] for s in seq]), atol=1e-12)
    np.testing.assert_allclose(many.gyro_bias, one.gyro_bias, atol=1e-15)


def test_odometry_white_noise_statistics():
    cfg = OdometryConfig(position_drift_density=0.0, yaw_drift_density=0.0)
    odo = Odometry(cfg, np.random.default_rng(7))
    p = np.array([3.0, -1.0, 2.0])
    v = np.array([0.5, 0.0, -0.2])
    q = Rotation.from_euler("z", 0.4).as_quat()
    outs = [odo.measure(0.025 * k, p, v, q, Z3) for k in range(5000)]
    ps = np.array([o.p_WB for o in outs])
    vs = np.array([o.v_WB for o in outs])
    np.testing.assert_allclose(ps.mean(axis=0), p, atol=4 * cfg.position_noise_m / math.sqrt(5000))
    np.testing.assert_allclose(ps.std(axis=0), cfg.position_noise_m, rtol=0.05)
    np.testing.assert_allclose(vs.std(axis=0), cfg.velocity_noise_mps, rtol=0.05)
    # rotation noise: the angle of q_true^-1 q_meas per axis has the configured std
    rv = (Rotation.from_quat(q).inv() * Rotation.from_quat(np.array([o.q_WB for o in outs]))).as_rotvec()
    np.testing.assert_allclose(rv.std(axis=0), cfg.attitude_noise_rad, rtol=0.05)
    assert outs[5].t == pytest.approx(0.125)


def test_odometry_drift_is_a_rotated_and_offset_frame():
    cfg = OdometryConfig(
        position_noise_m=0.0,
        velocity_noise_mps=0.0,
        attitude_noise_rad=0.0,
        rate_noise_radps=0.0,
        position_drift_density=0.05,
        yaw_drift_density=0.02,
    )
    odo = Odometry(cfg, np.random.default_rng(8))
    p = np.array([10.0, 5.0, 2.0])
    v = np.array([1.0, 0.0, 0.0])
    q = Rotation.from_euler("xyz", [0.1, 0.2, 0.3]).as_quat()
    for k in range(100):
        psi, b = odo.drift_yaw, odo.drift_p.copy()
        e = odo.measure(k / cfg.rate_hz, p, v, q, Z3)
        Rz = Rotation.from_euler("z", psi)
        np.testing.assert_allclose(e.p_WB, Rz.apply(p) + b, atol=1e-12)
        np.testing.assert_allclose(e.v_WB, Rz.apply(v), atol=1e-12)
        np.testing.assert_allclose(
            quat_to_rotmat(e.q_WB), (Rz * Rotation.from_quat(q)).as_matrix(), atol=1e-12
        )
    yaw_steps, p_steps = [], []
    for k in range(3000):
        psi, b = odo.drift_yaw, odo.drift_p.copy()
        odo.measure(k / cfg.rate_hz, p, v, q, Z3)
        yaw_steps.append(odo.drift_yaw - psi)
        # the offset's own random walk: its step less what it took up of the heading's step
        taken_up = Rotation.from_euler("z", psi).apply(p) - Rotation.from_euler("z", odo.drift_yaw).apply(p)
        p_steps.append(odo.drift_p - b - taken_up)
    sq_dt = 1.0 / math.sqrt(cfg.rate_hz)
    assert np.std(yaw_steps) == pytest.approx(cfg.yaw_drift_density * sq_dt, rel=0.05)
    np.testing.assert_allclose(np.std(p_steps, axis=0), cfg.position_drift_density * sq_dt, rtol=0.05)


def test_range_to_pad_and_to_ground():
    rf = RangeFinder(RangeFinderConfig(noise_std_m=0.0, min_range_m=0.0), np.random.default_rng(9))
    pad = _pad(x=5.0, y=0.0, h=0.5)
    # over the pad: from the feet (0.1 m under the body) down to the pad surface
    assert rf.measure(np.array([5.3, 0.2, 3.0]), Q_LEVEL, pad, 1.5) == pytest.approx(3.0 - 0.1 - 0.5)
    # beside the pad: down to the ground
    assert rf.measure(np.array([6.0, 0.0, 3.0]), Q_LEVEL, pad, 1.5) == pytest.approx(2.9)
    # below the pad's surface beside it
    assert rf.measure(np.array([7.0, 0.0, 0.3]), Q_LEVEL, pad, 1.5) == pytest.approx(0.2)
    # out of range (REP 117)
    assert rf.measure(np.array([0.0, 0.0, 20.0]), Q_LEVEL, pad, 1.5) == math.inf
    # the default is the TeraRanger One's 0.2 m blind zone: closer, it reports -inf, never a number
    blind = RangeFinder(RangeFinderConfig(noise_std_m=0.0), np.random.default_rng(9))
    assert blind.config.min_range_m == 0.2
    assert blind.measure(np.array([5.0, 0.0, 0.7]), Q_LEVEL, pad, 1.5) == -math.inf
    assert blind.measure(np.array([5.0, 0.0, 0.79]), Q_LEVEL, pad, 1.5) == -math.inf
    # standing on the pad, the feet (and the sensor) pressed a millimetre into it: still the pad, at 0
    assert rf.measure(np.array([5.0, 0.0, 0.599]), Q_LEVEL, pad, 1.5) == pytest.approx(0.0)
    assert blind.measure(np.array([5.0, 0.0, 0.599]), Q_LEVEL, pad, 1.5) == -math.inf
    assert blind.measure(np.array([5.0, 0.0, 0.9]), Q_LEVEL, pad, 1.5) == pytest.approx(0.3)


def test_range_tilted_geometry():
    rf = RangeFinder(RangeFinderConfig(noise_std_m=0.0, origin_B=(0.0, 0.0, 0.0)), np.random.default_rng(10))
    far_pad = _pad(x=100.0)
    for angle in (0.1, 0.5, 1.0):
        q = Rotation.from_euler("x", angle).as_quat()
        assert rf.measure(np.array([0.0, 0.0, 4.0]), q, far_pad, 1.5) == pytest.approx(4.0 / math.cos(angle))
    # pitched forward (nose down) by 30 deg, the ray leans backwards: hits the ground behind, missing a
    # pad that lies ahead, but the pad behind is hit at (4 - 0.5) / cos 30 deg
    q = Rotation.from_euler("y", math.radians(30.0)).as_quat()
    p = np.array([0.0, 0.0, 4.0])
    d = -quat_to_rotmat(q)[:, 2]
    assert d[0] < 0
    assert rf.measure(p, q, _pad(x=1.0), 1.5) == pytest.approx(4.0 / math.cos(math.radians(30)))
    hit_x = 3.5 * math.tan(math.radians(30))
    assert rf.measure(p, q, _pad(x=-hit_x), 1.5) == pytest.approx(3.5 / math.cos(math.radians(30)))
    # a rotated pad: (0.7, 0.7) is near a corner of the unrotated pad, 0.99 m along the x axis of the pad
    # turned by 45 deg, so outside it
    pt = np.array([0.7, 0.7, 4.0])
    down = np.array([0, 0, -1.0])
    assert range_to_surface(pt, down, np.array([0.0, 0.0, 0.5]), 0.0, 1.5) == pytest.approx(3.5)
    assert range_to_surface(pt, down, np.array([0.0, 0.0, 0.5]), math.pi / 4, 1.5) == pytest.approx(4.0)
    assert range_to_surface(
        np.array([0.5, 0.0, 4.0]), np.array([0, 0, -1.0]), np.array([0.0, 0.0, 0.5]), math.pi / 4, 1.5
    ) == pytest.approx(3.5)
    # upside down: nothing below
    assert rf.measure(p, Rotation.from_euler("x", 2.0).as_quat(), far_pad, 1.5) == math.inf


def test_range_noise_statistics():
    cfg = RangeFinderConfig(noise_std_m=0.02)
    rf = RangeFinder(cfg, np.random.default_rng(11))
    r = np.array([rf.measure(np.array([0.0, 0.0, 5.1]), Q_LEVEL, _pad(x=50.0), 1.5) for _ in range(5000)])
    assert r.mean() == pytest.approx(5.0, abs=4 * 0.02 / math.sqrt(5000))
    assert r.std() == pytest.approx(0.02, rel=0.05)


def test_noise_stream_peek_and_skip_give_the_same_numbers_as_rows() -> None:
    from alight.sim.sensors import _NormalStream

    a = _NormalStream(np.random.default_rng(3), 4, block=5)
    b = _NormalStream(np.random.default_rng(3), 4, block=5)
    rows = np.array([a.row() for _ in range(23)])
    got = []
    for want, use in [(2, 1), (2, 2), (3, 1), (2, 2), (4, 3), (2, 1), (5, 5), (2, 2), (3, 3), (3, 3)]:
        peeked = b.peek(want)
        np.testing.assert_array_equal(peeked, rows[len(got) : len(got) + want])
        b.skip(use)
        got.extend(peeked[:use])
    np.testing.assert_array_equal(np.array(got), rows[: len(got)])
    np.testing.assert_array_equal(b.take(0), np.empty((0, 4)))


def test_odometry_heading_drift_turns_the_motion_not_the_path_flown():
    """Far from take-off (1 km) at 18 m/s, the heading drift must not make the position jump: one
    sample's position step is the true step turned by the drift (|dp| psi, millimetres), where rotating
    the whole path about W's origin jumped it by |p| dpsi (0.08 m std per sample at 40 Hz)."""
    cfg = OdometryConfig(
        position_noise_m=0.0,
        velocity_noise_mps=0.0,
        attitude_noise_rad=0.0,
        rate_noise_radps=0.0,
        position_drift_density=0.0,
        yaw_drift_density=5.0e-4,
    )
    odo = Odometry(cfg, np.random.default_rng(9))
    v = np.array([18.0, 0.0, 0.0])
    p0 = np.array([1000.0, 0.0, 3.0])
    q = Rotation.from_euler("z", 0.0).as_quat()
    dt = 1.0 / cfg.rate_hz
    outs = [odo.measure(k * dt, p0 + v * k * dt, v, q, Z3) for k in range(2000)]
    ps = np.array([o.p_WB for o in outs])
    vs = np.array([o.v_WB for o in outs])
    # each step is the odometry's own velocity times dt (the velocity is turned by the same heading)
    np.testing.assert_allclose(np.diff(ps, axis=0), vs[1:] * dt, atol=1e-6)
    assert abs(odo.drift_yaw) > 1e-3  # the heading did drift
