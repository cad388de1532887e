"""The Pipeline's detector hooks: what it passes to a detector before each image."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from alight.airframe import DEFAULT_AIRFRAME
from alight.estimation.sdu_kf import SduKalmanFilter
from alight.mission.pipeline import BLOCKS
from alight.mission.presets import PRESETS, build_preset
from alight.scenario import scenario_from_dict
from alight.types import PlatformMeasurement


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


class _SlowDetector:
    """Finds nothing, after 20 ms."""

    def detect(self, image: object, t: float) -> list:
        time.sleep(0.02)
        return []


def test_the_detectors_time_is_charged_to_the_detector() -> None:
    s = scenario_from_dict({"preset": "falanga2017", "seed": 1, "platform": {"path": "straight"}})
    pipeline = build_preset(s, DEFAULT_AIRFRAME, np.random.default_rng(0)).pipeline
    pipeline.detector = _SlowDetector()  # type: ignore[assignment]
    pipeline.ego_estimator.initialize(0.0, np.array([0.0, 0.0, 12.0]), np.zeros(3), np.array([0, 0, 0, 1.0]))
    before = dict(pipeline.stats.block_time_s)
    for k in range(3):
        pipeline.on_image(0.05 * k, np.zeros((480, 752), np.uint8))
    spent = {b: pipeline.stats.block_time_s[b] - before[b] for b in BLOCKS}
    assert spent["detector"] >= 0.06
    assert all(spent[b] == 0.0 for b in BLOCKS if b != "detector"), spent  # nothing else ran
    detector_s = pipeline.stats.block_time_s["detector"]
    pipeline.step(0.2)  # the mission starts the take-off, the guidance plans it
    pipeline.command(0.2)  # the controller flies it
    after = pipeline.stats.block_time_s
    assert after["mission"] > 0 and after["guidance"] > 0 and after["controller"] > 0
    assert after["ego_estimator"] > 0
    assert after["detector"] == detector_s


def _fly_a_jump(announced: bool) -> list[float]:
    """2 s of hover at 100 Hz in the pipeline; the odometry jumps 0.5 m along x after 1 s, its reset
    counter going up when ``announced``. Returns the distance of the pipeline's ego position from the
    true one at each step."""
    s = scenario_from_dict({"preset": "groundtruth", "seed": 1, "platform": {"path": "straight"}})
    pipeline = build_preset(s, DEFAULT_AIRFRAME, np.random.default_rng(0)).pipeline
    q = np.array([0.0, 0.0, 0.0, 1.0])
    p0 = np.array([1.0, 2.0, 5.0])
    f_hover, w0 = np.array([0.0, 0.0, 9.81]), np.zeros(3)
    pipeline.on_odometry(0.0, p0, q, np.zeros(3), 0)
    errors = []
    for k in range(1, 201):
        t = 0.01 * k
        jumped = t > 1.0
        pipeline.on_imu(t, f_hover, w0)
        p = p0 + (np.array([0.5, 0.0, 0.0]) if jumped else 0.0)
        pipeline.on_odometry(t, p, q, np.zeros(3), int(jumped and announced))
        errors.append(float(np.linalg.norm(pipeline.ego().p_WB - p0)))
    return errors


def test_an_announced_odometry_jump_does_not_move_the_pipelines_frame() -> None:
    """The odometry says its frame jumped (reset_counter up, a VIO re-localising 0.5 m away): the ego
    estimator restarts at the new pose and the pipeline hands on one continuous frame, the one the
    platform estimate, the plan and the pose history were made in."""
    assert max(_fly_a_jump(announced=True)) < 0.05


def test_an_unannounced_odometry_jump_is_gated_then_followed() -> None:
    """Without the counter the jump is an outlier to the ego estimator's gate for 10 messages, then the
    estimate follows it (its own drift corrected, as far as it can tell): the frame moves 0.5 m."""
    errors = _fly_a_jump(announced=False)
    assert max(errors[:100]) < 0.05 and max(errors[100:108]) < 0.05  # gated
    assert abs(errors[-1] - 0.5) < 0.05  # followed


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_the_pipeline_gives_the_platform_estimator_its_clock(preset: str) -> None:
    """A measurement stamped 1,000 s after the pipeline's clock is refused, and the real ones after it
    are still fused: the step sets the estimator's clock (without one, the future stamp would be taken
    and every real measurement after it refused as out of order)."""
    s = scenario_from_dict({"preset": preset, "seed": 1, "platform": {"path": "straight"}})
    pipeline = build_preset(s, DEFAULT_AIRFRAME, np.random.default_rng(0)).pipeline
    pipeline.ego_estimator.initialize(0.0, np.array([0.0, 0.0, 5.0]), np.zeros(3), np.array([0, 0, 0, 1.0]))
    est = pipeline.platform_estimator
    cov = np.eye(3) * 0.01

    def measured(t: float, x: float) -> PlatformMeasurement:
        return PlatformMeasurement(t=t, p_WP=np.array([x, 0.0, 0.5]), cov_p_WP=cov)

    if isinstance(est, SduKalmanFilter):
        est.set_ego(pipeline.ego())  # the SDU filter predicts with the UAV's motion (the pipeline feeds it)
    pipeline.step(1.0)
    assert est.update(measured(1.0, 2.0))
    pipeline.step(1.1)
    assert not est.update(measured(1001.0, 900.0))  # from the future
    pipeline.step(1.2)
    assert est.update(measured(1.2, 2.0))
    p = est.state(1.2).p_WP
    assert np.all(np.isfinite(p)) and abs(p[0] - 2.0) < 0.5, p


def test_one_spurious_long_return_does_not_reach_the_ground_check() -> None:
    """The mission's committed-descent ground check reads the smallest of the last three valid ranges:
    a single spurious return of 9 m over a deck 0.4 m below does not look like the ground beside it;
    three in a row do. (The detector keeps the largest, robust to one low reading.)"""
    s = scenario_from_dict({"preset": "groundtruth", "seed": 1, "platform": {"path": "straight"}})
    pipeline = build_preset(s, DEFAULT_AIRFRAME, np.random.default_rng(0)).pipeline
    for k, r in enumerate((0.4, 0.4, 0.4, 9.0)):
        pipeline.on_range(0.01 * k, r)
    assert pipeline.range_low_m == 0.4 and pipeline.range_m == 9.0
    for k in range(2):
        pipeline.on_range(0.05 + 0.01 * k, 9.0)
    assert pipeline.range_low_m == 9.0
    pipeline.on_range(0.08, math.inf)  # invalid: no range at all
    assert pipeline.range_low_m is None and pipeline.range_m is None
