"""Pad geometry and textures: the texture shows what the geometry says, in the documented convention."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from alight.blockspec import NoContext
from alight.pads import APRILTAG_DICTIONARY, PADS, AprilTagPad, FalangaTag, PadDesign


def _to_px(H: np.ndarray, pts_P: np.ndarray) -> np.ndarray:
    q = np.c_[pts_P[:, :2], np.ones(len(pts_P))] @ H.T
    return q[:, :2] / q[:, 2:]


def _distance_to_polygon_edges(p: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distance of points (N, 2) to the closed polygon's boundary."""
    a = poly[None, :, :]
    b = np.roll(poly, -1, axis=0)[None, :, :]
    ab = b - a
    t = np.clip(np.sum((p[:, None, :] - a) * ab, axis=2) / np.sum(ab * ab, axis=2), 0.0, 1.0)
    closest = a + t[:, :, None] * ab
    return np.min(np.linalg.norm(p[:, None, :] - closest, axis=2), axis=1)


def _signed_area(xy: np.ndarray) -> float:
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


@pytest.mark.parametrize("name", sorted(PADS))
@pytest.mark.parametrize("px_per_m", [37.3, 100.0, 211.7])
def test_registry_contract(name: str, px_per_m: float) -> None:
    pad = PADS[name].build_default(NoContext())
    assert isinstance(pad, PadDesign)
    tex = pad.texture(px_per_m)
    n = round(pad.size_m * px_per_m)
    assert tex.shape[:2] == (n, n) and tex.ndim in (2, 3) and tex.dtype == np.uint8
    H = pad.texture_homography_P_to_px(px_per_m)
    h = pad.size_m / 2
    # the square's corners land on the outer edges of the corner pixels (pixel centres at integers)
    corners = _to_px(H, np.array([[h, h, 0], [-h, h, 0], [-h, -h, 0], [h, -h, 0]]))
    np.testing.assert_allclose(corners, [[-0.5, -0.5], [-0.5, n - 0.5], [n - 0.5, n - 0.5], [n - 0.5, -0.5]])
    # +x is up (row decreases), +y is left (column decreases)
    c, fx, ly = _to_px(H, np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0]]))
    assert fx[1] < c[1] and fx[0] == pytest.approx(c[0])
    assert ly[0] < c[0] and ly[1] == pytest.approx(c[1])


def test_falanga_default_scales_with_size() -> None:
    a, b = FalangaTag.default(1.5), FalangaTag.default(3.0)
    assert a == FalangaTag()
    for f in ("ring_outer_radius_m", "ring_width_m", "cross_arm_half_length_m", "cross_bar_width_m"):
        assert getattr(b, f) == pytest.approx(2 * getattr(a, f))
    assert a.ring_outer_radius_m == pytest.approx(0.63) and a.cross_bar_width_m == pytest.approx(0.15)


def test_falanga_point_sets_geometry() -> None:
    tag = FalangaTag.default(1.5)
    out, inn = tag.circle_points_P(17), tag.circle_inner_points_P(17)
    np.testing.assert_allclose(np.hypot(out[:, 0], out[:, 1]), 0.63)
    np.testing.assert_allclose(np.hypot(inn[:, 0], inn[:, 1]), 0.63 - 0.105)
    for pts in (tag.quad_corners_P(), tag.cross_inner_corners_P(), tag.cross_outer_corners_P(), out):
        assert np.all(pts[:, 2] == 0)
        assert _signed_area(pts[:, :2]) > 0  # counter-clockwise seen from above
    np.testing.assert_allclose(tag.quad_corners_P()[0], [0.75, 0.75, 0])
    np.testing.assert_allclose(tag.cross_inner_corners_P()[0], [0.075, 0.075, 0])
    ang = np.mod(np.arctan2(tag.cross_outer_corners_P()[:, 1], tag.cross_outer_corners_P()[:, 0]), 2 * np.pi)
    assert np.all(np.diff(ang) > 0)
    outline = tag.cross_outline_P()[:, :2]
    # the 12-gon's area is the union of the two bars
    L, w = 0.42, 0.15
    assert _signed_area(outline) == pytest.approx(2 * (2 * L * w) - w * w)


def test_falanga_texture_matches_geometry() -> None:
    """Every pixel farther than one pixel from an edge is exactly black or white as the geometry says."""
    tag = FalangaTag.default(1.5)
    s = 120.0
    tex = tag.texture(s)
    n = tex.shape[0]
    v, u = np.mgrid[0:n, 0:n].astype(float)
    Hinv = np.linalg.inv(tag.texture_homography_P_to_px(s))
    q = np.stack([u.ravel(), v.ravel(), np.ones(n * n)]).T @ Hinv.T
    x, y = q[:, 0] / q[:, 2], q[:, 1] / q[:, 2]
    r = np.hypot(x, y)
    in_ring = (r <= tag.ring_outer_radius_m) & (r >= tag.ring_inner_radius_m)
    L, h = tag.cross_arm_half_length_m, tag.cross_bar_width_m / 2
    in_cross = ((np.abs(x) <= L) & (np.abs(y) <= h)) | ((np.abs(x) <= h) & (np.abs(y) <= L))
    black = in_ring | in_cross
    # distance to the nearest edge, in pixels
    d_ring = np.minimum(np.abs(r - tag.ring_outer_radius_m), np.abs(r - tag.ring_inner_radius_m))
    d_cross = _distance_to_polygon_edges(np.stack([x, y], axis=1), tag.cross_outline_P()[:, :2])
    far = np.minimum(d_ring, d_cross) * s > 1.0
    t = tex.ravel()
    assert np.all(t[far & black] == 0)
    assert np.all(t[far & ~black] == 255)
    assert far.mean() > 0.8
    # anti-aliasing: the black area (coverage) matches the exact area to within a fraction of a percent
    area_px = float(np.sum(255 - tex.astype(float)) / 255.0) / s**2
    ro, ri = tag.ring_outer_radius_m, tag.ring_inner_radius_m
    exact = np.pi * (ro**2 - ri**2) + 2 * (2 * L * 2 * h) - (2 * h) ** 2
    assert area_px == pytest.approx(exact, rel=2e-3)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"size_m": -1.0},
        {"ring_outer_radius_m": 0.9},  # outside the square
        {"ring_width_m": 0.7},
        {"cross_arm_half_length_m": 0.6},  # crosses the ring
        {"cross_bar_width_m": float("nan")},
    ],
)
def test_falanga_rejects_bad_geometry(kwargs: dict) -> None:
    with pytest.raises(ValueError):
        FalangaTag(**kwargs)


def test_texture_rejects_bad_resolution() -> None:
    with pytest.raises(ValueError):
        FalangaTag().texture(0.0)
    with pytest.raises(ValueError):
        AprilTagPad().texture(0.5)  # a 1-pixel texture
    with pytest.raises(ValueError):
        AprilTagPad().texture_homography_P_to_px(float("inf"))


@pytest.mark.parametrize("px_per_m", [160.0, 203.3, 317.9])
def test_apriltag_texture_read_back_by_opencv(px_per_m: float) -> None:
    pad = AprilTagPad.default(1.5)
    tex = pad.texture(px_per_m)
    border = 20
    img = cv2.copyMakeBorder(tex, border, border, border, border, cv2.BORDER_CONSTANT, value=255)
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    det = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(APRILTAG_DICTIONARY), params)
    corners, ids, _ = det.detectMarkers(img)
    assert ids is not None and sorted(ids.ravel().tolist()) == sorted(pad.marker_ids)
    H = pad.texture_homography_P_to_px(px_per_m)
    for c, i in zip(corners, ids.ravel(), strict=True):
        expected = _to_px(H, pad.marker_corners_P(int(i))) + border
        np.testing.assert_allclose(c[0], expected, atol=0.25)


def test_apriltag_corner_order_and_layout() -> None:
    pad = AprilTagPad()
    c = pad.marker_corners_P(pad.center_id)
    np.testing.assert_allclose(c[:, :2], [[0.4, 0.4], [0.4, -0.4], [-0.4, -0.4], [-0.4, 0.4]])
    assert _signed_area(c[:, :2]) < 0  # clockwise seen from above = clockwise in the texture
    for k, (sx, sy) in enumerate([(1, 1), (-1, 1), (-1, -1), (1, -1)]):
        centre = pad.marker_corners_P(pad.corner_ids[k]).mean(axis=0)
        np.testing.assert_allclose(centre, [0.6 * sx, 0.6 * sy, 0.0])
    with pytest.raises(ValueError):
        pad.marker_corners_P(99)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"corner_ids": (1, 2, 3, 0)},  # duplicate of the central id
        {"center_id": 10_000},
        {"center_size_m": 1.3},
        {"corner_offset_m": 0.5},  # corner tags inside the central tag's quiet zone
        {"corner_offset_m": 0.7},  # quiet zone outside the pad
    ],
)
def test_apriltag_rejects_bad_layout(kwargs: dict) -> None:
    with pytest.raises(ValueError):
        AprilTagPad(**kwargs)
