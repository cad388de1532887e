"""A landing pad of AprilTag 36h11 markers: one large central tag and four small corner tags.

Paper 000 (Sec. II-B) notes that its framework generalises to AprilTags; this pad is that variant, and
it is also what OpenCV's ``cv2.aruco.ArucoDetector`` with ``DICT_APRILTAG_36h11`` reads. The marker
bits come from ``cv2.aruco.generateImageMarker``: 8 x 8 cells (6 x 6 data cells inside a one-cell black
border). A marker's *size* here is the side of that black square; the white quiet zone a detector needs
around it (at least one cell) is the pad's white background, checked in ``__post_init__``.

Pad frame ``P`` and texture convention as in :mod:`alight.pads.falanga_tag`: the texture is the pad seen
from above with +x (platform front) at the top and +y (left) at the left, not mirrored.

Marker corner order: OpenCV's ArUco order, top-left, top-right, bottom-right, bottom-left of the marker as
it appears in the texture (and so in an image taken looking straight down with the image top toward +x).
For a marker centred at ``(cx, cy)`` with side ``a`` these are, in P,
``(cx + a/2, cy + a/2)``, ``(cx + a/2, cy - a/2)``, ``(cx - a/2, cy - a/2)``, ``(cx - a/2, cy + a/2)``:
clockwise seen from above (z up), starting at the marker's front-left corner.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from alight.pads._texture import (
    marker_square_corners_P,
    paint_marker,
    square_corners_P,
    texture_homography,
    texture_side_px,
)
from alight.types import FloatArray

APRILTAG_DICTIONARY = cv2.aruco.DICT_APRILTAG_36h11
"""The OpenCV dictionary the markers come from (and a detector must use)."""

_MARKER_CELLS = 8  # 6 data cells + 2 border cells per side (36h11 in OpenCV with borderBits = 1)


@dataclass(frozen=True, slots=True)
class AprilTagPad:
    """Geometry of the AprilTag pad (lengths in metres, markers' sides are their black squares)."""

    size_m: float = 1.5
    """Side of the white square (m)."""
    center_id: int = 0
    """Id of the central marker."""
    center_size_m: float = 0.8
    """Side of the central marker's black square (m)."""
    corner_ids: tuple[int, int, int, int] = (1, 2, 3, 4)
    """Ids of the corner markers at (+x, +y), (-x, +y), (-x, -y), (+x, -y) (counter-clockwise from the
    front-left, like ``FalangaTag.quad_corners_P``)."""
    corner_size_m: float = 0.2
    """Side of each corner marker's black square (m)."""
    corner_offset_m: float = 0.6
    """|x| = |y| of each corner marker's centre in P (m)."""

    def __post_init__(self) -> None:
        ids = (self.center_id, *self.corner_ids)
        if len(self.corner_ids) != 4:
            raise ValueError(f"corner_ids must have 4 ids, got {self.corner_ids}")
        n_dict = cv2.aruco.getPredefinedDictionary(APRILTAG_DICTIONARY).bytesList.shape[0]
        if len(set(ids)) != 5 or not all(0 <= i < n_dict for i in ids):
            raise ValueError(f"marker ids must be 5 distinct ids in [0, {n_dict}), got {ids}")
        for v in (self.size_m, self.center_size_m, self.corner_size_m, self.corner_offset_m):
            if not (math.isfinite(v) and v > 0):
                raise ValueError("AprilTagPad lengths must be finite and positive")
        # a one-cell white quiet zone around every marker, inside the white square, not overlapping
        q_c = self.center_size_m / 2 * (1 + 2 / _MARKER_CELLS)
        q_k = self.corner_size_m / 2 * (1 + 2 / _MARKER_CELLS)
        if q_c > self.size_m / 2 or self.corner_offset_m + q_k > self.size_m / 2:
            raise ValueError("every marker with a one-cell quiet zone must fit inside the pad")
        gap_ok = self.corner_offset_m - self.corner_size_m / 2 >= q_c - 1e-12
        gap_ok = gap_ok and self.center_size_m / 2 <= self.corner_offset_m - q_k + 1e-12
        if not gap_ok:
            raise ValueError("a corner marker lies in the central marker's quiet zone or vice versa")

    @classmethod
    def default(cls, size_m: float = 1.5) -> AprilTagPad:
        """The default layout scaled to a white square of side ``size_m`` (m)."""
        k = size_m / 1.5
        return cls(size_m=size_m, center_size_m=0.8 * k, corner_size_m=0.2 * k, corner_offset_m=0.6 * k)

    @property
    def min_view_side_m(self) -> float:
        """Side of the smallest square around the pad centre that a camera must see whole for the pad
        to be detected at all (m): the central marker with its one-cell quiet zone. Closer than where
        this square fills the image, no marker is whole in view (the corner markers lie outside it)."""
        return self.center_size_m * (1 + 2 / _MARKER_CELLS)

    @property
    def marker_ids(self) -> tuple[int, ...]:
        """All marker ids, central first."""
        return (self.center_id, *self.corner_ids)

    def marker_center_and_size_P(self, marker_id: int) -> tuple[float, float, float]:
        """``(cx, cy, side)`` of a marker in P (m)."""
        if marker_id == self.center_id:
            return 0.0, 0.0, self.center_size_m
        signs = ((1, 1), (-1, 1), (-1, -1), (1, -1))
        for mid, (sx, sy) in zip(self.corner_ids, signs, strict=True):
            if mid == marker_id:
                return sx * self.corner_offset_m, sy * self.corner_offset_m, self.corner_size_m
        raise ValueError(f"marker id {marker_id} is not on this pad (ids {self.marker_ids})")

    def marker_corners_P(self, marker_id: int) -> FloatArray:
        """Corners of a marker's black square in P, shape (4, 3), z = 0, in OpenCV's ArUco order
        (top-left, top-right, bottom-right, bottom-left in the texture; see the module docstring)."""
        return marker_square_corners_P(*self.marker_center_and_size_P(marker_id))

    def quad_corners_P(self) -> FloatArray:
        """Corners of the white square, shape (4, 3): (+x, +y), (-x, +y), (-x, -y), (+x, -y)."""
        return square_corners_P(self.size_m)

    def texture_homography_P_to_px(self, px_per_m: float) -> FloatArray:
        """3x3 homography from pad-plane points ``(x, y, 1)`` (m) to texture pixels ``(u, v, 1)``."""
        return texture_homography(self.size_m, px_per_m)

    def texture(self, px_per_m: float) -> NDArray[np.uint8]:
        """The pad as a grayscale image (white 255, black 0), shape (n, n), ``n = round(size_m *
        px_per_m)``. Each marker's cells are painted with exact area coverage (a box filter), so a cell
        edge between pixels gives the proportional grey and the marker corners stay where P says."""
        n = texture_side_px(self.size_m, px_per_m)
        img = np.full((n, n), 255.0, dtype=np.float64)
        dictionary = cv2.aruco.getPredefinedDictionary(APRILTAG_DICTIONARY)
        for mid in self.marker_ids:
            paint_marker(
                img, self.size_m, dictionary, mid, _MARKER_CELLS, *self.marker_center_and_size_P(mid)
            )
        return np.round(np.clip(img, 0, 255)).astype(np.uint8)
