"""The Pipeline's detector hooks: what it passes to a detector before each image."""

from __future__ import annotations

import numpy as np

from alight.airframe import DEFAULT_AIRFRAME
from alight.mission.presets import build_preset
from alight.scenario import scenario_from_dict


def test_the_falanga_detector_gets_the_range_finder_reading_before_each_image() -> None:
    s = scenario_from_dict({"preset": "falanga2017", "seed": 1, "platform": {"path": "straight"}})
    pipeline = build_preset(s, DEFAULT_AIRFRAME, np.random.default_rng(0)).pipeline
    detector = pipeline.detector
    assert detector is not None
    pipeline.ego_estimator.initialize(0.0, np.array([0.0, 0.0, 12.0]), np.zeros(3), np.array([0, 0, 0, 1.0]))
    blank = np.full((480, 752), 90, np.uint8)
    for r in (12.0, 12.0, 12.0):
        pipeline.on_range(0.0, r)
    pipeline.on_image(0.0, blank)
    assert detector._range_m == 12.0  # the close-range stage is skipped up there
    pipeline.on_range(0.01, None)  # an invalid reading: no range, the stage runs again
    pipeline.on_image(0.01, blank)
    assert detector._range_m is None
