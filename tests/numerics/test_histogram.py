"""The histogram quantile against numpy's inverted-CDF percentile."""

from __future__ import annotations

import numpy as np

from alight.numerics.histogram import histogram_quantile


def test_histogram_quantile_is_the_inverse_empirical_distribution() -> None:
    values = np.array([3, 3, 5, 7, 7, 7, 9, 200], dtype=np.int64)
    hist = np.bincount(values, minlength=256)
    total = int(hist.sum())
    for q in (0.02, 0.1, 0.25, 0.5, 0.75, 0.98, 1.0):
        # the smallest v with #{values <= v} >= q n (numpy's "inverted_cdf" percentile)
        assert histogram_quantile(hist, total, q) == int(
            np.percentile(values, 100 * q, method="inverted_cdf")
        )
    assert histogram_quantile(hist, total, 0.5) == 7
    assert histogram_quantile(np.zeros(256, np.int64), 0, 0.5) == 0  # empty: the first bin
