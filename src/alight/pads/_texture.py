"""The texture convention shared by every pad design (see :mod:`alight.pads`)."""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from alight.types import FloatArray


def texture_side_px(size_m: float, px_per_m: float) -> int:
    """Pixels per side of the texture of a square pad of side ``size_m`` (m) at ``px_per_m``."""
    if not (math.isfinite(px_per_m) and px_per_m > 0):
        raise ValueError(f"px_per_m must be finite and positive, got {px_per_m}")
    n = int(round(size_m * px_per_m))
    if n < 2:
        raise ValueError(f"px_per_m = {px_per_m} gives a texture of {n} px for a {size_m} m pad")
    return n


def texture_homography(size_m: float, px_per_m: float) -> FloatArray:
    """Homography from P-plane points ``(x, y, 1)`` (m) to texture pixels ``(u, v, 1)``:
    ``u = s (size_m/2 - y) - 0.5``, ``v = s (size_m/2 - x) - 0.5`` with ``s = n / size_m`` the effective
    scale of the ``n``-pixel texture (integer pixel coordinates at pixel centres, OpenCV's convention)."""
    n = texture_side_px(size_m, px_per_m)
    s = n / size_m
    c = s * size_m / 2 - 0.5
    return np.array([[0.0, -s, c], [-s, 0.0, c], [0.0, 0.0, 1.0]])


def texture_grid_P(size_m: float, n: int) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """P coordinates ``(x, y)`` of the centres of an ``n x n`` texture's pixels, each shape (n, n), and
    the effective scale ``s`` (px/m)."""
    s = n / size_m
    idx = (np.arange(n) + 0.5) / s
    x = (size_m / 2 - idx)[:, None] * np.ones((1, n))  # row v -> x
    y = np.ones((n, 1)) * (size_m / 2 - idx)[None, :]  # column u -> y
    return x, y, s


def box_overlap_weights(n_px: int, edges_px: NDArray[np.float64]) -> NDArray[np.float64]:
    """Overlap lengths between the unit pixel intervals ``[i, i+1)`` (i < n_px) and the cells bounded by
    ``edges_px`` (increasing, in pixel units from the texture edge), shape (n_px, len(edges_px) - 1).
    Used to paint a cell grid into a texture with exact area coverage (box-filter anti-aliasing)."""
    lo = np.arange(n_px, dtype=np.float64)[:, None]
    a = edges_px[None, :-1]
    b = edges_px[None, 1:]
    # a typed local: numpy types np.minimum/np.maximum of these operands Any
    w: NDArray[np.float64] = np.clip(np.minimum(lo + 1, b) - np.maximum(lo, a), 0.0, None)
    return w


def marker_square_corners_P(cx: float, cy: float, a: float) -> FloatArray:
    """Corners of a marker's black square of side ``a`` (m) centred at ``(cx, cy)`` in P, shape (4, 3),
    z = 0, in OpenCV's ArUco order: top-left, top-right, bottom-right, bottom-left in the texture (whose
    top is +x and left +y, see :func:`texture_homography`)."""
    h = a / 2
    return np.array(
        [[cx + h, cy + h, 0.0], [cx + h, cy - h, 0.0], [cx - h, cy - h, 0.0], [cx - h, cy + h, 0.0]]
    )


def square_corners_P(size_m: float) -> FloatArray:
    """Corners of the square of side ``size_m`` (m) centred at P's origin, shape (4, 3), z = 0:
    (+x, +y), (-x, +y), (-x, -y), (+x, -y)."""
    h = size_m / 2
    return np.array([[h, h, 0.0], [-h, h, 0.0], [-h, -h, 0.0], [h, -h, 0.0]])


def paint_marker(
    img: NDArray[np.float64],
    size_m: float,
    dictionary: cv2.aruco.Dictionary,
    marker_id: int,
    cells_n: int,
    cx: float,
    cy: float,
    a: float,
) -> None:
    """Darken ``img`` (the (n, n) texture of a pad of side ``size_m``, white 255) by the ArUco/AprilTag
    marker ``marker_id`` of ``dictionary`` (``cells_n`` cells a side plus a one-cell black border) whose
    black square has side ``a`` (m) and centre ``(cx, cy)`` in P: each cell painted with exact area
    coverage (:func:`box_overlap_weights`), so the marker's corners stay where P says."""
    n = img.shape[0]
    s = n / size_m
    cells = cv2.aruco.generateImageMarker(dictionary, marker_id, cells_n, borderBits=1)
    cells = cells.astype(np.float64) - 255.0
    # texture column of the marker's left (+y) edge and row of its top (+x) edge, in pixel units from
    # the texture's edge (pixel i spans [i, i+1))
    u0 = s * (size_m / 2 - (cy + a / 2))
    v0 = s * (size_m / 2 - (cx + a / 2))
    steps = np.arange(cells_n + 1) * (s * a / cells_n)
    img += box_overlap_weights(n, v0 + steps) @ cells @ box_overlap_weights(n, u0 + steps).T
