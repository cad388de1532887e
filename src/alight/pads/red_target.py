"""The red target of paper 003 (Kim et al., KAIST): a red shape on the platform, found by a colour filter
(Alg. 1 and 2) as the largest red contour.

The paper does not give the target's shape or size (its Fig. 1 and 10 are photographs missing from the
text; Sec. V-B only says a rover "drags [a] red target"). The choice here, all fields, so a user can match
what they printed: a red disc of diameter 1.0 m on a neutral grey square of side 1.5 m (the pad). A disc
because it looks the same from every heading and its blob centroid stays near the projected centre under
a fisheye's distortion; ``shape="square"`` gives a red square of side ``2 * target_radius_m`` instead.

Colours are BGR (OpenCV's channel order) and deliberately not pure: red ``(40, 40, 200)`` on grey
``(150, 150, 150)``, so the thresholds ``K_I``, ``C_I`` of Alg. 1 and the ``0.6 R < G`` test of Alg. 2
matter (a pure (0, 0, 255) passes any threshold).

Pad frame ``P`` and texture convention as in :mod:`alight.pads`: the texture is the pad seen from above,
+x (platform front) at the top, +y (left) at the left, not mirrored; :meth:`RedTarget.texture` returns a
BGR image, shape (n, n, 3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from alight.pads._texture import texture_grid_P, texture_homography, texture_side_px
from alight.types import FloatArray

TARGET_SHAPES = ("disc", "square")
"""Shapes :class:`RedTarget` knows."""


def _bgr(value: tuple[int, int, int], name: str) -> tuple[int, int, int]:
    try:
        out = tuple(int(v) for v in value)
        ok = len(out) == 3 and all(0 <= v <= 255 for v in out) and all(float(v) == int(v) for v in value)
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ValueError(f"RedTarget.{name} must be 3 integers in [0, 255] (B, G, R), got {value!r}")
    return out  # type: ignore[return-value]


@dataclass(frozen=True, slots=True)
class RedTarget:
    """A red disc (or square) centred on a neutral square pad (lengths in m, colours BGR 0-255)."""

    size_m: float = 1.5
    """Side of the pad's square (m): the sheet or board the target is painted on."""
    target_radius_m: float = 0.5
    """Radius of the red disc, or half the side of the red square (m)."""
    shape: str = "disc"
    """``disc`` or ``square`` (axis-aligned with P)."""
    target_bgr: tuple[int, int, int] = (40, 40, 200)
    """Colour of the target (B, G, R)."""
    background_bgr: tuple[int, int, int] = (150, 150, 150)
    """Colour of the rest of the pad (B, G, R)."""

    def __post_init__(self) -> None:
        for name in ("size_m", "target_radius_m"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"RedTarget.{name} must be finite and positive, got {v!r}")
        if self.shape not in TARGET_SHAPES:
            raise ValueError(f"RedTarget.shape must be one of {TARGET_SHAPES}, got {self.shape!r}")
        if self.target_radius_m > self.size_m / 2:
            raise ValueError("the target must fit on the pad (target_radius_m <= size_m / 2)")
        object.__setattr__(self, "target_bgr", _bgr(self.target_bgr, "target_bgr"))
        object.__setattr__(self, "background_bgr", _bgr(self.background_bgr, "background_bgr"))

    @classmethod
    def default(cls, size_m: float = 1.5) -> RedTarget:
        """The default target scaled to a pad of side ``size_m`` (m): disc diameter ``2/3 size_m``."""
        return cls(size_m=size_m, target_radius_m=size_m / 3.0)

    # ---------------------------------------------------------------------------------------- geometry

    @property
    def target_area_m2(self) -> float:
        """Area of the red shape (m^2)."""
        r = self.target_radius_m
        return math.pi * r * r if self.shape == "disc" else 4.0 * r * r

    def quad_corners_P(self) -> FloatArray:
        """Corners of the pad's square, shape (4, 3): (+x, +y), (-x, +y), (-x, -y), (+x, -y)."""
        h = self.size_m / 2
        return np.array([[h, h, 0.0], [-h, h, 0.0], [-h, -h, 0.0], [h, -h, 0.0]])

    def target_outline_P(self, n: int = 64) -> FloatArray:
        """``n`` points on the red shape's boundary, shape (n, 3), z = 0, counter-clockwise seen from above
        starting on +x (a disc: angles ``2 pi k / n``; a square: its perimeter at equal arc length)."""
        if n < 4:
            raise ValueError(f"n must be >= 4, got {n}")
        r = self.target_radius_m
        t = np.arange(n) / n
        if self.shape == "disc":
            a = 2 * np.pi * t
            return np.stack([r * np.cos(a), r * np.sin(a), np.zeros(n)], axis=1)
        # the square's perimeter from (r, 0) counter-clockwise, 8 r long
        s = (8.0 * r * t + r) % (8.0 * r)  # arc length from the corner (r, -r)
        side, f = np.divmod(s, 2.0 * r)
        starts = np.array([[r, -r], [r, r], [-r, r], [-r, -r]])
        dirs = np.array([[0.0, 1.0], [-1.0, 0.0], [0.0, -1.0], [1.0, 0.0]])
        k = side.astype(int)
        xy = starts[k] + f[:, None] * dirs[k]
        out: FloatArray = np.c_[xy, np.zeros(n)]  # np.c_ is typed Any
        return out

    # ---------------------------------------------------------------------------------------- texture

    def texture_homography_P_to_px(self, px_per_m: float) -> FloatArray:
        """3x3 homography from pad-plane points ``(x, y, 1)`` (m, in P) to texture pixels ``(u, v, 1)``."""
        return texture_homography(self.size_m, px_per_m)

    def texture(self, px_per_m: float) -> NDArray[np.uint8]:
        """The pad as a BGR image, shape (n, n, 3), ``n = round(size_m * px_per_m)``. The target's edge
        is anti-aliased with a one-pixel linear ramp of the exact signed distance, so the 50 % mix of the
        two colours sits on the true edge."""
        n = texture_side_px(self.size_m, px_per_m)
        x, y, s = texture_grid_P(self.size_m, n)
        r = self.target_radius_m
        if self.shape == "disc":
            sd = np.hypot(x, y) - r
        else:
            dx, dy = np.abs(x) - r, np.abs(y) - r
            sd = np.hypot(np.maximum(dx, 0), np.maximum(dy, 0)) + np.minimum(np.maximum(dx, dy), 0)
        w = np.clip(0.5 - sd * s, 0.0, 1.0)[..., None]  # fraction of the pixel that is target
        fg = np.asarray(self.target_bgr, dtype=np.float64)
        bg = np.asarray(self.background_bgr, dtype=np.float64)
        return np.rint(bg + w * (fg - bg)).astype(np.uint8)
