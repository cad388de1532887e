"""The tracking height that keeps an uncertain platform estimate inside the camera's view
(``track_view_sigmas``), against cases worked by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.airframe import DEFAULT_AIRFRAME
from alight.mission.guidance import Guidance, GuidanceConfig
from alight.mission.state_machine import MissionConfig
from alight.planning.candidates import CandidatePlanner, PlannerConfig
from alight.types import EgoState, PlatformEstimate


def _guidance(**kw: object) -> Guidance:
    planner = CandidatePlanner(PlannerConfig.from_airframe(DEFAULT_AIRFRAME))
    return Guidance(MissionConfig(), planner, GuidanceConfig(**kw))  # type: ignore[arg-type]


def _target(std_m: float) -> PlatformEstimate:
    cov = np.diag([std_m**2, std_m**2, 0.01])
    return PlatformEstimate(
        10.0, np.array([3.0, 4.0, 0.5]), np.array([6.0, 0.0, 0.0]), np.zeros(3), 0.0, cov, 10.0
    )


def _over(target: PlatformEstimate, height_above_pad: float) -> EgoState:
    p = target.p_WP + np.array([0.0, 0.0, height_above_pad])
    return EgoState(target.t, p, target.v_WP, np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3))


def test_a_gnss_only_estimate_is_tracked_high_enough_to_see_the_pad() -> None:
    # By hand: a 1.2 m standard deviation, 2 sigmas, a 64 deg narrower view: 2.4 / tan(32 deg) = 3.84 m
    # above the pad, not the mission's 2 m tracking height.
    g = _guidance(track_view_sigmas=2.0, camera_fov_rad=math.radians(64.0))
    target = _target(1.2)
    expected = 2.4 / math.tan(math.radians(32.0))
    assert expected == pytest.approx(3.8408, abs=1e-4)
    assert g._track_height(10.0, _over(target, 2.0), target, True) == pytest.approx(expected)
    # also before the estimator has a heading: it holds its height, but not below the view height
    assert g._track_height(10.0, _over(target, 2.0), target, False) == pytest.approx(expected)


def test_a_camera_estimate_leaves_the_papers_height_rule_alone() -> None:
    # 3 cm: 2 sigmas need 0.1 m, far below the 2 m tracking height
    on, off = _guidance(track_view_sigmas=2.0), _guidance()
    target = _target(0.03)
    ego = _over(target, 2.0)
    assert on._track_height(10.0, ego, target, True) == off._track_height(10.0, ego, target, True)
    assert off._track_height(10.0, ego, target, True) == pytest.approx(MissionConfig().track_height_m)


def test_the_view_height_never_exceeds_the_exploration_altitude() -> None:
    g = _guidance(track_view_sigmas=2.0)
    target = _target(20.0)  # 64 m by the rule
    top = MissionConfig().explore_altitude_m - 0.5
    assert g._track_height(10.0, _over(target, 2.0), target, True) == pytest.approx(top)


def test_bad_settings_are_refused() -> None:
    for bad in (-1.0, math.inf, math.nan):
        with pytest.raises(ValueError, match="track_view_sigmas"):
            GuidanceConfig(track_view_sigmas=bad)


@pytest.mark.parametrize("preset", ["groundtruth", "falanga2017", "kim_kaist", "zamanakos_sdu", "alight"])
def test_the_key_reaches_every_presets_guidance(preset: str) -> None:
    from alight.mission.presets import build_preset
    from alight.scenario import scenario_from_dict

    def sigmas(extra: dict) -> float | None:
        s = scenario_from_dict({"preset": preset, "seed": 1, "mission": extra})
        return build_preset(
            s, DEFAULT_AIRFRAME, np.random.default_rng(0)
        ).pipeline.guidance.config.track_view_sigmas

    assert sigmas({"track_view_sigmas": 1.5}) == 1.5
    assert sigmas({}) == (2.0 if preset == "alight" else None)
