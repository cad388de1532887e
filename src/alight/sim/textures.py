"""Procedural textures for the camera renderer: tileable ground and the platform deck with its pad.

Everything is uint8 grayscale and built from a seeded ``numpy.random.Generator`` with whole-array
operations (noise octaves upsampled with ``cv2.resize``, grain with ``cv2.GaussianBlur``), never per-pixel
Python loops.

Ground textures tile: every octave is periodic on the tile (noise is wrapped before it is upsampled or
blurred), so the renderer samples them with wrap-around and the seam is invisible.
"""

from __future__ import annotations

import collections
import math
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from alight.pads import PadDesign
from alight.types import FloatArray

GROUND_KINDS = ("grass", "asphalt", "concrete")
"""Ground textures :func:`make_ground_texture` knows."""


@dataclass(frozen=True, eq=False)
class GroundTexture:
    """A square, tileable ground texture for the world plane z = 0 (placement: :meth:`texel_of_W`)."""

    image: NDArray[np.uint8]
    """Grayscale tile, shape (n, n)."""
    m_per_px: float
    """Ground size of one texel (m)."""
    kind: str = "custom"
    """What it shows (``grass``, ``asphalt``, ``concrete`` or ``custom``)."""

    def __post_init__(self) -> None:
        img = np.ascontiguousarray(self.image)
        if img.dtype != np.uint8 or img.ndim != 2 or img.shape[0] != img.shape[1] or img.shape[0] < 2:
            raise ValueError(f"ground image must be a square uint8 image, got {img.dtype} {img.shape}")
        if not (math.isfinite(self.m_per_px) and self.m_per_px > 0):
            raise ValueError(f"m_per_px must be finite and positive, got {self.m_per_px}")
        img.setflags(write=False)
        object.__setattr__(self, "image", img)

    @property
    def size_px(self) -> int:
        return int(self.image.shape[0])

    @property
    def tile_m(self) -> float:
        """Side of one tile on the ground (m)."""
        return self.size_px * self.m_per_px

    def texel_of_W(self) -> FloatArray:
        """3x3 map from ground points ``(x_W, y_W, 1)`` (m) to texture coordinates ``(u, v, 1)`` before
        wrapping: ``u = x_W / m_per_px``, ``v = -y_W / m_per_px`` (north up when the image is viewed)."""
        s = 1.0 / self.m_per_px
        return np.array([[s, 0.0, 0.0], [0.0, -s, 0.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True, eq=False)
class DeckTexture:
    """The platform deck (a dark rectangle) with the pad in its centre, in the pad frame ``P``."""

    image: NDArray[np.uint8]
    """Grayscale image, shape (rows, cols): rows along -x_P, columns along -y_P (the pad texture
    convention of :mod:`alight.pads`)."""
    H_P_to_px: FloatArray
    """3x3 homography from deck-plane points ``(x, y, 1)`` in P (m) to pixels ``(u, v, 1)``."""
    length_m: float
    """Deck extent along x_P (m), after rounding to whole pixels."""
    width_m: float
    """Deck extent along y_P (m), after rounding to whole pixels."""


# --------------------------------------------------------------------------------------------------
# Noise
# --------------------------------------------------------------------------------------------------


def _periodic_upsample(cells: NDArray[np.float32], n: int) -> NDArray[np.float32]:
    """Bicubic upsampling of a periodic ``k x k`` grid to ``n x n`` (``n`` a multiple of ``k``), periodic."""
    k = cells.shape[0]
    f = n // k
    pad = 2  # bicubic reads two cells either side
    big = np.pad(cells, pad, mode="wrap")
    up = cv2.resize(big, ((k + 2 * pad) * f, (k + 2 * pad) * f), interpolation=cv2.INTER_CUBIC)
    o = pad * f
    return np.ascontiguousarray(up[o : o + n, o : o + n])


def _periodic_blur(img: NDArray[np.float32], sigma_px: float) -> NDArray[np.float32]:
    if sigma_px <= 0:
        return img
    pad = int(math.ceil(4 * sigma_px)) + 1
    big = np.pad(img, pad, mode="wrap")
    out = cv2.GaussianBlur(big, (0, 0), sigma_px, borderType=cv2.BORDER_REFLECT)
    return np.ascontiguousarray(out[pad:-pad, pad:-pad])


def fractal_noise(
    rng: np.random.Generator, n: int, base_cells: int = 4, persistence: float = 0.5
) -> NDArray[np.float32]:
    """Periodic multi-scale value noise on an ``n x n`` tile (``n`` a power of two), zero mean, unit
    standard deviation. Octave ``i`` has ``base_cells * 2^i`` cells per side and amplitude
    ``persistence^i``; the finest octave is per-pixel white noise."""
    if n < 2 or n & (n - 1):
        raise ValueError(f"n must be a power of two >= 2, got {n}")
    out = np.zeros((n, n), np.float32)
    cells, amp = max(1, min(base_cells, n)), 1.0
    while cells <= n:
        grid = rng.standard_normal((cells, cells), dtype=np.float32)
        out += np.float32(amp) * (grid if cells == n else _periodic_upsample(grid, n))
        cells *= 2
        amp *= persistence
    out -= out.mean()
    std = float(out.std())
    return out / np.float32(std if std > 0 else 1.0)


def _to_u8(img: NDArray[np.float32]) -> NDArray[np.uint8]:
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


# --------------------------------------------------------------------------------------------------
# Ground
# --------------------------------------------------------------------------------------------------


_GROUND_CACHE_SIZE = 4
_GROUND_CACHE: collections.OrderedDict[object, tuple[GroundTexture, dict[str, Any]]]
_GROUND_CACHE = collections.OrderedDict()
"""Ground textures by (kind, size, texel, generator state before), with the generator state after;
least recently used first. One entry is ~1 MB for the default tile."""


def _freeze_state(value: object) -> object:
    """A hashable copy of a bit generator's state (nested dicts of ints, strings and arrays)."""
    if isinstance(value, dict):
        return tuple((k, _freeze_state(v)) for k, v in sorted(value.items()))
    if isinstance(value, np.ndarray):
        return (value.dtype.str, value.shape, value.tobytes())
    hash(value)  # TypeError for anything else that is not hashable
    return value


def make_ground_texture(
    kind: str, rng: np.random.Generator, size_px: int = 1024, m_per_px: float = 0.02
) -> GroundTexture:
    """A tileable ground texture.

    ``kind``: ``grass`` (mid-dark, strong fine texture with patches), ``asphalt`` (dark, fine grain and
    faint stains), ``concrete`` (light, slabs with dark joints every ``size_px / 8`` texels, stains and
    grain). ``size_px`` (a power of two) texels of ``m_per_px`` metres: the default tile is 20.48 m.

    Making a tile costs ~60-100 ms, so the last few are cached by their arguments and the generator's
    state: a generator in a state seen before (a scenario seed flown again, with other settings) gets the
    same (immutable) texture and is left in the state that drawing it would leave, so what it draws
    afterwards is unchanged too.
    """
    try:
        key: object = (kind, int(size_px), float(m_per_px), _freeze_state(rng.bit_generator.state))
    except (AttributeError, TypeError):
        key = None  # not a numpy Generator with a readable state: no caching
    if key is not None:
        hit = _GROUND_CACHE.get(key)
        if hit is not None:
            _GROUND_CACHE.move_to_end(key)
            rng.bit_generator.state = hit[1]
            return hit[0]
    tex = _make_ground_texture(kind, rng, size_px, m_per_px)
    if key is not None:
        _GROUND_CACHE[key] = (tex, rng.bit_generator.state)
        while len(_GROUND_CACHE) > _GROUND_CACHE_SIZE:
            _GROUND_CACHE.popitem(last=False)
    return tex


def _make_ground_texture(kind: str, rng: np.random.Generator, size_px: int, m_per_px: float) -> GroundTexture:
    n = int(size_px)
    if kind == "grass":
        patches = fractal_noise(rng, n, base_cells=8, persistence=0.55)
        blades = _periodic_blur(rng.standard_normal((n, n), dtype=np.float32), 0.8)
        blades /= np.float32(max(float(blades.std()), 1e-6))
        img = 100.0 + 18.0 * patches + 14.0 * blades
    elif kind == "asphalt":
        stains = fractal_noise(rng, n, base_cells=4, persistence=0.45)
        grain = _periodic_blur(rng.standard_normal((n, n), dtype=np.float32), 0.6)
        grain /= np.float32(max(float(grain.std()), 1e-6))
        stones = (rng.random((n, n)) < 0.004).astype(np.float32) * 45.0  # light aggregate specks
        img = 78.0 + 7.0 * stains + 8.0 * grain + _periodic_blur(stones, 0.7)
    elif kind == "concrete":
        stains = fractal_noise(rng, n, base_cells=4, persistence=0.4)
        grain = _periodic_blur(rng.standard_normal((n, n), dtype=np.float32), 0.7)
        grain /= np.float32(max(float(grain.std()), 1e-6))
        img = 162.0 + 10.0 * stains + 5.0 * grain
        slab = max(n // 8, 2)
        joints = np.zeros((n, n), np.float32)
        joints[slab // 2 :: slab, :] = 1.0  # periodic; off the tile edge so the seam is mid-slab
        joints[:, slab // 2 :: slab] = 1.0
        joints = _periodic_blur(joints, 0.8)
        img -= 55.0 * joints / np.float32(max(float(joints.max()), 1e-6))
    else:
        raise ValueError(f"unknown ground kind {kind!r}; known: {GROUND_KINDS}")
    return GroundTexture(_to_u8(img.astype(np.float32)), float(m_per_px), kind)


# --------------------------------------------------------------------------------------------------
# Deck
# --------------------------------------------------------------------------------------------------


def make_deck_texture(
    pad: PadDesign,
    px_per_m: float,
    *,
    length_m: float = 2.0,
    width_m: float = 1.7,
    deck_gray: float = 60.0,
    rng: np.random.Generator | None = None,
    shadow_polygon_P: FloatArray | None = None,
    shadow_gain: float = 0.45,
) -> DeckTexture:
    """The deck (a ``length_m`` (along x_P) by ``width_m`` (along y_P) rectangle of grey ``deck_gray``,
    with a faint stain texture when ``rng`` is given) with ``pad``'s texture at its centre, pixel-aligned:
    the scale is the pad texture's effective ``n / size_m`` and the deck margins are whole pixels, so the
    deck's extent is rounded to the nearest pixel (returned in the result).

    ``shadow_polygon_P`` (K, 2) in P (m): a hard shadow over that polygon, brightness times ``shadow_gain``.
    """
    if length_m < pad.size_m or width_m < pad.size_m:
        raise ValueError(f"the deck ({length_m} x {width_m} m) must be at least the pad ({pad.size_m} m)")
    tex = pad.texture(px_per_m)
    n = tex.shape[0]
    s = n / pad.size_m
    mx = int(round((length_m - pad.size_m) / 2 * s))  # margin rows (along x)
    my = int(round((width_m - pad.size_m) / 2 * s))  # margin columns (along y)
    rows, cols = n + 2 * mx, n + 2 * my
    if rng is not None:
        # low-frequency stains: a 256-texel noise tile stretched over the deck
        stain = cv2.resize(fractal_noise(rng, 256, base_cells=4, persistence=0.5), (cols, rows))
        deck = deck_gray + 4.0 * stain
    else:
        deck = np.full((rows, cols), deck_gray, np.float32)
    img = _to_u8(deck.astype(np.float32))
    img[mx : mx + n, my : my + n] = tex
    L, W = rows / s, cols / s
    H = np.array([[0.0, -s, s * W / 2 - 0.5], [-s, 0.0, s * L / 2 - 0.5], [0.0, 0.0, 1.0]])
    if shadow_polygon_P is not None:
        poly = np.asarray(shadow_polygon_P, dtype=np.float64)
        if poly.ndim != 2 or poly.shape[1] != 2 or poly.shape[0] < 3 or not np.isfinite(poly).all():
            raise ValueError(f"shadow_polygon_P must be a finite (K >= 3, 2) array, got {poly.shape}")
        uv = np.c_[poly, np.ones(len(poly))] @ H.T
        cover = _polygon_coverage(uv[:, :2] / uv[:, 2:], img.shape)
        gain = 1.0 - (1.0 - shadow_gain) * cover
        img = _to_u8(img.astype(np.float32) * gain)
    return DeckTexture(img, H, L, W)


def _polygon_coverage(uv: FloatArray, shape: tuple[int, int], ss: int = 8) -> NDArray[np.float32]:
    """Fraction of each pixel covered by the polygon with vertices ``uv`` (pixel coordinates, integer
    at pixel centres), by ``ss x ss`` supersampling over the polygon's bounding box (cv2.fillPoly's own
    anti-aliasing paints a one-pixel rim outside the edge, so it overstates the area)."""
    cover = np.zeros(shape, np.float32)
    u0 = max(int(math.floor(uv[:, 0].min())) - 1, 0)
    v0 = max(int(math.floor(uv[:, 1].min())) - 1, 0)
    u1 = min(int(math.ceil(uv[:, 0].max())) + 2, shape[1])
    v1 = min(int(math.ceil(uv[:, 1].max())) + 2, shape[0])
    if u1 <= u0 or v1 <= v0:
        return cover
    shift = 4
    # fine pixel j has its centre at coarse coordinate (j + 0.5) / ss - 0.5
    fine = ((uv - [u0, v0]) + 0.5) * ss - 0.5
    pts = np.rint(fine * (1 << shift)).astype(np.int32)
    hi = np.zeros(((v1 - v0) * ss, (u1 - u0) * ss), np.uint8)
    cv2.fillPoly(hi, [pts], 255, lineType=cv2.LINE_8, shift=shift)
    lo = cv2.resize(hi, (u1 - u0, v1 - v0), interpolation=cv2.INTER_AREA)
    cover[v0:v1, u0:u1] = lo.astype(np.float32) / 255.0
    return cover
