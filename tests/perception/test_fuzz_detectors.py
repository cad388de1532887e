"""The detector fuzz harness in short (benchmarks/fuzz_detectors.py, issue 39; the long run of 1,800 images
per detector is in the branch's report): corrupt and adversarial images into every registered image
detector give no crash other than a documented refusal, no hang, no malformed observation and no
detection where there is no target, and the detectors still find their rendered pads and the real
photos' markers."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest
from perception_scenes import testdata_dir as real_data_dir

from alight.perception.detect_cli import detector_names

ROOT = Path(__file__).resolve().parents[2]


def _harness() -> ModuleType:
    spec = importlib.util.spec_from_file_location("fuzz_detectors", ROOT / "benchmarks" / "fuzz_detectors.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def harness() -> ModuleType:
    return _harness()


@pytest.fixture(scope="module")
def summary(harness: ModuleType) -> dict[str, Any]:
    # 75 images: every synthetic kind and every photo corruption once, then a few at random
    result: dict[str, Any] = harness.run(n=75, seed=1, limit_s=30.0, testdata=real_data_dir(), n_targets=3)
    return result


def test_every_detector_survives_the_short_fuzz(summary: dict[str, Any]) -> None:
    assert set(summary["detectors"]) == set(detector_names())
    for name, block in summary["detectors"].items():
        assert block["images"] == 75, name
        for k in ("crashes", "hangs", "malformed", "false_detections"):
            assert block[k] == 0, (name, k, block["examples"])


def test_real_targets_are_still_found(summary: dict[str, Any]) -> None:
    for name, block in summary["detectors"].items():
        assert block["targets"] >= 3 and block["targets_missed"] == 0, (name, block["examples"])
    if summary["photos"]:  # the AprilTag photos' markers (the test data beside the repo)
        assert summary["detectors"]["aruco"]["targets"] == 3 + 4


def test_every_kind_is_drawn_and_the_draw_is_seeded(harness: ModuleType) -> None:
    photos = harness.load_photos(real_data_dir())
    a = list(harness.images(70, 5, photos))
    b = list(harness.images(70, 5, photos))
    kinds = {k for k, _, _ in a}
    assert {k for k, _ in harness.synthetic_kinds(np.random.default_rng(0))} <= kinds
    if photos:
        assert {f"photo_{c}" for c in harness.PHOTO_CORRUPTIONS} <= kinds
    for (ka, pa, ia), (kb, pb, ib) in zip(a, b, strict=True):
        assert ka == kb and pa == pb
        assert type(ia) is type(ib)
        if isinstance(ia, np.ndarray) and ia.dtype != object:
            assert np.array_equal(ia, ib, equal_nan=ia.dtype.kind in "fc")


def test_a_detection_on_a_target_free_image_is_counted(
    harness: ModuleType, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The harness can fail: a detector that reports something on every image is caught."""

    class Always:
        def detect(self, image: Any, t: float) -> list[Any]:
            from alight.types import Observation

            return [Observation(t=t, kind="blob", quality=1.0, pixels=np.zeros((1, 2)))]

    monkeypatch.setattr(harness, "make_detector", lambda name: Always())
    block = harness.run_detector("red", 10, 0, 30.0, {}, 1)
    assert block["false_detections"] == 10 and block["targets_missed"] == 0
