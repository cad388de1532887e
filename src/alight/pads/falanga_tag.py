"""The landing tag of paper 000 (Falanga et al. 2017, Fig. 3): a black cross inside a black ring on a
white square.

The paper shows the tag only as a figure; the proportions here (ring outer radius 0.42 s, ring width
0.07 s, cross arm 0.28 s from the centre to the bar end, bar width 0.10 s, for a white square of side s)
were measured off that figure and are fields, so a user can match a tag they printed.

Pad frame ``P``: origin at the pad centre, z up, x along the platform heading, y to the left. Every point
method returns points on the pad surface (z = 0) in P, in metres.

Texture convention (shared by every pad, see :func:`alight.pads.texture_homography`): the texture is the
pad seen from above with the platform's front (+x) at the top of the image and its left (+y) at the left.
With ``n = round(size_m * px_per_m)`` pixels per side and ``s = n / size_m`` the effective scale, a point
``(x, y)`` in P lands at the (sub)pixel ``u = s (size_m/2 - y) - 0.5`` (column), ``v = s (size_m/2 - x)
- 0.5`` (row), OpenCV's convention of integer coordinates at pixel centres. So pixel (0, 0) is the
front-left (+x, +y) corner of the square and the image is not mirrored: a camera looking straight down
with its image top toward +x sees the texture as it is stored.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from alight.pads._texture import texture_grid_P, texture_homography, texture_side_px
from alight.types import FloatArray


@dataclass(frozen=True, slots=True)
class FalangaTag:
    """Geometry of the cross-and-ring tag (all lengths in metres). Defaults are the 1.5 m tag; use
    :meth:`default` to scale every length with the square's side."""

    size_m: float = 1.5
    """Side of the white square (m)."""
    ring_outer_radius_m: float = 0.42 * 1.5
    """Radius of the ring's outer edge (m)."""
    ring_width_m: float = 0.07 * 1.5
    """Radial width of the black ring (m); the inner edge is at ``ring_outer_radius_m - ring_width_m``."""
    cross_arm_half_length_m: float = 0.28 * 1.5
    """Distance from the centre to the end of each bar of the cross (m)."""
    cross_bar_width_m: float = 0.10 * 1.5
    """Width of each bar of the cross (m)."""

    def __post_init__(self) -> None:
        vals = (
            self.size_m,
            self.ring_outer_radius_m,
            self.ring_width_m,
            self.cross_arm_half_length_m,
            self.cross_bar_width_m,
        )
        if not all(math.isfinite(v) and v > 0 for v in vals):
            raise ValueError(f"FalangaTag lengths must be finite and positive, got {vals}")
        if self.ring_outer_radius_m > self.size_m / 2:
            raise ValueError("the ring must fit inside the white square (ring_outer_radius_m <= size_m / 2)")
        if self.ring_width_m >= self.ring_outer_radius_m:
            raise ValueError("ring_width_m must be smaller than ring_outer_radius_m")
        if self.cross_bar_width_m >= 2 * self.cross_arm_half_length_m:
            raise ValueError("cross_bar_width_m must be smaller than the cross span")
        if math.hypot(self.cross_arm_half_length_m, self.cross_bar_width_m / 2) >= self.ring_inner_radius_m:
            raise ValueError("the cross must fit inside the ring's inner edge")

    @classmethod
    def default(cls, size_m: float = 1.5) -> FalangaTag:
        """The tag of paper 000's Fig. 3 scaled to a white square of side ``size_m`` (m)."""
        return cls(
            size_m=size_m,
            ring_outer_radius_m=0.42 * size_m,
            ring_width_m=0.07 * size_m,
            cross_arm_half_length_m=0.28 * size_m,
            cross_bar_width_m=0.10 * size_m,
        )

    @property
    def ring_inner_radius_m(self) -> float:
        """Radius of the ring's inner edge (m)."""
        return self.ring_outer_radius_m - self.ring_width_m

    # ---------------------------------------------------------------------------------------- geometry

    def quad_corners_P(self) -> FloatArray:
        """Corners of the white square, shape (4, 3), z = 0, counter-clockwise seen from above starting
        front-left: (+x, +y), (-x, +y), (-x, -y), (+x, -y)."""
        h = self.size_m / 2
        return np.array([[h, h, 0.0], [-h, h, 0.0], [-h, -h, 0.0], [h, -h, 0.0]])

    def circle_points_P(self, n: int) -> FloatArray:
        """``n`` points on the ring's outer edge, shape (n, 3), counter-clockwise from +x (angle 2 pi k/n)."""
        return _circle(self.ring_outer_radius_m, n)

    def circle_inner_points_P(self, n: int) -> FloatArray:
        """``n`` points on the ring's inner edge, shape (n, 3), counter-clockwise from +x."""
        return _circle(self.ring_inner_radius_m, n)

    def cross_inner_corners_P(self) -> FloatArray:
        """The 4 concave corners where the bars meet, shape (4, 3), counter-clockwise from (+x, +y):
        (+w/2, +w/2), (-w/2, +w/2), (-w/2, -w/2), (+w/2, -w/2) with ``w`` the bar width."""
        h = self.cross_bar_width_m / 2
        return np.array([[h, h, 0.0], [-h, h, 0.0], [-h, -h, 0.0], [h, -h, 0.0]])

    def cross_outer_corners_P(self) -> FloatArray:
        """The 8 convex corners at the ends of the bars, shape (8, 3), by increasing angle in [0, 2 pi)
        seen from above: (L, w/2), (w/2, L), (-w/2, L), (-L, w/2), (-L, -w/2), (-w/2, -L), (w/2, -L),
        (L, -w/2) with ``L`` the arm half length and ``w`` the bar width."""
        L, h = self.cross_arm_half_length_m, self.cross_bar_width_m / 2
        xy = [(L, h), (h, L), (-h, L), (-L, h), (-L, -h), (-h, -L), (h, -L), (L, -h)]
        return np.array([[x, y, 0.0] for x, y in xy])

    def cross_outline_P(self) -> FloatArray:
        """The cross's 12-vertex outline, shape (12, 3), counter-clockwise seen from above, starting at
        (L, w/2): outer corners and inner corners interleaved as the boundary visits them."""
        outer = self.cross_outer_corners_P()
        inner = self.cross_inner_corners_P()
        # boundary order (* = inner corner):
        # (L,h) (h,h)* (h,L) (-h,L) (-h,h)* (-L,h) (-L,-h) (-h,-h)* (-h,-L) (h,-L) (h,-h)* (L,-h)
        order = [outer[0], inner[0], outer[1], outer[2], inner[1], outer[3], outer[4], inner[2], outer[5]]
        order += [outer[6], inner[3], outer[7]]
        return np.array(order)

    # ---------------------------------------------------------------------------------------- texture

    def texture_homography_P_to_px(self, px_per_m: float) -> FloatArray:
        """3x3 homography from pad-plane points ``(x, y, 1)`` (m, in P) to texture pixels ``(u, v, 1)`` of
        :meth:`texture` at the same ``px_per_m`` (see the module docstring for the convention)."""
        return texture_homography(self.size_m, px_per_m)

    def texture(self, px_per_m: float) -> NDArray[np.uint8]:
        """The tag as a grayscale image (white 255, black 0), shape (n, n) with
        ``n = round(size_m * px_per_m)``. Edges are anti-aliased with a one-pixel linear ramp of the exact
        signed distance to each shape, so the 50 % grey level sits on the true edge."""
        n = texture_side_px(self.size_m, px_per_m)
        x64, y64, s = texture_grid_P(self.size_m, n)
        # the tag is symmetric about both axes and so is the pixel grid: compute the (+x, +y) quadrant
        # (rows and columns 0 .. ceil(n/2)) and mirror it
        m = (n + 1) // 2
        x = x64[:m, :m].astype(np.float32)
        y = y64[:m, :m].astype(np.float32)
        r = np.hypot(x, y)
        mid = self.ring_outer_radius_m - self.ring_width_m / 2
        sd_ring = np.abs(r - np.float32(mid)) - np.float32(self.ring_width_m / 2)
        L, h = self.cross_arm_half_length_m, self.cross_bar_width_m / 2
        sd_cross = np.minimum(_sd_box(x, y, L, h), _sd_box(x, y, h, L))
        sd_black = np.minimum(sd_ring, sd_cross)  # signed distance to the black set (m), < 0 inside
        black = np.clip(np.float32(0.5) - sd_black * np.float32(s), 0.0, 1.0)
        q = np.rint(np.float32(255.0) * (np.float32(1.0) - black)).astype(np.uint8)
        out = np.empty((n, n), np.uint8)
        out[:m, :m] = q
        out[:m, n - m :] = q[:, ::-1]
        out[n - m :, :] = out[:m, :][::-1, :]
        return out


def _circle(radius: float, n: int) -> FloatArray:
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n}")
    a = 2 * np.pi * np.arange(n) / n
    return np.stack([radius * np.cos(a), radius * np.sin(a), np.zeros(n)], axis=1)


def _sd_box(x: NDArray[np.float32], y: NDArray[np.float32], hx: float, hy: float) -> NDArray[np.float32]:
    """Exact signed distance to the axis-aligned box of half sides (hx, hy) centred at the origin."""
    dx = np.abs(x) - np.float32(hx)
    dy = np.abs(y) - np.float32(hy)
    outside = np.hypot(np.maximum(dx, 0), np.maximum(dy, 0))
    inside = np.minimum(np.maximum(dx, dy), 0)
    return outside + inside
