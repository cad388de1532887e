"""EgoHistory: the camera pose at an image's capture time, from a ring of ego estimates."""

from __future__ import annotations

import math

import numpy as np

from alight.mission.pipeline import EgoHistory
from alight.types import quat_to_rotmat


def _q_yaw(yaw: float) -> np.ndarray:
    return np.array([0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)])


def test_interpolates_position_velocity_and_attitude_after_the_ring_wraps() -> None:
    h = EgoHistory(capacity=16)
    dt = 0.01
    for k in range(40):  # 2.5 times around the ring
        t = k * dt
        h.add(t, np.array([t, 2 * t, 3.0]), _q_yaw(0.5 * t), np.array([1.0, 2.0, 0.0]))
    # only the last 16 samples remain: t in [0.24, 0.39]
    t = 0.305
    pose = h.pose_at(t)
    assert pose is not None
    p, R = pose
    np.testing.assert_allclose(p, [t, 2 * t, 3.0], atol=1e-12)
    np.testing.assert_allclose(R, quat_to_rotmat(_q_yaw(0.5 * t)), atol=1e-6)
    state = h.state_at(t)
    assert state is not None
    np.testing.assert_allclose(state.v_WB, [1.0, 2.0, 0.0], atol=1e-12)
    # 50 ms beyond the stored span is still answered (held), farther is not
    assert h.pose_at(0.24 - 0.04) is not None and h.pose_at(0.24 - 0.06) is None
    assert h.pose_at(0.39 + 0.04) is not None and h.pose_at(0.39 + 0.06) is None


def test_before_the_ring_is_full_and_when_empty() -> None:
    h = EgoHistory(capacity=16)
    assert h.pose_at(0.0) is None
    for k in range(5):
        h.add(k * 0.1, np.array([k * 0.1, 0.0, 0.0]), _q_yaw(0.0))
    pose = h.pose_at(0.25)
    assert pose is not None
    np.testing.assert_allclose(pose[0], [0.25, 0.0, 0.0], atol=1e-12)
