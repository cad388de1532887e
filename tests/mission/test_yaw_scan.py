"""The heading scan: the reference's heading turns while nothing is in view and holds otherwise, and the
scenario key that sets the rate acts on every preset."""

from __future__ import annotations

import math

import numpy as np
import pytest
from preset_flight import pipeline_taking_off

from alight.airframe import DEFAULT_AIRFRAME
from alight.mission.guidance import GuidanceConfig
from alight.mission.presets import PRESETS, build_preset
from alight.scenario import scenario_from_dict
from alight.types import Mode


def _guidance(rate: float):  # type: ignore[no-untyped-def]
    s = scenario_from_dict({"preset": "groundtruth", "seed": 1, "mission": {"scan_yaw_rate_rad_s": rate}})
    return build_preset(s, DEFAULT_AIRFRAME, np.random.default_rng(0)).pipeline.guidance


def test_the_heading_turns_in_the_scan_modes_and_holds_in_the_others() -> None:
    g = _guidance(1.5)
    # by hand: 1.5 rad/s from t = 0; at 1 s the heading is 1.5 rad, at 2 s 3.0 rad (both turning)
    assert g._heading(0.0, Mode.TAKEOFF) == (0.0, 1.5)
    assert g._heading(1.0, Mode.TAKEOFF) == pytest.approx((1.5, 1.5))
    assert g._heading(2.0, Mode.EXPLORE) == pytest.approx((3.0, 1.5))
    # tracking holds the heading reached, at rate 0, however long it lasts
    assert g._heading(2.5, Mode.TRACK) == pytest.approx((3.0, 0.0))
    assert g._heading(9.0, Mode.LAND) == pytest.approx((3.0, 0.0))
    # searching turns again from where it was, wrapped to (-pi, pi]: 3.0 + 1.5 * 0.5 = 3.75 -> 3.75 - 2 pi
    assert g._heading(9.5, Mode.SEARCH) == pytest.approx((3.75 - 2.0 * math.pi, 1.5))


def test_no_rate_keeps_the_papers_fixed_heading() -> None:
    g = _guidance(0.0)
    for t, mode in ((0.0, Mode.TAKEOFF), (5.0, Mode.EXPLORE), (9.0, Mode.SEARCH), (12.0, Mode.TRACK)):
        assert g._heading(t, mode) == (0.0, 0.0)
    with pytest.raises(ValueError, match="scan_yaw_rate_rad_s"):
        GuidanceConfig(scan_yaw_rate_rad_s=math.nan)


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_the_scan_key_acts_on_every_preset(preset: str) -> None:
    def heading_after_climb(extra: dict) -> float:
        pipeline = pipeline_taking_off(preset, extra)
        pipeline.command(0.0)
        pipeline.step(1.0)  # 1 s into the climb
        pipeline.command(1.0)
        ref = pipeline.last_reference
        assert ref is not None
        return float(ref.yaw)

    assert heading_after_climb({"scan_yaw_rate_rad_s": 0.7}) == pytest.approx(0.7)
    assert heading_after_climb({"scan_yaw_rate_rad_s": 0.0}) == 0.0
    default = 1.5 if preset == "alight" else 0.0
    assert heading_after_climb({}) == pytest.approx(default)
