"""The moving platform: a non-holonomic ground vehicle that carries the landing pad along a path.

Every path is parametrised by its arc length ``s``, and the vehicle is at ``s = speed * t``. Its
heading is the path tangent, so it moves at exactly the set speed and never slides sideways (a
unicycle, as the platform models of paper 000 Sec. II-C and paper 004 Sec. IV-B assume). With the
signed curvature ``kappa(s)``::

    v_WP = speed (cos yaw, sin yaw, 0),  a_WP = speed^2 kappa (-sin yaw, cos yaw, 0),  yaw_rate = speed kappa

Paths (each starts at ``start_xy_m`` with heading ``start_heading``):

- ``straight``: a line.
- ``circle``: radius ``circle_radius_m`` (10 m), turning left unless ``turn_left`` is false. With the
  default start (10, 0) heading +y the circle is centred on the take-off point.
- ``figure8``: a lemniscate of Bernoulli ``x = a cos u / (1 + sin^2 u), y = a sin u cos u / (1 + sin^2 u)``
  with ``a = figure8_length_m / 2`` (30 m tip to tip, 78.7 m around), starting at the crossing. Its arc
  length is ``a F(u | -1)`` (incomplete elliptic integral of the first kind, evaluated with Carlson's R_F)
  and its curvature ``3 cos u / (a sqrt(1 + sin^2 u))``, both derived from the parametrisation.
- ``tractor``: boustrophedon rows of ``tractor_row_length_m`` (30 m) joined by semicircular U-turns of
  radius ``tractor_turn_radius_m`` (4 m), alternately left and right, so that the field is swept row
  after row (8 m apart) without end.
- ``random``: smooth random curvature ``kappa(s) = kappa_max tanh(z(s))``, ``z`` a cubic spline through
  N(0, 0.6^2) knots every ``random_length_scale_m``, so ``|kappa| < random_max_curvature`` (0.15 1/m). The
  curvature is held constant over 0.25 m pieces (arcs, so the geometry is exact); the path is drawn for
  ``random_length_m`` and goes straight on after that.

Speed profiles (:class:`SpeedProfile`): the speed along the path may change with a piecewise-constant
tangential acceleration ``a_t`` (a hard brake to a stop and driving on, or a ramp to a new speed). The
arc length is then integrated in closed form, ``s = s_i + v_i (t - t_i) + a_i (t - t_i)^2 / 2`` in
phase i, so the geometry is the same path and only the timing along it changes; the velocity is
``v(t)`` along the tangent and the acceleration gains the tangential term ``a_t (cos yaw, sin yaw, 0)``.

The arc-type paths are tables of circular arcs evaluated in closed form by a numba kernel; use
:meth:`Platform.states` (vectorised) when many times are needed at once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numba import njit
from scipy.interpolate import CubicSpline

from alight.types import FloatArray, wrap_angle

PathKind = Literal["straight", "circle", "figure8", "tractor", "random"]
PATH_KINDS: tuple[str, ...] = ("straight", "circle", "figure8", "tractor", "random")

_RANDOM_PIECE_M = 0.25
_RANDOM_KNOT_STD = 0.6


@dataclass(frozen=True)
class SpeedProfile:
    """Speed along the path as phases of constant tangential acceleration.

    The platform starts at ``PlatformConfig.speed_mps`` with no acceleration; from ``t_s[i]`` on its
    tangential acceleration is ``accel_mps2[i]`` (m/s^2), until the next phase. The constructors below
    build phases that never make the speed negative.
    """

    t_s: tuple[float, ...]
    """Start of each phase (s), increasing."""
    accel_mps2: tuple[float, ...]
    """Tangential acceleration in each phase (m/s^2)."""

    def __post_init__(self) -> None:
        if len(self.t_s) != len(self.accel_mps2) or not self.t_s:
            raise ValueError("a speed profile needs one acceleration per phase start, at least one phase")
        if any(not math.isfinite(x) for x in (*self.t_s, *self.accel_mps2)):
            raise ValueError("speed profile times and accelerations must be finite")
        if any(b <= a for a, b in zip(self.t_s, self.t_s[1:], strict=False)) or self.t_s[0] < 0.0:
            raise ValueError(f"speed profile phases must start at increasing times >= 0, got {self.t_s}")

    @classmethod
    def brake_stop(
        cls, speed_mps: float, t_s: float, decel_mps2: float, wait_s: float, accel_mps2: float
    ) -> SpeedProfile:
        """Brake at ``t_s`` from ``speed_mps`` to a stop at ``decel_mps2``, stand ``wait_s``, then drive on
        back to ``speed_mps`` at ``accel_mps2``."""
        if not (decel_mps2 > 0.0 and accel_mps2 > 0.0 and wait_s >= 0.0 and speed_mps >= 0.0):
            raise ValueError("brake_stop needs decel_mps2, accel_mps2 > 0 and wait_s, speed_mps >= 0")
        if speed_mps == 0.0:
            return cls((t_s,), (0.0,))  # a parked platform has nothing to brake
        t_stop = t_s + speed_mps / decel_mps2
        t_go = t_stop + wait_s
        phases = [(t_s, -decel_mps2)]
        if wait_s > 0.0:
            phases.append((t_stop, 0.0))
        phases += [(t_go, accel_mps2), (t_go + speed_mps / accel_mps2, 0.0)]
        return cls(tuple(p[0] for p in phases), tuple(p[1] for p in phases))

    @classmethod
    def ramp(cls, speed_mps: float, t_s: float, new_speed_mps: float, accel_mps2: float) -> SpeedProfile:
        """From ``speed_mps``, change speed at ``t_s`` to ``new_speed_mps`` at ``accel_mps2`` (either way)."""
        if not (accel_mps2 > 0.0 and new_speed_mps >= 0.0):
            raise ValueError("ramp needs accel_mps2 > 0 and new_speed_mps >= 0")
        dv = new_speed_mps - speed_mps
        if dv == 0.0:
            return cls((t_s,), (0.0,))
        return cls((t_s, t_s + abs(dv) / accel_mps2), (math.copysign(accel_mps2, dv), 0.0))

    def kinematics(self, speed_mps: float, t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Arc length s (m), speed v (m/s) and tangential acceleration a_t (m/s^2) at the times t (s),
        each shape (N,), starting at ``speed_mps`` at t = 0."""
        ts = np.concatenate([[0.0], np.asarray(self.t_s, dtype=np.float64)])
        acc = np.concatenate([[0.0], np.asarray(self.accel_mps2, dtype=np.float64)])
        if self.t_s[0] == 0.0:  # a phase starting at 0 replaces the constant-speed start
            ts, acc = ts[1:], acc[1:]
        dts = np.diff(ts)
        v_at = speed_mps + np.concatenate([[0.0], np.cumsum(acc[:-1] * dts)])
        s_at = np.concatenate([[0.0], np.cumsum(v_at[:-1] * dts + 0.5 * acc[:-1] * dts**2)])
        tt = np.asarray(t, dtype=np.float64)
        i = np.clip(np.searchsorted(ts, tt, side="right") - 1, 0, ts.size - 1)
        dt = tt - ts[i]
        v = v_at[i] + acc[i] * dt
        # the constructors end each braking phase exactly at v = 0; rounding must not make it negative
        v = np.maximum(v, 0.0)
        s = s_at[i] + v_at[i] * dt + 0.5 * acc[i] * dt**2
        return s, v, np.where(v > 0.0, acc[i], np.maximum(acc[i], 0.0))


@dataclass(frozen=True, kw_only=True)
class PlatformConfig:
    """How the platform moves and what it carries."""

    path: PathKind = "straight"
    """One of ``straight``, ``circle``, ``figure8``, ``tractor``, ``random``."""
    speed_mps: float = 1.5
    """Speed along the path (m/s), constant; 0 for a parked platform."""
    pad_size_m: float = 1.5
    """Side of the square pad (m)."""
    pad_height_m: float = 0.5
    """Height of the pad surface above the ground (m)."""
    start_xy_m: tuple[float, float] = (10.0, 0.0)
    """Pad centre at t = 0, in W (m)."""
    start_heading: float = math.pi / 2
    """Heading at t = 0 (rad, from W x, counter-clockwise)."""
    turn_left: bool = True
    """Circle: turn left (counter-clockwise); tractor: first U-turn to the left."""
    circle_radius_m: float = 10.0
    """Radius of the circle path (m)."""
    figure8_length_m: float = 30.0
    """Tip-to-tip length of the figure-8 (m); the lemniscate's a is half of it."""
    tractor_row_length_m: float = 30.0
    """Length of a straight row of the tractor path (m)."""
    tractor_turn_radius_m: float = 4.0
    """Radius of the tractor's U-turns (m); rows are twice this apart."""
    random_max_curvature: float = 0.15
    """Bound on |kappa| of the random path (1/m)."""
    random_length_scale_m: float = 20.0
    """Distance between the random curvature's knots (m)."""
    random_length_m: float = 5000.0
    """Length of the random path drawn at construction (m); it continues straight beyond."""
    speed_profile: SpeedProfile | None = None
    """Changes of speed along the path; None: ``speed_mps`` throughout."""

    def __post_init__(self) -> None:
        if self.path not in PATH_KINDS:
            raise ValueError(f"path must be one of {PATH_KINDS}, got {self.path!r}")
        if not (self.speed_mps >= 0.0 and math.isfinite(self.speed_mps)):
            raise ValueError(f"speed_mps must be finite and >= 0, got {self.speed_mps}")
        for name in (
            "pad_size_m",
            "circle_radius_m",
            "figure8_length_m",
            "tractor_row_length_m",
            "tractor_turn_radius_m",
            "random_max_curvature",
            "random_length_scale_m",
            "random_length_m",
        ):
            v = getattr(self, name)
            if not (v > 0.0 and math.isfinite(v)):
                raise ValueError(f"{name} must be positive and finite, got {v}")
        if self.pad_height_m < 0.0:
            raise ValueError(f"pad_height_m must be >= 0, got {self.pad_height_m}")
        if len(self.start_xy_m) != 2:
            raise ValueError(f"start_xy_m must have 2 entries, got {self.start_xy_m}")


@dataclass(frozen=True, slots=True)
class PlatformTruth:
    """The platform's true state at one time (pad centre on the pad surface)."""

    t: float
    """Time (s)."""
    p_WP: FloatArray
    """Pad centre in W (m), shape (3,); z is the pad height."""
    v_WP: FloatArray
    """Velocity in W (m/s), shape (3,)."""
    a_WP: FloatArray
    """Acceleration in W (m/s^2), shape (3,)."""
    yaw: float
    """Heading, wrapped to [-pi, pi) (rad)."""
    yaw_rate: float
    """Heading rate (rad/s)."""


@dataclass(frozen=True, slots=True)
class PlatformStates:
    """The platform's true states at N times (the fields of :class:`PlatformTruth`, stacked)."""

    t: FloatArray
    """Times (s), shape (N,)."""
    p_WP: FloatArray
    """Pad centres in W (m), shape (N, 3)."""
    v_WP: FloatArray
    """Velocities in W (m/s), shape (N, 3)."""
    a_WP: FloatArray
    """Accelerations in W (m/s^2), shape (N, 3)."""
    yaw: FloatArray
    """Headings in [-pi, pi) (rad), shape (N,)."""
    yaw_rate: FloatArray
    """Heading rates (rad/s), shape (N,)."""

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def at(self, i: int) -> PlatformTruth:
        """The i-th state as a :class:`PlatformTruth`."""
        return PlatformTruth(
            float(self.t[i]),
            self.p_WP[i].copy(),
            self.v_WP[i].copy(),
            self.a_WP[i].copy(),
            float(self.yaw[i]),
            float(self.yaw_rate[i]),
        )


# --------------------------------------------------------------------------------------------------
# Geometry kernels
# --------------------------------------------------------------------------------------------------

# geo array layout (float64): kind, period, shift_x, shift_y, lem_a, lem_u0, lem_rot, lem_x, lem_y,
# lem_s0, lem_len
_KIND_ARCS = 0.0
_KIND_LEMNISCATE = 1.0


@njit(cache=True)
def _carlson_rf(x: float, y: float, z: float) -> float:
    """Carlson's symmetric elliptic integral R_F (duplication method, B. C. Carlson, Numer. Algorithms
    10, 1995); relative error below 1e-15 with the stopping test used here."""
    for _ in range(60):
        sx, sy, sz = math.sqrt(x), math.sqrt(y), math.sqrt(z)
        lam = sx * sy + sx * sz + sy * sz
        x = 0.25 * (x + lam)
        y = 0.25 * (y + lam)
        z = 0.25 * (z + lam)
        mu = (x + y + z) / 3.0
        if max(abs(x - mu), abs(y - mu), abs(z - mu)) < 1e-3 * mu:
            break
    mu = (x + y + z) / 3.0
    X = 1.0 - x / mu
    Y = 1.0 - y / mu
    Z = -(X + Y)
    e2 = X * Y - Z * Z
    e3 = X * Y * Z
    return (1.0 - e2 / 10.0 + e3 / 14.0 + e2 * e2 / 24.0 - 3.0 * e2 * e3 / 44.0) / math.sqrt(mu)


@njit(cache=True)
def ellipf_m1(u: float) -> float:
    """Incomplete elliptic integral of the first kind F(u | m = -1) for any real u."""
    k = math.floor(u / math.pi + 0.5)
    r = u - k * math.pi
    s = math.sin(r)
    f = s * _carlson_rf(math.cos(r) ** 2, 1.0 + s * s, 1.0)
    if k != 0.0:
        f += 2.0 * k * _carlson_rf(0.0, 2.0, 1.0)
    return f


@njit(cache=True)
def _eval_arcs(s: float, seg: FloatArray, geo: FloatArray) -> tuple[float, float, float, float]:
    period = geo[1]
    sx = 0.0
    sy = 0.0
    if period > 0.0:
        n = math.floor(s / period)
        s -= n * period
        sx = n * geo[2]
        sy = n * geo[3]
    i = int(np.searchsorted(seg[:, 0], s, side="right")) - 1
    if i < 0:
        i = 0
    sig = s - seg[i, 0]
    kap = seg[i, 1]
    h0 = seg[i, 4]
    half = 0.5 * kap * sig
    # chord of a circular arc: length sig sin(half) / half, direction h0 + half (exact, and smooth at 0)
    if abs(half) > 1e-6:
        chord = sig * math.sin(half) / half
    else:
        chord = sig * (1.0 - half * half / 6.0)
    x = seg[i, 2] + chord * math.cos(h0 + half) + sx
    y = seg[i, 3] + chord * math.sin(h0 + half) + sy
    return x, y, h0 + 2.0 * half, kap


@njit(cache=True)
def _lemniscate_u(target: float, a: float, u: float) -> float:
    """The parameter u where the lemniscate's arc length from u = 0, a F(u | -1), equals ``target``;
    Newton's method from the guess u (ds/du = a / sqrt(1 + sin^2 u) lies in [a / sqrt 2, a])."""
    for _ in range(40):
        su = math.sin(u)
        du = (a * ellipf_m1(u) - target) * math.sqrt(1.0 + su * su) / a
        u -= du
        if abs(du) < 1e-14:
            break
    return u


@njit(cache=True)
def _eval_lemniscate(s: float, seg: FloatArray, geo: FloatArray) -> tuple[float, float, float, float]:
    a = geo[4]
    u0 = geo[5]
    rot = geo[6]
    length = geo[10]
    # arc length from u = 0 is a F(u | -1); one period (u from 0 to 2 pi) is 4 a K(-1) long
    target = geo[9] + s
    n = math.floor(target / length)
    target -= n * length
    # seg[:, 0] tabulates u on a uniform grid of arc length: a close guess, so Newton takes 2-3 steps
    m = seg.shape[0] - 1
    w = target / length * m
    k = min(int(w), m - 1)
    u = _lemniscate_u(target, a, seg[k, 0] + (w - k) * (seg[k + 1, 0] - seg[k, 0]))
    su, cu = math.sin(u), math.cos(u)
    d = 1.0 + su * su
    xl = a * cu / d
    yl = a * su * cu / d
    # dx/du = -a s (3 - s^2) / D^2, dy/du = a (1 - 3 s^2) / D^2, |d(x,y)/du| = a / sqrt(D)
    h = math.atan2(1.0 - 3.0 * su * su, -su * (3.0 - su * su))
    kap = 3.0 * cu / (a * math.sqrt(d))
    # move the start point to the origin, rotate to the start heading, then translate
    xs = a * math.cos(u0) / (1.0 + math.sin(u0) ** 2)
    ys = a * math.sin(u0) * math.cos(u0) / (1.0 + math.sin(u0) ** 2)
    cr, sr = math.cos(rot), math.sin(rot)
    x = geo[7] + cr * (xl - xs) - sr * (yl - ys)
    y = geo[8] + sr * (xl - xs) + cr * (yl - ys)
    return x, y, h + rot, kap


# One kernel per kind of path, chosen in Python (Platform._eval, _eval_many): a kernel that branched on
# the kind would compile the figure-8's elliptic integrals for every path, and the arcs' search for it.


@njit(cache=True)
def _eval_arcs_many(s: FloatArray, seg: FloatArray, geo: FloatArray) -> FloatArray:
    """(x, y, heading, signed curvature) at each arc length s (m), shape (N, 4): a path of arcs."""
    out = np.empty((s.shape[0], 4))
    for j in range(s.shape[0]):
        x, y, h, k = _eval_arcs(s[j], seg, geo)
        out[j, 0] = x
        out[j, 1] = y
        out[j, 2] = h
        out[j, 3] = k
    return out


@njit(cache=True)
def _eval_lemniscate_many(s: FloatArray, seg: FloatArray, geo: FloatArray) -> FloatArray:
    """(x, y, heading, signed curvature) at each arc length s (m), shape (N, 4): the figure-8."""
    out = np.empty((s.shape[0], 4))
    for j in range(s.shape[0]):
        x, y, h, k = _eval_lemniscate(s[j], seg, geo)
        out[j, 0] = x
        out[j, 1] = y
        out[j, 2] = h
        out[j, 3] = k
    return out


def _arc_table(x0: float, y0: float, h0: float, lengths: FloatArray, kappas: FloatArray) -> FloatArray:
    """Segment table rows (s_start, kappa, x_start, y_start, heading_start) for consecutive arcs."""
    n = lengths.shape[0]
    s_start = np.concatenate([[0.0], np.cumsum(lengths)[:-1]])
    dh = kappas * lengths
    h_start = h0 + np.concatenate([[0.0], np.cumsum(dh)[:-1]])
    half = 0.5 * dh
    chord = lengths * np.sinc(half / np.pi)  # np.sinc(x) = sin(pi x) / (pi x)
    dx = chord * np.cos(h_start + half)
    dy = chord * np.sin(h_start + half)
    xs = x0 + np.concatenate([[0.0], np.cumsum(dx)[:-1]])
    ys = y0 + np.concatenate([[0.0], np.cumsum(dy)[:-1]])
    seg = np.empty((n, 5))
    seg[:, 0] = s_start
    seg[:, 1] = kappas
    seg[:, 2] = xs
    seg[:, 3] = ys
    seg[:, 4] = h_start
    return seg


# --------------------------------------------------------------------------------------------------
# Pad geometry (pure functions, shared with touchdown judging)
# --------------------------------------------------------------------------------------------------


def pad_contains(
    p_xy: FloatArray, p_WP: FloatArray, yaw: float, pad_size_m: float, shrink_m: float = 0.0
) -> bool | np.ndarray:
    """Whether the point(s) p_xy, shape (2,) or (N, 2) in W (m), lie inside the pad square centred at
    p_WP with heading ``yaw``, shrunk by ``shrink_m`` on every side (negative grows it). Edges count as
    inside. Returns a bool, or a bool array of shape (N,)."""
    p = np.asarray(p_xy, dtype=np.float64)
    c, s = math.cos(yaw), math.sin(yaw)
    dx = p[..., 0] - p_WP[0]
    dy = p[..., 1] - p_WP[1]
    lim = 0.5 * pad_size_m - shrink_m
    inside = (np.abs(c * dx + s * dy) <= lim) & (np.abs(-s * dx + c * dy) <= lim)
    return bool(inside) if np.ndim(inside) == 0 else inside


def pad_corners(p_WP: FloatArray, yaw: float, pad_size_m: float) -> FloatArray:
    """Pad corners in W (m), shape (4, 3), counter-clockwise from (+x, +y) of the pad frame P."""
    h = 0.5 * pad_size_m
    local = np.array([[h, h], [-h, h], [-h, -h], [h, -h]])
    c, s = math.cos(yaw), math.sin(yaw)
    out = np.empty((4, 3))
    out[:, 0] = p_WP[0] + c * local[:, 0] - s * local[:, 1]
    out[:, 1] = p_WP[1] + s * local[:, 0] + c * local[:, 1]
    out[:, 2] = p_WP[2]
    return out


# --------------------------------------------------------------------------------------------------
# Platform
# --------------------------------------------------------------------------------------------------


class Platform:
    """The platform moving along its path; ``state(t)`` for one time, ``states(ts)`` for many."""

    def __init__(self, config: PlatformConfig, rng: np.random.Generator | None = None) -> None:
        """``rng`` draws the random path (only ``path="random"`` needs one)."""
        self.config = config
        x0, y0 = float(config.start_xy_m[0]), float(config.start_xy_m[1])
        h0 = float(config.start_heading)
        geo = np.zeros(11)
        side = 1.0 if config.turn_left else -1.0
        self.period_m: float | None = None
        """Length after which the path repeats itself (m), None for open paths."""
        if config.path == "straight":
            seg = _arc_table(x0, y0, h0, np.array([1.0]), np.array([0.0]))
        elif config.path == "circle":
            r = config.circle_radius_m
            seg = _arc_table(x0, y0, h0, np.array([2 * math.pi * r]), np.array([side / r]))
            geo[1] = 2 * math.pi * r
            self.period_m = geo[1]
        elif config.path == "tractor":
            L, r = config.tractor_row_length_m, config.tractor_turn_radius_m
            lengths = np.array([L, math.pi * r, L, math.pi * r])
            seg = _arc_table(x0, y0, h0, lengths, np.array([0.0, side / r, 0.0, -side / r]))
            geo[1] = float(lengths.sum())
            # after a left and a right U-turn the vehicle is 4 r to the side, heading as at the start
            geo[2] = 4 * r * side * -math.sin(h0)
            geo[3] = 4 * r * side * math.cos(h0)
        elif config.path == "random":
            if rng is None:
                raise ValueError("the random path needs a numpy Generator")
            seg = self._random_table(config, rng, x0, y0, h0)
        else:  # figure8
            a = 0.5 * config.figure8_length_m
            u0 = -0.5 * math.pi  # the crossing, heading -45 deg in the lemniscate's own frame
            geo[0] = _KIND_LEMNISCATE
            geo[4] = a
            geo[5] = u0
            geo[6] = h0 + 0.25 * math.pi
            geo[7] = x0
            geo[8] = y0
            geo[10] = 4.0 * a * float(_carlson_rf(0.0, 2.0, 1.0))  # 4 a K(-1)
            geo[9] = a * float(ellipf_m1(u0)) % geo[10]
            self.period_m = geo[10]
            n_tab = 256
            seg = np.zeros((n_tab + 1, 5))
            for k in range(n_tab + 1):
                seg[k, 0] = _lemniscate_u(k * geo[10] / n_tab, a, 2 * math.pi * k / n_tab)
        self._seg = np.ascontiguousarray(seg)
        self._geo = geo
        lemniscate = geo[0] == _KIND_LEMNISCATE
        self._eval = _eval_lemniscate if lemniscate else _eval_arcs
        self._eval_many = _eval_lemniscate_many if lemniscate else _eval_arcs_many

    @staticmethod
    def _random_table(
        config: PlatformConfig, rng: np.random.Generator, x0: float, y0: float, h0: float
    ) -> FloatArray:
        ell = config.random_length_scale_m
        n_knots = int(math.ceil(config.random_length_m / ell)) + 2
        z = rng.normal(0.0, _RANDOM_KNOT_STD, n_knots)
        spline = CubicSpline(np.arange(n_knots) * ell, z)
        n = int(math.ceil(config.random_length_m / _RANDOM_PIECE_M))
        mid = (np.arange(n) + 0.5) * _RANDOM_PIECE_M
        kappa = config.random_max_curvature * np.tanh(spline(mid))
        lengths = np.full(n + 1, _RANDOM_PIECE_M)
        kappa = np.append(kappa, 0.0)  # the last piece extends straight on without end
        return _arc_table(x0, y0, h0, lengths, kappa)

    # ----------------------------------------------------------------------------------------------

    def _along(self, t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Arc length (m), speed (m/s) and tangential acceleration (m/s^2) at the times t (s)."""
        v = self.config.speed_mps
        if self.config.speed_profile is None:
            return v * t, np.full(t.shape, v), np.zeros(t.shape)
        return self.config.speed_profile.kinematics(v, t)

    def state(self, t: float) -> PlatformTruth:
        """The platform at time t (s)."""
        if self.config.speed_profile is not None:
            return self.states(np.array([t])).at(0)
        v = self.config.speed_mps
        x, y, h, k = self._eval(v * t, self._seg, self._geo)
        c, s = math.cos(h), math.sin(h)
        ac = v * v * k
        return PlatformTruth(
            float(t),
            np.array([x, y, self.config.pad_height_m]),
            np.array([v * c, v * s, 0.0]),
            np.array([-ac * s, ac * c, 0.0]),
            wrap_angle(h),
            v * k,
        )

    def states(self, ts: FloatArray) -> PlatformStates:
        """The platform at the times ts (s), shape (N,); vectorised (about 1 us per time for the
        figure-8, less for the others)."""
        t = np.ascontiguousarray(ts, dtype=np.float64).reshape(-1)
        if self.config.speed_profile is not None:
            # the path evaluated at the integrated arc length, with the tangential acceleration
            s_m, v, a_t = self._along(t)
            return self._states_along(t, np.ascontiguousarray(s_m), v, a_t)
        v0 = self.config.speed_mps
        return self._states_along(t, v0 * t, v0, None)

    def _states_along(
        self, t: FloatArray, s_m: FloatArray, v: FloatArray | float, a_t: FloatArray | None
    ) -> PlatformStates:
        # The states at arc lengths s_m (m) driven at speeds v (m/s) with tangential accelerations a_t
        # (m/s^2; None: a constant speed); the centripetal acceleration from the path's curvature.
        g = self._eval_many(s_m, self._seg, self._geo)
        n = t.shape[0]
        c, s = np.cos(g[:, 2]), np.sin(g[:, 2])
        ac = v * v * g[:, 3]
        p = np.empty((n, 3))
        p[:, 0] = g[:, 0]
        p[:, 1] = g[:, 1]
        p[:, 2] = self.config.pad_height_m
        vel = np.zeros((n, 3))
        vel[:, 0] = v * c
        vel[:, 1] = v * s
        acc = np.zeros((n, 3))
        if a_t is None:
            acc[:, 0] = -ac * s
            acc[:, 1] = ac * c
        else:
            acc[:, 0] = a_t * c - ac * s
            acc[:, 1] = a_t * s + ac * c
        yaw = wrap_angle(g[:, 2])
        return PlatformStates(t.copy(), p, vel, acc, yaw, v * g[:, 3])

    def curvature(self, t: float) -> float:
        """Signed path curvature at time t (1/m), positive turning left."""
        s_m = float(self._along(np.array([float(t)]))[0][0])
        return float(self._eval(s_m, self._seg, self._geo)[3])

    def pad_corners_W(self, t: float) -> FloatArray:
        """Pad corners in W at time t (m), shape (4, 3), counter-clockwise from (+x, +y) of P."""
        st = self.state(t)
        return pad_corners(st.p_WP, st.yaw, self.config.pad_size_m)

    def contains(self, p_xy: FloatArray, t: float, shrink_m: float = 0.0) -> bool | np.ndarray:
        """Whether p_xy, shape (2,) or (N, 2) in W (m), is over the pad at time t, with the pad shrunk by
        ``shrink_m`` on every side."""
        st = self.state(t)
        return pad_contains(p_xy, st.p_WP, st.yaw, self.config.pad_size_m, shrink_m)
