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


def test_pose_at_matches_a_search_of_the_ordered_times() -> None:
    """pose_at bisects the ring in place: the same sample pair (and the same numbers) as interpolating
    between the times put in order, with the ring partly filled, full and wrapped, and repeated times."""
    rng = np.random.default_rng(5)
    for capacity in (2, 3, 7, 16):
        h = EgoHistory(capacity=capacity)
        t = 0.0
        for _ in range(3 * capacity):
            t += float(rng.choice([0.0, 0.01, 0.02, 0.07]))
            q = rng.normal(size=4)
            h.add(t, rng.normal(size=3), q / np.linalg.norm(q))
            order = h._order()
            ts, ps = h.t[order], h.p[order]
            for tq in [*rng.uniform(ts[0] - 0.1, t + 0.1, 20), ts[0], t, t + 0.05]:
                pose = h.pose_at(float(tq))
                k = int(np.searchsorted(ts, tq))
                if (k == 0 and ts[0] - tq > 0.05) or (k == ts.size and tq - ts[-1] > 0.05):
                    assert pose is None
                    continue
                assert pose is not None
                if k in (0, ts.size):
                    np.testing.assert_array_equal(pose[0], ps[min(k, ts.size - 1)])
                else:
                    s = (tq - ts[k - 1]) / max(ts[k] - ts[k - 1], 1e-9)
                    np.testing.assert_array_equal(pose[0], (1 - s) * ps[k - 1] + s * ps[k])
