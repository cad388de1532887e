"""An animated GIF replay of one mission: what the onboard camera saw (with the detections drawn on the
image), a top view of both vehicles, and an altitude strip.

Layout: with camera frames, the camera panel is on the left and the top view on the right; without
(presets that do not use the camera) the top view is alone. The altitude strip runs along the bottom,
under a band of the mission modes, with a cursor at the current time.

How a GIF is made, cheaply enough to write one for every failed mission of a campaign:

1. Everything that does not move (axes, grid, the whole paths drawn faint, the mode band, labels) is
   drawn once with matplotlib into an RGB background; its data-to-pixel transforms are then used to
   turn the whole log into pixel coordinates at once.
2. Each GIF frame is a copy of the background with the moving parts drawn by OpenCV (trails up to now,
   the pad, the vehicles, the estimate, the camera image and its detections, text).
3. Frames are mapped to one fixed 255-colour palette (32 greys for the camera image, the drawing colours,
   the background's colours) through a lookup table on 5-bit RGB, so there is no per-frame palette, and
   Pillow stores each frame as its difference to the previous one (unchanged pixels transparent).

Size: the playback runs at ``fps`` frames per simulated second; a mission longer than ``max_seconds``
is sped up to fit in ``max_seconds`` of playback, so a GIF has at most ``fps * max_seconds + 2`` frames
whatever the mission's length. Camera frames are downscaled to the panel (376 px wide), blurred a little
and cut to 16 grey levels, and the camera panel is refreshed at most ``camera_hz`` times per second of
playback, which bounds the bytes it adds. Measured with the defaults: a 60 s falanga2017 mission
(2x, 301 frames) with the camera is 2.1 MB; 19 s (188 frames) 1.4 MB; top view only about 2.5 kB a frame.

The replay is an evaluation artefact: it reads ground truth and writes a file.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import cast

import cv2
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from numpy.typing import NDArray
from PIL import Image
from scipy.spatial import cKDTree

from alight.evaluation.plots import MODE_COLORS, mode_color, mode_segments, new_figure
from alight.types import Observation

REPLAY_GIF = "replay.gif"
"""File name of the replay in a mission directory."""

Frame = tuple[float, NDArray[np.uint8], Sequence[Observation]]
"""One camera frame: capture time (s), the image (uint8, (H, W) grey or (H, W, 3) RGB), and the
observations the detector made on it (their pixels in this image's coordinates)."""

_UAV = (31, 119, 180)  # tab:blue
_UAV_FAINT = (178, 206, 228)
_PLATFORM = (214, 39, 40)  # tab:red
_PLATFORM_FAINT = (240, 180, 180)
_PAD_FILL = (250, 205, 200)
_ESTIMATE = (255, 127, 14)  # tab:orange
_DETECTION = (44, 160, 44)  # tab:green
_CURSOR = (60, 60, 60)
_TEXT = (31, 35, 40)
_WHITE = (255, 255, 255)
_CAMERA_BG = (40, 40, 40)
_CENTRE = (255, 230, 0)
_DRAW_COLORS = (_UAV, _PLATFORM, _PAD_FILL, _ESTIMATE, _DETECTION, _CURSOR, _TEXT, _WHITE, _CENTRE)
_N_GREYS = 32
_SHIFT = 4  # fixed-point bits of the pixel coordinates handed to OpenCV (sub-pixel, anti-aliased lines)
_FONT = cv2.FONT_HERSHEY_SIMPLEX
_END_HOLD_MS = 1500  # the last frame stays up this long, so the end of the mission can be seen

CAMERA_PANEL_WIDTH_PX = 376
"""Width of the camera panel (px); frames are downscaled to it."""


# --------------------------------------------------------------------------------------------------
# recording frames
# --------------------------------------------------------------------------------------------------


class FrameRecorder:
    """A ``frame_sink(t_capture, image, observations)`` that keeps camera frames for :func:`write_replay`.

    Keeps at most one frame per ``1 / rate_hz`` seconds of capture time, downscaled (area averaging) to
    at most ``max_width_px`` wide, with the observations' pixels scaled to match, and at most
    ``max_frames`` of them: when full, every other frame is dropped and the rate halved, so a long
    mission keeps frames evenly spread over its whole length. A replay shows at most about 90 camera
    images (``max_seconds`` x ``camera_hz`` of :func:`write_replay`), so the default 400 frames (40 s at
    10 Hz before the first halving) leave every camera refresh of the GIF a frame as recent as at 10 Hz
    up to 40 s, and within a refresh interval beyond. Memory: 400 x 376 x 282 x 3 bytes (127 MB) for a
    colour camera, 36 MB for a 752 x 480 grey one, whatever the mission's length (a 120 s colour mission
    kept 381 MB before the bound).

    Attributes:
        frames: the kept frames, in capture order, ready for ``write_replay(..., frames=...)``.
    """

    def __init__(
        self, *, rate_hz: float = 10.0, max_width_px: int = CAMERA_PANEL_WIDTH_PX, max_frames: int = 400
    ) -> None:
        if not (rate_hz > 0 and math.isfinite(rate_hz)):
            raise ValueError(f"rate_hz must be positive, got {rate_hz}")
        if max_width_px < 16:
            raise ValueError(f"max_width_px must be >= 16, got {max_width_px}")
        if max_frames < 2:
            raise ValueError(f"max_frames must be >= 2, got {max_frames}")
        self.rate_hz = float(rate_hz)
        self.max_width_px = int(max_width_px)
        self.max_frames = int(max_frames)
        self.period_s = 1.0 / self.rate_hz
        """The spacing of the kept frames now (s): ``1 / rate_hz``, doubled at each halving."""
        self.frames: list[Frame] = []
        self._t_next = -math.inf

    def wants(self, t_capture: float) -> bool:
        """Whether the frame captured at ``t_capture`` would be kept (the runner's ``frame_wanted``: a
        frame the detector skips is rendered only for this)."""
        # A small tolerance: capture times are multiples of the camera period, in floating point.
        return float(t_capture) + 1e-9 >= self._t_next

    def __call__(
        self, t_capture: float, image: NDArray[np.uint8], observations: Sequence[Observation]
    ) -> None:
        t = float(t_capture)
        if not self.wants(t):
            return
        self._t_next = t + self.period_s
        img = np.asarray(image)
        if img.dtype != np.uint8 or img.ndim not in (2, 3):
            raise ValueError(f"camera frames must be uint8 (H, W) or (H, W, 3), got {img.dtype} {img.shape}")
        h, w = img.shape[:2]
        scale = min(1.0, self.max_width_px / w)
        if scale < 1.0:
            size = (max(1, round(w * scale)), max(1, round(h * scale)))
            # uint8 like its input, so np.asarray converts nothing: OpenCV's stubs type it MatLike
            img = np.asarray(cv2.resize(img, size, interpolation=cv2.INTER_AREA), dtype=np.uint8)
            observations = [_scaled(o, size[0] / w, size[1] / h) for o in observations]
        else:
            img = img.copy()
        if img.ndim == 3:  # the camera's images are OpenCV's BGR; the replay's frames are RGB
            img = np.asarray(cv2.cvtColor(img, cv2.COLOR_BGR2RGB), dtype=np.uint8)
        self.frames.append((t, img, list(observations)))
        if len(self.frames) >= self.max_frames:
            del self.frames[1::2]  # the first frame stays: the spacing is even from the start
            self.period_s *= 2.0
            self._t_next = self.frames[-1][0] + self.period_s


def _scaled(obs: Observation, sx: float, sy: float) -> Observation:
    """The observation with its pixels in an image resized by (sx, sy)."""
    if obs.pixels.shape[0] == 0:
        return obs
    # pixel centres: (u + 0.5) scales with the image, so u' = (u + 0.5) s - 0.5
    return dataclasses.replace(obs, pixels=(obs.pixels + 0.5) * np.array([sx, sy]) - 0.5)


# --------------------------------------------------------------------------------------------------
# layout and background
# --------------------------------------------------------------------------------------------------


@dataclasses.dataclass
class _Layout:
    width: int
    height: int
    top: tuple[int, int, int, int]  # x, y, w, h of each axes box in image pixels (y down)
    alt: tuple[int, int, int, int]
    camera: tuple[int, int, int, int] | None
    time_xy: tuple[int, int]  # where the clock text goes (baseline left)


def _layout(with_camera: bool) -> _Layout:
    if with_camera:
        return _Layout(
            width=860,
            height=430,
            camera=(14, 50, CAMERA_PANEL_WIDTH_PX, 240),
            top=(466, 50, 380, 340),
            alt=(54, 322, 336, 68),
            time_xy=(700, 24),
        )
    return _Layout(
        width=520, height=480, camera=None, top=(64, 50, 430, 310), alt=(64, 398, 430, 44), time_xy=(330, 24)
    )


def _add_axes(fig: Figure, box: tuple[int, int, int, int], lay: _Layout) -> Axes:
    x, y, w, h = box
    return fig.add_axes((x / lay.width, 1.0 - (y + h) / lay.height, w / lay.width, h / lay.height))


def _finite_rows(a: np.ndarray) -> np.ndarray:
    rows: np.ndarray = np.isfinite(a).all(axis=1)  # .all(axis=...) is typed Any
    return rows


def _to_pixels(ax: Axes, xy: np.ndarray, height: int) -> np.ndarray:
    """Data coordinates (N, 2) -> image pixels (N, 2), y down, as float (NaN stays NaN)."""
    out = np.full(xy.shape, np.nan)
    ok = _finite_rows(xy)
    if ok.any():
        d = ax.transData.transform(xy[ok])
        out[ok, 0] = d[:, 0]
        out[ok, 1] = height - d[:, 1]
    return out


def _hex_rgb(color: str) -> tuple[int, int, int]:
    c = color.lstrip("#")
    return int(c[0:2], 16), int(c[2:4], 16), int(c[4:6], 16)


def _rgb01(c: tuple[int, int, int]) -> tuple[float, float, float]:
    return c[0] / 255, c[1] / 255, c[2] / 255


@dataclasses.dataclass
class _Scene:
    background: NDArray[np.uint8]
    uav_px: np.ndarray  # (N, 2) top-view pixels of the UAV
    plat_px: np.ndarray
    est_px: np.ndarray
    det_px: np.ndarray  # (M, 2)
    alt_uav_px: np.ndarray  # (N, 2) altitude strip pixels
    alt_plat_px: np.ndarray
    alt_t_px: np.ndarray  # (N,) x pixel of each sample time in the strip
    alt_y_range: tuple[float, float]  # y pixels of the strip's top and bottom
    px_per_m: float  # top-view scale


@dataclasses.dataclass
class _Tracks:
    """The log's channels the replay draws, as float arrays (nan where a channel is missing)."""

    t: np.ndarray  # (N,) sample times (s)
    p_WB: np.ndarray  # (N, 3) UAV position in W (m)
    p_WP: np.ndarray  # (N, 3) platform position in W (m)
    p_est: np.ndarray  # (N, 3) estimated platform position in W (m)
    p_det: np.ndarray  # (M, 3) detections' platform positions in W (m), in time order
    mode: np.ndarray  # (N,) the mission mode's name at each sample


def _tracks(log: Mapping[str, np.ndarray]) -> _Tracks:
    t = np.asarray(log["t"], dtype=np.float64)
    n = t.shape[0]
    p_WB = np.asarray(log["p_WB"], dtype=np.float64).reshape(n, 3)
    p_WP = _channel(log, "p_WP", n)
    p_est = _channel(log, "p_WP_est", n)
    p_det = np.asarray(log.get("p_WP_meas", np.zeros((0, 3))), dtype=np.float64).reshape(-1, 3)
    t_det = np.asarray(log.get("t_det", np.zeros(0)), dtype=np.float64).reshape(-1)
    if t_det.shape[0] != p_det.shape[0]:
        raise ValueError(f"t_det has {t_det.shape[0]} entries but p_WP_meas has {p_det.shape[0]}")
    p_det = p_det[np.argsort(t_det, kind="stable")]  # drawn in time order, as the frames reach them
    mode = np.asarray(log.get("mode", np.full(n, "", dtype=np.str_))).astype(str)
    return _Tracks(t=t, p_WB=p_WB, p_WP=p_WP, p_est=p_est, p_det=p_det, mode=mode)


def _draw_top_view(fig: Figure, lay: _Layout, tr: _Tracks) -> Axes:
    """The top view's faint tracks, equal-scale limits around them, and the legend."""
    p_WB, p_WP = tr.p_WB, tr.p_WP
    ax = _add_axes(fig, lay.top, lay)
    ax.plot(p_WP[:, 0], p_WP[:, 1], color=_rgb01(_PLATFORM_FAINT), lw=1.2)
    ax.plot(p_WB[:, 0], p_WB[:, 1], color=_rgb01(_UAV_FAINT), lw=1.2)
    pts = np.concatenate([p_WB[:, :2], p_WP[:, :2]])
    pts = pts[_finite_rows(pts)]
    if pts.shape[0] == 0:
        pts = np.zeros((1, 2))
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    mid = 0.5 * (lo + hi)
    # equal scale on both axes (the limits take the axes box's aspect ratio), at least 4 m across
    dx, dy = max(float(hi[0] - lo[0]), 4.0), max(float(hi[1] - lo[1]), 4.0)
    box_w, box_h = lay.top[2], lay.top[3]
    half_x = 0.55 * max(dx, dy * box_w / box_h)
    half_y = half_x * box_h / box_w
    ax.set_xlim(mid[0] - half_x, mid[0] + half_x)
    ax.set_ylim(mid[1] - half_y, mid[1] + half_y)
    ax.grid(True, lw=0.4, alpha=0.6)
    ax.tick_params(labelsize=7, pad=1)
    ax.set_xlabel("x (m)", fontsize=8, labelpad=1)
    ax.set_ylabel("y (m)", fontsize=8, labelpad=1)
    ax.set_title("top view", fontsize=9, loc="left", pad=3)
    handles = [
        ax.plot([], [], color=_rgb01(_UAV), lw=2, label="UAV")[0],
        ax.plot([], [], color=_rgb01(_PLATFORM), lw=2, label="platform")[0],
    ]
    if np.isfinite(tr.p_est).any():
        handles.append(
            ax.plot(
                [], [], ls="none", marker="o", mfc="none", mec=_rgb01(_ESTIMATE), mew=2, label="estimate"
            )[0]
        )
    if tr.p_det.shape[0]:
        handles.append(ax.plot([], [], ls="none", marker=".", color=_rgb01(_ESTIMATE), label="detections")[0])
    ax.legend(handles=handles, loc="lower right", fontsize=6.5, framealpha=0.85, handlelength=1.4)
    return ax


def _draw_altitude(fig: Figure, lay: _Layout, tr: _Tracks) -> Axes:
    """The altitude strip: the faint heights over time under a band of the mission's modes."""
    t, p_WB, p_WP = tr.t, tr.p_WB, tr.p_WP
    axa = _add_axes(fig, lay.alt, lay)
    axa.plot(t, p_WP[:, 2], color=_rgb01(_PLATFORM_FAINT), lw=1.0)
    axa.plot(t, p_WB[:, 2], color=_rgb01(_UAV_FAINT), lw=1.0)
    for m, t0, t1 in mode_segments(t, tr.mode):
        axa.axvspan(t0, t1, ymin=0.86, ymax=1.0, color=mode_color(m), lw=0)
    z = np.concatenate([p_WB[:, 2], p_WP[:, 2]])
    z = z[np.isfinite(z)]
    zmax = float(z.max()) if z.size else 1.0
    axa.set_ylim(min(0.0, float(z.min()) if z.size else 0.0), max(zmax, 1.0) * 1.18)
    axa.set_xlim(float(t[0]), float(t[-1]) if t[-1] > t[0] else float(t[0]) + 1.0)
    axa.tick_params(labelsize=7, pad=1)
    axa.set_ylabel("z (m)", fontsize=8, labelpad=1)
    axa.set_xlabel("t (s)", fontsize=8, labelpad=0)
    axa.grid(True, lw=0.4, alpha=0.6)
    return axa


def _background(log: Mapping[str, np.ndarray], lay: _Layout, title: str) -> _Scene:
    """The replay's static picture (title, camera box, top view, altitude strip) drawn once, and where
    each sample of the tracks falls on it in pixels, for the frames to draw over."""
    tr = _tracks(log)
    t, p_WB, p_WP = tr.t, tr.p_WB, tr.p_WP
    n = t.shape[0]

    dpi = 100
    fig = new_figure(lay.width / dpi, lay.height / dpi)
    fig.set_dpi(dpi)
    fig.text(12 / lay.width, 1 - 24 / lay.height, title, fontsize=11, fontweight="bold", va="baseline")

    if lay.camera is not None:
        axc = _add_axes(fig, lay.camera, lay)
        axc.set_axis_off()
        axc.set_title("onboard camera", fontsize=9, loc="left", pad=3)
    ax = _draw_top_view(fig, lay, tr)
    axa = _draw_altitude(fig, lay, tr)

    fig.canvas.draw()
    bg = np.asarray(fig.canvas.buffer_rgba())[:, :, :3].copy()  # type: ignore[attr-defined]
    if bg.shape[:2] != (lay.height, lay.width):
        bg = cv2.resize(bg, (lay.width, lay.height), interpolation=cv2.INTER_AREA)
    if lay.camera is not None:
        x, y, w, h = lay.camera
        bg[y : y + h, x : x + w] = _CAMERA_BG

    H = lay.height
    x0 = ax.transData.transform([(0.0, 0.0), (1.0, 0.0)])
    alt_t = _to_pixels(axa, np.column_stack([t, np.zeros(n)]), H)[:, 0]
    y_top = H - axa.transAxes.transform([(0.0, 1.0)])[0, 1]
    y_bot = H - axa.transAxes.transform([(0.0, 0.0)])[0, 1]
    return _Scene(
        background=bg,
        uav_px=_to_pixels(ax, p_WB[:, :2], H),
        plat_px=_to_pixels(ax, p_WP[:, :2], H),
        est_px=_to_pixels(ax, tr.p_est[:, :2], H),
        det_px=_to_pixels(ax, tr.p_det[:, :2], H),
        alt_uav_px=_to_pixels(axa, np.column_stack([t, p_WB[:, 2]]), H),
        alt_plat_px=_to_pixels(axa, np.column_stack([t, p_WP[:, 2]]), H),
        alt_t_px=alt_t,
        alt_y_range=(float(y_top), float(y_bot)),
        px_per_m=float(x0[1, 0] - x0[0, 0]),
    )


def _channel(log: Mapping[str, np.ndarray], name: str, n: int) -> np.ndarray:
    if name not in log:
        return np.full((n, 3), np.nan)
    a = np.asarray(log[name], dtype=np.float64)
    if a.shape != (n, 3):
        raise ValueError(f"log channel {name!r} has shape {a.shape}, expected ({n}, 3)")
    return a


# --------------------------------------------------------------------------------------------------
# palette
# --------------------------------------------------------------------------------------------------


def _palette(background: NDArray[np.uint8]) -> tuple[np.ndarray, NDArray[np.uint8]]:
    """255 colours (32 greys, the drawing colours, the rest fitted to the background) and the lookup
    table (32768,) from 5-bit RGB, ``r << 10 | g << 5 | b``, to the nearest of them."""
    greys = np.linspace(0, 255, _N_GREYS).round()
    fixed = [(g, g, g) for g in greys] + list(_DRAW_COLORS) + [_hex_rgb(c) for c in MODE_COLORS.values()]
    fixed += [_UAV_FAINT, _PLATFORM_FAINT, _CAMERA_BG]
    n_rest = 255 - len(fixed)
    q = Image.fromarray(background).quantize(colors=n_rest, method=Image.Quantize.MEDIANCUT)
    rest = np.asarray(q.getpalette()[: 3 * n_rest], dtype=np.float64).reshape(-1, 3)  # type: ignore[index]
    pal = np.concatenate([np.asarray(fixed, dtype=np.float64), rest])[:255]
    bins = (np.arange(32) * 8 + 4).astype(np.float64)
    r, g, b = np.meshgrid(bins, bins, bins, indexing="ij")
    cube = np.stack([r.ravel(), g.ravel(), b.ravel()], axis=1)
    # the nearest indices (an array for an array of points; the stubs also allow a scalar): no conversion
    lut = np.asarray(cKDTree(pal).query(cube)[1]).astype(np.uint8)
    return pal.astype(np.uint8), lut


# --------------------------------------------------------------------------------------------------
# drawing one frame
# --------------------------------------------------------------------------------------------------


def _fx(p: np.ndarray) -> np.ndarray:
    """Pixel coordinates (N, 2) as OpenCV fixed-point int32 (NaN rows dropped)."""
    p = p[_finite_rows(p)]
    return np.round(p * (1 << _SHIFT)).astype(np.int32)


def _polyline(img: np.ndarray, p: np.ndarray, color: tuple[int, int, int], thickness: int) -> None:
    q = _fx(p)
    if q.shape[0] >= 2:
        cv2.polylines(img, [q], False, color, thickness, cv2.LINE_AA, _SHIFT)


def _dot(img: np.ndarray, p: np.ndarray, r: int, color: tuple[int, int, int], thickness: int = -1) -> None:
    if np.isfinite(p).all():
        c = (int(round(p[0] * (1 << _SHIFT))), int(round(p[1] * (1 << _SHIFT))))
        cv2.circle(img, c, r << _SHIFT, color, thickness, cv2.LINE_AA, _SHIFT)


def _text(
    img: np.ndarray,
    s: str,
    xy: tuple[int, int],
    color: tuple[int, int, int] = _TEXT,
    scale: float = 0.45,
    bg: tuple[int, int, int] | None = None,
) -> None:
    """Text with its baseline starting at ``xy`` (px), on a filled box of colour ``bg`` if given."""
    if bg is not None:
        (w, h), base = cv2.getTextSize(s, _FONT, scale, 1)
        cv2.rectangle(img, (xy[0] - 3, xy[1] - h - 3), (xy[0] + w + 3, xy[1] + base), bg, -1)
    cv2.putText(img, s, xy, _FONT, scale, color, 1, cv2.LINE_AA)


def _heading(log_v: np.ndarray, i: int, previous: float) -> float:
    v = log_v[i]
    if np.isfinite(v[:2]).all() and math.hypot(v[0], v[1]) > 0.05:
        return math.atan2(v[1], v[0])
    return previous


def _extend_trails(base: np.ndarray, sc: _Scene, i0: int, i1: int, d0: int, d1: int) -> None:
    """Add the trails from sample ``i0`` to ``i1`` and the detections ``d0:d1`` to the trail layer.

    Trails are drawn into a persistent layer a piece at a time, so a frame costs the same late in a long
    mission as early on."""
    if i1 > i0:
        _polyline(base, sc.plat_px[i0 : i1 + 1], _PLATFORM, 2)
        _polyline(base, sc.alt_plat_px[i0 : i1 + 1], _PLATFORM, 1)
        _polyline(base, sc.alt_uav_px[i0 : i1 + 1], _UAV, 1)
    for q in sc.det_px[d0:d1]:
        _dot(base, q, 1, _ESTIMATE)
    if i1 > i0:
        _polyline(base, sc.uav_px[i0 : i1 + 1], _UAV, 2)


def _draw_markers(img: np.ndarray, sc: _Scene, i: int, yaw: float, pad_size_m: float) -> None:
    """The pad, the vehicles, the platform estimate and the time cursor at sample ``i``."""
    p = sc.plat_px[i]
    if np.isfinite(p).all():
        # the pad, a square of pad_size_m rotated by the platform's heading (image y points down)
        h = 0.5 * pad_size_m * sc.px_per_m
        c, s = math.cos(yaw), math.sin(yaw)
        corners = np.array([[h, h], [-h, h], [-h, -h], [h, -h]]) @ np.array([[c, s], [-s, c]])
        corners[:, 1] *= -1
        q = _fx(corners + p)
        cv2.fillConvexPoly(img, q, _PAD_FILL, cv2.LINE_AA, _SHIFT)
        cv2.polylines(img, [q], True, _PLATFORM, 1, cv2.LINE_AA, _SHIFT)
    _dot(img, p, 3, _PLATFORM)
    _dot(img, sc.est_px[i], 5, _ESTIMATE, 2)
    _dot(img, sc.uav_px[i], 5, _WHITE)
    _dot(img, sc.uav_px[i], 4, _UAV)
    x = sc.alt_t_px[i]
    if math.isfinite(x):
        y0, y1 = sc.alt_y_range
        xi = int(round(x * (1 << _SHIFT)))
        cv2.line(img, (xi, int(y0) << _SHIFT), (xi, int(y1) << _SHIFT), _CURSOR, 1, cv2.LINE_AA, _SHIFT)
    _dot(img, sc.alt_uav_px[i], 3, _UAV)


def _draw_camera(img: np.ndarray, frame: Frame | None) -> None:
    """Draw a camera frame, scaled to fit and centred, with its detections into the panel ``img``:
    each observation's pixel points as green dots, their centre as a yellow cross, kind and quality."""
    h, w = img.shape[:2]
    if frame is None:
        _text(img, "no image yet", (w // 2 - 45, h // 2), color=(200, 200, 200))
        return
    t_cap, image, observations = frame
    im = np.asarray(image)
    if im.dtype != np.uint8 or im.ndim not in (2, 3):
        raise ValueError(f"camera frames must be uint8 (H, W) or (H, W, 3), got {im.dtype} {im.shape}")
    if im.ndim == 2:
        # uint8 like its input, so np.asarray converts nothing: OpenCV's stubs type it MatLike
        im = np.asarray(cv2.cvtColor(im, cv2.COLOR_GRAY2RGB), dtype=np.uint8)
    scale = min(w / im.shape[1], h / im.shape[0])
    size = (max(1, round(im.shape[1] * scale)), max(1, round(im.shape[0] * scale)))
    sxy = np.array([size[0] / im.shape[1], size[1] / im.shape[0]])
    if size != (im.shape[1], im.shape[0]):
        im = np.asarray(
            cv2.resize(im, size, interpolation=cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR),
            dtype=np.uint8,
        )
    # A light blur and 16 grey levels: sensor noise and fine texture are what make a GIF frame of a
    # camera image large (half the bytes of 32 raw levels), and neither matters in a replay.
    im = np.asarray(cv2.GaussianBlur(im, (3, 3), 0), dtype=np.uint8)
    # uint8 (NEP 50: a Python int operand takes the array's dtype); numpy's stubs say signedinteger
    im = cast(NDArray[np.uint8], (im & 0xF0) | 0x08)
    ox, oy = (w - size[0]) // 2, (h - size[1]) // 2
    img[oy : oy + size[1], ox : ox + size[0]] = im
    labels = []
    for obs in observations:
        # pixel centres scale as (u + 0.5) s - 0.5
        px = (np.asarray(obs.pixels, dtype=np.float64).reshape(-1, 2) + 0.5) * sxy - 0.5 + (ox, oy)
        for q in px:
            _dot(img, q, 2, _DETECTION)
        ok = px[_finite_rows(px)]
        if ok.shape[0]:
            cx, cy = ok.mean(axis=0)
            cv2.drawMarker(
                img, (int(round(cx)), int(round(cy))), _CENTRE, cv2.MARKER_CROSS, 14, 2, cv2.LINE_AA
            )
        labels.append(f"{obs.kind} q={obs.quality:.2f}")
    status = ", ".join(labels[:3]) if labels else "no detection"
    _text(img, status, (ox + 6, oy + size[1] - 8), color=_WHITE if labels else (255, 190, 190), bg=(0, 0, 0))
    _text(img, f"capture t = {t_cap:5.1f} s", (ox + 6, oy + 18), color=_WHITE, bg=(0, 0, 0))


def _readouts(log: Mapping[str, np.ndarray], n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per sample: horizontal distance UAV-pad centre (m), height above the pad (m), and the horizontal
    error of the platform estimate (m, NaN without an estimate)."""
    p_WB = np.asarray(log["p_WB"], dtype=np.float64).reshape(n, 3)
    p_WP = _channel(log, "p_WP", n)
    p_est = _channel(log, "p_WP_est", n)
    d = p_WB - p_WP
    e = p_est - p_WP
    return np.hypot(d[:, 0], d[:, 1]), d[:, 2], np.hypot(e[:, 0], e[:, 1])


def _draw_readouts(img: np.ndarray, xy: tuple[int, int], values: list[tuple[str, float]]) -> None:
    lines = [f"{k} {v:5.2f} m" for k, v in values if math.isfinite(v)]
    if not lines:
        return
    x, y = xy
    cv2.rectangle(img, (x - 3, y - 12), (x + 112, y + 14 * len(lines) - 8), _WHITE, -1)
    for k, line in enumerate(lines):
        cv2.putText(img, line, (x, y + 14 * k), _FONT, 0.38, _TEXT, 1, cv2.LINE_AA)


# --------------------------------------------------------------------------------------------------
# the GIF
# --------------------------------------------------------------------------------------------------


def replay_times(t0: float, t1: float, fps: float, max_seconds: float) -> tuple[np.ndarray, float]:
    """Simulated times of the GIF frames and the speed-up factor.

    Frames are ``1 / fps`` s of playback apart; playback is real time (factor 1) unless the mission is
    longer than ``max_seconds``, in which case it is sped up to last ``max_seconds``. The last frame is
    the end of the log: ``floor(D / step) + 1`` frames when the log's span ``D`` is within half a step of
    the grid, one more otherwise (``step = speed / fps``).
    """
    if not (fps > 0 and math.isfinite(fps)):
        raise ValueError(f"fps must be positive, got {fps}")
    if not (max_seconds > 0 and math.isfinite(max_seconds)):
        raise ValueError(f"max_seconds must be positive, got {max_seconds}")
    duration = max(0.0, t1 - t0)
    speed = max(1.0, duration / max_seconds)
    step = speed / fps
    n = int(math.floor(duration / step + 1e-9)) + 1
    times = t0 + step * np.arange(n)
    # The end of the log is always shown; it replaces the last frame when that is less than half a step
    # before it, so that no two frames are closer than half a step (they would look alike).
    if times[-1] < t1 - 0.5 * step:
        times = np.append(times, t1)
    else:
        times[-1] = t1
    return times, speed


def render_replay_frames(
    log: Mapping[str, np.ndarray],
    *,
    frames: Sequence[Frame] | None = None,
    fps: float = 10.0,
    max_seconds: float = 30.0,
    camera_hz: float = 3.0,
    pad_size_m: float = 1.5,
    title: str | None = None,
) -> tuple[list[Image.Image], list[int]]:
    """The replay's frames (palette images, all with the same 255-colour palette) and their display
    durations (ms); see :func:`write_replay` for the arguments."""
    if "t" not in log or "p_WB" not in log:
        raise ValueError("the log needs 't' and 'p_WB'")
    t = np.asarray(log["t"], dtype=np.float64).reshape(-1)
    n = t.shape[0]
    if n == 0 or not np.isfinite(t).all():
        raise ValueError("the log has no samples (or non-finite times)")
    if np.asarray(log["p_WB"]).shape != (n, 3):
        raise ValueError(f"p_WB must have shape ({n}, 3), got {np.asarray(log['p_WB']).shape}")
    if not (camera_hz > 0 and math.isfinite(camera_hz)):
        raise ValueError(f"camera_hz must be positive, got {camera_hz}")
    if not (pad_size_m > 0 and math.isfinite(pad_size_m)):
        raise ValueError(f"pad_size_m must be positive, got {pad_size_m}")
    times, speed = replay_times(float(t[0]), float(t[-1]), fps, max_seconds)
    cam = sorted(frames, key=lambda f: float(f[0])) if frames else []
    cam_t = np.array([float(f[0]) for f in cam])

    lay = _layout(with_camera=bool(cam))
    sc = _background(log, lay, title or "mission replay")
    pal, lut = _palette(sc.background)
    v_WP = _channel(log, "v_WP", n)
    mode = np.asarray(log.get("mode", np.full(n, "", dtype=np.str_))).astype(str)
    t_det = np.sort(np.asarray(log.get("t_det", np.zeros(0)), dtype=np.float64).reshape(-1))
    dist, height, est_err = _readouts(log, n)

    base = sc.background.copy()  # background + trails so far
    i_done, d_done = 0, 0
    yaw = 0.0
    shown_cam = -1
    t_cam_shown = -math.inf
    cam_img: np.ndarray | None = None
    palette = pal.ravel().tolist()
    images: list[Image.Image] = []
    for k, tf in enumerate(times):
        i = min(max(int(np.searchsorted(t, tf + 1e-9, side="right")) - 1, 0), n - 1)
        d = int(np.searchsorted(t_det, tf + 1e-9, side="right"))
        _extend_trails(base, sc, i_done, i, d_done, d)
        i_done, d_done = max(i_done, i), max(d_done, d)
        img = base.copy()
        yaw = _heading(v_WP, i, yaw)
        _draw_markers(img, sc, i, yaw, pad_size_m)
        if lay.camera is not None:
            x, y, w, h = lay.camera
            j = int(np.searchsorted(cam_t, tf + 1e-9, side="right")) - 1
            # Refresh the camera panel at most camera_hz times per second of playback (and always on the
            # last frame): the camera image is what costs bytes in every GIF frame where it changes.
            playback = k / fps
            due = playback - t_cam_shown >= 1.0 / camera_hz - 1e-9 or k == len(times) - 1
            if cam_img is None or (j != shown_cam and due):
                cam_img = sc.background[y : y + h, x : x + w].copy()
                _draw_camera(cam_img, cam[j] if j >= 0 else None)
                shown_cam, t_cam_shown = j, playback
            img[y : y + h, x : x + w] = cam_img
        m = str(mode[i])
        _text(img, m or "-", (lay.top[0] + 8, lay.top[1] + 20), bg=_hex_rgb(mode_color(m)))
        readouts = [("to pad", dist[i]), ("height", height[i]), ("est. err", est_err[i])]
        _draw_readouts(img, (lay.top[0] + 8, lay.top[1] + 44), readouts)
        clock = f"t = {tf:6.2f} s" + (f"   (x{speed:.1f})" if speed > 1.0 + 1e-9 else "")
        _text(img, clock, lay.time_xy, scale=0.5)
        q = (img >> 3).astype(np.uint16)
        p = Image.fromarray(lut[(q[:, :, 0] << 10) | (q[:, :, 1] << 5) | q[:, :, 2]])
        p.putpalette(palette)
        images.append(p)
    frame_ms = max(20, int(round(100.0 / fps)) * 10)  # GIF delays are in 10 ms units
    durations = [frame_ms] * len(images)
    durations[-1] = max(frame_ms, _END_HOLD_MS)
    return images, durations


def write_replay(
    log: Mapping[str, np.ndarray],
    out_path: str | Path,
    *,
    frames: Sequence[Frame] | None = None,
    fps: float = 10.0,
    max_seconds: float = 30.0,
    camera_hz: float = 3.0,
    pad_size_m: float = 1.5,
    title: str | None = None,
) -> Path:
    """Write an animated GIF replay of a mission and return its path.

    Args:
        log: :meth:`alight.evaluation.log.MissionLog.finalize` arrays; needs ``t`` (N,) and ``p_WB``
            (N, 3); uses ``p_WP``, ``v_WP``, ``p_WP_est``, ``mode``, ``t_det``/``p_WP_meas`` when present.
        out_path: the ``.gif`` to write (parent directories are created).
        frames: camera frames ``(t_capture (s), image uint8, observations)`` in capture order (e.g. a
            :class:`FrameRecorder`'s ``frames``); ``None`` or empty gives the top view alone.
        fps: GIF frames per second of playback (and per simulated second, unless sped up).
        max_seconds: longest playback (s); longer missions are sped up to fit.
        camera_hz: most camera-panel refreshes per second of playback (bounds the file size).
        pad_size_m: side of the pad square drawn in the top view (m).
        title: heading in the GIF (default ``mission replay``).

    Raises:
        ValueError: a log without samples or ``p_WB``, bad ``fps``/``max_seconds``/``camera_hz``.
    """
    images, durations = render_replay_frames(
        log,
        frames=frames,
        fps=fps,
        max_seconds=max_seconds,
        camera_hz=camera_hz,
        pad_size_m=pad_size_m,
        title=title,
    )
    out = Path(out_path)
    out.parent.mkdir(parents=True, exist_ok=True)
    images[0].save(
        out,
        format="GIF",
        save_all=True,
        append_images=images[1:],
        duration=durations,
        loop=0,
        optimize=True,
        disposal=1,
    )
    return out
