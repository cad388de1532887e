"""PnP with covariance: exact recovery, the Jacobian against finite differences, and the covariance
against Monte Carlo (NEES)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.stats import chi2

from alight.cameras import PinholeCamera
from alight.pads import FalangaTag
from alight.perception.pnp import project_with_jacobian, solve_pnp

CAM = PinholeCamera.default_downward()  # with lens distortion
TAG = FalangaTag.default()


def pose(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A pad 3-8 m in front of the camera, facing it, tilted by up to ~0.4 rad."""
    rvec = np.array([np.pi, 0.0, 0.0]) + rng.uniform(-0.4, 0.4, 3)
    tvec = np.array([rng.uniform(-1, 1), rng.uniform(-0.7, 0.7), rng.uniform(3, 8)])
    return rvec, tvec


def model_points(n: int = 32) -> np.ndarray:
    return np.concatenate([TAG.circle_points_P(n), TAG.circle_inner_points_P(n)])


def test_exact_correspondences_give_the_exact_pose() -> None:
    rng = np.random.default_rng(0)
    for _ in range(10):
        rvec, tvec = pose(rng)
        pts = model_points()
        px, _ = project_with_jacobian(pts, rvec, tvec, CAM.K, CAM.dist)
        res = solve_pnp(px, pts, CAM)
        assert res is not None
        R_true, _ = cv2.Rodrigues(rvec)
        assert np.allclose(res.p_CP, tvec, atol=1e-6)
        assert np.allclose(res.R_CP, R_true, atol=1e-7)
        assert res.reprojection_rms_px < 1e-6
        assert np.allclose(res.R_CP.T @ res.R_CP, np.eye(3), atol=1e-12)


def _refine_both(px: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """The pose (rvec, tvec) that refining both IPPE solutions and keeping the better fit gives."""
    obj, img = pts.reshape(-1, 1, 3), px.reshape(-1, 1, 2)
    n, rvecs, tvecs, _ = cv2.solvePnPGeneric(obj, img, CAM.K, CAM.dist, flags=cv2.SOLVEPNP_IPPE)
    best = None
    for k in range(n):
        rv, tv = cv2.solvePnPRefineLM(obj, img, CAM.K, CAM.dist, rvecs[k].copy(), tvecs[k].copy())
        proj, _ = project_with_jacobian(pts, rv, tv, CAM.K, CAM.dist)
        rms = float(np.sqrt(np.mean(np.sum((proj - px) ** 2, axis=1))))
        if tv[2, 0] > 0 and (best is None or rms < best[0]):
            best = (rms, np.r_[rv.ravel(), tv.ravel()])
    assert best is not None
    return best[1]


def test_skipping_the_far_worse_ippe_solution_changes_no_pose() -> None:
    # solve_pnp refines only the IPPE solutions within 4x of the better one's error; on noisy views from
    # near (unambiguous) to far (both solutions close), the pose is the one refining both gives.
    rng = np.random.default_rng(7)
    for k in range(300):
        rvec, tvec = pose(rng)
        tvec = tvec * (0.3 + 3.0 * k / 300)  # 1 to 30 m: the ambiguity grows with range
        pts = model_points(16) if k % 2 else TAG.quad_corners_P()
        px, _ = project_with_jacobian(pts, rvec, tvec, CAM.K, CAM.dist)
        px = px + rng.normal(0.0, 0.5, px.shape)
        res = solve_pnp(px, pts, CAM)
        assert res is not None
        expected = _refine_both(px, pts)
        # to LM's own termination tolerance; the other IPPE solution is 0.05 rad or more away
        assert np.allclose(res.p_CP, expected[3:], atol=1e-5 * np.linalg.norm(expected[3:]))
        assert np.allclose(res.R_CP, cv2.Rodrigues(expected[:3])[0], atol=1e-5)


def test_four_quad_corners_suffice() -> None:
    rng = np.random.default_rng(1)
    rvec, tvec = pose(rng)
    pts = TAG.quad_corners_P()
    px, _ = project_with_jacobian(pts, rvec, tvec, CAM.K, CAM.dist)
    res = solve_pnp(px, pts, CAM)
    assert res is not None and np.allclose(res.p_CP, tvec, atol=1e-6)


def test_projection_matches_the_camera_model() -> None:
    rng = np.random.default_rng(2)
    rvec, tvec = pose(rng)
    pts = model_points(8)
    px, _ = project_with_jacobian(pts, rvec, tvec, CAM.K, CAM.dist)
    R, _ = cv2.Rodrigues(rvec)
    assert np.allclose(px, CAM.project((R @ pts.T).T + tvec), atol=1e-9)


def test_jacobian_matches_finite_differences() -> None:
    rng = np.random.default_rng(3)
    rvec, tvec = pose(rng)
    pts = model_points(8)
    _, J = project_with_jacobian(pts, rvec, tvec, CAM.K, CAM.dist)
    x0 = np.concatenate([rvec, tvec])
    J_fd = np.zeros_like(J)
    h = 1e-6
    for k in range(6):
        d = np.zeros(6)
        d[k] = h
        p_plus, _ = project_with_jacobian(pts, (x0 + d)[:3], (x0 + d)[3:], CAM.K, CAM.dist)
        p_minus, _ = project_with_jacobian(pts, (x0 - d)[:3], (x0 - d)[3:], CAM.K, CAM.dist)
        J_fd[:, k] = (p_plus - p_minus).ravel() / (2 * h)
    assert np.allclose(J, J_fd, rtol=1e-5, atol=1e-4)


def test_covariance_is_consistent_with_monte_carlo() -> None:
    """NEES of p_CP over noisy trials: its mean is 3 for a consistent covariance (chi-square bounds
    for 300 trials at 99.9 %)."""
    rng = np.random.default_rng(4)
    rvec, tvec = pose(rng)
    pts = model_points(16)
    px0, _ = project_with_jacobian(pts, rvec, tvec, CAM.K, CAM.dist)
    sigma = 0.5
    n = 300
    nees = np.empty(n)
    for i in range(n):
        res = solve_pnp(px0 + rng.normal(0.0, sigma, px0.shape), pts, CAM, sigma_px=sigma)
        assert res is not None
        e = res.p_CP - tvec
        nees[i] = e @ np.linalg.solve(res.cov_p_CP, e)
    lo, hi = chi2.ppf([0.0005, 0.9995], 3 * n) / n
    assert lo < nees.mean() < hi
    # the covariance scales with sigma_px^2
    a = solve_pnp(px0, pts, CAM, sigma_px=1.0)
    b = solve_pnp(px0, pts, CAM, sigma_px=2.0)
    assert a is not None and b is not None and np.allclose(b.cov_p_CP, 4 * a.cov_p_CP)
    assert np.all(np.linalg.eigvalsh(a.cov_pose) > 0)


def test_degenerate_inputs_give_none() -> None:
    pts = TAG.quad_corners_P()
    px = np.array([[100.0, 100.0], [200.0, 100.0], [200.0, 200.0], [100.0, 200.0]])
    assert solve_pnp(px[:3], pts[:3], CAM) is None
    line = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.2, 0.0, 0.0], [0.3, 0.0, 0.0]])
    assert solve_pnp(px, line, CAM) is None


def test_bad_inputs_raise() -> None:
    pts = TAG.quad_corners_P()
    px = np.zeros((4, 2))
    with pytest.raises(ValueError):
        solve_pnp(px[:3], pts, CAM)
    with pytest.raises(ValueError):
        solve_pnp(np.full((4, 2), np.nan), pts, CAM)
    with pytest.raises(ValueError):
        solve_pnp(px, pts, CAM, sigma_px=0.0)
