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
from alight.sim.quadrotor import IX_Q, IX_V, IX_W, rest_on_surface, step
from alight.sim.sensors import imu_sample_kernel
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


# Layout of the per-tick input vector of :func:`tick` (the runner updates it in place).
IN_THRUST = 0  # collective thrust command (N)
IN_W_CMD = 1  # body-rate command (rad/s), [1:4]
IN_MOTORS_ON = 4  # 1.0 while the motors run
IN_SUPPORTED = 5  # 1.0 while a surface holds the vehicle up
IN_SUPPORT_Z = 6  # that surface's height (m)
IN_SUPPORT_V = 7  # its velocity in W (m/s), [7:10]
IN_F_EXT = 10  # external (wind) force in W (N), [10:13]
IN_V_WIND = 13  # air velocity in W (m/s), [13:16]
N_IN = 16


@njit(cache=True)
def tick(
    x: FloatArray,
    inputs: FloatArray,
    sim_params: FloatArray,
    ll_params: FloatArray,
    imu_bias: FloatArray,
    imu_noise: FloatArray,
    imu_scale: FloatArray,
    dt: float,
    n: int,
    gear_height: float,
) -> tuple[FloatArray, FloatArray]:
    """One IMU period: :func:`advance` with the inputs packed in ``inputs`` (layout ``IN_*``), then one
    IMU sample at the end of the interval. Returns the new state and the stacked (specific force in B,
    body rate in B) (6,). The IMU sees the mean acceleration over the interval (its anti-aliasing filter),
    the attitude and body rates at its end. Few arguments and one compiled call per 200 Hz tick: numba's
    per-argument dispatch cost, not the arithmetic, is what this loop spends its time on."""
    y = advance(
        x,
        inputs[IN_THRUST],
        inputs[IN_W_CMD : IN_W_CMD + 3],
        inputs[IN_MOTORS_ON] > 0.5,
        inputs[IN_F_EXT : IN_F_EXT + 3],
        inputs[IN_V_WIND : IN_V_WIND + 3],
        sim_params,
        ll_params,
        dt,
        n,
        inputs[IN_SUPPORT_Z],
        inputs[IN_SUPPORT_V : IN_SUPPORT_V + 3],
        gear_height,
        inputs[IN_SUPPORTED] > 0.5,
    )
    a = np.empty(3)
    span = dt * n
    for k in range(3):
        a[k] = (y[IX_V + k] - x[IX_V + k]) / span
    imu = imu_sample_kernel(a, y[IX_Q : IX_Q + 4], y[IX_W : IX_W + 3], imu_bias, imu_noise, imu_scale)
    return y, imu


@njit(cache=True)
def tick_batch(
    x: FloatArray,
    inputs: FloatArray,
    sim_params: FloatArray,
    ll_params: FloatArray,
    imu_bias: FloatArray,
    imu_noise: FloatArray,
    imu_scale: FloatArray,
    dt: float,
    n: int,
    gear_height: float,
    m: int,
    z_low: float,
    z_high: float,
) -> tuple[FloatArray, FloatArray, int]:
    """Up to ``m`` consecutive :func:`tick` s with the inputs held, in one compiled call: the states
    (m, NX) and IMU samples (m, 6) after each, and how many were run. It stops early after a tick that
    leaves the body height outside (``z_low``, ``z_high``), where the caller must act (a touchdown to
    judge, a lift-off that releases the ground support). ``imu_noise`` (m, 12): one row per tick.

    Between two commands of the 100 Hz controller nothing else changes the inputs, so the runner asks
    for two 200 Hz ticks at a time: half the calls into compiled code, the same arithmetic."""
    xs = np.empty((m, x.shape[0]))
    imus = np.empty((m, 6))
    y = x
    done = 0
    for i in range(m):
        y, imu = tick(y, inputs, sim_params, ll_params, imu_bias, imu_noise[i], imu_scale, dt, n, gear_height)
        xs[i] = y
        imus[i] = imu
        done += 1
        if y[2] <= z_low or y[2] >= z_high:
            break
    return xs, imus, done
