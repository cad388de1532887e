"""Rigid-body quadrotor with four first-order rotors, rotor drag and an external force.

The equations (W is ENU z-up, B is FLU, ``R = R_WB``)::

    p' = v
    m v' = R (0, 0, sum f_i) + m g_W - m R diag(d) R^T (v - v_wind_W) + f_ext_W
    q' = 1/2 q (x) (w_WB_B, 0)                              (Hamilton product, q = (x, y, z, w))
    J w' = tau - w x J w                                    (gyroscopic term of the rigid body)
    f_i' = (clip(u_i) - f_i) / tau_up   if clip(u_i) >= f_i else  (clip(u_i) - f_i) / tau_down

with ``tau = (sum y_i f_i, -sum x_i f_i, -sum spin_i c_tau f_i)`` (the rows of
:attr:`alight.airframe.Airframe.allocation`), ``clip`` the saturation to ``[f_min, f_max]`` per rotor.
The rotor drag is the linear, mass-normalised model of Faessler, Franchi and Scaramuzza (RA-L 2018,
eq. 2): proportional to the sum of the rotor speeds, here ``d`` (the airframe's, at hover) times the mean
of ``sqrt(f_i / f_hover)`` (a rotor's speed goes as the root of its thrust), so stopped rotors drag
nothing (a vehicle standing on a deck in the wind with its motors off); ``v_wind_W`` is the air's
velocity (zero when the wind is modelled as a force, as the SDU gust model does).

Everything numeric is a ``@njit`` function of plain arrays so that the evaluation runner can fuse
:func:`step` with a rate controller in one compiled loop. The state and parameter layouts are module
constants (``IX_*``, ``PAR_*``); :class:`QuadrotorSim` is a thin shell over them.

Integrator: the motors are integrated exactly (the command is held over a step, so each rotor follows
an exponential toward it; the approach is monotone, so the up/down time constant never switches inside a
step) and the rigid body by classical RK4 with the exact rotor thrusts at the RK4 stage times. Exact
motors remove the stiffness limit of ``dt`` against the 12.5 ms time constant; RK4 keeps the rigid body's
invariants (energy, angular momentum) to ~1e-12 per second at 1 ms, which a semi-implicit Euler step
would not (it drifts at O(dt)). The quaternion is renormalised after each step.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from alight.airframe import DEFAULT_AIRFRAME, Airframe
from alight.numerics.rotation import quat_to_R_scaled, rotmat_entries
from alight.types import GRAVITY_MPS2, FloatArray, quat_to_rotmat

# --------------------------------------------------------------------------------------------------
# State layout, shape (NX,)
# --------------------------------------------------------------------------------------------------
IX_P = 0
"""p_WB (m), x[0:3]."""
IX_V = 3
"""v_WB (m/s), x[3:6]."""
IX_Q = 6
"""q_WB (x, y, z, w), x[6:10]."""
IX_W = 10
"""w_WB_B (rad/s), x[10:13]."""
IX_F = 13
"""Rotor thrusts (N) in the airframe's rotor order (FL, RL, RR, FR), x[13:17]."""
NX = 17

SL_P = slice(IX_P, IX_P + 3)
SL_V = slice(IX_V, IX_V + 3)
SL_Q = slice(IX_Q, IX_Q + 4)
SL_W = slice(IX_W, IX_W + 3)
SL_F = slice(IX_F, IX_F + 4)

# --------------------------------------------------------------------------------------------------
# Parameter layout, shape (NPAR,), built by pack_params
# --------------------------------------------------------------------------------------------------
PAR_MASS = 0
"""Mass (kg)."""
PAR_J = 1
"""Principal inertia Jxx, Jyy, Jzz (kg m^2), params[1:4]."""
PAR_TAU_UP = 4
"""Motor time constant when the thrust rises (s)."""
PAR_TAU_DOWN = 5
"""Motor time constant when the thrust falls (s)."""
PAR_F_MIN = 6
"""Lowest rotor thrust (N)."""
PAR_F_MAX = 7
"""Highest rotor thrust (N)."""
PAR_C_TAU = 8
"""Rotor drag torque per unit thrust (m)."""
PAR_DRAG = 9
"""Mass-normalised rotor drag d_x, d_y, d_z along B (1/s), params[9:12]."""
PAR_G = 12
"""Gravity magnitude (m/s^2)."""
PAR_ROTOR_X = 13
"""Rotor x positions in B (m), params[13:17]."""
PAR_ROTOR_Y = 17
"""Rotor y positions in B (m), params[17:21]."""
PAR_SPIN = 21
"""Rotor spin, +1 counter-clockwise seen from above, params[21:25]."""
NPAR = 25


def pack_params(airframe: Airframe = DEFAULT_AIRFRAME) -> FloatArray:
    """The airframe as the flat float64 array the kernels read, shape (NPAR,); see ``PAR_*``."""
    par = np.zeros(NPAR)
    par[PAR_MASS] = airframe.mass
    par[PAR_J : PAR_J + 3] = airframe.inertia_diag
    par[PAR_TAU_UP] = airframe.motor_tau_up
    par[PAR_TAU_DOWN] = airframe.motor_tau_down
    par[PAR_F_MIN] = airframe.motor_thrust_min_N
    par[PAR_F_MAX] = airframe.motor_thrust_max_N
    par[PAR_C_TAU] = airframe.torque_coefficient
    par[PAR_DRAG : PAR_DRAG + 3] = airframe.rotor_drag
    par[PAR_G] = GRAVITY_MPS2
    par[PAR_ROTOR_X : PAR_ROTOR_X + 4] = airframe.rotor_positions_B[:, 0]
    par[PAR_ROTOR_Y : PAR_ROTOR_Y + 4] = airframe.rotor_positions_B[:, 1]
    par[PAR_SPIN : PAR_SPIN + 4] = airframe.rotor_spin
    if not (airframe.motor_tau_up > 0 and airframe.motor_tau_down > 0):
        raise ValueError("motor time constants must be positive")
    return par


# --------------------------------------------------------------------------------------------------
# Kernels
# --------------------------------------------------------------------------------------------------


@njit(cache=True)
def _rigid_body_deriv(
    y: FloatArray,
    f: FloatArray,
    f_ext_W: FloatArray,
    v_wind_W: FloatArray,
    par: FloatArray,
    out: FloatArray,
) -> None:
    """Derivative of the rigid-body part y = x[0:13] for rotor thrusts f (4,), written into out (13,)."""
    m = par[PAR_MASS]
    qx, qy, qz, qw = y[6], y[7], y[8], y[9]
    # R_WB of a unit quaternion; RK4 stages are off the unit sphere by O(dt^5), normalise anyway
    n2 = qx * qx + qy * qy + qz * qz + qw * qw
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = rotmat_entries(qx, qy, qz, qw, 2.0 / n2)

    thrust = f[0] + f[1] + f[2] + f[3]
    tau_x = 0.0
    tau_y = 0.0
    tau_z = 0.0
    c_tau = par[PAR_C_TAU]
    for i in range(4):
        tau_x += par[PAR_ROTOR_Y + i] * f[i]
        tau_y -= par[PAR_ROTOR_X + i] * f[i]
        tau_z -= par[PAR_SPIN + i] * c_tau * f[i]

    # rotor drag: -m R diag(d) R^T v_air, scaled by the rotors' speed relative to hover (the sum of the
    # rotor speeds in Faessler et al.'s model; a rotor's speed goes as the root of its thrust): stopped
    # rotors have no drag
    hover = 0.25 * m * par[PAR_G]
    spin = 0.25 * (
        math.sqrt(max(f[0], 0.0) / hover)
        + math.sqrt(max(f[1], 0.0) / hover)
        + math.sqrt(max(f[2], 0.0) / hover)
        + math.sqrt(max(f[3], 0.0) / hover)
    )
    vax = y[3] - v_wind_W[0]
    vay = y[4] - v_wind_W[1]
    vaz = y[5] - v_wind_W[2]
    bx = spin * par[PAR_DRAG] * (r00 * vax + r10 * vay + r20 * vaz)
    by = spin * par[PAR_DRAG + 1] * (r01 * vax + r11 * vay + r21 * vaz)
    bz = spin * par[PAR_DRAG + 2] * (r02 * vax + r12 * vay + r22 * vaz)

    out[0] = y[3]
    out[1] = y[4]
    out[2] = y[5]
    out[3] = (r02 * thrust + f_ext_W[0]) / m - (r00 * bx + r01 * by + r02 * bz)
    out[4] = (r12 * thrust + f_ext_W[1]) / m - (r10 * bx + r11 * by + r12 * bz)
    out[5] = (r22 * thrust + f_ext_W[2]) / m - (r20 * bx + r21 * by + r22 * bz) - par[PAR_G]

    wx, wy, wz = y[10], y[11], y[12]
    # q' = 1/2 q (x) (w, 0): vector part qw w + qv x w, scalar part -qv . w
    out[6] = 0.5 * (qw * wx + qy * wz - qz * wy)
    out[7] = 0.5 * (qw * wy + qz * wx - qx * wz)
    out[8] = 0.5 * (qw * wz + qx * wy - qy * wx)
    out[9] = -0.5 * (qx * wx + qy * wy + qz * wz)

    jx, jy, jz = par[PAR_J], par[PAR_J + 1], par[PAR_J + 2]
    hx, hy, hz = jx * wx, jy * wy, jz * wz
    out[10] = (tau_x - (wy * hz - wz * hy)) / jx
    out[11] = (tau_y - (wz * hx - wx * hz)) / jy
    out[12] = (tau_z - (wx * hy - wy * hx)) / jz


@njit(cache=True)
def derivatives(
    x: FloatArray, motor_cmd_N: FloatArray, f_ext_W: FloatArray, v_wind_W: FloatArray, params: FloatArray
) -> FloatArray:
    """Time derivative of the state x (NX,) for rotor commands (4,) in N, an external force on the
    centre of mass f_ext_W (3,) in N and the air's velocity v_wind_W (3,) in m/s. ``xdot[3:6]`` is the
    acceleration a_WB that an IMU senses (plus gravity)."""
    out = np.empty(NX)
    _rigid_body_deriv(x, x[IX_F : IX_F + 4], f_ext_W, v_wind_W, params, out)
    f_lo, f_hi = params[PAR_F_MIN], params[PAR_F_MAX]
    for i in range(4):
        c = min(max(motor_cmd_N[i], f_lo), f_hi)
        f = x[IX_F + i]
        tau = params[PAR_TAU_UP] if c >= f else params[PAR_TAU_DOWN]
        out[IX_F + i] = (c - f) / tau
    return out


@njit(cache=True)
def _motor_thrust_at(f0: FloatArray, c: FloatArray, tau: FloatArray, h: float, out: FloatArray) -> None:
    for i in range(4):
        out[i] = c[i] + (f0[i] - c[i]) * math.exp(-h / tau[i])


@njit(cache=True)
def step(
    x: FloatArray,
    motor_cmd_N: FloatArray,
    f_ext_W: FloatArray,
    v_wind_W: FloatArray,
    params: FloatArray,
    dt: float,
) -> FloatArray:
    """The state after ``dt`` seconds with the inputs held; returns a new array (NX,), x is untouched.

    Rotors exactly (exponential toward the saturated command), rigid body by RK4, quaternion
    renormalised. Arguments as in :func:`derivatives`.
    """
    f_lo, f_hi = params[PAR_F_MIN], params[PAR_F_MAX]
    f0 = x[IX_F : IX_F + 4].copy()
    c = np.empty(4)
    tau = np.empty(4)
    for i in range(4):
        c[i] = min(max(motor_cmd_N[i], f_lo), f_hi)
        tau[i] = params[PAR_TAU_UP] if c[i] >= f0[i] else params[PAR_TAU_DOWN]
    f_mid = np.empty(4)
    f_end = np.empty(4)
    _motor_thrust_at(f0, c, tau, 0.5 * dt, f_mid)
    _motor_thrust_at(f0, c, tau, dt, f_end)

    y0 = x[:13]
    k1 = np.empty(13)
    k2 = np.empty(13)
    k3 = np.empty(13)
    k4 = np.empty(13)
    tmp = np.empty(13)
    _rigid_body_deriv(y0, f0, f_ext_W, v_wind_W, params, k1)
    for j in range(13):
        tmp[j] = y0[j] + 0.5 * dt * k1[j]
    _rigid_body_deriv(tmp, f_mid, f_ext_W, v_wind_W, params, k2)
    for j in range(13):
        tmp[j] = y0[j] + 0.5 * dt * k2[j]
    _rigid_body_deriv(tmp, f_mid, f_ext_W, v_wind_W, params, k3)
    for j in range(13):
        tmp[j] = y0[j] + dt * k3[j]
    _rigid_body_deriv(tmp, f_end, f_ext_W, v_wind_W, params, k4)

    out = np.empty(NX)
    h6 = dt / 6.0
    for j in range(13):
        out[j] = y0[j] + h6 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
    nq = math.sqrt(out[6] ** 2 + out[7] ** 2 + out[8] ** 2 + out[9] ** 2)
    for j in range(6, 10):
        out[j] /= nq
    for i in range(4):
        out[IX_F + i] = f_end[i]
    return out


@njit(cache=True)
def step_many(
    x: FloatArray,
    motor_cmd_N: FloatArray,
    f_ext_W: FloatArray,
    v_wind_W: FloatArray,
    params: FloatArray,
    dt: float,
    n: int,
) -> FloatArray:
    """``n`` calls of :func:`step` with the same inputs; returns the final state (NX,)."""
    y = x.copy()
    for _ in range(n):
        y = step(y, motor_cmd_N, f_ext_W, v_wind_W, params, dt)
    return y


# --------------------------------------------------------------------------------------------------
# Contact with the deck (the pad on the moving platform) and the ground
# --------------------------------------------------------------------------------------------------
# A penalty (spring-damper) model at the four landing-gear feet, with regularised Coulomb friction.
#
# Why a penalty model rather than impulses or constraints: it is a smooth force inside the same RK4
# step as the rest of the dynamics (no event detection, no complementarity solve, nothing that changes
# the integrator's order), it gives an impact a duration and so an accelerometer spike the onboard land
# detector can read, and it carries the deck's velocity and acceleration into the vehicle through the
# feet's relative velocity. Its cost is a small penetration (1.2 mm at rest with the defaults) and a
# stiffness that must stay inside RK4's stability region at 1 kHz: with k = 2500 N/m and c = 25 N s/m per
# foot, a 1 kg vehicle's vertical mode is 100 rad/s (0.1 rad per step), the roll/pitch mode on feet 0.2 m
# out with J = 0.0104 kg m^2 about 200 rad/s (0.2 rad per step), far from RK4's |lambda dt| ~ 2.8 limit;
# the friction's regularisation (slip speed 0.02 m/s) keeps its stiffness (mu m g / v_slip / m) near
# 300 1/s (0.3 per step); its price is a creep of the feet, ~1 cm/s on a deck braking at 2.5 m/s^2.
# tests/sim/test_sim_contact.py checks rest, impact, bounce, friction, a braking deck and the edges.

CP_K = 0
"""Normal stiffness per foot (N/m)."""
CP_C = 1
"""Normal damping per foot (N s/m); the normal force never pulls."""
CP_MU = 2
"""Coulomb friction coefficient (feet on the deck or the ground)."""
CP_V_SLIP = 3
"""Slip speed of the regularised friction (m/s): below it the friction force grows linearly."""
CP_GEAR_H = 4
"""Height of the body origin above the feet (m)."""
CP_GEAR_W = 5
"""Half the distance between feet along x_B and y_B (m): feet at (+-w, +-w, -gear_height) in B."""
CP_DECK_DEPTH = 6
"""A foot deeper than this below the deck surface is beside the platform, not on it (m)."""
N_CP = 7

DK_ON = 0
"""1.0 when there is a deck (a platform carrying the pad)."""
DK_P = 1
"""Deck (pad) centre in W at the deck time (m), [1:4]; z is the deck surface."""
DK_YAW = 4
"""Deck heading (rad)."""
DK_HALF = 5
"""Half the side of the square deck (m)."""
DK_V = 6
"""Deck velocity in W (m/s), [6:9]."""
DK_A = 9
"""Deck acceleration in W (m/s^2), [9:12]."""
DK_YAW_RATE = 12
"""Deck heading rate (rad/s)."""
DK_TILTED = 13
"""1.0 for a deck that tilts (a vessel at sea): the entries below describe it, and the square of
``DK_HALF``, the heading and its rate are not used."""
DK_R = 14
"""The deck's orientation R_WP at the deck time, row-major, [14:23]; its third column is the normal."""
DK_W = 23
"""The deck's angular velocity in W (rad/s), [23:26]."""
DK_EXT = 26
"""The deck's extent in its own frame P: x_min, x_max, y_min, y_max (m), [26:30]."""
N_DK = 30


def pack_contact_params(
    airframe: Airframe = DEFAULT_AIRFRAME,
    *,
    stiffness_N_per_m: float = 2500.0,
    damping_Ns_per_m: float = 25.0,
    friction: float = 0.6,
    slip_speed_mps: float = 0.02,
    gear_half_width_m: float = 0.2,
    deck_depth_m: float = 0.15,
) -> FloatArray:
    """The contact model's parameters as the flat array the kernels read, shape (N_CP,); see ``CP_*``.
    Defaults: a stiff skid with damping ratio 0.5 (1 kg on four feet: restitution ~0.16, so a 0.4 m/s
    touchdown with hover thrust still on rebounds at ~0.07 m/s and hops a few centimetres until the
    thrust drops: the bounces ``result.json`` counts), rubber-on-plastic friction 0.6.
    """
    values = (stiffness_N_per_m, damping_Ns_per_m, friction, slip_speed_mps, gear_half_width_m, deck_depth_m)
    if not all(math.isfinite(v) and v >= 0.0 for v in values) or slip_speed_mps <= 0.0:
        raise ValueError("contact parameters must be finite and >= 0, slip speed > 0")
    cp = np.zeros(N_CP)
    cp[CP_K] = stiffness_N_per_m
    cp[CP_C] = damping_Ns_per_m
    cp[CP_MU] = friction
    cp[CP_V_SLIP] = slip_speed_mps
    cp[CP_GEAR_H] = airframe.gear_height
    cp[CP_GEAR_W] = gear_half_width_m
    cp[CP_DECK_DEPTH] = deck_depth_m
    return cp


def no_deck() -> FloatArray:
    """A deck array (N_DK,) for a world with only the ground."""
    return np.zeros(N_DK)


@njit(cache=True)
def deck_at(deck: FloatArray, tau: float, out: FloatArray) -> None:
    """The deck ``tau`` seconds after its stamped state (constant acceleration and turn rate over the
    few milliseconds a batch of steps spans), written into ``out`` (N_DK,)."""
    for j in range(N_DK):
        out[j] = deck[j]
    for j in range(3):
        out[DK_P + j] = deck[DK_P + j] + deck[DK_V + j] * tau + 0.5 * deck[DK_A + j] * tau * tau
        out[DK_V + j] = deck[DK_V + j] + deck[DK_A + j] * tau
    out[DK_YAW] = deck[DK_YAW] + deck[DK_YAW_RATE] * tau
    if deck[DK_TILTED] > 0.5:
        _turn_deck(deck, tau, out)


@njit(cache=True)
def _turn_deck(deck: FloatArray, tau: float, out: FloatArray) -> None:
    """The tilted deck's orientation ``tau`` seconds on at its constant angular velocity: R = Exp(w tau)
    R0 (Rodrigues), into ``out``'s ``DK_R`` entries."""
    ax, ay, az = deck[DK_W] * tau, deck[DK_W + 1] * tau, deck[DK_W + 2] * tau
    th2 = ax * ax + ay * ay + az * az
    if th2 < 1e-18:
        return
    th = math.sqrt(th2)
    a = math.sin(th) / th
    b = (1.0 - math.cos(th)) / th2
    # E = I + a K + b K^2, K = [axis x]
    E = np.empty((3, 3))
    E[0, 0] = 1.0 - b * (ay * ay + az * az)
    E[1, 1] = 1.0 - b * (ax * ax + az * az)
    E[2, 2] = 1.0 - b * (ax * ax + ay * ay)
    E[0, 1] = -a * az + b * ax * ay
    E[1, 0] = a * az + b * ax * ay
    E[0, 2] = a * ay + b * ax * az
    E[2, 0] = -a * ay + b * ax * az
    E[1, 2] = -a * ax + b * ay * az
    E[2, 1] = a * ax + b * ay * az
    for i in range(3):
        for j in range(3):
            out[DK_R + 3 * i + j] = (
                E[i, 0] * deck[DK_R + j] + E[i, 1] * deck[DK_R + 3 + j] + E[i, 2] * deck[DK_R + 6 + j]
            )


@njit(cache=True)
def tilted_deck_top(deck: FloatArray) -> float:
    """The height of a tilted deck's highest corner (m)."""
    top = -math.inf
    for x in (deck[DK_EXT], deck[DK_EXT + 1]):
        for y in (deck[DK_EXT + 2], deck[DK_EXT + 3]):
            top = max(top, deck[DK_P + 2] + deck[DK_R + 6] * x + deck[DK_R + 7] * y)
    return top


@njit(cache=True)
def feet_clear(z_WB: float, deck: FloatArray, cp: FloatArray) -> bool:
    """True when no foot can touch the deck (``deck``, ``DK_*``) or the ground with the body origin at
    height ``z_WB`` (m), whatever the attitude: :func:`contact_wrench` is then zero."""
    gh, gw = cp[CP_GEAR_H], cp[CP_GEAR_W]
    reach = math.sqrt(gh * gh + 2.0 * gw * gw)
    if deck[DK_TILTED] > 0.5:
        top = max(tilted_deck_top(deck), 0.0) if deck[DK_ON] > 0.5 else 0.0
    else:
        top = deck[DK_P + 2] if deck[DK_ON] > 0.5 and deck[DK_P + 2] > 0.0 else 0.0
    return z_WB - reach > top


@njit(cache=True)
def tilted_deck_force(
    deck: FloatArray,
    cp: FloatArray,
    p: tuple[float, float, float],
    v: tuple[float, float, float],
    f: FloatArray,
) -> int:
    """The force of a tilted, moving deck on a foot at ``p`` moving at ``v`` (W), into ``f`` (3,): 1 when
    the foot presses on the deck, -1 when it is in the deck's volume without pressing (separating), 0
    when it is not over the deck (the ground may hold it). The deck's surface velocity under the foot is
    v_WP + w x s (s the surface point from the deck's centre); the normal force ``max(k d + c d', 0)``
    acts along the deck's normal (d the penetration along it), the friction ``-mu N v_t / sqrt(|v_t|^2
    + v_slip^2)`` in the deck's plane against the foot's velocity relative to the surface."""
    dx, dy, dz = p[0] - deck[DK_P], p[1] - deck[DK_P + 1], p[2] - deck[DK_P + 2]
    r0 = DK_R
    lx = deck[r0] * dx + deck[r0 + 3] * dy + deck[r0 + 6] * dz
    ly = deck[r0 + 1] * dx + deck[r0 + 4] * dy + deck[r0 + 7] * dz
    lz = deck[r0 + 2] * dx + deck[r0 + 5] * dy + deck[r0 + 8] * dz
    ext = DK_EXT
    if not (
        deck[ext] <= lx <= deck[ext + 1]
        and deck[ext + 2] <= ly <= deck[ext + 3]
        and -cp[CP_DECK_DEPTH] < lz <= 0.0
    ):
        return 0
    nx, ny, nz = deck[r0 + 2], deck[r0 + 5], deck[r0 + 8]
    sx, sy, sz = dx - lz * nx, dy - lz * ny, dz - lz * nz
    wx, wy, wz = deck[DK_W], deck[DK_W + 1], deck[DK_W + 2]
    rx = v[0] - (deck[DK_V] + wy * sz - wz * sy)
    ry = v[1] - (deck[DK_V + 1] + wz * sx - wx * sz)
    rz = v[2] - (deck[DK_V + 2] + wx * sy - wy * sx)
    vn = rx * nx + ry * ny + rz * nz
    normal = cp[CP_K] * (-lz) - cp[CP_C] * vn
    if normal <= 0.0:
        return -1
    tx, ty, tz = rx - vn * nx, ry - vn * ny, rz - vn * nz
    scale = cp[CP_MU] * normal / math.sqrt(tx * tx + ty * ty + tz * tz + cp[CP_V_SLIP] ** 2)
    f[0] = normal * nx - scale * tx
    f[1] = normal * ny - scale * ty
    f[2] = normal * nz - scale * tz
    return 1


@njit(cache=True)
def contact_wrench(
    y: FloatArray, deck: FloatArray, cp: FloatArray, f_W: FloatArray, tau_B: FloatArray, counts: FloatArray
) -> int:
    """Contact force on the body in W (N) and torque about the centre of mass in B (N m) from the feet
    touching the deck or the ground, written into ``f_W`` (3,) and ``tau_B`` (3,); returns how many feet
    touch, and the number on the deck and on the ground into ``counts`` (2,). ``y``: the state (at least
    the first 13 entries); ``deck``: the deck now (``DK_*``).

    A foot whose (x, y) is over the deck square and whose height is between the deck surface and
    ``deck_depth`` below it presses on the deck, whose surface velocity at the foot is the deck's
    velocity plus its turn (yaw rate x lever arm); any other foot below z = 0 presses on the ground. A
    tilted deck (``DK_TILTED``, a vessel at sea) is met along its normal (:func:`tilted_deck_force`).
    Normal force ``max(k d + c d', 0)`` (d the penetration), friction ``-mu N v_t / sqrt(|v_t|^2 +
    v_slip^2)`` against the foot's tangential velocity relative to the surface.

    One kernel: the physics' innermost loop, called at every integrator stage, accumulating
    each foot's force and torque as it goes (the common case, no foot near a surface, leaves at
    ``feet_clear``); a per-foot helper would hand back the foot's force, its surface and whether it touches,
    four times per stage, for a loop body that already reads as the docstring's three sentences.
    """
    for j in range(3):
        f_W[j] = 0.0
        tau_B[j] = 0.0
    counts[0] = 0.0
    counts[1] = 0.0
    if feet_clear(y[2], deck, cp):
        return 0  # no foot can reach a surface: the common case, kept cheap
    gh, gw = cp[CP_GEAR_H], cp[CP_GEAR_W]
    deck_on = deck[DK_ON] > 0.5
    qx, qy, qz, qw = y[6], y[7], y[8], y[9]
    n2 = qx * qx + qy * qy + qz * qz + qw * qw
    R = np.empty((3, 3))
    quat_to_R_scaled(qx, qy, qz, qw, 2.0 / n2, R)
    wx, wy, wz = y[10], y[11], y[12]
    k, c, mu, vs = cp[CP_K], cp[CP_C], cp[CP_MU], cp[CP_V_SLIP]
    cyaw, syaw = math.cos(deck[DK_YAW]), math.sin(deck[DK_YAW])
    half = deck[DK_HALF]
    tilted = deck_on and deck[DK_TILTED] > 0.5
    ff = np.empty(3)
    touching = 0
    for i in range(4):
        rx = gw if (i == 0 or i == 3) else -gw
        ry = gw if i < 2 else -gw
        rz = -gh
        # foot position and velocity in W: p + R r, v + R (w x r)
        px = y[0] + R[0, 0] * rx + R[0, 1] * ry + R[0, 2] * rz
        py = y[1] + R[1, 0] * rx + R[1, 1] * ry + R[1, 2] * rz
        pz = y[2] + R[2, 0] * rx + R[2, 1] * ry + R[2, 2] * rz
        cx = wy * rz - wz * ry
        cy = wz * rx - wx * rz
        cz = wx * ry - wy * rx
        vx = y[3] + R[0, 0] * cx + R[0, 1] * cy + R[0, 2] * cz
        vy = y[4] + R[1, 0] * cx + R[1, 1] * cy + R[1, 2] * cz
        vz = y[5] + R[2, 0] * cx + R[2, 1] * cy + R[2, 2] * cz
        surf_z = 0.0
        svx = 0.0
        svy = 0.0
        svz = 0.0
        on_deck = False
        if tilted:
            hit = tilted_deck_force(deck, cp, (px, py, pz), (vx, vy, vz), ff)
            if hit < 0:
                continue
            if hit > 0:
                touching += 1
                counts[0] += 1.0
                add_foot_wrench(R, (rx, ry, rz), ff, f_W, tau_B)
                continue
        elif deck_on:
            dx = px - deck[DK_P]
            dy = py - deck[DK_P + 1]
            dz = deck[DK_P + 2]
            if (
                abs(cyaw * dx + syaw * dy) <= half
                and abs(-syaw * dx + cyaw * dy) <= half
                and dz - cp[CP_DECK_DEPTH] < pz <= dz
            ):
                on_deck = True
                surf_z = dz
                r = deck[DK_YAW_RATE]
                svx = deck[DK_V] - r * dy
                svy = deck[DK_V + 1] + r * dx
                svz = deck[DK_V + 2]
        if not on_deck and pz > 0.0:
            continue
        pen = surf_z - pz
        normal = k * pen - c * (vz - svz)
        if normal <= 0.0:
            continue
        touching += 1
        counts[0 if on_deck else 1] += 1.0
        tx = vx - svx
        ty = vy - svy
        scale = mu * normal / math.sqrt(tx * tx + ty * ty + vs * vs)
        fx = -scale * tx
        fy = -scale * ty
        fz = normal
        f_W[0] += fx
        f_W[1] += fy
        f_W[2] += fz
        # torque in B: r x (R^T f)
        bx = R[0, 0] * fx + R[1, 0] * fy + R[2, 0] * fz
        by = R[0, 1] * fx + R[1, 1] * fy + R[2, 1] * fz
        bz = R[0, 2] * fx + R[1, 2] * fy + R[2, 2] * fz
        tau_B[0] += ry * bz - rz * by
        tau_B[1] += rz * bx - rx * bz
        tau_B[2] += rx * by - ry * bx
    return touching


@njit(cache=True)
def add_foot_wrench(
    R: FloatArray, r_B: tuple[float, float, float], f: FloatArray, f_W: FloatArray, tau_B: FloatArray
) -> None:
    """Add a foot's force ``f`` (W) at ``r_B`` (B) to the body's force in W and torque in B."""
    rx, ry, rz = r_B
    f_W[0] += f[0]
    f_W[1] += f[1]
    f_W[2] += f[2]
    bx = R[0, 0] * f[0] + R[1, 0] * f[1] + R[2, 0] * f[2]
    by = R[0, 1] * f[0] + R[1, 1] * f[1] + R[2, 1] * f[2]
    bz = R[0, 2] * f[0] + R[1, 2] * f[1] + R[2, 2] * f[2]
    tau_B[0] += ry * bz - rz * by
    tau_B[1] += rz * bx - rx * bz
    tau_B[2] += rx * by - ry * bx


@njit(cache=True)
def _contact_deriv(
    y: FloatArray,
    f: FloatArray,
    f_ext_W: FloatArray,
    v_wind_W: FloatArray,
    par: FloatArray,
    deck: FloatArray,
    cp: FloatArray,
    fc: FloatArray,
    tc: FloatArray,
    out: FloatArray,
) -> None:
    """:func:`_rigid_body_deriv` plus the contact wrench."""
    _rigid_body_deriv(y, f, f_ext_W, v_wind_W, par, out)
    counts = np.empty(2)
    if contact_wrench(y, deck, cp, fc, tc, counts) > 0:
        m = par[PAR_MASS]
        for j in range(3):
            out[3 + j] += fc[j] / m
            out[10 + j] += tc[j] / par[PAR_J + j]


@njit(cache=True)
def step_contact(
    x: FloatArray,
    motor_cmd_N: FloatArray,
    f_ext_W: FloatArray,
    v_wind_W: FloatArray,
    params: FloatArray,
    dt: float,
    deck: FloatArray,
    deck_tau: float,
    cp: FloatArray,
) -> FloatArray:
    """:func:`step` with the contact of the feet with the deck and the ground. ``deck`` (N_DK,) is the
    deck's state at its stamp and ``deck_tau`` the time of ``x`` since that stamp (s); each RK4 stage
    sees the deck where it is at the stage's time."""
    f_lo, f_hi = params[PAR_F_MIN], params[PAR_F_MAX]
    f0 = x[IX_F : IX_F + 4].copy()
    c = np.empty(4)
    tau = np.empty(4)
    for i in range(4):
        c[i] = min(max(motor_cmd_N[i], f_lo), f_hi)
        tau[i] = params[PAR_TAU_UP] if c[i] >= f0[i] else params[PAR_TAU_DOWN]
    f_mid = np.empty(4)
    f_end = np.empty(4)
    _motor_thrust_at(f0, c, tau, 0.5 * dt, f_mid)
    _motor_thrust_at(f0, c, tau, dt, f_end)

    d0 = np.empty(N_DK)
    dm = np.empty(N_DK)
    d1 = np.empty(N_DK)
    deck_at(deck, deck_tau, d0)
    deck_at(deck, deck_tau + 0.5 * dt, dm)
    deck_at(deck, deck_tau + dt, d1)
    fc = np.empty(3)
    tc = np.empty(3)

    y0 = x[:13]
    k1 = np.empty(13)
    k2 = np.empty(13)
    k3 = np.empty(13)
    k4 = np.empty(13)
    tmp = np.empty(13)
    # High above every surface (the common case) the contact adds nothing: the rigid body's derivative
    # alone is the same number, without the contact's calls (which cost more than its arithmetic).
    if feet_clear(y0[2], d0, cp):
        _rigid_body_deriv(y0, f0, f_ext_W, v_wind_W, params, k1)
    else:
        _contact_deriv(y0, f0, f_ext_W, v_wind_W, params, d0, cp, fc, tc, k1)
    for j in range(13):
        tmp[j] = y0[j] + 0.5 * dt * k1[j]
    if feet_clear(tmp[2], dm, cp):
        _rigid_body_deriv(tmp, f_mid, f_ext_W, v_wind_W, params, k2)
    else:
        _contact_deriv(tmp, f_mid, f_ext_W, v_wind_W, params, dm, cp, fc, tc, k2)
    for j in range(13):
        tmp[j] = y0[j] + 0.5 * dt * k2[j]
    if feet_clear(tmp[2], dm, cp):
        _rigid_body_deriv(tmp, f_mid, f_ext_W, v_wind_W, params, k3)
    else:
        _contact_deriv(tmp, f_mid, f_ext_W, v_wind_W, params, dm, cp, fc, tc, k3)
    for j in range(13):
        tmp[j] = y0[j] + dt * k3[j]
    if feet_clear(tmp[2], d1, cp):
        _rigid_body_deriv(tmp, f_end, f_ext_W, v_wind_W, params, k4)
    else:
        _contact_deriv(tmp, f_end, f_ext_W, v_wind_W, params, d1, cp, fc, tc, k4)

    out = np.empty(NX)
    h6 = dt / 6.0
    for j in range(13):
        out[j] = y0[j] + h6 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
    nq = math.sqrt(out[6] ** 2 + out[7] ** 2 + out[8] ** 2 + out[9] ** 2)
    for j in range(6, 10):
        out[j] /= nq
    for i in range(4):
        out[IX_F + i] = f_end[i]
    return out


# --------------------------------------------------------------------------------------------------
# Thin stateful shell
# --------------------------------------------------------------------------------------------------

_ZERO3 = np.zeros(3)


def initial_state(p_WB: FloatArray, yaw: float = 0.0, motor_thrust_N: float = 0.0) -> FloatArray:
    """A state at rest at p_WB (3,) with heading ``yaw`` (rad) and all rotors at ``motor_thrust_N``."""
    x = np.zeros(NX)
    x[SL_P] = np.asarray(p_WB, dtype=np.float64).reshape(3)
    x[IX_Q + 2] = math.sin(0.5 * yaw)
    x[IX_Q + 3] = math.cos(0.5 * yaw)
    x[SL_F] = motor_thrust_N
    return x


class QuadrotorSim:
    """The quadrotor as an object: holds the state and the packed parameters, steps the kernels."""

    def __init__(self, airframe: Airframe = DEFAULT_AIRFRAME, *, dt: float = 0.001) -> None:
        """``dt``: integration step (s), at most 2 ms (the design asks for >= 500 Hz)."""
        if not (0.0 < dt <= 0.002):
            raise ValueError(f"dt must be in (0, 0.002] s, got {dt}")
        self.airframe = airframe
        self.params = pack_params(airframe)
        self.dt = float(dt)
        self.t = 0.0
        self.x = initial_state(np.zeros(3))

    def reset(self, p_WB: FloatArray, yaw: float = 0.0, *, hover: bool = False, t: float = 0.0) -> None:
        """At rest at p_WB (3,) with heading yaw; rotors off, or at hover thrust when ``hover``."""
        f0 = self.airframe.weight_N / 4.0 if hover else 0.0
        self.x = initial_state(p_WB, yaw, f0)
        self.t = float(t)

    def step(
        self,
        motor_cmd_N: FloatArray,
        f_ext_W: FloatArray | None = None,
        v_wind_W: FloatArray | None = None,
        n: int = 1,
    ) -> None:
        """Advance ``n`` steps of ``dt`` with rotor commands (4,) N, external force (3,) N and air
        velocity (3,) m/s held."""
        u = np.asarray(motor_cmd_N, dtype=np.float64)
        fe = _ZERO3 if f_ext_W is None else np.asarray(f_ext_W, dtype=np.float64)
        vw = _ZERO3 if v_wind_W is None else np.asarray(v_wind_W, dtype=np.float64)
        if n == 1:
            self.x = step(self.x, u, fe, vw, self.params, self.dt)
        else:
            self.x = step_many(self.x, u, fe, vw, self.params, self.dt, n)
        self.t += n * self.dt

    def accel_W(self, f_ext_W: FloatArray | None = None, v_wind_W: FloatArray | None = None) -> FloatArray:
        """Acceleration a_WB (3,) in m/s^2 at the current state (what the IMU senses, plus gravity)."""
        fe = _ZERO3 if f_ext_W is None else np.asarray(f_ext_W, dtype=np.float64)
        vw = _ZERO3 if v_wind_W is None else np.asarray(v_wind_W, dtype=np.float64)
        return derivatives(self.x, self.x[SL_F], fe, vw, self.params)[SL_V]

    @property
    def p_WB(self) -> FloatArray:
        return self.x[SL_P].copy()

    @property
    def v_WB(self) -> FloatArray:
        return self.x[SL_V].copy()

    @property
    def q_WB(self) -> FloatArray:
        return self.x[SL_Q].copy()

    @property
    def R_WB(self) -> FloatArray:
        return quat_to_rotmat(self.x[SL_Q])

    @property
    def w_WB_B(self) -> FloatArray:
        return self.x[SL_W].copy()

    @property
    def motor_thrust_N(self) -> FloatArray:
        return self.x[SL_F].copy()
