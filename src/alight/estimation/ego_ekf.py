"""Ego-state error-state EKF: IMU at 200 Hz fused with VIO-like odometry at 40 Hz (paper 000 Sec. II-A).

Paper 000 fuses 40 Hz pose estimates of its visual-inertial odometry with a 200 Hz IMU in an EKF (its
ref. [21]) but gives no equations; this is the standard error-state formulation (J. Sola, "Quaternion
kinematics for the error-state Kalman filter", 2017, Sec. 5-7) with the attitude error taken locally
(in B), as used in the VIO literature the paper builds on.

Nominal state ``x`` (16,): ``p_WB`` (0:3), ``v_WB`` (3:6), ``q_WB`` (6:10, x y z w), accelerometer
bias ``b_a`` (10:13), gyro bias ``b_g`` (13:16).
Error state ``dx`` (15,): ``dp`` (0:3), ``dv`` (3:6), ``dtheta`` (6:9, ``R_WB = R_nom Exp(dtheta)``),
``db_a`` (9:12), ``db_g`` (12:15).

IMU model (g_W = (0, 0, -g)):
    f_B = R_WB^T (a_WB - g_W) + b_a + n_a,      w_B = w_WB_B + b_g + n_g,
    d(b_a)/dt = n_ba,  d(b_g)/dt = n_bg          (white noises given as densities).

Discretisation: an IMU sample is the value at its time stamp, so the interval between two samples is
integrated with their mean (trapezoid), and the acceleration is rotated with the mid-interval attitude.
This is second-order accurate, where using one end sample (zero-order hold) is first-order: at 200 Hz
and 1 rad/s^2 of angular acceleration the hold costs ~1e-5 rad per step, comparable with the gyro noise
between two odometry updates. ``F`` below is the exact Jacobian of this discrete map (checked against
finite differences in the tests), not the usual first-order ``I + A dt``.

Non-finite inputs (IMU sample, odometry, time) raise :class:`alight.errors.EstimationError` and leave
the filter untouched: they come from a broken sensor driver or a bug upstream, and silently skipping them
would hide that. The caller (the pipeline) decides whether to skip the sample and carry on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from alight.errors import EstimationError, MeasurementError
from alight.estimation.guards import (
    FUTURE_TOLERANCE_S,
    GATE_SIGMA,
    MAX_HORIZON_S,
    MAX_POSITION_M,
    MAX_SPEED_MPS,
    StampRun,
    bounded_steps,
    check_clock,
    check_real_inputs,
    check_time,
    check_times,
    check_vector,
    imu_plausible,
    plausible_velocity,
)
from alight.numerics.linalg import chol_solve
from alight.numerics.rotation import quat_exp, quat_log, quat_mul, quat_to_R
from alight.types import GRAVITY_MPS2, EgoState, FloatArray

IMU_RUN = 20
"""IMU samples in a row, in order among themselves, that make :meth:`EgoEkf.predict_imu` believe a jump of
the IMU clock beyond ``FUTURE_TOLERANCE_S`` (0.1 s of a 200 Hz IMU; :class:`~.guards.StampRun`)."""
ODOMETRY_RUN = 10
"""Odometry messages in a row, in order among themselves, that make :meth:`EgoEkf.update_odometry` believe
a jump of the filter's clock beyond ``FUTURE_TOLERANCE_S`` before the filter has propagated (0.25 s at
40 Hz)."""

# status codes shared by the kernels of this subpackage
OK = 0
NOT_FINITE = 1
NOT_POSITIVE_DEFINITE = 2

# --------------------------------------------------------------------------------------------------
# Small linear algebra and SO(3) helpers (numba). Hand-written loops: the matrices are at most 15x15,
# where a BLAS call costs more than the arithmetic. The Cholesky solve and the quaternion product,
# exponential and logarithm are alight.numerics'.
# --------------------------------------------------------------------------------------------------


@njit(cache=True)
def _skew(v: FloatArray, out: FloatArray) -> None:
    out[0, 0] = 0.0
    out[0, 1] = -v[2]
    out[0, 2] = v[1]
    out[1, 0] = v[2]
    out[1, 1] = 0.0
    out[1, 2] = -v[0]
    out[2, 0] = -v[1]
    out[2, 1] = v[0]
    out[2, 2] = 0.0


@njit(cache=True)
def _mm(A: FloatArray, B: FloatArray, out: FloatArray) -> None:
    """``out = A @ B`` by loops (numba's ``@`` calls BLAS, whose per-call cost dominates at these sizes)."""
    n, k = A.shape
    m = B.shape[1]
    for i in range(n):
        for j in range(m):
            s = 0.0
            for q in range(k):
                s += A[i, q] * B[q, j]
            out[i, j] = s


@njit(cache=True)
def _mmt(A: FloatArray, B: FloatArray, out: FloatArray) -> None:
    """``out = A @ B.T`` by loops."""
    n, k = A.shape
    m = B.shape[0]
    for i in range(n):
        for j in range(m):
            s = 0.0
            for q in range(k):
                s += A[i, q] * B[j, q]
            out[i, j] = s


@njit(cache=True)
def _mv(A: FloatArray, v: FloatArray, out: FloatArray) -> None:
    """``out = A @ v`` by loops."""
    n, k = A.shape
    for i in range(n):
        s = 0.0
        for q in range(k):
            s += A[i, q] * v[q]
        out[i] = s


@njit(cache=True)
def so3_right_jacobian(phi: FloatArray, J: FloatArray) -> None:
    """Right Jacobian of SO(3): ``Exp(phi + d) ~= Exp(phi) Exp(J_r(phi) d)``."""
    th2 = phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]
    th = math.sqrt(th2)
    if th < 1e-4:
        a = 0.5 - th2 / 24.0  # (1 - cos th) / th^2
        b = 1.0 / 6.0 - th2 / 120.0  # (th - sin th) / th^3
    else:
        a = (1.0 - math.cos(th)) / th2
        b = (th - math.sin(th)) / (th2 * th)
    K = np.empty((3, 3))
    _skew(phi, K)
    for i in range(3):
        for j in range(3):
            kk = K[i, 0] * K[0, j] + K[i, 1] * K[1, j] + K[i, 2] * K[2, j]
            J[i, j] = (1.0 if i == j else 0.0) - a * K[i, j] + b * kk


@njit(cache=True)
def so3_left_jacobian_inv(phi: FloatArray, J: FloatArray) -> None:
    """Inverse left Jacobian of SO(3): ``Log(Exp(d) Exp(phi)) ~= phi + J_l^{-1}(phi) d``."""
    th2 = phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]
    th = math.sqrt(th2)
    if th < 1e-4:
        c = 1.0 / 12.0 + th2 / 720.0
    else:
        c = 1.0 / th2 - (1.0 + math.cos(th)) / (2.0 * th * math.sin(th))
    K = np.empty((3, 3))
    _skew(phi, K)
    for i in range(3):
        for j in range(3):
            kk = K[i, 0] * K[0, j] + K[i, 1] * K[1, j] + K[i, 2] * K[2, j]
            J[i, j] = (1.0 if i == j else 0.0) - 0.5 * K[i, j] + c * kk


# --------------------------------------------------------------------------------------------------
# Process model
# --------------------------------------------------------------------------------------------------


@njit(cache=True)
def ego_step(x: FloatArray, f_B: FloatArray, w_B: FloatArray, dt: float, g: float, out: FloatArray) -> None:
    """Nominal state after ``dt`` (s) with the interval's mean specific force ``f_B`` (m/s^2) and rate
    ``w_B`` (rad/s), shapes (3,). ``x``, ``out`` (16,), may not alias."""
    om = np.empty(3)
    ab = np.empty(3)
    for i in range(3):
        om[i] = (w_B[i] - x[13 + i]) * dt
        ab[i] = f_B[i] - x[10 + i]
    dq = np.empty(4)
    qh = np.empty(4)
    half = 0.5 * om
    quat_exp(half, dq)
    quat_mul(x[6:10], dq, qh)
    Rh = np.empty((3, 3))
    quat_to_R(qh, Rh)
    a = np.empty(3)
    _mv(Rh, ab, a)
    a[2] -= g
    for i in range(3):
        out[i] = x[i] + x[3 + i] * dt + 0.5 * a[i] * dt * dt
        out[3 + i] = x[3 + i] + a[i] * dt
    quat_exp(om, dq)
    quat_mul(x[6:10], dq, out[6:10])
    n = math.sqrt(out[6] ** 2 + out[7] ** 2 + out[8] ** 2 + out[9] ** 2)
    for i in range(6, 10):
        out[i] /= n
    for i in range(10, 16):
        out[i] = x[i]


@njit(cache=True)
def ego_error_jacobian(x: FloatArray, f_B: FloatArray, w_B: FloatArray, dt: float, F: FloatArray) -> None:
    """Exact Jacobian ``F`` (15, 15) of the error state through :func:`ego_step`.

    With ``w = w_B - b_g``, ``a_b = f_B - b_a``, ``dR = Exp(w dt)``, ``dR_h = Exp(w dt / 2)``,
    ``R_h = R dR_h`` and ``a = R_h a_b + g_W``:
    ``da/dtheta = -R [dR_h a_b]x``, ``da/db_a = -R_h``, ``da/db_g = R_h [a_b]x J_r(w dt/2) dt/2``,
    ``dtheta'/dtheta = dR^T``, ``dtheta'/db_g = -J_r(w dt) dt``; ``p`` and ``v`` take ``a dt^2/2`` and
    ``a dt``.
    """
    om = np.empty(3)
    ab = np.empty(3)
    for i in range(3):
        om[i] = (w_B[i] - x[13 + i]) * dt
        ab[i] = f_B[i] - x[10 + i]
    half = 0.5 * om
    dqh = np.empty(4)
    quat_exp(half, dqh)
    dRh = np.empty((3, 3))
    quat_to_R(dqh, dRh)
    R = np.empty((3, 3))
    quat_to_R(x[6:10], R)
    Rh = np.empty((3, 3))
    _mm(R, dRh, Rh)
    y = np.empty(3)
    _mv(dRh, ab, y)
    Sy = np.empty((3, 3))
    _skew(y, Sy)
    da_dth = np.empty((3, 3))
    _mm(R, Sy, da_dth)  # sign applied below
    Sab = np.empty((3, 3))
    _skew(ab, Sab)
    Jh = np.empty((3, 3))
    so3_right_jacobian(half, Jh)
    T = np.empty((3, 3))
    _mm(Rh, Sab, T)
    da_dbg = np.empty((3, 3))
    _mm(T, Jh, da_dbg)  # times dt/2 below
    dq = np.empty(4)
    quat_exp(om, dq)
    dR = np.empty((3, 3))
    quat_to_R(dq, dR)
    J = np.empty((3, 3))
    so3_right_jacobian(om, J)

    F[:, :] = 0.0
    for i in range(15):
        F[i, i] = 1.0
    h2 = 0.5 * dt * dt
    for i in range(3):
        F[i, 3 + i] = dt
        for j in range(3):
            F[i, 6 + j] = -h2 * da_dth[i, j]
            F[i, 9 + j] = -h2 * Rh[i, j]
            F[i, 12 + j] = h2 * 0.5 * dt * da_dbg[i, j]
            F[3 + i, 6 + j] = -dt * da_dth[i, j]
            F[3 + i, 9 + j] = -dt * Rh[i, j]
            F[3 + i, 12 + j] = dt * 0.5 * dt * da_dbg[i, j]
            F[6 + i, 6 + j] = dR[j, i]
            F[6 + i, 12 + j] = -dt * J[i, j]


@njit(cache=True)
def _propagate_cov(P: FloatArray, F: FloatArray, q: FloatArray, dt: float, FP: FloatArray) -> None:
    """``P <- F P F^T + Q`` in place, using that ``F`` is block upper triangular and mostly zero.

    ``q`` = (accel noise density, gyro noise density, accel bias walk, gyro bias walk). The IMU noise of
    a sample is constant over its interval, so ``dv = n_a dt``, ``dp = n_a dt^2/2`` with
    ``Var(n_a) = sigma_a^2 / dt`` (rotation by ``R_h`` does not change an isotropic covariance).
    """
    # F is block upper triangular: row i has no entries left of its own 3x3 block
    for i in range(15):
        for j in range(15):
            FP[i, j] = 0.0
    for i in range(15):
        k0 = (i // 3) * 3
        for k in range(k0, 15):
            f = F[i, k]
            if f != 0.0:
                for j in range(15):
                    FP[i, j] += f * P[k, j]
    # P = FP F^T, upper triangle then mirror
    for i in range(15):
        for j in range(i, 15):
            P[i, j] = 0.0
    for j in range(15):
        k0 = (j // 3) * 3
        for k in range(k0, 15):
            f = F[j, k]
            if f != 0.0:
                for i in range(j + 1):
                    P[i, j] += FP[i, k] * f
    sa2 = q[0] * q[0]
    qpp = 0.25 * dt * dt * dt * sa2
    qpv = 0.5 * dt * dt * sa2
    qvv = dt * sa2
    qth = dt * q[1] * q[1]
    qba = dt * q[2] * q[2]
    qbg = dt * q[3] * q[3]
    for i in range(3):
        P[i, i] += qpp
        P[i, 3 + i] += qpv
        P[3 + i, 3 + i] += qvv
        P[6 + i, 6 + i] += qth
        P[9 + i, 9 + i] += qba
        P[12 + i, 12 + i] += qbg
    for i in range(15):
        for j in range(i + 1, 15):
            P[j, i] = P[i, j]


@njit(cache=True)
def ego_predict_kernel(
    x: FloatArray, P: FloatArray, imu: FloatArray, params: FloatArray, dt: float, max_step: float
) -> int:
    """Propagate ``x`` (16,), ``P`` (15, 15) in place over ``dt`` (s) >= 0.

    ``imu`` (12,): previous sample ``f_B, w_B`` (0:6) and the new one (6:12); on success the new sample
    is copied into the previous slot. ``params`` (5,): the four noise densities and ``g``. Gaps longer than
    ``max_step`` are split, with the samples interpolated linearly. Returns a status code and changes
    nothing unless it is ``OK``.
    """
    if not imu_plausible(imu, 6):  # alight.estimation.guards: finite and within an airframe's range
        return NOT_FINITE
    n = bounded_steps(dt, max_step)
    h = dt / n
    F = np.empty((15, 15))
    FP = np.empty((15, 15))
    xn = np.empty(16)
    fm = np.empty(3)
    wm = np.empty(3)
    for s in range(n):
        # mean of the linearly interpolated samples at the ends of this sub-interval
        c = (s + 0.5) / n
        for i in range(3):
            fm[i] = imu[i] + c * (imu[6 + i] - imu[i])
            wm[i] = imu[3 + i] + c * (imu[9 + i] - imu[3 + i])
        if h > 0.0:
            ego_error_jacobian(x, fm, wm, h, F)
            ego_step(x, fm, wm, h, params[4], xn)
            # by element: numba compiles a slice assignment's error message (~1 s)
            for i in range(x.shape[0]):
                x[i] = xn[i]
            _propagate_cov(P, F, params, h, FP)
    for i in range(6):
        imu[i] = imu[6 + i]
    return OK


@njit(cache=True)
def ego_predict_many_kernel(
    x: FloatArray,
    P: FloatArray,
    imu: FloatArray,
    params: FloatArray,
    t0: float,
    ts: FloatArray,
    fs: FloatArray,
    ws: FloatArray,
    n: int,
    max_step: float,
) -> int:
    """:func:`ego_predict_kernel` over the first ``n`` samples ``ts`` (s), ``fs``, ``ws`` ((n, 3) each)
    from the filter time ``t0``, in one compiled call. Returns -1 when all went through; else the index
    ``k`` of the first sample that is not finite or beyond an airframe's range, or ``-(k + 2)`` when sample
    ``k`` is earlier than the one before (or than ``t0``), more than ``FUTURE_TOLERANCE_S`` after it, or
    not finite in time; the samples before it were applied."""
    t = t0
    for k in range(n):
        if not (t <= ts[k] <= t + FUTURE_TOLERANCE_S):  # guards (left to predict_imu's rule); also NaN
            return -(k + 2)
        for i in range(3):
            imu[6 + i] = fs[k, i]
            imu[9 + i] = ws[k, i]
        status = ego_predict_kernel(x, P, imu, params, ts[k] - t, max_step)
        if status != OK:
            return k
        t = ts[k]
    return -1


# --------------------------------------------------------------------------------------------------
# Odometry update
# --------------------------------------------------------------------------------------------------


@njit(cache=True)
def odometry_residual(x: FloatArray, z: FloatArray, m: int, r: FloatArray) -> None:
    """Residual ``z - h(x)`` (m,) of an odometry measurement ``z`` (10,) = p (3), q (4), v (3).

    Position and velocity are differences; attitude is ``Log(R^T R_z)`` (rad, in B), since the
    measured attitude is modelled as ``R_z = R_WB Exp(n_theta)``.
    """
    qi = np.empty(4)
    qi[0] = -x[6]
    qi[1] = -x[7]
    qi[2] = -x[8]
    qi[3] = x[9]
    qe = np.empty(4)
    quat_mul(qi, z[3:7], qe)
    n = math.sqrt(qe[0] ** 2 + qe[1] ** 2 + qe[2] ** 2 + qe[3] ** 2)
    for i in range(4):
        qe[i] /= n
    quat_log(qe, r[3:6])
    for i in range(3):
        r[i] = z[i] - x[i]
    if m == 9:
        for i in range(3):
            r[6 + i] = z[7 + i] - x[3 + i]


@njit(cache=True)
def odometry_jacobian(r: FloatArray, m: int, H: FloatArray) -> None:
    """Measurement Jacobian ``H`` (m, 15) at the residual ``r``: ``r(x [+] dx) ~= r - H dx``.

    ``Log(Exp(-dtheta) Exp(r_theta)) ~= r_theta - J_l^{-1}(r_theta) dtheta``, so the attitude block is
    ``J_l^{-1}(r_theta)`` (identity for a small residual), keeping the measurement noise untransformed.
    """
    H[:, :] = 0.0
    Jinv = np.empty((3, 3))
    so3_left_jacobian_inv(r[3:6], Jinv)
    for i in range(3):
        H[i, i] = 1.0
        for j in range(3):
            H[3 + i, 6 + j] = Jinv[i, j]
    if m == 9:
        for i in range(3):
            H[6 + i, 3 + i] = 1.0


@njit(cache=True)
def ego_inject(x: FloatArray, dx: FloatArray) -> None:
    """``x <- x [+] dx``: add the error state into the nominal state (attitude on the right)."""
    for i in range(6):
        x[i] += dx[i]
    dq = np.empty(4)
    quat_exp(dx[6:9], dq)
    qn = np.empty(4)
    quat_mul(x[6:10], dq, qn)
    n = math.sqrt(qn[0] ** 2 + qn[1] ** 2 + qn[2] ** 2 + qn[3] ** 2)
    for i in range(4):
        x[6 + i] = qn[i] / n
    for i in range(6):
        x[10 + i] += dx[9 + i]


@njit(cache=True)
def ego_update_kernel(
    x: FloatArray, P: FloatArray, z: FloatArray, Rm: FloatArray, m: int, info: FloatArray
) -> int:
    """Odometry update of ``x`` (16,), ``P`` (15, 15) in place. ``z`` (10,), ``Rm`` (m, m) with m = 6
    (position, attitude) or 9 (+ velocity). ``info[0]`` gets the NIS. Returns a status code; nothing
    changes unless it is ``OK``.

    The covariance update is in Joseph form, ``P = (I - K H) P (I - K H)^T + K R K^T``: it keeps ``P``
    symmetric positive semi-definite under round-off (the short form ``(I - K H) P`` does not, and a
    15-state filter running for 12,000 steps a minute would drift), and it stays right if the gain is
    not exactly optimal (e.g. after the reset Jacobian below).

    One kernel: the 15-state update shares ``H P``, ``S`` with its Cholesky factor (for the gain and the NIS),
    ``K`` and ``A P`` between the gain, the Joseph-form covariance and the reset Jacobian; splitting would
    pass those (15, 15) and (15, m) arrays through more calls at every odometry message (the residual, the
    Jacobian and the error injection are apart already).
    """
    for i in range(10):
        if i < 7 or m == 9:
            if not math.isfinite(z[i]):
                return NOT_FINITE
    for i in range(m):
        for j in range(m):
            if not math.isfinite(Rm[i, j]):
                return NOT_FINITE
    r = np.empty(m)
    odometry_residual(x, z, m, r)
    H = np.empty((m, 15))
    odometry_jacobian(r, m, H)
    HP = np.empty((m, 15))
    _mm(H, P, HP)
    S = np.empty((m, m))
    _mmt(HP, H, S)
    for i in range(m):
        for j in range(m):
            S[i, j] = 0.5 * (S[i, j] + S[j, i]) + Rm[i, j]
    L = np.empty((m, m))
    Kt = np.empty((m, 15))
    if not chol_solve(S, HP, L, Kt):  # S K^T = H P
        return NOT_POSITIVE_DEFINITE
    w = np.empty((m, 1))
    Sr = np.empty((m, 1))
    for i in range(m):
        w[i, 0] = r[i]
    chol_solve(S, w, L, Sr)
    nis = 0.0
    for i in range(m):
        nis += r[i] * Sr[i, 0]
    info[0] = nis
    K = np.ascontiguousarray(Kt.T)
    dx = np.empty(15)
    _mv(K, r, dx)
    # Joseph form with A = I - K H, in the order that uses the already computed H P:
    # A P = P - K (H P);  A P A^T + K R K^T = A P + (K R - (A P) H^T) K^T
    AP = np.empty((15, 15))
    _mm(K, HP, AP)
    for i in range(15):
        for j in range(15):
            AP[i, j] = P[i, j] - AP[i, j]
    M = np.empty((15, m))
    _mmt(AP, H, M)
    KR = np.empty((15, m))
    _mm(K, Rm, KR)
    for i in range(15):
        for j in range(m):
            M[i, j] = KR[i, j] - M[i, j]
    Pn = np.empty((15, 15))
    _mmt(M, K, Pn)
    for i in range(15):
        for j in range(15):
            Pn[i, j] += AP[i, j]
    ego_inject(x, dx)
    # reset Jacobian G = I - [dtheta/2]x on the attitude block (Sola 2017, eq. 287): only the attitude
    # rows and columns change
    G = np.eye(3)
    Sk = np.empty((3, 3))
    _skew(dx[6:9], Sk)
    for i in range(3):
        for j in range(3):
            G[i, j] -= 0.5 * Sk[i, j]
    T = np.empty((3, 15))
    for i in range(3):
        for j in range(15):
            T[i, j] = G[i, 0] * Pn[6, j] + G[i, 1] * Pn[7, j] + G[i, 2] * Pn[8, j]
    for i in range(3):
        for j in range(15):
            Pn[6 + i, j] = T[i, j]
    for i in range(15):
        a0, a1, a2 = Pn[i, 6], Pn[i, 7], Pn[i, 8]
        for j in range(3):
            Pn[i, 6 + j] = a0 * G[j, 0] + a1 * G[j, 1] + a2 * G[j, 2]
    for i in range(15):
        for j in range(15):
            P[i, j] = 0.5 * (Pn[i, j] + Pn[j, i])
    return OK


# --------------------------------------------------------------------------------------------------
# The filter
# --------------------------------------------------------------------------------------------------


def _check_nonneg(name: str, value: float) -> None:
    if not (math.isfinite(value) and value >= 0.0):
        raise ValueError(f"{name} must be finite and >= 0, got {value}")


@njit(cache=True)
def _pack_state(x, imu, has_imu, gravity, out):  # type: ignore[no-untyped-def]
    """The ego state (16,) = p, v, q, w, a from the nominal state and the last IMU sample: body rates are
    the gyro minus its bias, ``a = R (f - b_a) + g``. One compiled call instead of a dozen array ops."""
    for i in range(10):
        out[i] = x[i]
    if not has_imu:
        for i in range(10, 16):
            out[i] = 0.0
        return
    R = np.empty((3, 3))
    quat_to_R(x[6:10], R)
    for i in range(3):
        out[10 + i] = imu[3 + i] - x[13 + i]
    for i in range(3):
        out[13 + i] = R[i, 0] * (imu[0] - x[10]) + R[i, 1] * (imu[1] - x[11]) + R[i, 2] * (imu[2] - x[12])
    out[15] -= gravity


def _mahalanobis2_3(S: list[list[float]], e: list[float]) -> float | None:
    """``e^T S^-1 e`` for a 3x3 ``S`` (nested lists) by its adjugate, in Python floats; None when ``S``
    is singular. The odometry gate's test at 40 Hz, where ``np.linalg.solve`` on a 3x3 matrix cost
    several microseconds of overhead; only compared to a threshold, so the rounding (last bits, not
    LAPACK's) does not matter."""
    (a, b, c), (d, f, g), (h, i, j) = S
    c00, c01, c02 = f * j - g * i, c * i - b * j, b * g - c * f
    c10, c11, c12 = g * h - d * j, a * j - c * h, c * d - a * g
    c20, c21, c22 = d * i - f * h, b * h - a * i, a * f - b * d
    det = a * c00 + b * c10 + c * c20
    if det == 0.0:
        return None
    e0, e1, e2 = e
    x0 = c00 * e0 + c01 * e1 + c02 * e2
    x1 = c10 * e0 + c11 * e1 + c12 * e2
    x2 = c20 * e0 + c21 * e1 + c22 * e2
    return (e0 * x0 + e1 * x1 + e2 * x2) / det


@dataclass(frozen=True, kw_only=True)
class EgoEkfConfig:
    """Noise model and initial uncertainty of :class:`EgoEkf`.

    IMU defaults are those of the ADIS16448 in the EuRoC MAV data set (Burri et al., IJRR 2016), the
    class of IMU on VIO rigs like paper 000's; the odometry defaults are typical of a VIO at 40 Hz.
    """

    accel_noise_density: float = 2.0e-3
    """Accelerometer white noise (m/s^2/sqrt(Hz)); a sample's std is this / sqrt(sample period)."""
    gyro_noise_density: float = 1.6968e-4
    """Gyro white noise (rad/s/sqrt(Hz))."""
    accel_bias_random_walk: float = 3.0e-3
    """Accelerometer bias random walk (m/s^3/sqrt(Hz))."""
    gyro_bias_random_walk: float = 1.9393e-5
    """Gyro bias random walk (rad/s^2/sqrt(Hz))."""
    init_position_std: float = 0.05
    """Initial position std (m)."""
    init_velocity_std: float = 0.1
    """Initial velocity std (m/s)."""
    init_attitude_std: float = 0.02
    """Initial attitude std per axis (rad)."""
    init_accel_bias_std: float = 0.1
    """Initial accelerometer bias std (m/s^2)."""
    init_gyro_bias_std: float = 0.01
    """Initial gyro bias std (rad/s)."""
    odometry_position_std: float = 0.02
    """Default odometry position std (m) when ``update_odometry`` gets no covariance."""
    odometry_attitude_std: float = 0.01
    """Default odometry attitude std per axis (rad)."""
    odometry_velocity_std: float = 0.05
    """Default odometry velocity std (m/s)."""
    max_odometry_lag: float = 0.02
    """Odometry older than the filter time by up to this (s) is moved forward to it (first order, with
    the estimated velocity and body rates); older odometry is rejected and counted."""
    max_step: float = 0.01
    """Longest single propagation step (s); longer IMU gaps are split."""
    odometry_gate: bool = True
    """Refuse odometry whose position innovation is more than ``GATE_SIGMA`` (10) standard deviations from
    the prediction (Mahalanobis, ``P_pp + R_pp``; :mod:`alight.estimation.guards`)."""
    odometry_reset_after: int = 10
    """Gated odometry messages in a row after which the filter restarts at the odometry's pose (the
    estimate, not the odometry, was wrong: e.g. after a bad IMU stretch)."""
    gravity: float = GRAVITY_MPS2
    """Magnitude of gravity (m/s^2)."""

    def __post_init__(self) -> None:
        for name in (
            "accel_noise_density",
            "gyro_noise_density",
            "accel_bias_random_walk",
            "gyro_bias_random_walk",
            "init_position_std",
            "init_velocity_std",
            "init_attitude_std",
            "init_accel_bias_std",
            "init_gyro_bias_std",
            "max_odometry_lag",
        ):
            _check_nonneg(name, getattr(self, name))
        if self.odometry_reset_after < 1:
            raise ValueError(f"odometry_reset_after must be >= 1, got {self.odometry_reset_after}")
        for name in ("odometry_position_std", "odometry_attitude_std", "odometry_velocity_std", "max_step"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{name} must be finite and > 0, got {v}")

    def initial_covariance(self) -> FloatArray:
        """Diagonal initial error-state covariance (15, 15)."""
        s = np.repeat(
            [
                self.init_position_std,
                self.init_velocity_std,
                self.init_attitude_std,
                self.init_accel_bias_std,
                self.init_gyro_bias_std,
            ],
            3,
        )
        return np.diag(s * s)


def _vec3(a: object, name: str) -> FloatArray:
    v = np.asarray(a, dtype=np.float64)
    if v.shape != (3,):
        raise EstimationError(f"{name} must have shape (3,), got {v.shape}")
    return v


def _cov3(a: object, name: str) -> FloatArray:
    c = np.asarray(a, dtype=np.float64)
    if c.shape != (3, 3):
        raise EstimationError(f"{name} must have shape (3, 3), got {c.shape}")
    return c


class EgoEkf:
    """Error-state EKF of the vehicle's own state (paper 000 Sec. II-A).

    Call :meth:`initialize` once, then :meth:`predict_imu` for every IMU sample (in time order) and
    :meth:`update_odometry` for every odometry message. Cost (one core, after numba compilation): a few
    microseconds per IMU sample, see ``estimation/README.md``.

    Bad input (:mod:`alight.estimation.guards`): odometry with a non-finite value, a position beyond
    ``MAX_POSITION_M``, a speed beyond ``MAX_SPEED_MPS``, a time beyond ``MAX_TIME_S`` or a quaternion
    that is not a rotation (norm outside [0.5, 2]: zero, NaN) raises
    :class:`alight.errors.MeasurementError` and leaves the filter untouched; odometry stamped more than
    ``FUTURE_TOLERANCE_S`` after the filter's clock (the last IMU sample, or before the first one the time
    :meth:`initialize` was given) is refused, unless ``ODOMETRY_RUN`` of them in order say, before the
    filter has propagated, that the clock it started from was wrong; with ``odometry_gate`` a position more
    than ``GATE_SIGMA`` standard deviations from the prediction is refused, and ``odometry_reset_after``
    refusals in a row restart the filter at the odometry pose. :meth:`predict_imu_many` checks that
    its arrays hold ``n`` samples before the compiled loop reads them.
    """

    def __init__(self, config: EgoEkfConfig | None = None) -> None:
        self.config = config if config is not None else EgoEkfConfig()
        c = self.config
        self._params = np.array(
            [
                c.accel_noise_density,
                c.gyro_noise_density,
                c.accel_bias_random_walk,
                c.gyro_bias_random_walk,
                c.gravity,
            ]
        )
        self._R9 = np.diag(
            np.repeat([c.odometry_position_std, c.odometry_attitude_std, c.odometry_velocity_std], 3) ** 2
        )
        self._R6 = self._R9[:6, :6].copy()
        self._x = np.zeros(16)
        self._P = np.zeros((15, 15))
        self._imu = np.zeros(12)
        self._z = np.zeros(10)
        self._info = np.zeros(1)
        self.reset()

    # ---- lifecycle --------------------------------------------------------------------------------

    def reset(self) -> None:
        """Forget everything; :meth:`initialize` must be called again."""
        self._x[:] = 0.0
        self._x[9] = 1.0
        self._P[:, :] = 0.0
        self._imu[:] = 0.0
        self._t = math.nan
        self._has_imu = False
        self._initialized = False
        self._state_cache: EgoState | None = None
        self.n_odometry_updates = 0
        """Odometry messages fused."""
        self.n_odometry_rejected = 0
        """Odometry messages rejected as too old (see ``EgoEkfConfig.max_odometry_lag``) or stamped more
        than ``FUTURE_TOLERANCE_S`` after the last IMU sample (:mod:`alight.estimation.guards`)."""
        self.last_nis = math.nan
        """Normalised innovation squared of the last odometry update (chi-square, 6 or 9 dof)."""
        self.n_odometry_gated = 0
        """Odometry messages refused by the position gate (``EgoEkfConfig.odometry_gate``)."""
        self.n_odometry_resets = 0
        """Restarts at the odometry pose after ``odometry_reset_after`` gated messages in a row."""
        self.reset_delta_p_WB = np.zeros(3)
        """Sum of the position jumps of :meth:`relocalize` (m, W): each time the odometry said its frame
        moved, its new pose minus the estimate just before. A consumer that keeps its own positions in
        the estimate's frame (the pipeline) subtracts it to see one continuous frame (PX4 publishes the
        same as ``delta_xy``/``delta_z``). A restart after gated messages is the estimate's own drift
        being corrected, not a jump of the frame, and adds nothing."""
        self._consecutive_gated = 0
        self._gated_from = (math.nan, np.zeros(3))
        self._imu_run = StampRun(IMU_RUN)
        self.n_relocalizations = 0
        """Restarts at a pose the odometry announced as a jump of its frame (:meth:`relocalize`)."""
        self.n_clock_restarts = 0
        """Restarts after a believed jump of the clock longer than ``MAX_HORIZON_S``
        (:mod:`alight.estimation.guards`): IMU samples or, before the first IMU sample, odometry."""
        self._odometry_run = StampRun(ODOMETRY_RUN)

    def initialize(
        self,
        t: float,
        p_WB: FloatArray,
        v_WB: FloatArray,
        q_WB: FloatArray,
        *,
        b_a: FloatArray | None = None,
        b_g: FloatArray | None = None,
        covariance: FloatArray | None = None,
    ) -> None:
        """Start the filter at time ``t`` (s) from a pose, velocity and optional biases.

        ``q_WB`` (4,) x y z w is normalised here; ``covariance`` (15, 15) defaults to
        ``config.initial_covariance()``.
        """
        p = _vec3(p_WB, "p_WB")
        v = _vec3(v_WB, "v_WB")
        q = np.asarray(q_WB, dtype=np.float64)
        if q.shape != (4,):
            raise EstimationError(f"q_WB must have shape (4,), got {q.shape}")
        ba = np.zeros(3) if b_a is None else _vec3(b_a, "b_a")
        bg = np.zeros(3) if b_g is None else _vec3(b_g, "b_g")
        P = (
            self.config.initial_covariance()
            if covariance is None
            else np.asarray(covariance, dtype=np.float64)
        )
        if P.shape != (15, 15):
            raise EstimationError(f"covariance must have shape (15, 15), got {P.shape}")
        t = check_time(t, "EgoEkf.initialize")
        if not all(np.isfinite(a).all() for a in (p, v, q, ba, bg, P)):
            raise EstimationError("EgoEkf.initialize: inputs must be finite")
        nq = float(np.linalg.norm(q))
        if nq < 1e-6:
            raise EstimationError("EgoEkf.initialize: q_WB has zero norm")
        self.reset()
        self._x[0:3] = p
        self._x[3:6] = v
        self._x[6:10] = q / nq
        self._x[10:13] = ba
        self._x[13:16] = bg
        self._P[:, :] = 0.5 * (P + P.T)
        self._t = float(t)
        self._initialized = True

    # ---- filter steps -----------------------------------------------------------------------------

    def predict_imu(self, t: float, f_B: FloatArray, w_B: FloatArray) -> None:
        """Propagate to the IMU sample at ``t`` (s): specific force ``f_B`` (m/s^2) and rate ``w_B``
        (rad/s), both (3,) in B. Samples must come in time order; one at the filter time only refreshes
        the body rates. A sample more than ``FUTURE_TOLERANCE_S`` after the filter time (the first one
        after :meth:`initialize` included) is refused (:class:`alight.errors.MeasurementError`) unless
        ``IMU_RUN`` samples in a row, in order among themselves, say the clock really jumped: then a gap
        up to ``MAX_HORIZON_S`` is propagated in bounded steps, and a longer one, over which dead
        reckoning says nothing, restarts the filter at the sample (:meth:`_restart_after_gap`)."""
        if not self._initialized:
            raise EstimationError("EgoEkf.predict_imu called before initialize")
        try:
            ordinary = 0.0 <= t - self._t <= FUTURE_TOLERANCE_S  # False on NaN
        except (TypeError, ValueError):  # not a number, or an array
            ordinary = False
        if ordinary:
            dt = t - self._t
            if self._imu_run.times:
                self._imu_run.clear()
        else:  # the rare path, checked in full
            dt = self._imu_gap(t)
        self._apply_imu(t, dt, f_B, w_B)

    def _apply_imu(self, t: float, dt: float, f_B: FloatArray, w_B: FloatArray) -> None:
        """The propagation of :meth:`predict_imu` over ``dt`` (s) to the sample at ``t``, whose time the
        caller has judged (the IMU's rule, or the odometry's for a held sample)."""
        if np.iscomplexobj(f_B) or np.iscomplexobj(w_B):
            check_real_inputs(t, (f_B, w_B), "EgoEkf.predict_imu")  # raises
        try:
            self._imu[6:9] = f_B
            self._imu[9:12] = w_B
        except (ValueError, TypeError) as e:
            raise MeasurementError(f"EgoEkf.predict_imu: f_B and w_B must have shape (3,): {e}") from None
        if not self._has_imu:
            self._imu[0:6] = self._imu[6:12]
        status = ego_predict_kernel(self._x, self._P, self._imu, self._params, dt, self.config.max_step)
        if status != OK:
            raise MeasurementError(
                f"EgoEkf.predict_imu: IMU sample at t={t} not finite or beyond an airframe's range"
            )
        self._has_imu = True
        self._t = float(t)
        self._state_cache = None

    def _imu_gap(self, t: float) -> float:
        """The gap to an IMU sample outside ``[filter time, + FUTURE_TOLERANCE_S]``, or a refusal; 0 after
        a believed gap longer than ``MAX_HORIZON_S`` (the filter restarted at ``t``)."""
        t = check_time(t, "EgoEkf.predict_imu")
        dt = t - self._t
        if dt < 0.0:
            raise EstimationError(f"EgoEkf.predict_imu: time {t} is before the filter time {self._t}")
        if not self._imu_run.add(t):
            raise MeasurementError(
                f"EgoEkf.predict_imu: time {t} is more than {FUTURE_TOLERANCE_S:g} s after the filter time "
                f"{self._t}"
            )
        self._imu_run.clear()
        if dt > MAX_HORIZON_S:
            self._restart_after_gap(t)
            return 0.0
        return dt

    def _restart_after_gap(self, t: float) -> None:
        """A believed clock jump longer than ``MAX_HORIZON_S``: integrating the held IMU over it would
        only grow the covariance past what a double can update (the filter would refuse every odometry
        message after it), and the velocity it carried is no evidence after so long. Restart at ``t``
        from the last pose with no velocity and the initial covariance; odometry that disagrees is then
        gated, and ``odometry_reset_after`` messages restart the filter at the odometry's pose."""
        self._restart(t, self._x[0:3].copy(), np.zeros(3), self._x[6:10].copy())
        self.n_clock_restarts += 1

    def predict_imu_many(
        self, ts: FloatArray, f_B: FloatArray, w_B: FloatArray, n: int | None = None
    ) -> None:
        """As ``n`` calls of :meth:`predict_imu` (same arithmetic) in one compiled call: times ``ts``
        (n,), specific forces ``f_B`` and rates ``w_B`` (n, 3). For drivers that buffer a 200 Hz IMU
        stream and hand it over when the estimate is needed. From a sample :meth:`predict_imu` would
        refuse, the rest go through it one by one, and the first refusal is raised at the end."""
        if not self._initialized:
            raise EstimationError("EgoEkf.predict_imu_many called before initialize")
        if not (type(ts) is np.ndarray and ts.dtype == np.float64 and ts.ndim == 1):
            ts = check_times(ts, "EgoEkf.predict_imu_many")
        n = len(ts) if n is None else int(n)
        if n == 0:
            return
        # the compiled kernel reads rows 0..n-1 of every array unchecked: check their sizes here
        # (arrays, the 200 Hz drivers' case, by their attributes: np.ndim and np.shape cost more)
        if type(f_B) is np.ndarray and type(w_B) is np.ndarray:
            ok = (
                0 < n <= len(ts)
                and f_B.ndim == 2
                and w_B.ndim == 2
                and f_B.shape[1] == 3
                and w_B.shape[1] == 3
                and n <= min(len(f_B), len(w_B))
            )
        else:
            ok = (
                0 < n <= len(ts)
                and np.ndim(f_B) == 2
                and np.ndim(w_B) == 2
                and np.shape(f_B)[1] == 3
                and np.shape(w_B)[1] == 3
                and n <= min(len(f_B), len(w_B))
            )
        if not ok:
            raise MeasurementError(
                f"EgoEkf.predict_imu_many: n={n} samples need ts (>= n,), f_B and w_B (>= n, 3), got "
                f"{np.shape(ts)}, {np.shape(f_B)}, {np.shape(w_B)}"
            )
        check_real_inputs(0.0, (f_B, w_B), "EgoEkf.predict_imu_many")
        f_B = np.asarray(f_B, dtype=np.float64)  # no copy for the drivers' arrays
        w_B = np.asarray(w_B, dtype=np.float64)
        if not self._has_imu:
            self._imu[0:3] = f_B[0]
            self._imu[3:6] = w_B[0]
        bad = ego_predict_many_kernel(
            self._x, self._P, self._imu, self._params, self._t, ts, f_B, w_B, n, self.config.max_step
        )
        done = n if bad == -1 else (bad if bad >= 0 else -bad - 2)
        if done > 0:
            self._has_imu = True
            self._t = float(ts[done - 1])
            self._state_cache = None
            self._imu_run.clear()
        if bad >= 0:
            raise MeasurementError(
                f"EgoEkf.predict_imu_many: IMU sample at t={ts[bad]} not finite or beyond an airframe's range"
            )
        if bad < -1:
            self._one_by_one(ts[done:n], f_B[done:n], w_B[done:n])

    def _one_by_one(self, ts: FloatArray, f_B: FloatArray, w_B: FloatArray) -> None:
        """:meth:`predict_imu` on each sample from one the compiled loop refused by its time. Samples too
        far in the future are refused and go on (a run of them is believed, :class:`~.guards.StampRun`),
        the first such refusal raised after the last sample; any other refusal ends the call."""
        first: EstimationError | None = None
        for k in range(len(ts)):
            if not ts[k] > self._t + FUTURE_TOLERANCE_S:  # before the filter time, or NaN: ends here
                self.predict_imu(float(ts[k]), f_B[k], w_B[k])
                continue
            try:
                self.predict_imu(float(ts[k]), f_B[k], w_B[k])
            except MeasurementError as err:
                first = err if first is None else first
        if first is not None:
            raise first

    def update_odometry(
        self,
        t: float,
        p_WB: FloatArray,
        q_WB: FloatArray,
        v_WB: FloatArray | None = None,
        *,
        cov_p: FloatArray | None = None,
        cov_theta: FloatArray | None = None,
        cov_v: FloatArray | None = None,
    ) -> bool:
        """Fuse an odometry pose (and optionally velocity) measured at ``t`` (s).

        ``p_WB`` (3,) m, ``q_WB`` (4,) x y z w, ``v_WB`` (3,) m/s or None. Covariances (3, 3): ``cov_p``
        (m^2), ``cov_theta`` (rad^2) of the attitude error in B (``R_meas = R_WB Exp(n)``), ``cov_v``
        ((m/s)^2); None takes the config's defaults. A message newer than the filter is propagated to
        with the last IMU sample held; one older by at most ``max_odometry_lag`` is moved forward; older
        ones are rejected and counted. Returns True when fused.
        """
        t = check_real_inputs(t, (p_WB, q_WB, v_WB), "EgoEkf.update_odometry")  # guards: no None, "x", 1j
        if not self._initialized:
            raise EstimationError("EgoEkf.update_odometry called before initialize")
        if not math.isfinite(t):
            raise EstimationError(f"EgoEkf.update_odometry: time must be finite, got {t}")
        m = self._load_measurement(p_WB, q_WB, v_WB)
        Rm = self._measurement_noise(m, cov_p, cov_theta, cov_v)
        self._check_measurement(t, m, Rm)
        lag = self._t - t
        if lag > self.config.max_odometry_lag:
            self.n_odometry_rejected += 1
            return False
        if -lag > FUTURE_TOLERANCE_S:
            if not self._odometry_clock_jumped(t):
                # newer than the filter's clock by more than the tolerance: a bad stamp, which would
                # otherwise carry the filter ahead of every IMU sample or message to come
                self.n_odometry_rejected += 1
                return False
        elif self._odometry_run.times:
            self._odometry_run.clear()
        if lag < -MAX_HORIZON_S:  # a believed jump of the clock, before any IMU sample: nothing to hold
            self._restart(
                t, self._z[0:3].copy(), self._z[7:10].copy() if m == 9 else np.zeros(3), self._z[3:7]
            )
            self.n_clock_restarts += 1
            return True
        if lag < 0.0:
            self._hold_to(t)
        elif lag > 0.0:
            self._move_forward(lag, m)
        if self.config.odometry_gate and self._gated(Rm):
            return False
        status = ego_update_kernel(self._x, self._P, self._z, Rm, m, self._info)
        if status == NOT_FINITE:
            raise EstimationError(f"EgoEkf.update_odometry: non-finite measurement or covariance at t={t}")
        if status == NOT_POSITIVE_DEFINITE:
            raise EstimationError(
                f"EgoEkf.update_odometry: innovation covariance not positive definite at t={t}"
            )
        self.last_nis = float(self._info[0])
        self.n_odometry_updates += 1
        self._state_cache = None
        return True

    def _load_measurement(self, p_WB: FloatArray, q_WB: FloatArray, v_WB: FloatArray | None) -> int:
        """The measurement into ``self._z`` (position, quaternion, velocity); its size m (6 or 9)."""
        try:
            self._z[0:3] = p_WB
            self._z[3:7] = q_WB
            if v_WB is not None:
                self._z[7:10] = v_WB
        except (ValueError, TypeError) as e:
            raise EstimationError(f"EgoEkf.update_odometry: bad measurement shape: {e}") from None
        return 6 if v_WB is None else 9

    def _measurement_noise(
        self, m: int, cov_p: FloatArray | None, cov_theta: FloatArray | None, cov_v: FloatArray | None
    ) -> FloatArray:
        """R (m, m): the configured one (shared, not copied) unless a message covariance replaces a block."""
        if cov_p is None and cov_theta is None and cov_v is None:
            return self._R9 if m == 9 else self._R6
        Rm = (self._R9 if m == 9 else self._R6).copy()
        if cov_p is not None:
            Rm[0:3, 0:3] = _cov3(cov_p, "cov_p")
        if cov_theta is not None:
            Rm[3:6, 3:6] = _cov3(cov_theta, "cov_theta")
        if cov_v is not None and m == 9:
            Rm[6:9, 6:9] = _cov3(cov_v, "cov_v")
        return Rm

    def _check_measurement(self, t: float, m: int, Rm: FloatArray) -> None:
        """Checked before any propagation, so that a bad message leaves the filter untouched: finite
        values, and physical bounds (alight.estimation.guards: a position, a unit quaternion, a speed,
        a time) on Python floats (40 Hz: three numpy dot products cost more than the filter's update)."""
        z = self._z[: m + 1].tolist()
        if not (
            math.isfinite(sum(z))
            and (Rm is self._R9 or Rm is self._R6 or math.isfinite(float(Rm.sum())))  # configured: checked
        ):
            raise EstimationError(f"EgoEkf.update_odometry: non-finite measurement or covariance at t={t}")
        check_time(t, "EgoEkf.update_odometry")
        nq2 = z[3] * z[3] + z[4] * z[4] + z[5] * z[5] + z[6] * z[6]
        if not (0.25 <= nq2 <= 4.0):  # a rotation's quaternion has norm 1; renormalised below
            raise MeasurementError(f"EgoEkf.update_odometry: q_WB {z[3:7]} is not a rotation")
        if z[0] * z[0] + z[1] * z[1] + z[2] * z[2] > MAX_POSITION_M**2 or (
            m == 9 and z[7] * z[7] + z[8] * z[8] + z[9] * z[9] > MAX_SPEED_MPS**2
        ):
            raise MeasurementError(
                f"EgoEkf.update_odometry: position beyond {MAX_POSITION_M:g} m or speed beyond "
                f"{MAX_SPEED_MPS:g} m/s at t={t}"
            )

    def _odometry_clock_jumped(self, t: float) -> bool:
        """Whether a message more than ``FUTURE_TOLERANCE_S`` after the filter's clock is believed: never
        once the filter has propagated (an IMU sample, or a message's held one: its clock is then the
        IMU's), else once ``ODOMETRY_RUN`` such messages in a row are in order among themselves
        (:class:`~.guards.StampRun`: the clock :meth:`initialize` was given was wrong)."""
        if self._has_imu or not self._odometry_run.add(t):
            return False
        self._odometry_run.clear()
        return True

    def _hold_to(self, t: float) -> None:
        """Propagate to a message newer than the filter with the last IMU sample held, or without an
        IMU yet with the velocity held (the sample an unaccelerated body would give)."""
        if self._has_imu:
            self._apply_imu(t, t - self._t, self._imu[0:3].copy(), self._imu[3:6].copy())
        else:
            R = np.empty((3, 3))
            quat_to_R(self._x[6:10], R)
            f = R.T @ np.array([0.0, 0.0, self.config.gravity]) + self._x[10:13]
            self._apply_imu(t, t - self._t, f, self._x[13:16].copy())

    def _gated(self, Rm: FloatArray) -> bool:
        """The position gate on ``self._z`` (module config); True when the message is refused. After
        ``odometry_reset_after`` refusals in a row, restarts at the odometry pose instead."""
        d2 = _mahalanobis2_3(
            (self._P[0:3, 0:3] + Rm[0:3, 0:3]).tolist(), (self._z[0:3] - self._x[0:3]).tolist()
        )
        if d2 is None:
            return False  # the update kernel reports a singular innovation covariance
        if not d2 > GATE_SIGMA**2:
            self._consecutive_gated = 0
            return False
        self.n_odometry_gated += 1
        self._consecutive_gated += 1
        if self._consecutive_gated == 1:  # where the run of refused messages starts (for its velocity)
            self._gated_from = (self._t, self._z[0:3].copy())
        if self._consecutive_gated < self.config.odometry_reset_after:
            return True
        # the estimate drifted away from every message: restart at the odometry's pose (its own drift
        # corrected, not a jump of the odometry's frame: nothing added to reset_delta_p_WB)
        q = self._z[3:7] / math.sqrt(float(self._z[3:7] @ self._z[3:7]))
        # the estimate's velocity is judged wrong with its position (it carried it away): the message's
        # own, or the refused messages' mean velocity, bounded by guards.plausible_velocity
        if Rm.shape[0] == 9:
            v = self._z[7:10].copy()
        else:
            t0, p0 = self._gated_from
            v = (self._z[0:3] - p0) / (self._t - t0) if self._t > t0 else np.zeros(3)
        self._restart(self._t, self._z[0:3].copy(), plausible_velocity(v), q)
        self.n_odometry_resets += 1
        return True

    def _restart(self, t: float, p_WB: FloatArray, v_WB: FloatArray, q_WB: FloatArray) -> None:
        """:meth:`initialize` at a pose, keeping what the filter has counted over its life (the message
        counters and ``reset_delta_p_WB``), which ``initialize`` would zero."""
        kept = (
            self.n_odometry_updates, self.n_odometry_rejected, self.n_odometry_gated,
            self.n_odometry_resets, self.n_relocalizations, self.reset_delta_p_WB, self.n_clock_restarts,
        )  # fmt: skip
        self.initialize(t, p_WB, v_WB, q_WB)
        (
            self.n_odometry_updates, self.n_odometry_rejected, self.n_odometry_gated,
            self.n_odometry_resets, self.n_relocalizations, self.reset_delta_p_WB, self.n_clock_restarts,
        ) = kept  # fmt: skip

    def relocalize(
        self, t: float, p_WB: FloatArray, q_WB: FloatArray, v_WB: FloatArray | None = None
    ) -> None:
        """The odometry announced that its frame moved (a VIO re-localised; MAVLink ODOMETRY's
        ``reset_counter`` went up): restart at its new pose at once, instead of refusing it as an outlier,
        and add the jump (the new position minus the estimate, propagated to ``t``) to
        ``reset_delta_p_WB``. Raises like :meth:`update_odometry` on a message that is not a pose."""
        where = "EgoEkf.relocalize"
        t = check_clock(t, self._t, where)  # guards: within the tolerance of the IMU clock
        check_real_inputs(t, (p_WB, q_WB, v_WB), where)
        # guards.check_vector: the bounds tested on the largest element first (1e300 would overflow q @ q)
        p = check_vector(p_WB, 3, MAX_POSITION_M, "p_WB", where)
        q = check_vector(q_WB, 4, 2.0, "q_WB", where)
        v = (
            plausible_velocity(self._x[3:6])
            if v_WB is None
            else check_vector(v_WB, 3, MAX_SPEED_MPS, "v_WB", where)
        )
        nq2 = float(q @ q)
        if not nq2 >= 0.25:  # a rotation's quaternion has norm 1 (zero is not one)
            raise MeasurementError(f"{where}: q_WB {q.tolist()} is not a rotation at t={t}")
        if not self._initialized:
            self.initialize(t, p, v, q)
            return
        if self._has_imu and t > self._t:  # hold the last IMU sample up to the message
            self._apply_imu(t, t - self._t, self._imu[0:3].copy(), self._imu[3:6].copy())
        delta = self.reset_delta_p_WB + (p - self._x[0:3])
        self._restart(max(t, self._t), p, v, q / math.sqrt(nq2))
        self.n_relocalizations += 1
        self.reset_delta_p_WB = delta

    def _move_forward(self, lag: float, m: int) -> None:
        """First-order latency compensation of the measurement in ``self._z`` by ``lag`` seconds."""
        w = self._imu[3:6] - self._x[13:16]
        self._z[0:3] += self._x[3:6] * lag
        dq = np.empty(4)
        quat_exp(w * lag, dq)
        qn = np.empty(4)
        quat_mul(self._z[3:7].copy(), dq, qn)
        self._z[3:7] = qn
        if m == 9:
            R = np.empty((3, 3))
            quat_to_R(self._x[6:10], R)
            a = R @ (self._imu[0:3] - self._x[10:13])
            a[2] -= self.config.gravity
            self._z[7:10] += a * lag

    # ---- outputs ----------------------------------------------------------------------------------

    @property
    def initialized(self) -> bool:
        return self._initialized

    @property
    def t(self) -> float:
        """Time of the filter's state (s)."""
        return self._t

    @property
    def covariance(self) -> FloatArray:
        """Error-state covariance (15, 15): dp, dv, dtheta (in B), db_a, db_g."""
        return self._P.copy()

    @property
    def nominal(self) -> FloatArray:
        """Nominal state (16,): p_WB, v_WB, q_WB (x y z w), b_a, b_g."""
        return self._x.copy()

    @property
    def b_a(self) -> FloatArray:
        """Accelerometer bias estimate (m/s^2), (3,)."""
        return self._x[10:13].copy()

    @property
    def b_g(self) -> FloatArray:
        """Gyro bias estimate (rad/s), (3,)."""
        return self._x[13:16].copy()

    def state(self) -> EgoState:
        """The estimate at the filter time: body rates are the last gyro sample minus ``b_g``, and
        ``a_WB = R_WB (f_B - b_a) + g_W`` with the last accelerometer sample."""
        if not self._initialized:
            raise EstimationError("EgoEkf.state called before initialize")
        if self._state_cache is None:
            packed = np.empty(16)
            _pack_state(self._x, self._imu, self._has_imu, self.config.gravity, packed)
            # The filter's state is finite and its quaternion unit by construction (checked inputs,
            # renormalised after every step), so the unchecked constructor is safe here.
            self._state_cache = EgoState.from_packed(self._t, packed)
        return self._state_cache
