"""Guidance with issue 16's opt-in features: the search area growing with the platform's possible speed,
the intercept of a fast platform, and the defaults leaving paper 000's behaviour alone."""

from __future__ import annotations

import numpy as np
import pytest

from alight.airframe import DEFAULT_AIRFRAME
from alight.mission.guidance import Guidance, GuidanceConfig
from alight.mission.state_machine import MissionConfig
from alight.planning.candidates import CandidatePlanner, PlannerConfig
from alight.types import EgoState, FloatArray, Mode, PlatformEstimate


def _ego(t: float, p: FloatArray) -> EgoState:
    return EgoState(t, np.asarray(p, float), np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3))


def _guidance(**kw: object) -> Guidance:
    config = GuidanceConfig(search_area=(-20.0, 20.0, -20.0, 20.0), **kw)  # type: ignore[arg-type]
    # the scenario's default horizon, 1-3 s
    planner = CandidatePlanner(
        PlannerConfig.from_airframe(DEFAULT_AIRFRAME, horizon_min_s=1.0, horizon_max_s=3.0)
    )
    return Guidance(MissionConfig(), planner, config)


class _StraightLine:
    """A platform estimator stub: constant velocity from p0 at t = 0."""

    initialized = True
    has_measurement = True

    def __init__(self, p0: FloatArray, v: FloatArray) -> None:
        self.p0, self.v = np.asarray(p0, float), np.asarray(v, float)

    def predict_ahead(self, times: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        ts = np.asarray(times, float)[:, None]
        p = self.p0 + self.v * ts
        return p, np.repeat(self.v[None], ts.shape[0], 0), np.zeros_like(p), np.zeros(ts.shape[0])

    def state(self, t: float) -> PlatformEstimate:
        return PlatformEstimate(t, self.p0 + self.v * t, self.v, np.zeros(3), 0.0, np.eye(3) * 0.01, t)


def test_initial_search_grows_with_time_since_take_off() -> None:
    g = _guidance(max_platform_speed_mps=4.0)
    hover = np.array([0.0, 0.0, 4.0])
    g.update(0.0, Mode.TAKEOFF, _ego(0.0, [0.0, 0.0, 0.1]), None, None, hover)
    g.update(10.0, Mode.EXPLORE, _ego(10.0, hover), None, None, hover)
    # 20 m + 4 m/s x 10 s = 60 m on every side
    assert g._area == pytest.approx((-60.0, 60.0, -60.0, 60.0))
    assert g._route is not None
    reach = max(float(np.max(np.abs(seg.sample(seg.t0)[0][:2]))) for seg in g._route.segments)
    assert reach > 50.0  # the spiral's outer legs run out there


def test_search_after_a_sighting_is_centred_on_the_prediction() -> None:
    g = _guidance(max_platform_speed_mps=4.0)
    hover = np.array([0.0, 0.0, 4.0])
    g.update(0.0, Mode.TAKEOFF, _ego(0.0, [0.0, 0.0, 0.1]), None, None, hover)
    # last seen at t = 25 s; now t = 30 s, predicted at (50, 10), std 1 m: 3 + 4 x 5 = 23 m
    target = PlatformEstimate(
        30.0, np.array([50.0, 10.0, 0.5]), np.zeros(3), np.zeros(3), 0.0, np.eye(3), 25.0
    )
    g.update(30.0, Mode.EXPLORE, _ego(30.0, [40.0, 0.0, 12.0]), target, None, hover)
    assert g._area == pytest.approx((27.0, 73.0, -13.0, 33.0))


def test_defaults_keep_the_configured_area() -> None:
    g = _guidance()
    hover = np.array([0.0, 0.0, 4.0])
    g.update(0.0, Mode.TAKEOFF, _ego(0.0, [0.0, 0.0, 0.1]), None, None, hover)
    g.update(10.0, Mode.EXPLORE, _ego(10.0, hover), None, None, hover)
    assert g._area == (-20.0, 20.0, -20.0, 20.0)


def test_intercept_plans_to_meet_a_fast_platform() -> None:
    # The platform 30 m east driving north at 12 m/s; the F450's intercept speed is
    # min(15, 0.7 x g tan 45 / 0.3) = 15 m/s: T = 10/3 s at (30, 40) (tests/planning/test_envelope.py).
    est = _StraightLine([30.0, 0.0, 0.5], [0.0, 12.0, 0.0])
    g = _guidance(intercept=True, adaptive_horizon=True, no_feasible="extend")
    hover = np.array([0.0, 0.0, 4.0])
    g.update(0.0, Mode.TRACK, _ego(0.0, hover), est.state(0.0), est, hover)  # type: ignore[arg-type]
    T_int = 10.0 / 3.0
    assert g.t_intercept_s == pytest.approx(T_int, abs=0.02)
    assert g._plan is not None
    # 50 m in [3.3, 3.7] s from a hover is beyond the F450's thrust: the 'extend' rule doubled the
    # window once, [6.7, 7.3] s; the plan ends there on the platform's path, moving with it
    assert g.plans_extended == 1
    T = g._plan.t_end
    assert 2.0 * T_int - 0.05 <= T <= 2.2 * T_int + 0.05
    p_end, v_end, _, _ = g._plan.sample(T)
    np.testing.assert_allclose(p_end[:2], [30.0, 12.0 * T], atol=1e-6)
    np.testing.assert_allclose(v_end[:2], [0.0, 12.0], atol=1e-6)


def test_without_intercept_the_fixed_horizon_finds_nothing_far_away() -> None:
    est = _StraightLine([30.0, 0.0, 0.5], [0.0, 12.0, 0.0])
    g = _guidance()
    hover = np.array([0.0, 0.0, 4.0])
    g.update(0.0, Mode.TRACK, _ego(0.0, hover), est.state(0.0), est, hover)  # type: ignore[arg-type]
    assert g._plan is None  # paper 000's rule: no feasible candidate, nothing to fly
    g2 = _guidance(no_feasible="extend")
    g2.update(0.0, Mode.TRACK, _ego(0.0, hover), est.state(0.0), est, hover)  # type: ignore[arg-type]
    assert g2._plan is not None  # a longer horizon (or the clipped longest candidate) is flown
    assert g2.plans_extended + g2.plans_clipped == 1
