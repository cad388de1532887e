"""Wind: a force on the vehicle's centre of mass, and the air's velocity for the rotor-drag model.

Two models share one small interface (:class:`WindModel`): ``force_W(t, p_WB, v_WB)`` is the force (N)
to pass to the quadrotor as ``f_ext_W``, ``air_velocity_W(t)`` the wind velocity (m/s) to pass as
``v_wind_W`` (the rotor drag acts on the velocity relative to the air).

- :class:`SteadyWind`: a constant wind velocity; bluff-body drag ``F = 1/2 rho |v_rel| v_rel A`` with
  ``v_rel = v_wind - v_WB``, the dynamic-pressure law of paper 004 eq. (3) applied to the relative air
  velocity (so it also damps the vehicle's own motion in still air).
- :class:`GustWind`: the SDU gust model of paper 004 Sec. IV-C, a force with no air velocity.
- :class:`NoWind`.
"""

from __future__ import annotations

import math
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


class SteadyWind:
    """A constant wind; the drag force follows the air velocity relative to the vehicle."""

    def __init__(
        self, v_wind_W: FloatArray, *, area_m2: float = WIND_AREA_M2, rho: float = AIR_DENSITY_KGPM3
    ) -> None:
        """``v_wind_W``: the air's velocity in W (m/s), shape (3,); ``area_m2``: area the air pushes on
        (m^2); ``rho``: air density (kg/m^3)."""
        v = np.array(v_wind_W, dtype=np.float64).reshape(-1)
        if v.shape != (3,) or not np.isfinite(v).all():
            raise ValueError(f"v_wind_W must be 3 finite numbers, got {v_wind_W}")
        if not (area_m2 >= 0.0 and rho > 0.0):
            raise ValueError("area_m2 must be >= 0 and rho > 0")
        v.setflags(write=False)
        self.v_wind_W = v
        self._k = 0.5 * rho * area_m2

    def force_W(self, t: float, p_WB: FloatArray, v_WB: FloatArray) -> FloatArray:
        """``1/2 rho A |v_rel| v_rel`` with ``v_rel = v_wind - v_WB`` (N), shape (3,)."""
        v_rel = self.v_wind_W - v_WB
        return self._k * math.sqrt(float(v_rel @ v_rel)) * v_rel

    def air_velocity_W(self, t: float) -> FloatArray:
        return self.v_wind_W.copy()


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
