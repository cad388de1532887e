"""Coverage of a rectangular search area (paper 000 Sec. II-F.2: "The quadrotor explores a bounded area
with known dimensions, flying at a given height. The vehicle autonomously computes waypoints to inspect
the area and generates trajectories according to the strategy in Sec. II-D").

The paper does not say which pattern; we fly a lawnmower (boustrophedon) pattern: parallel sweeps spaced
by the downward camera's ground footprint, so every point of the area passes under the camera once per
pass. The route is made of minimum-jerk primitives (:mod:`alight.planning.min_jerk`):

- sweeps are flown straight at constant cruise speed (a primitive with alpha = beta = gamma = 0), so the
  images along a row are evenly spaced, the camera stays level (zero acceleration, no tilt) and no time
  or energy goes into stopping at each waypoint, as a rest-to-rest route would;
- turns between sweeps are primitives with fixed position, velocity and zero acceleration at both ends
  (the end state of one sweep to the start state of the next); each turn gets the shortest duration on a
  geometric grid that passes the input-feasibility test under gentle limits (``max_accel_mps2``), so
  the tilt stays small and the camera keeps looking roughly down. A turn may bulge outside the area by a
  little (the cost of turning at speed);
- the pattern repeats forever as a ping-pong cycle: all sweeps forward, then all sweeps backward, then
  forward again. The platform moves, so an area searched a minute ago may hold it now; flying the pattern
  backwards starts right where the forward pass ended (no transit back across the area).
"""

from __future__ import annotations

import bisect
import math

import numpy as np

from alight.airframe import DEFAULT_AIRFRAME
from alight.planning.min_jerk import (
    EndConstraint,
    InputFeasibility,
    MinJerkTrajectory,
    _evaluate_kernel,
    _states,
)
from alight.types import GRAVITY_MPS2, FloatArray

__all__ = [
    "footprint_width_m",
    "lawnmower_waypoints",
    "ring_waypoints",
    "spiral_waypoints",
    "ExplorationRoute",
]


def footprint_width_m(altitude_m: float, fov_rad: float, overlap: float = 0.0) -> float:
    """Row spacing (m) for a downward camera: the ground footprint width 2 h tan(fov / 2) of a nadir
    camera at height ``altitude_m`` (m above the ground) with field of view ``fov_rad`` across the sweep
    direction, reduced so that neighbouring footprints overlap by the fraction ``overlap`` in [0, 1)."""
    if not (altitude_m > 0.0 and math.isfinite(altitude_m)):
        raise ValueError(f"altitude_m must be > 0, got {altitude_m}")
    if not (0.0 < fov_rad < math.pi):
        raise ValueError(f"fov_rad must be in (0, pi), got {fov_rad}")
    if not (0.0 <= overlap < 1.0):
        raise ValueError(f"overlap must be in [0, 1), got {overlap}")
    return 2.0 * altitude_m * math.tan(0.5 * fov_rad) * (1.0 - overlap)


def _check_area(
    x_min: float, x_max: float, y_min: float, y_max: float, altitude_m: float, spacing_m: float
) -> None:
    """The search area's arguments, as both patterns take them; ValueError when they are unusable."""
    vals = (x_min, x_max, y_min, y_max, altitude_m, spacing_m)
    if not all(math.isfinite(v) for v in vals):
        raise ValueError("area bounds, altitude and spacing must be finite")
    if not (x_max > x_min and y_max > y_min):
        raise ValueError(f"empty search area: x [{x_min}, {x_max}], y [{y_min}, {y_max}]")
    if not spacing_m > 0.0:
        raise ValueError(f"spacing_m must be > 0, got {spacing_m}")


def lawnmower_waypoints(
    x_min: float,
    x_max: float,
    y_min: float,
    y_max: float,
    altitude_m: float,
    spacing_m: float,
    start_xy: FloatArray | None = None,
    rows_along: str = "auto",
) -> FloatArray:
    """Waypoints of a lawnmower pattern over the rectangle [x_min, x_max] x [y_min, y_max] at height
    ``altitude_m`` (m, world z), shape (2 R, 3): consecutive pairs are the start and end of each sweep.

    The R = ceil(width / spacing_m) sweeps are evenly spaced at width / R <= spacing_m, the outer ones
    half a spacing in from the edges, and run the full length of the area, so every point of the area is
    within spacing_m / 2 of a sweep. Sweeps run along the longer side (fewer turns) unless ``rows_along``
    is ``"x"`` or ``"y"``. The pattern starts at the corner nearest to ``start_xy`` ((2,), m; default
    (x_min, y_min)); ties go to the lower x, then the lower y.
    """
    _check_area(x_min, x_max, y_min, y_max, altitude_m, spacing_m)
    if rows_along not in ("auto", "x", "y"):
        raise ValueError(f"rows_along must be 'auto', 'x' or 'y', got {rows_along!r}")
    along_x = (x_max - x_min >= y_max - y_min) if rows_along == "auto" else rows_along == "x"
    lo_a, hi_a, lo_c, hi_c = (x_min, x_max, y_min, y_max) if along_x else (y_min, y_max, x_min, x_max)
    width = hi_c - lo_c
    n_rows = max(1, math.ceil(width / spacing_m - 1e-9))  # the 1e-9: width an exact multiple of spacing
    rows_c = lo_c + (np.arange(n_rows) + 0.5) * (width / n_rows)

    start = np.array([x_min, y_min] if start_xy is None else start_xy, dtype=np.float64).reshape(-1)
    if start.shape != (2,) or not np.isfinite(start).all():
        raise ValueError("start_xy must be a finite (2,) vector")
    # The four ways to lay the pattern: first row on the low/high side, first sweep forwards/backwards.
    # Ties: the lower x, then the lower y, of the first waypoint.
    layouts = []
    for first_a in (lo_a, hi_a):
        for first_c_low in (True, False):
            first_c = rows_c[0] if first_c_low else rows_c[-1]
            xy = (first_a, first_c) if along_x else (first_c, first_a)
            layouts.append(
                (math.hypot(xy[0] - start[0], xy[1] - start[1]), xy[0], xy[1], first_a, first_c_low)
            )
    _, _, _, first_a, first_c_low = min(layouts)
    order = rows_c if first_c_low else rows_c[::-1]
    out = np.empty((2 * n_rows, 3))
    a_from, a_to = (lo_a, hi_a) if first_a == lo_a else (hi_a, lo_a)
    for k, c in enumerate(order):
        s, e = (a_from, a_to) if k % 2 == 0 else (a_to, a_from)
        out[2 * k] = (s, c, altitude_m) if along_x else (c, s, altitude_m)
        out[2 * k + 1] = (e, c, altitude_m) if along_x else (c, e, altitude_m)
    return out


def spiral_waypoints(
    x_min: float,
    x_max: float,
    y_min: float,
    y_max: float,
    altitude_m: float,
    spacing_m: float,
    center_xy: FloatArray | None = None,
) -> FloatArray:
    """Waypoints of an outward square spiral over [x_min, x_max] x [y_min, y_max] at ``altitude_m``,
    shape (2 L, 3): consecutive pairs are the start and end of each straight leg, as for
    :func:`lawnmower_waypoints`.

    Why a spiral: a moving platform that drives through the area is most likely near the centre, where
    the vehicle takes off, early in the mission; a lawnmower from a corner reaches the centre only half-way
    through its pass. The legs go east, north, west, south with lengths s, s, 2s, 2s, 3s, 3s, ... (s =
    ``spacing_m``) around ``center_xy`` (default: the area's centre), so rings are s apart; legs are
    clipped to the area, and each leg is cut short by a quarter spacing at both ends so that the turn
    between two legs has room. Corner cuts and the clipped outer ring leave points up to about 2/3 s from
    the nearest leg (a lawnmower guarantees s / 2), so use a little more overlap than for a lawnmower.
    """
    _check_area(x_min, x_max, y_min, y_max, altitude_m, spacing_m)
    c = np.array(
        [0.5 * (x_min + x_max), 0.5 * (y_min + y_max)] if center_xy is None else center_xy, dtype=np.float64
    ).reshape(-1)
    if c.shape != (2,) or not np.isfinite(c).all():
        raise ValueError("center_xy must be a finite (2,) vector")
    c = np.clip(c, [x_min, y_min], [x_max, y_max])
    reach = max(c[0] - x_min, x_max - c[0], c[1] - y_min, y_max - c[1])
    directions = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
    lo, hi = np.array([x_min, y_min]), np.array([x_max, y_max])
    legs: list[tuple[FloatArray, FloatArray]] = []
    vertex = c.copy()
    k = 0
    while True:
        length = spacing_m * (k // 2 + 1)
        nxt = vertex + directions[k % 4] * length
        a, b = np.clip(vertex, lo, hi), np.clip(nxt, lo, hi)
        leg_len = float(np.linalg.norm(b - a))
        if leg_len > 1e-6:
            u = (b - a) / leg_len
            inset = min(0.25 * spacing_m, 0.25 * leg_len)
            legs.append((a + inset * u, b - inset * u))
        vertex = nxt
        k += 1
        # Stop when the spiral has grown past the area on every side: its legs now run along the
        # clipped border, which the last ring already flew.
        if length >= 2.0 * reach + spacing_m and k % 2 == 0:
            break
    out = np.empty((2 * len(legs), 3))
    for i, (a, b) in enumerate(legs):
        out[2 * i] = (a[0], a[1], altitude_m)
        out[2 * i + 1] = (b[0], b[1], altitude_m)
    return out


def ring_waypoints(
    x_min: float,
    x_max: float,
    y_min: float,
    y_max: float,
    grow_from_m: float,
    grow_to_m: float,
    altitude_m: float,
    spacing_m: float,
) -> FloatArray:
    """Waypoints of rectangular loops around [x_min, x_max] x [y_min, y_max]: the band between the area
    grown by ``grow_from_m`` and by ``grow_to_m`` on every side, loops ``spacing_m`` apart starting half a
    spacing outside the inner edge, shape (2 L, 3) as :func:`spiral_waypoints` (each leg cut short by a
    quarter spacing at both ends for the turn). For searching around an area already covered."""
    vals = (x_min, x_max, y_min, y_max, grow_from_m, grow_to_m, altitude_m, spacing_m)
    if not all(math.isfinite(v) for v in vals):
        raise ValueError("ring bounds, altitude and spacing must be finite")
    if not (x_max > x_min and y_max > y_min and spacing_m > 0 and grow_to_m > grow_from_m >= 0):
        raise ValueError("ring_waypoints needs a non-empty area, spacing > 0 and grow_to > grow_from >= 0")
    legs: list[tuple[tuple[float, float], tuple[float, float]]] = []
    d = grow_from_m + 0.5 * spacing_m
    while d <= grow_to_m + 1e-9 or not legs:
        x0, x1, y0, y1 = x_min - d, x_max + d, y_min - d, y_max + d
        corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)]
        legs += [(corners[i], corners[i + 1]) for i in range(4)]
        d += spacing_m
    out = np.empty((2 * len(legs), 3))
    for i, (a, b) in enumerate(legs):
        pa, pb = np.array(a), np.array(b)
        u = (pb - pa) / float(np.linalg.norm(pb - pa))
        inset = 0.25 * spacing_m
        out[2 * i, :2], out[2 * i + 1, :2] = pa + inset * u, pb - inset * u
        out[2 * i, 2] = out[2 * i + 1, 2] = altitude_m
    return out


class ExplorationRoute:
    """A reference trajectory that flies the sweeps of ``waypoints`` (pairs of start/end points, as from
    :func:`lawnmower_waypoints`) forever, starting from the state (p0, v0, a0) at time t0.

    Args:
        waypoints: (2 R, 3) sweep start/end points in W (m).
        t0: start time (s).
        p0, v0, a0: the vehicle's state at t0 (m, m/s, m/s^2), each (3,).
        cruise_speed_mps: speed along the sweeps (m/s).
        max_accel_mps2: gentle acceleration limit for the turns and the approach (m/s^2): the input test
            runs with thrust in [g - a, sqrt(g^2 + a^2)] (a level turn tilts by at most atan(a / g)).
        w_max: body-rate bound (rad/s).
        min_section_s: resolution of the input test (s).
        floor_z: floor height (m) every turn must stay above; None: no floor test.
    """

    def __init__(
        self,
        waypoints: FloatArray,
        *,
        t0: float,
        p0: FloatArray,
        v0: FloatArray | None = None,
        a0: FloatArray | None = None,
        cruise_speed_mps: float = 2.0,
        max_accel_mps2: float = 2.0,
        w_max: float = DEFAULT_AIRFRAME.max_body_rate,
        min_section_s: float = 0.02,
        floor_z: float | None = None,
    ) -> None:
        wp = np.asarray(waypoints, dtype=np.float64)
        if (
            wp.ndim != 2
            or wp.shape[1] != 3
            or wp.shape[0] < 2
            or wp.shape[0] % 2
            or not np.isfinite(wp).all()
        ):
            raise ValueError(f"waypoints must be finite (2R, 3) sweep start/end pairs, got shape {wp.shape}")
        if not (cruise_speed_mps > 0.0 and math.isfinite(cruise_speed_mps)):
            raise ValueError(f"cruise_speed_mps must be > 0, got {cruise_speed_mps}")
        if not (0.0 < max_accel_mps2 < GRAVITY_MPS2):
            raise ValueError(f"max_accel_mps2 must be in (0, g), got {max_accel_mps2}")
        if not (w_max > 0.0 and min_section_s > 0.0):
            raise ValueError("w_max and min_section_s must be > 0")
        if not math.isfinite(t0):
            raise ValueError("t0 must be finite")
        self.cruise_speed_mps = float(cruise_speed_mps)
        self._limits = np.array(
            [GRAVITY_MPS2 - max_accel_mps2, math.hypot(GRAVITY_MPS2, max_accel_mps2), w_max, min_section_s]
        )
        self._floor_z = floor_z
        self._max_accel = float(max_accel_mps2)
        z3 = np.zeros(3)
        p_start = np.asarray(p0, dtype=np.float64).reshape(3)
        v_start = z3 if v0 is None else np.asarray(v0, dtype=np.float64).reshape(3)
        a_start = z3 if a0 is None else np.asarray(a0, dtype=np.float64).reshape(3)

        fwd = [(wp[2 * k], wp[2 * k + 1]) for k in range(wp.shape[0] // 2)]
        sweeps = fwd + [(e, s) for s, e in reversed(fwd)]  # the ping-pong cycle
        v = self.cruise_speed_mps
        units = []
        for s, e in sweeps:
            length = float(np.linalg.norm(e - s))
            if length <= 0.0:
                raise ValueError("a sweep has zero length")
            units.append((e - s) / length)

        # the approach to the first sweep's start at cruise speed along it
        self.approach = self._turn(float(t0), p_start, v_start, a_start, sweeps[0][0], v * units[0])
        # one cycle, with absolute times of the first cycle
        segs: list[MinJerkTrajectory] = []
        t = self.approach.t_end
        self.t_cycle_start = t
        n_fwd = len(fwd)
        t_first_pass_end = math.nan
        for k, ((s, e), u) in enumerate(zip(sweeps, units, strict=True)):
            length = float(np.linalg.norm(e - s))
            straight = MinJerkTrajectory(t, length / v, s, v * u, z3, z3, z3, z3)
            segs.append(straight)
            t = straight.t_end
            if k == n_fwd - 1:
                t_first_pass_end = t
            k1 = (k + 1) % len(sweeps)
            turn = self._turn(t, e, v * u, z3, sweeps[k1][0], v * units[k1])
            segs.append(turn)
            t = turn.t_end
        self.segments: tuple[MinJerkTrajectory, ...] = tuple(segs)
        """One cycle of the route (sweeps and turns), timed for the first cycle."""
        self.period_s = t - self.t_cycle_start
        """Duration of one ping-pong cycle (s)."""
        self.t_first_pass_end = t_first_pass_end
        """Time at which every sweep has been flown once (s)."""
        self._offsets = [s.t0 - self.t_cycle_start for s in segs]

    def _turn(
        self, t0: float, p0: FloatArray, v0: FloatArray, a0: FloatArray, p1: FloatArray, v1: FloatArray
    ) -> MinJerkTrajectory:
        """The quickest primitive (durations on a x1.15 grid) to (p1, v1, a = 0) that the input test (and
        the floor test, with a floor) proves feasible under the route's gentle limits."""
        dist = float(np.linalg.norm(p1 - p0))
        dv = float(np.linalg.norm(v1 - v0))
        # a lower bound on the duration to start the search from: a min-jerk velocity change needs a peak
        # acceleration of at least dv / T
        T = max(0.5, dist / self.cruise_speed_mps, dv / self._max_accel)
        # _states: (1, 3) writable arrays whatever the caller hands in (a read-only argument, an estimate's
        # frozen state, would be another compiled signature of the kernel, compiled mid-mission)
        P0, V0, A0 = _states(p0, "p0"), _states(v0, "v0"), _states(a0, "a0")
        PF, VF = _states(p1, "p1"), _states(v1, "v1")
        AF = np.zeros((1, 3))
        check = self._floor_z is not None
        q = np.array([0.0, 0.0, self._floor_z if check else 0.0])
        nrm = np.array([0.0, 0.0, 1.0])
        al, be, ga = np.empty((1, 3)), np.empty((1, 3)), np.empty((1, 3))
        cost, codes, floor_ok = np.empty(1), np.empty(1, np.int64), np.empty(1, np.bool_)
        for _ in range(80):  # 1.15^80 ~ 7e4: from 0.5 s to hours
            Ts = np.array([T])
            _evaluate_kernel(
                P0, V0, A0, Ts, PF, VF, AF, int(EndConstraint.POS_VEL_ACC), self._limits, check, q, nrm,
                al, be, ga, cost, codes, floor_ok,
            )  # fmt: skip
            if codes[0] == InputFeasibility.FEASIBLE and floor_ok[0]:
                return MinJerkTrajectory(t0, T, P0[0], V0[0], A0[0], al[0], be[0], ga[0])
            T *= 1.15
        raise ValueError(
            "no feasible turn found: the start state is too far from feasible or below the floor"
        )

    def _segment(self, t: float) -> MinJerkTrajectory | tuple[MinJerkTrajectory, float]:
        if t < self.t_cycle_start:
            return self.approach
        tau = math.fmod(t - self.t_cycle_start, self.period_s)
        i = bisect.bisect_right(self._offsets, tau) - 1
        seg = self.segments[i]
        return seg, seg.t0 + (tau - self._offsets[i])

    def reference(self, t: float) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Position (m), velocity (m/s), acceleration (m/s^2), jerk (m/s^3) at time t, each (3,).
        Before t0 the route is held at its start state."""
        s = self._segment(t)
        if isinstance(s, MinJerkTrajectory):
            return s.sample(t)
        seg, ts = s
        return seg.sample(ts)

    def reference_packed(self, t: float) -> FloatArray:
        """As :meth:`reference`, stacked in one new array (4, 3): rows p, v, a, j."""
        s = self._segment(t)
        if isinstance(s, MinJerkTrajectory):
            return s.sample_packed(t)
        seg, ts = s
        return seg.sample_packed(ts)

    def done(self, t: float) -> bool:
        """True once every sweep has been flown at least once (the route itself keeps looping)."""
        return t >= self.t_first_pass_end
