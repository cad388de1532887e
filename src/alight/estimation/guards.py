"""Bounds and checks shared by the estimators' public entry points: what a measurement or a time may be.

A filter fed garbage must refuse it and stay as it was, never end in a NaN state, block on it or spend
time in proportion to it. The limits below are generous physical bounds (orders of magnitude beyond
anything alight flies, so valid data never meets them) and every estimator documents which it applies:

- :data:`MAX_TIME_S`: a time stamp is a finite number of seconds within 1e9 s (31 years) of the clock's
  origin; beyond, ``t**2`` terms overflow and step counts become absurd.
- :data:`MAX_POSITION_M`: a measured position is within 1e5 m (100 km) of the world origin.
- :data:`MAX_SPEED_MPS`: a measured velocity is below 100 m/s.
- :data:`FUTURE_TOLERANCE_S`: a measurement may be stamped at most 1 s after the estimator's clock (the
  latest time it was told is *now*); later is a clock fault upstream, refused so that it cannot make
  every real measurement after it look out of order.
- :data:`MAX_HORIZON_S`: predictions are integrated at most 120 s past the last measurement; a query
  further out gets the estimate at that horizon with its uncertainty grown for the rest (bounded work
  for any gap, and a stale track is reported as such by its age and covariance, not extrapolated into
  nonsense).
- :data:`GATE_SIGMA`: an innovation further than 10 standard deviations (Mahalanobis distance) from the
  prediction is an outlier: a consistent filter sees one with probability ``e^-50``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from alight.errors import MeasurementError
from alight.types import FloatArray

MAX_TIME_S = 1.0e9
MAX_POSITION_M = 1.0e5
MAX_SPEED_MPS = 100.0
FUTURE_TOLERANCE_S = 1.0
MAX_HORIZON_S = 120.0
GATE_SIGMA = 10.0
MAX_VARIANCE = 1.0e10
"""Largest variance (m^2) a measurement covariance may hold (a standard deviation of 100 km)."""


def check_time(t: Any, where: str) -> float:
    """``t`` as a float; :class:`MeasurementError` unless finite and within :data:`MAX_TIME_S`."""
    try:
        value = float(t)
    except (TypeError, ValueError):
        raise MeasurementError(f"{where}: time must be a number of seconds, got {t!r}") from None
    if not (math.isfinite(value) and abs(value) <= MAX_TIME_S):
        raise MeasurementError(f"{where}: time must be finite and within {MAX_TIME_S:g} s, got {t!r}")
    return value


def check_vector(v: Any, n: int, bound: float, what: str, where: str) -> FloatArray:
    """``v`` as a float (n,) array; :class:`MeasurementError` unless finite with norm <= ``bound``."""
    a = np.asarray(v, dtype=np.float64)
    if a.shape != (n,):
        raise MeasurementError(f"{where}: {what} must have shape ({n},), got {a.shape}")
    norm = float(np.sqrt(a @ a))
    if not (math.isfinite(norm) and norm <= bound):
        raise MeasurementError(f"{where}: {what} must be finite with norm <= {bound:g}, got {a.tolist()}")
    return a


def check_covariance(c: Any, n: int, where: str, what: str = "covariance") -> FloatArray:
    """``c`` as a float (n, n) array; :class:`MeasurementError` unless finite, symmetric (to 1e-9
    relative), positive semi-definite and with variances at most :data:`MAX_VARIANCE`."""
    a = np.asarray(c, dtype=np.float64)
    if a.shape != (n, n):
        raise MeasurementError(f"{where}: {what} must have shape ({n}, {n}), got {a.shape}")
    if not np.isfinite(a).all():
        raise MeasurementError(f"{where}: {what} is not finite")
    scale = float(np.abs(a).max())
    if float(np.abs(a - a.T).max()) > 1e-9 * max(scale, 1e-300):
        raise MeasurementError(f"{where}: {what} is not symmetric")
    if float(np.diagonal(a).max()) > MAX_VARIANCE:
        raise MeasurementError(f"{where}: {what} has a variance above {MAX_VARIANCE:g}")
    if float(np.linalg.eigvalsh(a).min()) < -1e-9 * max(scale, 1e-300):
        raise MeasurementError(f"{where}: {what} is not positive semi-definite")
    return a


__all__ = [
    "FUTURE_TOLERANCE_S",
    "GATE_SIGMA",
    "MAX_HORIZON_S",
    "MAX_POSITION_M",
    "MAX_SPEED_MPS",
    "MAX_TIME_S",
    "MAX_VARIANCE",
    "check_covariance",
    "check_time",
    "check_vector",
]
