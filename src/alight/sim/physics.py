"""The fused inner loop: the autopilot's body-rate loop and mixer, and the vehicle's dynamics, at 1 kHz.

The low level (``control.mixer.low_level``) and the dynamics (``sim.quadrotor.step``) live in separate
packages that do not know each other; this module and ``sim/world.py``, the simulator's one part that
sees the autopilot's inner loop (tests/meta/test_layers.py), run them together in one compiled loop so
that the 1 kHz part of a mission costs no Python calls. The rate loop
reads the true body rates: on a real autopilot it runs on the filtered gyro at 1 kHz or more, and the
gyro's white noise at that level is below what matters for the outer loops.

The contact of the feet with the deck and the ground is part of the dynamics
(:func:`alight.sim.quadrotor.step_contact`); whether the motors run is only ever the pipeline's command.

numba's cache of these kernels is keyed on this file's content alone: the machine code of the callees
from ``sim/quadrotor.py`` and ``control/`` is compiled into it, and a change there reaches an existing
cache only when this file changes too (or its ``__pycache__`` entries are removed). (Changed with
``quadrotor.py``'s tilted deck of a vessel at sea.)
"""

from __future__ import annotations

import numpy as np
from numba import njit

from alight.control.mixer import low_level
from alight.sim.quadrotor import IX_Q, IX_V, IX_W, N_DK, contact_wrench, deck_at, step_contact
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
    deck: FloatArray,
    deck_tau: float,
    contact_params: FloatArray,
) -> FloatArray:
    """Advance the vehicle ``n`` steps of ``dt`` with the command held; returns the new state.

    The feet touch the deck (``deck``, layout ``DK_*``, stamped ``deck_tau`` seconds before ``x``) and
    the ground through the contact model of :func:`alight.sim.quadrotor.step_contact`: nothing here
    holds the vehicle up or stops its motors; ``motors_on`` is the pipeline's command.
    """
    off = np.zeros(4)
    y = x.copy()
    for i in range(n):
        if motors_on:
            u = low_level(thrust_N, w_cmd, y[IX_W : IX_W + 3], ll_params)
        else:
            u = off
        y = step_contact(y, u, f_ext_W, v_wind_W, sim_params, dt, deck, deck_tau + i * dt, contact_params)
    return y


# Layout of the per-tick input vector of :func:`tick` (the runner updates it in place).
IN_THRUST = 0  # collective thrust command (N)
IN_W_CMD = 1  # body-rate command (rad/s), [1:4]
IN_MOTORS_ON = 4  # 1.0 while the motors run (the pipeline's command)
IN_F_EXT = 5  # external (wind) force in W (N), [5:8]
IN_V_WIND = 8  # air velocity in W (m/s), [8:11]
IN_DECK = 11  # the deck's state at the start of the batch, layout DK_* of sim.quadrotor, [11:41]
N_IN = IN_DECK + N_DK


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
    contact_params: FloatArray,
    deck_tau: float,
    counts: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """One IMU period: :func:`advance` with the inputs packed in ``inputs`` (layout ``IN_*``), then one
    IMU sample at the end of the interval. Returns the new state and the stacked (specific force in B,
    body rate in B) (6,); writes the feet on the deck and on the ground at the end into ``counts`` (2,).
    The IMU sees the mean acceleration over the interval (its anti-aliasing filter), the attitude and
    body rates at its end: an impact on the feet shows in it as it would on a real accelerometer. Few
    arguments and one compiled call per 200 Hz tick: numba's per-argument dispatch cost, not the
    arithmetic, is what this loop spends its time on."""
    deck = inputs[IN_DECK : IN_DECK + N_DK]
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
        deck,
        deck_tau,
        contact_params,
    )
    a = np.empty(3)
    span = dt * n
    for k in range(3):
        a[k] = (y[IX_V + k] - x[IX_V + k]) / span
    imu = imu_sample_kernel(a, y[IX_Q : IX_Q + 4], y[IX_W : IX_W + 3], imu_bias, imu_noise, imu_scale)
    now = np.empty(N_DK)
    deck_at(deck, deck_tau + span, now)
    f = np.empty(3)
    tq = np.empty(3)
    contact_wrench(y, now, contact_params, f, tq, counts)
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
    contact_params: FloatArray,
    m: int,
    z_low: float,
    z_high: float,
) -> tuple[FloatArray, FloatArray, FloatArray, int]:
    """Up to ``m`` consecutive :func:`tick` s with the inputs held, in one compiled call: the states
    (m, NX), IMU samples (m, 6) and feet touching (deck, ground) (m, 2) after each, and how many were
    run. The deck in ``inputs`` is stamped at ``x``'s time and carried forward through the batch. It
    stops early after a tick that leaves the body height outside (``z_low``, ``z_high``), where the
    caller must act (a first contact to judge, a lift-off). ``imu_noise`` (m, 12): one row per tick.

    Between two commands of the 100 Hz controller nothing else changes the inputs, so the runner asks
    for two 200 Hz ticks at a time: half the calls into compiled code, the same arithmetic."""
    xs = np.empty((m, x.shape[0]))
    imus = np.empty((m, 6))
    touch = np.zeros((m, 2))
    counts = np.zeros(2)
    y = x
    done = 0
    for i in range(m):
        y, imu = tick(
            y, inputs, sim_params, ll_params, imu_bias, imu_noise[i], imu_scale, dt, n, contact_params,
            i * dt * n, counts,
        )  # fmt: skip
        # by element: numba compiles a slice assignment's error message (~1 s)
        for k in range(y.shape[0]):
            xs[i, k] = y[k]
        for k in range(6):
            imus[i, k] = imu[k]
        touch[i, 0] = counts[0]
        touch[i, 1] = counts[1]
        done += 1
        if y[2] <= z_low or y[2] >= z_high:
            break
    return xs, imus, touch, done
