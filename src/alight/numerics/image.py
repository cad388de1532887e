"""Sampling an image between its pixels (numba): one bilinear interpolation for the detectors that read
an image along a homography (:mod:`alight.perception.falanga_tag`, :mod:`alight.perception.falanga_close`).
Pixel ``(i, j)`` (row, column) holds the value at ``(x, y) = (j, i)``: integer coordinates at pixel
centres, OpenCV's convention."""

from __future__ import annotations

import numba


@numba.njit(cache=True)
def bilinear(img, x, y):  # type: ignore[no-untyped-def]  # pragma: no cover
    """Bilinear sample at (x = column, y = row); the caller keeps (x, y) inside [0, w-1] x [0, h-1]."""
    h, w = img.shape
    j = min(int(x), w - 2)
    i = min(int(y), h - 2)
    fx = x - j
    fy = y - i
    a = img[i, j] * (1 - fx) + img[i, j + 1] * fx
    b = img[i + 1, j] * (1 - fx) + img[i + 1, j + 1] * fx
    return a * (1 - fy) + b * fy
