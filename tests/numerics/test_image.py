"""The bilinear sampler: exact on a bilinear image, the pixel values at the pixel centres, and the last
row and column reachable."""

from __future__ import annotations

import numpy as np
import pytest

from alight.numerics.image import bilinear


def test_bilinear_is_exact_on_a_bilinear_image() -> None:
    h, w = 7, 9
    i, j = np.mgrid[0:h, 0:w].astype(np.float64)
    img = 3.0 + 2.0 * j - 1.5 * i + 0.25 * i * j  # bilinear in (x = j, y = i)
    rng = np.random.default_rng(0)
    for x, y in rng.uniform([0, 0], [w - 1, h - 1], (200, 2)):
        assert bilinear(img, x, y) == pytest.approx(3.0 + 2.0 * x - 1.5 * y + 0.25 * x * y, abs=1e-12)
    # pixel centres give the pixel, including the last row and column
    assert bilinear(img, 0.0, 0.0) == img[0, 0]
    assert bilinear(img, w - 1.0, h - 1.0) == img[h - 1, w - 1]
    u8 = np.arange(12, dtype=np.uint8).reshape(3, 4)
    assert bilinear(u8, 1.5, 0.5) == pytest.approx(0.25 * (1 + 2 + 5 + 6))
