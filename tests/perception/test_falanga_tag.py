"""The Falanga tag detector (paper 000 Alg. 1) on rendered frames, odd inputs and its numba kernels."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from perception_scenes import random_scenes, render_scene, tilt

from alight.cameras import PinholeCamera
from alight.pads import AprilTagPad, FalangaTag
from alight.perception import falanga_tag as ft
from alight.perception.falanga_tag import STAGES, FalangaDetectorConfig, FalangaTagDetector
from alight.perception.pnp import solve_pnp
from alight.sim.render import RenderOptions

TAG = FalangaTag.default()
CAM = PinholeCamera.default_downward()


@pytest.fixture(scope="module")
def det() -> FalangaTagDetector:
    return FalangaTagDetector(TAG)


def rel_pose_error(obs, sc) -> float:  # type: ignore[no-untyped-def]
    res = solve_pnp(obs.pixels, obs.points_P, CAM)
    assert res is not None
    return float(np.linalg.norm(res.p_CP - sc.p_CP) / np.linalg.norm(sc.p_CP))


# ------------------------------------------------------------------------------------------ detection


@pytest.mark.parametrize("ground", ["grass", "asphalt", "concrete"])
def test_circle_found_and_pose_accurate_on_rendered_frames(det: FalangaTagDetector, ground: str) -> None:
    """2-14 m, up to 0.3 rad of tilt, any heading, pad fully in view, lens distortion: the ring is found in
    every frame and PnP on its points is within 1 % of the range (median well under 0.2 %)."""
    scenes = random_scenes(TAG, np.random.default_rng(11), 12, ground=ground)
    errors = []
    for sc in scenes:
        obs = det.detect(sc.image, 1.25)
        assert len(obs) == 1
        o = obs[0]
        assert o.kind == "circle" and o.t == 1.25 and 0.8 <= o.quality <= 1.0
        assert o.points_P is not None and o.pixels.shape == (o.points_P.shape[0], 2)
        # the points are on the ring's edges, z = 0
        r = np.hypot(o.points_P[:, 0], o.points_P[:, 1])
        assert np.allclose(o.points_P[:, 2], 0.0)
        assert np.all(np.isclose(r, TAG.ring_outer_radius_m) | np.isclose(r, TAG.ring_inner_radius_m))
        errors.append(rel_pose_error(o, sc))
    assert max(errors) < 0.01
    assert float(np.median(errors)) < 0.002


@pytest.mark.parametrize(
    "options",
    [
        RenderOptions(exposure_gain=0.5, gamma=1.3, vignetting=0.4, pad_px_per_m=300.0),
        RenderOptions(exposure_gain=1.6, pad_px_per_m=300.0),
        # the whole deck in a shadow (pad darker than in the sun, ground unchanged)
        RenderOptions(
            shadow_gain=0.65,
            shadow_polygon_P=((-1.2, -1.0), (1.2, -1.0), (1.2, 1.0), (-1.2, 1.0)),
            pad_px_per_m=300.0,
        ),
        # a shadow inside the pad (the vehicle's own, over the cross and part of the ring)
        RenderOptions(
            shadow_polygon_P=((-0.3, -0.3), (0.3, -0.4), (0.35, 0.2), (-0.2, 0.3)), pad_px_per_m=300.0
        ),
    ],
    ids=["dark_gamma_vignette", "overexposed", "deck_in_shadow", "shadow_inside_pad"],
)
def test_robust_to_exposure_and_shadows(det: FalangaTagDetector, options: RenderOptions) -> None:
    scenes = random_scenes(
        TAG, np.random.default_rng(3), 10, z_range=(2.0, 10.0), ground="grass", options=options
    )
    found = [det.detect(sc.image, 0.0) for sc in scenes]
    assert sum(bool(o) for o in found) >= 9
    for o, sc in zip(found, scenes, strict=True):
        if o:
            assert rel_pose_error(o[0], sc) < 0.02


def test_occluded_ring_falls_back_to_the_cross(det: FalangaTagDetector) -> None:
    """Alg. 1 line 10: with half of the ring hidden the cross's corners are used."""
    scenes = random_scenes(TAG, np.random.default_rng(5), 6, z_range=(2.5, 5.0), ground="asphalt")
    kinds = []
    for sc in scenes:
        img = sc.image.copy()
        # cover the ring from angle -100 to +100 deg (pad frame) with deck grey, leaving the cross
        a = np.linspace(-1.75, 1.75, 40)
        outer = np.stack([0.72 * np.cos(a), 0.72 * np.sin(a), 0 * a], axis=1)
        inner = np.stack([0.48 * np.cos(a[::-1]), 0.48 * np.sin(a[::-1]), 0 * a], axis=1)
        poly = CAM.project((sc.R_CP @ np.concatenate([outer, inner]).T).T + sc.p_CP)
        cv2.fillPoly(img, [np.round(poly).astype(np.int32)], 200)
        obs = det.detect(img, 0.0)
        assert obs, "the quad and the cross are still in view"
        kinds.append(obs[0].kind)
        if obs[0].kind == "cross":
            assert obs[0].points_P is not None and obs[0].points_P.shape[0] >= 8
            assert rel_pose_error(obs[0], sc) < 0.03
    assert kinds.count("cross") >= 5


def test_quad_only_when_inner_features_are_not_searched() -> None:
    """Alg. 1 line 13: with the ring and the cross below the resolvable size the quad's corners are used."""
    det = FalangaTagDetector(TAG, FalangaDetectorConfig(min_feature_px=1000.0))
    for sc in random_scenes(TAG, np.random.default_rng(8), 5, z_range=(3.0, 8.0)):
        obs = det.detect(sc.image, 0.0)
        assert len(obs) == 1 and obs[0].kind == "quad"
        assert obs[0].pixels.shape == (4, 2)
        assert np.array_equal(obs[0].points_P, TAG.quad_corners_P())
        assert rel_pose_error(obs[0], sc) < 0.03


def test_quad_corners_are_labelled_for_a_camera_with_the_image_top_forward() -> None:
    """The tag is 4-fold symmetric; the corner labelled (+x, +y) is the one nearest the image's top-left,
    which is the true (+x, +y) corner when the image top points to the pad's front."""
    det = FalangaTagDetector(TAG, FalangaDetectorConfig(min_feature_px=1000.0))
    sc = render_scene(TAG, np.array([0.1, -0.2, 5.5]), tilt(0.02, -0.03, 0.1), np.array([0.0, 0.0, 0.5]), 0.0)
    obs = det.detect(sc.image, 0.0)
    truth = CAM.project((sc.R_CP @ TAG.quad_corners_P().T).T + sc.p_CP)
    assert np.abs(obs[0].pixels - truth).max() < 1.0


def test_detection_is_deterministic(det: FalangaTagDetector) -> None:
    sc = random_scenes(TAG, np.random.default_rng(1), 1)[0]
    a, b = det.detect(sc.image, 0.0), det.detect(sc.image.copy(), 0.0)
    assert np.array_equal(a[0].pixels, b[0].pixels) and a[0].quality == b[0].quality


def test_bgr_and_grey_give_the_same_detection(det: FalangaTagDetector) -> None:
    sc = random_scenes(TAG, np.random.default_rng(2), 1)[0]
    bgr = cv2.cvtColor(sc.image, cv2.COLOR_GRAY2BGR)
    a, b = det.detect(sc.image, 0.0), det.detect(bgr, 0.0)
    assert np.allclose(a[0].pixels, b[0].pixels)


def test_detect_timed_stage_table(det: FalangaTagDetector) -> None:
    sc = random_scenes(TAG, np.random.default_rng(4), 1)[0]
    obs, times = det.detect_timed(sc.image, 0.0)
    assert obs and set(times) == {*STAGES, "total"}
    assert all(v >= 0.0 for v in times.values())
    assert sum(times[k] for k in STAGES) <= times["total"] + 1e-6


# ------------------------------------------------------------------------------------------ no tag


def test_no_detection_on_ground_only_frames(det: FalangaTagDetector) -> None:
    """The camera looks at the ground far from the platform."""
    for ground in ("grass", "asphalt", "concrete"):
        for k in range(3):
            sc = render_scene(
                TAG,
                np.array([30.0 + 7 * k, -20.0, 3.0 + 4 * k]),
                tilt(0.1, -0.1, k),
                np.array([0.0, 0.0, 0.5]),
                0.0,
                ground=ground,
            )
            assert det.detect(sc.image, 0.0) == []


def test_no_detection_on_the_apriltag_pad(det: FalangaTagDetector) -> None:
    """A white square with a black pattern that is not the tag's (the pattern check rejects it)."""
    pad = AprilTagPad.default()
    for sc in random_scenes(pad, np.random.default_rng(6), 8, z_range=(2.0, 10.0)):
        assert det.detect(sc.image, 0.0) == []


def test_no_detection_on_a_plain_white_square(det: FalangaTagDetector) -> None:
    img = np.full((480, 752), 70, np.uint8)
    cv2.fillConvexPoly(img, np.array([[300, 150], [460, 170], [440, 330], [290, 310]], np.int32), 240)
    assert det.detect(img, 0.0) == []


@pytest.mark.parametrize("seed", range(3))
def test_no_detection_on_noise(det: FalangaTagDetector, seed: int) -> None:
    rng = np.random.default_rng(seed)
    assert det.detect(rng.integers(0, 256, (480, 752), dtype=np.uint8), 0.0) == []
    blobs = cv2.resize(
        rng.integers(0, 256, (30, 47), dtype=np.uint8), (752, 480), interpolation=cv2.INTER_NEAREST
    )
    assert det.detect(blobs, 0.0) == []


@pytest.mark.parametrize(
    "image",
    [
        np.zeros((0, 0), np.uint8),
        np.zeros((0, 10), np.uint8),
        np.zeros((1, 1), np.uint8),
        np.zeros((15, 15), np.uint8),
        np.zeros((1, 1000), np.uint8),
        np.zeros((480, 752), np.uint8),
        np.full((480, 752), 255, np.uint8),
        np.full((480, 752), 128, np.uint8),
        np.zeros((480, 752, 3), np.uint8),
        np.full((64, 64, 4), 255, np.uint8),
        np.zeros((64, 64, 1), np.uint8),
        np.zeros((64, 64, 2), np.uint8),
        np.zeros((4, 4, 4, 4), np.uint8),
        np.full((100, 100), np.nan),
        np.ones((100, 100), np.float32),
        np.ones((100, 100), bool),
        np.full((100, 100), 60000, np.uint16),
        np.zeros((480, 752), np.uint8)[::2, ::3],
        None,
        "not an image",
    ],
    ids=lambda a: f"{type(a).__name__}{getattr(a, 'shape', '')}{getattr(a, 'dtype', '')}",
)
def test_odd_inputs_give_nothing_and_never_raise(det: FalangaTagDetector, image: object) -> None:
    assert det.detect(image, 0.0) == []


def test_config_validation() -> None:
    with pytest.raises(ValueError, match="min_pattern_corr"):
        FalangaDetectorConfig(min_pattern_corr=2.0)
    with pytest.raises(ValueError, match="n_ring_rays"):
        FalangaDetectorConfig(n_ring_rays=2)


# ------------------------------------------------------------------------------------------ kernels


def test_run_labelling_matches_opencv_components() -> None:
    """The runs of ``_threshold_runs`` rebuild the thresholded image, and their 8-connected components
    are OpenCV's (same count, same bounding boxes)."""
    rng = np.random.default_rng(0)
    img = cv2.resize(
        rng.integers(0, 256, (60, 90), dtype=np.uint8), (181, 123), interpolation=cv2.INTER_LINEAR
    )
    n, row, x0, x1, root, bx0, bx1, by0, by1 = ft._threshold_runs(img, 3, 0.05, 4.0, False)
    binary = np.zeros(img.shape, np.uint8)
    for k in range(n):
        assert x0[k] <= x1[k]
        binary[row[k], x0[k] : x1[k] + 1] = 1
    assert binary.any() and not binary.all()
    n_cv, labels, stats, _ = cv2.connectedComponentsWithStats(binary, connectivity=8)
    roots = np.flatnonzero(root == np.arange(n))
    assert len(roots) == n_cv - 1
    ours = sorted(
        (int(bx0[r]), int(by0[r]), int(bx1[r] - bx0[r] + 1), int(by1[r] - by0[r] + 1)) for r in roots
    )
    theirs = sorted(tuple(int(v) for v in s[:4]) for s in stats[1:])
    assert ours == theirs


def test_threshold_is_local_mean_plus_offset() -> None:
    """On an image whose tiles are constant the threshold is exactly the clipped-window mean + offset."""
    rng = np.random.default_rng(1)
    tiles = rng.integers(20, 230, (10, 12))
    img = np.kron(tiles, np.ones((4, 4), np.int64)).astype(np.uint8)
    offset_min = 10.0
    n, row, x0, x1, *_ = ft._threshold_runs(img, 1, 0.0, offset_min, False)
    binary = np.zeros(img.shape, bool)
    for k in range(n):
        binary[row[k], x0[k] : x1[k] + 1] = True
    pad = np.pad(tiles.astype(float), 1, constant_values=np.nan)
    win = np.stack([pad[i : i + 10, j : j + 12] for i in range(3) for j in range(3)])
    mean = np.nanmean(win, axis=0)
    expected = np.kron(tiles > np.floor(mean + offset_min), np.ones((4, 4), bool))
    assert np.array_equal(binary, expected)


def test_quadness_and_solidity_separate_squares_from_discs() -> None:
    img = np.zeros((200, 300), np.uint8)
    cv2.fillConvexPoly(img, np.array([[40, 60], [110, 40], [130, 110], [60, 130]], np.int32), 255)
    cv2.circle(img, (220, 100), 40, 255, -1)
    n, row, x0, x1, root, bx0, bx1, by0, by1 = ft._threshold_runs(img, 4, 0.0, 1.0, False)
    roots = np.flatnonzero(root == np.arange(n)).astype(np.int32)
    sol, hull, quadness, corners = ft._solidity(row, x0, x1, root, roots, by0, by1)
    sq = int(np.argmin(bx0[roots]))
    disc = 1 - sq
    assert sol[sq] > 0.97 and sol[disc] > 0.97
    assert quadness[sq] > 0.95
    assert abs(quadness[disc] - 2 / math.pi) < 0.04
    # the inscribed quad of the square is its corners (to a pixel)
    true = np.array([[40, 60], [110, 40], [130, 110], [60, 130]], float)
    for c in true:
        assert np.min(np.hypot(*(corners[sq] - c).T)) < 1.5


def test_edge_search_is_subpixel() -> None:
    """A blurred step edge at a known sub-pixel position along a slanted line."""
    x_edge = 40.3
    xs = np.arange(100)
    prof = 200.0 - 150.0 / (1.0 + np.exp(-(xs - x_edge) / 0.6))  # bright to dark at x_edge
    img = np.tile(prof, (60, 1)).astype(np.float64)
    img8 = np.round(img).astype(np.uint8)
    d = np.array([math.cos(0.3), math.sin(0.3)])
    start = np.array([x_edge - 2.0 * d[0], 30.0 - 2.0 * d[1]])
    ok, ex, ey = ft._edge1(img8, start[0], start[1], d[0], d[1], 4.0, -1.0, 10.0)
    assert ok and abs(ex - x_edge) < 0.1
    ok, *_ = ft._edge1(img8, start[0], start[1], d[0], d[1], 4.0, 1.0, 10.0)
    assert not ok  # no edge of the other polarity
