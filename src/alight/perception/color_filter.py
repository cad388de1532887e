"""Red-target detector of paper 003 (Kim et al., Sec. II): a colour filter (Alg. 1 and 2), the biggest
contour as the target and its centroid as the measurement.

**Alg. 1** (``getBinaryImageofColor(I1, I2, I3)``): a pixel is set where one channel dominates the other
two,

    I1_ij >= K_I (I2_ij + I3_ij) + C_I.                                                  (Alg. 1)

**Alg. 2** (``colorFilter(I_R, I_G, I_B)``): Alg. 1 once per colour, ``I_RR = Alg1(R, G, B)``,
``I_GG = Alg1(G, B, R)``, ``I_BB = Alg1(B, R, G)``, a test ``I_Temp = [0.6 I_R < I_G]`` and

    I_CF = I_RR - I_GG - I_BB - I_Temp,                                                  (Alg. 2)

on binary images. We read the subtraction as the paper's OpenCV code would do it on 8-bit masks:
saturating at 0, so ``I_CF = I_RR and not I_GG and not I_BB and not I_Temp``. The paper gives no values
for ``K_I`` and ``C_I``; the defaults ``K_I = 0.8``, ``C_I = 20`` accept a saturated red down to a
quarter of full exposure (``(B, G, R) = (10, 10, 64)``) and reject neutral, skin, brown, pink, green,
blue and orange (``G > 0.6 R``) tones; a red-orange with ``G < 0.6 R`` passes (a test checks this
list). The 0.6 of Alg. 2 is ``green_ratio``.

Exactness: the comparisons are evaluated in exact arithmetic on the integer pixel values and the
decimal values of the parameters (a tie ``I1 = K_I (I2 + I3) + C_I`` counts as set, as written; 0.8 is
4/5, not the binary float next to it). For ``K_I > 0``, Alg. 1 is equivalent to
``I2 + I3 <= floor((I1 - C_I) / K_I)``, so a 256-entry look-up table on ``I1`` (built once with exact
rational arithmetic) and one 16-bit comparison replace the floating-point product; ``0.6 I_R < I_G`` is
``I_G > floor(0.6 I_R)`` likewise. The four tests and the three saturating subtractions are one pass of
a compiled kernel over the image (:func:`color_filter`): written with OpenCV's whole-image operations
(``cv2.split``, three ``cv2.add`` to 16 bits, four ``cv2.LUT``, four ``cv2.compare``, three
``cv2.subtract``) they are 14 passes over the frame and took 2.6-2.8x as long on rendered 640x480 and
752x480 frames (``benchmarks/bench_kim.py`` times both and checks that they agree).

**Target.** Contours of ``I_CF`` (``cv2.findContours``, Suzuki-Abe, the paper's ref. [9]; outer contours
only); the biggest (``cv2.contourArea``) is the target and its centroid is the measurement: one
:class:`BlobObservation` (kind ``blob``) with that single pixel, the target's area, shape measures and a
quality score (the solidity, area / convex hull area). Candidates are measured on their contour polygon;
the chosen one's centroid and area come from its pixels (:func:`region_moments`: within 0.1 px of the
true centre for a disc of radius >= 20 px, where the polygon through the boundary pixels' centres is
biased by half a pixel all round). ``min_area_px`` drops
specks below a noise floor in every mode (the paper keeps even a one-pixel "biggest contour"; set it to 0
for that).

**Mitigation of false locks** (``mitigation``, not in the paper; ``none`` is the paper):

- ``shape``: a candidate must pass area bounds (``min_area_px`` .. ``max_area_frac`` of the image),
  circularity ``4 pi A / P^2 >= min_circularity``, solidity ``>= min_solidity``, aspect ratio of the
  minimum-area rectangle ``<= max_aspect`` and fill ratio ``A / (rectangle area)`` in
  ``[min_fill, max_fill]``; the biggest that passes is the target. A disc seen through a fisheye 70 deg
  off axis has an aspect ratio near 3.8 (``theta / (sin theta cos theta)`` for an equidistant lens), hence
  the default 4.5. A disc's fill ratio is ``pi / 4``, a rectangle's 1: ``max_fill = 0.9`` tells a disc
  target from rectangular red objects.
- ``gate``: with a prediction set by :meth:`RedTargetDetector.set_prediction` (the estimator's predicted
  pixel and a gate radius), the candidate whose centroid is nearest the prediction, within the radius, is
  the target; none within the radius gives ``[]`` (a lost target is better than a false one). Without a
  prediction, the biggest.
- ``gate+shape``: both; the gate picks among the candidates that pass the shape checks.

With ``gate``, :meth:`detect` depends on the last prediction set, so it is no longer a pure function of
the image; the pipeline sets the prediction before each frame (or clears it with ``None``).

**An object, not a tint or noise** (every mode, not in the paper). Alg. 2 is a per-pixel test, so a frame
that is red all over (a red tarpaulin filling the view, a colour cast, a wrong white balance) is one
"biggest contour" covering the image, and sensor or compression noise on a reddish scene makes ragged
speckle clusters; the paper's rule reports either as the target (a uniformly red frame came out with
quality 1.0). The chosen candidate must therefore be a bounded region with contrast against what surrounds
it, two checks on the candidate alone:

- *bounded*: at least ``min_inside_boundary_frac`` (default 0.25) of its boundary pixels lie inside the
  image rather than on the image border. A target seen from close by and cut by the frame keeps the arcs
  of its rim that are in view (a disc cut by one border through its centre: 61 % inside); a frame red all
  over has none.
- *contrast*: in a band around it (from 2 px out, where the contour's own 8-neighbours end, to
  ``max(4, 0.25 sqrt(area))`` px), at most ``max_surround_red_frac`` (default 0.1) of the pixels pass the
  colour filter. A target lies on a background of another colour (its band is empty); a speckle of noise
  is surrounded by other speckles as red as itself (20-60 % of the band on noise frames). A distractor
  that touches the band takes part of it, so the bound is a fraction, not zero.
- *a disc cut by the border* (``min_arc_sagitta_frac``): a candidate that touches the image border must
  have a rim (its boundary inside the image) that is an arc of a circle or of an ellipse around it
  (:func:`rim_is_arc`): curved (sagitta at least 3 px and 2 % of the chord), fitted to 1 px RMS and 3
  times better than by a straight line, the candidate inside the curve. A half-frame tint, a corner of
  red, a stripe or the region above an iso-line of a red gradient has a straight or angular rim and is
  not the target (each came out at quality 1.0, also with ``shape``). The last metre of a landing keeps
  its target: the pad's rim in view is an arc whatever the border cuts, for a disc of radius up to
  about 3,000 px in a 640x480 frame (a rim across the frame's height then has a sagitta of 9.6 px, the 2 %
  bound); a disc much larger than the frame shows an edge as straight as a tint's.
  Decided: a candidate with no rim in view (the frame red all over, the pad filling the whole view) is
  indistinguishable from a tint and gives ``[]``; the estimator predicts through those last frames.

Input: :func:`alight.perception.image_input.as_bgr_u8` (16-bit, float and BGRA images are converted). A
grey image has no colour to filter: ``detect`` returns ``[]`` for it (the Detector protocol: no exception
on a uniform frame), so pair this detector with a colour camera (:attr:`RedTargetDetector.needs_colour`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from typing import Any, cast

import cv2
import numpy as np
from numba import njit
from numpy.typing import NDArray

from alight.perception.image_input import as_bgr_u8, check_time
from alight.types import FloatArray, Image, Observation

MITIGATIONS = ("none", "gate", "shape", "gate+shape")
"""Values of :attr:`RedTargetDetectorConfig.mitigation`."""


# --------------------------------------------------------------------------------------------------
# Alg. 1 and 2
# --------------------------------------------------------------------------------------------------


def _decimal(v: float) -> Fraction:
    """The number as written: 0.8 is 4/5, not the binary float just above it (shortest repr)."""
    return Fraction(repr(float(v)))


def alg1_table(K_I: float, C_I: float) -> NDArray[np.uint16]:
    """Look-up table ``T`` (256,) uint16 such that Alg. 1 holds iff ``I2 + I3 < T[I1]``: ``T[i]`` is one
    more than the largest sum ``s`` in [0, 510] with ``i >= K_I s + C_I`` (exact rational arithmetic on
    the decimal values of ``K_I``, ``C_I``), 0 when no sum qualifies."""
    if not (math.isfinite(K_I) and math.isfinite(C_I) and K_I >= 0.0):
        raise ValueError(f"K_I must be finite and >= 0 and C_I finite, got {K_I}, {C_I}")
    K = _decimal(K_I)
    C = _decimal(C_I)
    T = np.zeros(256, dtype=np.uint16)
    for i in range(256):
        if i < C:
            continue  # i >= K s + C fails for every s >= 0
        if K == 0:
            T[i] = 511
        else:
            s_max = math.floor((i - C) / K)  # exact: Fraction floor
            T[i] = min(s_max, 510) + 1
    return T


def temp_table(green_ratio: float) -> NDArray[np.uint8]:
    """Look-up table ``G_max`` (256,) uint8 such that ``green_ratio * R < G`` iff ``G > G_max[R]`` for
    integer ``G`` in [0, 255] (exact: ``G_max = floor(green_ratio R)``, clipped to 255)."""
    if not (math.isfinite(green_ratio) and green_ratio >= 0.0):
        raise ValueError(f"green_ratio must be finite and >= 0, got {green_ratio}")
    q = _decimal(green_ratio)
    return np.array([min(math.floor(q * r), 255) for r in range(256)], dtype=np.uint8)


def binary_image_of_color(
    I1: NDArray[np.uint8], I2: NDArray[np.uint8], I3: NDArray[np.uint8], table: NDArray[np.uint16]
) -> NDArray[np.uint8]:
    """Alg. 1 (``getBinaryImageofColor``): 255 where ``I1 >= K_I (I2 + I3) + C_I``, else 0. ``I1..I3``
    are single-channel uint8 images of one shape; ``table`` is :func:`alg1_table` ``(K_I, C_I)``."""
    s = cv2.add(I2, I3, dtype=cv2.CV_16U)
    # a comparison is uint8 (0/255) whatever its operands: OpenCV's stubs type every result MatLike
    return cast(NDArray[np.uint8], cv2.compare(s, cv2.LUT(I1, table), cv2.CMP_LT))


@njit(cache=True, nogil=True)
def _color_filter_kernel(
    bgr: NDArray[np.uint8], T1: NDArray[np.uint16], T2: NDArray[np.uint8], out: NDArray[np.uint8]
) -> None:  # pragma: no cover  (compiled; color_filter's tests run it)
    # Alg. 2 per pixel: I_RR and not I_GG and not I_BB and not I_Temp (the saturating subtraction of
    # 0/255 masks), each Alg. 1 test through the exact table T1, the 0.6 test through T2
    rows, cols = out.shape
    for i in range(rows):
        for j in range(cols):
            b = np.int32(bgr[i, j, 0])
            g = np.int32(bgr[i, j, 1])
            r = np.int32(bgr[i, j, 2])
            red = g + b < np.int32(T1[r])
            spoilt = b + r < np.int32(T1[g]) or r + g < np.int32(T1[b]) or g > np.int32(T2[r])
            out[i, j] = 255 if red and not spoilt else 0


def color_filter(
    image_bgr: NDArray[np.uint8],
    K_I: float = 0.8,
    C_I: float = 20.0,
    green_ratio: float = 0.6,
    *,
    tables: tuple[NDArray[np.uint16], NDArray[np.uint8]] | None = None,
) -> NDArray[np.uint8]:
    """Alg. 2 (``colorFilter``) on a BGR uint8 image (H, W, 3): the binary image ``I_CF`` (H, W) uint8,
    255 on the "most reddish" pixels. ``tables`` = ``(alg1_table(K_I, C_I), temp_table(green_ratio))``
    precomputed (then ``K_I``, ``C_I``, ``green_ratio`` are ignored)."""
    T1, T2 = tables if tables is not None else (alg1_table(K_I, C_I), temp_table(green_ratio))
    image = np.asarray(image_bgr)
    if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"color_filter needs a BGR uint8 image (H, W, 3), got {image.dtype} {image.shape}")
    out = np.empty(image.shape[:2], np.uint8)
    _color_filter_kernel(
        np.ascontiguousarray(image),
        np.ascontiguousarray(T1, dtype=np.uint16),
        np.ascontiguousarray(T2, dtype=np.uint8),
        out,
    )
    return out


# --------------------------------------------------------------------------------------------------
# Detector
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class RedTargetDetectorConfig:
    """Parameters of :class:`RedTargetDetector` (see the module docstring)."""

    K_I: float = 0.8
    """Dominance factor of Alg. 1 (>= 0): the channel must exceed ``K_I`` times the sum of the others."""
    C_I: float = 20.0
    """Offset of Alg. 1 (digital numbers, 0-255 scale)."""
    green_ratio: float = 0.6
    """The constant of Alg. 2's test ``green_ratio * I_R < I_G`` that removes orange and yellow (0.6)."""
    mitigation: str = "none"
    """``none`` (the paper: biggest contour), ``gate``, ``shape`` or ``gate+shape``."""
    open_px: int = 0
    """Side (px) of a square morphological opening of ``I_CF`` before the contours (0: none, the paper)."""
    min_area_px: float = 16.0
    """Smallest contour area (px^2) that can be the target, in every mode (noise floor)."""
    max_area_frac: float = 0.6
    """With ``shape``: largest contour area as a fraction of the image."""
    min_circularity: float = 0.45
    """With ``shape``: smallest ``4 pi area / perimeter^2`` (1 for a disc, 0.785 a square)."""
    min_solidity: float = 0.85
    """With ``shape``: smallest area / convex hull area (the target is convex)."""
    max_aspect: float = 4.5
    """With ``shape``: largest long / short side of the minimum-area rectangle."""
    min_fill: float = 0.6
    """With ``shape``: smallest area / minimum-area rectangle area (a disc: pi/4, a rectangle: 1)."""
    max_fill: float = 1.0
    """With ``shape``: largest area / minimum-area rectangle area (0.9 rejects rectangles, keeps discs)."""
    gate_radius_px: float = 60.0
    """With ``gate``: radius (px) used when :meth:`RedTargetDetector.set_prediction` gives none."""
    min_inside_boundary_frac: float = 0.25
    """In every mode: smallest fraction of the target's boundary pixels that lie inside the image, not on
    its border (0 turns the check off; see "An object, not a tint or noise" in the module docstring)."""
    max_surround_red_frac: float = 0.1
    """In every mode: largest fraction of red (``I_CF``) pixels in the band around the target (1 turns the
    check off)."""
    min_arc_sagitta_frac: float = 0.02
    """In every mode, for a target cut by the image border: smallest sagitta of its boundary inside the
    image, as a fraction of that boundary's length along its chord (0 turns the check off; see "A disc cut
    by the border" in the module docstring)."""

    def __post_init__(self) -> None:
        if self.mitigation not in MITIGATIONS:
            raise ValueError(f"mitigation must be one of {MITIGATIONS}, got {self.mitigation!r}")
        if not (math.isfinite(self.K_I) and self.K_I >= 0):
            raise ValueError(f"K_I must be finite and >= 0, got {self.K_I}")
        if not math.isfinite(self.C_I):
            raise ValueError(f"C_I must be finite, got {self.C_I}")
        if not (math.isfinite(self.green_ratio) and self.green_ratio >= 0):
            raise ValueError(f"green_ratio must be finite and >= 0, got {self.green_ratio}")
        if int(self.open_px) != self.open_px or self.open_px < 0:
            raise ValueError(f"open_px must be an integer >= 0, got {self.open_px}")
        for name in ("min_area_px", "min_circularity", "min_solidity", "min_fill"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be finite and >= 0, got {v}")
        if not (0 < self.max_area_frac <= 1):
            raise ValueError(f"max_area_frac must be in (0, 1], got {self.max_area_frac}")
        if not (math.isfinite(self.max_aspect) and self.max_aspect >= 1):
            raise ValueError(f"max_aspect must be >= 1, got {self.max_aspect}")
        if not (self.min_fill <= self.max_fill):
            raise ValueError("min_fill must be <= max_fill")
        if not (math.isfinite(self.gate_radius_px) and self.gate_radius_px > 0):
            raise ValueError(f"gate_radius_px must be finite and > 0, got {self.gate_radius_px}")
        for name in ("min_inside_boundary_frac", "max_surround_red_frac", "min_arc_sagitta_frac"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise ValueError(f"{name} must be in [0, 1], got {v}")


@dataclass(frozen=True, slots=True)
class BlobObservation(Observation):
    """An :class:`~alight.types.Observation` of a colour blob: ``pixels`` is its centroid (1, 2), plus the
    contour's measures."""

    area_px: float = 0.0
    """Number of target pixels (px^2): the region the contour encloses, holes excluded."""
    circularity: float = 0.0
    """``4 pi area / perimeter^2``."""
    solidity: float = 0.0
    """Area / convex hull area."""
    aspect: float = 1.0
    """Long / short side of the minimum-area rectangle."""
    fill: float = 0.0
    """Area / minimum-area rectangle area."""


@dataclass(frozen=True, slots=True)
class Blob:
    """One contour of ``I_CF`` with its measures."""

    centroid: FloatArray
    """Polygon centroid (u, v) (px), shape (2,)."""
    area_px: float
    circularity: float
    solidity: float
    aspect: float
    fill: float
    contour: NDArray[np.int32]
    """The contour as ``cv2.findContours`` gives it, (N, 1, 2)."""


def blob_measures(contour: NDArray[np.int32]) -> Blob | None:
    """Centroid and shape measures of one contour; None for a degenerate one (zero area)."""
    m = cv2.moments(contour)
    area = m["m00"]
    if not area > 0:
        return None
    per = cv2.arcLength(contour, True)
    hull = cv2.contourArea(cv2.convexHull(contour))
    (_, _), (w, h), _ = cv2.minAreaRect(contour)
    long_, short = max(w, h), min(w, h)
    return Blob(
        centroid=np.array([m["m10"] / area, m["m01"] / area]),
        area_px=float(area),
        circularity=float(min(1.0, 4.0 * math.pi * area / (per * per))) if per > 0 else 0.0,
        solidity=float(min(1.0, area / hull)) if hull > 0 else 0.0,
        aspect=float(long_ / short) if short > 0 else math.inf,
        fill=float(area / (w * h)) if w * h > 0 else 0.0,
        contour=contour,
    )


def region_moments(mask: NDArray[np.uint8], contour: NDArray[np.int32]) -> tuple[FloatArray, float]:
    """Centroid (u, v) (px) and pixel count of the set pixels of ``mask`` inside ``contour`` (its holes
    excluded): the mean of the pixel centres. Unbiased where the contour polygon, which runs through the
    boundary pixels' centres, loses half a pixel all round (2 % of the area of a 50 px disc)."""
    x, y, w, h = cv2.boundingRect(contour)
    roi = np.zeros((h, w), np.uint8)
    cv2.drawContours(roi, [contour - np.array([x, y], dtype=contour.dtype)], -1, 255, -1)
    cv2.bitwise_and(roi, mask[y : y + h, x : x + w], dst=roi)
    mo = cv2.moments(roi, binaryImage=True)
    if not mo["m00"] > 0:
        return np.full(2, np.nan), 0.0
    return np.array([mo["m10"] / mo["m00"] + x, mo["m01"] / mo["m00"] + y]), float(mo["m00"])


def _edge_points(closed: NDArray[np.int32], seg: NDArray[np.int32], keep: NDArray[np.bool_]) -> FloatArray:
    """The pixel centres along the kept edges of the closed polygon ``closed`` (N + 1, 2), one per pixel
    step (``seg`` the edges' Chebyshev lengths): CHAIN_APPROX_SIMPLE left only the ends of straight runs."""
    a = closed[:-1][keep].astype(np.float64)
    d = closed[1:][keep].astype(np.float64) - a
    n = np.maximum(seg[keep], 1)
    idx = np.repeat(np.arange(len(n)), n)
    frac = (np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)) / np.repeat(n, n)
    return cast(FloatArray, a[idx] + frac[:, None] * d[idx])


def _circle_fit(q: FloatArray, centroid: FloatArray, max_aspect: float) -> tuple[float, bool]:
    """RMS geometric residual (px) of Kasa's algebraic circle fit to the points ``q`` (N, 2) and whether
    ``centroid`` (2,) is inside the circle; ``(inf, False)`` for a degenerate fit (``max_aspect``: unused,
    the ellipse's signature)."""
    A = np.column_stack([q, np.ones(len(q))])  # x^2 + y^2 + a x + b y + e = 0
    sol, *_ = np.linalg.lstsq(A, -(q * q).sum(axis=1), rcond=None)
    centre = -0.5 * sol[:2]
    r2 = float(centre @ centre - sol[2])
    if not (math.isfinite(r2) and r2 > 0.0):
        return math.inf, False
    radius = math.sqrt(r2)
    rms = float(np.sqrt(np.mean((np.hypot(q[:, 0] - centre[0], q[:, 1] - centre[1]) - radius) ** 2)))
    return rms, bool(np.hypot(*(centroid - centre)) < radius)


def _ellipse_fit(q: FloatArray, centroid: FloatArray, max_aspect: float) -> tuple[float, bool]:
    """RMS Sampson distance (px) of ``cv2.fitEllipseDirect`` to the points ``q`` (N, 2) and whether
    ``centroid`` (2,) is inside the ellipse; ``(inf, False)`` for a degenerate fit or one longer than
    ``max_aspect`` times its width (two parallel edges of a stripe fit a very long ellipse)."""
    (ex, ey), (w, h), angle_deg = cv2.fitEllipseDirect(q.astype(np.float32))
    if not (w > 0.0 and h > 0.0 and math.isfinite(w * h) and max(w, h) <= max_aspect * min(w, h)):
        return math.inf, False
    a2, b2 = (0.5 * w) ** 2, (0.5 * h) ** 2
    ca, sa = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    p = np.vstack([q, centroid.reshape(1, 2)])
    u = (p[:, 0] - ex) * ca + (p[:, 1] - ey) * sa
    v = -(p[:, 0] - ex) * sa + (p[:, 1] - ey) * ca
    F = u * u / a2 + v * v / b2 - 1.0  # the implicit function, and its gradient's norm for Sampson's
    grad = 2.0 * np.hypot(u / a2, v / b2)
    rms = float(np.sqrt(np.mean((F[:-1] / np.maximum(grad[:-1], 1e-12)) ** 2)))
    return rms, bool(F[-1] < 0.0)


def rim_is_arc(
    p_px: FloatArray, centroid_px: FloatArray, min_sagitta_frac: float, max_aspect: float = 4.5
) -> bool:
    """Whether the boundary points ``p_px`` (N, 2) of a blob cut by the image border (the part inside the
    image) are an arc of a circle or an ellipse around the blob (centroid ``centroid_px``; a disc's image
    is one), not a straight or ragged line: (1) curved, their spread across their best straight line (the
    sagitta) at least ``max(MIN_SAGITTA_PX, min_sagitta_frac * chord)``; (2) a circle (Kasa's fit, stable
    on a short arc) or an ellipse (``cv2.fitEllipseDirect``, a disc seen obliquely) fits them at least
    ``ARC_FIT_GAIN`` times better (RMS) than that line and to at most ``ARC_MAX_RMS_PX`` (two straight
    edges meeting at a corner are neither), (3) with the blob's centroid inside it (the blob is the disc,
    not what is left around one) and (4), an ellipse, no longer than ``max_aspect`` times its width."""
    if len(p_px) < 5:
        return False
    c = p_px.mean(axis=0)
    q = p_px - c
    _, _, vt = np.linalg.svd(q, full_matrices=False)
    along, across = q @ vt[0], q @ vt[1]
    chord = float(along.max() - along.min())
    if float(across.max() - across.min()) < max(MIN_SAGITTA_PX, min_sagitta_frac * chord):
        return False
    rms_line = float(np.sqrt(np.mean(across**2)))
    for fit in (_circle_fit, _ellipse_fit):
        rms, inside = fit(q, centroid_px - c, max_aspect)
        if inside and rms <= ARC_MAX_RMS_PX and rms * ARC_FIT_GAIN <= rms_line:
            return True
    return False


MIN_SAGITTA_PX = 3.0
"""Smallest sagitta (px) of a rim cut by the border: a digital straight edge, even a ragged one after a
threshold, spreads 1-2 px across its line."""
ARC_MAX_RMS_PX = 1.0
"""Largest RMS residual (px) of the circle or ellipse on a cut rim: a disc's rim, thresholded from an
anti-aliased or blurred image, is fitted to a fraction of a pixel."""
ARC_FIT_GAIN = 3.0
"""How many times smaller an ellipse's RMS residual must be than the straight line's on a cut rim: the
arc of a disc's image is fitted to a fraction of a pixel, a ragged line is not helped by the extra
parameters."""


class RedTargetDetector:
    """Paper 003's colour-filter detector (Alg. 1, 2, biggest contour), with optional false-lock mitigation.

    ``detect(image, t)`` takes a BGR image (H, W, 3) (a 4th alpha channel is ignored; 16-bit and float
    images are converted by :func:`alight.perception.image_input.as_bgr_u8`) and returns ``[]`` or one
    :class:`BlobObservation`; empty, tiny, malformed and grey images (no colour to filter) give ``[]``;
    a non-finite ``t`` raises :class:`alight.errors.ImageError`.
    """

    needs_colour = True
    """This detector finds nothing in grey frames: a configuration that feeds it a grey camera is wrong."""

    def __init__(self, config: RedTargetDetectorConfig | None = None) -> None:
        self.config = config if config is not None else RedTargetDetectorConfig()
        c = self.config
        self._tables = (alg1_table(c.K_I, c.C_I), temp_table(c.green_ratio))
        self._kernel = (
            cv2.getStructuringElement(cv2.MORPH_RECT, (int(c.open_px), int(c.open_px)))
            if c.open_px > 1
            else None
        )
        self._expected_px: FloatArray | None = None
        self._gate_radius_px = c.gate_radius_px

    # ---- gating input ----------------------------------------------------------------------------

    def set_prediction(self, px: FloatArray | None, radius_px: float | None = None) -> None:
        """The estimator's predicted pixel ``(u, v)`` of the target in the next image and the gate radius
        (px; the config's ``gate_radius_px`` when None). ``px=None`` clears the prediction. Used by the
        ``gate`` mitigations only."""
        if px is None:
            self._expected_px = None
            return
        p = np.asarray(px, dtype=np.float64).ravel()
        if p.shape != (2,) or not np.isfinite(p).all():
            raise ValueError(f"px must be a finite (u, v), got {px!r}")
        r = self.config.gate_radius_px if radius_px is None else float(radius_px)
        if not (math.isfinite(r) and r > 0):
            raise ValueError(f"radius_px must be finite and > 0, got {radius_px}")
        self._expected_px = p
        self._gate_radius_px = r

    @property
    def prediction(self) -> tuple[FloatArray, float] | None:
        """The prediction in use, ``(px, radius_px)``, or None."""
        if self._expected_px is None:
            return None
        return self._expected_px.copy(), self._gate_radius_px

    # ---- detection -------------------------------------------------------------------------------

    @staticmethod
    def _as_bgr(image: Any) -> NDArray[np.uint8] | None:
        img = as_bgr_u8(image)
        if img is None or img.shape[0] < 2 or img.shape[1] < 2:
            return None
        return img

    def mask(self, image: Any) -> NDArray[np.uint8] | None:
        """``I_CF`` of Alg. 2 (after the optional opening), or None for an image it cannot read."""
        img = self._as_bgr(image)
        if img is None:
            return None
        m = color_filter(img, tables=self._tables)
        if self._kernel is not None:
            # uint8 like its input: OpenCV's stubs type it MatLike
            m = cast(NDArray[np.uint8], cv2.morphologyEx(m, cv2.MORPH_OPEN, self._kernel))
        return m

    def candidates(self, image: Any) -> list[Blob]:
        """Every contour of ``I_CF`` with area >= ``min_area_px``, biggest first."""
        m = self.mask(image)
        return [] if m is None else self._blobs(m)

    def _blobs(self, m: NDArray[np.uint8]) -> list[Blob]:
        if cv2.countNonZero(m) == 0:
            return []
        contours, _ = cv2.findContours(m, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        out = []
        min_area = self.config.min_area_px
        for cnt in contours:
            if cv2.contourArea(cnt) < max(min_area, 1e-9):
                continue
            b = blob_measures(cast(NDArray[np.int32], cnt))  # findContours' points are int32; stubs: MatLike
            if b is not None:
                out.append(b)
        out.sort(key=lambda b: -b.area_px)
        return out

    def passes_shape(self, blob: Blob, image_area_px: float) -> bool:
        """The ``shape`` checks of the module docstring."""
        c = self.config
        return (
            c.min_area_px <= blob.area_px <= c.max_area_frac * image_area_px
            and blob.circularity >= c.min_circularity
            and blob.solidity >= c.min_solidity
            and blob.aspect <= c.max_aspect
            and c.min_fill <= blob.fill <= c.max_fill
        )

    def select(self, blobs: list[Blob], image_area_px: float) -> Blob | None:
        """The target among ``blobs`` (biggest first) under the configured mitigation."""
        mode = self.config.mitigation
        if "shape" in mode:
            blobs = [b for b in blobs if self.passes_shape(b, image_area_px)]
        if not blobs:
            return None
        if "gate" in mode and self._expected_px is not None:
            d = np.array([np.hypot(*(b.centroid - self._expected_px)) for b in blobs])
            k = int(np.argmin(d))
            return blobs[k] if d[k] <= self._gate_radius_px else None
        return blobs[0]

    def is_object(self, m: NDArray[np.uint8], blob: Blob) -> bool:
        """The *bounded* and *contrast* checks of the module docstring on ``blob``, a contour of the mask
        ``m`` (``I_CF``)."""
        c = self.config
        H, W = m.shape
        x, y, w, h = cv2.boundingRect(blob.contour)
        pts = blob.contour.reshape(-1, 2)
        # CHAIN_APPROX_SIMPLE keeps only the ends of straight runs: walk the polygon's edges instead
        closed = np.concatenate([pts, pts[:1]])
        seg = np.abs(np.diff(closed, axis=0)).max(axis=1)
        on_border = (
            ((closed[:-1, 0] == 0) & (closed[1:, 0] == 0))
            | ((closed[:-1, 0] == W - 1) & (closed[1:, 0] == W - 1))
            | ((closed[:-1, 1] == 0) & (closed[1:, 1] == 0))
            | ((closed[:-1, 1] == H - 1) & (closed[1:, 1] == H - 1))
        )
        total = float(seg.sum())
        if c.min_inside_boundary_frac > 0.0:
            if total > 0.0 and float(seg[~on_border].sum()) < c.min_inside_boundary_frac * total:
                return False
        if c.min_arc_sagitta_frac > 0.0 and bool(on_border.any()):
            inside = _edge_points(closed, seg, ~on_border)
            if not rim_is_arc(inside, blob.centroid, c.min_arc_sagitta_frac, c.max_aspect):
                return False
        if c.max_surround_red_frac < 1.0:
            band = max(4, round(0.25 * math.sqrt(blob.area_px)))
            x0, y0 = max(0, x - band), max(0, y - band)
            x1, y1 = min(W, x + w + band), min(H, y + h + band)
            region = np.zeros((y1 - y0, x1 - x0), np.uint8)
            cv2.drawContours(
                region, [blob.contour - np.array([x0, y0], dtype=blob.contour.dtype)], -1, 255, -1
            )
            outer = cv2.dilate(
                region, cv2.getStructuringElement(cv2.MORPH_RECT, (2 * band + 1, 2 * band + 1))
            )
            inner = cv2.dilate(region, cv2.getStructuringElement(cv2.MORPH_RECT, (3, 3)))
            ring = cv2.subtract(outer, inner)
            n_ring = cv2.countNonZero(ring)
            if n_ring > 0:
                red = cv2.countNonZero(cv2.bitwise_and(ring, m[y0:y1, x0:x1]))
                if red > c.max_surround_red_frac * n_ring:
                    return False
        return True

    def detect(self, image: Image, t: float) -> list[Observation]:
        """The target in ``image`` captured at ``t`` (s): ``[]`` or one :class:`BlobObservation`."""
        t = check_time(t)
        try:
            m = self.mask(image)
            if m is None:
                return []
            blobs = self._blobs(m)
            if not blobs:
                return []
            b = self.select(blobs, float(m.shape[0] * m.shape[1]))
            if b is None or not self.is_object(m, b):
                return []
            centroid, area = region_moments(m, b.contour)
        except cv2.error:
            return []
        if not area > 0:
            return []
        return [
            BlobObservation(
                t=t,
                kind="blob",
                quality=b.solidity,
                pixels=centroid.reshape(1, 2),
                area_px=area,
                circularity=b.circularity,
                solidity=b.solidity,
                aspect=b.aspect,
                fill=b.fill,
            )
        ]


__all__ = [
    "MITIGATIONS",
    "Blob",
    "BlobObservation",
    "RedTargetDetector",
    "RedTargetDetectorConfig",
    "alg1_table",
    "binary_image_of_color",
    "blob_measures",
    "region_moments",
    "color_filter",
    "temp_table",
]
