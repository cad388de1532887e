"""The renderer's per-camera ray cache and the ground-texture cache: a hit must be indistinguishable from
building anew (same rays, same texture, the generator left in the same state), and both stay bounded."""

from __future__ import annotations

import numpy as np

from alight.cameras import CameraMount, PinholeCamera, camera_pose_W
from alight.pads import FalangaTag
from alight.sim import render, textures
from alight.sim.render import Renderer, RenderOptions
from alight.sim.textures import make_ground_texture
from alight.types import rot_z


def _small_camera(f: float = 60.0, k1: float = -0.05) -> PinholeCamera:
    K = np.array([[f, 0.0, 31.5], [0.0, f, 23.5], [0.0, 0.0, 1.0]])
    return PinholeCamera(64, 48, K, np.array([k1, 0.0, 0.0, 0.0, 0.0]))


def test_equal_cameras_share_rays_and_different_ones_do_not() -> None:
    a, b = _small_camera(), _small_camera()
    assert a is not b
    ra = render._camera_rays(a, True)
    rb = render._camera_rays(b, True)
    assert all(x is y for x, y in zip(ra[:6], rb[:6], strict=True))  # one entry for equal parameters
    fresh = render._unproject_grid(b, True)
    for x, y in zip(ra[:6], fresh[:6], strict=True):
        np.testing.assert_array_equal(x, y)
    assert ra[6] == fresh[6]
    rc = render._camera_rays(_small_camera(k1=-0.06), True)  # other distortion: other rays
    assert not np.array_equal(rc[0], ra[0])
    rd = render._camera_rays(_small_camera(f=61.0), True)
    assert not np.array_equal(rd[0], ra[0]) and rd[6] != ra[6]


def test_ray_cache_is_bounded_and_keeps_recent_entries() -> None:
    cams = [_small_camera(f=50.0 + i) for i in range(render._RAY_CACHE_SIZE + 3)]
    for c in cams:
        render._camera_rays(c, True)
    assert len(render._RAY_CACHE) == render._RAY_CACHE_SIZE
    last = render._camera_rays(cams[-1], True)
    assert render._camera_rays(_small_camera(f=50.0 + len(cams) - 1), True)[0] is last[0]


def test_camera_without_parameter_key_is_cached_by_object() -> None:
    class Plain:  # a CameraModel that is not a frozen dataclass
        def __init__(self) -> None:
            self.inner = _small_camera()
            self.width, self.height = 64, 48

        def project(self, p: np.ndarray) -> np.ndarray:
            return self.inner.project(p)

        def unproject(self, uv: np.ndarray) -> np.ndarray:
            return self.inner.unproject(uv)

    cam = Plain()
    assert render._camera_key(cam) is None
    r1 = render._camera_rays(cam, True)
    assert render._camera_rays(cam, True)[0] is r1[0]
    assert render._camera_rays(Plain(), True)[0] is not r1[0]
    np.testing.assert_array_equal(render._camera_rays(Plain(), True)[0], r1[0])


def test_renderers_of_equal_cameras_render_the_same_image() -> None:
    ground = make_ground_texture("grass", np.random.default_rng(3), size_px=256)
    pad = FalangaTag.default(1.5)
    p_WC, R_WC = camera_pose_W(np.array([0.3, -0.2, 3.0]), rot_z(0.4), CameraMount.downward())
    pose = (np.array([0.0, 0.0, 0.5]), 0.3)
    rngs = [np.random.default_rng(9), np.random.default_rng(9)]
    opt = RenderOptions()
    images = [Renderer(_small_camera(), ground, pad, opt, g).render(p_WC, R_WC, pose) for g in rngs]
    np.testing.assert_array_equal(images[0], images[1])


def test_ground_texture_cache_hit_leaves_the_generator_as_a_fresh_draw_would() -> None:
    textures._GROUND_CACHE.clear()
    rng1 = np.random.default_rng(11)
    t1 = make_ground_texture("asphalt", rng1, size_px=128)
    after1 = rng1.standard_normal(5)
    rng2 = np.random.default_rng(11)
    t2 = make_ground_texture("asphalt", rng2, size_px=128)  # a hit
    assert t2 is t1 and not t2.image.flags.writeable
    np.testing.assert_array_equal(rng2.standard_normal(5), after1)
    # anything else in the key makes a miss: kind, size, texel size, generator state
    assert make_ground_texture("grass", np.random.default_rng(11), size_px=128) is not t1
    assert make_ground_texture("asphalt", np.random.default_rng(11), size_px=64) is not t1
    assert make_ground_texture("asphalt", np.random.default_rng(11), size_px=128, m_per_px=0.03) is not t1
    rng3 = np.random.default_rng(11)
    rng3.random()
    assert make_ground_texture("asphalt", rng3, size_px=128) is not t1


def test_ground_texture_cache_is_bounded() -> None:
    textures._GROUND_CACHE.clear()
    for seed in range(textures._GROUND_CACHE_SIZE + 2):
        make_ground_texture("concrete", np.random.default_rng(seed), size_px=64)
    assert len(textures._GROUND_CACHE) == textures._GROUND_CACHE_SIZE
