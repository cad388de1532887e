"""Camera-image renderer: geometry against the camera model, determinism, robustness, effects."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from alight.cameras import CameraMount, PinholeCamera, camera_pose_W
from alight.pads import APRILTAG_DICTIONARY, AprilTagPad, FalangaTag
from alight.sim.render import Renderer, RenderOptions, _motion_blur_kernel
from alight.sim.textures import GroundTexture, make_ground_texture
from alight.types import quat_to_rotmat, rot_z

MOUNT = CameraMount.downward()


class _EquidistantFisheye:
    """A minimal non-pinhole CameraModel (r = f theta, 200 deg field of view inside an image circle) to
    check that the renderer only relies on the protocol: rays beyond 90 deg and pixels without a ray."""

    def __init__(self, width: int = 640, height: int = 480, f: float = 150.0, theta_max: float = 1.745):
        self.width, self.height, self.f, self.theta_max = width, height, f, theta_max
        self.c = np.array([(width - 1) / 2, (height - 1) / 2])

    def project(self, points_C: np.ndarray) -> np.ndarray:
        P = np.asarray(points_C, dtype=float)
        theta = np.arctan2(np.hypot(P[:, 0], P[:, 1]), P[:, 2])
        phi = np.arctan2(P[:, 1], P[:, 0])
        uv = self.c + (self.f * theta)[:, None] * np.stack([np.cos(phi), np.sin(phi)], axis=1)
        uv[theta > self.theta_max] = np.nan
        return uv

    def unproject(self, pixels: np.ndarray) -> np.ndarray:
        d = np.asarray(pixels, dtype=float) - self.c
        theta = np.hypot(d[:, 0], d[:, 1]) / self.f
        phi = np.arctan2(d[:, 1], d[:, 0])
        s = np.sin(theta)
        rays = np.stack([s * np.cos(phi), s * np.sin(phi), np.cos(theta)], axis=1)
        rays[theta > self.theta_max] = np.nan
        return rays


CAMERAS = {
    "default": PinholeCamera.default_downward(),
    # the ChArUco tutorial calibration: strong distortion (k1 = 0.12, k2 = -1.09, k3 = 2.95)
    "strong": PinholeCamera(
        640,
        480,
        np.array([[452.51, 0.0, 317.70], [0.0, 456.77, 277.75], [0.0, 0.0, 1.0]]),
        np.array([0.12137, -1.08547, 1.1787e-04, -4.6241e-04, 2.95426]),
    ),
    "fisheye": _EquidistantFisheye(),
    "odd_size": PinholeCamera(641, 479, np.array([[350.0, 0, 320.0], [0, 350.0, 239.0], [0, 0, 1.0]])),
}
PLATFORM = (np.array([3.0, -2.0, 0.9]), 0.7)
CLEAN = RenderOptions(noise_sigma_dn=0.0)


@pytest.fixture(scope="module")
def grass() -> GroundTexture:
    return make_ground_texture("grass", np.random.default_rng(11), size_px=512)


def _to_image(cam: PinholeCamera, p_WC: np.ndarray, R_WC: np.ndarray, pts_P: np.ndarray) -> np.ndarray:
    p_WP, yaw = PLATFORM
    X_W = pts_P @ rot_z(yaw).T + p_WP
    return cam.project((X_W - p_WC) @ R_WC)


def _sample(img: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear image values at sub-pixel points (N, 2)."""
    m = uv.astype(np.float32).reshape(1, -1, 2)
    return cv2.remap(img.astype(np.float32), m[..., 0], m[..., 1], cv2.INTER_LINEAR).ravel()


def _pose_over_pad(h: float, offset=(0.2, -0.15), yaw_B: float = 1.1, tilt: float = 0.0):
    p_WP, _ = PLATFORM
    R_WB = rot_z(yaw_B) @ quat_to_rotmat(np.array([math.sin(tilt / 2), 0.0, 0.0, math.cos(tilt / 2)]))
    return camera_pose_W(p_WP + np.array([offset[0], offset[1], h]), R_WB, MOUNT)


@pytest.mark.parametrize("cam_name", sorted(CAMERAS))
@pytest.mark.parametrize("h, tilt", [(4.0, 0.0), (2.5, 0.0), (3.0, 0.35)])
def test_pad_edges_are_where_the_camera_model_puts_them(grass, cam_name: str, h: float, tilt: float) -> None:
    """The 50 % crossing between the white square and the dark deck, measured along the edge's normal,
    lies on the projection of the square's edge (sub-pixel)."""
    cam = CAMERAS[cam_name]
    r = Renderer(cam, grass, FalangaTag(), CLEAN, None)
    p_WC, R_WC = _pose_over_pad(h, tilt=tilt)
    img = r.render(p_WC, R_WC, PLATFORM)
    tag = FalangaTag()
    half = tag.size_m / 2
    t = np.linspace(-0.6, 0.6, 13) * half
    errors = []
    for normal in ([1, 0], [-1, 0], [0, 1], [0, -1]):
        n = np.array([*normal, 0.0])
        along = np.array([-normal[1], normal[0], 0.0])
        E = half * n + t[:, None] * along
        I, O = E - 0.03 * n, E + 0.03 * n  # inside the white margin / on the deck margin
        uvI, uvE, uvO = (_to_image(cam, p_WC, R_WC, X) for X in (I, E, O))
        ok = np.all(np.isfinite(uvI) & np.isfinite(uvO), axis=1)
        ok &= np.all((uvI > 2) & (uvI < [cam.width - 3, cam.height - 3]), axis=1)
        ok &= np.all((uvO > 2) & (uvO < [cam.width - 3, cam.height - 3]), axis=1)
        for a, e, b in zip(uvI[ok], uvE[ok], uvO[ok], strict=True):
            s = np.linspace(0.0, 1.0, 401)
            vals = _sample(img, a + s[:, None] * (b - a))
            mid = 0.5 * (255.0 + vals[-1])
            k = int(np.argmax(vals < mid))
            assert 0 < k, "no white-to-deck edge along the normal"
            s_cross = s[k - 1] + (vals[k - 1] - mid) / (vals[k - 1] - vals[k]) * (s[k] - s[k - 1])
            s_edge = float(np.dot(e - a, b - a) / np.dot(b - a, b - a))
            errors.append(abs(s_cross - s_edge) * float(np.linalg.norm(b - a)))
    assert len(errors) > 20
    assert max(errors) < 0.3, f"edge offsets (px): max {max(errors):.3f}"


@pytest.mark.parametrize("cam_name", sorted(CAMERAS))
def test_pad_corners_found_at_projected_corners(grass, cam_name: str) -> None:
    cam = CAMERAS[cam_name]
    r = Renderer(cam, grass, FalangaTag(), CLEAN, None)
    p_WC, R_WC = _pose_over_pad(3.5)
    img = r.render(p_WC, R_WC, PLATFORM)
    uv = _to_image(cam, p_WC, R_WC, FalangaTag().quad_corners_P())
    start = (uv + np.array([1.2, -0.9])).astype(np.float32).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-3)
    found = cv2.cornerSubPix(img, start, (4, 4), (-1, -1), crit).reshape(-1, 2)
    assert np.max(np.linalg.norm(found - uv, axis=1)) < 1.0


def test_intensities_inside_and_outside_the_pad(grass) -> None:
    cam = CAMERAS["default"]
    r = Renderer(cam, grass, FalangaTag(), CLEAN, None)
    p_WC, R_WC = _pose_over_pad(3.0)
    img = r.render(p_WC, R_WC, PLATFORM)
    tag = FalangaTag()
    h = tag.size_m / 2
    white = np.array([[s1 * (h - 0.04), s2 * (h - 0.04), 0.0] for s1 in (1, -1) for s2 in (1, -1)])
    ring = tag.circle_points_P(12) * (1 - tag.ring_width_m / 2 / tag.ring_outer_radius_m)
    cross = np.array([[0.0, 0.0, 0.0], [0.3, 0.0, 0.0], [0.0, -0.3, 0.0]])
    deck = np.array([[0.0, h + 0.1, 0.0], [h + 0.2, 0.0, 0.0], [-(h + 0.2), 0.0, 0.0]])
    for pts, lo, hi in ((white, 250, 255), (ring, 0, 5), (cross, 0, 5), (deck, 45, 75)):
        vals = _sample(img, _to_image(cam, p_WC, R_WC, pts))
        assert np.all((vals >= lo) & (vals <= hi)), (vals, lo, hi)
    # outside the deck the image is the ground: identical to a render with the platform far away
    far = r.render(p_WC, R_WC, (np.array([500.0, 0.0, 0.9]), 0.0))
    deck_px = _to_image(cam, p_WC, R_WC, r.deck_corners_P).astype(np.float32)
    mask = np.zeros(img.shape, np.uint8)
    cv2.fillConvexPoly(mask, np.rint(deck_px).astype(np.int32), 1)
    mask = cv2.dilate(mask, np.ones((5, 5), np.uint8))
    assert mask.mean() > 0.1
    np.testing.assert_array_equal(img[mask == 0], far[mask == 0])
    assert np.any(img[mask == 1] != far[mask == 1])


@pytest.mark.parametrize("cam_name", sorted(CAMERAS))
def test_ground_geometry_matches_the_texture(cam_name: str) -> None:
    """A smooth periodic ground texture: each pixel shows the texture value at its ray's ground hit
    (orientation, scale, translation and wrap-around of the tile)."""
    n, m = 512, 0.02
    v, u = np.mgrid[0:n, 0:n]
    f = lambda uu, vv: 128 + 60 * np.sin(2 * np.pi * uu / n) + 50 * np.cos(2 * np.pi * vv / n)  # noqa: E731
    ground = GroundTexture(np.rint(f(u, v)).astype(np.uint8), m)
    cam = CAMERAS[cam_name]
    r = Renderer(cam, ground, FalangaTag(), CLEAN, None)
    rng = np.random.default_rng(0)
    far_platform = (np.array([-900.0, 0.0, 0.9]), 0.0)
    for p_WB, yaw, tilt in (((1.3, -0.4, 6.0), 0.3, 0.0), ((1234.5, -987.6, 9.0), -2.0, 0.5)):
        R_WB = rot_z(yaw) @ quat_to_rotmat(np.array([0.0, math.sin(tilt / 2), 0.0, math.cos(tilt / 2)]))
        p_WC, R_WC = camera_pose_W(np.array(p_WB), R_WB, MOUNT)
        img = r.render(p_WC, R_WC, far_platform)
        px = rng.integers([5, 5], [cam.width - 6, cam.height - 6], size=(2000, 2)).astype(float)
        rays = cam.unproject(px)
        # within 60 deg of the optical axis (a fisheye's periphery is too compressed for this tolerance)
        keep = np.isfinite(rays).all(axis=1) & (rays[:, 2] > 0.5)
        px, rays = px[keep], rays[keep]
        d_W = rays @ R_WC.T
        t = -p_WC[2] / d_W[:, 2]
        # one mip level per frame, picked at the optical axis: farther ground (a fisheye's horizon) aliases
        t_axis = p_WC[2] / -R_WC[2, 2]
        keep = (d_W[:, 2] < 0) & (t < 1.5 * t_axis)
        px, d_W, t = px[keep], d_W[keep], t[keep]
        assert len(px) > 100
        X = p_WC + t[:, None] * d_W
        expected = f(X[:, 0] / m, -X[:, 1] / m)
        got = img[px[:, 1].astype(int), px[:, 0].astype(int)]
        # half-resolution nearest-texel sampling (texels of up to 4 cm at the mip level used here) and
        # smoothing: the texture changes by up to 1.4 DN per 2 cm, a wrong geometry by tens of DN
        err = np.abs(got - expected)
        assert np.max(err) < 3.0 and np.mean(err) < 1.0


def test_fisheye_outside_its_image_circle_is_black(grass) -> None:
    cam = CAMERAS["fisheye"]
    r = Renderer(cam, grass, FalangaTag(), CLEAN, None)
    img = r.render(*_pose_over_pad(3.0), (np.array([100.0, 0.0, 0.9]), 0.0))  # no black pad in view
    v, u = np.mgrid[0 : cam.height, 0 : cam.width]
    radius = np.hypot(u - cam.c[0], v - cam.c[1])
    assert np.all(img[radius > cam.f * cam.theta_max + 3] == 0)
    assert np.all(img[radius < cam.f * cam.theta_max - 3] > 0)
    # the circle reaches past 90 deg: the sky shows around the rim
    assert np.mean(img[(radius < cam.f * cam.theta_max - 3) & (radius > cam.f * 1.65)] == CLEAN.sky_dn) > 0.9


def test_deterministic_for_a_seed(grass) -> None:
    cam = CAMERAS["default"]
    opt = RenderOptions(noise_sigma_dn=3.0)
    p_WC, R_WC = _pose_over_pad(4.0)
    a = Renderer(cam, grass, FalangaTag(), opt, np.random.default_rng(5))
    b = Renderer(cam, grass, FalangaTag(), opt, np.random.default_rng(5))
    c = Renderer(cam, grass, FalangaTag(), opt, np.random.default_rng(6))
    frames_a = [a.render(p_WC, R_WC, PLATFORM) for _ in range(3)]
    frames_b = [b.render(p_WC, R_WC, PLATFORM) for _ in range(3)]
    for fa, fb in zip(frames_a, frames_b, strict=True):
        np.testing.assert_array_equal(fa, fb)
    assert np.any(frames_a[0] != frames_a[1])  # the noise changes from frame to frame
    assert np.any(c.render(p_WC, R_WC, PLATFORM) != frames_a[0])
    g1 = make_ground_texture("asphalt", np.random.default_rng(3), size_px=256)
    g2 = make_ground_texture("asphalt", np.random.default_rng(3), size_px=256)
    np.testing.assert_array_equal(g1.image, g2.image)


def test_noise_statistics(grass) -> None:
    cam = CAMERAS["default"]
    p_WC, R_WC = _pose_over_pad(6.0)
    clean = Renderer(cam, grass, FalangaTag(), CLEAN, None).render(p_WC, R_WC, PLATFORM)
    noisy = Renderer(cam, grass, FalangaTag(), RenderOptions(noise_sigma_dn=4.0), np.random.default_rng(1))
    d = noisy.render(p_WC, R_WC, PLATFORM).astype(float) - clean
    inner = (clean > 20) & (clean < 235)  # no clipping at 0 / 255
    assert abs(d[inner].mean()) < 0.1
    assert d[inner].std() == pytest.approx(4.0, rel=0.05)


def _horizon_pose(z: float, pitch_up: float = 0.0):
    # camera optical axis along +x_W, image x along -y_W, image y down along -z_W, then pitched up
    R_WC = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    c, s = math.cos(pitch_up), math.sin(pitch_up)
    R_WC = np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]]) @ R_WC
    return np.array([0.0, 0.0, z]), R_WC


def test_horizon_sky_and_haze(grass) -> None:
    cam = CAMERAS["default"]
    opt = RenderOptions(noise_sigma_dn=0.0, sky_dn=222, max_range_m=100.0)
    r = Renderer(cam, grass, FalangaTag(), opt, None)
    p_WC, R_WC = _horizon_pose(2.0)
    img = r.render(p_WC, R_WC, PLATFORM)
    v, u = np.mgrid[0 : cam.height, 0 : cam.width]
    d_W = cam.unproject(np.stack([u.ravel(), v.ravel()], axis=1).astype(float)) @ R_WC.T
    dz = d_W[:, 2].reshape(img.shape)
    # away from the half-resolution upsampling's reach of the horizon line (a few pixels)
    sky = dz > 0.02
    near = dz < -2.0 / 60.0  # range < 60 m
    haze = (dz < -0.002) & (dz > -2.0 / 140.0)  # range 140 .. 1000 m
    assert sky.sum() > 1000 and near.sum() > 1000 and haze.sum() > 1000
    assert np.all(img[sky] == 222)
    assert np.all(img[haze] == int(round(grass.image.mean())))
    assert img[near].std() > 5  # textured ground


@pytest.mark.parametrize(
    "p_WC, R_WC",
    [
        _horizon_pose(0.5),  # below the deck plane, beside the platform
        _horizon_pose(-1.0),  # below the ground
        _horizon_pose(3.0, pitch_up=math.pi / 2),  # looking straight up
        _horizon_pose(0.9),  # exactly at the deck height
        (np.array([3.0, -2.0, 0.95]), MOUNT.R_BC),  # 5 cm above the pad, inside the deck
        (np.array([3.5, -2.0, 5.0]), _horizon_pose(0.0, pitch_up=-0.2)[1]),  # pad partly behind
        (np.array([3.0, -2.0, 1e6]), MOUNT.R_BC),  # very high
        (np.array([1e7, -3e7, 20.0]), MOUNT.R_BC),  # very far from the origin
    ],
)
def test_any_pose_renders(grass, p_WC, R_WC) -> None:
    for cam in CAMERAS.values():
        r = Renderer(cam, grass, AprilTagPad(), RenderOptions(), np.random.default_rng(0))
        img = r.render(p_WC, R_WC, PLATFORM)
        assert img.shape == (cam.height, cam.width) and img.dtype == np.uint8


def test_looking_up_sees_only_sky(grass) -> None:
    r = Renderer(CAMERAS["default"], grass, FalangaTag(), CLEAN, None)
    img = r.render(*_horizon_pose(3.0, pitch_up=math.pi / 2), PLATFORM)
    assert np.all(img == CLEAN.sky_dn)


def test_camera_low_over_the_deck_sees_only_deck(grass) -> None:
    """30 cm above the pad the deck fills the view: the ground texture makes no difference."""
    other = make_ground_texture("concrete", np.random.default_rng(99), size_px=512)
    p_WC = PLATFORM[0] + np.array([0.1, 0.0, 0.3])
    a = Renderer(CAMERAS["default"], grass, FalangaTag(), CLEAN, None).render(p_WC, MOUNT.R_BC, PLATFORM)
    b = Renderer(CAMERAS["default"], other, FalangaTag(), CLEAN, None).render(p_WC, MOUNT.R_BC, PLATFORM)
    np.testing.assert_array_equal(a, b)
    assert a.min() < 5 and a.max() > 250  # cross and white square in view
    # 1 m higher the deck no longer fills the image and the ground shows
    p_WC[2] += 1.0
    a = Renderer(CAMERAS["default"], grass, FalangaTag(), CLEAN, None).render(p_WC, MOUNT.R_BC, PLATFORM)
    b = Renderer(CAMERAS["default"], other, FalangaTag(), CLEAN, None).render(p_WC, MOUNT.R_BC, PLATFORM)
    assert np.mean(a != b) > 0.1


def test_apriltag_pad_detected_at_5m(grass) -> None:
    cam = CAMERAS["default"]
    pad = AprilTagPad()
    r = Renderer(cam, grass, pad, RenderOptions(noise_sigma_dn=2.0), np.random.default_rng(2))
    p_WC, R_WC = _pose_over_pad(5.0, offset=(0.6, -0.4), yaw_B=2.0)
    img = r.render(p_WC, R_WC, PLATFORM)
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    det = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(APRILTAG_DICTIONARY), params)
    corners, ids, _ = det.detectMarkers(img)
    assert ids is not None and pad.center_id in ids.ravel()
    assert set(ids.ravel().tolist()) <= set(pad.marker_ids)
    for c, i in zip(corners, ids.ravel(), strict=True):
        expected = _to_image(cam, p_WC, R_WC, pad.marker_corners_P(int(i)))
        assert np.max(np.linalg.norm(c[0] - expected, axis=1)) < 1.5


def test_exposure_gamma_shadow_vignetting(grass) -> None:
    cam = CAMERAS["default"]
    p_WC, R_WC = _pose_over_pad(3.0)
    base = Renderer(cam, grass, FalangaTag(), CLEAN, None).render(p_WC, R_WC, PLATFORM)
    bright = Renderer(cam, grass, FalangaTag(), RenderOptions(noise_sigma_dn=0, exposure_gain=2.0), None)
    b = bright.render(p_WC, R_WC, PLATFORM).astype(int)
    np.testing.assert_array_equal(b, np.minimum(np.rint(2.0 * base), 255))
    gam = Renderer(cam, grass, FalangaTag(), RenderOptions(noise_sigma_dn=0, gamma=2.0), None)
    g = gam.render(p_WC, R_WC, PLATFORM).astype(float)
    np.testing.assert_allclose(g, 255.0 * (base / 255.0) ** 2, atol=0.5 + 1e-9)
    # a shadow over the front-left white corner of the pad
    tri = ((0.74, 0.74), (0.3, 0.74), (0.74, 0.3))
    sh = Renderer(cam, grass, FalangaTag(), RenderOptions(noise_sigma_dn=0, shadow_polygon_P=tri), None)
    s = sh.render(p_WC, R_WC, PLATFORM)
    inside = _sample(s, _to_image(cam, p_WC, R_WC, np.array([[0.65, 0.65, 0.0]])))
    outside = _sample(s, _to_image(cam, p_WC, R_WC, np.array([[-0.65, -0.65, 0.0]])))
    assert inside[0] == pytest.approx(255 * 0.45, abs=1.5) and outside[0] > 250
    # vignetting on a uniform sky: corners lose the set fraction, the centre nothing
    vig = Renderer(cam, grass, FalangaTag(), RenderOptions(noise_sigma_dn=0, vignetting=0.3), None)
    img = vig.render(*_horizon_pose(3.0, pitch_up=math.pi / 2), PLATFORM).astype(float)
    sky = CLEAN.sky_dn
    assert img[cam.height // 2, cam.width // 2] == pytest.approx(sky, abs=1)
    assert img[0, 0] == pytest.approx(0.7 * sky, abs=1.5)


def test_motion_blur_kernel_and_direction(grass) -> None:
    f, T, w = 400.0, 0.01, 0.8  # 3.2 px of blur
    k = _motion_blur_kernel(np.array([w, 0.0, 0.0]), T, f)  # rotation about x_C: motion along v
    assert k is not None and k.sum() == pytest.approx(1.0, abs=1e-6)
    rows = np.nonzero(k.sum(axis=1) > 1e-3)[0]
    cols = np.nonzero(k.sum(axis=0) > 1e-3)[0]
    assert len(cols) == 1 and rows.max() - rows.min() == pytest.approx(f * w * T, abs=1.0)
    assert _motion_blur_kernel(np.array([0.0, 0.0, 5.0]), T, f) is None  # roll only: ignored
    assert _motion_blur_kernel(np.array([0.01, 0.0, 0.0]), T, f) is None  # under half a pixel
    # in the image: a rate about x_C smears along v, one about y_C along u
    cam = CAMERAS["default"]
    p_WC, R_WC = _pose_over_pad(3.0, yaw_B=PLATFORM[1])  # pad edges aligned with the image axes
    sharp = Renderer(cam, grass, FalangaTag(), CLEAN, None).render(p_WC, R_WC, PLATFORM)
    blur = Renderer(cam, grass, FalangaTag(), RenderOptions(noise_sigma_dn=0, exposure_time_s=T), None)
    gv = lambda im: float(np.abs(np.diff(im.astype(float), axis=0)).sum())  # noqa: E731
    gu = lambda im: float(np.abs(np.diff(im.astype(float), axis=1)).sum())  # noqa: E731
    for w_C, smeared, kept in (([w, 0.0, 0.0], gv, gu), ([0.0, w, 0.0], gu, gv)):
        w_WB_B = MOUNT.R_BC @ np.array(w_C)  # the body rate that is w_C in the camera frame
        img = blur.render(p_WC, R_WC, PLATFORM, w_WB_B=w_WB_B)
        assert smeared(img) / smeared(sharp) < kept(img) / kept(sharp) - 0.1
        assert smeared(img) < 0.85 * smeared(sharp)
    np.testing.assert_array_equal(blur.render(p_WC, R_WC, PLATFORM), sharp)  # no rates, no blur


def test_bad_inputs(grass) -> None:
    cam = CAMERAS["default"]
    with pytest.raises(ValueError, match="rng"):
        Renderer(cam, grass, FalangaTag(), RenderOptions(noise_sigma_dn=1.0), None)
    for bad in ({"gamma": 0.0}, {"vignetting": 1.0}, {"max_range_m": -1.0}, {"noise_sigma_dn": math.nan}):
        with pytest.raises(ValueError):
            RenderOptions(**bad)
    with pytest.raises(ValueError):
        RenderOptions(shadow_polygon_P=((0.0, 0.0), (1.0, 0.0)))
    r = Renderer(cam, grass, FalangaTag(), CLEAN, None)
    p_WC, R_WC = _pose_over_pad(3.0)
    with pytest.raises(ValueError):
        r.render(np.array([0.0, np.nan, 1.0]), R_WC, PLATFORM)
    with pytest.raises(ValueError):
        r.render(p_WC, R_WC[:2], PLATFORM)
    with pytest.raises(ValueError):
        r.render(p_WC, R_WC, (PLATFORM[0], math.inf))
