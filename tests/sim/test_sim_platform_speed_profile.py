"""Platform speed profiles: the same path, driven at a varying speed, with consistent kinematics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.errors import ConfigError
from alight.scenario import scenario_from_dict
from alight.sim.faults import speed_profile
from alight.sim.platform import Platform, PlatformConfig, SpeedProfile

DT = 1e-3


def _platform(path: str, speed: float, profile: SpeedProfile | None) -> Platform:
    return Platform(
        PlatformConfig(path=path, speed_mps=speed, speed_profile=profile),  # type: ignore[arg-type]
        np.random.default_rng(4),
    )


@pytest.mark.parametrize("path", ["straight", "circle", "figure8", "tractor", "random"])
def test_positions_differentiate_to_velocity_and_velocity_to_acceleration(path: str) -> None:
    profile = SpeedProfile.brake_stop(4.0, 2.0, 8.0, 1.5, 4.0)
    st = _platform(path, 4.0, profile).states(np.arange(0.0, 8.0, DT))
    fd_v = np.diff(st.p_WP, axis=0) / DT
    mid_v = 0.5 * (st.v_WP[1:] + st.v_WP[:-1])
    assert np.abs(fd_v - mid_v).max() < 1e-4
    fd_a = np.diff(st.v_WP, axis=0) / DT
    mid_a = 0.5 * (st.a_WP[1:] + st.a_WP[:-1])
    # away from the instants where the acceleration jumps (the phase starts), they agree
    t_mid = st.t[:-1] + 0.5 * DT
    smooth = np.min(np.abs(t_mid[:, None] - np.array(profile.t_s)[None, :]), axis=1) > 2 * DT
    assert np.abs(fd_a - mid_a)[smooth].max() < 2e-2
    speed = np.hypot(st.v_WP[:, 0], st.v_WP[:, 1])
    assert speed.min() >= 0.0 and speed.max() <= 4.0 + 1e-9


def test_braking_distance_is_v_squared_over_2a_and_it_waits_then_drives_on() -> None:
    v, a = 3.0, 6.0
    profile = SpeedProfile.brake_stop(v, 5.0, a, 2.0, 2.0)
    p = _platform("straight", v, profile)
    t_stop = 5.0 + v / a
    s = p.states(np.array([5.0, t_stop, t_stop + 1.0, t_stop + 2.0]))
    travelled = np.linalg.norm(s.p_WP[1] - s.p_WP[0])
    assert travelled == pytest.approx(v * v / (2 * a), rel=1e-9)
    assert np.allclose(s.p_WP[2], s.p_WP[1]) and np.allclose(s.v_WP[1:3], 0.0)
    late = p.state(t_stop + 2.0 + v / 2.0 + 1.0)
    assert np.linalg.norm(late.v_WP) == pytest.approx(v)  # back at the path speed after accelerating


def test_the_path_is_the_same_only_the_timing_changes() -> None:
    plain = _platform("figure8", 2.0, None)
    ramped = _platform("figure8", 2.0, SpeedProfile.ramp(2.0, 1.0, 4.0, 1.0))
    t = np.linspace(0.0, 30.0, 301)
    s_ramp = ramped.config.speed_profile.kinematics(2.0, t)[0]  # type: ignore[union-attr]
    # the ramped platform at time t is where the constant-speed one is after driving the same distance
    same = plain.states(s_ramp / 2.0)
    assert np.allclose(ramped.states(t).p_WP, same.p_WP, atol=1e-9)
    assert np.allclose(ramped.states(t).yaw, same.yaw, atol=1e-9)
    # before the ramp it is the constant-speed platform exactly
    early = np.linspace(0.0, 1.0, 11)
    assert np.array_equal(ramped.states(early).p_WP, plain.states(early).p_WP)


def test_ramp_reaches_the_new_speed_and_the_state_matches_states() -> None:
    p = _platform("circle", 1.0, SpeedProfile.ramp(1.0, 2.0, 3.0, 2.0))
    assert np.linalg.norm(p.state(2.5).v_WP) == pytest.approx(2.0)
    assert np.linalg.norm(p.state(10.0).v_WP) == pytest.approx(3.0)
    one, many = p.state(2.5), p.states(np.array([2.5]))
    assert np.array_equal(one.p_WP, many.p_WP[0]) and np.array_equal(one.a_WP, many.a_WP[0])
    # tangential acceleration along the heading while ramping
    tangent = np.array([math.cos(one.yaw), math.sin(one.yaw), 0.0])
    assert float(one.a_WP @ tangent) == pytest.approx(2.0)
    slow = _platform("straight", 3.0, SpeedProfile.ramp(3.0, 1.0, 0.0, 1.5))
    assert np.linalg.norm(slow.state(20.0).v_WP) == 0.0  # a ramp to 0 parks the platform


def test_scenario_speed_profile_reaches_the_platform_and_limits_are_refused() -> None:
    s = scenario_from_dict(
        {"platform": {"speed_mps": 2.0, "speed_profile": {"brake_stop": {"t_s": 4.0, "decel_mps2": 8.0}}}}
    )
    prof = speed_profile(s.platform.speed_profile, s.platform.speed_mps)
    assert prof is not None and prof.t_s[0] == 4.0 and prof.accel_mps2[0] == -8.0
    for bad, where in [
        ({"brake_stop": {"t_s": 1.0, "decel_mps2": 9.0}}, "decel_mps2"),
        ({"brake_stop": {"t_s": 1.0, "accel_mps2": 5.0}}, "accel_mps2"),
        ({"ramp": {"t_s": 1.0, "speed_mps": 3.0, "accel_mps2": 4.5}}, "accel_mps2"),
        ({"ramp": {"t_s": 1.0, "speed_mps": 3.0}, "brake_stop": {"t_s": 1.0}}, "exactly one"),
    ]:
        with pytest.raises(ConfigError, match=where) as err:
            scenario_from_dict({"platform": {"speed_profile": bad}})
        assert "\n" not in str(err.value)
