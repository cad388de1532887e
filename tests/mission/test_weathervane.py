"""The weathervane: outside the scan the heading turns, rate-limited, so that the camera's wider view lies
along the vehicle's steady lean; the scenario key that sets it acts on every preset."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from alight.airframe import DEFAULT_AIRFRAME
from alight.errors import ConfigError
from alight.mission.guidance import GuidanceConfig
from alight.mission.presets import PRESETS, build_preset
from alight.scenario import scenario_from_dict
from alight.types import EgoState, Mode


def _leaning(t: float, tilt_rad: float, toward_rad: float) -> EgoState:
    """At rest, the body z axis tilted by ``tilt_rad`` toward the horizontal direction ``toward_rad``."""
    axis = np.array([-math.sin(toward_rad), math.cos(toward_rad), 0.0])  # e_z x direction
    q = Rotation.from_rotvec(tilt_rad * axis).as_quat()
    return EgoState(t, np.zeros(3), np.zeros(3), q, np.zeros(3))


def _guidance(preset: str = "groundtruth", **mission: float):  # type: ignore[no-untyped-def]
    s = scenario_from_dict({"preset": preset, "seed": 1, "mission": mission})
    return build_preset(s, DEFAULT_AIRFRAME, np.random.default_rng(0)).pipeline.guidance


def _settle_lean(g, tilt_rad: float, toward_rad: float, seconds: float = 30.0) -> float:  # type: ignore[no-untyped-def]
    """Feed the lean at 10 Hz (the planner's rate) long enough for the low-pass to settle; the last t."""
    t = 0.0
    for k in range(int(seconds * 10) + 1):
        t = 0.1 * k
        g._update_lean(t, _leaning(t, tilt_rad, toward_rad))
    return t


def test_the_wide_view_axis_comes_from_the_camera_and_its_mount() -> None:
    # paper 000's camera, 752 x 480 (the wider field along the image columns), mounted with the image x
    # axis along -y of the body: the wider view lies along body y, -pi/2 from body x
    assert _guidance("falanga2017").config.wide_view_axis_B_rad == pytest.approx(-0.5 * math.pi)
    # the ground-truth sensor: 90 x 64 deg on the same mount
    assert _guidance("groundtruth").config.wide_view_axis_B_rad == pytest.approx(-0.5 * math.pi)


def test_the_heading_turns_the_wide_view_along_the_lean_at_the_rate_limit() -> None:
    g = _guidance(weathervane_min_tilt_rad=0.1)
    # leaning 25 deg toward 30 deg: the wide view (body y) must lie along 30 deg or 210 deg, i.e. the
    # heading at 30 - 90 = -60 deg or 120 deg; from 0 the nearer is -60 deg
    t = _settle_lean(g, math.radians(25.0), math.radians(30.0))
    assert g.weathervane_goal() == pytest.approx(math.radians(-60.0), abs=1e-6)
    # at most 0.5 rad/s: 0.1 s later the heading is -0.05 rad, turning at -0.5 rad/s
    assert g._heading(t, Mode.TRACK) == (0.0, 0.0)  # the first call only starts the clock
    yaw, rate = g._heading(t + 0.1, Mode.TRACK)
    assert (yaw, rate) == pytest.approx((-0.05, -0.5))
    # after 3 s in all it has arrived (1.047 rad at 0.5 rad/s takes 2.09 s) and stays
    for k in range(2, 31):
        yaw, rate = g._heading(t + 0.1 * k, Mode.LAND)
    assert (yaw, rate) == pytest.approx((math.radians(-60.0), 0.0), abs=1e-9)


def test_a_small_lean_or_the_scan_leaves_the_heading_alone() -> None:
    g = _guidance(weathervane_min_tilt_rad=0.1)
    t = _settle_lean(g, 0.09, 1.0)  # below 0.1 rad (sin 0.09 < sin 0.1)
    assert g.weathervane_goal() is None
    g._heading(t, Mode.TRACK)
    assert g._heading(t + 1.0, Mode.TRACK) == (0.0, 0.0)
    # a scan turns at the scan rate whatever the lean
    g = _guidance(weathervane_min_tilt_rad=0.1, scan_yaw_rate_rad_s=1.5)
    t = _settle_lean(g, 0.4, 1.0)
    assert g.weathervane_goal() is not None
    g._heading(t, Mode.EXPLORE)
    assert g._heading(t + 0.2, Mode.EXPLORE) == pytest.approx((0.3, 1.5))


def test_off_by_default_for_the_papers_and_bad_values_refused() -> None:
    g = _guidance()
    _settle_lean(g, 0.4, 1.0)
    assert g.weathervane_goal() is None
    with pytest.raises(ValueError, match="weathervane_min_tilt_rad"):
        GuidanceConfig(weathervane_min_tilt_rad=math.nan)
    with pytest.raises(ValueError, match="weathervane_yaw_rate_rad_s"):
        GuidanceConfig(weathervane_yaw_rate_rad_s=0.0)
    with pytest.raises(ConfigError, match="mission.weathervane_min_tilt_rad: Input should be less than 1.5"):
        scenario_from_dict({"preset": "alight", "seed": 1, "mission": {"weathervane_min_tilt_rad": 2.0}})


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_the_weathervane_key_acts_on_every_preset(preset: str) -> None:
    for value, turns in ((0.1, True), (None, preset == "alight")):
        g = _guidance(preset, **({} if value is None else {"weathervane_min_tilt_rad": value}))
        t = _settle_lean(g, math.radians(20.0), 0.0)
        g._heading(t, Mode.TRACK)
        yaw, _ = g._heading(t + 0.5, Mode.TRACK)
        assert (abs(yaw) > 0.2) is turns, (preset, value, yaw)
