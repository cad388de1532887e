"""The commit height rises to where the camera can no longer see the AprilTag pad's central marker."""

from __future__ import annotations

import math

import pytest

from alight.mission.presets import VIEW_TILT_ALLOWANCE_RAD, build_preset, visibility_commit_height_m
from alight.pads.apriltag_pad import AprilTagPad
from alight.pads.falanga_tag import FalangaTag
from alight.scenario import Scenario

APRILTAG_SET = {
    "preset": "falanga2017",
    "blocks": {"camera": "pinhole", "pad": "apriltag", "detector": "aruco", "geolocator": "pnp"},
}


class _Camera:
    def __init__(self, h_fov: float, v_fov: float) -> None:
        self._fov = (h_fov, v_fov)

    def fov_rad(self) -> tuple[float, float]:
        return self._fov


def test_height_worked_by_hand() -> None:
    # a 1.5 m pad: central marker 0.8 m, with its one-cell quiet zone 0.8 * 10 / 8 = 1.0 m; a 63.43 deg
    # vertical field of view: half 31.715 deg less 5 deg of tilt allowance = 26.715 deg, tan = 0.50318
    pad = AprilTagPad.default(1.5)
    assert pad.min_view_side_m == pytest.approx(1.0, abs=1e-12)
    h = visibility_commit_height_m(pad, _Camera(math.radians(90.7), math.radians(63.43)))
    assert h == pytest.approx(0.5 / math.tan(math.radians(31.715) - VIEW_TILT_ALLOWANCE_RAD), rel=1e-12)
    assert h == pytest.approx(0.9937, abs=1e-3)


def test_pads_seen_in_part_keep_their_commit_height() -> None:
    assert visibility_commit_height_m(FalangaTag.default(1.5), _Camera(1.5, 1.1)) is None
    assert visibility_commit_height_m(AprilTagPad.default(1.5), None) is None


def test_the_preset_commits_no_lower_and_a_scenario_value_stands() -> None:
    import numpy as np

    from alight.airframes import load_airframe

    af, rng = load_airframe("f450"), np.random.default_rng(0)
    floor = build_preset(Scenario.model_validate(APRILTAG_SET), af, rng).pipeline.mission.config
    assert floor.land_commit_height_m == pytest.approx(0.99, abs=0.01)
    own = build_preset(
        Scenario.model_validate({**APRILTAG_SET, "mission": {"land_commit_height_m": 0.7}}), af, rng
    ).pipeline.mission.config
    assert own.land_commit_height_m == 0.7
    paper = build_preset(Scenario.model_validate({"preset": "falanga2017"}), af, rng).pipeline.mission.config
    assert paper.land_commit_height_m == 0.6  # paper 000's tag: unchanged
