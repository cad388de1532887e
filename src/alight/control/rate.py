"""Body-rate loop: commanded and measured body rates -> body torques.

Faessler, Falanga, Scaramuzza, RA-L 2017 (the low level of paper 000 Sec. II-E):
``tau_B = J K_w (w_cmd - w) + w x (J w)``, a proportional loop on the rates shaped by the inertia (so the
gain is a bandwidth in 1/s, the same on any vehicle) plus the gyroscopic term, which the rigid body
``J dw/dt = tau - w x (J w)`` would otherwise feel as a disturbance.

No derivative term: it would need the derivative of the measured rate, i.e. a differentiated gyro
(noise) and state in the kernel, while with the default airframe the P loop already has a phase margin of
~60 deg against the motors' first-order lag (crossover ~20 rad/s, motor time constant <= 25 ms).

The low-level parameters of the rate loop and the mixer are packed into ONE float64 vector
(``pack_low_level_params``), so that the fused kernel ``alight.control.mixer.low_level`` can be called
from another numba function (the simulator's 1 kHz physics loop) with plain arrays.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from alight.airframe import DEFAULT_AIRFRAME, Airframe
from alight.types import FloatArray

__all__ = [
    "BodyRateController",
    "RateControllerGains",
    "pack_low_level_params",
    "rate_torque",
]

# Layout of the low-level parameter vector (float64), shared by rate_torque, mix and low_level.
LL_J = 0  # 3: principal moments of inertia (kg m^2)
LL_KW = 3  # 3: body-rate gains K_w (1/s)
LL_AINV = 6  # 16: inverse allocation A^-1, row-major: f = A^-1 [T, tau_x, tau_y, tau_z]
LL_F_MIN = 22  # 1: lowest rotor thrust (N)
LL_F_MAX = 23  # 1: largest rotor thrust (N)
LL_N_PARAMS = 24


@dataclass(frozen=True, kw_only=True)
class RateControllerGains:
    """Gains of the body-rate loop. The defaults give roll/pitch rate bandwidths of 25 rad/s (about 3x
    the 8.3 rad/s of the default tilt loop) and 10 rad/s on yaw, whose torque per unit of differential
    thrust is ~10x smaller (0.016 m against 0.159 m), so that yaw saturates the motors less often."""

    k_rate: tuple[float, float, float] = (25.0, 25.0, 10.0)
    """Proportional body-rate gains K_w about x_B, y_B, z_B (1/s)."""

    def __post_init__(self) -> None:
        k = tuple(float(v) for v in np.broadcast_to(np.asarray(self.k_rate, dtype=np.float64), (3,)))
        if not all(math.isfinite(v) and v > 0 for v in k):
            raise ValueError(f"k_rate must be positive and finite (positive-definite K_w), got {k}")
        object.__setattr__(self, "k_rate", k)

    @classmethod
    def for_airframe(cls, airframe: Airframe) -> RateControllerGains:
        """The defaults, slowed for an airframe whose motors are too slow for them: a proportional rate
        loop through a first-order motor of time constant tau (the mean of ``motor_tau_up`` and
        ``motor_tau_down``) has the damping 1 / (2 sqrt(K tau)); the roll/pitch gain is capped at
        ``1 / (4 zeta^2 tau)`` for zeta = 0.6 (the yaw gain scaled alike). The F450's motors (tau 19 ms)
        allow 37 1/s, so it keeps 25; the Matrice 100's (38 ms, assumed) get 18.5: with 25 its loop
        rang (zeta 0.45), saturated the motors in fast manoeuvres, and the mixer's torque priority
        raised the collective until the vehicle climbed hundreds of metres (alight_speed, 14 m/s)."""
        k_max = rate_gain_limit(airframe)
        default = cls()
        scale = min(1.0, k_max / default.k_rate[0])
        return cls(k_rate=tuple(k * scale for k in default.k_rate))  # type: ignore[arg-type]


def tilt_time_constant_s(airframe: Airframe) -> float:
    """Time constant of the tilt feedback (HighLevelGains.tau_tilt) for the airframe: the default 0.12 s,
    or three times the rate loop's time constant when the motors slow that loop (a cascade keeps its
    outer loop about 3x slower than its inner one, as the defaults do: 8.3 against 25 1/s)."""
    k = RateControllerGains.for_airframe(airframe).k_rate[0]
    return max(0.12, 3.0 / k)


RATE_LOOP_DAMPING = 0.6
"""Least damping of the roll/pitch rate loop through the motors' lag (RateControllerGains.for_airframe)."""


def rate_gain_limit(airframe: Airframe) -> float:
    """Largest roll/pitch rate gain (1/s) that keeps the rate loop's damping at RATE_LOOP_DAMPING through
    the airframe's motor lag: 1 / (4 zeta^2 tau), tau the mean of the spin-up and spin-down constants."""
    tau = 0.5 * (airframe.motor_tau_up + airframe.motor_tau_down)
    return 1.0 / (4.0 * RATE_LOOP_DAMPING**2 * tau)


def pack_low_level_params(
    airframe: Airframe = DEFAULT_AIRFRAME, rate_gains: RateControllerGains | None = None
) -> FloatArray:
    """Parameter vector of ``rate_torque``, ``mix`` and ``low_level``, shape (LL_N_PARAMS,).

    Raises ValueError when the allocation is singular or a unit of collective thrust does not raise every
    rotor's thrust (the mixer's priority scheme needs both).
    """
    gains = rate_gains if rate_gains is not None else RateControllerGains.for_airframe(airframe)
    A = airframe.allocation
    if abs(np.linalg.det(A)) < 1e-12:
        raise ValueError("the airframe's allocation matrix is singular")
    A_inv = np.linalg.inv(A)
    if not (A_inv[:, 0] > 0).all():
        raise ValueError(f"collective thrust must map to positive rotor thrusts, got {A_inv[:, 0]}")
    f_min = airframe.motor_thrust_min_N
    f_max = airframe.motor_thrust_max_N
    if not (0.0 <= f_min < f_max):
        raise ValueError(f"need 0 <= motor_thrust_min_N < motor_thrust_max_N, got {f_min}, {f_max}")
    p = np.zeros(LL_N_PARAMS)
    p[LL_J : LL_J + 3] = airframe.inertia_diag
    p[LL_KW : LL_KW + 3] = gains.k_rate
    p[LL_AINV : LL_AINV + 16] = A_inv.ravel()
    p[LL_F_MIN] = f_min
    p[LL_F_MAX] = f_max
    return p


@njit(cache=True)
def rate_torque(w_cmd: FloatArray, w: FloatArray, params: FloatArray) -> FloatArray:
    """Body torque (N m, B, shape (3,)) = J K_w (w_cmd - w) + w x (J w).

    Args:
        w_cmd: commanded body rates (rad/s, B), shape (3,).
        w: measured body rates (rad/s, B), shape (3,).
        params: ``pack_low_level_params`` vector.
    """
    J0, J1, J2 = params[LL_J], params[LL_J + 1], params[LL_J + 2]
    h0, h1, h2 = J0 * w[0], J1 * w[1], J2 * w[2]
    tau = np.empty(3)
    tau[0] = J0 * params[LL_KW] * (w_cmd[0] - w[0]) + (w[1] * h2 - w[2] * h1)
    tau[1] = J1 * params[LL_KW + 1] * (w_cmd[1] - w[1]) + (w[2] * h0 - w[0] * h2)
    tau[2] = J2 * params[LL_KW + 2] * (w_cmd[2] - w[2]) + (w[0] * h1 - w[1] * h0)
    return tau


class BodyRateController:
    """Thin shell over ``rate_torque``."""

    def __init__(
        self, airframe: Airframe = DEFAULT_AIRFRAME, gains: RateControllerGains | None = None
    ) -> None:
        self.airframe = airframe
        self.gains = gains if gains is not None else RateControllerGains.for_airframe(airframe)
        self.params = pack_low_level_params(airframe, self.gains)

    def torque(self, w_cmd: FloatArray, w: FloatArray) -> FloatArray:
        """Body torque (N m, B), shape (3,), for commanded and measured rates (rad/s, B), shape (3,)."""
        wc = np.ascontiguousarray(w_cmd, dtype=np.float64)
        wm = np.ascontiguousarray(w, dtype=np.float64)
        if wc.shape != (3,) or wm.shape != (3,):
            raise ValueError(f"w_cmd and w must have shape (3,), got {wc.shape}, {wm.shape}")
        return rate_torque(wc, wm, self.params)
