"""Procedural textures for the camera renderer: tileable ground and the platform deck with its pad.

Everything is uint8, grayscale (H, W) or BGR colour (H, W, 3), and built from a seeded
``numpy.random.Generator`` with whole-array operations (noise octaves upsampled with ``cv2.resize``, grain
with ``cv2.GaussianBlur``), never per-pixel Python loops.

A colour ground is its grey version tinted: the grey tile is drawn exactly as for ``color=False`` (same
draws, so the grey tile of a seed never changes), then a low-frequency hue field (drawn after it) mixes
two tints of unit luma per kind, so the colour tile's luma (``cv2.COLOR_BGR2GRAY``) is the grey tile.
Distractors (:class:`DistractorSpec`: red discs or rectangles, the false targets of a colour filter) are
drawn right after the grey tile (so they sit at the same places in a grey and a colour tile of one
seed), painted last, and listed with their world positions.

Ground textures tile: every octave is periodic on the tile (noise is wrapped before it is upsampled or
blurred), so the renderer samples them with wrap-around and the seam is invisible.
"""

from __future__ import annotations

import collections
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Annotated, Any, Literal

import cv2
import numpy as np
from numpy.typing import NDArray
from pydantic import Field
from pydantic.dataclasses import dataclass as pydantic_dataclass

from alight.pads import PadDesign
from alight.settings import SETTINGS
from alight.types import FloatArray

GROUND_KINDS = ("grass", "asphalt", "concrete")
"""Ground textures :func:`make_ground_texture` knows."""

DISTRACTOR_SHAPES = ("disc", "rect", "mixed")
"""Shapes :class:`DistractorSpec` knows (``mixed``: each one a disc or a rectangle, half and half)."""


ColorLevel = Annotated[int, Field(ge=0, le=255)]
"""One channel of an 8-bit colour."""


@pydantic_dataclass(frozen=True, config=SETTINGS)
class DistractorSpec:
    """Coloured objects to paint on the ground, per 20 m ground tile: the false targets of a colour
    filter (red boxes, cars, tarpaulins). Positions are uniform over the tile, drawn from the texture's
    generator."""

    count: Annotated[int, Field(ge=0, le=500)] = 8
    """Number of objects per tile."""
    size_m: Annotated[float, Field(gt=0, le=100.0, allow_inf_nan=False)] = 0.8
    """Diameter of a disc, length of a rectangle's long side (m)."""
    shape: Literal["disc", "rect", "mixed"] = "mixed"
    """``disc``, ``rect`` or ``mixed`` (:data:`DISTRACTOR_SHAPES`)."""
    aspect: Annotated[float, Field(ge=1, le=100, allow_inf_nan=False)] = 2.0
    """A rectangle's long side over its short side (>= 1); its orientation is uniform."""
    color_bgr: tuple[ColorLevel, ColorLevel, ColorLevel] = (40, 40, 200)
    """Mean colour, BGR, 0-255 (default: the red of :class:`alight.pads.RedTarget`)."""
    color_jitter_dn: Annotated[float, Field(ge=0, le=255, allow_inf_nan=False)] = 25.0
    """Each object's colour is the mean plus a uniform offset in +-this per channel (DN), clipped."""


@dataclass(frozen=True)
class Distractor:
    """One object painted on the ground tile (see :meth:`GroundTexture.distractor_centers_W`)."""

    center_W: tuple[float, float]
    """Centre ``(x_W, y_W)`` (m) in the tile at the origin; it repeats every ``tile_m``."""
    shape: str
    """``disc`` or ``rect``."""
    length_m: float
    """Diameter of a disc, long side of a rectangle (m)."""
    width_m: float
    """Short side of a rectangle, the diameter again for a disc (m)."""
    angle_rad: float
    """Direction of a rectangle's long side from +x_W, counter-clockwise (rad); 0 for a disc."""
    color_bgr: tuple[int, int, int]
    """Its colour, BGR (a grey tile holds its luma)."""


@dataclass(frozen=True, eq=False)
class GroundTexture:
    """A square, tileable ground texture for the world plane z = 0 (placement: :meth:`texel_of_W`)."""

    image: NDArray[np.uint8]
    """The tile: grayscale, shape (n, n), or BGR colour, shape (n, n, 3)."""
    m_per_px: float
    """Ground size of one texel (m)."""
    kind: str = "custom"
    """What it shows (``grass``, ``asphalt``, ``concrete`` or ``custom``)."""
    distractors: tuple[Distractor, ...] = ()
    """Objects painted on the tile (:class:`Distractor`), their centres in the tile at the world origin;
    the tile repeats every :attr:`tile_m` in x and y, and so do they (:meth:`distractor_centers_W`)."""

    def __post_init__(self) -> None:
        img = np.ascontiguousarray(self.image)
        square = img.ndim in (2, 3) and img.shape[0] == img.shape[1] and img.shape[0] >= 2
        if img.dtype != np.uint8 or not square or (img.ndim == 3 and img.shape[2] != 3):
            raise ValueError(
                f"ground image must be a square uint8 (n, n) or (n, n, 3) image, got {img.dtype} {img.shape}"
            )
        if not (math.isfinite(self.m_per_px) and self.m_per_px > 0):
            raise ValueError(f"m_per_px must be finite and positive, got {self.m_per_px}")
        img.setflags(write=False)
        object.__setattr__(self, "image", img)
        object.__setattr__(self, "distractors", tuple(self.distractors))

    @property
    def size_px(self) -> int:
        return int(self.image.shape[0])

    @property
    def is_color(self) -> bool:
        """True for a BGR tile."""
        return self.image.ndim == 3

    def distractor_centers_W(
        self, center_W: FloatArray | tuple[float, float] = (0.0, 0.0), radius_m: float | None = None
    ) -> FloatArray:
        """Centres ``(x_W, y_W)`` (m) of every painted distractor, shape (K, 2): without ``radius_m``
        those of the tile at the origin (``0 <= x_W < tile_m``, ``-tile_m < y_W <= 0``); with it every
        repetition of the tiled ground within ``radius_m`` (m) of ``center_W`` (2,). The order is by
        distractor, then by tile; :meth:`distractor_index_W` gives each row's distractor."""
        return self._copies(center_W, radius_m)[0]

    def distractor_index_W(
        self, center_W: FloatArray | tuple[float, float] = (0.0, 0.0), radius_m: float | None = None
    ) -> NDArray[np.intp]:
        """Index into :attr:`distractors` of each row of :meth:`distractor_centers_W` (same arguments)."""
        return self._copies(center_W, radius_m)[1]

    def _copies(
        self, center_W: FloatArray | tuple[float, float], radius_m: float | None
    ) -> tuple[FloatArray, NDArray[np.intp]]:
        base = np.array([d.center_W for d in self.distractors], dtype=np.float64).reshape(-1, 2)
        idx = np.arange(len(base))
        if radius_m is None:
            return base, idx
        c = np.asarray(center_W, dtype=np.float64)
        if c.shape != (2,) or not np.isfinite(c).all() or not (math.isfinite(radius_m) and radius_m >= 0):
            raise ValueError("distractor_centers_W needs a finite center_W (2,) and a radius_m >= 0")
        T = self.tile_m
        i0, i1 = math.floor((c[0] - radius_m) / T) - 1, math.floor((c[0] + radius_m) / T) + 1
        j0, j1 = math.floor((c[1] - radius_m) / T) - 1, math.floor((c[1] + radius_m) / T) + 2
        ii, jj = np.meshgrid(np.arange(i0, i1 + 1), np.arange(j0, j1 + 1), indexing="ij")
        shifts = T * np.stack([ii.ravel(), jj.ravel()], axis=1).astype(np.float64)
        pts = (base[:, None, :] + shifts[None, :, :]).reshape(-1, 2)
        rows = np.repeat(idx, len(shifts))
        keep = np.hypot(pts[:, 0] - c[0], pts[:, 1] - c[1]) <= radius_m
        return pts[keep], rows[keep]

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
    """Grayscale image, shape (rows, cols), or BGR, shape (rows, cols, 3): rows along -x_P, columns along
    -y_P (the pad texture convention of :mod:`alight.pads`)."""
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
_GROUND_CACHE: collections.OrderedDict[object, tuple[GroundTexture, Mapping[str, Any]]]
_GROUND_CACHE = collections.OrderedDict()
"""Ground textures by (kind, size, texel, colour, distractors, generator state before), with the
generator state after; least recently used first. One entry is ~1 MB (grey) or ~3 MB (colour) for the
default tile."""

_LUMA_BGR = np.array([0.114, 0.587, 0.299])
"""OpenCV's ``COLOR_BGR2GRAY`` weights, in BGR order."""

_TINTS_BGR = {
    # two tints per kind, each scaled to unit luma, mixed by a low-frequency field: lush green to dry
    # yellow-green grass, grey-blue to grey asphalt, warm to neutral grey concrete. Every tint keeps
    # G > 0.6 R, so no ground texel passes paper 003's red test (Alg. 2).
    "grass": ((0.55, 1.18, 0.80), (0.50, 1.05, 1.15)),
    "asphalt": ((1.14, 1.00, 0.92), (1.03, 1.00, 0.98)),
    "concrete": ((0.88, 1.00, 1.08), (0.96, 1.00, 1.02)),
}


def _freeze_state(value: object) -> object:
    """A hashable copy of a bit generator's state (nested dicts of ints, strings and arrays)."""
    if isinstance(value, dict):
        return tuple((k, _freeze_state(v)) for k, v in sorted(value.items()))
    if isinstance(value, np.ndarray):
        return (value.dtype.str, value.shape, value.tobytes())
    hash(value)  # TypeError for anything else that is not hashable
    return value


def make_ground_texture(
    kind: str,
    rng: np.random.Generator,
    size_px: int = 1024,
    m_per_px: float = 0.02,
    *,
    color: bool = False,
    distractors: DistractorSpec | None = None,
) -> GroundTexture:
    """A tileable ground texture.

    ``kind``: ``grass`` (mid-dark, strong fine texture with patches), ``asphalt`` (dark, fine grain and
    faint stains), ``concrete`` (light, slabs with dark joints every ``size_px / 8`` texels, stains and
    grain). ``size_px`` (a power of two) texels of ``m_per_px`` metres: the default tile is 20.48 m.

    ``color``: a BGR tile, shape (n, n, 3) (grass greenish, asphalt grey-blue, concrete warm grey) whose
    luma is the grey tile of the same generator state (see the module docstring); else grayscale (n, n),
    byte for byte what this function always drew. ``distractors``: objects painted on the tile after
    that (:class:`DistractorSpec`), listed in ``GroundTexture.distractors``; on a grey tile they hold
    their colour's luma.

    Making a tile costs ~60-100 ms, so the last few are cached by their arguments and the generator's
    state: a generator in a state seen before (a scenario seed flown again, with other settings) gets the
    same (immutable) texture and is left in the state that drawing it would leave, so what it draws
    afterwards is unchanged too.
    """
    if distractors is not None and not isinstance(distractors, DistractorSpec):
        raise ValueError(f"distractors must be a DistractorSpec or None, got {type(distractors).__name__}")
    try:
        key: object = (
            kind,
            int(size_px),
            float(m_per_px),
            bool(color),
            distractors,
            _freeze_state(rng.bit_generator.state),
        )
    except (AttributeError, TypeError):
        key = None  # not a numpy Generator with a readable state: no caching
    if key is not None:
        hit = _GROUND_CACHE.get(key)
        if hit is not None:
            _GROUND_CACHE.move_to_end(key)
            rng.bit_generator.state = hit[1]
            return hit[0]
    tex = _make_ground_texture(kind, rng, size_px, m_per_px, bool(color), distractors)
    if key is not None:
        _GROUND_CACHE[key] = (tex, rng.bit_generator.state)
        while len(_GROUND_CACHE) > _GROUND_CACHE_SIZE:
            _GROUND_CACHE.popitem(last=False)
    return tex


def _make_ground_texture(
    kind: str,
    rng: np.random.Generator,
    size_px: int,
    m_per_px: float,
    color: bool = False,
    distractors: DistractorSpec | None = None,
) -> GroundTexture:
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
    img = img.astype(np.float32)
    # the distractors are drawn before the hue field, so they sit at the same places in grey and colour
    drawn = None
    if distractors is not None and distractors.count > 0:
        drawn = _draw_distractors(distractors, rng, n, float(m_per_px))
    if color:
        # hue field: smooth noise on at most 64 cells, stretched periodically over the tile
        k = min(n, 64)
        hue = fractal_noise(rng, k, base_cells=4, persistence=0.5)
        if k < n:
            hue = _periodic_upsample(hue, n)
        mix = np.clip(np.float32(0.5) + np.float32(0.3) * hue, 0.0, 1.0)[..., None]
        t0, t1 = (np.asarray(t) / (np.asarray(t) @ _LUMA_BGR) for t in _TINTS_BGR[kind])
        img = img[..., None] * (t0.astype(np.float32) + mix * (t1 - t0).astype(np.float32))
    placed: tuple[Distractor, ...] = ()
    if drawn is not None and distractors is not None:
        img, placed = _paint_distractors(img, distractors, drawn, float(m_per_px))
    return GroundTexture(_to_u8(img), float(m_per_px), kind, placed)


def _draw_distractors(
    spec: DistractorSpec, rng: np.random.Generator, n: int, m_per_px: float
) -> tuple[NDArray[np.float64], ...]:
    """Texel positions (k, 2), rectangle flags, angles and colours (k, 3) of ``spec.count`` objects on
    an ``n``-texel tile. Every draw is made whatever the shape, so the positions do not depend on it."""
    if 2 * (int(math.ceil(spec.size_m / m_per_px / 2)) + 2) + 1 > n:
        raise ValueError(f"distractors of {spec.size_m} m do not fit in a {n * m_per_px} m tile")
    k = int(spec.count)
    uv = rng.random((k, 2)) * n
    is_rect = rng.random(k) < 0.5
    angle = rng.random(k) * math.pi
    jitter = rng.uniform(-spec.color_jitter_dn, spec.color_jitter_dn, (k, 3))
    if spec.shape != "mixed":
        is_rect[:] = spec.shape == "rect"
    colors = np.clip(np.rint(np.asarray(spec.color_bgr, dtype=np.float64) + jitter), 0, 255)
    return uv, is_rect.astype(np.float64), angle, colors


def _paint_distractors(
    img: NDArray[np.float32], spec: DistractorSpec, drawn: tuple[NDArray[np.float64], ...], m_per_px: float
) -> tuple[NDArray[np.float32], tuple[Distractor, ...]]:
    """Paint the objects of :func:`_draw_distractors` onto the float tile (grey (n, n) or BGR (n, n, 3))
    with exact area coverage at their edges (a one-texel linear ramp of the signed distance) and
    wrap-around at the tile's edges. Texel ``(u, v)`` (integer at texel centres) is the ground point
    ``(u m_per_px, -v m_per_px)`` (``GroundTexture.texel_of_W``)."""
    n = img.shape[0]
    uv, is_rect, angle, colors = drawn
    length_px = spec.size_m / m_per_px
    reach = int(math.ceil(length_px / 2)) + 2
    out = img.copy()
    placed = []
    offs = np.arange(-reach, reach + 1)
    for i in range(len(uv)):
        uc, vc = float(uv[i, 0]), float(uv[i, 1])
        iu, iv = int(math.floor(uc)), int(math.floor(vc))
        cols, rows = iu + offs, iv + offs
        du = (cols - uc)[None, :].astype(np.float64)
        dv = (rows - vc)[:, None].astype(np.float64)
        if is_rect[i]:
            w_px = length_px / spec.aspect
            a = float(angle[i])
            # the long side's direction (cos a, sin a) in W is (cos a, -sin a) in (u, v)
            along = du * math.cos(a) - dv * math.sin(a)
            across = du * math.sin(a) + dv * math.cos(a)
            ex = np.abs(along) - length_px / 2
            ey = np.abs(across) - w_px / 2
            sd = np.hypot(np.maximum(ex, 0), np.maximum(ey, 0)) + np.minimum(np.maximum(ex, ey), 0)
            shape, width_m, ang = "rect", spec.size_m / spec.aspect, a
        else:
            sd = np.hypot(du, dv) - length_px / 2
            shape, width_m, ang = "disc", spec.size_m, 0.0
        cover = np.clip(0.5 - sd, 0.0, 1.0).astype(np.float32)
        bgr = (int(colors[i, 0]), int(colors[i, 1]), int(colors[i, 2]))
        value = np.asarray(bgr, np.float32) if out.ndim == 3 else np.float32(float(colors[i] @ _LUMA_BGR))
        ix = np.ix_(rows % n, cols % n)
        c = cover[..., None] if out.ndim == 3 else cover
        out[ix] = out[ix] * (np.float32(1.0) - c) + value * c
        placed.append(Distractor((uc * m_per_px, -vc * m_per_px), shape, spec.size_m, width_m, ang, bgr))
    return out, tuple(placed)


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
    color: bool = False,
) -> DeckTexture:
    """The deck (a ``length_m`` (along x_P) by ``width_m`` (along y_P) rectangle of grey ``deck_gray``,
    with a faint stain texture when ``rng`` is given) with ``pad``'s texture at its centre, pixel-aligned:
    the scale is the pad texture's effective ``n / size_m`` and the deck margins are whole pixels, so the
    deck's extent is rounded to the nearest pixel (returned in the result).

    ``shadow_polygon_P`` (K, 2) in P (m): a hard shadow over that polygon, brightness times ``shadow_gain``.
    ``color``: a BGR image (the deck a neutral grey, a grey pad texture replicated in the three channels);
    else grayscale (a BGR pad texture converted with ``cv2.COLOR_BGR2GRAY``).
    """
    if length_m < pad.size_m or width_m < pad.size_m:
        raise ValueError(f"the deck ({length_m} x {width_m} m) must be at least the pad ({pad.size_m} m)")
    # uint8 throughout (checked below); OpenCV's stubs return MatLike, without the dtype
    tex: NDArray[Any] = np.asarray(pad.texture(px_per_m))
    n = tex.shape[0]
    if tex.dtype != np.uint8 or tex.shape[:2] != (n, n) or not (tex.ndim == 2 or tex.shape[2:] == (3,)):
        raise ValueError(f"a pad texture must be uint8 (n, n) or (n, n, 3), got {tex.dtype} {tex.shape}")
    if color and tex.ndim == 2:
        tex = cv2.cvtColor(tex, cv2.COLOR_GRAY2BGR)
    elif not color and tex.ndim == 3:
        tex = cv2.cvtColor(np.ascontiguousarray(tex), cv2.COLOR_BGR2GRAY)
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
    img: NDArray[Any] = _to_u8(deck.astype(np.float32))
    if color:
        img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    img[mx : mx + n, my : my + n] = tex
    L, W = rows / s, cols / s
    H = np.array([[0.0, -s, s * W / 2 - 0.5], [-s, 0.0, s * L / 2 - 0.5], [0.0, 0.0, 1.0]])
    if shadow_polygon_P is not None:
        poly = np.asarray(shadow_polygon_P, dtype=np.float64)
        if poly.ndim != 2 or poly.shape[1] != 2 or poly.shape[0] < 3 or not np.isfinite(poly).all():
            raise ValueError(f"shadow_polygon_P must be a finite (K >= 3, 2) array, got {poly.shape}")
        uv = np.c_[poly, np.ones(len(poly))] @ H.T
        cover = _polygon_coverage(uv[:, :2] / uv[:, 2:], (rows, cols))
        gain = 1.0 - (1.0 - shadow_gain) * cover
        if color:
            gain = gain[..., None]
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
