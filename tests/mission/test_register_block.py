"""Adding a block from outside the package: one class and one registry entry, then a scenario names it and
it flies (the worked example of docs/architecture.md). Also: an unknown name is refused in one line."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import pytest

from alight.blockspec import BlockSpec
from alight.cameras import MountedCamera
from alight.errors import ConfigError
from alight.estimation import PlatformEkf, PlatformEkfConfig, PlatformEstimator
from alight.evaluation.runner import run_mission
from alight.mission.blocks import BLOCKS, register_block, unregister_block
from alight.perception import Detector, DetectorContext
from alight.perception.detect_cli import detector_names, make_detector
from alight.scenario import scenario_from_dict
from alight.types import Image, Observation, PlatformMeasurement

# -- a platform estimator: paper 000's EKF that counts the measurements it is given ----------------------


class CountingEkf(PlatformEkf):
    """The unicycle EKF, counting its updates (to show the flight used this block)."""

    updates = 0

    def update(self, measurement: PlatformMeasurement) -> bool:
        CountingEkf.updates += 1
        return super().update(measurement)


def _counting_ekf(p: PlatformEkfConfig, ctx: MountedCamera) -> PlatformEstimator:
    return CountingEkf(p)


COUNTING_EKF = BlockSpec(
    "platform_estimator",
    "counting_ekf",
    "the unicycle EKF, counting its updates (a test's block)",
    PlatformEkfConfig,
    build=_counting_ekf,
    defaults=BLOCKS["platform_estimator"]["unicycle_ekf"].defaults,  # what the unicycle EKF flies with
)


# -- a detector: the centroid of the red pixels ----------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class RedCentroidParams:
    """The centroid of the pixels whose red channel dominates."""

    red_over_others: float = 1.6
    """A pixel is red when R exceeds this multiple of G and of B."""
    min_pixels: int = 20
    """Fewer red pixels than this: nothing found."""


class RedCentroidDetector:
    """The centroid of the red pixels of a BGR image, as one observation (a deliberately small detector)."""

    calls = 0

    def __init__(self, params: RedCentroidParams) -> None:
        self.params = params

    def detect(self, image: Image, t: float) -> list[Observation]:
        RedCentroidDetector.calls += 1
        img = np.asarray(image)
        if img.ndim != 3 or img.shape[2] != 3 or img.size == 0:
            return []
        b, g, r = (img[..., k].astype(np.float64) for k in range(3))
        k = self.params.red_over_others
        v, u = np.nonzero((r > 60.0) & (r > k * g) & (r > k * b))
        if u.size < self.params.min_pixels:
            return []
        quality = min(1.0, u.size / 400.0)
        return [Observation(t=t, kind="blob", quality=quality, pixels=np.array([[u.mean(), v.mean()]]))]


def _red_centroid(p: RedCentroidParams, ctx: DetectorContext) -> Detector:
    return RedCentroidDetector(p)


RED_CENTROID = BlockSpec(
    "detector",
    "red_centroid",
    "the centroid of the red pixels (a test's block)",
    RedCentroidParams,
    build=_red_centroid,
    needs={"pad": ("red_target",), "camera.color": (True,)},
    provides={"observation": ("pixel",), "image": True},
)


@pytest.fixture
def registered() -> Iterator[None]:
    register_block(COUNTING_EKF)
    register_block(RED_CENTROID)
    try:
        yield
    finally:
        unregister_block("platform_estimator", "counting_ekf")
        unregister_block("detector", "red_centroid")


@pytest.mark.usefixtures("registered")
def test_a_platform_estimator_registered_from_outside_flies_and_lands() -> None:
    CountingEkf.updates = 0
    s = scenario_from_dict(
        {
            "preset": "groundtruth",
            "seed": 1,
            "platform": {"path": "straight", "speed_mps": 1.2},
            "blocks": {"platform_estimator": "counting_ekf"},
        }
    )
    r = run_mission(s, record=False).result
    assert r["outcome"] == "landed", (r["outcome_reason"], r["abort_reason"])
    assert CountingEkf.updates > 50  # the ground-truth sensor's sightings, through this block
    assert r["touchdown_error_m"] < 0.15


@pytest.mark.usefixtures("registered")
def test_a_detector_registered_from_outside_flies_and_alight_detect_runs_it() -> None:
    assert "red_centroid" in detector_names()
    assert isinstance(make_detector("red_centroid"), RedCentroidDetector)  # what ``alight detect`` runs
    RedCentroidDetector.calls = 0
    s = scenario_from_dict(
        {
            "preset": "kim_kaist",
            "seed": 1,
            "platform": {"path": "straight", "speed_mps": 1.5},
            "blocks": {"detector": {"name": "red_centroid", "min_pixels": 30}},
        }
    )
    r = run_mission(s, record=False).result
    assert RedCentroidDetector.calls > 100 and r["detections"] > 50
    assert r["outcome"] == "landed", (r["outcome_reason"], r["abort_reason"])


@pytest.mark.usefixtures("registered")
def test_a_registered_block_is_refused_where_it_does_not_fit() -> None:
    with pytest.raises(ConfigError, match=r"blocks.detector: detector 'red_centroid' needs pad red_target"):
        scenario_from_dict({"preset": "falanga2017", "blocks": {"detector": "red_centroid"}})
    with pytest.raises(ValueError, match="registered already"):
        register_block(RED_CENTROID)


def test_an_unknown_block_is_refused_in_one_line_naming_the_known_ones() -> None:
    with pytest.raises(ConfigError) as err:
        scenario_from_dict({"preset": "groundtruth", "blocks": {"platform_estimator": "counting_ekf"}})
    assert str(err.value) == (
        "scenario: blocks.platform_estimator: unknown platform_estimator 'counting_ekf', "
        "expected one of ['unicycle_ekf', 'deck_kf', 'kim_ukf', 'sdu_kf']"
    )
    with pytest.raises(ValueError, match="unknown stage 'lidar'"):
        register_block(BlockSpec("lidar", "x", "", RedCentroidParams, build=_red_centroid))
