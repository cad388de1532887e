"""The texture convention shared by every pad design (see :mod:`alight.pads`)."""

from __future__ import annotations

import math

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
    # numpy's ufunc stubs (np.minimum, np.maximum) drop the dtype, so clip's result is typed Any
    w: NDArray[np.float64] = np.clip(np.minimum(lo + 1, b) - np.maximum(lo, a), 0.0, None)
    return w
