"""Colour rendering, the red target, ground distractors, lighting, and cameras that see past 90 deg."""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass

import cv2
import numpy as np
import pytest

from alight.blockspec import NoContext
from alight.cameras import CameraMount, PinholeCamera, camera_pose_W
from alight.pads import PADS, AprilTagPad, FalangaTag, PadDesign, RedTarget
from alight.sim import render
from alight.sim.render import Renderer, RenderOptions
from alight.sim.textures import (
    GROUND_KINDS,
    DistractorSpec,
    GroundTexture,
    make_deck_texture,
    make_ground_texture,
)
from alight.types import quat_to_rotmat, rot_z

MOUNT = CameraMount.downward()
CLEAN = RenderOptions(noise_sigma_dn=0.0)
CLEAN_C = RenderOptions(noise_sigma_dn=0.0, color=True)
PLATFORM = (np.array([3.0, -2.0, 0.9]), 0.7)


@dataclass(frozen=True)
class _Equidistant:
    """A fisheye CameraModel (r = f theta inside an image circle, NaN rays outside it and inside an
    optional central hole), a frozen dataclass so the renderer's ray cache keys it by its parameters."""

    width: int = 640
    height: int = 480
    f: float = 150.0
    theta_max: float = 1.745
    hole_px: float = 0.0

    @property
    def c(self) -> np.ndarray:
        return np.array([(self.width - 1) / 2, (self.height - 1) / 2])

    def project(self, points_C: np.ndarray) -> np.ndarray:
        P = np.asarray(points_C, dtype=float)
        theta = np.arctan2(np.hypot(P[:, 0], P[:, 1]), P[:, 2])
        phi = np.arctan2(P[:, 1], P[:, 0])
        uv = self.c + (self.f * theta)[:, None] * np.stack([np.cos(phi), np.sin(phi)], axis=1)
        uv[(theta > self.theta_max) | (self.f * theta < self.hole_px)] = np.nan
        return uv

    def unproject(self, pixels: np.ndarray) -> np.ndarray:
        d = np.asarray(pixels, dtype=float) - self.c
        theta = np.hypot(d[:, 0], d[:, 1]) / self.f
        phi = np.arctan2(d[:, 1], d[:, 0])
        s = np.sin(theta)
        rays = np.stack([s * np.cos(phi), s * np.sin(phi), np.cos(theta)], axis=1)
        rays[(theta > self.theta_max) | (self.f * theta < self.hole_px)] = np.nan
        return rays


def _pose(p_WB, yaw=0.0, tilt=0.0):
    R_WB = rot_z(yaw) @ quat_to_rotmat(np.array([math.sin(tilt / 2), 0.0, 0.0, math.cos(tilt / 2)]))
    return camera_pose_W(np.asarray(p_WB, dtype=float), R_WB, MOUNT)


def _to_image(cam, p_WC, R_WC, pts_P, platform=PLATFORM):
    p_WP, yaw = platform
    X_W = np.asarray(pts_P) @ rot_z(yaw).T + p_WP
    return cam.project((X_W - p_WC) @ R_WC)


def _valid_pixels(cam) -> np.ndarray:
    v, u = np.mgrid[0 : cam.height, 0 : cam.width]
    rays = cam.unproject(np.stack([u.ravel(), v.ravel()], axis=1).astype(float))
    return np.isfinite(rays).all(axis=1).reshape(cam.height, cam.width)


def _polygon_area_centroid(uv: np.ndarray) -> tuple[float, np.ndarray]:
    """Area and centroid of the polygon with vertices uv (N, 2) (shoelace)."""
    x, y = uv[:, 0], uv[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    a = 0.5 * cross.sum()
    c = np.array([((x + xn) * cross).sum(), ((y + yn) * cross).sum()]) / (6.0 * a)
    return abs(float(a)), c


def _redness(img: np.ndarray, target: RedTarget) -> np.ndarray:
    """Per-pixel fraction of the red target: the renderer mixes target and background linearly (edge
    anti-aliasing, bilinear sampling), and R - G is 0 on the grey pad and deck, 160 on the target and
    negative on asphalt, so it reads the coverage back exactly."""
    fg, bg = target.target_bgr, target.background_bgr
    span = float((fg[2] - fg[1]) - (bg[2] - bg[1]))
    d = img[..., 2].astype(float) - img[..., 1].astype(float)
    return np.clip(d / span, 0.0, 1.0)


def _paper003_color_filter(img: np.ndarray, K: float = 1.0, C: float = 40.0) -> np.ndarray:
    """Paper 003 Alg. 1 and 2 (the red filter) on a BGR image: a binary mask."""
    B, G, R = (img[..., k].astype(float) for k in range(3))
    rr = R >= K * (G + B) + C
    gg = G >= K * (B + R) + C
    bb = B >= K * (R + G) + C
    temp = 0.6 * R < G
    return rr & ~gg & ~bb & ~temp


@pytest.fixture(scope="module")
def asphalt_c() -> GroundTexture:
    return make_ground_texture("asphalt", np.random.default_rng(21), size_px=512, color=True)


# ----------------------------------------------------------------------------------------- grey path


def _h(a: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()[:16]


# Hashes of grey outputs taken before colour rendering was added. They pin the grey path (pinhole
# cameras) byte for byte on this machine's kind (OpenCV and numba are deterministic on one CPU type; a
# machine with other SIMD units may round differently and then needs new values). Cameras that see past
# 90 deg changed on purpose (a mip level per ray; black outside the image circle after every effect).
GREY_HASHES = {
    "tex_grass": "1ec5e4aa49210840",
    "tex_asphalt": "b24e2060abfe2ebb",
    "tex_concrete": "b9d69a35c2112176",
    "deck_falanga": "a29c08173f465ac6",
    "render_noise_falanga": "72d7d86675ae22fe",
    "render_noise_april": "77f92eadcbed7330",
    "render_effects_falanga": "fe8a4a6157ef9472",
    "render_effects_april": "b057feebd069cb7f",
}


def test_grey_path_is_byte_identical_to_before() -> None:
    got = {}
    for kind in GROUND_KINDS:
        got["tex_" + kind] = _h(make_ground_texture(kind, np.random.default_rng(7), size_px=256).image)
    got["deck_falanga"] = _h(make_deck_texture(FalangaTag(), 200.0, rng=np.random.default_rng(0)).image)
    cam = PinholeCamera.default_downward()
    g = make_ground_texture("grass", np.random.default_rng(7), size_px=256)
    p_WC, R_WC = _pose(PLATFORM[0] + np.array([0.2, -0.15, 3.0]), yaw=1.1, tilt=0.3)
    opts = {
        "noise": RenderOptions(noise_sigma_dn=3.0),
        "effects": RenderOptions(
            noise_sigma_dn=2.0,
            exposure_time_s=0.01,
            exposure_gain=1.3,
            gamma=1.2,
            vignetting=0.3,
            shadow_polygon_P=((0.74, 0.74), (0.3, 0.74), (0.74, 0.3)),
        ),
    }
    w = np.array([0.3, -0.5, 0.2])
    for name, o in opts.items():
        for pad_name, pad in (("falanga", FalangaTag()), ("april", AprilTagPad())):
            r = Renderer(cam, g, pad, o, np.random.default_rng(3), R_BC=MOUNT.R_BC)
            frames = [r.render(p_WC, R_WC, PLATFORM, w_WB_B=w) for _ in range(2)]
            got[f"render_{name}_{pad_name}"] = _h(np.stack(frames))
    assert got == GREY_HASHES


def test_color_render_of_grey_textures_is_the_grey_render_in_three_channels() -> None:
    """Grey ground and grey pad in a colour image: every channel is the grey image (remap, pyrUp and the
    lookup table act per channel), with the same geometry, effects and sky."""
    g = make_ground_texture("grass", np.random.default_rng(3), size_px=256)
    cam = PinholeCamera.default_downward()
    for pose in (_pose(PLATFORM[0] + np.array([0.3, 0.2, 3.0]), 0.4, 0.2), _pose([0.0, 0.0, 2.0], 0.0, 1.4)):
        for kw in ({}, {"exposure_gain": 1.4, "gamma": 1.3, "vignetting": 0.2}):
            grey = Renderer(cam, g, FalangaTag(), RenderOptions(noise_sigma_dn=0, **kw)).render(
                *pose, PLATFORM
            )
            col = Renderer(cam, g, FalangaTag(), RenderOptions(noise_sigma_dn=0, color=True, **kw))
            img = col.render(*pose, PLATFORM)
            assert img.shape == (cam.height, cam.width, 3) and img.dtype == np.uint8
            for k in range(3):
                np.testing.assert_array_equal(img[..., k], grey)


# ----------------------------------------------------------------------------------------- textures


@pytest.mark.parametrize("kind", GROUND_KINDS)
def test_color_ground_is_the_grey_ground_tinted(kind: str) -> None:
    grey = make_ground_texture(kind, np.random.default_rng(5), size_px=256).image
    col = make_ground_texture(kind, np.random.default_rng(5), size_px=256, color=True)
    assert col.is_color and col.image.shape == (256, 256, 3) and col.image.dtype == np.uint8
    # the tints have unit luma: the colour tile's luma is the grey tile (rounding, and clipping of
    # saturated channels, aside)
    luma = cv2.cvtColor(col.image, cv2.COLOR_BGR2GRAY).astype(int)
    unclipped = np.all((col.image > 0) & (col.image < 255), axis=2)
    assert unclipped.mean() > 0.99
    assert np.max(np.abs(luma - grey)[unclipped]) <= 1
    b, g, r = (col.image[..., k].astype(float) for k in range(3))
    order = {"grass": g.mean() > r.mean() > b.mean(), "asphalt": b.mean() > g.mean() > r.mean()}
    order["concrete"] = r.mean() > g.mean() > b.mean()
    assert order[kind]
    # no ground texel looks red to paper 003's filter (its 0.6 R < G test rejects every one)
    assert not _paper003_color_filter(col.image, K=0.5, C=10.0).any()
    # the hue varies over the tile (two tints mixed by a smooth field), not one global tint
    ratio = cv2.blur(r / np.maximum(g, 1.0), (32, 32))
    assert ratio.max() - ratio.min() > 0.02
    # tileable like the grey one
    f = col.image.astype(float)
    seam = 0.5 * (np.abs(f[0] - f[-1]).mean() + np.abs(f[:, 0] - f[:, -1]).mean())
    inner = 0.5 * (np.abs(np.diff(f, axis=0)).mean() + np.abs(np.diff(f, axis=1)).mean())
    assert 0.7 < seam / inner < 1.3


def test_distractors_are_painted_where_they_are_listed() -> None:
    spec = DistractorSpec(count=5, size_m=0.5, shape="disc", color_jitter_dn=0.0)
    dim = DistractorSpec(count=5, size_m=0.5, shape="disc", color_jitter_dn=0.0, color_bgr=(40, 40, 100))
    m = 0.02
    tex, other = (
        make_ground_texture(
            "grass", np.random.default_rng(8), size_px=512, m_per_px=m, color=True, distractors=d
        )
        for d in (spec, dim)
    )
    assert len(tex.distractors) == 5
    np.testing.assert_array_equal(tex.distractor_centers_W(), other.distractor_centers_W())
    centers = tex.distractor_centers_W()
    T = tex.tile_m
    assert np.all((centers[:, 0] >= 0) & (centers[:, 0] < T) & (centers[:, 1] <= 0) & (centers[:, 1] > -T))
    # disjoint (periodic distance), so each one's painted area is a whole disc
    d = centers[:, None, :] - centers[None, :, :]
    d -= T * np.round(d / T)
    dist = np.hypot(d[..., 0], d[..., 1]) + np.eye(5) * 1e9
    assert dist.min() > spec.size_m + 0.1
    # coverage from the red channel: the same objects painted in two reds over the same ground differ
    # by the coverage times the difference of the reds
    cover = (tex.image[..., 2].astype(float) - other.image[..., 2]) / (200.0 - 100.0)
    area_px = math.pi * (spec.size_m / 2 / m) ** 2
    assert cover.sum() == pytest.approx(5 * area_px, rel=0.01)
    n = tex.size_px
    for (x, y), dis in zip(centers, tex.distractors, strict=True):
        u, v = x / m, -y / m  # texel coordinates (GroundTexture.texel_of_W)
        assert tuple(tex.image[int(round(v)) % n, int(round(u)) % n]) == (40, 40, 200)
        assert dis.color_bgr == (40, 40, 200) and dis.shape == "disc" and dis.length_m == 0.5
        # the disc's texels lie within its radius (periodically), the paint's centroid is its centre
        vv, uu = np.mgrid[0:n, 0:n]
        du = (uu - u + n / 2) % n - n / 2
        dv = (vv - v + n / 2) % n - n / 2
        near = np.hypot(du, dv) < 0.5 * spec.size_m / m + 1.5
        w = cover * near
        assert w.sum() == pytest.approx(area_px, rel=0.01)
        assert abs((w * du).sum() / w.sum()) < 0.05 and abs((w * dv).sum() / w.sum()) < 0.05
        assert cover[~near & (np.hypot(du, dv) < 0.5 * spec.size_m / m + 6)].max() == 0


def test_distractors_wrap_around_the_tile() -> None:
    """A disc cut by the tile's edge continues on the other side: its whole area is painted, centred
    (periodically) on its listed centre."""
    m, n, size = 0.02, 64, 0.5
    spec = DistractorSpec(count=1, size_m=size, shape="disc", color_jitter_dn=0.0)
    dim = DistractorSpec(count=1, size_m=size, shape="disc", color_jitter_dn=0.0, color_bgr=(40, 40, 100))
    straddling = 0
    for seed in range(6):
        tex, other = (
            make_ground_texture("asphalt", np.random.default_rng(seed), size_px=n, color=True, distractors=d)
            for d in (spec, dim)
        )
        cover = (tex.image[..., 2].astype(float) - other.image[..., 2]) / (200.0 - 100.0)
        u, v = tex.distractor_centers_W()[0] * [1 / m, -1 / m]
        r_px = size / 2 / m
        straddling += int(min(u, n - u, v, n - v) < r_px)
        assert cover.sum() == pytest.approx(math.pi * r_px**2, rel=0.01)
        vv, uu = np.mgrid[0:n, 0:n]
        du, dv = (uu - u + n / 2) % n - n / 2, (vv - v + n / 2) % n - n / 2
        assert abs((cover * du).sum() / cover.sum()) < 0.05 and abs((cover * dv).sum() / cover.sum()) < 0.05
    assert straddling >= 3


def test_distractor_shapes_colours_and_determinism() -> None:
    spec = DistractorSpec(count=60, size_m=0.4, shape="mixed", aspect=2.5)
    a = make_ground_texture("concrete", np.random.default_rng(2), size_px=128, color=True, distractors=spec)
    shapes = {d.shape for d in a.distractors}
    assert shapes == {"disc", "rect"}
    assert all(d.width_m == pytest.approx(0.4 / 2.5) for d in a.distractors if d.shape == "rect")
    jit = np.array([d.color_bgr for d in a.distractors], dtype=float) - [40, 40, 200]
    assert np.all(np.abs(jit) <= 25) and jit.std() > 5
    from alight.sim import textures

    textures._GROUND_CACHE.clear()
    b = make_ground_texture("concrete", np.random.default_rng(2), size_px=128, color=True, distractors=spec)
    assert b is not a and b.distractors == a.distractors
    np.testing.assert_array_equal(a.image, b.image)
    # positions do not depend on the shape setting; a grey tile holds the luma of the same objects
    discs = make_ground_texture(
        "concrete", np.random.default_rng(2), size_px=128, color=True,
        distractors=DistractorSpec(count=60, size_m=0.4, shape="disc", aspect=2.5),
    )  # fmt: skip
    np.testing.assert_array_equal(discs.distractor_centers_W(), a.distractor_centers_W())
    grey = make_ground_texture("concrete", np.random.default_rng(2), size_px=128, distractors=spec)
    assert grey.image.ndim == 2
    np.testing.assert_array_equal(grey.distractor_centers_W(), a.distractor_centers_W())
    luma = cv2.cvtColor(a.image, cv2.COLOR_BGR2GRAY).astype(int)
    assert np.mean(np.abs(luma - grey.image)) < 0.6


def test_distractor_centers_near_a_point_cover_every_tile_copy() -> None:
    spec = DistractorSpec(count=7, size_m=0.3)
    tex = make_ground_texture("grass", np.random.default_rng(4), size_px=64, color=True, distractors=spec)
    T = tex.tile_m  # 1.28 m
    c, radius = np.array([-13.7, 40.2]), 3.1
    got = tex.distractor_centers_W(c, radius)
    idx = tex.distractor_index_W(c, radius)
    base = tex.distractor_centers_W()
    # brute force over a wide range of tile shifts
    k = np.arange(-60, 61)
    allpts = (base[:, None, None, :] + T * np.stack(np.meshgrid(k, k, indexing="ij"), -1)[None]).reshape(
        -1, 2
    )
    allidx = np.repeat(np.arange(7), len(k) ** 2)
    keep = np.hypot(*(allpts - c).T) <= radius
    assert len(got) == keep.sum() > 7
    order = np.lexsort(got.T)
    ref = np.lexsort(allpts[keep].T)
    np.testing.assert_allclose(got[order], allpts[keep][ref], atol=1e-9)
    np.testing.assert_array_equal(idx[order], allidx[keep][ref])
    with pytest.raises(ValueError):
        tex.distractor_centers_W(c, -1.0)


def test_distractor_spec_validation() -> None:
    for bad in (
        {"count": -1},
        {"count": 2.5},
        {"size_m": 0.0},
        {"shape": "star"},
        {"aspect": 0.5},
        {"color_bgr": (0, 0, 256)},
        {"color_jitter_dn": -1.0},
    ):
        with pytest.raises(ValueError):
            DistractorSpec(**bad)
    with pytest.raises(ValueError):  # larger than the tile
        make_ground_texture(
            "grass", np.random.default_rng(0), size_px=16, distractors=DistractorSpec(size_m=1.0)
        )
    with pytest.raises(ValueError):
        make_ground_texture("grass", np.random.default_rng(0), size_px=16, distractors=(1, 2))  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        GroundTexture(np.zeros((4, 4, 2), np.uint8), 0.02)


# ----------------------------------------------------------------------------------------- red target


def test_red_target_texture_matches_its_geometry() -> None:
    for t in (RedTarget(), RedTarget(size_m=1.2, target_radius_m=0.35, shape="square")):
        assert isinstance(t, PadDesign)
        s_req = 200.0
        tex = t.texture(s_req)
        n = round(t.size_m * s_req)
        assert tex.shape == (n, n, 3) and tex.dtype == np.uint8
        s = n / t.size_m
        H = t.texture_homography_P_to_px(s_req)
        # coverage read back from the red channel integrates to the shape's area
        w = (tex[..., 2].astype(float) - 150.0) / 50.0
        assert w.sum() / s**2 == pytest.approx(t.target_area_m2, rel=2e-3)
        # pixels more than a pixel inside or outside the boundary are exactly target or background
        v, u = np.mgrid[0:n, 0:n]
        x, y = t.size_m / 2 - (v + 0.5) / s, t.size_m / 2 - (u + 0.5) / s
        r = t.target_radius_m
        inside = (
            np.hypot(x, y) < r - 1.5 / s if t.shape == "disc" else np.maximum(abs(x), abs(y)) < r - 1.5 / s
        )
        outside = (
            np.hypot(x, y) > r + 1.5 / s if t.shape == "disc" else np.maximum(abs(x), abs(y)) > r + 1.5 / s
        )
        assert np.all(tex[inside] == t.target_bgr) and np.all(tex[outside] == t.background_bgr)
        # the centroid is the pad centre, at the texture's centre (H maps P (0, 0) to it)
        c = H @ [0.0, 0.0, 1.0]
        assert (w * u).sum() / w.sum() == pytest.approx(c[0], abs=1e-6)
        assert (w * v).sum() / w.sum() == pytest.approx(c[1], abs=1e-6)
        out = t.target_outline_P(40)
        assert out.shape == (40, 3) and np.allclose(out[0], [r, 0, 0])
        area, cen = _polygon_area_centroid(out[:, :2])
        assert np.allclose(cen, 0.0, atol=1e-12)
        assert _polygon_area_centroid(out[:, :2])[0] > 0
        assert area == pytest.approx(t.target_area_m2, rel=0.01 if t.shape == "disc" else 1e-12)
    assert PADS["red_target"].build_default(NoContext()) == RedTarget.default(1.5)
    assert RedTarget.default(3.0).target_radius_m == 1.0
    # the default red passes paper 003's filter, the grey background does not
    tex = RedTarget().texture(20.0)
    mask = _paper003_color_filter(tex)
    assert mask[15, 15] and not mask[0, 0]


def test_red_target_validation() -> None:
    for bad in (
        {"size_m": 0.0},
        {"target_radius_m": 0.8},  # larger than half the 1.5 m pad
        {"shape": "cross"},
        {"target_bgr": (0, 0, 300)},
        {"background_bgr": (1, 2)},
        {"target_radius_m": math.nan},
    ):
        with pytest.raises(ValueError):
            RedTarget(**bad)
    with pytest.raises(ValueError):
        RedTarget().target_outline_P(3)


def test_colour_pad_in_a_grey_render_is_its_luma(asphalt_c) -> None:
    cam = PinholeCamera.default_downward()
    p_WC, R_WC = _pose(PLATFORM[0] + np.array([0.1, 0.1, 2.5]), yaw=0.2)
    img = Renderer(cam, asphalt_c, RedTarget(), CLEAN).render(p_WC, R_WC, PLATFORM)
    assert img.ndim == 2
    luma = 0.114 * 40 + 0.587 * 40 + 0.299 * 200
    val = img[tuple(np.rint(_to_image(cam, p_WC, R_WC, np.zeros((1, 3)))[0, ::-1]).astype(int))]
    assert val == pytest.approx(luma, abs=1)


# ----------------------------------------------------------------------------------------- geometry


def _red_blob(img: np.ndarray, target: RedTarget) -> tuple[float, np.ndarray]:
    w = _redness(img, target)
    v, u = np.mgrid[0 : img.shape[0], 0 : img.shape[1]]
    return float(w.sum()), np.array([(w * u).sum(), (w * v).sum()]) / w.sum()


@pytest.mark.parametrize("shape", ["disc", "square"])
def test_red_target_centroid_projects_to_the_pad_centre(asphalt_c, shape: str) -> None:
    """From above (image plane parallel to the deck) the map from deck to image is affine up to the lens
    distortion, so the red area's centroid is the projected pad centre; its area and centroid also equal
    those of the projected outline."""
    target = RedTarget(shape=shape)
    default = PinholeCamera.default_downward()
    ideal = PinholeCamera(default.width, default.height, default.K)  # no lens distortion: affine
    for cam in (ideal, default):
        r = Renderer(cam, asphalt_c, target, CLEAN_C)
        for offset, yaw, h in (((0.0, 0.0), 0.3, 4.0), ((1.2, -0.8), 1.9, 5.0), ((0.4, 0.9), -0.6, 2.5)):
            p_WC, R_WC = _pose(PLATFORM[0] + np.array([*offset, h]), yaw=yaw)
            img = r.render(p_WC, R_WC, PLATFORM)
            area, cen = _red_blob(img, target)
            truth = _to_image(cam, p_WC, R_WC, np.zeros((1, 3)))[0]
            if cam is ideal:  # lens distortion bends the blob: its centroid moves off the centre's image
                assert np.linalg.norm(cen - truth) < 0.05, (cen, truth)
            outline = _to_image(cam, p_WC, R_WC, target.target_outline_P(720))
            poly_area, poly_cen = _polygon_area_centroid(outline)
            assert area == pytest.approx(poly_area, rel=0.01)
            assert np.linalg.norm(cen - poly_cen) < 0.05
            # what paper 003's filter finds: the largest red contour, centred on the pad
            mask = _paper003_color_filter(img).astype(np.uint8)
            n, labels, stats, cents = cv2.connectedComponentsWithStats(mask)
            k = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
            assert np.linalg.norm(cents[k] - poly_cen) < 0.6


def _camera_looking_at(p_WC: np.ndarray, target_W: np.ndarray, off_axis: float) -> np.ndarray:
    """R_WC whose optical axis is ``off_axis`` (rad) from the direction to ``target_W``, tilted upward."""
    d = target_W - p_WC
    d /= np.linalg.norm(d)
    up = np.array([0.0, 0.0, 1.0])
    e = up - (up @ d) * d
    e /= np.linalg.norm(e)
    z = math.cos(off_axis) * d + math.sin(off_axis) * e
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=1)


@pytest.mark.parametrize("off_axis_deg", [0.0, 65.0, 100.0])
def test_fisheye_sees_the_red_target_far_off_axis(asphalt_c, off_axis_deg: float) -> None:
    """Through a 200 deg equidistant fisheye the red area's centroid and area are those of the projected
    outline, also past 90 deg off the optical axis (behind the image plane)."""
    cam = _Equidistant(f=115.0, theta_max=math.radians(115.0))  # a 230 deg image circle
    target = RedTarget()
    r = Renderer(cam, asphalt_c, target, CLEAN_C)
    p_WC = PLATFORM[0] + np.array([-2.0, 1.0, 2.2])
    R_WC = _camera_looking_at(p_WC, PLATFORM[0], math.radians(off_axis_deg))
    ray = (PLATFORM[0] - p_WC) @ R_WC
    assert math.degrees(math.acos(ray[2] / np.linalg.norm(ray))) == pytest.approx(off_axis_deg, abs=1e-6)
    img = r.render(p_WC, R_WC, PLATFORM)
    area, cen = _red_blob(img, target)
    poly_area, poly_cen = _polygon_area_centroid(_to_image(cam, p_WC, R_WC, target.target_outline_P(720)))
    assert poly_area > 200
    assert area == pytest.approx(poly_area, rel=0.02)
    assert np.linalg.norm(cen - poly_cen) < 0.15
    truth = _to_image(cam, p_WC, R_WC, np.zeros((1, 3)))[0]
    assert np.linalg.norm(cen - truth) < 2.0  # the lens bends the disc's image: close, not exact


def test_pixels_without_a_ray_are_black_and_rays_upward_see_the_sky(asphalt_c) -> None:
    cam = _Equidistant()
    valid = _valid_pixels(cam)
    sky = (230, 200, 170)
    opt = RenderOptions(
        color=True, noise_sigma_dn=3.0, exposure_time_s=0.02, vignetting=0.3, sky_bgr=sky, gamma=0.8
    )
    r = Renderer(cam, asphalt_c, RedTarget(), opt, np.random.default_rng(0), R_BC=MOUNT.R_BC)
    p_WC = np.array([0.0, 0.0, 3.0])
    R_WC = _camera_looking_at(p_WC, np.array([10.0, 0.0, 3.0]), 0.0)  # optical axis horizontal
    img = r.render(p_WC, R_WC, PLATFORM, w_WB_B=np.array([0.0, 2.0, 0.0]))
    assert np.all(img[~valid] == 0)
    assert np.mean(np.any(img[valid] > 0, axis=1)) > 0.999
    clean = Renderer(cam, asphalt_c, RedTarget(), RenderOptions(color=True, noise_sigma_dn=0, sky_bgr=sky))
    img = clean.render(p_WC, R_WC, PLATFORM)
    assert np.all(img[~valid] == 0)
    v, u = np.mgrid[0 : cam.height, 0 : cam.width]
    d_W = cam.unproject(np.stack([u.ravel(), v.ravel()], axis=1).astype(float)) @ R_WC.T
    # away from the horizon and the circle's rim, where the half-resolution ground's upsampling blends
    # the sky with the ground and with the black outside (2 px)
    rim = cv2.erode(valid.astype(np.uint8), np.ones((9, 9), np.uint8)) == 0
    up = (d_W[:, 2] > 0.05).reshape(valid.shape) & ~rim
    assert up.sum() > 20000
    assert np.all(img[up] == sky)
    down = (d_W[:, 2] < -0.3).reshape(valid.shape)
    assert np.all(np.abs(img[down].astype(int) - sky).sum(axis=1) > 30)


def test_wide_camera_takes_a_mip_level_per_ray() -> None:
    """Through a fisheye the ground runs from the nadir to the horizon. A checkerboard of 16 cm squares
    stays sharp below the camera and averages to grey far away (one level for the whole frame would
    alias it into random black and white there)."""
    n, m = 256, 0.02
    v, u = np.mgrid[0:n, 0:n]
    checker = np.where(((u // 8) + (v // 8)) % 2 == 0, 255, 0).astype(np.uint8)
    ground = GroundTexture(checker, m)
    cam = _Equidistant()
    r = Renderer(cam, ground, FalangaTag(), CLEAN)
    assert r._atlas is not None
    p_WC, R_WC = _pose([0.37, -0.21, 6.0])
    img = r.render(p_WC, R_WC, (np.array([900.0, 0.0, 0.9]), 0.0)).astype(float)
    pix = np.stack(np.meshgrid(np.arange(cam.width), np.arange(cam.height)), -1).reshape(-1, 2).astype(float)
    a = -(cam.unproject(pix) @ R_WC.T)[:, 2].reshape(img.shape)  # cos of the angle to the nadir
    near, far = a > 0.95, (a > 0.05) & (a < 0.3)  # within 18 deg of the nadir; 73 to 87 deg from it
    assert near.sum() > 5000 and far.sum() > 5000
    assert img[near].std() > 60
    assert np.mean(np.abs(img[far] - 127.5) < 20) > 0.98


def test_ground_maps_mip_matches_the_level_of_each_ray() -> None:
    """Per ray, the kernel's atlas coordinates are those of the level whose texel is just below the ray's
    footprint (``Renderer._level``), wrapped into that level's block."""
    g = make_ground_texture("grass", np.random.default_rng(0), size_px=256)
    levels, _ = render._ground_pyramid(g, 200)
    at = render._ground_atlas(levels)
    n0 = 256
    assert at.image.shape == (n0 + 7, int(sum(at.size + 1)))
    for k, lev in enumerate(levels):  # each block is its level's extended tile
        o, nk = int(at.off[k]), int(at.size[k])
        np.testing.assert_array_equal(at.image[: nk + 1, o : o + nk + 1], lev.image[: nk + 1])
    rng = np.random.default_rng(1)
    d = rng.standard_normal((4000, 3))
    d[:, 2] = -np.abs(d[:, 2]) - 0.05
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    h, pa = 7.0, 0.004
    p_WC, R_WC = np.array([0.31, -0.77, h]), np.eye(3)
    N = np.array([[-h, 0.0, p_WC[0]], [0.0, -h, p_WC[1]], [0.0, 0.0, 1.0]])
    M = (levels[0].H @ N @ R_WC).astype(np.float32).ravel()
    K = 2.0 * pa * h
    thr = ((K / at.texel_m) ** (2.0 / 3.0)).astype(np.float32)
    rx, ry, rz = (np.ascontiguousarray(d[:, i], dtype=np.float32) for i in range(3))
    mx, my = np.empty(len(d), np.float32), np.empty(len(d), np.float32)
    render._ground_maps_mip(rx, ry, rz, M, np.float32(h / 100.0), thr, at.inv_f, at.size, at.off, n0, mx, my)
    hits = p_WC[:2] + (h / -d[:, 2])[:, None] * d[:, :2]
    foot = K / (-d[:, 2]) ** 1.5
    far = h / -d[:, 2] > 100.0  # beyond the haze range
    assert far.sum() > 10 and np.all(my[far] == n0 + 3.5)
    checked = 0
    for i in np.flatnonzero(~far):
        k = max(j for j in range(len(levels)) if j == 0 or levels[j].texel_m <= foot[i] * (1 - 1e-5))
        if abs(foot[i] - levels[k].texel_m) < 1e-4 * foot[i] or (
            k + 1 < len(levels) and abs(foot[i] - levels[k + 1].texel_m) < 1e-4 * foot[i]
        ):
            continue  # at a level boundary float32 may pick either
        uvw = levels[k].H @ [hits[i, 0], hits[i, 1], 1.0]
        nk = at.size[k]
        want = np.array([uvw[0] % nk + at.off[k], uvw[1] % nk])
        got = np.array([mx[i], my[i]])
        # wrapped coordinates agree modulo the tile (a hit on the seam may land at 0 or at nk)
        dd = got - want
        dd[1] -= nk * np.round(dd[1] / nk)
        dd[0] -= nk * np.round(dd[0] / nk)
        assert np.all(np.abs(dd) < 0.02), (i, k, got, want)
        assert at.off[k] <= got[0] <= at.off[k] + nk
        checked += 1
    assert checked > 3000


def test_camera_without_a_centre_ray_renders() -> None:
    """A camera with no ray at the image centre (a catadioptric mirror's hole) takes its pixel angle
    next to the hole, and the hole is black."""
    cam = _Equidistant(hole_px=20.0)
    rays = render._unproject_grid(cam, True)
    assert rays[6] == pytest.approx(1.0 / cam.f, rel=1e-3)
    g = make_ground_texture("grass", np.random.default_rng(0), size_px=128, color=True)
    img = Renderer(cam, g, RedTarget(), CLEAN_C).render(*_pose([0.0, 0.0, 5.0]), PLATFORM)
    assert np.all(img[~_valid_pixels(cam)] == 0)
    assert np.all(img[int(cam.c[1]), int(cam.c[0])] == 0)


def test_distractors_appear_red_where_they_project(asphalt_c) -> None:
    spec = DistractorSpec(count=20, size_m=0.6, shape="disc", color_jitter_dn=15.0)
    g = make_ground_texture("grass", np.random.default_rng(30), size_px=512, color=True, distractors=spec)
    cam = PinholeCamera.default_downward()
    far = (np.array([500.0, 500.0, 0.9]), 0.0)
    p_WC, R_WC = _pose([4.0, -6.0, 12.0], yaw=0.5)
    img = Renderer(cam, g, RedTarget(), CLEAN_C).render(p_WC, R_WC, far)
    pts = g.distractor_centers_W(p_WC[:2], 40.0)
    uv = cam.project(np.c_[pts, np.zeros(len(pts))] @ R_WC - p_WC @ R_WC)
    inside = np.all(np.isfinite(uv) & (uv > 3) & (uv < [cam.width - 4, cam.height - 4]), axis=1)
    assert inside.sum() >= 5
    mask = _paper003_color_filter(img)
    for p in uv[inside]:
        assert mask[int(round(p[1])), int(round(p[0]))]
    # and every red blob is one of them (or a part of one cut by the image border): no false red
    n, labels, stats, cents = cv2.connectedComponentsWithStats(mask.astype(np.uint8))
    finite = uv[np.all(np.isfinite(uv), axis=1)]
    radius_px = 0.5 * spec.size_m / (12.0 / 400.0)
    for c in cents[1:]:
        assert np.min(np.linalg.norm(finite - c, axis=1)) < radius_px


# ----------------------------------------------------------------------------------------- effects


def test_color_exposure_illumination_and_gamma_per_channel(asphalt_c) -> None:
    cam = PinholeCamera.default_downward()
    p_WC, R_WC = _pose(PLATFORM[0] + np.array([0.3, -0.2, 3.0]), yaw=0.9)
    base = Renderer(cam, asphalt_c, RedTarget(), CLEAN_C).render(p_WC, R_WC, PLATFORM).astype(float)
    gains, gamma, expo = (1.25, 1.0, 0.7), 1.4, 1.1
    opt = RenderOptions(
        noise_sigma_dn=0, color=True, illumination_gain_bgr=gains, gamma=gamma, exposure_gain=expo
    )
    img = Renderer(cam, asphalt_c, RedTarget(), opt).render(p_WC, R_WC, PLATFORM).astype(float)
    for k, gk in enumerate(gains):
        want = 255.0 * np.clip(base[..., k] / 255.0 * expo * gk, 0.0, 1.0) ** gamma
        np.testing.assert_allclose(img[..., k], want, atol=0.5 + 1e-9)
    # a cold light weakens the red channel: the target's redness drops
    assert img[..., 2].mean() < base[..., 2].mean()
    # a grey image takes the illumination's luma
    grey = Renderer(cam, asphalt_c, RedTarget(), RenderOptions(noise_sigma_dn=0)).render(p_WC, R_WC, PLATFORM)
    lit = Renderer(cam, asphalt_c, RedTarget(), RenderOptions(noise_sigma_dn=0, illumination_gain_bgr=gains))
    luma = float(np.dot(gains, (0.114, 0.587, 0.299)))
    want = np.clip(np.rint(grey.astype(float) * luma), 0, 255)
    np.testing.assert_allclose(lit.render(p_WC, R_WC, PLATFORM), want, atol=1)


def test_brightness_drift_follows_its_sine(asphalt_c) -> None:
    cam = PinholeCamera.default_downward()
    pose = _pose(PLATFORM[0] + np.array([0.3, -0.2, 3.0]), yaw=0.9)
    A, T = 0.3, 40.0
    for color in (False, True):
        r = Renderer(cam, asphalt_c, RedTarget(), RenderOptions(noise_sigma_dn=0, color=color,
                     brightness_drift=A, brightness_drift_period_s=T))  # fmt: skip
        base = Renderer(cam, asphalt_c, RedTarget(), RenderOptions(noise_sigma_dn=0, color=color))
        ref = base.render(*pose, PLATFORM)
        np.testing.assert_array_equal(r.render(*pose, PLATFORM), ref)  # no time: no drift
        np.testing.assert_array_equal(r.render(*pose, PLATFORM, t_s=0.0), ref)
        for t in (T / 4, 3 * T / 4, 7.0):
            g = 1.0 + A * math.sin(2 * math.pi * t / T)
            same = Renderer(cam, asphalt_c, RedTarget(), RenderOptions(noise_sigma_dn=0, color=color,
                            exposure_gain=g))  # fmt: skip
            np.testing.assert_array_equal(r.render(*pose, PLATFORM, t_s=t), same.render(*pose, PLATFORM))
        with pytest.raises(ValueError):
            r.render(*pose, PLATFORM, t_s=math.nan)


def test_color_noise_is_independent_per_channel(asphalt_c) -> None:
    cam = PinholeCamera.default_downward()
    pose = _pose([0.0, 0.0, 6.0])
    far = (np.array([500.0, 0.0, 0.9]), 0.0)
    clean = Renderer(cam, asphalt_c, RedTarget(), CLEAN_C).render(*pose, far).astype(float)
    noisy = Renderer(cam, asphalt_c, RedTarget(), RenderOptions(noise_sigma_dn=4.0, color=True),
                     np.random.default_rng(1)).render(*pose, far)  # fmt: skip
    d = noisy.astype(float) - clean
    inner = np.all((clean > 20) & (clean < 235), axis=2)
    for k in range(3):
        assert abs(d[inner, k].mean()) < 0.1 and d[inner, k].std() == pytest.approx(4.0, rel=0.05)
    c = np.corrcoef(d[inner].T)
    assert np.max(np.abs(c - np.eye(3))) < 0.02


def test_render_options_validation() -> None:
    for bad in (
        {"illumination_gain_bgr": (1.0, 0.0, 1.0)},
        {"illumination_gain_bgr": (1.0, 1.0)},
        {"illumination_gain_bgr": (1.0, math.inf, 1.0)},
        {"sky_bgr": (0, 0, 256)},
        {"sky_bgr": (1, 2)},
        {"brightness_drift": 1.0},
        {"brightness_drift": -0.1},
        {"brightness_drift_period_s": 0.0},
    ):
        with pytest.raises(ValueError):
            RenderOptions(**bad)
    a = RenderOptions(illumination_gain_bgr=[1, 2, 3], sky_bgr=np.array([1, 2, 3]))  # type: ignore[arg-type]
    assert a.illumination_gain_bgr == (1.0, 2.0, 3.0) and a.sky_bgr == (1, 2, 3)
    hash(a)


# ----------------------------------------------------------------------------------------- OmniCamera


def test_omni_camera_renders_the_red_target_off_axis(asphalt_c) -> None:
    omni = pytest.importorskip("alight.cameras.omni")
    if not hasattr(omni.OmniCamera, "synthetic"):
        pytest.skip("OmniCamera has no synthetic constructor")
    cam = omni.OmniCamera.synthetic(640, 480, fov_deg=186.0)
    target = RedTarget()
    r = Renderer(
        cam, asphalt_c, target, RenderOptions(color=True, noise_sigma_dn=2.0), np.random.default_rng(0)
    )
    valid = _valid_pixels(cam)
    for off_axis_deg in (0.0, 65.0, 80.0):  # the whole disc inside the 186 deg circle
        p_WC = PLATFORM[0] + np.array([-2.0, 1.0, 2.2])
        R_WC = _camera_looking_at(p_WC, PLATFORM[0], math.radians(off_axis_deg))
        img = r.render(p_WC, R_WC, PLATFORM)
        assert np.all(img[~valid] == 0)
        mask = _paper003_color_filter(img).astype(np.uint8)
        n, labels, stats, cents = cv2.connectedComponentsWithStats(mask)
        k = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
        poly_area, poly_cen = _polygon_area_centroid(_to_image(cam, p_WC, R_WC, target.target_outline_P(720)))
        assert np.linalg.norm(cents[k] - poly_cen) < 1.0
        assert stats[k, cv2.CC_STAT_AREA] == pytest.approx(poly_area, rel=0.15)
