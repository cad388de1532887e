"""The shared homography routines: exact on exact correspondences (4-point and least-squares normalised
DLT), RANSAC through outliers, and the point map."""

from __future__ import annotations

import math

import numpy as np

from alight.numerics.homography import (
    apply_homography,
    homography_4pt,
    homography_lsq,
    map_point,
    ransac_homography,
)


def test_least_squares_and_4_point_homographies_are_exact_on_exact_data() -> None:
    rng = np.random.default_rng(8)
    H = np.array([[50.0, 5.0, 100.0], [-3.0, 60.0, 90.0], [0.01, 0.02, 1.0]])
    src = rng.uniform(-1, 1, (12, 2))
    ok, H_est = homography_lsq(src, apply_homography(H, src), np.ones(12, bool))
    assert ok and np.allclose(H_est, H, rtol=1e-8, atol=1e-9)
    ok4, H4 = homography_4pt(src, apply_homography(H, src), 0, 1, 2, 3)
    assert ok4 and np.allclose(H4, H, rtol=1e-8, atol=1e-9)


def test_least_squares_homography_on_the_close_range_scale() -> None:
    # the close-range cross: pad metres to image pixels, 4 and 9 corners (the fewest and the most used)
    rng = np.random.default_rng(1)
    H = np.array([[300.0, 12.0, 370.0], [-9.0, 310.0, 240.0], [0.1, -0.05, 1.0]])
    src = rng.uniform(-0.4, 0.4, (9, 2))
    q = src @ H[:2, :2].T + H[:2, 2]
    dst = q / (src @ H[2, :2] + H[2, 2])[:, None]  # the map written out, not through apply_homography
    for k in (4, 9):
        ok, H_est = homography_lsq(src[:k], dst[:k], np.ones(k, bool))
        assert ok and np.allclose(H_est, H, rtol=1e-7, atol=1e-7)


def test_least_squares_homography_uses_only_the_masked_pairs_and_needs_four() -> None:
    rng = np.random.default_rng(2)
    H = np.array([[40.0, 2.0, 10.0], [1.0, 45.0, -20.0], [0.005, 0.01, 1.0]])
    src = rng.uniform(-1, 1, (10, 2))
    dst = apply_homography(H, src)
    dst[7:] += 50.0  # garbage, masked out
    mask = np.arange(10) < 7
    ok, H_est = homography_lsq(src, dst, mask)
    assert ok and np.allclose(H_est, H, rtol=1e-8, atol=1e-9)
    mask[3:] = False
    ok, H_est = homography_lsq(src, dst, mask)
    assert not ok and np.array_equal(H_est, np.eye(3))
    # collinear points determine no homography
    line = np.stack([np.linspace(0, 1, 6), np.linspace(0, 2, 6)], axis=1)
    assert not homography_lsq(line, line, np.ones(6, bool))[0]


def test_ransac_homography_with_outliers() -> None:
    rng = np.random.default_rng(7)
    H = np.array([[80.0, -12.0, 300.0], [9.0, 75.0, 220.0], [0.02, -0.03, 1.0]])
    src = rng.uniform(-0.7, 0.7, (60, 2))
    dst = apply_homography(H, src) + rng.normal(0.0, 0.2, (60, 2))
    bad = rng.choice(60, 18, replace=False)
    dst[bad] += rng.uniform(5.0, 40.0, (18, 2)) * rng.choice([-1, 1], (18, 2))
    ok, H_est, mask = ransac_homography(src, dst, 1.5, 500)
    assert ok
    assert not mask[bad].any() and mask.sum() >= 40
    test = rng.uniform(-0.7, 0.7, (20, 2))
    assert np.abs(apply_homography(H_est, test) - apply_homography(H, test)).max() < 0.3
    # exact inliers and 30 % outliers: the inliers exactly, H to rounding
    dst = apply_homography(H, src)
    dst[bad] += 30.0
    ok, H_est, mask = ransac_homography(src, dst, 1e-6, 500)
    assert ok and np.array_equal(mask, ~np.isin(np.arange(60), bad))
    assert np.allclose(H_est, H, rtol=1e-8, atol=1e-9)
    # fewer than 4 pairs: nothing
    assert not ransac_homography(src[:3], dst[:3], 1.5, 100)[0]


def test_point_map_matches_the_array_map_and_the_line_at_infinity() -> None:
    H = np.array([[2.0, 0.0, 1.0], [0.0, 3.0, -1.0], [1.0, 0.0, 1.0]])
    xy = np.array([[0.5, 2.0], [3.0, -1.0]])
    for k in range(2):
        assert map_point(H, xy[k, 0], xy[k, 1]) == tuple(apply_homography(H, xy[k : k + 1])[0])
    assert map_point(H, 0.5, 2.0) == ((2.0 * 0.5 + 1.0) / 1.5, (3.0 * 2.0 - 1.0) / 1.5)
    u, v = map_point(H, -1.0, 5.0)  # w = x + 1 = 0: the line at infinity
    assert math.isnan(u) and math.isnan(v)
    assert np.isnan(apply_homography(H, np.array([[-1.0, 5.0]]))).all()
