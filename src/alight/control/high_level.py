"""High-level controller: reference (p, v, a, j, yaw, yaw rate) -> collective thrust and body rates.

Paper 000 (Falanga et al. 2017) Sec. II-E flies the nonlinear controller of its references [27], [28]:
Faessler, Franchi, Scaramuzza, "Differential flatness of quadrotor dynamics subject to rotor drag for
accurate tracking of high-speed trajectories", RA-L 2018, and Faessler, Falanga, Scaramuzza, "Thrust
mixing, saturation, and body-rate control for accurate aggressive quadrotor flight", RA-L 2017. In outline
(``/work/shared/references/flatness_control.md``):

1. desired acceleration ``a_des = a_ref + K_p (p_ref - p) + K_v (v_ref - v)`` (+ an optional integral);
2. thrust vector ``f_des = a_des - g + R_ref D R_ref^T v_ref``: the rotor-drag acceleration
   ``a_rd = -R D R^T v`` of Faessler 2018's translational dynamics (D = diag(d_x, d_y, d_z), mass-
   normalised) evaluated on the reference, so the drag is compensated by feed-forward, not by feedback;
3. tilt limit on ``f_des`` (its vertical part has priority), desired attitude from ``f_des`` and the
   reference yaw, collective thrust ``c = f_des . z_B`` projected on the CURRENT body z axis;
4. body rates = feed-forward rates of the reference (from the jerk and the yaw rate; scaled down by
   c_ref / |f_des| while step 3 holds the vertical part at its floor, so that a reference near free
   fall does not feed its huge rates) + a tilt-prioritised attitude-error feedback (Faessler 2017: the
   error quaternion is split into a tilt part, which the thrust direction and thus the position depend
   on, and a yaw part, which has the least authority).

Yaw parametrisation. The attitude is built as in Faessler 2018 (x_B from y_C): with ``y_C = (-sin psi,
cos psi, 0)``, ``x_B = y_C x z_B / |y_C x z_B|``, ``y_B = z_B x x_B``. Then ``x_B`` lies in the vertical
plane of the heading ``psi``, so ``alight.types.yaw_of(R_WB) == psi`` exactly (the ZYX yaw every other
block reads). The reference sheet's construction (Mellinger & Kumar 2011, ``y_B`` perpendicular to
``x_C``) is the ZXY yaw instead, which differs from ``yaw_of`` by a tilt-dependent amount; its rate
formula was re-derived for this construction by differentiating the constraint ``x_B . y_C = 0``:
``w_z = (w_y (z_B . y_C) + psi_dot (x_B . x_C)) / (y_B . y_C)`` (tested against finite differences).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numba import njit, types

from alight.airframe import DEFAULT_AIRFRAME, Airframe
from alight.control.rate import tilt_time_constant_s
from alight.numerics.rotation import R_to_quat, quat_to_R
from alight.types import GRAVITY_MPS2, Command, EgoState, FloatArray, Reference

__all__ = [
    "HighLevelController",
    "HighLevelGains",
    "attitude_from_accel_yaw",
    "body_rates_from_jerk",
    "high_level_kernel",
    "pack_high_level_params",
]

# --------------------------------------------------------------------------------------------------
# Layout of the packed parameter vector of ``high_level_kernel`` (float64).
# --------------------------------------------------------------------------------------------------
HL_KP = 0  # 3: position gains K_p (1/s^2)
HL_KV = 3  # 3: velocity gains K_v (1/s)
HL_KI = 6  # 3: integral gains K_i (1/s^3)
HL_I_LIM = 9  # 1: largest integral contribution per axis (m/s^2)
HL_K_TILT = 10  # 1: tilt gain 1 / tau_tilt (1/s)
HL_K_YAW = 11  # 1: yaw gain 1 / tau_yaw (1/s)
HL_TAN_TILT = 12  # 1: tan(max tilt)
HL_FZ_MIN = 13  # 1: lowest vertical part of the thrust vector (m/s^2)
HL_C_MAX = 14  # 1: largest mass-normalised collective thrust (m/s^2)
HL_MASS = 15  # 1: mass (kg)
HL_DRAG = 16  # 3: rotor-drag coefficients used for compensation (1/s), zeros when disabled
HL_RATE_LIM = 19  # 1: per-axis limit of the body-rate command (rad/s)
HL_T_MIN = 20  # 1: lowest collective thrust (N)
HL_T_MAX = 21  # 1: largest collective thrust (N)
HL_DT_MAX = 22  # 1: longest step the integral accepts (s); longer gaps are not integrated
HL_N_PARAMS = 23

HL_N_OUT = 8
"""``out`` of ``high_level_kernel``: [thrust (N), w_cmd_B (3, rad/s), q_WB_des (4, x y z w)]."""

_G = GRAVITY_MPS2
_FP_TOL = 1e-13  # fixed-point tolerance of the rotor-drag iterations (m/s^2 and rad/s)
_FP_MAX_IT = 50  # contraction ~d|v|/c: ~10 iterations at 5 m/s, ~30 at 12 m/s


# --------------------------------------------------------------------------------------------------
# numba kernels
# --------------------------------------------------------------------------------------------------


@njit(cache=True)
def _frame_from_thrust_vector(f: FloatArray, yaw: float, R: FloatArray) -> float:
    """Attitude whose z axis is along the thrust vector ``f`` (m/s^2, W) with ZYX yaw ``yaw``.

    Writes R_WB = [x_B y_B z_B] into ``R`` and returns the collective thrust c = |f| (m/s^2).
    As Faessler 2018: x_B = y_C x z_B / |.|, y_B = z_B x x_B.
    """
    c = math.sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2])
    zx, zy, zz = f[0] / c, f[1] / c, f[2] / c
    sy, cy = math.sin(yaw), math.cos(yaw)
    # y_C x z_B with y_C = (-sy, cy, 0)
    xx = cy * zz
    xy = sy * zz
    xz = -sy * zy - cy * zx
    nx = math.sqrt(xx * xx + xy * xy + xz * xz)
    xx, xy, xz = xx / nx, xy / nx, xz / nx
    # y_B = z_B x x_B
    yx = zy * xz - zz * xy
    yy = zz * xx - zx * xz
    yz = zx * xy - zy * xx
    R[0, 0], R[1, 0], R[2, 0] = xx, xy, xz
    R[0, 1], R[1, 1], R[2, 1] = yx, yy, yz
    R[0, 2], R[1, 2], R[2, 2] = zx, zy, zz
    return c


@njit(cache=True)
def _rates_from_thrust_rate(
    R: FloatArray, c: float, fdot: FloatArray, yaw: float, yaw_rate: float, w: FloatArray
) -> None:
    """Body rates (rad/s, B) of the frame of ``_frame_from_thrust_vector`` given d/dt of the thrust
    vector ``fdot`` (m/s^3, W) and the yaw rate (rad/s). Writes ``w``.

    z_B = f/|f| gives dz_B/dt = h_w = (fdot - (z_B . fdot) z_B) / c = w_y x_B - w_x y_B; the yaw rate
    follows from d/dt (x_B . y_C) = 0 with dx_B/dt = w_z y_B - w_y z_B and dy_C/dt = -psi_dot x_C.
    """
    zf = R[0, 2] * fdot[0] + R[1, 2] * fdot[1] + R[2, 2] * fdot[2]
    h0 = (fdot[0] - zf * R[0, 2]) / c
    h1 = (fdot[1] - zf * R[1, 2]) / c
    h2 = (fdot[2] - zf * R[2, 2]) / c
    wx = -(h0 * R[0, 1] + h1 * R[1, 1] + h2 * R[2, 1])
    wy = h0 * R[0, 0] + h1 * R[1, 0] + h2 * R[2, 0]
    sy, cy = math.sin(yaw), math.cos(yaw)
    z_yc = -sy * R[0, 2] + cy * R[1, 2]
    x_xc = cy * R[0, 0] + sy * R[1, 0]
    y_yc = -sy * R[0, 1] + cy * R[1, 1]
    w[0] = wx
    w[1] = wy
    w[2] = (wy * z_yc + yaw_rate * x_xc) / y_yc


@njit(cache=True)
def _drag_accel(R: FloatArray, d: FloatArray, v: FloatArray, out: FloatArray) -> None:
    """out = R D R^T v (m/s^2): minus the rotor-drag acceleration of Faessler 2018."""
    out[0] = 0.0
    out[1] = 0.0
    out[2] = 0.0
    for k in range(3):
        s = d[k] * (R[0, k] * v[0] + R[1, k] * v[1] + R[2, k] * v[2])
        out[0] += s * R[0, k]
        out[1] += s * R[1, k]
        out[2] += s * R[2, k]


@njit(cache=True)
def _flat_state(
    a: FloatArray,
    v: FloatArray,
    j: FloatArray,
    yaw: float,
    yaw_rate: float,
    d: FloatArray,
    R: FloatArray,
    f: FloatArray,
    w: FloatArray,
) -> float:
    """Attitude, thrust and body rates of a flat output (a, v, j, yaw, yaw rate) under rotor drag D.

    Solves c z_B = a - g + R D R^T v (Faessler 2018's translational dynamics) for R by fixed-point
    iteration from the drag-free attitude (the map contracts by ~|D v| / c: ~0.15 at 5 m/s with the default
    airframe), then the body rates from fdot = j + R (D a_B + w x (D v_B) - D (w x v_B)), with
    v_B = R^T v and a_B = R^T a, again by fixed point in w because fdot depends on w. With D = 0 both
    are the plain flatness relations.
    Writes R, the thrust vector f (m/s^2) and w (rad/s, B); returns c (m/s^2).
    """
    tmp = np.empty(3)
    f[0] = a[0]
    f[1] = a[1]
    f[2] = a[2] + _G
    c = _frame_from_thrust_vector(f, yaw, R)
    has_drag = d[0] != 0.0 or d[1] != 0.0 or d[2] != 0.0
    if has_drag:
        for _ in range(_FP_MAX_IT):
            _drag_accel(R, d, v, tmp)
            fx, fy, fz = a[0] + tmp[0], a[1] + tmp[1], a[2] + _G + tmp[2]
            delta = abs(fx - f[0]) + abs(fy - f[1]) + abs(fz - f[2])
            f[0], f[1], f[2] = fx, fy, fz
            c = _frame_from_thrust_vector(f, yaw, R)
            if delta < _FP_TOL:
                break
    # j copied to a writable array: the messages' j_ref is read-only, the fixed point below passes its
    # own fdot, and numba would compile _rates_from_thrust_rate once for each
    jw = np.empty(3)
    for k in range(3):
        jw[k] = j[k]
    _rates_from_thrust_rate(R, c, jw, yaw, yaw_rate, w)
    if has_drag:
        vb = np.empty(3)
        ab = np.empty(3)
        fdot = np.empty(3)
        for k in range(3):
            vb[k] = R[0, k] * v[0] + R[1, k] * v[1] + R[2, k] * v[2]
            ab[k] = R[0, k] * a[0] + R[1, k] * a[1] + R[2, k] * a[2]
        for _ in range(_FP_MAX_IT):
            # body-frame derivative of D v_B seen from W: D a_B + w x (D v_B) - D (w x v_B)
            dv0, dv1, dv2 = d[0] * vb[0], d[1] * vb[1], d[2] * vb[2]
            wv0 = w[1] * vb[2] - w[2] * vb[1]
            wv1 = w[2] * vb[0] - w[0] * vb[2]
            wv2 = w[0] * vb[1] - w[1] * vb[0]
            tmp[0] = d[0] * ab[0] + (w[1] * dv2 - w[2] * dv1) - d[0] * wv0
            tmp[1] = d[1] * ab[1] + (w[2] * dv0 - w[0] * dv2) - d[1] * wv1
            tmp[2] = d[2] * ab[2] + (w[0] * dv1 - w[1] * dv0) - d[2] * wv2
            for r in range(3):
                fdot[r] = j[r] + R[r, 0] * tmp[0] + R[r, 1] * tmp[1] + R[r, 2] * tmp[2]
            w0, w1, w2 = w[0], w[1], w[2]
            _rates_from_thrust_rate(R, c, fdot, yaw, yaw_rate, w)
            if abs(w[0] - w0) + abs(w[1] - w1) + abs(w[2] - w2) < _FP_TOL:
                break
    return c


@njit(cache=True)
def high_level_kernel(
    p: FloatArray,
    v: FloatArray,
    q: FloatArray,
    p_ref: FloatArray,
    v_ref: FloatArray,
    a_ref: FloatArray,
    j_ref: FloatArray,
    yaw_ref: float,
    yaw_rate_ref: float,
    dt: float,
    params: FloatArray,
    integ: FloatArray,
    out: FloatArray,
) -> bool:
    """One step of the high-level controller (plain arrays, callable from other numba code).

    Args:
        p, v: estimated position (m) and velocity (m/s) of the body in W, shape (3,).
        q: estimated attitude q_WB (x, y, z, w), shape (4,).
        p_ref, v_ref, a_ref, j_ref: reference position, velocity, acceleration, jerk in W, shape (3,).
        yaw_ref, yaw_rate_ref: reference ZYX yaw (rad) and its rate (rad/s).
        dt: time since the previous call (s); the integral is updated only for 0 < dt <= dt_max.
        params: packed parameters (``pack_high_level_params``), shape (HL_N_PARAMS,).
        integ: integral of the position error (m s), shape (3,), updated in place.
        out: shape (HL_N_OUT,): thrust (N), w_cmd_B (rad/s, 3), q_WB_des (x, y, z, w).

    Returns:
        True when the inputs and outputs are finite.

    One kernel: the steps hand each other the thrust vector as clipped, whether its vertical part was floored,
    c_ref and three rotation matrices (R, R_ref, R_des); the flatness feed-forward and the frame from the
    thrust vector are already @njit helpers (``_flat_state``, ``_frame_from_thrust_vector``), and what is left
    reads top to bottom as the paper's steps. A further split would pass those arrays and flags through more
    calls at every control tick for no gain in clarity.
    """
    R = np.empty((3, 3))
    R_ref = np.empty((3, 3))
    R_des = np.empty((3, 3))
    f_ref = np.empty(3)
    w_ref = np.empty(3)
    # q copied to a writable array: the messages' q is read-only, the ego filter's is not, and numba would
    # compile quat_to_R once for each
    qw = np.empty(4)
    for k in range(4):
        qw[k] = q[k]
    quat_to_R(qw, R)
    d = params[HL_DRAG : HL_DRAG + 3]

    # Feed-forward: attitude, thrust vector and body rates of the reference (flatness, with drag).
    c_ref = _flat_state(a_ref, v_ref, j_ref, yaw_ref, yaw_rate_ref, d, R_ref, f_ref, w_ref)

    # Step 1-2: f_des = a_ref + K_p e_p + K_v e_v + K_i int(e_p) - g + R_ref D R_ref^T v_ref.
    f = np.empty(3)
    ilim = params[HL_I_LIM]
    for k in range(3):
        ik = params[HL_KI + k] * integ[k]
        ik = min(max(ik, -ilim), ilim)
        f[k] = f_ref[k] + params[HL_KP + k] * (p_ref[k] - p[k]) + params[HL_KV + k] * (v_ref[k] - v[k]) + ik

    # Step 3: limits with the vertical part first, then the horizontal part within the tilt cone and the
    # thrust that is left, so that an aggressive correction never costs altitude.
    saturated = False
    fz_min = params[HL_FZ_MIN]
    c_max = params[HL_C_MAX]
    floored = False
    if f[2] < fz_min:
        f[2] = fz_min
        saturated = True
        floored = True
    elif f[2] > c_max:
        f[2] = c_max
        saturated = True
    h_max = min(f[2] * params[HL_TAN_TILT], math.sqrt(max(c_max * c_max - f[2] * f[2], 0.0)))
    h = math.sqrt(f[0] * f[0] + f[1] * f[1])
    if h > h_max:
        f[0] *= h_max / h
        f[1] *= h_max / h
        saturated = True

    # Conditional integration (anti-windup): freeze while the thrust vector is clipped, clamp otherwise.
    if not saturated and dt > 0.0 and dt <= params[HL_DT_MAX]:
        for k in range(3):
            ki = params[HL_KI + k]
            if ki > 0.0:
                integ[k] += (p_ref[k] - p[k]) * dt
                lim = ilim / ki
                integ[k] = min(max(integ[k], -lim), lim)

    _frame_from_thrust_vector(f, yaw_ref, R_des)

    # Collective thrust along the CURRENT z_B: no climb while the vehicle is still tilting.
    c_cmd = f[0] * R[0, 2] + f[1] * R[1, 2] + f[2] * R[2, 2]
    thrust = min(max(params[HL_MASS] * c_cmd, params[HL_T_MIN]), params[HL_T_MAX])

    # Step 4: tilt-prioritised attitude error (Faessler 2017). q_e rotates B into B_des:
    # R_e = R^T R_des = R_tilt R_yaw, q_e = q_tilt (x) q_yaw with q_tilt = (a_x, a_y, 0, a_w) and
    # q_yaw = (0, 0, sin(psi_e/2), cos(psi_e/2)); so a_w = sqrt(w^2 + z^2).
    Re = np.empty((3, 3))
    for r in range(3):
        for s in range(3):
            Re[r, s] = R[0, r] * R_des[0, s] + R[1, r] * R_des[1, s] + R[2, r] * R_des[2, s]
    qe = np.empty(4)
    R_to_quat(Re, qe)  # w >= 0: the shorter way round
    aw = math.sqrt(qe[3] * qe[3] + qe[2] * qe[2])
    if aw > 1e-9:
        tx = (qe[3] * qe[0] - qe[2] * qe[1]) / aw
        ty = (qe[3] * qe[1] + qe[2] * qe[0]) / aw
        yz = qe[2] / aw
    else:  # tilt error of 180 deg: the yaw part is undefined, correct the tilt only
        tx, ty, yz = qe[0], qe[1], 0.0
    k_tilt = params[HL_K_TILT]
    k_yaw = params[HL_K_YAW]

    # Feed-forward rates are those of B_ref; express them in the current B.
    wW0 = R_ref[0, 0] * w_ref[0] + R_ref[0, 1] * w_ref[1] + R_ref[0, 2] * w_ref[2]
    wW1 = R_ref[1, 0] * w_ref[0] + R_ref[1, 1] * w_ref[1] + R_ref[1, 2] * w_ref[2]
    wW2 = R_ref[2, 0] * w_ref[0] + R_ref[2, 1] * w_ref[1] + R_ref[2, 2] * w_ref[2]
    lim = params[HL_RATE_LIM]
    ok = math.isfinite(c_cmd)  # before the clamps, which could hide a NaN
    # The feed-forward rates are the rates of the reference's attitude, |j_perp| / c_ref. When step 3 had
    # to raise the vertical part to its floor, the commanded thrust vector is not the reference's, and
    # its direction turns at |j_perp| / |f| for the same jerk: the rates are rescaled by c_ref / |f|.
    # Where the reference asks for nearly free fall, c_ref is small and its own rates are huge: fed in
    # full they tipped a Matrice 100 over (12 m/s wind, a descent from a climb's overshoot: 65 deg of
    # tilt, then a flip). Never scaled up: on a deck the floor binds through the feedback (the descent
    # reference goes on below the deck) with c_ref near g, and the reference's rates stay as they are.
    # A tilt-cone clip keeps them too: dropping them there slowed a take-off's chase of a 6 m/s platform
    # (the pad seen 0.3 s later on 5 of 20 brake seeds).
    ff = 1.0
    if floored:
        f_norm = math.sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2])
        ff = min(1.0, c_ref / f_norm)
    for k in range(3):
        wff = ff * (R[0, k] * wW0 + R[1, k] * wW1 + R[2, k] * wW2)
        if k == 0:
            wfb = 2.0 * k_tilt * tx
        elif k == 1:
            wfb = 2.0 * k_tilt * ty
        else:
            wfb = 2.0 * k_yaw * yz
        wk = min(max(wff + wfb, -lim), lim)
        ok = ok and math.isfinite(wff + wfb)
        out[1 + k] = wk
    out[0] = thrust
    qd = np.empty(4)
    R_to_quat(R_des, qd)
    for i in range(4):  # by element: numba compiles a slice assignment's error message (~1 s)
        out[4 + i] = qd[i]
    return ok


@njit(cache=True)
def _attitude_kernel(
    a: FloatArray,
    v: FloatArray,
    j: FloatArray,
    yaw: float,
    yaw_rate: float,
    d: FloatArray,
    R: FloatArray,
    w: FloatArray,
) -> float:
    f = np.empty(3)
    return _flat_state(a, v, j, yaw, yaw_rate, d, R, f, w)


# --------------------------------------------------------------------------------------------------
# Pure flatness functions (Python API over the kernels)
# --------------------------------------------------------------------------------------------------


def _vec3(x: object, name: str) -> FloatArray:
    arr = np.array(x, dtype=np.float64)  # a writable copy: one compiled specialisation for all callers
    if arr.shape != (3,) or not np.isfinite(arr).all():
        raise ValueError(f"{name} must be a finite array of shape (3,), got {arr!r}")
    return arr


def _flat(
    a: object,
    yaw: float,
    j: object,
    yaw_rate: float,
    v_W: object | None,
    rotor_drag: tuple[float, float, float] | None,
) -> tuple[FloatArray, float, FloatArray]:
    a_ = _vec3(a, "a")
    j_ = _vec3(j, "j")
    v_ = np.zeros(3) if v_W is None else _vec3(v_W, "v_W")
    d_ = np.zeros(3) if rotor_drag is None else _vec3(rotor_drag, "rotor_drag")
    if not (math.isfinite(yaw) and math.isfinite(yaw_rate)):
        raise ValueError("yaw and yaw_rate must be finite")
    if a_[0] == 0.0 and a_[1] == 0.0 and a_[2] <= -_G:
        raise ValueError(f"a = {a_} leaves no thrust direction (free fall or faster downwards)")
    R = np.empty((3, 3))
    w = np.empty(3)
    c = _attitude_kernel(a_, v_, j_, float(yaw), float(yaw_rate), d_, R, w)
    if not (np.isfinite(R).all() and np.isfinite(w).all()):
        raise ValueError("the thrust direction is horizontal along the heading's normal: yaw undefined")
    return R, float(c), w


def attitude_from_accel_yaw(
    a: object, yaw: float, *, v_W: object | None = None, rotor_drag: tuple[float, float, float] | None = None
) -> tuple[FloatArray, float]:
    """Attitude and mass-normalised collective thrust that produce the acceleration ``a`` at yaw ``yaw``.

    Args:
        a: acceleration in W (m/s^2), shape (3,).
        yaw: ZYX heading (rad); ``alight.types.yaw_of`` of the result equals it.
        v_W: velocity in W (m/s), shape (3,), only used with ``rotor_drag``.
        rotor_drag: mass-normalised rotor-drag coefficients (d_x, d_y, d_z) (1/s); None for no drag.

    Returns:
        (R_WB, c): rotation matrix, shape (3, 3), and collective thrust c = |a - g + R D R^T v| (m/s^2).
    """
    R, c, _ = _flat(a, yaw, np.zeros(3), 0.0, v_W, rotor_drag)
    return R, c


def body_rates_from_jerk(
    a: object,
    j: object,
    yaw: float,
    yaw_rate: float,
    *,
    v_W: object | None = None,
    rotor_drag: tuple[float, float, float] | None = None,
) -> FloatArray:
    """Body rates w_WB_B (rad/s, shape (3,)) along a flat trajectory with acceleration ``a`` (m/s^2),
    jerk ``j`` (m/s^3), yaw (rad) and yaw rate (rad/s), for the attitude of ``attitude_from_accel_yaw``.
    With ``rotor_drag`` (1/s) the velocity ``v_W`` (m/s) enters the thrust vector and its derivative."""
    _, _, w = _flat(a, yaw, j, yaw_rate, v_W, rotor_drag)
    return w


# --------------------------------------------------------------------------------------------------
# Gains and the thin stateful shell
# --------------------------------------------------------------------------------------------------


def _triple(x: object, name: str) -> tuple[float, float, float]:
    t = tuple(float(v) for v in np.broadcast_to(np.asarray(x, dtype=np.float64), (3,)))
    if not all(math.isfinite(v) for v in t):
        raise ValueError(f"{name} must be finite, got {t}")
    return (t[0], t[1], t[2])


@dataclass(frozen=True, kw_only=True)
class HighLevelGains:
    """Gains and limits of ``HighLevelController``. Defaults suit the default ``Airframe``: position loop
    critically damped at 2 rad/s per axis, tilt time constant 0.12 s (about 4x faster than the position
    loop, with the body-rate loop another ~3x faster), yaw time constant 0.3 s.

    The integral is off by default: with the rotor drag compensated and the thrust projected on the
    current body axis, the nominal vehicle has no steady-state error at hover, and an integrator on the
    position of a reference that is replanned at 50 Hz towards a moving pad mainly adds lag (phase margin)
    and overshoot at touchdown. Turn it on (``ki``) for a wrong mass, steady wind or a thrust-model error;
    it is then clamped and frozen while the thrust vector saturates (anti-windup).
    """

    kp: tuple[float, float, float] = (4.0, 4.0, 4.0)
    """Position gains K_p per W axis (1/s^2); omega_n = sqrt(kp)."""
    kv: tuple[float, float, float] = (4.0, 4.0, 4.0)
    """Velocity gains K_v per W axis (1/s); zeta = kv / (2 sqrt(kp))."""
    ki: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Integral gains K_i on the position error per W axis (1/s^3); 0 disables. Needs ki < kp kv."""
    integral_limit: float = 2.0
    """Largest integral contribution to the acceleration per axis (m/s^2)."""
    integral_dt_max: float = 0.1
    """Longest time step the integral accepts (s); after a longer gap the step is not integrated."""
    tau_tilt: float = 0.12
    """Time constant of the tilt (roll/pitch) error feedback (s)."""
    tau_yaw: float = 0.3
    """Time constant of the yaw error feedback (s)."""
    max_tilt: float | None = None
    """Largest angle between the commanded thrust and the world z axis (rad), in (0, pi/2); None: the
    airframe's ``max_tilt_rad`` (45 deg for the default F450), so that the vehicle's own limit, not a
    controller constant, decides how much wind it can lean into."""
    min_vertical_accel: float = 2.0
    """Lowest vertical part of the commanded thrust vector (m/s^2): keeps the vehicle upright."""
    rotor_drag_compensation: bool = True
    """Feed forward the rotor-drag acceleration of the reference (Faessler 2018) with Airframe.rotor_drag."""
    body_rate_limit: float = 10.0
    """Per-axis limit of the body-rate command (rad/s)."""

    def __post_init__(self) -> None:
        kp = _triple(self.kp, "kp")
        kv = _triple(self.kv, "kv")
        ki = _triple(self.ki, "ki")
        object.__setattr__(self, "kp", kp)
        object.__setattr__(self, "kv", kv)
        object.__setattr__(self, "ki", ki)
        # The closed loop per axis is s^3 + kv s^2 + kp s + ki (s^2 + kv s + kp without the integral):
        # Hurwitz iff kp, kv > 0 and 0 <= ki < kp kv.
        for k in range(3):
            if not (kp[k] > 0 and kv[k] > 0):
                raise ValueError(
                    f"kp and kv must be positive (positive-definite gain matrices), got {kp}, {kv}"
                )
            if not (0.0 <= ki[k] < kp[k] * kv[k]):
                raise ValueError(f"ki must satisfy 0 <= ki < kp kv (Routh-Hurwitz), got ki={ki}")
        for name in (
            "integral_limit",
            "integral_dt_max",
            "tau_tilt",
            "tau_yaw",
            "min_vertical_accel",
            "body_rate_limit",
        ):
            val = getattr(self, name)
            if not (math.isfinite(val) and val > 0):
                raise ValueError(f"{name} must be positive and finite, got {val}")
        if self.max_tilt is not None and not (0.0 < self.max_tilt < math.pi / 2):
            raise ValueError(f"max_tilt must be in (0, pi/2) rad, got {self.max_tilt}")

    @classmethod
    def from_bandwidth(cls, omega_n: float, zeta: float = 1.0, **kwargs: object) -> HighLevelGains:
        """Gains for a position loop with natural frequency ``omega_n`` (rad/s) and damping ``zeta``."""
        if not (omega_n > 0 and zeta > 0):
            raise ValueError(f"omega_n and zeta must be positive, got {omega_n}, {zeta}")
        kp = omega_n * omega_n
        kv = 2.0 * zeta * omega_n
        return cls(kp=(kp, kp, kp), kv=(kv, kv, kv), **kwargs)  # type: ignore[arg-type]


def pack_high_level_params(airframe: Airframe, gains: HighLevelGains) -> FloatArray:
    """Parameter vector of ``high_level_kernel``, shape (HL_N_PARAMS,)."""
    t_min = 4.0 * airframe.motor_thrust_min_N
    t_max = 4.0 * airframe.motor_thrust_max_N
    c_max = t_max / airframe.mass
    if gains.min_vertical_accel >= c_max:
        raise ValueError(
            f"min_vertical_accel {gains.min_vertical_accel} must be below the largest "
            f"collective thrust {c_max:.3f} m/s^2 of the airframe"
        )
    p = np.zeros(HL_N_PARAMS)
    p[HL_KP : HL_KP + 3] = gains.kp
    p[HL_KV : HL_KV + 3] = gains.kv
    p[HL_KI : HL_KI + 3] = gains.ki
    p[HL_I_LIM] = gains.integral_limit
    p[HL_K_TILT] = 1.0 / gains.tau_tilt
    p[HL_K_YAW] = 1.0 / gains.tau_yaw
    p[HL_TAN_TILT] = math.tan(airframe.max_tilt_rad if gains.max_tilt is None else gains.max_tilt)
    p[HL_FZ_MIN] = gains.min_vertical_accel
    p[HL_C_MAX] = c_max
    p[HL_MASS] = airframe.mass
    if gains.rotor_drag_compensation:
        p[HL_DRAG : HL_DRAG + 3] = airframe.rotor_drag
    p[HL_RATE_LIM] = gains.body_rate_limit
    p[HL_T_MIN] = t_min
    p[HL_T_MAX] = t_max
    p[HL_DT_MAX] = gains.integral_dt_max
    return p


_RO = types.Array(types.float64, 1, "C", readonly=True)
_RW = types.Array(types.float64, 1, "C")
_MESSAGE_SIG = (_RO,) * 7 + (types.float64,) * 3 + (_RW,) * 3
"""``high_level_kernel``'s argument types when it is fed ``EgoState`` / ``Reference`` arrays (read-only
C-contiguous float64, shapes checked by the messages) and the controller's own buffers."""


def _message_entry_point() -> Callable[..., bool]:
    """The compiled kernel for ``_MESSAGE_SIG``. Calling it directly skips the dispatcher's type
    resolution, which costs ~0.2-0.4 us per argument (13 here), i.e. more than the arithmetic (~1 us).
    Safe because the messages guarantee the types; anything else goes through the dispatcher."""
    try:
        return high_level_kernel.compile(_MESSAGE_SIG)
    except Exception:  # pragma: no cover - a numba without Dispatcher.compile returning the entry point
        return high_level_kernel


class HighLevelController:
    """Faessler-style high-level controller (module docstring). ``command`` costs a few microseconds.

    State: the position-error integral (only used when ``gains.ki`` is non-zero) and the time of the
    previous call. The last desired attitude is kept for logging in ``q_WB_des``.
    """

    def __init__(self, airframe: Airframe = DEFAULT_AIRFRAME, gains: HighLevelGains | None = None) -> None:
        self.airframe = airframe
        self.gains = gains if gains is not None else HighLevelGains(tau_tilt=tilt_time_constant_s(airframe))
        self.params = pack_high_level_params(airframe, self.gains)
        self._tan_tilt_own = float(self.params[HL_TAN_TILT])
        self._integ = np.zeros(3)
        self._out = np.zeros(HL_N_OUT)
        self._t_last = math.nan
        self._kernel = _message_entry_point()

    def reset(self) -> None:
        """Forget the integral and the time of the last call (e.g. at a mode change)."""
        self._integ[:] = 0.0
        self._t_last = math.nan

    def set_tilt_limit(self, max_tilt_rad: float | None) -> None:
        """Limit the tilt of the commands to ``max_tilt_rad`` (rad), never above the controller's own
        limit; None: the own limit again (:class:`~alight.control.TiltLimited`)."""
        if max_tilt_rad is None:
            self.params[HL_TAN_TILT] = self._tan_tilt_own
            return
        if not (0.0 < max_tilt_rad < math.pi / 2):
            raise ValueError(f"max_tilt_rad must be in (0, pi/2) rad, got {max_tilt_rad}")
        self.params[HL_TAN_TILT] = min(math.tan(max_tilt_rad), self._tan_tilt_own)

    @property
    def q_WB_des(self) -> FloatArray:
        """Desired attitude of the last command, (x, y, z, w), shape (4,)."""
        return self._out[4:8].copy()

    @property
    def integral(self) -> FloatArray:
        """Integral of the position error (m s), shape (3,)."""
        return self._integ.copy()

    def command(self, ego: EgoState, ref: Reference) -> Command:
        """Collective thrust (N) and body-rate command (rad/s, B) at time ``ego.t``."""
        t = ego.t
        dt = t - self._t_last  # NaN on the first call: no integration
        self._t_last = t
        out = self._out
        ok = self._kernel(
            ego.p_WB,
            ego.v_WB,
            ego.q_WB,
            ref.p,
            ref.v,
            ref.a,
            ref.j,
            float(ref.yaw),
            float(ref.yaw_rate),
            float(dt),
            self.params,
            self._integ,
            out,
        )
        if not ok:
            raise ValueError(f"non-finite controller output at t={t}: check the ego state and reference")
        return Command.trusted(t, out[0], out[1:4])
