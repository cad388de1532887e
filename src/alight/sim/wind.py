"""Wind: a force on the vehicle's centre of mass, and the air's velocity for the rotor-drag model.

Two models share one small interface (:class:`WindModel`): ``force_W(t, p_WB, v_WB)`` is the force (N)
to pass to the quadrotor as ``f_ext_W``, ``air_velocity_W(t)`` the wind velocity (m/s) to pass as
``v_wind_W`` (the rotor drag acts on the velocity relative to the air).

- :class:`SteadyWind`: a constant wind velocity; bluff-body drag ``F = 1/2 rho |v_rel| v_rel A`` with
  ``v_rel = v_wind - v_WB``, the dynamic-pressure law of paper 004 eq. (3) applied to the relative air
  velocity (so it also damps the vehicle's own motion in still air). ``A`` is the airframe's
  ``body_drag_area_m2``. The wind's direction may turn at a constant rate or in steps.
- :class:`DrydenWind`: the same mean wind plus Dryden turbulence (MIL-F-8785C low-altitude spectra), the
  same drag law on the turbulent air velocity.
- :class:`GustWind`: the SDU gust model of paper 004 Sec. IV-C, a force with no air velocity.
- :class:`NoWind`.

Dryden turbulence is implemented here, not taken from a library: no maintained package provides the
MIL-spec model as a component (jsbsim is a whole flight model in feet; rotorpy's ``DrydenGust`` is not
MIL-calibrated: fixed 1 m/s airspeed, no W20 law, unscaled noise; see
``/work/shared/references/dryden_turbulence.md``), and the exact discrete recursions are a few lines.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np

from alight.types import FloatArray

AIR_DENSITY_KGPM3 = 1.2
"""Air density used by paper 004 (kg/m^3)."""
WIND_AREA_M2 = 0.09
"""Area the wind pushes on in paper 004 (m^2): a UAV with an extra payload."""

_ZERO3 = np.zeros(3)
_ZERO3.setflags(write=False)


def force_from_wind_speed(
    v_mps: float, area_m2: float = WIND_AREA_M2, rho: float = AIR_DENSITY_KGPM3
) -> float:
    """Paper 004 eq. (3): F = p_d A with the dynamic pressure p_d = rho v^2 / 2 (N).

    8 m/s gives 3.456 N and 12 m/s 7.776 N with the defaults; the paper prints 3.45 N and 7.76 N
    (within 0.02 N of these: its last digits are truncated or mistyped).
    """
    return 0.5 * rho * v_mps * v_mps * area_m2


class WindModel(Protocol):
    """What the runner asks of a wind model."""

    def force_W(self, t: float, p_WB: FloatArray, v_WB: FloatArray) -> FloatArray:
        """Force on the centre of mass in W (N), shape (3,)."""
        ...

    def air_velocity_W(self, t: float) -> FloatArray:
        """Velocity of the air in W (m/s), shape (3,)."""
        ...


class NoWind:
    """Still air and no force."""

    def force_W(self, t: float, p_WB: FloatArray, v_WB: FloatArray) -> FloatArray:
        return np.zeros(3)

    def air_velocity_W(self, t: float) -> FloatArray:
        return np.zeros(3)


class WindDirection:
    """How the mean wind's direction turns: the azimuth added to the wind's own at time t (rad) is
    ``rate_rad_s * t`` plus every step ``(t_i, delta_i)`` with ``t_i <= t``. Positive is
    counter-clockwise seen from above (about +z of W)."""

    def __init__(self, rate_rad_s: float = 0.0, changes: Sequence[tuple[float, float]] = ()) -> None:
        steps = sorted((float(t), float(d)) for t, d in changes)
        if not math.isfinite(rate_rad_s) or not all(math.isfinite(t + d) for t, d in steps):
            raise ValueError("direction rate and changes must be finite")
        self.rate_rad_s = float(rate_rad_s)
        self.changes = tuple(steps)

    @property
    def constant(self) -> bool:
        return self.rate_rad_s == 0.0 and not self.changes

    def angle(self, t: float) -> float:
        """Azimuth turned by time ``t`` (rad)."""
        return self.rate_rad_s * t + sum(d for ti, d in self.changes if ti <= t)

    def rotate(self, t: float, v_W: FloatArray) -> FloatArray:
        """``v_W`` turned about +z by :meth:`angle` (the vertical part unchanged), shape (3,)."""
        a = self.angle(t)
        c, s = math.cos(a), math.sin(a)
        return np.array([c * v_W[0] - s * v_W[1], s * v_W[0] + c * v_W[1], v_W[2]])


def _wind_vector(v_wind_W: FloatArray | Sequence[float]) -> FloatArray:
    v = np.array(v_wind_W, dtype=np.float64).reshape(-1)
    if v.shape != (3,) or not np.isfinite(v).all():
        raise ValueError(f"v_wind_W must be 3 finite numbers, got {v_wind_W}")
    v.setflags(write=False)
    return v


class SteadyWind:
    """A steady wind, whose direction may turn; the drag force follows the air velocity relative to the
    vehicle."""

    def __init__(
        self,
        v_wind_W: FloatArray | Sequence[float],
        *,
        area_m2: float = WIND_AREA_M2,
        rho: float = AIR_DENSITY_KGPM3,
        direction: WindDirection | None = None,
    ) -> None:
        """``v_wind_W``: the air's velocity in W at t = 0 (m/s), shape (3,); ``area_m2``: area the air
        pushes on (m^2), the airframe's ``body_drag_area_m2``; ``rho``: air density (kg/m^3);
        ``direction``: how the wind turns (None: it does not)."""
        self.v_wind_W = _wind_vector(v_wind_W)
        if not (area_m2 >= 0.0 and rho > 0.0):
            raise ValueError("area_m2 must be >= 0 and rho > 0")
        self._k = 0.5 * rho * area_m2
        self.direction = direction if direction is not None and not direction.constant else None

    def velocity_W(self, t: float) -> FloatArray:
        """The wind's velocity at ``t`` (m/s), shape (3,); the constant array when it does not turn."""
        return self.v_wind_W if self.direction is None else self.direction.rotate(t, self.v_wind_W)

    def force_W(self, t: float, p_WB: FloatArray, v_WB: FloatArray) -> FloatArray:
        """``1/2 rho A |v_rel| v_rel`` with ``v_rel = v_wind - v_WB`` (N), shape (3,)."""
        v_rel = self.velocity_W(t) - v_WB
        return self._k * math.sqrt(float(v_rel @ v_rel)) * v_rel

    def air_velocity_W(self, t: float) -> FloatArray:
        return np.array(self.velocity_W(t), dtype=np.float64)


# -- Dryden turbulence ---------------------------------------------------------------------------------

KNOT_MPS = 1852.0 / 3600.0
TURBULENCE_W20_MPS = {"light": 15.0 * KNOT_MPS, "moderate": 30.0 * KNOT_MPS, "severe": 45.0 * KNOT_MPS}
"""Wind speed at 20 ft (6.1 m) that sets the low-altitude intensity, MIL-F-8785C: light 15 kt,
moderate 30 kt, severe 45 kt (m/s)."""
DRYDEN_MIN_HEIGHT_M = 3.05
"""Lowest height the low-altitude law is evaluated at (10 ft, as JSBSim clamps it): below it L_w = h
would shrink to zero (m)."""
DRYDEN_MAX_HEIGHT_M = 304.8
"""Top of the low-altitude region (1000 ft), where the law becomes isotropic (m)."""
_SQRT3 = math.sqrt(3.0)


def dryden_low_altitude(height_m: float, w20_mps: float) -> tuple[float, float, float, float, float, float]:
    """MIL-F-8785C low-altitude parameters at ``height_m`` (clamped to [3.05, 304.8] m) for the wind
    ``w20_mps`` at 20 ft: ``(sigma_u, sigma_v, sigma_w, L_u, L_v, L_w)`` in m/s and m.

    k = 0.177 + 0.0027 h (h in m; 0.000823 per ft), L_w = h, L_u = L_v = h / k^1.2, sigma_w = 0.1 W20,
    sigma_u = sigma_v = sigma_w / k^0.4 (8785C lengths: the v and w filters below use T = L / V)."""
    h = min(max(float(height_m), DRYDEN_MIN_HEIGHT_M), DRYDEN_MAX_HEIGHT_M)
    k = 0.177 + 0.0027 * h
    length_uv = h / k**1.2
    sigma_w = 0.1 * float(w20_mps)
    sigma_uv = sigma_w / k**0.4
    return sigma_uv, sigma_uv, sigma_w, length_uv, length_uv, h


def dryden_transfer_function(
    component: str, sigma_mps: float, length_m: float, airspeed_mps: float
) -> tuple[list[float], list[float]]:
    """Numerator and denominator (highest power of s first) of the shaping filter of ``component``
    (``u``, ``v`` or ``w``), for unit-intensity white noise (one-sided PSD 1 per rad/s, i.e. two-sided
    intensity pi), so that ``|H(j omega)|^2`` is the temporal one-sided PSD per rad/s, T = L / V:

        H_u(s) = sigma sqrt(2 T / pi) / (1 + T s)
        H_v(s) = H_w(s) = sigma sqrt(T / pi) (1 + sqrt(3) T s) / (1 + T s)^2   (MIL-F-8785C)
    """
    tc = length_m / airspeed_mps
    if component == "u":
        return [sigma_mps * math.sqrt(2.0 * tc / math.pi)], [tc, 1.0]
    if component in ("v", "w"):
        g = sigma_mps * math.sqrt(tc / math.pi)
        return [g * _SQRT3 * tc, g], [tc * tc, 2.0 * tc, 1.0]
    raise ValueError(f"component must be u, v or w, got {component!r}")


class DrydenTurbulence:
    """The three Dryden shaping filters, discretised exactly, as unit-sigma states (the caller scales
    them by sigma, which may change with height without disturbing the statistics).

    u: the sampled Ornstein-Uhlenbeck process ``u+ = phi u + sqrt(1 - phi^2) eta``, phi = exp(-dt/T_u),
    exact at any dt. v and w: the zero-order-hold recursion of the state form ``a' = (K n - a) / T``,
    ``b' = (a - b) / T``, output ``sqrt(3) a + (1 - sqrt(3)) b``, K = sqrt(T / pi), with the held noise
    ``n ~ N(0, pi / dt)`` (the printed filters need white noise of intensity pi). The stationary
    covariance of (a, b) is [[1/2, 1/4], [1/4, 1/4]] whatever T is, so T (i.e. the airspeed and the
    height) may change every step: the coefficients are recomputed and the states kept.
    """

    def __init__(self, rng: np.random.Generator) -> None:
        self._rng = rng
        self.u = float(rng.standard_normal())
        # Initial (a, b) from the stationary covariance: a = z1 / sqrt(2), b = a / 2 + z2 / 2.
        z = rng.standard_normal(4)
        self.a_v, self.b_v = z[0] / math.sqrt(2.0), 0.5 * z[0] / math.sqrt(2.0) + 0.5 * z[1]
        self.a_w, self.b_w = z[2] / math.sqrt(2.0), 0.5 * z[2] / math.sqrt(2.0) + 0.5 * z[3]

    def output(self) -> tuple[float, float, float]:
        """Unit-sigma (u, v, w) of the current step."""
        v = _SQRT3 * self.a_v + (1.0 - _SQRT3) * self.b_v
        w = _SQRT3 * self.a_w + (1.0 - _SQRT3) * self.b_w
        return self.u, v, w

    def step(self, dt: float, tc_u: float, tc_v: float, tc_w: float) -> None:
        """Advance by ``dt`` (s) with the filters' time constants ``T = L / V`` (s)."""
        eta, n_v, n_w = self._rng.standard_normal(3)
        phi = math.exp(-dt / tc_u)
        self.u = phi * self.u + math.sqrt(1.0 - phi * phi) * eta
        self.a_v, self.b_v = _zoh_step(self.a_v, self.b_v, dt, tc_v, n_v * math.sqrt(math.pi / dt))
        self.a_w, self.b_w = _zoh_step(self.a_w, self.b_w, dt, tc_w, n_w * math.sqrt(math.pi / dt))


def _zoh_step(a: float, b: float, dt: float, tc: float, n: float) -> tuple[float, float]:
    """One zero-order-hold step of the unit-sigma second-order Dryden filter (class docstring)."""
    phi = math.exp(-dt / tc)
    k = math.sqrt(tc / math.pi)
    r = dt / tc
    return phi * a + (1.0 - phi) * k * n, phi * b + r * phi * a + (1.0 - phi * (1.0 + r)) * k * n


class DrydenWind:
    """A steady mean wind (whose direction may turn) plus Dryden turbulence; bluff-body drag on the
    turbulent air velocity relative to the vehicle, as :class:`SteadyWind`.

    Frozen turbulence (Taylor's hypothesis): the field is carried by the mean wind and the vehicle moves
    through it at ``V = max(|v_WB - w_mean|, min_airspeed_mps)``; the filters' time constants are L / V.
    In hover that is the mean wind's speed; the floor keeps the filters finite in still air (at V = 0 a
    frozen field would not change at all). The intensities and lengths follow the low-altitude law at the
    vehicle's height. The components are along the mean wind's horizontal direction (u), across it (v,
    to its left) and vertical (w, up); with no mean wind, u is along the turned x axis of W.

    The filters advance on a fixed grid of ``dt`` (the runner's wind update period), with V and the
    height of the query that reaches each grid point, so the sequence depends only on the seed and the
    flight. Draws come from a child generator split off ``rng`` at construction.
    """

    def __init__(
        self,
        rng: np.random.Generator,
        v_mean_W: FloatArray | Sequence[float],
        w20_mps: float,
        *,
        dt: float = 0.01,
        min_airspeed_mps: float = 1.0,
        area_m2: float = WIND_AREA_M2,
        rho: float = AIR_DENSITY_KGPM3,
        direction: WindDirection | None = None,
    ) -> None:
        """``v_mean_W``: the mean wind at t = 0 (m/s), shape (3,); ``w20_mps``: wind speed at 20 ft that
        sets the intensity (:data:`TURBULENCE_W20_MPS`); ``dt``: update period (s); ``min_airspeed_mps``:
        floor of the Taylor airspeed V (m/s); ``area_m2``, ``rho``: as :class:`SteadyWind`."""
        if not (dt > 0.0 and min_airspeed_mps > 0.0 and w20_mps >= 0.0):
            raise ValueError("dt and min_airspeed_mps must be > 0 and w20_mps >= 0")
        self.mean = SteadyWind(v_mean_W, area_m2=area_m2, rho=rho, direction=direction)
        self.w20_mps = float(w20_mps)
        self.dt = float(dt)
        self.min_airspeed_mps = float(min_airspeed_mps)
        self._k = 0.5 * rho * area_m2
        self.filters = DrydenTurbulence(np.random.default_rng(rng.integers(0, 2**63 - 1)))
        self._n = 0  # grid points reached
        self._v_air = self._compose(0.0, DRYDEN_MIN_HEIGHT_M)

    def _compose(self, t: float, height_m: float) -> FloatArray:
        su, sv, sw, _, _, _ = dryden_low_altitude(height_m, self.w20_mps)
        u, v, w = self.filters.output()
        mean = self.mean.velocity_W(t)
        speed = math.hypot(mean[0], mean[1])
        if speed > 1e-9:
            cx, cy = mean[0] / speed, mean[1] / speed
        else:
            a = 0.0 if self.mean.direction is None else self.mean.direction.angle(t)
            cx, cy = math.cos(a), math.sin(a)
        gu, gv = su * u, sv * v
        return np.array([mean[0] + cx * gu - cy * gv, mean[1] + cy * gu + cx * gv, mean[2] + sw * w])

    def _advance(self, t: float, p_WB: FloatArray, v_WB: FloatArray) -> None:
        target = int(math.floor(t / self.dt + 1e-9))
        if target <= self._n:
            return
        height = float(p_WB[2])
        mean = self.mean.velocity_W(t)
        rel = np.asarray(v_WB, dtype=np.float64) - mean
        airspeed = max(math.sqrt(float(rel @ rel)), self.min_airspeed_mps)
        _, _, _, lu, lv, lw = dryden_low_altitude(height, self.w20_mps)
        while self._n < target:
            self.filters.step(self.dt, lu / airspeed, lv / airspeed, lw / airspeed)
            self._n += 1
        self._v_air = self._compose(t, height)

    def force_W(self, t: float, p_WB: FloatArray, v_WB: FloatArray) -> FloatArray:
        """``1/2 rho A |v_rel| v_rel`` with ``v_rel = v_air - v_WB`` (N), shape (3,); advances the
        turbulence to ``t`` with the vehicle's height and airspeed."""
        self._advance(t, p_WB, v_WB)
        v_rel = self._v_air - v_WB
        return self._k * math.sqrt(float(v_rel @ v_rel)) * v_rel

    def air_velocity_W(self, t: float) -> FloatArray:
        """The air's velocity (mean + turbulence) at the last :meth:`force_W` query (m/s), shape (3,)."""
        return self._v_air.copy()


class GustWind:
    """The wind-gust force of paper 004 Sec. IV-C, implemented as written there.

    Every ``cycle_s`` (5.5 s) a factor ``noise ~ U(0.9, 1.2)`` is drawn, and the force is::

        force_x = -0.8 * power * noise,   force_y = -0.2 * power * noise,   force_z = 0

    The direction (0.8, 0.2) is used as written, *not normalised* (its norm is 0.825), so the horizontal
    force is 0.825 power noise. The paper's axes are Gazebo's world (x, y), which is ENU like W, so no
    axis change. ``power`` scales with the vehicle's altitude ``z = p_WB[2]`` (above the take-off ground)::

        z > 6 m:        power = power_init
        3 m < z <= 6 m: power = power_init * z / 6
        z <= 3 m:       power = 0.5 N

    The last rule is discontinuous at 3 m (power_init / 2 = 3.5 N just above, 0.5 N at and below with
    the default 7 N); it is kept as the paper states it. The noise factor multiplies every branch. The
    model is a force on the centre of mass: :meth:`air_velocity_W` is zero.

    The draws come from a child generator split off ``rng`` at construction (one draw from it), taken
    in order of cycles, so a force only depends on its cycle, whatever order the queries come in.
    """

    CYCLE_S = 5.5
    NOISE_LOW = 0.9
    NOISE_HIGH = 1.2
    DIRECTION = (0.8, 0.2)
    FULL_ALTITUDE_M = 6.0
    LOW_ALTITUDE_M = 3.0
    LOW_POWER_N = 0.5

    def __init__(
        self,
        rng: np.random.Generator,
        *,
        power_init_N: float = 7.0,
        cycle_s: float = CYCLE_S,
        noise_low: float = NOISE_LOW,
        noise_high: float = NOISE_HIGH,
        direction_xy: tuple[float, float] = DIRECTION,
        t0: float = 0.0,
    ) -> None:
        """``power_init_N``: force scale (N), 7.0 in the paper (3.45 N and 7.76 N are the 8 and 12 m/s
        equivalents, see :func:`force_from_wind_speed`); ``cycle_s``: update period (s); ``noise_low``,
        ``noise_high``: bounds of the uniform factor; ``direction_xy``: (x_norm, y_norm), applied with a
        minus sign; ``t0``: start of the first cycle (s)."""
        if not (cycle_s > 0.0 and power_init_N >= 0.0 and noise_high >= noise_low):
            raise ValueError("cycle_s must be > 0, power_init_N >= 0 and noise_high >= noise_low")
        self.power_init_N = float(power_init_N)
        self.cycle_s = float(cycle_s)
        self.noise_low = float(noise_low)
        self.noise_high = float(noise_high)
        self.direction_xy = (float(direction_xy[0]), float(direction_xy[1]))
        self.t0 = float(t0)
        self._rng = np.random.default_rng(rng.integers(0, 2**63 - 1))
        self._noise = np.empty(0)

    @classmethod
    def from_wind_speed(
        cls,
        rng: np.random.Generator,
        wind_speed_mps: float,
        *,
        area_m2: float = WIND_AREA_M2,
        rho: float = AIR_DENSITY_KGPM3,
        **kwargs: Any,
    ) -> GustWind:
        """A gust model whose ``power_init`` is the eq. (3) force of a wind of ``wind_speed_mps``."""
        return cls(rng, power_init_N=force_from_wind_speed(wind_speed_mps, area_m2, rho), **kwargs)

    def noise(self, cycle: int) -> float:
        """The uniform factor of cycle number ``cycle`` (>= 0)."""
        if cycle < 0:
            raise ValueError(f"cycle must be >= 0, got {cycle}")
        if cycle >= self._noise.shape[0]:
            n_new = max(64, cycle + 1 - self._noise.shape[0])
            draws = self._rng.uniform(self.noise_low, self.noise_high, n_new)
            self._noise = np.concatenate([self._noise, draws])
        return float(self._noise[cycle])

    def power(self, altitude_m: float) -> float:
        """Force scale at an altitude (N), before the noise factor."""
        if altitude_m <= self.LOW_ALTITUDE_M:
            return self.LOW_POWER_N
        if altitude_m <= self.FULL_ALTITUDE_M:
            return self.power_init_N * altitude_m / self.FULL_ALTITUDE_M
        return self.power_init_N

    def force_W(self, t: float, p_WB: FloatArray, v_WB: FloatArray) -> FloatArray:
        """The gust force in W (N), shape (3,); depends on t (cycle) and p_WB[2] (altitude) only."""
        cycle = max(0, int(math.floor((t - self.t0) / self.cycle_s)))
        f = self.power(float(p_WB[2])) * self.noise(cycle)
        return np.array([-self.direction_xy[0] * f, -self.direction_xy[1] * f, 0.0])

    def air_velocity_W(self, t: float) -> FloatArray:
        return np.zeros(3)
