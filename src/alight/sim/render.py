"""Camera-image renderer for the planar world: the ground (z = 0) and the platform deck with the pad on
top (the plane z = p_WP[2]).

How a frame is made (all per-pixel work in numba kernels or OpenCV, nothing per pixel in Python):

1. Once per camera, every pixel's ray in C is unprojected through the camera model (any
   :class:`alight.cameras.CameraModel`, so lens distortion, or a fisheye model, is exact) and stored as
   float32 planes; a second set holds the rays of a half-resolution grid. They are cached by the camera's
   parameters, so the new camera object of every mission reuses them (unprojecting costs ~0.1 s).
2. Per frame the ray-plane intersection with texture lookup is a homography on the ray,
   ``(u, v, w) = M d_C`` with ``M = T N R`` (texture scale/offset T, plane intersection N, rotation R into
   the plane's frame). A vectorised numba kernel evaluates it for every pixel into float32 maps, and
   ``cv2.remap`` samples the texture bilinearly.
3. The ground is rendered at half resolution and upsampled with ``cv2.pyrUp`` (it is a background of
   noise whose fine detail nothing depends on; this halves the frame time), with nearest-texel lookup
   unless the texture is magnified more than 2x. Rays that do not hit the ground in front show the sky;
   hits farther than ``max_range_m`` show a uniform haze (the texture mean). One mip level serves the
   whole frame, so ground much farther than the point on the optical axis aliases (towards a horizon);
   a camera with rays over 75 deg off its axis (a fisheye: nadir to horizon in one frame) takes a level
   per ray instead, from an atlas of all levels (:func:`_ground_maps_mip`).
4. The deck is rendered at full resolution over its bounding box only (found by projecting its outline),
   and copied over the ground where the ray hits the deck rectangle (a hard edge against the ground): the
   pad is never blurred by the half-resolution ground and its edges are where the camera model puts
   them (to 0.3 px in the tests). When the deck fills the view the ground is skipped.
5. Both textures are mip-mapped (area-averaged halvings); each frame picks the level whose texel is just
   below the pixel footprint at the pad (and at the ground point on the optical axis).
6. Optional effects, in the order a camera produces them: vignetting, motion blur from the body rates
   over the exposure time, illumination and exposure gain and gamma (one lookup table), Gaussian sensor
   noise. Pixels without a ray (outside a fisheye's image circle) are 0 after all of them.

Colour (``RenderOptions.color``): the same steps on BGR images, shape (H, W, 3): OpenCV's remap, pyrUp,
filter2D and LUT work per channel, and the noise is independent per channel. Textures are stored as BGRA
and sampled into BGRA buffers, converted to BGR after sampling: OpenCV's remap has SIMD code for 1 and 4
channels, not 3 (3 to 4 times slower). A grey ground or pad is
replicated into the three channels, a colour one drawn in a grey image as its luma. The grey path is
unchanged (same bytes, same speed) when ``color`` is False.

Wide-angle cameras (fisheye, omnidirectional, > 180 deg): any ray direction works (rays that point up
see the sky, NaN rays are black), and the deck's bounding box comes from projecting its outline also when
part of it lies behind the image plane, as long as the camera model projects every outline point.

Conventions: world W is ENU z-up; the pad frame P is at ``p_WP`` rotated by ``yaw`` about z; camera C is
OpenCV's. A camera below the pad plane does not see the deck (the platform's body is not modelled); a
camera at or below the ground renders as if 1 mm above it.

Speed (``benchmarks/bench_render.py``, one core, noise off, 752 x 480): about 0.5 ms with the pad small
in view, 1.2-1.4 ms with the pad filling a large part of it; colour costs about twice that. A renderer
reuses its buffers: one instance per thread.
"""

from __future__ import annotations

import collections
import dataclasses
import functools
import math
import weakref
from dataclasses import dataclass, field
from typing import Any

import cv2
import numba
import numpy as np
from numpy.typing import NDArray

from alight.cameras import CameraModel, CameraMount
from alight.cameras.omni import OmniCamera
from alight.cameras.pinhole import PinholeCamera
from alight.pads import PadDesign
from alight.sim.textures import DeckTexture, GroundTexture, make_deck_texture
from alight.types import FloatArray

# fastmath without nnan / ninf: invalid rays and rays parallel to a plane must still compare false
_FASTMATH = {"nsz", "arcp", "contract", "afn", "reassoc"}
_MIN_HEIGHT_M = 1e-3
_LUMA_BGR = (0.114, 0.587, 0.299)  # OpenCV's COLOR_BGR2GRAY weights


@dataclass(frozen=True)
class RenderOptions:
    """Scenario options of the renderer. All effects are off by default except a mild sensor noise."""

    noise_sigma_dn: float = 2.0
    """Standard deviation of additive Gaussian sensor noise (DN, 8-bit)."""
    exposure_time_s: float = 0.0
    """Exposure time for motion blur from the body rates (s); 0 disables the blur."""
    exposure_gain: float = 1.0
    """Brightness gain (1 = unchanged), applied before the gamma."""
    gamma: float = 1.0
    """Gamma exponent on normalised intensity (1 = unchanged; > 1 darkens mid-tones)."""
    vignetting: float = 0.0
    """Brightness lost at the image corners, in [0, 1) (0 = none); falls off as cos^4 of the ray angle,
    scaled so the corner loses this fraction."""
    shadow_polygon_P: tuple[tuple[float, float], ...] | None = None
    """A hard shadow over this polygon in the pad frame (m), e.g. of the vehicle or a mast."""
    shadow_gain: float = 0.45
    """Brightness factor inside the shadow."""
    sky_dn: int = 215
    """Intensity of the sky (DN)."""
    max_range_m: float = 300.0
    """Ground farther than this (along the ray) is drawn as uniform haze (m)."""
    deck_length_m: float = 2.0
    """Deck extent along the platform heading (m)."""
    deck_width_m: float = 1.7
    """Deck extent across the platform (m)."""
    deck_gray_dn: float = 60.0
    """Deck brightness (DN)."""
    pad_px_per_m: float = 1024.0
    """Resolution of the finest deck texture level (px/m): 1 mm, enough for a camera 0.4 m above."""
    color: bool = False
    """Render BGR colour images, shape (H, W, 3), instead of grayscale ones, shape (H, W)."""
    sky_bgr: tuple[int, int, int] | None = None
    """Colour of the sky in colour images (B, G, R, 0-255); None: ``sky_dn`` in every channel."""
    illumination_gain_bgr: tuple[float, float, float] = (1.0, 1.0, 1.0)
    """Gain of the light per channel (B, G, R), applied with ``exposure_gain`` before the gamma: a colour
    temperature or white-balance error (e.g. (1.2, 1.0, 0.8): cold light, the red target's red channel
    drops). A grayscale image takes its luma, ``0.114 B + 0.587 G + 0.299 R``."""
    brightness_drift: float = 0.0
    """Amplitude of a slow brightness change, in [0, 1): every channel's gain is multiplied by
    ``1 + brightness_drift * sin(2 pi t_s / brightness_drift_period_s)`` at the time ``t_s`` (s) passed to
    :meth:`Renderer.render` (clouds passing the sun; 0 = none; no ``t_s``: no drift)."""
    brightness_drift_period_s: float = 60.0
    """Period of the brightness drift (s)."""

    def __post_init__(self) -> None:
        try:
            gains = tuple(float(g) for g in self.illumination_gain_bgr)
        except (TypeError, ValueError):
            gains = ()
        if len(gains) != 3 or not all(math.isfinite(g) and g > 0 for g in gains):
            raise ValueError(f"RenderOptions.illumination_gain_bgr must be 3 finite gains > 0, got {gains}")
        object.__setattr__(self, "illumination_gain_bgr", gains)
        if self.sky_bgr is not None:
            try:
                sky = tuple(int(c) for c in self.sky_bgr)
                ok = len(sky) == 3 and all(0 <= c <= 255 for c in sky)
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise ValueError(f"RenderOptions.sky_bgr must be 3 ints in [0, 255], got {self.sky_bgr}")
            object.__setattr__(self, "sky_bgr", sky)
        object.__setattr__(self, "color", bool(self.color))
        if self.shadow_polygon_P is not None:  # a hashable tuple, whatever array-like was passed
            poly = np.asarray(self.shadow_polygon_P, dtype=np.float64)
            if poly.ndim != 2 or poly.shape[1] != 2 or poly.shape[0] < 3 or not np.isfinite(poly).all():
                raise ValueError(f"shadow_polygon_P must be a finite (K >= 3, 2) array, got {poly.shape}")
            object.__setattr__(self, "shadow_polygon_P", tuple((float(x), float(y)) for x, y in poly))
        checks = {
            "noise_sigma_dn": self.noise_sigma_dn >= 0,
            "exposure_time_s": self.exposure_time_s >= 0,
            "exposure_gain": self.exposure_gain > 0,
            "gamma": self.gamma > 0,
            "vignetting": 0 <= self.vignetting < 1,
            "shadow_gain": 0 <= self.shadow_gain <= 1,
            "sky_dn": 0 <= self.sky_dn <= 255,
            "max_range_m": self.max_range_m > 0,
            "deck_gray_dn": 0 <= self.deck_gray_dn <= 255,
            "pad_px_per_m": self.pad_px_per_m > 0,
            "brightness_drift": 0 <= self.brightness_drift < 1,
            "brightness_drift_period_s": self.brightness_drift_period_s > 0,
        }
        for name, ok in checks.items():
            if not ok or not math.isfinite(float(getattr(self, name))):
                raise ValueError(f"RenderOptions.{name} out of range: {getattr(self, name)}")


# --------------------------------------------------------------------------------------------------
# Kernels
# --------------------------------------------------------------------------------------------------


@numba.njit(cache=True, fastmath=_FASTMATH, error_model="numpy", boundscheck=False)
def _ground_maps(rx, ry, rz, M, min_den, n, mapx, mapy):  # type: ignore[no-untyped-def]
    """Texture coordinates of the ground hit of each ray (flat float32 arrays), wrapped into the tile
    ``[0, n)``. ``M``'s last row gives ``den = d_Wz``; the ray hits the ground in front iff ``den < 0``.
    Rays with ``-min_den <= den < 0`` hit beyond the haze range, rays with ``den >= 0`` see the sky, and
    invalid rays (all zero) read the black rows of the extended texture."""
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = M[0], M[1], M[2], M[3], M[4], M[5], M[6], M[7], M[8]
    fn = np.float32(n)
    inv_n = np.float32(1.0 / n)
    one = np.float32(1.0)
    sky_v = fn + np.float32(1.5)
    haze_v = fn + np.float32(3.5)
    black_v = fn + np.float32(5.5)
    zero = np.float32(0.0)
    for i in range(rx.shape[0]):
        x = rx[i]
        y = ry[i]
        z = rz[i]
        den = m20 * x + m21 * y + m22 * z
        iw = one / den
        tu = (m00 * x + m01 * y + m02 * z) * iw
        tv = (m10 * x + m11 * y + m12 * z) * iw
        tu = tu - np.floor(tu * inv_n) * fn
        tv = tv - np.floor(tv * inv_n) * fn
        far = den >= -min_den
        invalid = (x == zero) & (y == zero) & (z == zero)
        special_v = black_v if invalid else (sky_v if den >= zero else haze_v)
        use_special = far | invalid
        mapx[i] = one if use_special else tu
        mapy[i] = special_v if use_special else tv


@numba.njit(cache=True, fastmath=_FASTMATH, error_model="numpy", boundscheck=False)
def _ground_maps_mip(rx, ry, rz, M, min_den, thr, inv_f, size, off, n0, mapx, mapy):  # type: ignore[no-untyped-def]
    """:func:`_ground_maps` with a mip level per ray, into the atlas of :func:`_ground_atlas`: ``M`` maps
    to level-0 texels; a ray whose ground hit is at ``a = -d_Wz`` (the cosine of its angle to the nadir)
    takes level ``k`` = the number of ``thr[1:]`` with ``a <= thr[j]`` (the footprint ``K a^-1.5`` is at
    least that level's texel), whose texel coordinates are ``(t0 + 0.5) inv_f[k] - 0.5`` wrapped into
    ``[0, size[k])`` and shifted by the level's column ``off[k]`` in the atlas. Sky, haze and black are
    rows ``n0 + 1.5``, ``n0 + 3.5``, ``n0 + 5.5`` of level 0's block."""
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = M[0], M[1], M[2], M[3], M[4], M[5], M[6], M[7], M[8]
    fn0 = np.float32(n0)
    one = np.float32(1.0)
    half = np.float32(0.5)
    sky_v = fn0 + np.float32(1.5)
    haze_v = fn0 + np.float32(3.5)
    black_v = fn0 + np.float32(5.5)
    zero = np.float32(0.0)
    L = thr.shape[0]
    for i in range(rx.shape[0]):
        x = rx[i]
        y = ry[i]
        z = rz[i]
        den = m20 * x + m21 * y + m22 * z
        iw = one / den
        tu = (m00 * x + m01 * y + m02 * z) * iw
        tv = (m10 * x + m11 * y + m12 * z) * iw
        a = -den
        k = 0
        for j in range(1, L):
            k += a <= thr[j]
        f = inv_f[k]
        n = size[k]
        tu = (tu + half) * f - half
        tv = (tv + half) * f - half
        tu = tu - np.floor(tu / n) * n + off[k]
        tv = tv - np.floor(tv / n) * n
        far = den >= -min_den
        invalid = (x == zero) & (y == zero) & (z == zero)
        special_v = black_v if invalid else (sky_v if den >= zero else haze_v)
        use_special = far | invalid
        mapx[i] = one if use_special else tu
        mapy[i] = special_v if use_special else tv


@numba.njit(cache=True, fastmath=_FASTMATH, error_model="numpy", boundscheck=False)
def _deck_maps_row(rx, ry, rz, M, umax, vmax, mapx, mapy, mask):  # type: ignore[no-untyped-def]
    """One image row of deck texture coordinates and the hit mask (1 where the ray hits the deck
    rectangle in front of the camera: ``den = d_Pz < 0`` and inside the texture's extent). Branch-free,
    so LLVM vectorises it."""
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = M[0], M[1], M[2], M[3], M[4], M[5], M[6], M[7], M[8]
    lo = np.float32(-0.5)
    one = np.float32(1.0)
    zero = np.float32(0.0)
    for i in range(rx.shape[0]):
        x = rx[i]
        y = ry[i]
        z = rz[i]
        den = m20 * x + m21 * y + m22 * z
        iw = one / den
        tu = (m00 * x + m01 * y + m02 * z) * iw
        tv = (m10 * x + m11 * y + m12 * z) * iw
        hit = (den < zero) & (tu >= lo) & (tv >= lo) & (tu <= umax) & (tv <= vmax)
        mapx[i] = tu if hit else lo
        mapy[i] = tv if hit else lo
        mask[i] = np.uint8(hit)


@numba.njit(cache=True, boundscheck=False)
def _deck_maps(rx, ry, rz, M, umax, vmax, v0, v1, u0, u1, mapx, mapy, mask):  # type: ignore[no-untyped-def]
    """Deck maps and mask over the image rows ``v0:v1`` and columns ``u0:u1`` (outputs of that size)."""
    for v in range(v0, v1):
        r = v - v0
        _deck_maps_row(rx[v, u0:u1], ry[v, u0:u1], rz[v, u0:u1], M, umax, vmax, mapx[r], mapy[r], mask[r])


# --------------------------------------------------------------------------------------------------
# Texture preparation (cached: campaigns build many renderers with the same pad)
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class _Level:
    image: NDArray[np.uint8]
    H: FloatArray  # P or W plane point (x, y, 1) -> pixel (u, v, 1)
    texel_m: float  # size of one texel (m)


def _deck_pyramid(*args: object) -> tuple[_Level, ...]:
    """Deck texture levels, cached when the pad is hashable (the frozen dataclasses of ``alight.pads``)."""
    try:
        hash(args)
    except TypeError:
        return _build_deck_pyramid(*args)  # type: ignore[arg-type]
    return _cached_deck_pyramid(*args)


@functools.lru_cache(maxsize=8)
def _cached_deck_pyramid(*args: object) -> tuple[_Level, ...]:
    return _build_deck_pyramid(*args)  # type: ignore[arg-type]


def _build_deck_pyramid(
    pad: PadDesign,
    px_per_m: float,
    length_m: float,
    width_m: float,
    gray: float,
    shadow: tuple[tuple[float, float], ...] | None,
    shadow_gain: float,
    color: bool = False,
) -> tuple[_Level, ...]:
    poly = None if shadow is None else np.asarray(shadow, dtype=np.float64)
    deck: DeckTexture = make_deck_texture(
        pad,
        px_per_m,
        length_m=length_m,
        width_m=width_m,
        deck_gray=gray,
        rng=np.random.default_rng(0),  # the deck's stains are part of the platform, not of a scenario
        shadow_polygon_P=poly,
        shadow_gain=shadow_gain,
        color=color,
    )
    levels = []
    # uint8 throughout: OpenCV's stubs return MatLike, without the (preserved) dtype
    img: NDArray[Any] = cv2.cvtColor(deck.image, cv2.COLOR_BGR2BGRA) if color else deck.image
    L, W = deck.length_m, deck.width_m
    while True:
        rows, cols = img.shape[:2]
        su, sv = cols / W, rows / L
        H = np.array([[0.0, -su, su * W / 2 - 0.5], [-sv, 0.0, sv * L / 2 - 0.5], [0.0, 0.0, 1.0]])
        levels.append(_Level(img, H, 1.0 / min(su, sv)))
        if min(rows, cols) < 16:
            break
        img = cv2.resize(img, ((cols + 1) // 2, (rows + 1) // 2), interpolation=cv2.INTER_AREA)
    for lev in levels:
        lev.image.setflags(write=False)
    return tuple(levels)


def _ground_pyramid(
    ground: GroundTexture, sky: int | tuple[int, int, int], color: bool = False
) -> tuple[tuple[_Level, ...], int | tuple[int, ...]]:
    """Levels of the tile, each extended by a wrap-around row and column (so bilinear lookups at the
    tile's last texel read the first), and 6 constant rows: sky (n+1, n+2), haze (n+3, n+4) and black
    (n+5, n+6). Returns the levels and the haze intensity (per channel in colour). ``color``: BGRA
    levels (a grey tile replicated), else grey (a BGR tile as its luma); ``sky`` a DN or a BGR triple."""
    tile: NDArray[Any] = ground.image  # uint8; OpenCV's stubs return MatLike, without the dtype
    if color and tile.ndim == 2:
        tile = cv2.cvtColor(tile, cv2.COLOR_GRAY2BGRA)
    elif color:
        tile = cv2.cvtColor(tile, cv2.COLOR_BGR2BGRA)
    elif tile.ndim == 3:
        tile = cv2.cvtColor(tile, cv2.COLOR_BGR2GRAY)
    haze: int | tuple[int, ...]
    if color:
        haze = tuple(int(round(float(c))) for c in tile[..., :3].reshape(-1, 3).mean(axis=0)) + (255,)
        sky = (*sky, 255)  # type: ignore[misc]
    else:
        haze = int(round(float(tile.mean())))
    levels = []
    m = ground.m_per_px
    while True:
        n = tile.shape[0]
        ext = np.empty((n + 7, n + 1, *tile.shape[2:]), np.uint8)
        ext[:n, :n] = tile
        ext[n, :n] = tile[0]
        ext[: n + 1, n] = ext[: n + 1, 0]
        ext[n + 1 : n + 3] = sky
        ext[n + 3 : n + 5] = haze
        ext[n + 5 :] = 0
        ext.setflags(write=False)
        levels.append(_Level(ext, _ground_H(m, m / ground.m_per_px), m))
        if n % 2 or n < 16:
            break
        # a 2x2 box average of a periodic tile is periodic: the halving stays tileable
        tile = cv2.resize(tile, (n // 2, n // 2), interpolation=cv2.INTER_AREA)
        m *= 2.0
    return tuple(levels), haze


@dataclass(frozen=True, eq=False)
class _Atlas:
    """Every ground level side by side in one image, for a mip level per ray (:func:`_ground_maps_mip`)."""

    image: NDArray[np.uint8]
    size: NDArray[np.float32]  # tile side of each level (texels)
    off: NDArray[np.float32]  # first column of each level's block
    inv_f: NDArray[np.float32]  # 1 / (level texel / level-0 texel)
    texel_m: NDArray[np.float64]  # texel of each level (m)


def _ground_atlas(levels: tuple[_Level, ...]) -> _Atlas:
    """Level k's extended tile (tile, wrap-around row and column) at columns ``off[k]`` onwards, rows 0 to
    ``n_k``; below level 0's block its 6 constant rows (sky, haze, black) across the whole width."""
    n0 = levels[0].image.shape[0] - 7
    sizes = [lev.image.shape[1] - 1 for lev in levels]
    offs = np.concatenate([[0], np.cumsum([n + 1 for n in sizes])[:-1]])
    ch = levels[0].image.shape[2:]
    img = np.zeros((n0 + 7, int(sum(n + 1 for n in sizes)), *ch), np.uint8)
    for lev, n, o in zip(levels, sizes, offs, strict=True):
        img[: n + 1, o : o + n + 1] = lev.image[: n + 1]
    for r in (n0 + 1, n0 + 3, n0 + 5):  # the constant rows, a pair per value
        img[r : r + 2] = levels[0].image[r, 0]
    img.setflags(write=False)
    return _Atlas(
        img,
        np.array(sizes, np.float32),
        offs.astype(np.float32),
        np.array([n / n0 for n in sizes], np.float32),
        np.array([lev.texel_m for lev in levels]),
    )


def _ground_H(m_per_px: float, factor: float) -> FloatArray:
    """Ground point (x_W, y_W, 1) -> texel (u, v, 1) of a level ``factor`` times coarser than the tile
    (``GroundTexture.texel_of_W`` at level 0). A coarse texel averages ``factor`` fine ones, so its centre
    sits ``(factor - 1) / 2`` fine texels past the first one's."""
    s = 1.0 / m_per_px
    c = -0.5 + 0.5 / factor
    return np.array([[s, 0.0, c], [0.0, -s, c], [0.0, 0.0, 1.0]])


# --------------------------------------------------------------------------------------------------
# Renderer
# --------------------------------------------------------------------------------------------------


def _planes(rays: FloatArray, shape: tuple[int, int]) -> tuple[NDArray[np.float32], ...]:
    """Split (N, 3) rays into three contiguous float32 planes of ``shape``; invalid (NaN) rays become 0."""
    r = np.where(np.isfinite(rays).all(axis=1, keepdims=True), rays, 0.0).astype(np.float32)
    return tuple(np.ascontiguousarray(r[:, k].reshape(shape)) for k in range(3))


_RAY_CACHE_SIZE = 4
_RAY_CACHE: collections.OrderedDict[object, tuple] = collections.OrderedDict()  # type: ignore[type-arg]
"""Rays by camera parameters (:func:`_camera_key`), least recently used first. Bounded: one entry is
~5.4 MB for a 752 x 480 camera."""
_RAY_CACHE_BY_ID: weakref.WeakKeyDictionary[object, dict] = weakref.WeakKeyDictionary()  # type: ignore[type-arg]
"""Rays of camera objects that have no parameter key (not frozen dataclasses), by object."""


def _freeze(value: object) -> object:
    """A hashable stand-in for a camera parameter that equals another exactly when the values do."""
    if isinstance(value, np.ndarray):
        return ("ndarray", value.dtype.str, value.shape, value.tobytes())
    if isinstance(value, (tuple, list)):
        return (type(value).__name__, tuple(_freeze(v) for v in value))
    hash(value)  # TypeError for anything else that is not hashable
    return value


def _camera_key(camera: CameraModel) -> object | None:
    """The camera's type and constructor parameters when it is one of :mod:`alight.cameras`' models (frozen
    dataclasses): two such cameras with equal parameters have equal rays, so every mission's new
    ``PinholeCamera.default_downward()`` shares one entry. None for anything else (a camera model
    registered from outside the package is rendered without the shared cache)."""
    if not isinstance(camera, PinholeCamera | OmniCamera):
        return None
    try:
        return (
            type(camera).__module__,
            type(camera).__qualname__,
            tuple((f.name, _freeze(getattr(camera, f.name))) for f in dataclasses.fields(camera) if f.init),
        )
    except TypeError:
        return None


def _camera_rays(camera: CameraModel, pyrup: bool) -> tuple:  # type: ignore[type-arg]
    """Unit rays of every pixel (three (H, W) float32 planes), of the half-resolution grid (three flat
    planes) and the angle between neighbouring pixels at the image centre (rad). Unprojecting 360 k
    pixels costs ~0.1 s, more than a few seconds of simulated flight, so the rays are cached by the
    camera's parameters (bounded, least recently used out) or, for a camera that has no parameter key,
    by the camera object."""
    key = _camera_key(camera)
    try:
        if key is not None:
            out = _RAY_CACHE[(key, pyrup)]
            _RAY_CACHE.move_to_end((key, pyrup))
            return out
        return _RAY_CACHE_BY_ID[camera][pyrup]  # type: ignore[no-any-return]
    except (KeyError, TypeError):
        pass
    out = _unproject_grid(camera, pyrup)
    if key is not None:
        _RAY_CACHE[(key, pyrup)] = out
        while len(_RAY_CACHE) > _RAY_CACHE_SIZE:
            _RAY_CACHE.popitem(last=False)
    else:
        try:
            _RAY_CACHE_BY_ID.setdefault(camera, {})[pyrup] = out
        except TypeError:
            pass  # a camera object that cannot be weakly referenced: no caching
    return out


def _unproject_grid(camera: CameraModel, pyrup: bool) -> tuple:  # type: ignore[type-arg]
    """The rays of :func:`_camera_rays`, computed."""
    W, H = int(camera.width), int(camera.height)
    v, u = np.mgrid[0:H, 0:W]
    uv = np.stack([u.ravel(), v.ravel()], axis=1).astype(np.float64)
    rx, ry, rz = _planes(camera.unproject(uv), (H, W))
    H2, W2 = (H + 1) // 2, (W + 1) // 2
    v2, u2 = np.mgrid[0:H2, 0:W2]
    # upsampled with cv2.pyrUp when the size is even (src pixel i at dst 2i, and faster than resize),
    # else with cv2.resize (src pixel i at dst (i + 0.5) W / W2 - 0.5)
    if pyrup:
        uv2 = np.stack([2.0 * u2.ravel(), 2.0 * v2.ravel()], axis=1).astype(np.float64)
    else:
        uv2 = np.stack([(u2.ravel() + 0.5) * W / W2 - 0.5, (v2.ravel() + 0.5) * H / H2 - 0.5], axis=1)
    hx, hy, hz = (a.ravel() for a in _planes(camera.unproject(uv2), (H2, W2)))
    c = np.array([[(W - 1) / 2, (H - 1) / 2], [(W - 1) / 2 + 1, (H - 1) / 2]])
    rc = camera.unproject(c)
    pixel_angle = float(np.arccos(np.clip(rc[0] @ rc[1], -1.0, 1.0)))
    if not (pixel_angle > 0):
        # no ray at the image centre (a catadioptric camera's mirror hole, an off-centre image circle):
        # the angle between neighbours at the valid pixel pair of the middle row closest to the centre
        row = np.stack([rx[H // 2], ry[H // 2], rz[H // 2]], axis=1).astype(np.float64)
        ok = np.flatnonzero(np.any(row[:-1] != 0, axis=1) & np.any(row[1:] != 0, axis=1))
        if len(ok):
            j = int(ok[np.argmin(np.abs(ok - (W - 1) / 2))])
            a, b = row[j], row[j + 1]
            pixel_angle = float(np.arctan2(np.linalg.norm(np.cross(a, b)), a @ b))
    if not (pixel_angle > 0):
        raise ValueError("the camera has no valid ray on its middle image row")
    for a in (rx, ry, rz, hx, hy, hz):
        a.setflags(write=False)
    return (rx, ry, rz, hx, hy, hz, pixel_angle)


@dataclass
class _Buffers:
    gmx: NDArray[np.float32]
    gmy: NDArray[np.float32]
    half: NDArray[np.uint8]
    pmx: NDArray[np.float32] = field(repr=False)
    pmy: NDArray[np.float32] = field(repr=False)
    mask: NDArray[np.uint8] = field(repr=False)
    tmp: NDArray[np.uint8] = field(repr=False)
    half4: NDArray[np.uint8] | None = field(default=None, repr=False)  # colour: BGRA samples
    tmp4: NDArray[np.uint8] | None = field(default=None, repr=False)


class Renderer:
    """Renders grayscale or BGR colour images of the ground and the platform's pad through a camera model.

    ``camera``: any :class:`~alight.cameras.CameraModel`; ``ground_texture``: the tileable ground;
    ``pad``: a :class:`~alight.pads.PadDesign`; ``options``: :class:`RenderOptions`; ``rng``: the
    generator of the sensor noise (needed when ``options.noise_sigma_dn > 0``); ``R_BC``: camera mount
    rotation, used only to turn body rates into image motion blur (default: the downward mount).
    """

    def __init__(
        self,
        camera: CameraModel,
        ground_texture: GroundTexture,
        pad: PadDesign,
        options: RenderOptions | None = None,
        rng: np.random.Generator | None = None,
        *,
        R_BC: FloatArray | None = None,
    ) -> None:
        self.camera = camera
        self.ground = ground_texture
        self.pad = pad
        self.options = options if options is not None else RenderOptions()
        opt = self.options
        if opt.noise_sigma_dn > 0 and rng is None:
            raise ValueError("a numpy Generator (rng) is needed for the sensor noise")
        self._rng = rng
        self._R_BC = np.asarray(CameraMount.downward().R_BC if R_BC is None else R_BC, dtype=np.float64)
        self.width, self.height = int(camera.width), int(camera.height)
        valid, fisheye = self._init_rays()
        self._init_textures(fisheye)
        self._init_effects(valid, rng)
        self._init_buffers()

    def _init_rays(self) -> tuple[NDArray[np.bool_], bool]:
        """Step 1: the per-pixel rays, full and half resolution (cached by the camera's parameters).
        Returns which pixels have a ray, and whether the camera sees rays over 75 deg off its axis."""
        W, H = self.width, self.height
        self._pyrup = H % 2 == 0 and W % 2 == 0
        rays = _camera_rays(self.camera, self._pyrup)
        self._rx, self._ry, self._rz, self._hx, self._hy, self._hz, self._pixel_angle = rays
        self._half_shape = ((H + 1) // 2, (W + 1) // 2)

        # rays with z_C <= 0 (a field of view over 180 deg), rays over 75 deg off the optical axis (a
        # fisheye's), and pixels without a ray
        valid = (self._rx != 0) | (self._ry != 0) | (self._rz != 0)
        self._wide = bool(np.any((self._rz <= 0) & valid))
        fisheye = bool(np.any((self._rz < math.cos(math.radians(75.0))) & valid))
        return valid, fisheye

    def _init_textures(self, fisheye: bool) -> None:
        """Step 2: the ground's and the deck's mip pyramids, and the deck's outline in P."""
        opt = self.options
        self._color = bool(opt.color)
        self._chan: tuple[int, ...] = (3,) if self._color else ()
        sky: int | tuple[int, int, int] = int(opt.sky_dn)
        if self._color:
            sky = opt.sky_bgr if opt.sky_bgr is not None else (int(opt.sky_dn),) * 3
        self._glevels, self._haze = _ground_pyramid(self.ground, sky, self._color)
        # a fisheye sees from the nadir to the horizon at once: one level for the frame would alias the
        # far ground badly, so it picks a level per ray from an atlas of all levels
        self._atlas = _ground_atlas(self._glevels) if fisheye else None
        deck_args: tuple[object, ...] = (
            self.pad,
            float(opt.pad_px_per_m),
            float(opt.deck_length_m),
            float(opt.deck_width_m),
            float(opt.deck_gray_dn),
            opt.shadow_polygon_P,
            float(opt.shadow_gain),
        )
        self._dlevels = _deck_pyramid(*deck_args, True) if self._color else _deck_pyramid(*deck_args)
        L0 = self._dlevels[0]
        rows0, cols0 = L0.image.shape[:2]
        Hinv = np.linalg.inv(L0.H)
        edge = np.array([[-0.5, -0.5], [cols0 - 0.5, -0.5], [cols0 - 0.5, rows0 - 0.5], [-0.5, rows0 - 0.5]])
        q = np.c_[edge, np.ones(4)] @ Hinv.T
        corners = q[:, :2] / q[:, 2:]
        self.deck_corners_P = np.c_[corners, np.zeros(4)]
        """Deck rectangle corners in P (m), shape (4, 3)."""
        t = np.linspace(0.0, 1.0, 17)[:-1, None]
        self._outline_P = np.concatenate(
            [np.c_[(1 - t) * corners[k] + t * corners[(k + 1) % 4], np.zeros(len(t))] for k in range(4)]
        )

    def _init_effects(self, valid: NDArray[np.bool_], rng: np.random.Generator | None) -> None:
        """Step 3: the brightness lookup table, the vignetting, the mask of pixels without a ray and the
        sensor-noise bank (the only draw from ``rng``)."""
        opt = self.options
        W, H = self.width, self.height
        self._drift_factor = 1.0
        self._lut, self._lut_identity = self._make_lut(1.0)
        self._vignette: NDArray[np.uint8] | None = None
        if opt.vignetting > 0:
            # cos^4 of the angle to the optical axis (unit rays; 0 past 90 deg and for pixels without a ray)
            cos4 = np.clip(self._rz.astype(np.float64), 0.0, 1.0) ** 4
            lo = float(cos4.min())
            gain = 1.0 - opt.vignetting * (1.0 - cos4) / max(1.0 - lo, 1e-9)
            # as uint8 (gain x 255): a uint8 x uint8 multiply is several times faster than one by float32
            vignette: NDArray[Any] = np.clip(np.rint(255.0 * gain), 0, 255).astype(np.uint8)
            if self._color:
                vignette = cv2.cvtColor(vignette, cv2.COLOR_GRAY2BGR)  # still uint8 (MatLike in the stubs)
            self._vignette = vignette
        # pixels without a ray are black after every effect (blur, pyrUp and noise would spill into them)
        self._valid: NDArray[np.uint8] | None = None
        if not valid.all():
            v8 = np.where(valid, np.uint8(255), np.uint8(0))
            valid8: NDArray[Any] = cv2.cvtColor(v8, cv2.COLOR_GRAY2BGR) if self._color else v8
            self._valid = valid8
        # sensor noise: one bank of Gaussian samples twice the image size, from which each frame takes a
        # window at a random offset (drawing 360 k normals per frame would cost 4 ms). Stored as its
        # positive and negative parts in uint8, so adding it is two saturating uint8 operations, which
        # equal the saturated sum because only one of the two is non-zero at any pixel.
        self._noise_pos: NDArray[np.uint8] | None = None
        self._noise_neg: NDArray[np.uint8] | None = None
        if opt.noise_sigma_dn > 0 and rng is not None:
            bank = np.rint(
                rng.standard_normal((2 * H, 2 * W, *self._chan), dtype=np.float32)
                * np.float32(opt.noise_sigma_dn)
            )
            self._noise_pos = np.clip(bank, 0, 255).astype(np.uint8)
            self._noise_neg = np.clip(-bank, 0, 255).astype(np.uint8)

    def _init_buffers(self) -> None:
        """The scratch arrays every frame reuses."""
        W, H = self.width, self.height
        H2, W2 = self._half_shape
        C = 3 if self._color else 1
        self._buf = _Buffers(
            gmx=np.empty(H2 * W2, np.float32),
            gmy=np.empty(H2 * W2, np.float32),
            half=np.empty((H2, W2, *self._chan), np.uint8),
            pmx=np.empty(H * W, np.float32),
            pmy=np.empty(H * W, np.float32),
            mask=np.empty(H * W, np.uint8),
            tmp=np.empty(H * W * C, np.uint8),
            half4=np.empty((H2, W2, 4), np.uint8) if self._color else None,
            tmp4=np.empty(H * W * 4, np.uint8) if self._color else None,
        )

    def _make_lut(self, drift: float) -> tuple[NDArray[np.uint8], bool]:
        """The lookup table of exposure, illumination (times ``drift``) and gamma: shape (256,) for grey,
        (1, 256, 3) per channel for colour; and whether it is the identity."""
        opt = self.options
        x = np.arange(256, dtype=np.float64) / 255.0
        illum = opt.illumination_gain_bgr
        if self._color:
            g = opt.exposure_gain * drift * np.asarray(illum)
            lut = 255.0 * np.clip(x[:, None] * g[None, :], 0.0, 1.0) ** opt.gamma
            out = np.clip(np.rint(lut), 0, 255).astype(np.uint8).reshape(1, 256, 3)
            return out, bool(np.all(out == np.arange(256)[None, :, None]))
        gain = opt.exposure_gain
        if illum != (1.0, 1.0, 1.0):
            gain = gain * float(np.dot(illum, _LUMA_BGR))
        if drift != 1.0:
            gain = gain * drift
        lut = 255.0 * np.clip(x * gain, 0.0, 1.0) ** opt.gamma
        out = np.clip(np.rint(lut), 0, 255).astype(np.uint8)
        return out, bool(np.all(out == np.arange(256)))

    # ------------------------------------------------------------------------------------------------

    def render(
        self,
        p_WC: FloatArray,
        R_WC: FloatArray,
        platform_pose: tuple[FloatArray, float],
        w_WB_B: FloatArray | None = None,
        *,
        t_s: float | None = None,
        noise_offset: tuple[int, int] | None = None,
        R_WP: FloatArray | None = None,
    ) -> NDArray[np.uint8]:
        """The camera image, uint8, shape (height, width) (grey) or (height, width, 3) (BGR, with
        ``RenderOptions.color``), a new array on every call.

        ``p_WC`` (3,) camera centre in W (m); ``R_WC`` (3, 3) camera orientation; ``platform_pose`` =
        ``(p_WP (3,), yaw)``, the pad centre in W (m, its z is the deck height) and the platform heading
        (rad); ``w_WB_B`` (3,) body rates (rad/s) for the motion blur (ignored when the exposure time is 0);
        ``t_s`` the capture time (s) for the brightness drift (ignored when there is none);
        ``noise_offset`` the frame's window into the sensor-noise bank from :meth:`draw_noise_offset`
        (default: drawn now); ``R_WP`` (3, 3) the deck's orientation when it tilts (a vessel at sea; the
        yaw is then not used), None: level, turned by ``yaw``.
        """
        p_WC = np.asarray(p_WC, dtype=np.float64)
        R_WC = np.asarray(R_WC, dtype=np.float64)
        p_WP = np.asarray(platform_pose[0], dtype=np.float64)
        yaw = float(platform_pose[1])
        if p_WC.shape != (3,) or R_WC.shape != (3, 3) or p_WP.shape != (3,):
            raise ValueError("render needs p_WC (3,), R_WC (3, 3) and platform_pose (p_WP (3,), yaw)")
        if not math.isfinite(float(p_WC.sum() + R_WC.sum() + p_WP.sum())):
            raise ValueError("render needs a finite camera pose and platform pose")
        if not math.isfinite(yaw):
            raise ValueError(f"platform yaw must be finite, got {yaw}")
        opt = self.options
        if opt.brightness_drift > 0 and t_s is not None:
            t = float(t_s)
            if not math.isfinite(t):
                raise ValueError(f"t_s must be finite, got {t_s}")
            drift = 1.0 + opt.brightness_drift * math.sin(2.0 * math.pi * t / opt.brightness_drift_period_s)
            if drift != self._drift_factor:
                self._drift_factor = drift
                self._lut, self._lut_identity = self._make_lut(drift)
        H, W = self.height, self.width
        out = np.empty((H, W, *self._chan), np.uint8)

        if R_WP is not None:
            R_WP = np.asarray(R_WP, dtype=np.float64)
            if R_WP.shape != (3, 3) or not np.isfinite(R_WP).all():
                raise ValueError("render needs a finite deck orientation R_WP (3, 3)")
        deck = self._deck_maps(p_WC, R_WC, p_WP, yaw, R_WP)
        if deck is not None and deck[0] == (0, H, 0, W) and deck[2] == H * W:
            # the deck fills the image: no ground to draw, remap straight into the output
            b = self._buf
            lev = deck[1]
            mx, my = b.pmx.reshape(H, W), b.pmy.reshape(H, W)
            if b.tmp4 is None:
                cv2.remap(lev.image, mx, my, cv2.INTER_LINEAR, dst=out, borderMode=cv2.BORDER_REPLICATE)
            else:
                t4 = b.tmp4.reshape(H, W, 4)
                cv2.remap(lev.image, mx, my, cv2.INTER_LINEAR, dst=t4, borderMode=cv2.BORDER_REPLICATE)
                cv2.cvtColor(t4, cv2.COLOR_BGRA2BGR, dst=out)
        else:
            self._draw_ground(p_WC, R_WC, out)
            if deck is not None:
                self._composite_deck(out, deck[0], deck[1])
        return self._effects(out, w_WB_B, noise_offset)

    @property
    def frame_shape(self) -> tuple[int, ...]:
        """The shape of a rendered frame: (height, width), or (height, width, 3) in colour."""
        return (self.height, self.width, *self._chan)

    def draw_noise_offset(self) -> tuple[int, int] | None:
        """Draw the sensor noise of one frame (its window into the noise bank) from the renderer's
        generator, the draw :meth:`render` makes when it is not given one; None without noise. A caller
        that renders only some frames draws this for every frame, in capture order, so a frame not
        rendered does not shift the noise of the later ones."""
        if self._noise_pos is None or self._rng is None:
            return None
        oy, ox = (int(a) for a in self._rng.integers(0, (self.height, self.width)))
        return oy, ox

    # ------------------------------------------------------------------------------------------------

    def _level(self, levels: tuple[_Level, ...], footprint_m: float) -> _Level:
        """The coarsest level whose texel is no larger than the pixel footprint."""
        k = 0
        while k + 1 < len(levels) and levels[k + 1].texel_m <= footprint_m:
            k += 1
        return levels[k]

    def _draw_ground(self, p_WC: FloatArray, R_WC: FloatArray, out: NDArray[np.uint8]) -> None:
        opt = self.options
        h = max(float(p_WC[2]), _MIN_HEIGHT_M)
        # footprint of a half-resolution pixel where the optical axis meets the ground (or at a grazing
        # ray when it does not): geometric mean of the along- and across-range sizes
        dz = min(float(R_WC[2, 2]), -0.05)
        rng_m = min(h / -dz, opt.max_range_m)
        foot = rng_m * 2.0 * self._pixel_angle / math.sqrt(-dz)
        tile_m = self._glevels[0].texel_m * (self._glevels[0].image.shape[0] - 7)
        px, py = math.fmod(float(p_WC[0]), tile_m), math.fmod(float(p_WC[1]), tile_m)
        N = np.array([[-h, 0.0, px], [0.0, -h, py], [0.0, 0.0, 1.0]])
        b = self._buf
        min_den = np.float32(h / opt.max_range_m)
        if self._atlas is None:
            lev = self._level(self._glevels, foot)
            image = lev.image
            M = (lev.H @ N @ R_WC).astype(np.float32).ravel()
            n = lev.image.shape[1] - 1
            _ground_maps(self._hx, self._hy, self._hz, M, min_den, n, b.gmx, b.gmy)
        else:
            at = self._atlas
            image = at.image
            # a half-resolution pixel's footprint on the ground, at cos(angle to the nadir) = a:
            # 2 pa h / a^2 along the range, 2 pa h / a across, geometric mean K a^-1.5; the level's texel
            # is reached where a^1.5 <= K / texel. The nadir has the smallest footprint: K.
            K = 2.0 * self._pixel_angle * h
            thr = ((K / at.texel_m) ** (2.0 / 3.0)).astype(np.float32)
            M = (self._glevels[0].H @ N @ R_WC).astype(np.float32).ravel()
            n0 = self._glevels[0].image.shape[0] - 7
            _ground_maps_mip(
                self._hx, self._hy, self._hz, M, min_den, thr, at.inv_f, at.size, at.off, n0, b.gmx, b.gmy
            )
            foot = K
        H2, W2 = self._half_shape
        # nearest-texel lookup is 3x cheaper and, with the mip level at one to two texels per pixel (or
        # magnified up to 2x) and pyrUp's Gaussian after it, looks the same; bilinear only below that
        interp = cv2.INTER_NEAREST if foot >= 0.5 * self._glevels[0].texel_m else cv2.INTER_LINEAR
        cv2.remap(
            image,
            b.gmx.reshape(H2, W2),
            b.gmy.reshape(H2, W2),
            interp,
            dst=b.half if b.half4 is None else b.half4,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=0,
        )
        if b.half4 is not None:
            cv2.cvtColor(b.half4, cv2.COLOR_BGRA2BGR, dst=b.half)  # pyrUp is faster on 3 channels
        if self._pyrup:
            cv2.pyrUp(b.half, dst=out, dstsize=(self.width, self.height))
        else:
            cv2.resize(b.half, (self.width, self.height), dst=out, interpolation=cv2.INTER_LINEAR)

    def _deck_maps(
        self, p_WC: FloatArray, R_WC: FloatArray, p_WP: FloatArray, yaw: float, R_WP: FloatArray | None
    ) -> tuple[tuple[int, int, int, int], _Level, int] | None:
        """Deck texture maps and hit mask over the deck's bounding box in the image (into the buffers).
        Returns ``((v0, v1, u0, u1), texture level, number of deck pixels)``, or None when no deck pixel
        is visible. ``R_WP``: a tilted deck's orientation (None: level, turned by ``yaw``)."""
        if R_WP is None:
            h_p = float(p_WC[2] - p_WP[2])
            if h_p <= _MIN_HEIGHT_M:
                return None  # at or below the deck plane: the deck's top is not visible
            c, s = math.cos(yaw), math.sin(yaw)
            R_WP = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
            p_PC = R_WP.T @ (p_WC - p_WP)
        else:
            p_PC = R_WP.T @ (p_WC - p_WP)
            h_p = float(p_PC[2])  # the camera's height above the tilted deck's plane
            if h_p <= _MIN_HEIGHT_M:
                return None
        R_PC = R_WP.T @ R_WC
        H, W = self.height, self.width
        # bounding box of the deck's image from its outline (the whole image if part of it is behind
        # the camera or outside the lens model, where the outline does not bound the image)
        X_C = (self._outline_P - p_PC) @ R_PC
        if np.all(X_C[:, 2] <= 0) and not self._wide:
            return None  # the whole deck is behind the camera
        u0, u1, v0, v1 = 0, W, 0, H
        # a camera that sees past 90 deg projects points behind its image plane (NaN where it cannot)
        if self._wide or np.all(X_C[:, 2] > 1e-6):
            uv = self.camera.project(X_C)
            if np.isfinite(uv).all():
                u0 = max(int(math.floor(uv[:, 0].min())) - 2, 0)
                u1 = min(int(math.ceil(uv[:, 0].max())) + 3, W)
                v0 = max(int(math.floor(uv[:, 1].min())) - 2, 0)
                v1 = min(int(math.ceil(uv[:, 1].max())) + 3, H)
        if u1 <= u0 or v1 <= v0:
            return None
        # texel no larger than the pixel footprint at the pad centre (geometric mean of the along- and
        # across-range footprints on the tilted plane)
        dist = float(np.linalg.norm(p_PC))
        foot = dist * self._pixel_angle / math.sqrt(max(h_p / max(dist, 1e-9), 0.05))
        lev = self._level(self._dlevels, foot)
        N = np.array([[-h_p, 0.0, p_PC[0]], [0.0, -h_p, p_PC[1]], [0.0, 0.0, 1.0]])
        M = (lev.H @ N @ R_PC).astype(np.float32).ravel()
        rows, cols = lev.image.shape[:2]
        nr, nc = v1 - v0, u1 - u0
        b = self._buf
        mask = b.mask[: nr * nc].reshape(nr, nc)
        _deck_maps(
            self._rx, self._ry, self._rz, M, np.float32(cols - 0.5), np.float32(rows - 0.5),
            v0, v1, u0, u1, b.pmx[: nr * nc].reshape(nr, nc), b.pmy[: nr * nc].reshape(nr, nc), mask,
        )  # fmt: skip
        count = int(cv2.countNonZero(mask))
        return None if count == 0 else ((v0, v1, u0, u1), lev, count)

    def _composite_deck(self, out: NDArray[np.uint8], roi: tuple[int, int, int, int], lev: _Level) -> None:
        """Sample the deck over ``roi`` with the maps of :meth:`_deck_maps` and copy it where it is hit."""
        v0, v1, u0, u1 = roi
        nr, nc = v1 - v0, u1 - u0
        b = self._buf
        tmp = b.tmp[: nr * nc * (3 if self._color else 1)].reshape(nr, nc, *self._chan)
        cv2.remap(
            lev.image,
            b.pmx[: nr * nc].reshape(nr, nc),
            b.pmy[: nr * nc].reshape(nr, nc),
            cv2.INTER_LINEAR,
            dst=tmp if b.tmp4 is None else b.tmp4[: nr * nc * 4].reshape(nr, nc, 4),
            borderMode=cv2.BORDER_REPLICATE,
        )
        if b.tmp4 is not None:
            cv2.cvtColor(b.tmp4[: nr * nc * 4].reshape(nr, nc, 4), cv2.COLOR_BGRA2BGR, dst=tmp)
        cv2.copyTo(tmp, b.mask[: nr * nc].reshape(nr, nc), out[v0:v1, u0:u1])  # in place into the view

    def _effects(
        self, image: NDArray[np.uint8], w_WB_B: FloatArray | None, noise_offset: tuple[int, int] | None = None
    ) -> NDArray[np.uint8]:
        opt = self.options
        img: NDArray[Any] = image  # stays uint8; OpenCV's stubs return MatLike, without the dtype
        if self._vignette is not None:
            img = cv2.multiply(img, self._vignette, scale=1.0 / 255.0)
        if opt.exposure_time_s > 0 and w_WB_B is not None:
            w_C = self._R_BC.T @ np.asarray(w_WB_B, dtype=np.float64)
            k = _motion_blur_kernel(w_C, opt.exposure_time_s, 1.0 / self._pixel_angle)
            if k is not None:
                img = cv2.filter2D(img, -1, k, borderType=cv2.BORDER_REPLICATE)
        if not self._lut_identity:
            img = cv2.LUT(img, self._lut)
        off = noise_offset if noise_offset is not None else self.draw_noise_offset()
        if self._noise_pos is not None and self._noise_neg is not None and off is not None:
            H, W = self.height, self.width
            oy, ox = off
            cv2.add(img, self._noise_pos[oy : oy + H, ox : ox + W], dst=img)
            cv2.subtract(img, self._noise_neg[oy : oy + H, ox : ox + W], dst=img)
        if self._valid is not None:
            cv2.bitwise_and(img, self._valid, dst=img)
        return img


def _motion_blur_kernel(w_C: FloatArray, exposure_s: float, f_px: float) -> NDArray[np.float32] | None:
    """Line kernel of the image motion at the image centre during the exposure: a point fixed in the
    world moves as ``dX_C/dt = -w_C x X_C``, so at the centre ``du/dt = -f w_y``, ``dv/dt = f w_x``
    (rotation about the optical axis, which blurs the edges only, is ignored). ``None`` below 0.5 px."""
    bu = -f_px * float(w_C[1]) * exposure_s
    bv = f_px * float(w_C[0]) * exposure_s
    length = math.hypot(bu, bv)
    if not (length >= 0.5) or not math.isfinite(length):
        return None
    half = int(math.ceil(length / 2)) + 1
    size = 2 * half + 1
    shift = 4
    k = np.zeros((size, size), np.float32)
    p0 = (int(round((half - bu / 2) * (1 << shift))), int(round((half - bv / 2) * (1 << shift))))
    p1 = (int(round((half + bu / 2) * (1 << shift))), int(round((half + bv / 2) * (1 << shift))))
    cv2.line(k, p0, p1, 1.0, thickness=1, lineType=cv2.LINE_AA, shift=shift)
    total = float(k.sum())
    if total <= 0:
        return None
    return k / np.float32(total)
