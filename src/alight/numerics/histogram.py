"""Quantiles of an integer histogram (numba): the detectors' brightness percentiles, from which their
thresholds are set (:mod:`alight.perception.falanga_tag`, :mod:`alight.perception.falanga_close`)."""

from __future__ import annotations

import numba


@numba.njit(cache=True)
def histogram_quantile(hist, total, q):  # type: ignore[no-untyped-def]  # pragma: no cover
    """The ``q`` quantile of the values counted in ``hist`` (``hist[v]``: how many have value v; ``total``
    their number): the smallest v whose cumulative count reaches ``q total`` (the inverse of the empirical
    distribution function, no interpolation); the last bin when it is never reached."""
    acc = 0
    for v in range(hist.shape[0]):
        acc += hist[v]
        if acc >= q * total:
            return v
    return hist.shape[0] - 1
