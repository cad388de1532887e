"""OpenCV ArUco/AprilTag baseline: the AprilTag pad on rendered frames and the real photos."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from perception_scenes import random_scenes

from alight.cameras import PinholeCamera
from alight.pads import AprilTagPad
from alight.perception.aruco import ArucoPadDetector, dictionary_id, merge_observations
from alight.perception.falanga_tag import FalangaTagDetector
from alight.perception.pnp import solve_pnp

PAD = AprilTagPad.default()
CAM = PinholeCamera.default_downward()


def test_pad_markers_found_with_pad_points_and_a_good_pose() -> None:
    det = ArucoPadDetector(PAD, subpixel_corners=True)
    for sc in random_scenes(PAD, np.random.default_rng(2), 6, z_range=(2.0, 5.0)):
        obs = det.detect(sc.image, 0.5)
        ids = sorted(int(o.kind.split(":")[1]) for o in obs)
        assert ids == sorted(PAD.marker_ids)  # close enough for the small corner markers too
        for o in obs:
            assert o.t == 0.5 and 0.0 < o.quality <= 1.0
            mid = int(o.kind.split(":")[1])
            assert np.array_equal(o.points_P, PAD.marker_corners_P(mid))
            truth = CAM.project((sc.R_CP @ o.points_P.T).T + sc.p_CP)
            assert np.abs(o.pixels - truth).max() < 1.5  # OpenCV's corner order is the pad's
        merged = merge_observations(obs)
        assert merged is not None and merged.pixels.shape == (20, 2)
        res = solve_pnp(merged.pixels, merged.points_P, CAM)
        assert res is not None
        assert np.linalg.norm(res.p_CP - sc.p_CP) < 0.01 * np.linalg.norm(sc.p_CP)


def test_markers_not_on_the_pad_are_dropped(real_dir: Path) -> None:
    """The photos hold many id-0 tags; a pad whose ids do not include 0 sees none of them."""
    other = AprilTagPad(center_id=7, corner_ids=(8, 9, 10, 11))
    img = cv2.imread(str(real_dir / "apriltag_real_photos" / "33369213973_9d9bb4cc96_c.jpg"))
    assert ArucoPadDetector(other).detect(img, 0.0) == []
    assert len(ArucoPadDetector(None).detect(img, 0.0)) >= 12


# counts from MANIFEST.md (OpenCV 5.0, default parameters)
APRILTAG_COUNTS = {
    "apriltag_real_photos/33369213973_9d9bb4cc96_c.jpg": 13,
    "apriltag_real_photos/34085369442_304b6bafd9_c.jpg": 15,
    "apriltag_real_photos/34139872896_defdb2f8d9_c.jpg": 14,
    "fisheye_ocamcalib/img0.jpg": 2,
}


@pytest.mark.parametrize("name,count", sorted(APRILTAG_COUNTS.items()))
def test_generic_apriltag_counts_on_real_photos(real_dir: Path, name: str, count: int) -> None:
    img = cv2.imread(str(real_dir / name), cv2.IMREAD_COLOR)
    obs = ArucoPadDetector(None).detect(img, 0.0)
    assert len(obs) >= count
    assert all(o.points_P is None and o.pixels.shape == (4, 2) and o.kind.startswith("aruco:") for o in obs)
    if name.startswith("fisheye"):
        assert {o.kind for o in obs} >= {"aruco:1", "aruco:2"}


def test_generic_counts_match_the_reference_detections(real_dir: Path) -> None:
    """The .txt files beside the photos list reference detections; every one of the first photo's 12 has
    a detection within 5 px of its centroid (MANIFEST: 12/12 match, ~0.8 px apart)."""
    d = real_dir / "apriltag_real_photos"
    img = cv2.imread(str(d / "33369213973_9d9bb4cc96_c.jpg"))
    ours = np.array([o.pixels.mean(axis=0) for o in ArucoPadDetector(None).detect(img, 0.0)])
    ref = []
    for line in (d / "33369213973_9d9bb4cc96_c.txt").read_text().splitlines():
        nums = [float(v) for v in line.replace("(", " ").replace(")", " ").replace(",", " ").split()]
        ref.append(np.array(nums[1:9]).reshape(4, 2).mean(axis=0))
    dist = np.linalg.norm(np.array(ref)[:, None, :] - ours[None, :, :], axis=2).min(axis=1)
    assert len(ref) == 12 and dist.max() < 5.0 and np.median(dist) < 2.0


def test_other_dictionaries_by_name(real_dir: Path) -> None:
    img = cv2.imread(str(real_dir / "aruco_charuco_real_photos" / "singlemarkersoriginal.jpg"))
    obs = ArucoPadDetector(None, "DICT_6X6_250").detect(img, 0.0)
    assert {o.kind for o in obs} == {f"aruco:{i}" for i in (23, 40, 62, 98, 124, 203)}
    assert dictionary_id("APRILTAG_36h11") == cv2.aruco.DICT_APRILTAG_36h11
    with pytest.raises(ValueError, match="unknown marker dictionary"):
        dictionary_id("DICT_NOPE")


def test_falanga_detector_finds_nothing_on_any_real_photo(real_dir: Path) -> None:
    det = FalangaTagDetector()
    photos = sorted(p for p in real_dir.rglob("*") if p.suffix.lower() in (".jpg", ".png"))
    assert len(photos) >= 14
    for p in photos:
        img = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
        assert det.detect(img, 0.0) == [], p.name


@pytest.mark.parametrize("image", [np.zeros((0, 0), np.uint8), np.zeros((3, 3), np.uint8), None])
def test_odd_inputs(image: object) -> None:
    assert ArucoPadDetector(PAD).detect(image, 0.0) == []
    assert ArucoPadDetector(None).detect(image, 0.0) == []


def test_merge_needs_pad_points() -> None:
    assert merge_observations([]) is None
