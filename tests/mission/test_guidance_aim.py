"""Take-off and exploration aim the body-fixed downward camera, not the body, at their references."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.airframe import DEFAULT_AIRFRAME
from alight.mission.guidance import Guidance, GuidanceConfig
from alight.mission.state_machine import MissionConfig
from alight.planning.candidates import CandidatePlanner, PlannerConfig
from alight.types import EgoState, Mode

HOVER = np.array([0.0, 0.0, 12.0])


def _tilted(t: float, p: np.ndarray, tilt_rad: float, axis: np.ndarray) -> EgoState:
    """Ego state tilted by ``tilt_rad`` about the horizontal unit ``axis`` (x, y, 0)."""
    s, c = math.sin(tilt_rad / 2), math.cos(tilt_rad / 2)
    q = np.array([axis[0] * s, axis[1] * s, 0.0, c])
    return EgoState(t, p, np.zeros(3), q, np.zeros(3))


def _guidance(**kw: object) -> Guidance:
    planner = CandidatePlanner(PlannerConfig.from_airframe(DEFAULT_AIRFRAME))
    return Guidance(MissionConfig(), planner, GuidanceConfig(**kw))  # type: ignore[arg-type]


def _settle(g: Guidance, mode: Mode, tilt_rad: float, axis: np.ndarray, t_end: float = 20.0) -> float:
    """Hold a tilted ego state at HOVER for ``t_end`` s of 50 Hz updates; returns the last time. In
    TAKEOFF at the hover point the reference does not accelerate, so all the tilt is the side force's."""
    t = 0.0
    for t in np.arange(0.0, t_end, 0.02):
        g.update(float(t), mode, _tilted(float(t), HOVER, tilt_rad, axis), None, None, HOVER)
        g.reference(float(t), mode, None)
    return float(t)


def test_a_steady_tilt_shifts_the_exploration_reference_upwind_by_h_tan_tilt() -> None:
    # Pitching about +y tilts the thrust toward +x: the side force (wind) pushes toward -x, the camera
    # looks toward -x, so the reference moves h tan(tilt) toward +x to bring the view back.
    tilt = math.radians(35.0)
    g = _guidance()
    t = _settle(g, Mode.TAKEOFF, tilt, np.array([0.0, 1.0]))
    np.testing.assert_allclose(g.aim_offset_W, [HOVER[2] * math.tan(tilt), 0.0, 0.0], rtol=1e-3, atol=1e-6)
    p_takeoff = g.reference(t, Mode.TAKEOFF, None).p
    np.testing.assert_allclose(p_takeoff - HOVER, g.aim_offset_W, atol=1e-6)
    # exploration starts where the aimed take-off reference left off, its route at the hover point
    t += 0.02
    g.update(t, Mode.EXPLORE, _tilted(t, p_takeoff, tilt, np.array([0.0, 1.0])), None, None, HOVER)
    route = g._route
    assert route is not None
    p_route = route.reference(t)[0]
    p_ref = g.reference(t, Mode.EXPLORE, None).p
    np.testing.assert_allclose(p_route, HOVER, atol=1e-6)
    np.testing.assert_allclose(p_ref - p_route, g.aim_offset_W, atol=1e-9)
    # the camera's optical axis (-z_B) from a body at the reference meets the ground at the route point
    ego = _tilted(t, p_ref, tilt, np.array([0.0, 1.0]))
    x, y, z, w = ego.q_WB
    z_B = np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])
    ground = p_ref - z_B * (p_ref[2] / z_B[2])
    np.testing.assert_allclose(ground[:2], p_route[:2], atol=1e-2)


@pytest.mark.parametrize("axis", [np.array([1.0, 0.0]), np.array([-0.6, 0.8])])
def test_the_offset_follows_the_tilt_direction(axis: np.ndarray) -> None:
    tilt = math.radians(20.0)
    g = _guidance()
    _settle(g, Mode.TAKEOFF, tilt, axis)
    # a rotation about the unit axis (a, b, 0) turns z_B toward (b, -a)
    expected = HOVER[2] * math.tan(tilt) * np.array([axis[1], -axis[0]])
    np.testing.assert_allclose(g.aim_offset_W[:2], expected, rtol=1e-3)


def test_level_flight_and_the_option_off_leave_the_reference_alone() -> None:
    level = _guidance()
    _settle(level, Mode.TAKEOFF, 0.0, np.array([1.0, 0.0]))
    np.testing.assert_allclose(level.aim_offset_W, 0.0, atol=1e-12)
    off = _guidance(aim_camera=False)
    _settle(off, Mode.TAKEOFF, math.radians(35.0), np.array([0.0, 1.0]))
    np.testing.assert_allclose(off.aim_offset_W, 0.0, atol=1e-12)


def test_the_offset_is_capped_and_low_passed() -> None:
    g = _guidance(aim_max_tan_tilt=0.5, aim_time_constant_s=2.0)
    _settle(g, Mode.TAKEOFF, math.radians(60.0), np.array([0.0, 1.0]))
    assert np.linalg.norm(g.aim_offset_W) == pytest.approx(HOVER[2] * 0.5, rel=1e-6)
    # a gust step: one time constant after it, the offset has moved ~63% of the way (first order)
    g2 = _guidance(aim_time_constant_s=2.0)
    _settle(g2, Mode.TAKEOFF, 0.0, np.array([0.0, 1.0]), t_end=1.0)
    tilt = math.radians(30.0)
    for t in np.arange(1.02, 3.0 + 1e-9, 0.02):
        g2.update(
            float(t), Mode.TAKEOFF, _tilted(float(t), HOVER, tilt, np.array([0.0, 1.0])), None, None, HOVER
        )
    frac = g2.aim_offset_W[0] / (HOVER[2] * math.tan(tilt))
    assert 0.55 < frac < 0.70


def test_a_tilt_that_accelerates_the_vehicle_is_not_wind() -> None:
    # In calm air the vehicle tilts to accelerate (the position loop chasing its reference). Reading that
    # tilt as wind would shift the reference further the same way: the offset must stay at zero when the
    # measured acceleration accounts for the whole tilt.
    tilt = math.radians(20.0)
    accel = 9.81 * math.tan(tilt)  # toward +x for a rotation about +y
    g = _guidance()
    for t in np.arange(0.0, 10.0, 0.02):
        ego = _tilted(float(t), HOVER, tilt, np.array([0.0, 1.0]))
        ego = EgoState(float(t), HOVER, np.array([accel * t, 0.0, 0.0]), ego.q_WB, np.zeros(3))
        g.update(float(t), Mode.TAKEOFF, ego, None, None, HOVER)
    np.testing.assert_allclose(g.aim_offset_W, 0.0, atol=0.02)


def test_tracking_and_landing_are_not_aimed() -> None:
    g = _guidance()
    _settle(g, Mode.TAKEOFF, math.radians(35.0), np.array([0.0, 1.0]))
    assert g.aim_offset_W[0] > 5.0
    t = 20.0
    g.update(t, Mode.ABORT, _tilted(t, HOVER, math.radians(35.0), np.array([0.0, 1.0])), None, None, HOVER)
    ref = g.reference(t, Mode.ABORT, None)
    # abort holds where the vehicle is (the aimed reference), without adding the offset a second time
    np.testing.assert_allclose(ref.p[:2], HOVER[:2], atol=1e-6)


def test_bad_aim_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="aim_time_constant_s"):
        GuidanceConfig(aim_time_constant_s=0.0)
    with pytest.raises(ValueError, match="aim_max_tan_tilt"):
        GuidanceConfig(aim_max_tan_tilt=float("nan"))
