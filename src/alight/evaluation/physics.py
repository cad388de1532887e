"""The fused inner loop: the autopilot's body-rate loop and mixer, and the vehicle's dynamics, at 1 kHz.

The low level (``control.mixer.low_level``) and the dynamics (``sim.quadrotor.step``) live in separate
packages that must not know each other; this module, on the evaluation side that sees both, runs them
together in one compiled loop so that the 1 kHz part of a mission costs no Python calls. The rate loop
reads the true body rates: on a real autopilot it runs on the filtered gyro at 1 kHz or more, and the
gyro's white noise at that level is below what matters for the outer loops.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from alight.control.mixer import low_level
from alight.sim.quadrotor import IX_W, rest_on_surface, step
from alight.types import FloatArray


@njit(cache=True)
def advance(
    x: FloatArray,
    thrust_N: float,
    w_cmd: FloatArray,
    motors_on: bool,
    f_ext_W: FloatArray,
    v_wind_W: FloatArray,
    sim_params: FloatArray,
    ll_params: FloatArray,
    dt: float,
    n: int,
    support_z: float,
    support_v_W: FloatArray,
    gear_height: float,
    supported: bool,
) -> FloatArray:
    """Advance the vehicle ``n`` steps of ``dt`` with the command held; returns the new state.

    ``supported``: the vehicle stands on a surface at height ``support_z`` moving at ``support_v_W``
    (the ground before take-off, the pad after landing) that holds it up while its thrust is below its
    weight.
    """
    off = np.zeros(4)
    y = x.copy()
    for _ in range(n):
        if motors_on:
            u = low_level(thrust_N, w_cmd, y[IX_W : IX_W + 3], ll_params)
        else:
            u = off
        y = step(y, u, f_ext_W, v_wind_W, sim_params, dt)
        if supported:
            y = rest_on_surface(y, support_z, support_v_W, gear_height)
    return y
