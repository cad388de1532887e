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
eq. 2 with the thrust dependence folded into ``d``); ``v_wind_W`` is the air's velocity (zero when the
wind is modelled as a force, as the SDU gust model does).

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
    s = 2.0 / n2
    r00 = 1.0 - s * (qy * qy + qz * qz)
    r01 = s * (qx * qy - qz * qw)
    r02 = s * (qx * qz + qy * qw)
    r10 = s * (qx * qy + qz * qw)
    r11 = 1.0 - s * (qx * qx + qz * qz)
    r12 = s * (qy * qz - qx * qw)
    r20 = s * (qx * qz - qy * qw)
    r21 = s * (qy * qz + qx * qw)
    r22 = 1.0 - s * (qx * qx + qy * qy)

    thrust = f[0] + f[1] + f[2] + f[3]
    tau_x = 0.0
    tau_y = 0.0
    tau_z = 0.0
    c_tau = par[PAR_C_TAU]
    for i in range(4):
        tau_x += par[PAR_ROTOR_Y + i] * f[i]
        tau_y -= par[PAR_ROTOR_X + i] * f[i]
        tau_z -= par[PAR_SPIN + i] * c_tau * f[i]

    # rotor drag: -m R diag(d) R^T v_air
    vax = y[3] - v_wind_W[0]
    vay = y[4] - v_wind_W[1]
    vaz = y[5] - v_wind_W[2]
    bx = par[PAR_DRAG] * (r00 * vax + r10 * vay + r20 * vaz)
    by = par[PAR_DRAG + 1] * (r01 * vax + r11 * vay + r21 * vaz)
    bz = par[PAR_DRAG + 2] * (r02 * vax + r12 * vay + r22 * vaz)

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


@njit(cache=True)
def rest_on_surface(
    x: FloatArray, z_surface: float, v_surface_W: FloatArray, gear_height: float
) -> FloatArray:
    """A minimal resting contact for a vehicle standing on a level surface (the ground before take-off,
    the pad after landing).

    When the feet (``p_z - gear_height``) are at or below ``z_surface`` and the vehicle does not move up
    relative to the surface, the vehicle is put on the surface: feet at ``z_surface``, velocity equal to
    the surface's ``v_surface_W`` (3,), level attitude with the current heading, no body rates. Otherwise
    x is returned unchanged (a copy). Rotor thrusts are kept, so thrust above weight lifts off on the
    next step. Judge the touchdown (:mod:`alight.sim.touchdown`) before calling this.
    """
    y = x.copy()
    if x[IX_P + 2] - gear_height > z_surface:
        return y
    if x[IX_V + 2] - v_surface_W[2] > 0.0:
        return y
    y[IX_P + 2] = z_surface + gear_height
    for j in range(3):
        y[IX_V + j] = v_surface_W[j]
        y[IX_W + j] = 0.0
    qx, qy, qz, qw = x[6], x[7], x[8], x[9]
    yaw = math.atan2(2.0 * (qx * qy + qz * qw), 1.0 - 2.0 * (qy * qy + qz * qz))
    y[IX_Q] = 0.0
    y[IX_Q + 1] = 0.0
    y[IX_Q + 2] = math.sin(0.5 * yaw)
    y[IX_Q + 3] = math.cos(0.5 * yaw)
    return y


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
