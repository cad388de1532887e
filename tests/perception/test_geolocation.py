"""Geolocation: render -> detect -> PnP -> W round trips, the covariance of eq. (2), and the direct path."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from perception_scenes import tilt
from scipy.stats import chi2

from alight.cameras import CameraMount, MountedCamera, PinholeCamera, camera_pose_W
from alight.pads import AprilTagPad, FalangaTag
from alight.perception import GEOLOCATORS, Geolocator
from alight.perception.aruco import ArucoPadDetector, merge_observations
from alight.perception.falanga_tag import FalangaTagDetector
from alight.perception.geolocation import (
    DirectGeolocator,
    PnpGeolocator,
    level_pad_yaw,
    skew,
    world_covariance,
    wrap_yaw,
)
from alight.perception.pnp import project_with_jacobian
from alight.types import Observation, rot_z, wrap_angle

CAM = PinholeCamera.default_downward()
MOUNT = CameraMount.downward(np.array([0.05, 0.0, -0.03]))

POSES = [
    # (p_WB, (roll, pitch, yaw), p_WP, pad yaw)
    (np.array([3.2, -1.5, 6.0]), (0.1, -0.15, 0.4), np.array([3.0, -2.0, 0.5]), 0.7),
    (np.array([-4.0, 2.0, 4.0]), (-0.2, 0.1, -2.0), np.array([-3.5, 2.5, 0.5]), -2.5),
    (np.array([10.0, 10.0, 9.0]), (0.05, 0.25, 1.2), np.array([12.0, 9.0, 0.5]), 3.0),
]


def render_pose(pad, p_WB, rpy, p_WP, yaw):  # type: ignore[no-untyped-def]
    from perception_scenes import renderer

    R_WB = tilt(*rpy)
    p_WC, R_WC = camera_pose_W(p_WB, R_WB, MOUNT)
    img = renderer(pad).render(p_WC, R_WC, (p_WP, yaw))
    return img, R_WB


@pytest.mark.parametrize("p_WB,rpy,p_WP,yaw", POSES)
def test_falanga_round_trip(p_WB, rpy, p_WP, yaw) -> None:  # type: ignore[no-untyped-def]
    tag = FalangaTag.default()
    img, R_WB = render_pose(tag, p_WB, rpy, p_WP, yaw)
    obs = FalangaTagDetector(tag).detect(img, 2.0)
    assert obs and obs[0].kind == "circle"
    m = PnpGeolocator(CAM, MOUNT, sigma_px=0.5, yaw_fold=4).locate(obs[0], p_WB, R_WB)
    assert m is not None and m.t == 2.0
    rng_m = float(np.linalg.norm(p_WP - p_WB))
    assert np.linalg.norm(m.p_WP - p_WP) < 0.005 * rng_m
    # the tag is 4-fold symmetric: the yaw is known modulo pi/2
    assert m.yaw is not None and -math.pi / 4 <= m.yaw < math.pi / 4
    assert abs(wrap_yaw(m.yaw - yaw, 4)) < 0.02
    assert m.yaw_var is not None and 0 < m.yaw_var < 0.01
    assert np.all(np.linalg.eigvalsh(m.cov_p_WP) > 0)


@pytest.mark.parametrize("p_WB,rpy,p_WP,yaw", POSES[:2])
def test_apriltag_round_trip_gives_the_full_yaw(p_WB, rpy, p_WP, yaw) -> None:  # type: ignore[no-untyped-def]
    pad = AprilTagPad.default()
    img, R_WB = render_pose(pad, p_WB, rpy, p_WP, yaw)
    merged = merge_observations(ArucoPadDetector(pad, subpixel_corners=True).detect(img, 0.0))
    assert merged is not None
    m = PnpGeolocator(CAM, MOUNT).locate(merged, p_WB, R_WB)
    assert m is not None
    assert np.linalg.norm(m.p_WP - p_WP) < 0.01 * float(np.linalg.norm(p_WP - p_WB))
    assert m.yaw is not None and abs(wrap_angle(m.yaw - yaw)) < 0.03


def test_covariance_is_consistent_in_the_world_frame() -> None:
    """Noisy pixels of known truth through the geolocator: NEES of p_WP (3 dof) and of the yaw (1 dof)
    inside 99.9 % chi-square bounds of their means."""
    rng = np.random.default_rng(0)
    tag = FalangaTag.default()
    pts = np.concatenate([tag.circle_points_P(16), tag.circle_inner_points_P(16)])
    p_WB, R_WB = np.array([1.0, 2.0, 5.0]), tilt(0.1, -0.2, 0.8)
    p_WP, yaw = np.array([1.5, 1.0, 0.4]), 0.3
    p_WC, R_WC = camera_pose_W(p_WB, R_WB, MOUNT)
    R_CP = R_WC.T @ rot_z(yaw)
    p_CP = R_WC.T @ (p_WP - p_WC)
    rvec, _ = cv2.Rodrigues(R_CP)
    px0, _ = project_with_jacobian(pts, rvec.ravel(), p_CP, CAM.K, CAM.dist)
    sigma = 0.7
    geo = PnpGeolocator(CAM, MOUNT, sigma_px=sigma)
    n = 200
    nees_p, nees_y = np.empty(n), np.empty(n)
    for i in range(n):
        obs = Observation(
            t=0.0, kind="circle", quality=1.0, pixels=px0 + rng.normal(0, sigma, px0.shape), points_P=pts
        )
        m = geo.locate(obs, p_WB, R_WB)
        assert m is not None and m.yaw is not None and m.yaw_var is not None
        e = m.p_WP - p_WP
        nees_p[i] = e @ np.linalg.solve(m.cov_p_WP, e)
        nees_y[i] = wrap_angle(m.yaw - yaw) ** 2 / m.yaw_var
    for nees, dof in ((nees_p, 3), (nees_y, 1)):
        lo, hi = chi2.ppf([0.0005, 0.9995], dof * n) / n
        assert lo < nees.mean() < hi


def test_attitude_term_of_eq2_matches_finite_differences() -> None:
    """d(R_WC p_CP)/d(theta) for a small rotation theta applied in W is -[R_WC p_CP]x."""
    R_WC = tilt(0.3, -0.2, 1.1)
    p_CP = np.array([0.4, -0.3, 5.0])
    r = R_WC @ p_CP
    J_fd = np.zeros((3, 3))
    h = 1e-6
    for k in range(3):
        th = np.zeros(3)
        th[k] = h
        Rp, _ = cv2.Rodrigues(th)
        Rm, _ = cv2.Rodrigues(-th)
        J_fd[:, k] = (Rp @ r - Rm @ r) / (2 * h)
    assert np.allclose(J_fd, -skew(r), atol=1e-8)
    # and eq. (2) rotates the camera-frame covariance: a diagonal one comes back diagonal in C
    cov_C = np.diag([0.01, 0.02, 0.09])
    cov_W = world_covariance(R_WC, p_CP, cov_C, 0.0, 0.0)
    assert np.allclose(R_WC.T @ cov_W @ R_WC, cov_C)
    inflated = world_covariance(R_WC, p_CP, cov_C, 0.1, 0.01)
    assert np.allclose(inflated - cov_W, 0.01 * np.eye(3) + 1e-4 * skew(r) @ skew(r).T)


def test_direct_geolocator_and_level_pad_yaw() -> None:
    p_WB, R_WB = np.array([2.0, -1.0, 7.0]), tilt(0.2, 0.15, -0.6)
    p_WP, yaw = np.array([2.5, -0.2, 0.5]), 1.9
    p_WC, R_WC = camera_pose_W(p_WB, R_WB, MOUNT)
    p_CP = R_WC.T @ (p_WP - p_WC)
    x_C = R_WC.T @ rot_z(yaw)[:, 0]
    yaw_CP = math.atan2(x_C[1], x_C[0])
    obs = Observation(t=1.0, kind="truth", quality=1.0, p_CP=p_CP, cov_p_CP=0.01 * np.eye(3), yaw_CP=yaw_CP)
    m = DirectGeolocator(MOUNT).locate(obs, p_WB, R_WB)
    assert m is not None
    assert np.allclose(m.p_WP, p_WP, atol=1e-12)
    assert np.allclose(m.cov_p_WP, 0.01 * np.eye(3))
    assert m.yaw is not None and abs(wrap_angle(m.yaw - yaw)) < 1e-9
    assert abs(wrap_angle(level_pad_yaw(R_WC, yaw_CP) - yaw)) < 1e-9  # type: ignore[operator]
    # no covariance: the default; no p_CP: nothing
    m2 = DirectGeolocator(MOUNT, default_sigma_m=0.2).locate(
        Observation(t=1.0, kind="truth", quality=1.0, p_CP=p_CP), p_WB, R_WB
    )
    assert m2 is not None and np.allclose(m2.cov_p_WP, 0.04 * np.eye(3)) and m2.yaw is None
    assert DirectGeolocator(MOUNT).locate(Observation(t=1.0, kind="blob", quality=1.0), p_WB, R_WB) is None
    # the PnP geolocator passes observations without pad points but with p_CP to the direct path
    m3 = PnpGeolocator(CAM, MOUNT).locate(obs, p_WB, R_WB)
    assert m3 is not None and np.allclose(m3.p_WP, p_WP)


def test_bad_inputs() -> None:
    obs = Observation(t=0.0, kind="truth", quality=1.0, p_CP=np.array([0.0, 0.0, 5.0]))
    with pytest.raises(ValueError):
        DirectGeolocator(MOUNT).locate(obs, np.zeros(2), np.eye(3))
    with pytest.raises(ValueError):
        DirectGeolocator(MOUNT).locate(obs, np.zeros(3), np.full((3, 3), np.nan))
    with pytest.raises(ValueError):
        PnpGeolocator(CAM, MOUNT, yaw_fold=0)
    with pytest.raises(ValueError):
        PnpGeolocator(CAM, MOUNT, sigma_ego_att_rad=-1.0)
    assert (
        PnpGeolocator(CAM, MOUNT).locate(Observation(t=0.0, kind="quad", quality=1.0), np.zeros(3), np.eye(3))
        is None
    )


def test_registry_geolocators_satisfy_the_protocol() -> None:
    for spec in GEOLOCATORS.values():
        assert isinstance(spec.build_default(MountedCamera(camera=CAM, mount=MOUNT)), Geolocator), spec.name


def test_wrap_yaw() -> None:
    for a in np.linspace(-10, 10, 41):
        w = wrap_yaw(float(a), 4)
        assert -math.pi / 4 <= w < math.pi / 4
        k = (a - w) / (math.pi / 2)
        assert abs(k - round(k)) < 1e-9
