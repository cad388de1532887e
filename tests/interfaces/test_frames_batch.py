"""NED/FRD -> ENU/FLU at the replay's boundary (interfaces/frames.py)."""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from alight.interfaces.frames import frd_to_flu, mavlink_to_q_WB_many, ned_to_enu
from alight.types import quat_to_rotmat


def _px4_q(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """PX4's attitude quaternion (w, x, y, z) of FRD -> NED for Tait-Bryan angles (ZYX) in NED."""
    x, y, z, w = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_quat()
    return np.array([w, x, y, z])


def test_positions_swap_x_y_and_z_goes_up() -> None:
    # 3 m north, 4 m east, 2 m below the origin (NED) is 4 m east, 3 m north, 2 m down (ENU)
    assert np.array_equal(ned_to_enu(np.array([3.0, 4.0, 2.0])), [4.0, 3.0, -2.0])
    assert np.array_equal(ned_to_enu(np.array([[0.0, 0.0, -10.0]])), [[0.0, 0.0, 10.0]])


def test_accelerometer_at_rest_points_up_in_flu() -> None:
    # a level vehicle at rest: PX4's accelerometer reads -g along FRD z (down); FLU z is up
    assert np.array_equal(frd_to_flu(np.array([0.0, 0.0, -9.81])), [0.0, 0.0, 9.81])
    # a positive FRD yaw rate (clockwise seen from above) is a negative FLU yaw rate
    assert np.array_equal(frd_to_flu(np.array([0.1, 0.2, 0.3])), [0.1, -0.2, -0.3])


def test_heading_north_is_yaw_pi_over_2_in_enu() -> None:
    for yaw_ned in (0.0, 0.7, -2.0, math.pi / 2):
        R_WB = quat_to_rotmat(mavlink_to_q_WB_many(_px4_q(0.0, 0.0, yaw_ned))[0])
        forward_W = R_WB @ [1.0, 0.0, 0.0]
        # heading measured from north, clockwise; ENU yaw from east, anticlockwise
        expected = [math.sin(yaw_ned), math.cos(yaw_ned), 0.0]
        assert np.allclose(forward_W, expected, atol=1e-12)
        assert np.allclose(R_WB @ [0.0, 0.0, 1.0], [0.0, 0.0, 1.0], atol=1e-12)  # FLU up is ENU up


def test_roll_right_tilts_the_left_axis_up() -> None:
    # rolling right wing down (positive FRD roll) lifts the left side: FLU y gets a +z component
    R_WB = quat_to_rotmat(mavlink_to_q_WB_many(_px4_q(0.3, 0.0, 0.0))[0])
    y_W = R_WB @ [0.0, 1.0, 0.0]
    assert math.isclose(y_W[2], math.sin(0.3), abs_tol=1e-12)
    # and a pitch up (positive FRD pitch) lifts the nose: FLU x gets +z
    R_WB = quat_to_rotmat(mavlink_to_q_WB_many(_px4_q(0.0, 0.2, 1.0))[0])
    assert math.isclose((R_WB @ [1.0, 0.0, 0.0])[2], math.sin(0.2), abs_tol=1e-12)


def test_non_unit_quaternions_become_nan() -> None:
    q = mavlink_to_q_WB_many(np.array([[0.0, 0.0, 0.0, 0.0], [np.nan, 0, 0, 1], [1.0, 0, 0, 0]]))
    assert np.isnan(q[0]).all() and np.isnan(q[1]).all() and np.isfinite(q[2]).all()
