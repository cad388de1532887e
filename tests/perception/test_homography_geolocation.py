"""Paper 004's homography geolocation (Sec. IV-A, 8 steps): exactness against ray casting where the
method is exact, its known errors where it is not, landmark offsets, frames, and the covariance."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from alight.cameras import CameraMount, PinholeCamera, camera_pose_W
from alight.perception import Geolocator
from alight.perception.homography_geolocation import (
    HomographyGeolocator,
    apply_homography,
    enu_flu_from_ned_frd,
    heading_and_tilt,
    homography_4pt,
    ray_plane_point,
)
from alight.types import Observation, rot_z, wrap_angle, yaw_of

W, H = 752, 480
# an undistorted camera with the principal point at the image centre and fx != fy: the paper's
# field-of-view corners are then exactly this camera's
CENTRED = PinholeCamera(W, H, np.array([[400.0, 0, 375.5], [0, 410.0, 239.5], [0, 0, 1]]), np.zeros(5))
MOUNT = CameraMount.downward(np.array([0.05, 0.02, -0.03]))


def tilt(roll: float, pitch: float, yaw: float = 0.0) -> np.ndarray:
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    return rot_z(yaw) @ Ry @ Rx


def exact_point(camera: PinholeCamera, mount: CameraMount, px, p_WB, R_WB, plane_z):  # type: ignore[no-untyped-def]
    p_WC, R_WC = camera_pose_W(p_WB, R_WB, mount)
    return ray_plane_point(p_WC, R_WC @ camera.unproject(np.atleast_2d(px))[0], plane_z)


def random_poses(rng: np.random.Generator, n: int, max_tilt: float = 0.4):  # type: ignore[no-untyped-def]
    for _ in range(n):
        p_WB = np.array([rng.uniform(-20, 20), rng.uniform(-20, 20), rng.uniform(1.5, 25.0)])
        R_WB = tilt(rng.uniform(-max_tilt, max_tilt), rng.uniform(-max_tilt, max_tilt), rng.uniform(-4, 4))
        px = np.array([rng.uniform(-0.5, W - 0.5), rng.uniform(-0.5, H - 0.5)])
        yield p_WB, R_WB, px


# ---- steps 3-5: the homography --------------------------------------------------------------------------


def test_homography_4pt_maps_the_points_and_agrees_with_opencv() -> None:
    rng = np.random.default_rng(1)
    src = np.array([[-0.5, -0.5], [751.5, -0.5], [751.5, 479.5], [-0.5, 479.5]])
    for _ in range(20):
        dst = np.array([[-3.0, -2.0], [3.0, -2.0], [3.0, 2.0], [-3.0, 2.0]]) + rng.normal(0, 0.7, (4, 2))
        Hm = np.empty((3, 3))
        assert homography_4pt(src, dst, Hm)
        out = np.empty((4, 2))
        apply_homography(Hm, src, out)
        assert np.abs(out - dst).max() < 1e-12
        # OpenCV: findHomography (float64, iterative) to its own accuracy, getPerspectiveTransform
        # (float32 points only) to float32's
        p = rng.uniform(0, 700, (5, 2))
        a, b = np.empty((5, 2)), np.empty((5, 2))
        apply_homography(Hm, p, a)
        H_cv, _ = cv2.findHomography(src, dst, 0)
        apply_homography(H_cv / H_cv[2, 2], p, b)
        assert np.abs(a - b).max() < 1e-6
        H_32 = cv2.getPerspectiveTransform(src.astype(np.float32), dst.astype(np.float32))
        apply_homography(H_32 / H_32[2, 2], p, b)
        assert np.abs(a - b).max() < 1e-3
    collinear = np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [0.0, 1.0]])
    assert not homography_4pt(src, collinear, np.empty((3, 3)))


# ---- exactness -------------------------------------------------------------------------------------------


def test_equals_exact_ray_casting_on_a_centred_undistorted_pinhole() -> None:
    geo = HomographyGeolocator(CENTRED, MOUNT, plane_z_W=0.5)
    assert geo.virtual_intrinsics == pytest.approx((400.0, 410.0, 375.5, 239.5), abs=1e-9)
    rng = np.random.default_rng(2)
    n = 0
    for p_WB, R_WB, px in random_poses(rng, 300):
        ex = exact_point(CENTRED, MOUNT, px, p_WB, R_WB, 0.5)
        got = geo.ground_points(px[None], p_WB, R_WB)
        if ex is None:
            assert got is None
            continue
        assert got is not None
        assert np.abs(got[0] - ex).max() < 1e-9
        n += 1
    assert n > 250


def test_steep_tilt_with_corners_above_the_horizon_is_still_exact() -> None:
    # 60 deg of pitch with a 90 deg field of view: two image corners look above the horizon
    geo = HomographyGeolocator(CENTRED, MOUNT)
    p_WB, R_WB = np.array([1.0, 2.0, 6.0]), tilt(0.1, 1.05, 0.3)
    rng = np.random.default_rng(3)
    hits = 0
    for _ in range(100):
        px = np.array([rng.uniform(0, W - 1), rng.uniform(0, H - 1)])
        ex = exact_point(CENTRED, MOUNT, px, p_WB, R_WB, 0.0)
        got = geo.ground_points(px[None], p_WB, R_WB)
        assert (ex is None) == (got is None)
        if ex is not None:
            hits += 1
            assert np.abs(got[0] - ex).max() < 1e-7 * max(1.0, float(np.linalg.norm(ex - p_WB)))
    assert 10 < hits < 100


def test_exact_intrinsics_mode_is_exact_with_distortion_and_off_centre_principal_point() -> None:
    K = np.array([[420.0, 0, 360.0], [0, 415.0, 250.0], [0, 0, 1]])
    cam = PinholeCamera(W, H, K, np.array([-0.12, 0.03, 0.001, -0.0005, 0.0]))
    geo = HomographyGeolocator(cam, MOUNT, plane_z_W=0.3, exact_intrinsics=True)
    rng = np.random.default_rng(4)
    for p_WB, R_WB, px in random_poses(rng, 100):
        ex = exact_point(cam, MOUNT, px, p_WB, R_WB, 0.3)
        got = geo.ground_points(px[None], p_WB, R_WB)
        assert (ex is None) == (got is None)
        if ex is not None:
            assert np.abs(got[0] - ex).max() < 1e-9


def test_distortion_error_of_the_paper_method() -> None:
    """The numbers the module docstring quotes for the default camera looking straight down."""
    cam = PinholeCamera.default_downward()
    geo = HomographyGeolocator(cam, CameraMount.downward())
    h = 4.0
    p_WB, R_WB = np.array([0.0, 0.0, h]), np.eye(3)
    cx, cy = 375.5, 239.5
    cases = [
        ((cx, cy), 0.0),
        ((751.5, cy), 0.0),  # the fields of view are the edges' angles: exact there
        ((cx, 479.5), 0.0),
        ((cx + 752 / 4, cy), 0.028),
        ((cx + (751.5 - cx) / 2, cy + (479.5 - cy) / 2), 0.024),
        ((751.5, 479.5), 0.057),
    ]
    for px, rel in cases:
        got = geo.ground_points(np.array([px]), p_WB, R_WB)[0]
        ex = exact_point(cam, CameraMount.downward(), px, p_WB, R_WB, 0.0)
        assert np.linalg.norm(got - ex) / h == pytest.approx(rel, abs=0.0006)


def test_principal_point_off_centre_shifts_the_rays() -> None:
    K = np.array([[400.0, 0, 385.5], [0, 400.0, 239.5], [0, 0, 1]])  # 10 px right of the centre
    cam = PinholeCamera(W, H, K, np.zeros(5))
    geo = HomographyGeolocator(cam, CameraMount.downward())
    h = 5.0
    p_WB, R_WB = np.array([0.0, 0.0, h]), np.eye(3)
    px = np.array([[375.5, 239.5]])
    err = np.linalg.norm(
        geo.ground_points(px, p_WB, R_WB)[0]
        - exact_point(cam, CameraMount.downward(), px[0], p_WB, R_WB, 0.0)
    )
    assert err == pytest.approx(h * 10.0 / 400.0, rel=0.02)


def test_wrong_plane_height_error_is_the_closed_form() -> None:
    """The deck 0.5 m above the assumed plane: the point moves radially from the camera's nadir by
    d dz / h and sits dz too low."""
    geo = HomographyGeolocator(CENTRED, MOUNT, plane_z_W=0.0)
    dz = 0.5
    rng = np.random.default_rng(5)
    for p_WB, R_WB, px in random_poses(rng, 100):
        true = exact_point(CENTRED, MOUNT, px, p_WB, R_WB, dz)
        got = geo.ground_points(px[None], p_WB, R_WB)
        if true is None or got is None:
            continue
        p_WC, _ = camera_pose_W(p_WB, R_WB, MOUNT)
        h = p_WC[2] - dz
        d = true[:2] - p_WC[:2]
        expected = true[:2] + d * dz / h
        assert np.abs(got[0, :2] - expected).max() < 1e-9
        assert got[0, 2] == pytest.approx(true[2] - dz, abs=1e-12)


def test_camera_below_the_plane_or_ray_above_the_horizon_gives_none() -> None:
    geo = HomographyGeolocator(CENTRED, MOUNT, plane_z_W=2.0)
    obs = Observation(t=0.0, kind="nfold", quality=1.0, pixels=np.array([[375.0, 240.0]]))
    assert geo.locate(obs, np.array([0.0, 0.0, 1.0]), np.eye(3)) is None
    # pitched 80 deg nose down and looking back: the top of the image looks at the sky
    R = tilt(0.0, -1.4)
    assert geo.ground_points(np.array([[375.0, 0.0]]), np.array([0.0, 0.0, 10.0]), R) is None
    with pytest.raises(ValueError):
        geo.locate(obs, np.array([0.0, np.nan, 5.0]), np.eye(3))
    with pytest.raises(ValueError):
        HomographyGeolocator(CENTRED, MOUNT, sigma_px=0.0)


def test_satisfies_the_geolocator_protocol() -> None:
    assert isinstance(HomographyGeolocator(CENTRED, MOUNT), Geolocator)


# ---- frames --------------------------------------------------------------------------------------------


def test_ned_frd_attitude_conversion_and_step_1_split() -> None:
    rng = np.random.default_rng(6)
    for _ in range(20):
        roll, pitch, yaw_n = rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), rng.uniform(-3, 3)
        R_NF = Rotation.from_euler("ZYX", [yaw_n, pitch, roll]).as_matrix()  # the paper's convention
        R_WB = enu_flu_from_ned_frd(R_NF)
        assert np.allclose(R_WB.T @ R_WB, np.eye(3), atol=1e-12) and np.linalg.det(R_WB) > 0
        assert wrap_angle(yaw_of(R_WB) - (math.pi / 2 - yaw_n)) == pytest.approx(0.0, abs=1e-12)
        psi, R_tilt = heading_and_tilt(R_WB)
        assert np.allclose(R_tilt, tilt(roll, -pitch), atol=1e-12)
        assert np.allclose(rot_z(psi) @ R_tilt, R_WB, atol=1e-12)
        # the body's nose (FRD x) points where the NED rotation says, written in ENU
        nose_ned = R_NF[:, 0]
        assert np.allclose(R_WB[:, 0], [nose_ned[1], nose_ned[0], -nose_ned[2]], atol=1e-12)


# ---- step 8: landmarks and offsets ---------------------------------------------------------------------


def _pixel_of(camera: PinholeCamera, mount: CameraMount, p_W, p_WB, R_WB):  # type: ignore[no-untyped-def]
    p_WC, R_WC = camera_pose_W(p_WB, R_WB, mount)
    return camera.project((R_WC.T @ (p_W - p_WC))[None])[0]


def test_landmark_offset_with_measured_assumed_and_missing_heading() -> None:
    p_WP, pad_yaw = np.array([2.0, -1.0, 0.5]), 0.8
    off = np.array([0.5, 0.4, 0.0])
    p_mark = p_WP + rot_z(pad_yaw) @ off
    p_WB, R_WB = np.array([1.5, -0.5, 6.0]), tilt(0.1, -0.05, 0.4)
    px = _pixel_of(CENTRED, MOUNT, p_mark, p_WB, R_WB)
    geo = HomographyGeolocator(CENTRED, MOUNT, plane_z_W=0.5, landmark_offsets={"aruco:3": off[:2]})
    # heading unknown: no centre
    o = Observation(t=1.0, kind="aruco:3", quality=0.9, pixels=px[None])
    assert geo.locate(o, p_WB, R_WB) is None
    # heading from the marker's orientation in the image (the image direction of the pad's x axis)
    p_WC, R_WC = camera_pose_W(p_WB, R_WB, MOUNT)
    x_C = R_WC.T @ rot_z(pad_yaw)[:, 0]
    o2 = Observation(t=1.0, kind="aruco:3", quality=0.9, pixels=px[None], yaw_CP=math.atan2(x_C[1], x_C[0]))
    m = geo.locate(o2, p_WB, R_WB)
    assert m is not None and np.abs(m.p_WP - p_WP).max() < 1e-9
    assert m.yaw == pytest.approx(pad_yaw, abs=1e-9) and m.yaw_var == pytest.approx(0.05**2)
    # the same landmark given by points_P, and an assumed heading
    o3 = Observation(t=1.0, kind="nfold", quality=0.9, pixels=px[None], points_P=off[None])
    geo_a = HomographyGeolocator(CENTRED, MOUNT, plane_z_W=0.5, assume_pad_yaw=pad_yaw)
    m3 = geo_a.locate(o3, p_WB, R_WB)
    assert m3 is not None and np.abs(m3.p_WP - p_WP).max() < 1e-9 and m3.yaw is None
    # the heading's uncertainty widens the covariance across the offset only
    m0 = HomographyGeolocator(
        CENTRED, MOUNT, plane_z_W=0.5, assume_pad_yaw=pad_yaw, sigma_yaw_rad=0.0
    ).locate(o3, p_WB, R_WB)
    d = m3.cov_p_WP - m0.cov_p_WP
    across = np.cross([0, 0, 1.0], rot_z(pad_yaw) @ off)
    assert np.allclose(d, 0.05**2 * np.outer(across, across), atol=1e-15)


def test_several_landmarks_give_the_centre_and_heading_by_procrustes() -> None:
    p_WP, pad_yaw = np.array([-3.0, 4.0, 0.4]), -2.2
    offs = np.array([[0.0, 0.0, 0.0], [0.5, 0.45, 0.0], [-0.5, 0.45, 0.0], [0.5, -0.45, 0.0]])
    p_WB, R_WB = np.array([-2.0, 3.0, 7.0]), tilt(-0.1, 0.15, 2.0)
    px = np.array([_pixel_of(CENTRED, MOUNT, p_WP + rot_z(pad_yaw) @ o, p_WB, R_WB) for o in offs])
    geo = HomographyGeolocator(CENTRED, MOUNT, plane_z_W=0.4, points="all")
    m = geo.locate(Observation(t=0.0, kind="sdu", quality=1.0, pixels=px, points_P=offs), p_WB, R_WB)
    assert m is not None and np.abs(m.p_WP - p_WP).max() < 1e-9
    assert wrap_angle(m.yaw - pad_yaw) == pytest.approx(0.0, abs=1e-9)
    # one offset for several points of one landmark kind is ambiguous
    geo_k = HomographyGeolocator(CENTRED, MOUNT, landmark_offsets={"aruco:1": (0.5, 0.5)}, points="all")
    assert geo_k.locate(Observation(t=0.0, kind="aruco:1", quality=1.0, pixels=px[:2]), p_WB, R_WB) is None


# ---- covariance ---------------------------------------------------------------------------------------


SIGMAS = dict(sigma_px=1.5, sigma_att_rad=0.01, sigma_ego_pos_m=0.03, sigma_alt_m=0.05, sigma_plane_m=0.04)


def _perturbed(geo, obs, p_WB, R_WB, d_px, d_att, d_pos, d_plane, plane_z):  # type: ignore[no-untyped-def]
    o = Observation(
        t=obs.t, kind=obs.kind, quality=obs.quality, pixels=obs.pixels + d_px, points_P=obs.points_P
    )
    geo.plane_z_W = plane_z + d_plane
    try:
        return geo.locate(o, p_WB + d_pos, Rotation.from_rotvec(d_att).as_matrix() @ R_WB)
    finally:
        geo.plane_z_W = plane_z


@pytest.mark.parametrize("exact", [False, True])
def test_covariance_terms_match_finite_differences(exact: bool) -> None:
    """With one noise source at a time, the covariance is sigma^2 J J^T with J by central differences."""
    cam = PinholeCamera.default_downward() if exact else CENTRED
    p_WB, R_WB = np.array([0.5, -1.0, 5.5]), tilt(0.15, -0.2, 1.1)
    obs = Observation(t=0.0, kind="nfold", quality=1.0, pixels=np.array([[520.0, 130.0]]))
    zero = {k: 0.0 for k in SIGMAS} | {"sigma_px": 1e-300}
    eps = 1e-6
    z0 = np.zeros(3)

    def fd(sigma_name: str, which: str, dims: int) -> np.ndarray:
        geo = HomographyGeolocator(cam, MOUNT, plane_z_W=0.3, exact_intrinsics=exact, **zero)
        J = np.zeros((3, dims))
        for k in range(dims):
            d = np.zeros(dims)
            d[k] = eps
            args_p = dict(d_px=np.zeros(2), d_att=z0, d_pos=z0, d_plane=0.0)
            args_m = dict(args_p)
            if which == "px":
                args_p["d_px"], args_m["d_px"] = d, -d
            elif which == "att":
                args_p["d_att"], args_m["d_att"] = d, -d
            elif which == "pos":
                args_p["d_pos"], args_m["d_pos"] = d, -d
            else:
                args_p["d_plane"], args_m["d_plane"] = eps, -eps
            mp = _perturbed(geo, obs, p_WB, R_WB, plane_z=0.3, **args_p)
            mm = _perturbed(geo, obs, p_WB, R_WB, plane_z=0.3, **args_m)
            J[:, k] = (mp.p_WP - mm.p_WP) / (2 * eps)
        return J

    cases = [
        ("sigma_px", "px", 2, np.eye(2)),
        ("sigma_att_rad", "att", 3, np.eye(3)),
        ("sigma_ego_pos_m", "pos", 3, np.diag([1.0, 1.0, 0.0])),
        ("sigma_alt_m", "pos", 3, np.diag([0.0, 0.0, 1.0])),
        ("sigma_plane_m", "plane", 1, np.eye(1)),
    ]
    for name, which, dims, mask in cases:
        J = fd(name, which, dims)
        sig = SIGMAS[name]
        geo = HomographyGeolocator(cam, MOUNT, plane_z_W=0.3, exact_intrinsics=exact, **(zero | {name: sig}))
        cov = geo.locate(obs, p_WB, R_WB).cov_p_WP
        expected = sig**2 * J @ mask @ J.T
        assert np.allclose(cov, expected, rtol=1e-5, atol=1e-8 * np.abs(expected).max()), name


def test_covariance_matches_monte_carlo() -> None:
    p_WB, R_WB = np.array([0.5, -1.0, 5.5]), tilt(0.15, -0.2, 1.1)
    obs = Observation(t=0.0, kind="nfold", quality=1.0, pixels=np.array([[520.0, 130.0]]))
    geo = HomographyGeolocator(CENTRED, MOUNT, plane_z_W=0.3, **SIGMAS)
    m0 = geo.locate(obs, p_WB, R_WB)
    rng = np.random.default_rng(7)
    n = 3000
    errs = np.empty((n, 3))
    s = SIGMAS
    for i in range(n):
        d_pos = rng.normal(0, 1, 3) * [s["sigma_ego_pos_m"], s["sigma_ego_pos_m"], s["sigma_alt_m"]]
        m = _perturbed(
            geo,
            obs,
            p_WB,
            R_WB,
            d_px=rng.normal(0, s["sigma_px"], 2),
            d_att=rng.normal(0, s["sigma_att_rad"], 3),
            d_pos=d_pos,
            d_plane=rng.normal(0, s["sigma_plane_m"]),
            plane_z=0.3,
        )
        errs[i] = m.p_WP - m0.p_WP
    C = np.cov(errs.T)
    P = m0.cov_p_WP
    # sample covariance of 3000 draws: ~2.6 % standard error per entry; compare in P's own metric
    L = np.linalg.cholesky(P)
    Wm = np.linalg.solve(L, np.linalg.solve(L, C).T)
    assert np.abs(Wm - np.eye(3)).max() < 0.1
    nees = np.einsum("ij,jk,ik->i", errs, np.linalg.inv(P), errs)
    assert nees.mean() == pytest.approx(3.0, abs=0.15)


def test_sdu_observation_uses_its_fused_first_pixel() -> None:
    """The SDU detector's observation: row 0 the fused landing-marker pixel with ``points_P[0]`` the pad
    centre, then the raw points it fused (here deliberately off by 20 px) for PnP; ``yaw_CP`` the pad's
    orientation in the image."""
    p_WP, pad_yaw = np.array([1.0, 2.0, 0.5]), 2.5
    p_WB, R_WB = np.array([0.0, 1.0, 8.0]), tilt(0.05, 0.1, -0.7)
    px0 = _pixel_of(CENTRED, MOUNT, p_WP, p_WB, R_WB)
    corners = np.array([[0.6, 0.4, 0.0], [0.4, 0.4, 0.0], [0.4, 0.6, 0.0], [0.6, 0.6, 0.0]])
    pxc = np.array([_pixel_of(CENTRED, MOUNT, p_WP + rot_z(pad_yaw) @ c, p_WB, R_WB) for c in corners])
    p_WC, R_WC = camera_pose_W(p_WB, R_WB, MOUNT)
    x_C = R_WC.T @ rot_z(pad_yaw)[:, 0]
    obs = Observation(
        t=2.0,
        kind="sdu",
        quality=0.8,
        pixels=np.vstack([px0, pxc + 20.0]),
        points_P=np.vstack([np.zeros(3), corners]),
        yaw_CP=math.atan2(x_C[1], x_C[0]),
    )
    m = HomographyGeolocator(CENTRED, MOUNT, plane_z_W=0.5).locate(obs, p_WB, R_WB)
    assert m is not None and m.t == 2.0 and np.abs(m.p_WP - p_WP).max() < 1e-9
    assert m.yaw == pytest.approx(pad_yaw, abs=1e-9)
    single = Observation(t=2.0, kind="sdu", quality=0.8, pixels=px0[None])
    m1 = HomographyGeolocator(CENTRED, MOUNT, plane_z_W=0.5).locate(single, p_WB, R_WB)
    assert np.array_equal(m1.p_WP, m.p_WP) and np.array_equal(m1.cov_p_WP, m.cov_p_WP)
    # every row: the 20 px error of the extra rows moves the centre
    m_all = HomographyGeolocator(CENTRED, MOUNT, plane_z_W=0.5, points="all").locate(obs, p_WB, R_WB)
    assert np.linalg.norm(m_all.p_WP - p_WP) > 0.1
