"""Procedural ground textures and the platform deck."""

from __future__ import annotations

import numpy as np
import pytest

from alight.pads import AprilTagPad, FalangaTag
from alight.sim import textures
from alight.sim.textures import (
    GROUND_KINDS,
    GroundTexture,
    _periodic_upsample,
    fractal_noise,
    make_deck_texture,
    make_ground_texture,
)


def test_periodic_upsample_is_shift_equivariant() -> None:
    """Upsampling a rolled grid equals rolling the upsampled one: the result is periodic on the tile."""
    cells = np.random.default_rng(0).standard_normal((8, 8)).astype(np.float32)
    up = _periodic_upsample(cells, 64)
    up_rolled = _periodic_upsample(np.roll(cells, (3, -2), axis=(0, 1)), 64)
    np.testing.assert_allclose(up_rolled, np.roll(up, (3 * 8, -2 * 8), axis=(0, 1)), atol=1e-5)
    assert float(up.mean()) == pytest.approx(float(cells.mean()), abs=1e-3)


def test_fractal_noise_normalised() -> None:
    a = fractal_noise(np.random.default_rng(1), 256)
    assert a.dtype == np.float32 and a.shape == (256, 256)
    assert abs(float(a.mean())) < 1e-5 and float(a.std()) == pytest.approx(1.0, rel=1e-4)
    with pytest.raises(ValueError):
        fractal_noise(np.random.default_rng(1), 100)


def _seam_ratio(img: np.ndarray) -> float:
    """Mean jump across the wrap-around seam over the mean jump between interior neighbours."""
    f = img.astype(float)
    seam = 0.5 * (np.abs(f[0] - f[-1]).mean() + np.abs(f[:, 0] - f[:, -1]).mean())
    inner = 0.5 * (np.abs(np.diff(f, axis=0)).mean() + np.abs(np.diff(f, axis=1)).mean())
    return float(seam / inner)


@pytest.mark.parametrize("kind", GROUND_KINDS)
def test_ground_textures_tile_and_are_deterministic(kind: str) -> None:
    g = make_ground_texture(kind, np.random.default_rng(4), size_px=512, m_per_px=0.03)
    assert g.image.shape == (512, 512) and g.image.dtype == np.uint8 and g.kind == kind
    assert g.tile_m == pytest.approx(512 * 0.03)
    assert 0.7 < _seam_ratio(g.image) < 1.3
    # a texture that is not periodic has a seam far rougher than its interior: the measure can fail
    assert _seam_ratio(np.tile(np.linspace(0, 255, 512, dtype=np.uint8), (512, 1))) > 100
    textures._GROUND_CACHE.clear()  # drawn again, not read from the cache
    again = make_ground_texture(kind, np.random.default_rng(4), size_px=512, m_per_px=0.03)
    assert again is not g
    np.testing.assert_array_equal(g.image, again.image)
    other = make_ground_texture(kind, np.random.default_rng(5), size_px=512, m_per_px=0.03)
    assert np.any(other.image != g.image)
    assert g.image.std() > 4  # textured, not flat


def test_ground_kinds_differ_in_brightness() -> None:
    means = {
        k: make_ground_texture(k, np.random.default_rng(0), size_px=256).image.mean() for k in GROUND_KINDS
    }
    assert means["asphalt"] < means["grass"] < means["concrete"]
    with pytest.raises(ValueError):
        make_ground_texture("lava", np.random.default_rng(0))


def test_ground_texture_validation() -> None:
    with pytest.raises(ValueError):
        GroundTexture(np.zeros((4, 5), np.uint8), 0.02)
    with pytest.raises(ValueError):
        GroundTexture(np.zeros((4, 4), np.float32), 0.02)  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        GroundTexture(np.zeros((4, 4), np.uint8), 0.0)
    g = GroundTexture(np.zeros((4, 4), np.uint8), 0.5)
    np.testing.assert_allclose(g.texel_of_W() @ [1.0, 1.0, 1.0], [2.0, -2.0, 1.0])


@pytest.mark.parametrize("pad", [FalangaTag(), AprilTagPad.default(1.2)], ids=["falanga", "apriltag"])
@pytest.mark.parametrize("px_per_m", [100.0, 333.3])
def test_deck_holds_the_pad_pixel_aligned(pad, px_per_m: float) -> None:
    deck = make_deck_texture(pad, px_per_m, length_m=2.0, width_m=1.7, rng=np.random.default_rng(0))
    tex = pad.texture(px_per_m)
    n = tex.shape[0]
    s = n / pad.size_m
    rows, cols = deck.image.shape
    assert deck.length_m == pytest.approx(2.0, abs=1.0 / s) and deck.width_m == pytest.approx(
        1.7, abs=1.0 / s
    )
    assert rows / s == pytest.approx(deck.length_m) and cols / s == pytest.approx(deck.width_m)
    # the pad's square maps onto whole pixels of the deck and the block is exactly the pad texture
    q = np.c_[pad.texture_homography_P_to_px(px_per_m) @ np.linalg.inv(deck.H_P_to_px) @ np.eye(3)]
    corner_px = deck.H_P_to_px @ np.array([pad.size_m / 2, pad.size_m / 2, 1.0])
    r0, c0 = corner_px[1] + 0.5, corner_px[0] + 0.5
    assert r0 == pytest.approx(round(r0), abs=1e-9) and c0 == pytest.approx(round(c0), abs=1e-9)
    r0, c0 = int(round(r0)), int(round(c0))
    np.testing.assert_array_equal(deck.image[r0 : r0 + n, c0 : c0 + n], tex)
    # the same point of P maps to the same pixel in both (up to the block offset)
    np.testing.assert_allclose(q[:2, 2], [-c0, -r0], atol=1e-9)
    margin = np.ones(deck.image.shape, bool)
    margin[r0 : r0 + n, c0 : c0 + n] = False
    assert 50 < deck.image[margin].mean() < 70  # the dark deck


def test_deck_shadow_and_validation() -> None:
    pad = FalangaTag()
    s = 400.0
    tri = np.array([[0.74, 0.74], [0.64, 0.74], [0.74, 0.64]])  # all on the white corner of the pad
    plain = make_deck_texture(pad, s)
    shaded = make_deck_texture(pad, s, shadow_polygon_P=tri, shadow_gain=0.5)
    u, v, _ = plain.H_P_to_px @ [0.72, 0.72, 1.0]
    assert shaded.image[int(round(v)), int(round(u))] == pytest.approx(0.5 * 255, abs=1)
    u, v, _ = plain.H_P_to_px @ [-0.65, -0.65, 1.0]
    assert shaded.image[int(round(v)), int(round(u))] == plain.image[int(round(v)), int(round(u))]
    # the darkening integrates to the triangle's area (anti-aliased edges count in part)
    dark = (plain.image.astype(float) - shaded.image) / (255 * 0.5)
    assert dark.sum() == pytest.approx(0.5 * 0.1 * 0.1 * s**2, rel=0.03)
    with pytest.raises(ValueError):
        make_deck_texture(pad, 100.0, length_m=1.0)
    with pytest.raises(ValueError):
        make_deck_texture(pad, 100.0, shadow_polygon_P=np.array([[0.0, 0.0], [1.0, 1.0]]))
