"""ENU/FLU <-> NED/FRD: known values (the worked example of the MAVLink reference sheet), round trips,
and agreement of the quaternion, matrix and Euler forms."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from alight.interfaces import frames
from alight.types import quat_to_rotmat


def test_known_vectors() -> None:
    np.testing.assert_allclose(frames.enu_to_ned(np.array([1.0, 2.0, 3.0])), [2.0, 1.0, -3.0])
    np.testing.assert_allclose(frames.flu_to_frd(np.array([0.1, 0.2, 0.3])), [0.1, -0.2, -0.3])
    # a level vehicle at rest: the accelerometer's specific force points up in FLU, down in FRD
    np.testing.assert_allclose(frames.flu_to_frd(np.array([0.0, 0.0, 9.81])), [0.0, 0.0, -9.81])


def test_worked_example_quaternion() -> None:
    # yaw 30 deg (ENU), pitch -10 deg about FLU y (nose up), roll +5 deg
    q_enu = Rotation.from_euler("ZYX", [30.0, -10.0, 5.0], degrees=True).as_quat()  # (x, y, z, w)
    q_ned = frames.q_WB_to_mavlink(q_enu)
    np.testing.assert_allclose(q_ned, [0.8638, -0.0059, 0.0971, 0.4943], atol=1e-4)
    yaw, pitch, roll = Rotation.from_quat(q_ned, scalar_first=True).as_euler("ZYX", degrees=True)
    assert yaw == pytest.approx(60.0, abs=1e-6) and pitch == pytest.approx(10.0, abs=1e-6)
    assert roll == pytest.approx(5.0, abs=1e-6)
    # yaw-only case of the sheet
    q = frames.q_WB_to_mavlink(np.array([0.0, 0.0, 0.2588190451, 0.9659258263]))
    np.testing.assert_allclose(q, [0.8660, 0.0, 0.0, 0.5], atol=1e-4)


def test_euler_and_yaw() -> None:
    q = frames.euler_ned_frd_to_q_WB(math.radians(5.0), math.radians(10.0), math.radians(60.0))
    expected = Rotation.from_euler("ZYX", [30.0, -10.0, 5.0], degrees=True).as_quat()
    assert abs(float(np.dot(q, expected))) == pytest.approx(1.0, abs=1e-12)
    assert frames.yaw_enu_to_ned(math.radians(30.0)) == pytest.approx(math.radians(60.0))
    assert frames.yaw_enu_to_ned(0.0) == pytest.approx(math.pi / 2)  # east is heading 90 deg
    assert frames.yaw_enu_to_ned(math.pi / 2) == pytest.approx(0.0)  # north is heading 0
    assert frames.yaw_rate_enu_to_ned(0.3) == -0.3


def test_round_trips_and_consistency() -> None:
    rng = np.random.default_rng(7)
    for q_enu in Rotation.random(200, random_state=rng).as_quat():
        q_enu = q_enu if q_enu[3] >= 0 else -q_enu
        back = frames.mavlink_to_q_WB(frames.q_WB_to_mavlink(q_enu))
        np.testing.assert_allclose(back, q_enu, atol=1e-12)
        R_ned = frames.rotmat_enu_flu_to_ned_frd(quat_to_rotmat(q_enu))
        q_ned = frames.q_WB_to_mavlink(q_enu)
        np.testing.assert_allclose(
            Rotation.from_quat(q_ned, scalar_first=True).as_matrix(), R_ned, atol=1e-12
        )
        np.testing.assert_allclose(frames.rotmat_ned_frd_to_enu_flu(R_ned), quat_to_rotmat(q_enu), atol=1e-12)
        # a body vector rotated into the world gives the same world vector in both conventions
        v_B = rng.normal(size=3)
        v_W = quat_to_rotmat(q_enu) @ v_B
        np.testing.assert_allclose(R_ned @ frames.flu_to_frd(v_B), frames.enu_to_ned(v_W), atol=1e-12)
    v = rng.normal(size=(10, 3))
    np.testing.assert_allclose(frames.ned_to_enu(frames.enu_to_ned(v)), v)
    np.testing.assert_allclose(frames.frd_to_flu(frames.flu_to_frd(v)), v)
    P = np.cov(rng.normal(size=(3, 50)))
    np.testing.assert_allclose(frames.cov_enu_to_ned(frames.cov_enu_to_ned(P)), P)
    assert frames.cov_enu_to_ned(P)[0, 0] == pytest.approx(P[1, 1])


@pytest.mark.parametrize("bad", [[0.0, 0.0, 0.0, 0.0], [math.nan, 0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
def test_bad_quaternion_is_refused(bad: list[float]) -> None:
    with pytest.raises(ValueError, match="quaternion"):
        frames.mavlink_to_q_WB(np.array(bad))


@pytest.mark.parametrize("seed", range(5))
def test_attitude_angles_round_trip_through_the_mavlink_quaternion(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for _ in range(200):
        roll, yaw = rng.uniform(-math.pi + 1e-6, math.pi - 1e-6, 2)
        pitch = rng.uniform(-0.5 * math.pi + 1e-3, 0.5 * math.pi - 1e-3)
        q_wxyz = frames.q_WB_to_mavlink(frames.euler_ned_frd_to_q_WB(roll, pitch, yaw))
        back = frames.mavlink_q_to_euler_ned_frd(q_wxyz)
        assert np.allclose(back, (roll, pitch, yaw), atol=1e-9)
