"""Telemetry fusion (estimation/telemetry.py, PlatformEkf.update_telemetry): the bias filter worked by hand,
and closed-loop-free filter runs on a platform driving a straight line at 8 m/s."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.errors import EstimationError
from alight.estimation import PlatformEkf, PlatformEkfConfig, TelemetryFusing
from alight.estimation.telemetry import (
    bias_update,
    carry_fix,
    carry_fix_on_turn,
    telemetry_adds_information,
)
from alight.types import PlatformMeasurement


def test_bias_update_by_hand() -> None:
    # P = 4 I, R = 4 I: K = 1/2; b = 0 + 1/2 (2, 0, -2) = (1, 0, -1); P = (1/2)^2 4 + (1/2)^2 4 = 2
    b, P = bias_update(np.zeros(3), 4.0 * np.eye(3), np.array([2.0, 0.0, -2.0]), 4.0 * np.eye(3))
    np.testing.assert_allclose(b, [1.0, 0.0, -1.0])
    np.testing.assert_allclose(P, 2.0 * np.eye(3))


def test_carry_fix_by_hand() -> None:
    # 0.5 s on (8, 0, 0) m/s moves 4 m along x; variance grows by (0.2 * 0.5)^2 = 0.01
    p, c = carry_fix(1.0, np.array([1.0, 2.0, 0.5]), np.array([8.0, 0.0, 0.0]), np.eye(3), 1.5, 0.2)
    np.testing.assert_allclose(p, [5.0, 2.0, 0.5])
    np.testing.assert_allclose(np.diag(c), [1.01, 1.01, 1.01])


@pytest.mark.parametrize("dt", [-0.25, -1.0, 0.3, 2.0])
def test_carry_on_turn_lands_on_the_exact_circle(dt: float) -> None:
    # a circle of radius R about c at speed v: p(t) = c + R (cos wt, sin wt), v(t) = v (-sin wt, cos wt),
    # w = v / R; a fix at t0 carried by dt along the turn is the circle's point and velocity at t0 + dt
    R, v, t0 = 30.0, 8.5, 1.7
    w = v / R
    c = np.array([3.0, -4.0])

    def on_circle(t: float) -> tuple[np.ndarray, np.ndarray]:
        a = w * t
        return (
            np.array([c[0] + R * math.cos(a), c[1] + R * math.sin(a), 0.5]),
            np.array([-v * math.sin(a), v * math.cos(a), 0.0]),
        )

    p0, v0 = on_circle(t0)
    p, vt, cov = carry_fix_on_turn(t0, p0, v0, np.eye(3), t0 + dt, 0.2, w)
    p_exact, v_exact = on_circle(t0 + dt)
    np.testing.assert_allclose(p, p_exact, atol=1e-9)
    np.testing.assert_allclose(vt, v_exact, atol=1e-9)
    np.testing.assert_allclose(np.diag(cov), 1.0 + (0.2 * dt) ** 2)
    # carried straight instead, the fix is off the circle by about (v dt)^2 / (2 R) and its heading by w dt
    p_straight, _ = carry_fix(t0, p0, v0, np.eye(3), t0 + dt, 0.2)
    off = float(np.linalg.norm(p_straight - p_exact))
    assert off == pytest.approx((v * dt) ** 2 / (2.0 * R), rel=0.15)


def test_carry_on_turn_without_turn_is_the_straight_carry() -> None:
    args = (1.0, np.array([1.0, 2.0, 0.5]), np.array([8.0, -3.0, 0.1]), np.eye(3), 1.4, 0.2)
    p, v, c = carry_fix_on_turn(*args, 0.0)
    p_s, c_s = carry_fix(*args)
    np.testing.assert_allclose(p, p_s)
    np.testing.assert_allclose(v, args[2])
    np.testing.assert_allclose(c, c_s)
    # a tiny turn (the series branch) is continuous with the closed form
    p_small, v_small, _ = carry_fix_on_turn(*args, 1e-6)
    p_big, v_big, _ = carry_fix_on_turn(*args, 1e-3)
    assert np.linalg.norm(p_small - p) < 1e-5 and np.linalg.norm(p_big - p) < 1e-2
    assert np.linalg.norm(v_small - args[2]) < 1e-5 and np.linalg.norm(v_big - args[2]) < 1e-2


def test_adds_information_rule() -> None:
    assert telemetry_adds_information(np.eye(2) * 2.0, np.eye(2))
    assert not telemetry_adds_information(np.eye(2) * 0.5, np.eye(2))


SPEED = 8.0
BIAS = np.array([1.5, -1.0, 0.3])


def _truth(t: float) -> np.ndarray:
    return np.array([SPEED * t, 0.0, 0.5])


def _fly(ekf: PlatformEkf, rng: np.random.Generator, t_end: float, camera_from: float | None) -> list[float]:
    """Telemetry at 10 Hz (0.3 m noise, BIAS, 0.2 s latency) and, from ``camera_from``, the camera at
    20 Hz (5 cm, 0.1 s latency), delivered in arrival order; returns the horizontal errors at 1 Hz."""
    events: list[tuple[float, str, float]] = []
    for k in range(int(t_end * 10)):
        events.append((0.1 * k + 0.2, "tel", 0.1 * k))
    if camera_from is not None:
        for k in range(int(camera_from * 20), int(t_end * 20)):
            events.append((0.05 * k + 0.1, "cam", 0.05 * k))
    events.sort()
    errors = []
    next_check = 1.0
    for t_arr, kind, t_s in events:
        if t_arr > t_end:
            break
        if kind == "tel":
            p = _truth(t_s) + BIAS + rng.normal(0.0, 0.3, 3)
            v = np.array([SPEED, 0.0, 0.0]) + rng.normal(0.0, 0.1, 3)
            ekf.update_telemetry(t_s, p, v, np.eye(3) * 0.09)
        else:
            z = _truth(t_s) + rng.normal(0.0, 0.05, 3)
            m = PlatformMeasurement(t=t_s, p_WP=z, cov_p_WP=np.eye(3) * 0.0025)
            if ekf.update(m):
                ekf.learn_telemetry_bias(m)
        if t_arr >= next_check and ekf.has_measurement:
            errors.append(float(np.linalg.norm(ekf.state(t_arr).p_WP[:2] - _truth(t_arr)[:2])))
            next_check += 1.0
    return errors


def test_ekf_is_telemetry_fusing() -> None:
    assert isinstance(PlatformEkf(), TelemetryFusing)


def test_telemetry_only_follows_the_fixes_within_noise_and_bias() -> None:
    ekf = PlatformEkf(PlatformEkfConfig(use_turn_rate=True, heading_noise=0.05))
    errors = _fly(ekf, np.random.default_rng(1), 20.0, camera_from=None)
    assert ekf.initialized
    bias_xy = float(np.linalg.norm(BIAS[:2]))
    # nothing can remove the bias without the camera; the noise averages down
    assert max(errors[3:]) < bias_xy + 1.0
    assert ekf.telemetry.n_bias_updates == 0
    np.testing.assert_allclose(ekf.telemetry.b, 0.0)
    # and the filter does not claim to know much better than the bias prior: a fix is fused only while
    # the filter's variance exceeds the bias's, and its own R includes the bias's, so after it the
    # variance is at least half the bias's (std >= 1/sqrt(2) of it)
    std = math.sqrt(0.5 * np.trace(ekf.state(20.0).cov_p_WP[:2, :2]))
    assert std > 0.7 * ekf.telemetry.config.bias_prior_std_m


def test_camera_makes_the_bias_converge_to_the_truth() -> None:
    ekf = PlatformEkf(PlatformEkfConfig(use_turn_rate=True, heading_noise=0.05))
    errors = _fly(ekf, np.random.default_rng(2), 20.0, camera_from=5.0)
    assert ekf.telemetry.n_bias_updates > 100
    np.testing.assert_allclose(ekf.telemetry.b, BIAS, atol=0.1)
    assert max(errors[8:]) < 0.2  # the camera's accuracy, not the telemetry's


def test_update_telemetry_refuses_bad_fixes() -> None:
    ekf = PlatformEkf()
    with pytest.raises(EstimationError):
        ekf.update_telemetry(0.0, np.array([np.nan, 0.0, 0.0]), np.zeros(3), np.eye(3))
    with pytest.raises(EstimationError):
        ekf.update_telemetry(0.0, np.zeros(2), np.zeros(3), np.eye(3))


def test_fixes_on_a_circle_keep_the_heading_of_the_circle() -> None:
    """A 30 m circle at 8.5 m/s (0.283 rad/s, 2.4 m/s^2), noise-free fixes at 10 Hz, 0.2 s late, so each
    is fused 0.25 s before its stamp (time_guard_s): carried along the filter's turn, the estimate's
    velocity stays on the circle's. Carried straight, each fix's heading was 0.07 rad behind, its
    velocity 0.6 m/s across the track."""
    R, v = 30.0, 8.5
    w = v / R

    def state(t: float) -> tuple[np.ndarray, np.ndarray]:
        a = w * t
        return (
            np.array([R * math.cos(a), R * math.sin(a), 0.5]),
            np.array([-v * math.sin(a), v * math.cos(a), 0.0]),
        )

    ekf = PlatformEkf(PlatformEkfConfig(use_turn_rate=True, heading_noise=0.05))
    errors = []
    for k in range(200):  # 20 s
        t_s = 0.1 * k
        p, vel = state(t_s)
        ekf.predict(t_s + 0.2)
        ekf.update_telemetry(t_s, p, vel, np.eye(3) * 0.25)
        if t_s > 10.0:
            est = ekf.state(t_s + 0.2)
            errors.append(float(np.linalg.norm(est.v_WP[:2] - state(t_s + 0.2)[1][:2])))
    assert ekf.initialized
    assert max(errors) < 0.1, max(errors)
