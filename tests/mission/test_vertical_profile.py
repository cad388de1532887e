"""The height profile of a long intercept plan asks for no more vertical acceleration than the airframe
gives: from a fast climb toward a point below, a 2 s profile asked for -15 m/s^2 (more than gravity gives
with the motors idle) and the vehicle, unable to follow, climbed to 83 m while each replanning restarted
from its velocity (envelope wind, seed 2469339022)."""

from __future__ import annotations

import numpy as np
import pytest

from alight.airframe import DEFAULT_AIRFRAME
from alight.mission.guidance import _peak_vertical_accel, _SplitAxes
from alight.mission.presets import build_preset
from alight.planning.min_jerk import MinJerkTrajectory
from alight.scenario import scenario_from_dict

ZERO = np.zeros(3)


def test_peak_vertical_accel_of_a_rest_to_rest_move_by_hand() -> None:
    # rest to rest over d in T: the peak acceleration is 10 d / (sqrt(3) T^2) (at t = T (3 -+ sqrt 3) / 6)
    traj = MinJerkTrajectory.from_boundary(0.0, 2.0, ZERO, ZERO, ZERO, np.array([0.0, 0.0, 4.0]), ZERO, ZERO)
    assert _peak_vertical_accel(traj) == pytest.approx(10.0 * 4.0 / (np.sqrt(3.0) * 4.0), rel=0.03)


def test_a_long_plan_from_a_fast_climb_gets_a_height_profile_within_the_limit() -> None:
    s = scenario_from_dict({"preset": "alight", "seed": 1})
    g = build_preset(s, DEFAULT_AIRFRAME, np.random.default_rng(0)).pipeline.guidance
    limit = min(g.config.max_climb_accel_mps2, 0.5 * 9.81)
    p0, v0 = np.array([0.0, 0.0, 8.0]), np.array([0.0, 0.0, 5.0])
    pf = np.array([40.0, 0.0, 6.0])  # 2 m below, 40 m ahead, 8.8 s: the horizontal plan
    plan = MinJerkTrajectory.from_boundary(0.0, 8.8, p0, v0, ZERO, pf, ZERO, ZERO)
    # the old 2 s profile: from 5 m/s up to 2 m below in 2 s asks for far more than the limit
    old = MinJerkTrajectory.from_boundary(0.0, 2.0, p0, v0, ZERO, np.array([0.0, 0.0, 6.0]), ZERO, ZERO)
    assert _peak_vertical_accel(old) > 2.0 * limit
    split = g._split_vertical(0.0, plan, p0, v0, ZERO)
    assert isinstance(split, _SplitAxes)
    assert split.z.T > 2.0 and _peak_vertical_accel(split.z) <= limit
    # the horizontal axes are the plan's, the height ends at the plan's end height
    np.testing.assert_allclose(split.sample_packed(4.0)[:, :2], plan.sample_packed(4.0)[:, :2])
    assert split.sample_packed(split.z.t_end)[0, 2] == pytest.approx(6.0)
