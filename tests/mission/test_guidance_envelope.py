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


def _estimate(
    t: float, p: tuple[float, float], v: tuple[float, float], std: float, t_meas: float
) -> PlatformEstimate:
    return PlatformEstimate(
        t,
        np.array([p[0], p[1], 0.5]),
        np.array([v[0], v[1], 0.0]),
        np.zeros(3),
        0.0,
        np.eye(3) * std**2,
        t_meas,
    )


def test_exploration_after_a_loss_covers_what_the_platform_can_reach_from_its_last_sighting() -> None:
    """Seen at t = 10 s at (5, 0) with 0.5 m std, 3 m/s east; at t = 30 s the prediction has run on to
    (65, 0) with 100 m std. The platform is within 1.5 m + 4 m/s x 20 s = 81.5 m of (5, 0), wherever the
    prediction went; the exploration covers that square and spirals out from (5, 0)."""
    g = _guidance(max_platform_speed_mps=4.0)
    hover = np.array([0.0, 0.0, 12.0])
    g.update(
        10.0, Mode.TRACK, _ego(10.0, [5.0, 0.0, 4.0]), _estimate(10.0, (5, 0), (3, 0), 0.5, 10.0), None, hover
    )
    lost = _estimate(30.0, (65, 0), (3, 0), 100.0, 10.0)
    g.update(30.0, Mode.EXPLORE, _ego(30.0, [60.0, 0.0, 12.0]), lost, None, hover)
    assert g._area == pytest.approx((5.0 - 81.5, 5.0 + 81.5, -81.5, 81.5))
    assert g._route is not None
    first_leg_start = g._route.segments[1].sample(g._route.segments[1].t0)[0]  # after the approach
    assert np.hypot(first_leg_start[0] - 5.0, first_leg_start[1]) < 15.0


def test_a_platform_seen_faster_than_the_configured_bound_widens_the_reach() -> None:
    g = _guidance(max_platform_speed_mps=4.0)
    hover = np.array([0.0, 0.0, 12.0])
    g.update(
        10.0, Mode.TRACK, _ego(10.0, [5.0, 0.0, 4.0]), _estimate(10.0, (5, 0), (6, 8), 0.5, 10.0), None, hover
    )
    g.update(
        30.0,
        Mode.EXPLORE,
        _ego(30.0, [60.0, 0.0, 12.0]),
        _estimate(30.0, (205, 160), (6, 8), 99.0, 10.0),
        None,
        hover,
    )
    # 1.5 m + 10 m/s x 20 s
    assert g._area == pytest.approx((5.0 - 201.5, 5.0 + 201.5, -201.5, 201.5))


def _search_centre(g: Guidance, t: float, target: PlatformEstimate) -> tuple[np.ndarray, np.ndarray]:
    ref = g.reference(t, Mode.SEARCH, target)
    rho, th = g.search_radius_m, g._theta
    return ref.p[:2] - rho * np.array([np.cos(th), np.sin(th)]), ref.v[:2]


@pytest.mark.parametrize("bounded", [True, False])
def test_the_search_centre_holds_once_the_prediction_outgrows_the_reach(bounded: bool) -> None:
    """Seen at t = 10 s at (5, 0), 0.5 m std, 3 m/s east; the reach is 1.5 m + 4 m/s x (t - 10). The
    prediction's 3 sigma: 3 m at 13 s (reach 13.5: follow), 15 m at 14 s (17.5: follow), 30 m at 15 s
    (21.5: hold there, at (20, 0)), and the centre stays at (20, 0) at 16 s. Without a speed bound (the
    papers' presets) the centre follows the prediction throughout."""
    g = _guidance(max_platform_speed_mps=4.0) if bounded else _guidance()
    hover = np.array([0.0, 0.0, 12.0])
    ego = _ego(10.0, [5.0, 0.0, 4.0])
    g.update(10.0, Mode.TRACK, ego, _estimate(10.0, (5, 0), (3, 0), 0.5, 10.0), None, hover)
    for t, x, std in ((13.0, 14.0, 1.0), (14.0, 17.0, 5.0), (15.0, 20.0, 10.0), (16.0, 23.0, 20.0)):
        target = _estimate(t, (x, 0), (3, 0), std, 10.0)
        g.update(t, Mode.SEARCH, _ego(t, [x, 0.0, 12.0]), target, None, hover)
        c, v = _search_centre(g, t, target)
        held = bounded and t >= 15.0
        np.testing.assert_allclose(c, [20.0, 0.0] if held else [x, 0.0], atol=1e-9)
        # the reference's velocity is the centre's (0 once held) plus the spiral's, which is tangential
        v_spiral = v - (np.zeros(2) if held else np.array([3.0, 0.0]))
        radial = np.array([np.cos(g._theta), np.sin(g._theta)])
        assert float(v_spiral @ radial) == pytest.approx(0.0, abs=1e-9)
