"""planning/envelope.py: the intercept time, the top speed, the horizon and the search growth, each
against a case worked by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.planning.envelope import (
    MIN_JERK_PEAK_ACCEL,
    adaptive_horizon,
    horizontal_speed_limit,
    intercept_time,
    intercept_time_constant_velocity,
    reach_m,
    search_half_width,
)


def test_intercept_by_hand_crossing_path() -> None:
    # Platform 30 m east of the vehicle, driving north at 12 m/s; the vehicle flies at 15 m/s.
    # |(30, 12 T)| = 15 T  ->  900 + 144 T^2 = 225 T^2  ->  T^2 = 900 / 81  ->  T = 10/3 s,
    # where the platform is at (30, 40): 50 m away, 15 m/s x 10/3 s.
    T = intercept_time_constant_velocity(np.array([30.0, 0.0]), np.array([0.0, 12.0]), 15.0)
    assert T == pytest.approx(10.0 / 3.0)
    t = np.linspace(0.0, 20.0, 2001)
    p = np.stack([np.full_like(t, 30.0), 12.0 * t], axis=1)
    assert intercept_time(np.zeros(2), t, p, 15.0) == pytest.approx(10.0 / 3.0, abs=1e-3)


def test_intercept_by_hand_head_on_and_running_away() -> None:
    # Head-on: 100 m apart, closing at 12 + 8 = 20 m/s: T = 5 s.
    T = intercept_time_constant_velocity(np.array([100.0, 0.0]), np.array([-12.0, 0.0]), 8.0)
    assert T == pytest.approx(5.0)
    # Running away faster than the vehicle: never.
    assert intercept_time_constant_velocity(np.array([10.0, 0.0]), np.array([12.0, 0.0]), 10.0) is None
    t = np.linspace(0.0, 60.0, 241)
    p = np.stack([10.0 + 12.0 * t, 0.0 * t], axis=1)
    assert intercept_time(np.zeros(2), t, p, 10.0) is None
    # Running away slower: 10 m ahead at 12 m/s, vehicle 15 m/s: 10 + 12 T = 15 T -> T = 10/3 s.
    assert intercept_time_constant_velocity(np.array([10.0, 0.0]), np.array([12.0, 0.0]), 15.0) == (
        pytest.approx(10.0 / 3.0)
    )


def test_intercept_with_acceleration_by_hand() -> None:
    # From rest at 2 m/s^2 up to 10 m/s (10 s... ramp 5 s, 25 m), a platform standing 75 m away:
    # 10 T - 25 = 75 -> T = 10 s; one standing 9 m away is reached on the ramp: T^2 = 9 -> T = 3 s.
    t = np.linspace(0.0, 30.0, 3001)
    assert intercept_time(np.zeros(2), t, np.tile([75.0, 0.0], (t.size, 1)), 10.0, 2.0) == pytest.approx(10.0)
    assert intercept_time(np.zeros(2), t, np.tile([9.0, 0.0], (t.size, 1)), 10.0, 2.0) == pytest.approx(3.0)
    np.testing.assert_allclose(reach_m(np.array([1.0, 5.0, 6.0]), 10.0, 2.0), [1.0, 25.0, 35.0])


def test_horizontal_speed_limit_by_hand() -> None:
    # F450: tilt 45 deg, d = 0.3 /s: g tan 45 / 0.3 = 32.7 m/s.
    assert horizontal_speed_limit(math.radians(45.0), 0.3) == pytest.approx(9.81 / 0.3)
    assert horizontal_speed_limit(0.5, 0.0) == math.inf


def test_adaptive_horizon_by_hand() -> None:
    # 20 m with 9.81 m/s^2: sqrt(5.77 x 20 / 9.81) = 3.43 s; the window is [3.43, 6.86].
    lo, hi = adaptive_horizon(20.0, 9.81, 1.0, 3.0)
    assert lo == pytest.approx(math.sqrt(MIN_JERK_PEAK_ACCEL * 20.0 / 9.81))
    assert lo == pytest.approx(3.43, abs=0.01)
    assert hi == pytest.approx(2.0 * lo)
    # Close by, the configured window stays: sqrt(5.77 x 1 / 9.81) = 0.77 s < 1 s.
    assert adaptive_horizon(1.0, 9.81, 1.0, 3.0) == (1.0, 3.0)
    # With an intercept time the window is [T, 1.1 T].
    lo, hi = adaptive_horizon(50.0, 9.81, 1.0, 3.0, t_intercept_s=10.0 / 3.0)
    assert (lo, hi) == (pytest.approx(10.0 / 3.0), pytest.approx(11.0 / 3.0))


def test_search_growth_by_hand() -> None:
    # A 40 m square (half-width 20 m), 10 s of climb, a platform up to 4 m/s: half-width 60 m.
    assert search_half_width(20.0, 10.0, 4.0) == pytest.approx(60.0)
    assert search_half_width(20.0, -1.0, 4.0) == pytest.approx(20.0)
