"""Mixer: collective thrust and body torques -> rotor thrusts, with prioritised saturation.

Inverse allocation ``f = A^-1 [T, tau_x, tau_y, tau_z]`` with ``A = Airframe.allocation`` (rotor order
front-left, rear-left, rear-right, front-right; see ``alight.airframe``). When that ``f`` leaves the rotor
limits ``[f_min, f_max]``, the demand is degraded in a fixed priority order, following Faessler,
Falanga, Scaramuzza, "Thrust mixing, saturation, and body-rate control ...", RA-L 2017, and the reference
sheet's low-level note ("keep the roll/pitch torques and give up yaw torque and then collective thrust
first"):

1. roll/pitch torque ``(tau_x, tau_y)`` is kept whole whenever some collective thrust makes it feasible
   (with yaw torque zero). Only when even that is impossible (its differential thrusts span more than
   ``f_max - f_min``) is it scaled down, direction kept, to the largest feasible fraction.
2. collective thrust ``T`` is kept when it is feasible with step 1's roll/pitch torque and zero yaw
   torque; otherwise it is clamped to the nearest feasible value (less thrust on a climb, more on a
   descent): the vehicle loses some height but keeps its attitude, which its position depends on.
3. yaw torque ``tau_z`` gets the largest fraction in [0, 1] of the demand that fits with steps 1 and 2
   fixed. It is the first to be given up because it has the least authority (drag torque, 0.016 m per N
   against an arm of 0.159 m) and a heading error costs the mission nothing until the next detection.

Decomposition: ``f = beta f_rp + t u + alpha f_yaw`` with ``u = A^-1 e_T`` (rotor thrusts per newton of
collective thrust, all positive), ``f_rp = A^-1 [0, tau_x, tau_y, 0]`` and ``f_yaw = A^-1 [0, 0, 0, tau_z]``.
Each step is a one-dimensional interval problem over the four rotor constraints, so the result is exact
(no iteration) and the mixer is a plain inverse allocation whenever nothing saturates.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from alight.airframe import DEFAULT_AIRFRAME, Airframe
from alight.control.rate import (
    LL_AINV,
    LL_F_MAX,
    LL_F_MIN,
    RateControllerGains,
    pack_low_level_params,
    rate_torque,
)
from alight.types import FloatArray

__all__ = ["PriorityMixer", "low_level", "mix"]


@njit(cache=True)
def mix(thrust_N: float, torque_B: FloatArray, params: FloatArray) -> FloatArray:
    """Rotor thrusts (N), shape (4,), for a collective thrust (N) and body torques (N m, B, shape (3,)),
    saturated in the priority order of the module docstring. ``params`` from ``pack_low_level_params``."""
    f_min = params[LL_F_MIN]
    f_max = params[LL_F_MAX]
    u = np.empty(4)
    r = np.empty(4)
    y = np.empty(4)
    for i in range(4):
        row = LL_AINV + 4 * i
        u[i] = params[row]
        r[i] = params[row + 1] * torque_B[0] + params[row + 2] * torque_B[1]
        y[i] = params[row + 3] * torque_B[2]

    # 1. Largest beta in [0, 1] for which some t gives f_min <= beta r_i + t u_i <= f_max for all i:
    #    for every pair (i, j), (f_min - beta r_i) / u_i <= (f_max - beta r_j) / u_j.
    beta = 1.0
    for i in range(4):
        for j in range(4):
            ds = r[j] / u[j] - r[i] / u[i]
            if ds > 0.0:
                beta = min(beta, (f_max / u[j] - f_min / u[i]) / ds)
    beta = max(beta, 0.0)
    if beta < 1.0:
        for i in range(4):
            r[i] *= beta

    # 2. Collective thrust: the feasible interval of t given the roll/pitch part, and the demand in it.
    lo = -np.inf
    hi = np.inf
    for i in range(4):
        lo = max(lo, (f_min - r[i]) / u[i])
        hi = min(hi, (f_max - r[i]) / u[i])
    if lo > hi:  # only by rounding, when beta < 1 closed the interval to a point
        t = 0.5 * (lo + hi)
    else:
        t = min(max(thrust_N, lo), hi)

    # 3. Yaw: the largest alpha in [0, 1] that keeps every rotor in its limits.
    f = np.empty(4)
    alpha = 1.0
    for i in range(4):
        f[i] = r[i] + t * u[i]
        if y[i] > 0.0:
            alpha = min(alpha, (f_max - f[i]) / y[i])
        elif y[i] < 0.0:
            alpha = min(alpha, (f_min - f[i]) / y[i])
    alpha = max(alpha, 0.0)
    for i in range(4):
        # the clip only removes rounding at an active limit
        f[i] = min(max(f[i] + alpha * y[i], f_min), f_max)
    return f


@njit(cache=True)
def low_level(thrust_N: float, w_cmd: FloatArray, w_meas: FloatArray, params: FloatArray) -> FloatArray:
    """Fused body-rate loop and mixer: rotor thrusts (N), shape (4,).

    Args:
        thrust_N: commanded collective thrust (N).
        w_cmd: commanded body rates (rad/s, B), shape (3,).
        w_meas: measured body rates (rad/s, B), shape (3,).
        params: ``pack_low_level_params(airframe, rate_gains)``.

    A plain numba function of arrays: call it from the simulator's numba physics loop.
    """
    return mix(thrust_N, rate_torque(w_cmd, w_meas, params), params)


class PriorityMixer:
    """Thin shell over ``mix`` for one airframe."""

    def __init__(self, airframe: Airframe = DEFAULT_AIRFRAME) -> None:
        self.airframe = airframe
        self.params = pack_low_level_params(airframe, RateControllerGains.for_airframe(airframe))

    @property
    def allocation(self) -> FloatArray:
        """[T, tau_x, tau_y, tau_z] = A @ f, shape (4, 4)."""
        return self.airframe.allocation

    def mix(self, thrust_N: float, torque_B: FloatArray) -> FloatArray:
        """Rotor thrusts (N), shape (4,), for a collective thrust (N) and body torques (N m, B)."""
        tau = np.ascontiguousarray(torque_B, dtype=np.float64)
        if tau.shape != (3,) or not np.isfinite(tau).all() or not np.isfinite(thrust_N):
            raise ValueError(f"need a finite thrust and a finite torque of shape (3,), got {thrust_N}, {tau}")
        return mix(float(thrust_N), tau, self.params)
