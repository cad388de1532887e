"""The Detector contract, run over every registered image detector (``alight.perception.DETECTORS``;
STYLE: one contract test per registry)."""

from __future__ import annotations

import numpy as np
import pytest
from perception_scenes import random_scenes

from alight.pads import AprilTagPad, FalangaTag
from alight.perception import Detector
from alight.perception.detect_cli import detector_names, make_detector

BLANKS = [
    np.zeros((480, 752), np.uint8),
    np.full((480, 752), 255, np.uint8),
    np.full((480, 752, 3), 90, np.uint8),
    np.zeros((1, 1), np.uint8),
    np.zeros((0, 0), np.uint8),
]


@pytest.fixture(scope="module", params=sorted(detector_names()))
def detector(request: pytest.FixtureRequest) -> Detector:
    """Every image detector of the registry, at its block defaults on its pad's default layout."""
    return make_detector(request.param)


def test_satisfies_the_protocol(detector: Detector) -> None:
    assert isinstance(detector, Detector)


@pytest.mark.parametrize("k", range(len(BLANKS)))
def test_nothing_on_blank_images(detector: Detector, k: int) -> None:
    assert detector.detect(BLANKS[k], 0.0) == []


def test_nothing_on_noise(detector: Detector) -> None:
    rng = np.random.default_rng(0)
    assert detector.detect(rng.integers(0, 256, (480, 752), dtype=np.uint8), 0.0) == []


@pytest.mark.parametrize("pad", [FalangaTag.default(), AprilTagPad.default()], ids=["falanga", "apriltag"])
def test_outputs_are_well_formed_and_pure(detector: Detector, pad: object) -> None:
    for sc in random_scenes(pad, np.random.default_rng(3), 2, z_range=(2.5, 5.0)):
        obs = detector.detect(sc.image, 3.5)
        again = detector.detect(sc.image, 3.5)
        assert len(obs) == len(again)
        for o, o2 in zip(obs, again, strict=True):
            assert o.t == 3.5 and 0.0 <= o.quality <= 1.0
            assert o.pixels.ndim == 2 and o.pixels.shape[1] == 2 and np.isfinite(o.pixels).all()
            assert (
                (o.pixels >= -0.5).all()
                and (o.pixels[:, 0] <= 751.5).all()
                and (o.pixels[:, 1] <= 479.5).all()
            )
            if o.points_P is not None:
                assert o.points_P.shape == (o.pixels.shape[0], 3) and np.allclose(o.points_P[:, 2], 0.0)
            assert np.array_equal(o.pixels, o2.pixels) and o.kind == o2.kind
