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
- :data:`MAX_STEPS`: a propagation over any gap takes at most 4,096 steps (:func:`bounded_steps`): gaps up
  to ``MAX_STEPS * max_step`` are split as before, longer ones in longer steps (bounded work for any gap).
- :data:`MAX_SPECIFIC_FORCE_MPS2` and :data:`MAX_RATE_RADPS`: an IMU sample's specific force is below
  2,000 m/s^2 (200 g) and its rate below 100 rad/s (MEMS IMUs saturate near 16-32 g and 35 rad/s): beyond
  is a corrupt sample, refused so that one cannot throw the state to 1e9 m/s.
- :class:`StampRun`: the recovery rule. A run of ``length`` stamps that disagree with the estimator's
  clock but are in order among themselves (each at most ``FUTURE_TOLERANCE_S`` after the one before)
  means the clock was the fault: the estimator restarts (or moves its clock) from them.
- :data:`GATE_SIGMA`: an innovation further than 10 standard deviations (Mahalanobis distance) from the
  prediction is an outlier: a consistent filter sees one with probability ``e^-50``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from alight.errors import MeasurementError
from alight.types import FloatArray

MAX_TIME_S = 1.0e9
MAX_POSITION_M = 1.0e5
MAX_SPEED_MPS = 100.0
FUTURE_TOLERANCE_S = 1.0
MAX_HORIZON_S = 120.0
GATE_SIGMA = 10.0
MAX_STEPS = 4096
MAX_SPECIFIC_FORCE_MPS2 = 2000.0
MAX_RATE_RADPS = 100.0
MAX_VARIANCE = 1.0e10
"""Largest variance (m^2) a measurement covariance may hold (a standard deviation of 100 km)."""


def as_time(t: Any, where: str) -> float:
    """``t`` as a float (maybe not finite); :class:`MeasurementError` when it is not a real number."""
    if isinstance(t, (str, bytes)):
        raise MeasurementError(f"{where}: time must be a number of seconds, got {t!r:.80}")
    try:
        return float(t)
    except (TypeError, ValueError):
        raise MeasurementError(f"{where}: time must be a number of seconds, got {t!r:.80}") from None


def check_time(t: Any, where: str) -> float:
    """``t`` as a float; :class:`MeasurementError` unless finite and within :data:`MAX_TIME_S`."""
    value = as_time(t, where)
    if not (math.isfinite(value) and abs(value) <= MAX_TIME_S):
        raise MeasurementError(f"{where}: time must be finite and within {MAX_TIME_S:g} s, got {t!r}")
    return value


def check_vector(v: Any, n: int, bound: float, what: str, where: str) -> FloatArray:
    """``v`` as a float (n,) array; :class:`MeasurementError` unless finite with norm <= ``bound``."""
    a = as_real_array(v, what, where)
    if a.shape != (n,):
        raise MeasurementError(f"{where}: {what} must have shape ({n},), got {a.shape}")
    # the largest element first: a @ a of 1e300 would overflow (with a warning) before the test
    norm = float(np.sqrt(a @ a)) if float(np.abs(a).max()) <= bound else math.inf
    if not (math.isfinite(norm) and norm <= bound):
        raise MeasurementError(f"{where}: {what} must be finite with norm <= {bound:g}, got {a.tolist()}")
    return a


def check_rotation(R: Any, what: str, where: str) -> FloatArray:
    """``R`` as a float (3, 3) array; :class:`MeasurementError` unless a rotation matrix: real, finite,
    orthonormal to 1e-6 and with determinant +1 (the entries' bound first, so that 1e300 cannot overflow
    ``R^T R``)."""
    a = as_real_array(R, what, where)
    if a.shape != (3, 3):
        raise MeasurementError(f"{where}: {what} must have shape (3, 3), got {a.shape}")
    if not (
        float(np.abs(a).max()) <= 1.0 + 1e-6  # a rotation's entries are within [-1, 1]; False on NaN
        and float(np.abs(a.T @ a - np.eye(3)).max()) <= 1e-6
        and float(np.linalg.det(a)) > 0.0
    ):
        raise MeasurementError(f"{where}: {what} is not a rotation matrix")
    return a


def check_covariance(c: Any, n: int, where: str, what: str = "covariance") -> FloatArray:
    """``c`` as a float (n, n) array; :class:`MeasurementError` unless finite, symmetric (to 1e-9
    relative), positive semi-definite and with variances at most :data:`MAX_VARIANCE`."""
    a = as_real_array(c, what, where)
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


def as_real_array(v: Any, what: str, where: str) -> FloatArray:
    """``v`` as a float array; :class:`MeasurementError` when it holds something else than reals."""
    if np.iscomplexobj(v):  # numpy would drop the imaginary part with a warning
        raise MeasurementError(f"{where}: {what} must be real, got {v!r:.80}")
    try:
        return np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError):  # complex, ragged, None, strings
        raise MeasurementError(f"{where}: {what} must be an array of real numbers, got {v!r:.80}") from None


def check_real_inputs(t: Any, arrays: tuple[Any, ...], where: str) -> float:
    """:func:`check_time` of ``t``, and :class:`MeasurementError` when one of ``arrays`` (None allowed)
    holds complex numbers, which numpy would cast to their real part with only a warning."""
    for a in arrays:
        if a is not None and np.iscomplexobj(a):
            raise MeasurementError(f"{where}: inputs must be real, got {a!r:.80}")
    return check_time(t, where)


def check_clock(t: Any, now: float, where: str) -> float:
    """:func:`check_time`, and :class:`MeasurementError` when ``t`` is more than
    :data:`FUTURE_TOLERANCE_S` after the clock ``now`` (no check while ``now`` is NaN: no clock yet)."""
    value = check_time(t, where)
    if value > now + FUTURE_TOLERANCE_S:
        raise MeasurementError(f"{where}: time {value} is more than {FUTURE_TOLERANCE_S:g} s after {now}")
    return value


def check_times(ts: Any, where: str) -> FloatArray:
    """``ts`` as a float 1-D array; :class:`MeasurementError` unless real, finite, within MAX_TIME_S."""
    a = as_real_array(ts, "times", where)
    if a.ndim != 1:
        raise MeasurementError(f"{where}: times must be 1-D, got shape {a.shape}")
    if a.size and not (np.isfinite(a).all() and float(np.abs(a).max()) <= MAX_TIME_S):
        raise MeasurementError(f"{where}: times must be finite and within {MAX_TIME_S:g} s")
    return a


def check_measurement(m: Any, where: str) -> tuple[float, FloatArray, FloatArray]:
    """A :class:`~alight.types.PlatformMeasurement`'s ``t``, ``p_WP`` and ``cov_p_WP`` by
    :func:`check_time`, :func:`check_vector` (:data:`MAX_POSITION_M`) and :func:`check_covariance`; the
    camera path's one rule for every platform estimator."""
    try:
        t, p, cov = m.t, m.p_WP, m.cov_p_WP
    except AttributeError:
        raise MeasurementError(f"{where}: a PlatformMeasurement is needed, got {type(m).__name__}") from None
    return (
        check_time(t, where),
        check_vector(p, 3, MAX_POSITION_M, "p_WP", where),
        check_covariance(cov, 3, where, "cov_p_WP"),
    )


@njit(cache=True)
def bounded_steps(dt: float, max_step: float) -> int:
    """The number of steps of at most ``max_step`` over ``|dt|``, capped at :data:`MAX_STEPS`."""
    r = abs(dt) / max_step - 1e-9
    if not r < MAX_STEPS:  # also NaN; compared as a float, as int() of 1e300 overflows
        return MAX_STEPS
    return max(1, int(math.ceil(r)))


@njit(cache=True)
def imu_plausible(imu: FloatArray, i0: int) -> bool:
    """``imu[i0:i0+3]`` (specific force, m/s^2) and ``imu[i0+3:i0+6]`` (rate, rad/s) finite and within
    :data:`MAX_SPECIFIC_FORCE_MPS2` and :data:`MAX_RATE_RADPS`."""
    f2 = imu[i0] ** 2 + imu[i0 + 1] ** 2 + imu[i0 + 2] ** 2
    w2 = imu[i0 + 3] ** 2 + imu[i0 + 4] ** 2 + imu[i0 + 5] ** 2
    return bool(f2 <= MAX_SPECIFIC_FORCE_MPS2**2 and w2 <= MAX_RATE_RADPS**2)  # False on NaN


def plausible_velocity(v: FloatArray) -> FloatArray:
    """``v`` (3,) when finite and below :data:`MAX_SPEED_MPS`, else zero: what a restart may keep of an
    estimate's velocity."""
    s2 = float(v @ v)
    return v.copy() if s2 <= MAX_SPEED_MPS**2 else np.zeros(3)


class StampRun:
    """A run of time stamps that disagree with an estimator's clock, kept while they are in order among
    themselves (each at most :data:`FUTURE_TOLERANCE_S` after the one before). :meth:`add` says True once
    ``length`` of them agree: the clock was the fault, and the estimator restarts from them."""

    def __init__(self, length: int) -> None:
        self.length = length
        self.times: list[float] = []

    def clear(self) -> None:
        self.times.clear()

    def add(self, t: float) -> bool:
        if self.times and not (0.0 <= t - self.times[-1] <= FUTURE_TOLERANCE_S):
            self.times.clear()
        self.times.append(t)
        return len(self.times) >= self.length


__all__ = [
    "FUTURE_TOLERANCE_S",
    "GATE_SIGMA",
    "MAX_HORIZON_S",
    "MAX_POSITION_M",
    "MAX_RATE_RADPS",
    "MAX_SPECIFIC_FORCE_MPS2",
    "MAX_SPEED_MPS",
    "MAX_STEPS",
    "MAX_TIME_S",
    "MAX_VARIANCE",
    "StampRun",
    "as_real_array",
    "as_time",
    "bounded_steps",
    "check_clock",
    "check_covariance",
    "check_measurement",
    "check_real_inputs",
    "check_rotation",
    "check_time",
    "check_times",
    "check_vector",
    "imu_plausible",
    "plausible_velocity",
]
