"""Planning against a fast platform: where to meet it, how long to plan, how far to search.

Pure functions, each worked by hand in ``tests/unit/test_envelope.py``:

- :func:`intercept_time`: the earliest time T at which a vehicle leaving ``p0`` now at ``speed`` can be
  where the platform is predicted to be, ``|p_WP(T) - p0| <= speed T``. Flying to that point (ahead of a
  fast platform) means the vehicle need not out-run the platform from behind, which it cannot when the
  platform is about as fast as itself.
- :func:`horizontal_speed_limit`: the vehicle's top horizontal speed from its airframe: at the tilt
  limit the horizontal thrust ``g tan(tilt)`` is all spent against the rotor drag ``d v``.
- :func:`adaptive_horizon`: the candidates' duration window from the distance to cover and the
  horizontal acceleration the airframe has, so that a feasible primitive exists.
- :func:`search_half_width`: the half-width of the area a platform of bounded speed can have reached.
"""

from __future__ import annotations

import math

import numpy as np

from alight.types import GRAVITY_MPS2, FloatArray

MIN_JERK_PEAK_ACCEL = 10.0 / math.sqrt(3.0)
"""Peak acceleration of a rest-to-rest minimum-jerk move over distance d in time T is this times d / T^2
(5.77; the quintic 10 s^3 - 15 s^4 + 6 s^5 has its largest second derivative at s = 1/2 - sqrt(3)/6)."""


def reach_m(t: FloatArray, speed_mps: float, accel_mps2: float | None = None) -> FloatArray:
    """Distance (m) a vehicle starting from rest covers in ``t`` (s) accelerating at ``accel_mps2`` up to
    ``speed_mps`` (``speed t`` without an acceleration): ``a t^2 / 2`` until ``s / a``, then
    ``s t - s^2 / (2 a)``."""
    t = np.asarray(t, dtype=np.float64)
    if accel_mps2 is None or not math.isfinite(accel_mps2):
        return speed_mps * t
    t_ramp = speed_mps / accel_mps2
    return np.where(t < t_ramp, 0.5 * accel_mps2 * t * t, speed_mps * t - 0.5 * speed_mps * t_ramp)


def intercept_time(
    p0_xy: FloatArray, t_rel: FloatArray, p_xy: FloatArray, speed_mps: float, accel_mps2: float | None = None
) -> float | None:
    """Earliest T (s from now) at which the vehicle's reach (:func:`reach_m`: ``speed_mps T`` without an
    ``accel_mps2``) covers ``|p_xy(T) - p0_xy|``, the platform's predicted horizontal positions ``p_xy``
    (k, 2) sampled at increasing ``t_rel`` (k,) (s from now, t_rel[0] >= 0); linear between the samples.
    None when the platform stays out of reach over the samples."""
    t = np.asarray(t_rel, dtype=np.float64)
    d = np.linalg.norm(np.asarray(p_xy, dtype=np.float64) - np.asarray(p0_xy, dtype=np.float64), axis=1)
    gap = d - reach_m(t, speed_mps, accel_mps2)  # <= 0 once the vehicle can be there
    hit = np.flatnonzero(gap <= 0.0)
    if hit.size == 0:
        return None
    i = int(hit[0])
    if i == 0:
        return float(t[0])
    g0, g1 = float(gap[i - 1]), float(gap[i])
    return float(t[i - 1] + (t[i] - t[i - 1]) * g0 / (g0 - g1))


def intercept_time_constant_velocity(d_xy: FloatArray, v_xy: FloatArray, speed_mps: float) -> float | None:
    """Closed form of :func:`intercept_time` for a platform at ``d_xy`` (m, from the vehicle) moving at a
    constant ``v_xy`` (m/s): the smallest T >= 0 with ``|d + v T| = speed T``, a root of
    ``(|v|^2 - s^2) T^2 + 2 (d . v) T + |d|^2 = 0``; None when there is none."""
    d = np.asarray(d_xy, dtype=np.float64)
    v = np.asarray(v_xy, dtype=np.float64)
    a = float(v @ v) - speed_mps**2
    b = 2.0 * float(d @ v)
    c = float(d @ d)
    if c == 0.0:
        return 0.0
    if abs(a) < 1e-12:
        return -c / b if b < 0.0 else None
    disc = b * b - 4.0 * a * c
    if disc < 0.0:
        return None
    roots = sorted(((-b - math.sqrt(disc)) / (2 * a), (-b + math.sqrt(disc)) / (2 * a)))
    positive = [r for r in roots if r >= 0.0]
    return positive[0] if positive else None


def horizontal_speed_limit(max_tilt_rad: float, rotor_drag_per_s: float) -> float:
    """Top horizontal speed (m/s) in still air: at the tilt limit the horizontal thrust per unit mass,
    ``g tan(tilt)``, equals the linear rotor drag ``d v``; infinite without drag."""
    if rotor_drag_per_s <= 0.0:
        return math.inf
    return GRAVITY_MPS2 * math.tan(max_tilt_rad) / rotor_drag_per_s


def adaptive_horizon(
    distance_m: float,
    accel_max_mps2: float,
    horizon_min_s: float,
    horizon_max_s: float,
    t_intercept_s: float | None = None,
) -> tuple[float, float]:
    """The candidates' duration window (s) for a target ``distance_m`` away (to the intercept point when
    there is one), with ``accel_max_mps2`` of horizontal acceleration.

    A rest-to-rest minimum-jerk move over d needs ``T >= sqrt(5.77 d / a_max)`` (its peak acceleration is
    5.77 d / T^2), so a fixed 1-3 s window has no feasible candidate beyond ~5-15 m: the shortest duration
    is that bound (never below ``horizon_min_s``) and the longest twice it (never below
    ``horizon_max_s``).

    With an intercept time the window is ``[T, 1.1 T]`` (T never below ``horizon_min_s``): the
    planner picks the cheapest candidate, which is the longest one, and a window reaching far beyond T
    would put the meeting point later at every replanning, so that the vehicle never arrives."""
    if t_intercept_s is not None and math.isfinite(t_intercept_s):
        lo = max(horizon_min_s, t_intercept_s)
        return lo, 1.1 * lo
    t_acc = math.sqrt(MIN_JERK_PEAK_ACCEL * max(distance_m, 0.0) / accel_max_mps2)
    lo = max(horizon_min_s, t_acc)
    return lo, max(horizon_max_s, 2.0 * lo)


def search_half_width(base_half_width_m: float, elapsed_s: float, max_platform_speed_mps: float) -> float:
    """Half-width (m) of the square a platform can be in ``elapsed_s`` after it was somewhere within
    ``base_half_width_m`` of its centre, at no more than ``max_platform_speed_mps``: the area grows by
    speed x time on every side."""
    return base_half_width_m + max_platform_speed_mps * max(elapsed_s, 0.0)
