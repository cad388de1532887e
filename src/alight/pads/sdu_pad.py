"""The landing marker of paper 004 (Zamanakos et al., Sec. IV-A, Fig. 1): an n-fold marker with three
ArUco markers of different ids at known offsets.

The paper's text says only "an n-fold marker [26] along with three ArUco markers [27] with different
ids", that the n-fold marker serves from high altitude and the ArUco markers "as extra landmarks in case
the marker is partially visible", and that each ArUco marker's offset from the landing marker's centre is
known (its step 8). Fig. 1 is not in the text we have, so the layout is our choice, documented here:

- the **n-fold marker** (order 4 by default, sheet ``nfold_marker.md`` sec. 1) is centred on the pad: its
  tip is the pad centre, the origin of P (paper 004's local frame has its origin at "the center of the
  landing marker"). Its black wedges reach ``nfold_radius_m`` (0.45 m on the 1.5 m pad: a 0.9 m disc)
  and are centred on the directions ``2 pi j / n`` in P (from +x, counter-clockwise seen from above). It
  is a *plain* marker by default: the n-fold marker alone gives the heading only modulo ``2 pi / n``, and
  the ArUco markers resolve it. ``nfold_oriented=True`` gives MarkerLocator's *oriented* variant (the
  wedge along +x, the platform's front, left white: a unique heading), but its quality template also
  accepts T-junctions of dark bars, which square markers are full of (q = 1.0 on the ChArUco photos of
  the test data, against <= 0.27 for the plain template; see :mod:`alight.perception.nfold`);
- the **three ArUco markers** (OpenCV ``DICT_4X4_50`` by default: 4 x 4 data cells, the largest cells for
  a given marker size, so the longest detection range) sit in three corners of the pad, at
  ``(+a, +a)``, ``(-a, +a)``, ``(-a, -a)`` with ``a = aruco_offset_m`` (front-left, rear-left, rear-right),
  side ``aruco_size_m``; the front-right corner stays empty, so the layout is not symmetric either.

Every length scales with ``size_m`` in :meth:`SduPad.default`. Marker corners follow OpenCV's ArUco order
as in :class:`alight.pads.AprilTagPad`: top-left, top-right, bottom-right, bottom-left in the texture,
i.e. ``(cx + s/2, cy + s/2)``, ``(cx + s/2, cy - s/2)``, ``(cx - s/2, cy - s/2)``, ``(cx - s/2, cy + s/2)``
in P. Texture convention as for every pad (:mod:`alight.pads`): seen from above, +x at the top, +y at the
left, not mirrored.
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


@dataclass(frozen=True, slots=True)
class SduPad:
    """Geometry of paper 004's landing marker (lengths in metres; see the module docstring)."""

    size_m: float = 1.5
    """Side of the white square (m)."""
    nfold_order: int = 4
    """Order n of the n-fold marker: its number of black wedges, a missing leg included."""
    nfold_radius_m: float = 0.45
    """Radius to which the n-fold marker's wedges reach (m)."""
    nfold_oriented: bool = False
    """True: the black wedge along +x is left white (MarkerLocator's oriented marker, unique heading)."""
    aruco_dictionary: str = "DICT_4X4_50"
    """OpenCV predefined dictionary of the ArUco markers (by name)."""
    aruco_ids: tuple[int, int, int] = (1, 2, 3)
    """Ids of the markers at (+a, +a), (-a, +a), (-a, -a)."""
    aruco_size_m: float = 0.3
    """Side of each ArUco marker's black square (m)."""
    aruco_offset_m: float = 0.55
    """``a``: |x| = |y| of each ArUco marker's centre in P (m)."""

    def __post_init__(self) -> None:
        for name in ("size_m", "nfold_radius_m", "aruco_size_m", "aruco_offset_m"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"SduPad.{name} must be finite and positive, got {v}")
        if int(self.nfold_order) != self.nfold_order or self.nfold_order < 2:
            raise ValueError(f"nfold_order must be an integer >= 2, got {self.nfold_order}")
        key = self.aruco_dictionary
        key = key if key.startswith("DICT_") else "DICT_" + key
        if not hasattr(cv2.aruco, key):
            raise ValueError(f"unknown ArUco dictionary {self.aruco_dictionary!r}")
        object.__setattr__(self, "aruco_dictionary", key)
        n_dict = cv2.aruco.getPredefinedDictionary(int(getattr(cv2.aruco, key))).bytesList.shape[0]
        ids = tuple(int(i) for i in self.aruco_ids)
        if len(ids) != 3 or len(set(ids)) != 3 or not all(0 <= i < n_dict for i in ids):
            raise ValueError(f"aruco_ids must be 3 distinct ids in [0, {n_dict}), got {self.aruco_ids}")
        object.__setattr__(self, "aruco_ids", ids)
        # a one-cell white quiet zone round every ArUco marker, inside the pad and clear of the n-fold disc
        q = self.aruco_size_m / 2 * (1 + 2 / self.aruco_cells)
        if self.aruco_offset_m + q > self.size_m / 2 + 1e-12:
            raise ValueError("every ArUco marker with a one-cell quiet zone must fit inside the pad")
        if math.sqrt(2.0) * (self.aruco_offset_m - q) < self.nfold_radius_m - 1e-12:
            raise ValueError("an ArUco marker's quiet zone overlaps the n-fold marker's disc")
        if self.nfold_radius_m > self.size_m / 2 + 1e-12:
            raise ValueError("the n-fold marker must fit inside the pad")

    @classmethod
    def default(cls, size_m: float = 1.5) -> SduPad:
        """The default layout scaled to a white square of side ``size_m`` (m)."""
        k = size_m / 1.5
        return cls(size_m=size_m, nfold_radius_m=0.45 * k, aruco_size_m=0.3 * k, aruco_offset_m=0.55 * k)

    # ------------------------------------------------------------------------------------ geometry

    @property
    def aruco_dictionary_id(self) -> int:
        """OpenCV id of :attr:`aruco_dictionary`."""
        return int(getattr(cv2.aruco, self.aruco_dictionary))

    @property
    def aruco_cells(self) -> int:
        """Cells per side of an ArUco marker's black square (data cells plus the one-cell border)."""
        return int(cv2.aruco.getPredefinedDictionary(self.aruco_dictionary_id).markerSize) + 2

    @property
    def marker_ids(self) -> tuple[int, ...]:
        """The ArUco ids (what :class:`alight.perception.aruco.ArucoPadDetector` expects of a pad)."""
        return self.aruco_ids

    @property
    def nfold_center_P(self) -> FloatArray:
        """The n-fold marker's tip in P (m), shape (3,): the pad centre."""
        return np.zeros(3)

    @property
    def nfold_missing_leg_yaw_P(self) -> float | None:
        """Direction of the oriented marker's missing (white) leg in P (rad from +x, counter-clockwise
        from above): 0, the platform's front. None for a plain marker."""
        return 0.0 if self.nfold_oriented else None

    def marker_center_and_size_P(self, marker_id: int) -> tuple[float, float, float]:
        """``(cx, cy, side)`` of an ArUco marker in P (m)."""
        signs = ((1, 1), (-1, 1), (-1, -1))
        for mid, (sx, sy) in zip(self.aruco_ids, signs, strict=True):
            if mid == marker_id:
                return sx * self.aruco_offset_m, sy * self.aruco_offset_m, self.aruco_size_m
        raise ValueError(f"marker id {marker_id} is not on this pad (ids {self.aruco_ids})")

    def marker_offset_P(self, marker_id: int) -> FloatArray:
        """Offset of an ArUco marker's centre from the n-fold marker's tip, in P (m), shape (3,) (paper
        004 step 8's "offset vector", in the pad frame)."""
        cx, cy, _ = self.marker_center_and_size_P(marker_id)
        return np.array([cx, cy, 0.0]) - self.nfold_center_P

    def marker_corners_P(self, marker_id: int) -> FloatArray:
        """Corners of an ArUco marker's black square in P, shape (4, 3), z = 0, OpenCV's ArUco order
        (top-left, top-right, bottom-right, bottom-left in the texture)."""
        return marker_square_corners_P(*self.marker_center_and_size_P(marker_id))

    def quad_corners_P(self) -> FloatArray:
        """Corners of the white square, shape (4, 3): (+x, +y), (-x, +y), (-x, -y), (+x, -y)."""
        return square_corners_P(self.size_m)

    def nfold_is_black_P(self, x: FloatArray, y: FloatArray) -> NDArray[np.bool_]:
        """Whether P points ``(x, y)`` (m, any equal shapes) are on a black wedge of the n-fold marker."""
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        n = self.nfold_order
        psi = np.arctan2(y, x)
        # distance in angle to the nearest wedge centre line 2 pi j / n
        d = np.abs(np.remainder(psi + np.pi / n, 2 * np.pi / n) - np.pi / n)
        black = (d < np.pi / (2 * n)) & (np.hypot(x, y) < self.nfold_radius_m)
        if self.nfold_oriented:
            black &= ~(np.abs(psi) < np.pi / (2 * n))
        return black

    # ------------------------------------------------------------------------------------ texture

    def texture_homography_P_to_px(self, px_per_m: float) -> FloatArray:
        """3x3 homography from pad-plane points ``(x, y, 1)`` (m) to texture pixels ``(u, v, 1)``."""
        return texture_homography(self.size_m, px_per_m)

    def texture(self, px_per_m: float) -> NDArray[np.uint8]:
        """The pad as a grayscale image (white 255, black 0), shape (n, n), ``n = round(size_m *
        px_per_m)``. The ArUco cells are painted with exact area coverage (a box filter); the n-fold
        wedges with the area coverage of their straight edges and their arc (a pixel cut by an edge at
        signed distance ``d`` px from its centre is covered ``clip(0.5 + d, 0, 1)``), so edges and the tip
        land where P says to a small fraction of a pixel."""
        n = texture_side_px(self.size_m, px_per_m)
        s = n / self.size_m
        img = np.full((n, n), 255.0, dtype=np.float64)
        # the n-fold disc's bounding box (pixel i spans [i, i+1) from the texture edge), one pixel wider
        lo = max(0, int(math.floor(s * (self.size_m / 2 - self.nfold_radius_m))) - 1)
        hi = min(n, int(math.ceil(s * (self.size_m / 2 + self.nfold_radius_m))) + 1)
        idx = (np.arange(lo, hi, dtype=np.float64) + 0.5) / s
        x = (self.size_m / 2 - idx)[:, None]  # row v -> x
        y = (self.size_m / 2 - idx)[None, :]  # column u -> y
        img[lo:hi, lo:hi] -= 255.0 * self._nfold_coverage(x, y, s)
        dictionary = cv2.aruco.getPredefinedDictionary(self.aruco_dictionary_id)
        cells_n = self.aruco_cells
        for mid in self.aruco_ids:
            paint_marker(img, self.size_m, dictionary, mid, cells_n, *self.marker_center_and_size_P(mid))
        return np.round(np.clip(img, 0, 255)).astype(np.uint8)

    def _nfold_coverage(self, x: FloatArray, y: FloatArray, s: float) -> FloatArray:
        """Fraction of each texture pixel (centres ``x``, ``y`` in P, scale ``s`` px/m) on a black wedge."""
        n = self.nfold_order
        r = np.hypot(x, y)
        psi = np.arctan2(y, x)
        # signed angular distance inside the nearest black wedge (> 0 inside), to a distance in pixels
        d_ang = np.pi / (2 * n) - np.abs(np.remainder(psi + np.pi / n, 2 * np.pi / n) - np.pi / n)
        edge_px = s * r * np.sin(np.clip(d_ang, -np.pi / 2, np.pi / 2))
        cov = np.clip(0.5 + edge_px, 0.0, 1.0)
        if self.nfold_oriented:
            # the missing leg along +x: pixels whose nearest wedge centre line is the leg's are white
            cov = np.where(np.abs(psi) < np.pi / n, 0.0, cov)
        cov = np.minimum(cov, np.clip(0.5 + s * (self.nfold_radius_m - r), 0.0, 1.0))
        return cov


__all__ = ["SduPad"]
