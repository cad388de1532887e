"""EKF of the landing platform with the non-holonomic unicycle model (paper 000 Sec. II-C, eq. 1-3).

State ``x`` (eq. 2): ``[p_x, p_y, p_z, theta, v_t]`` and, with ``use_turn_rate``, the turn rate ``omega``
appended (n = 5 or 6). ``theta`` is the heading of the platform's forward axis from world x (rad), ``v_t``
its tangential speed (m/s). The paper sets the inputs ``u1 = u2 = 0`` (eq. 2d, 2e: constant heading and
speed) and lets white process noise ``w(t)`` (eq. 1) absorb what the platform really does; the turn-rate
variant makes the heading rate a state (constant turn rate and velocity), which follows circles and
figure-8s without lag. Measurement ``z_k`` (eq. 3): the 3D pad position in W, optionally its yaw.

Detection latency: a detection is delivered ~100 ms after its image was captured, but detections come in
capture-time order. The filter therefore keeps its internal time at the last measurement's capture time:
an update first predicts to the capture time, and :meth:`PlatformEkf.state` / :meth:`predict_ahead`
extrapolate from there to any query time without changing the filter. A measurement captured before the
internal time (out of order) is rejected and counted (``n_out_of_order``); a retrodiction would be needed
to use it, and in-order delivery makes that case a fault upstream. :meth:`PlatformEkf.predict` only records
the caller's clock, it never moves the filter.

Discretisation: the mean is propagated in closed form (exact for constant turn rate; straight line when
``omega = 0``), the covariance with the exact Jacobian of that map and the process noise integrated over the
step for the model linearised about straight motion at the mid-step heading. Long steps are split into
``max_step`` pieces so that this linearisation stays good over measurement gaps.

Initialisation: heading and speed are unobservable from one point, so the first measurements are buffered
until there are ``init_min_measurements`` spanning ``init_min_span`` seconds; a weighted least-squares
line fit over them gives position, heading and speed with their covariance (plus the process noise over
the window, which the constant-velocity fit ignores). Until then ``initialized`` is False and
:meth:`state` returns a stationary estimate at the last measurement whose horizontal covariance grows with
its age as ``(init_speed_prior_std * age)^2`` (any speed up to a few m/s is plausible).

Robustness: ``v_t >= 0`` is kept by the exact reparametrisation ``(theta, v_t) -> (theta + pi, -v_t)``
(unless ``allow_reverse``). With ``gating``, an innovation whose Mahalanobis distance exceeds the
chi-square quantile ``gate_probability`` is rejected; after ``reinit_after_rejections`` consecutive
rejections the track is assumed lost and the filter re-initialises from those rejected measurements.
Non-finite measurements raise :class:`alight.errors.EstimationError` and leave the filter untouched.

Bad input (:mod:`alight.estimation.guards`): a time beyond ``MAX_TIME_S``, a position beyond
``MAX_POSITION_M`` or a covariance that is not symmetric positive semi-definite raises
:class:`alight.errors.MeasurementError` (an ``EstimationError``) and leaves the filter untouched. A
measurement stamped more than ``FUTURE_TOLERANCE_S`` after the clock given to :meth:`PlatformEkf.predict`
is refused (``n_future``). Without a clock, a measurement from the future is taken, but it cannot block
the filter: when ``reinit_after_rejections`` measurements in a row, in order among themselves, arrive
more than ``FUTURE_TOLERANCE_S`` before the filter's time, the filter's time was the fault and the track
restarts from them (``n_reinitializations``). :meth:`PlatformEkf.state` integrates at most
``MAX_HORIZON_S`` past the last measurement (bounded work for any query time); further out it reports the
estimate at that horizon with the horizontal variance grown by ``(init_speed_prior_std * excess)^2``.
:meth:`PlatformEkf.update_telemetry` applies the same rules (and a velocity below ``MAX_SPEED_MPS``; a fix
more than ``FUTURE_TOLERANCE_S`` after the clock is refused), and every propagation takes at most
``MAX_STEPS`` steps whatever the gap.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit
from scipy.special import chdtri

from alight.errors import EstimationError
from alight.estimation.ego_ekf import NOT_POSITIVE_DEFINITE, OK, _mm, _mmt
from alight.estimation.guards import (
    FUTURE_TOLERANCE_S,
    MAX_HORIZON_S,
    MAX_POSITION_M,
    MAX_SPEED_MPS,
    bounded_steps,
    check_clock,
    check_covariance,
    check_measurement,
    check_time,
    check_times,
    check_vector,
)
from alight.estimation.telemetry import (
    TelemetryBias,
    TelemetryFusionConfig,
    carry_fix_on_turn,
    telemetry_adds_information,
)
from alight.numerics.linalg import chol_solve
from alight.numerics.rotation import wrap_period
from alight.types import FloatArray, PlatformEstimate, PlatformMeasurement

REJECTED = 3
"""Status code of a gated-out measurement."""

I_PX, I_PY, I_PZ, I_THETA, I_V, I_OMEGA = 0, 1, 2, 3, 4, 5

# --------------------------------------------------------------------------------------------------
# Unicycle model (eq. 2) - pure numba functions
# --------------------------------------------------------------------------------------------------


TURN_JERK_CORNER_SPEED_MPS = 2.0
"""Speed (m/s) below which ``turn_jerk_noise`` fades (see :func:`turn_jerk_density`): a vehicle at rest
does not turn (with ``j / max(v, 1 m/s)`` the turn rate of a platform standing for 3 s wandered by several
rad/s, and the estimate curled when it drove on)."""
TURN_JERK_FADE_SPEED_MPS = 6.0
"""Speed (m/s) above which ``turn_jerk_noise`` fades faster than ``j / v`` (see :func:`turn_jerk_density`):
with ``j / v`` alone the turn rate of a 14 m/s platform followed each GNSS fix (10 Hz, 0.5 m) before the
camera saw the pad, the vehicle tracked a wandering prediction and found the pad 6 s later (Matrice 100 at
14 m/s, alight_speed.yaml: 15/20 -> 3/20 landed)."""


@njit(cache=True)
def turn_jerk_density(j: float, v: float) -> float:
    """The turn-acceleration density (rad/s^2/sqrt(Hz)) that a lateral-jerk density ``j`` (m/s^3/sqrt(Hz))
    adds at speed ``v`` (m/s): ``j v / (v^2 + v_c^2) * v_f^2 / (v^2 + v_f^2)``. Between the corner
    ``v_c`` (2 m/s) and ``v_f`` (6 m/s) it is about the lateral jerk's ``j / v`` (a vehicle whose side
    force is limited changes its turn rate the slower the faster it goes); it fades to 0 at rest and as
    ``j v_f^2 / v^3`` when fast, where the heading is well determined by the motion and the turn noise
    would only make it follow the fixes' noise."""
    v2 = v * v
    vf2 = TURN_JERK_FADE_SPEED_MPS * TURN_JERK_FADE_SPEED_MPS
    return j * abs(v) / (v2 + TURN_JERK_CORNER_SPEED_MPS * TURN_JERK_CORNER_SPEED_MPS) * vf2 / (v2 + vf2)


@njit(cache=True)
def _turn_coefficients(phi: float) -> tuple[float, float, float, float]:
    """``S = sin(phi)/phi``, ``C = (1 - cos(phi))/phi`` and their derivatives in ``phi``, stable at 0."""
    if abs(phi) < 1e-3:
        p2 = phi * phi
        S = 1.0 - p2 / 6.0 + p2 * p2 / 120.0
        C = phi * (0.5 - p2 / 24.0 + p2 * p2 / 720.0)
        dS = phi * (-1.0 / 3.0 + p2 / 30.0)
        dC = 0.5 - p2 / 8.0 + p2 * p2 / 144.0
    else:
        s = math.sin(phi)
        c = math.cos(phi)
        S = s / phi
        C = (1.0 - c) / phi
        dS = (phi * c - s) / (phi * phi)
        dC = (phi * s - (1.0 - c)) / (phi * phi)
    return S, C, dS, dC


@njit(cache=True)
def unicycle_step(x: FloatArray, dt: float, out: FloatArray) -> None:
    """Exact solution of eq. 2 over ``dt`` (s) with ``u1 = u2 = 0`` (constant ``omega``, 0 without it).

    ``p_x += v_t dt (cos(theta) S - sin(theta) C)``, ``p_y += v_t dt (sin(theta) S + cos(theta) C)``
    with ``S = sin(omega dt)/(omega dt)``, ``C = (1 - cos(omega dt))/(omega dt)``: the arc of a circle of
    radius ``v_t / omega``. ``x``, ``out`` (n,), n = 5 or 6; ``theta`` is wrapped to [-pi, pi).
    """
    n = x.shape[0]
    th = x[I_THETA]
    v = x[I_V]
    om = x[I_OMEGA] if n == 6 else 0.0
    S, C, _, _ = _turn_coefficients(om * dt)
    c = math.cos(th)
    s = math.sin(th)
    out[I_PX] = x[I_PX] + v * dt * (c * S - s * C)
    out[I_PY] = x[I_PY] + v * dt * (s * S + c * C)
    out[I_PZ] = x[I_PZ]
    out[I_THETA] = wrap_period(th + om * dt, 2.0 * math.pi)
    out[I_V] = v
    if n == 6:
        out[I_OMEGA] = om


@njit(cache=True)
def unicycle_jacobian(x: FloatArray, dt: float, F: FloatArray) -> None:
    """Jacobian ``F`` (n, n) of :func:`unicycle_step` with respect to ``x``."""
    n = x.shape[0]
    th = x[I_THETA]
    v = x[I_V]
    om = x[I_OMEGA] if n == 6 else 0.0
    S, C, dS, dC = _turn_coefficients(om * dt)
    c = math.cos(th)
    s = math.sin(th)
    for i in range(n):
        for j in range(n):
            F[i, j] = 1.0 if i == j else 0.0
    F[I_PX, I_THETA] = -v * dt * (s * S + c * C)
    F[I_PY, I_THETA] = v * dt * (c * S - s * C)
    F[I_PX, I_V] = dt * (c * S - s * C)
    F[I_PY, I_V] = dt * (s * S + c * C)
    if n == 6:
        F[I_PX, I_OMEGA] = v * dt * dt * (c * dS - s * dC)
        F[I_PY, I_OMEGA] = v * dt * dt * (s * dS + c * dC)
        F[I_THETA, I_OMEGA] = dt


@njit(cache=True)
def unicycle_process_noise(x: FloatArray, dt: float, q: FloatArray, Q: FloatArray) -> None:
    """Process noise ``Q`` (n, n) integrated over ``|dt|`` (s) for white noises of densities ``q`` (6,):
    tangential acceleration (m/s^2/sqrt(Hz)), heading rate (rad/s/sqrt(Hz)), turn acceleration
    (rad/s^2/sqrt(Hz), only with ``omega``), horizontal and vertical position random walks
    (m/s/sqrt(Hz)), lateral jerk (m/s^3/sqrt(Hz), only with ``omega``: it adds
    ``turn_jerk_density(q[5], v_t)^2`` to the turn acceleration's variance; a 5-element ``q`` has none).
    Exact integrals for the model linearised about straight motion at the mid-step heading (an impulse
    on ``d(v_t)/dt`` at lag ``u`` before the end moves p by ``u`` along the heading, one on
    ``d(theta)/dt`` by ``v_t u`` across it, one on ``d(omega)/dt`` by ``v_t u^2 / 2``)."""
    n = x.shape[0]
    h = abs(dt)
    v = x[I_V]
    om = x[I_OMEGA] if n == 6 else 0.0
    thm = x[I_THETA] + 0.5 * om * dt
    ex = math.cos(thm)
    ey = math.sin(thm)
    nx = -ey
    ny = ex
    sa2 = q[0] * q[0]
    sh2 = q[1] * q[1]
    sw2 = q[2] * q[2] if n == 6 else 0.0
    if n == 6 and q.shape[0] > 5 and q[5] > 0.0:
        sw2 += turn_jerk_density(q[5], v) ** 2
    h2 = h * h
    h3 = h2 * h
    # along-track (e) and cross-track (nn) position variances
    qee = sa2 * h3 / 3.0
    qnn = v * v * (sh2 * h3 / 3.0 + sw2 * h3 * h2 / 20.0)
    for i in range(n):
        for j in range(n):
            Q[i, j] = 0.0
    ph = q[3] * q[3] * h
    Q[0, 0] = qee * ex * ex + qnn * nx * nx + ph
    Q[1, 1] = qee * ey * ey + qnn * ny * ny + ph
    Q[0, 1] = qee * ex * ey + qnn * nx * ny
    Q[1, 0] = Q[0, 1]
    Q[2, 2] = q[4] * q[4] * h
    qpth = v * (sh2 * h2 / 2.0 + sw2 * h2 * h2 / 8.0)
    Q[0, 3] = Q[3, 0] = qpth * nx
    Q[1, 3] = Q[3, 1] = qpth * ny
    Q[3, 3] = sh2 * h + sw2 * h3 / 3.0
    qpv = sa2 * h2 / 2.0
    Q[0, 4] = Q[4, 0] = qpv * ex
    Q[1, 4] = Q[4, 1] = qpv * ey
    Q[4, 4] = sa2 * h
    if n == 6:
        qpw = sw2 * v * h3 / 6.0
        Q[0, 5] = Q[5, 0] = qpw * nx
        Q[1, 5] = Q[5, 1] = qpw * ny
        Q[3, 5] = Q[5, 3] = sw2 * h2 / 2.0
        Q[5, 5] = sw2 * h


@njit(cache=True)
def platform_propagate(
    x: FloatArray, P: FloatArray, dt: float, q: FloatArray, max_step: float, xo: FloatArray, Po: FloatArray
) -> None:
    """``xo, Po`` = ``x, P`` propagated by ``dt`` (s, may be negative: the mean goes back exactly and the
    process noise of ``|dt|`` is still added) in steps of at most ``max_step``."""
    n = x.shape[0]
    k = bounded_steps(dt, max_step)  # alight.estimation.guards: bounded work for any gap
    h = dt / k
    F = np.empty((n, n))
    Q = np.empty((n, n))
    FP = np.empty((n, n))
    xt = np.empty(n)
    for i in range(n):
        xo[i] = x[i]
        for j in range(n):
            Po[i, j] = P[i, j]
    if dt == 0.0:
        return
    for _ in range(k):
        unicycle_jacobian(xo, h, F)
        unicycle_process_noise(xo, h, q, Q)
        unicycle_step(xo, h, xt)
        for i in range(xo.shape[0]):  # by element: numba compiles a slice assignment's error message (~1 s)
            xo[i] = xt[i]
        _mm(F, Po, FP)
        _mmt(FP, F, Po)
        for i in range(n):
            for j in range(i, n):
                s = 0.5 * (Po[i, j] + Po[j, i]) + Q[i, j]
                Po[i, j] = s
                Po[j, i] = s


@njit(cache=True)
def platform_residual(x: FloatArray, z: FloatArray, m: int, yaw_period: float, r: FloatArray) -> None:
    """Residual ``z - h(x)`` (m,): position (3), and with m = 4 the yaw wrapped to the measurement's
    symmetry period (a tag that looks the same every ``yaw_period`` rad measures yaw modulo that); with
    m = 5 also the speed ``v_t`` (a telemetry fix's velocity as heading and speed)."""
    for i in range(3):
        r[i] = z[i] - x[i]
    if m >= 4:
        r[3] = wrap_period(z[3] - x[I_THETA], yaw_period)
    if m == 5:
        r[4] = z[4] - x[I_V]


@njit(cache=True)
def platform_update_kernel(
    x: FloatArray,
    P: FloatArray,
    dt: float,
    z: FloatArray,
    Rz: FloatArray,
    m: int,
    q: FloatArray,
    max_step: float,
    yaw_period: float,
    gate: float,
    flip: bool,
    xo: FloatArray,
    Po: FloatArray,
    info: FloatArray,
) -> int:
    """Predict ``x, P`` by ``dt`` to the capture time and update with ``z`` (m,), ``Rz`` (m, m) (eq. 3).

    Results go to ``xo, Po``; ``info[0]`` gets the squared Mahalanobis distance of the innovation, and
    when ``info`` is long enough, ``info[1 : 1 + m]`` the innovation and the next ``m * m`` its covariance
    (row-major). With
    ``gate > 0`` a distance above it returns ``REJECTED`` (``xo, Po`` then hold the prediction only).
    ``H`` selects p (and theta), so ``H P`` is rows of ``P``. Joseph form for the same reason as in the
    ego filter: the covariance stays symmetric positive definite under round-off.

    One kernel: the prediction, the innovation and its Cholesky-solved distance for the gate, the gain and the
    Joseph update share ``H P``, ``S``, its factor ``L`` and ``K`` (propagation and residual are apart
    already: ``platform_propagate``, ``platform_residual``); splitting would pass those arrays through more
    calls per measurement.
    """
    n = x.shape[0]
    platform_propagate(x, P, dt, q, max_step, xo, Po)
    r = np.empty(m)
    platform_residual(xo, z, m, yaw_period, r)
    HP = np.empty((m, n))
    S = np.empty((m, m))
    for i in range(m):
        for j in range(n):
            HP[i, j] = Po[i, j]
    for i in range(m):
        for j in range(m):
            S[i, j] = HP[i, j] + Rz[i, j]  # H P H^T picks columns 0..m-1 of H P
    L = np.empty((m, m))
    w = np.empty((m, 1))
    Sr = np.empty((m, 1))
    for i in range(m):
        w[i, 0] = r[i]
    if not chol_solve(S, w, L, Sr):
        return NOT_POSITIVE_DEFINITE
    d2 = 0.0
    for i in range(m):
        d2 += r[i] * Sr[i, 0]
    info[0] = d2
    if info.shape[0] >= 1 + m + m * m:  # the innovation and its covariance, for the manoeuvre test
        for i in range(m):
            info[1 + i] = r[i]
            for j in range(m):
                info[1 + m + i * m + j] = S[i, j]
    if gate > 0.0 and d2 > gate:
        return REJECTED
    Kt = np.empty((m, n))
    chol_solve(S, HP, L, Kt)  # S K^T = H P
    K = np.ascontiguousarray(Kt.T)
    # A P = P - K (H P);  A P A^T + K R K^T = A P + (K R - (A P) H^T) K^T
    AP = np.empty((n, n))
    _mm(K, HP, AP)
    for i in range(n):
        for j in range(n):
            AP[i, j] = Po[i, j] - AP[i, j]
    KR = np.empty((n, m))
    _mm(K, Rz, KR)
    M = np.empty((n, m))
    for i in range(n):
        for j in range(m):
            M[i, j] = KR[i, j] - AP[i, j]  # (A P) H^T picks columns 0..m-1
    _mmt(M, K, Po)
    for i in range(n):
        for j in range(n):
            Po[i, j] += AP[i, j]
    for i in range(n):
        for j in range(i + 1, n):
            s = 0.5 * (Po[i, j] + Po[j, i])
            Po[i, j] = s
            Po[j, i] = s
    for i in range(n):
        dxi = 0.0
        for j in range(m):
            dxi += K[i, j] * r[j]
        xo[i] += dxi
    if flip and xo[I_V] < 0.0:
        # (theta, v) and (theta + pi, -v) are the same motion; the map's Jacobian negates v's row/column
        xo[I_THETA] += math.pi
        xo[I_V] = -xo[I_V]
        for i in range(n):
            if i != I_V:
                Po[i, I_V] = -Po[i, I_V]
                Po[I_V, i] = -Po[I_V, i]
    xo[I_THETA] = wrap_period(xo[I_THETA], 2.0 * math.pi)
    return OK


@njit(cache=True)
def unicycle_predict_ahead(
    x: FloatArray, dts: FloatArray, p: FloatArray, v: FloatArray, a: FloatArray, yaw: FloatArray
) -> None:
    """Closed-form eq. 2 at each of ``dts`` (k,) seconds from ``x``: positions ``p`` (k, 3) (m),
    velocities ``v`` (k, 3) (m/s), accelerations ``a`` (k, 3) (m/s^2, centripetal ``v_t omega`` across the
    heading) and headings ``yaw`` (k,) (rad)."""
    n = x.shape[0]
    th = x[I_THETA]
    vt = x[I_V]
    om = x[I_OMEGA] if n == 6 else 0.0
    c = math.cos(th)
    s = math.sin(th)
    for k in range(dts.shape[0]):
        dt = dts[k]
        S, C, _, _ = _turn_coefficients(om * dt)
        p[k, 0] = x[I_PX] + vt * dt * (c * S - s * C)
        p[k, 1] = x[I_PY] + vt * dt * (s * S + c * C)
        p[k, 2] = x[I_PZ]
        thk = th + om * dt
        ck = math.cos(thk)
        sk = math.sin(thk)
        v[k, 0] = vt * ck
        v[k, 1] = vt * sk
        v[k, 2] = 0.0
        a[k, 0] = -vt * om * sk
        a[k, 1] = vt * om * ck
        a[k, 2] = 0.0
        yaw[k] = wrap_period(thk, 2.0 * math.pi)


@njit(cache=True)
def _position_covariance_ahead(
    x: FloatArray,
    P: FloatArray,
    dts: FloatArray,
    order: np.ndarray,
    q: FloatArray,
    max_step: float,
    out: FloatArray,
) -> None:
    """Position covariances at ``dts`` (k,) s from ``x, P``, visiting them in ascending ``order`` so that
    each future time continues from the previous one (times in the past start from ``x, P`` each)."""
    n = x.shape[0]
    xc = x.copy()
    Pc = P.copy()
    xn = np.empty(n)
    Pn = np.empty((n, n))
    tc = 0.0
    for idx in range(order.shape[0]):
        k = order[idx]
        if dts[k] < 0.0:
            platform_propagate(x, P, dts[k], q, max_step, xn, Pn)
        else:
            platform_propagate(xc, Pc, dts[k] - tc, q, max_step, xn, Pn)
            xc[:] = xn
            Pc[:, :] = Pn
            tc = dts[k]
        for i in range(3):
            for j in range(3):
                out[k, i, j] = Pn[i, j]


# --------------------------------------------------------------------------------------------------
# Initialisation: heading and speed from a line fit
# --------------------------------------------------------------------------------------------------


def fit_constant_velocity(
    ts: FloatArray, ps: FloatArray, covs: FloatArray, t_ref: float
) -> tuple[FloatArray, FloatArray, FloatArray] | None:
    """Weighted least-squares fit of ``p(t) = (p_x + v_x tau, p_y + v_y tau, p_z)``, ``tau = t - t_ref``.

    ``ts`` (k,) s, ``ps`` (k, 3) m, ``covs`` (k, 3, 3) m^2. Returns ``beta = [p_x, p_y, p_z, v_x, v_y]``
    at ``t_ref``, its covariance (5, 5) and each measurement's squared Mahalanobis residual (k,), or
    None when the fit is singular. Raises EstimationError for a singular measurement covariance.
    """
    k = ts.shape[0]
    A = np.zeros((k, 3, 5))
    A[:, 0, 0] = A[:, 1, 1] = A[:, 2, 2] = 1.0
    A[:, 0, 3] = A[:, 1, 4] = ts - t_ref
    try:
        W = np.linalg.inv(covs)
    except np.linalg.LinAlgError:
        raise EstimationError("PlatformEkf: singular measurement covariance") from None
    AtW = np.einsum("kji,kjl->kil", A, W)
    try:
        C = np.linalg.inv(np.einsum("kij,kjl->il", AtW, A))
    except np.linalg.LinAlgError:
        return None
    beta = C @ np.einsum("kij,kj->i", AtW, ps)
    r = ps - np.einsum("kij,j->ki", A, beta)
    d2 = np.einsum("ki,kij,kj->k", r, W, r)
    return beta, C, d2


def unicycle_from_fit(beta: FloatArray, C: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``[p_x, p_y, p_z, theta, v_t]`` (5,) and covariance (5, 5) from a fit ``beta``, ``C`` of
    :func:`fit_constant_velocity`: ``theta = atan2(v_y, v_x)``, ``v_t = |v|``, covariance through
    their Jacobian. When the speed is within its noise the linearised heading variance is meaningless;
    it is capped at that of a uniform heading, ``pi^2 / 3``, uncorrelated."""
    vx, vy = float(beta[3]), float(beta[4])
    speed = math.hypot(vx, vy)
    J = np.zeros((5, 5))
    J[0:3, 0:3] = np.eye(3)
    if speed > 1e-9:
        J[3, 3:5] = [-vy / speed**2, vx / speed**2]
        J[4, 3:5] = [vx / speed, vy / speed]
    P5 = J @ C @ J.T
    if speed <= 1e-9:
        P5[4, 4] = C[3, 3] + C[4, 4]
    if speed <= 1e-9 or P5[3, 3] > math.pi**2 / 3.0:
        P5[3, :] = 0.0
        P5[:, 3] = 0.0
        P5[3, 3] = math.pi**2 / 3.0
    x5 = np.array([beta[0], beta[1], beta[2], math.atan2(vy, vx), speed])
    return x5, P5


# --------------------------------------------------------------------------------------------------
# The filter
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class PlatformEkfConfig:
    """Parameters of :class:`PlatformEkf`. Noise densities are of continuous white noise."""

    use_turn_rate: bool = False
    """Add the turn rate ``omega`` to the state (constant turn rate and velocity); False is the paper's
    eq. 2 with ``u1 = 0``."""
    accel_noise: float = 0.5
    """Tangential acceleration noise on eq. 2e (m/s^2/sqrt(Hz))."""
    heading_noise: float = 0.3
    """Heading-rate noise on eq. 2d (rad/s/sqrt(Hz)); with ``use_turn_rate`` keep it small."""
    turn_accel_noise: float = 0.3
    """Noise on d(omega)/dt (rad/s^2/sqrt(Hz)), used with ``use_turn_rate``."""
    turn_jerk_noise: float = 0.0
    """Noise on the rate of the lateral acceleration ``v_t omega`` (m/s^3/sqrt(Hz)), used with
    ``use_turn_rate``: it adds about ``turn_jerk_noise / v_t`` to the turn acceleration noise (fading at
    rest and above ~6 m/s, :func:`turn_jerk_density`), so that a slow vehicle may change its turn rate
    quickly and a fast one only slowly, as a vehicle whose side force is limited does. 0: off (the fixed
    ``turn_accel_noise``). A tractor entering or leaving its U-turn steps omega by 0.75 rad/s; with 0.1
    rad/s^2/sqrt(Hz) the estimate took 2-3 s to follow, its heading 10-20 deg off meanwhile, while 2.0
    at every speed made the 12 m/s estimate chase each PnP fix."""
    horizontal_noise: float = 0.05
    """Horizontal position random walk (m/s/sqrt(Hz)): pad offset from the vehicle's turning point, slip."""
    vertical_noise: float = 0.05
    """Vertical position random walk on eq. 2c (m/s/sqrt(Hz)): bumps, slopes."""
    use_yaw: bool = False
    """Fuse the measured pad yaw as a measurement of ``theta`` when a measurement carries one."""
    yaw_symmetry: int = 1
    """The tag looks the same after a turn of ``2 pi / yaw_symmetry``; yaw residuals wrap to that."""
    yaw_std: float = 0.1
    """Yaw std (rad) for measurements that carry a yaw but no ``yaw_var``."""
    allow_reverse: bool = False
    """Allow ``v_t < 0``; when False a negative speed is flipped to ``(theta + pi, -v_t)``."""
    gating: bool = True
    """Reject measurements whose innovation fails the chi-square gate."""
    gate_probability: float = 0.999
    """Probability mass of the chi-square gate (3 dof, 4 with yaw)."""
    reinit_after_rejections: int = 5
    """Re-initialise after this many consecutive gate rejections (the track was lost)."""
    init_min_measurements: int = 3
    """Measurements needed for the initial line fit."""
    init_min_span: float = 0.3
    """Time span (s) the initial measurements must cover (but see ``init_max_speed_std_mps``)."""
    init_max_speed_std_mps: float | None = None
    """Initialise before ``init_min_span`` as soon as the line fit determines the velocity this well: the
    standard deviation (m/s) along the fit's worst velocity direction. None: wait for the span. A fast
    platform seen from a climbing vehicle can cross the view in 0.2 s; five fixes at 20 Hz then give
    its velocity to ~0.4 m/s, and waiting for 0.3 s left the filter stationary at the last fix while
    the platform drove out of view (figure-8 at 5 m/s: the mission tracked a point the pad had left)."""
    init_max_span: float = 1.0
    """Older buffered measurements are dropped before the fit (s), so the constant-velocity fit holds."""
    init_speed_prior_std: float = 3.0
    """Speed std (m/s) of the stationary estimate reported before initialisation."""
    init_turn_rate_std: float = 0.5
    """Initial turn-rate std (rad/s) with ``use_turn_rate``."""
    max_step: float = 0.05
    """Longest single propagation step (s)."""
    maneuver_accel_noise: float = 0.0
    """Tangential acceleration noise while the platform manoeuvres (m/s^2/sqrt(Hz)); 0: off, the fixed
    ``accel_noise`` of paper 000. The filter detects a manoeuvre (braking, accelerating) when the
    position innovations of the last ``maneuver_window`` measurements are biased: their sum, which is
    N(0, sum of their covariances) for a consistent filter, fails the chi-square test (3 dof) at
    ``maneuver_probability``; it then uses this noise level for at least ``maneuver_hold_s`` (Bar-Shalom,
    Li, Kirubarajan 2001, Sec. 11.2: an adjustable process noise level, with a whiteness test of the
    innovations). The measurement that reveals the manoeuvre is fused again with it, so the speed estimate
    follows a speed change within a few measurements instead of lagging it by a second or more."""
    maneuver_window: int = 6
    """Innovations summed for the manoeuvre test."""
    maneuver_probability: float = 0.999
    """Chi-square quantile of the manoeuvre test (false alarms with a consistent filter: 1 - this)."""
    maneuver_hold_s: float = 0.5
    """The manoeuvre noise level stays this long after the last detection (s)."""

    def __post_init__(self) -> None:
        for name in (
            "accel_noise",
            "heading_noise",
            "turn_accel_noise",
            "horizontal_noise",
            "vertical_noise",
            "maneuver_accel_noise",
            "turn_jerk_noise",
            "maneuver_hold_s",
        ):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"{name} must be finite and >= 0, got {v}")
        for name in (
            "yaw_std",
            "init_min_span",
            "init_max_span",
            "init_speed_prior_std",
            "init_turn_rate_std",
            "max_step",
        ):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{name} must be finite and > 0, got {v}")
        if not 0.0 < self.gate_probability < 1.0:
            raise ValueError(f"gate_probability must be in (0, 1), got {self.gate_probability}")
        if self.yaw_symmetry < 1:
            raise ValueError(f"yaw_symmetry must be >= 1, got {self.yaw_symmetry}")
        if self.reinit_after_rejections < 1:
            raise ValueError(f"reinit_after_rejections must be >= 1, got {self.reinit_after_rejections}")
        if self.init_min_measurements < 2:
            raise ValueError(f"init_min_measurements must be >= 2, got {self.init_min_measurements}")
        if self.init_max_speed_std_mps is not None and not (
            math.isfinite(self.init_max_speed_std_mps) and self.init_max_speed_std_mps > 0.0
        ):
            raise ValueError(
                f"init_max_speed_std_mps must be finite and > 0 or None, got {self.init_max_speed_std_mps}"
            )
        if self.init_max_span < self.init_min_span:
            raise ValueError("init_max_span must be >= init_min_span")
        if self.maneuver_window < 1:
            raise ValueError(f"maneuver_window must be >= 1, got {self.maneuver_window}")
        if not 0.0 < self.maneuver_probability < 1.0:
            raise ValueError(f"maneuver_probability must be in (0, 1), got {self.maneuver_probability}")

    @property
    def state_dim(self) -> int:
        return 6 if self.use_turn_rate else 5

    def noise_vector(self) -> FloatArray:
        """The densities in the order :func:`unicycle_process_noise` takes them, (6,)."""
        return np.array(
            [
                self.accel_noise,
                self.heading_noise,
                self.turn_accel_noise,
                self.horizontal_noise,
                self.vertical_noise,
                self.turn_jerk_noise,
            ]
        )


@dataclass(frozen=True, slots=True)
class _Buffered:
    t: float
    p: FloatArray
    cov: FloatArray


class PlatformEkf:
    """Platform estimator of paper 000 Sec. II-C (see the module docstring for the design)."""

    def __init__(
        self, config: PlatformEkfConfig | None = None, telemetry: TelemetryFusionConfig | None = None
    ) -> None:
        self.config = config if config is not None else PlatformEkfConfig()
        # The telemetry link's bias belongs to the link, not to the track: reset() keeps it.
        self.telemetry = TelemetryBias(telemetry)
        self.n_telemetry_fused = 0
        """Telemetry fixes fused (not counting those buffered for the initial fit)."""
        self.n_telemetry_skipped = 0
        """Fixes not fused: stale, adding nothing beyond the bias's uncertainty, or gated out."""
        c = self.config
        n = c.state_dim
        self._n = n
        self._q = c.noise_vector()
        self._q_maneuver = self._q.copy()
        self._q_maneuver[0] = max(c.maneuver_accel_noise, c.accel_noise)
        self._maneuver_gate = float(chdtri(3, 1.0 - c.maneuver_probability))
        self._gate3 = float(chdtri(3, 1.0 - c.gate_probability))
        self._gate4 = float(chdtri(4, 1.0 - c.gate_probability))
        self._yaw_period = 2.0 * math.pi / c.yaw_symmetry
        self._x = np.zeros(n)
        self._P = np.zeros((n, n))
        self._xo = np.zeros(n)
        self._Po = np.zeros((n, n))
        self._z = np.zeros(4)
        self._R4 = np.zeros((4, 4))
        self._info = np.zeros(1 + 5 + 25)
        self.reset()

    # ---- lifecycle --------------------------------------------------------------------------------

    def reset(self) -> None:
        """Forget everything (the filter is as new)."""
        self._x[:] = 0.0
        self._P[:, :] = 0.0
        self._t = math.nan
        self._t_now = math.nan
        self._initialized = False
        self._buffer: list[_Buffered] = []
        self._rejected: list[_Buffered] = []
        self._last: _Buffered | None = None
        self._consecutive_rejections = 0
        self._t_heard = -math.inf
        """Time of the last telemetry fix that agreed with the estimate but was not fused (it would have
        added nothing): the estimate is as fresh as that fix (-inf without telemetry)."""
        self.n_updates = 0
        """Measurements fused by the EKF (not counting those used by the initial fit)."""
        self.n_rejected = 0
        """Measurements rejected by the gate."""
        self.n_out_of_order = 0
        """Measurements captured before the filter's internal time, ignored."""
        self.n_reinitializations = 0
        """Times the track was dropped after consecutive gate rejections (or out-of-order measurements)."""
        self.n_future = 0
        """Measurements stamped more than ``FUTURE_TOLERANCE_S`` after the clock given to ``predict``."""
        self._late: list[_Buffered] = []
        self.last_mahalanobis2 = math.nan
        """Squared Mahalanobis distance of the last innovation (chi-square, 3 or 4 dof when consistent)."""
        self._innovations: list[tuple[FloatArray, FloatArray]] = []
        self._maneuver_until = -math.inf
        self.n_maneuvers = 0
        """Manoeuvres detected (``maneuver_accel_noise``): the noise level went up."""

    def set_state(self, t: float, x: FloatArray, P: FloatArray) -> None:
        """Initialise from an external estimate: ``x`` (n,), ``P`` (n, n) at time ``t`` (s)."""
        xa = np.asarray(x, dtype=np.float64)
        Pa = np.asarray(P, dtype=np.float64)
        n = self._n
        if xa.shape != (n,) or Pa.shape != (n, n):
            raise EstimationError(f"set_state needs x ({n},) and P ({n}, {n}), got {xa.shape} and {Pa.shape}")
        if not (np.isfinite(xa).all() and np.isfinite(Pa).all() and math.isfinite(t)):
            raise EstimationError("set_state: inputs must be finite")
        self.reset()
        self._x[:] = xa
        self._P[:, :] = 0.5 * (Pa + Pa.T)
        self._t = float(t)
        self._initialized = True
        self._last = _Buffered(float(t), xa[:3].copy(), Pa[:3, :3].copy())

    # ---- filter steps -----------------------------------------------------------------------------

    def predict(self, t: float) -> None:
        """Record the caller's clock ``t`` (s). The filter itself stays at its last measurement (see the
        module docstring); :meth:`state` and :meth:`predict_ahead` extrapolate on demand."""
        self._t_now = check_time(t, "PlatformEkf.predict")

    def update(self, measurement: PlatformMeasurement) -> bool:
        """Fuse a measurement (its ``t`` is the capture time). Returns True when it was used (fused, or
        buffered for initialisation), False when rejected (out of order, or gated out)."""
        t, p, cov = check_measurement(measurement, "PlatformEkf.update")  # alight.estimation.guards
        yaw = measurement.yaw
        if p.shape != (3,) or cov.shape != (3, 3):
            raise EstimationError(
                f"PlatformEkf.update: p_WP (3,) and cov_p_WP (3, 3) expected, got {p.shape}, {cov.shape}"
            )
        if not (math.isfinite(t) and math.isfinite(float(p.sum())) and math.isfinite(float(cov.sum()))):
            raise EstimationError(f"PlatformEkf.update: non-finite measurement at t={t}")
        use_yaw = self.config.use_yaw and yaw is not None
        if use_yaw and yaw is not None:  # (use_yaw implies it; said again for the type checker)
            yaw_var = measurement.yaw_var if measurement.yaw_var is not None else self.config.yaw_std**2
            if not (math.isfinite(yaw) and math.isfinite(yaw_var) and yaw_var > 0.0):
                raise EstimationError(f"PlatformEkf.update: yaw {yaw} / yaw_var {yaw_var} invalid at t={t}")
        if t > self._t_now + FUTURE_TOLERANCE_S:  # False while there is no clock (NaN)
            self.n_future += 1
            return False
        if t < self._t:  # False while self._t is NaN (nothing seen yet)
            self.n_out_of_order += 1
            self._note_late(_Buffered(t, p.copy(), cov.copy()))
            return False
        self._late.clear()
        # kept for initialisation and re-initialisation: own the data unless the message froze it
        meas = _Buffered(t, p.copy() if p.flags.writeable else p, cov.copy() if cov.flags.writeable else cov)
        if not self._initialized:
            self._last = meas
            self._t = t
            self._buffer.append(meas)
            self._try_initialize()
            return True
        m = 4 if use_yaw else 3
        self._z[0:3] = p
        R = self._R4
        R[0:3, 0:3] = cov
        if use_yaw:
            self._z[3] = yaw
            R[3, 0:3] = 0.0
            R[0:3, 3] = 0.0
            R[3, 3] = yaw_var
        Rm = R if m == 4 else R[0:3, 0:3].copy()
        gate = (self._gate4 if m == 4 else self._gate3) if self.config.gating else 0.0
        z = self._z[:m].copy()
        maneuvering = t <= self._maneuver_until
        status = self._update_kernel(t, z, Rm, m, gate, maneuvering)
        self.last_mahalanobis2 = float(self._info[0])
        if status != NOT_POSITIVE_DEFINITE and self._maneuver_detected(t, m) and not maneuvering:
            # the measurement that revealed the manoeuvre is fused with the manoeuvre's noise level
            status = self._update_kernel(t, z, Rm, m, gate, True)
            self.last_mahalanobis2 = float(self._info[0])
        if status == NOT_POSITIVE_DEFINITE:
            raise EstimationError(f"PlatformEkf.update: innovation covariance not positive definite at t={t}")
        if status == REJECTED:
            self.n_rejected += 1
            self._consecutive_rejections += 1
            self._rejected.append(meas)
            if self._consecutive_rejections >= self.config.reinit_after_rejections:
                self._reinitialize()
            return False
        self._x, self._xo = self._xo, self._x
        self._P, self._Po = self._Po, self._P
        self._t = t
        self._last = meas
        self._consecutive_rejections = 0
        self._rejected.clear()
        self.n_updates += 1
        return True

    def _update_kernel(
        self, t: float, z: FloatArray, R: FloatArray, m: int, gate: float, maneuvering: bool
    ) -> int:
        q = self._q_maneuver if maneuvering else self._q
        return int(
            platform_update_kernel(
                self._x,
                self._P,
                t - self._t,
                z,
                R,
                m,
                q,
                self.config.max_step,
                self._yaw_period,
                gate,
                not self.config.allow_reverse,
                self._xo,
                self._Po,
                self._info,
            )  # fmt: skip
        )

    def _maneuver_detected(self, t: float, m: int) -> bool:
        """Record the last innovation's distance; True when the window's sum fails the manoeuvre test
        (then the manoeuvre noise level holds until ``t + maneuver_hold_s``)."""
        c = self.config
        if c.maneuver_accel_noise <= c.accel_noise:
            return False
        info = self._info
        r = info[1:4].copy()
        S = info[1 + m : 1 + m + m * m].reshape(m, m)[0:3, 0:3].copy()
        window = self._innovations
        window.append((r, S))
        if len(window) > c.maneuver_window:
            window.pop(0)
        if len(window) < c.maneuver_window:
            return False
        # A consistent filter's innovations are white, zero mean, with covariances S_k: their sum over the
        # window is N(0, sum S_k). A manoeuvre the model does not have biases them all the same way, so
        # the sum grows like N while the noise grows like sqrt(N).
        r_sum = sum((w[0] for w in window), np.zeros(3))
        S_sum = sum((w[1] for w in window), np.zeros((3, 3)))
        try:
            d2 = float(r_sum @ np.linalg.solve(S_sum, r_sum))
        except np.linalg.LinAlgError:
            return False
        if not d2 > self._maneuver_gate:
            return False
        if t > self._maneuver_until:
            self.n_maneuvers += 1
        self._maneuver_until = t + c.maneuver_hold_s
        window.clear()
        return True

    @property
    def maneuvering(self) -> bool:
        """True while the manoeuvre noise level is in use (``maneuver_accel_noise``)."""
        return math.isfinite(self._t) and self._t <= self._maneuver_until

    def _note_late(self, meas: _Buffered) -> None:
        """Keep a run of measurements far before the filter's time; a long enough run, in order among
        itself, means the filter's time came from a measurement stamped in the future: restart from it."""
        if meas.t >= self._t - FUTURE_TOLERANCE_S:
            return  # slightly late: an ordinary out-of-order delivery
        if self._late and meas.t < self._late[-1].t:
            self._late.clear()
        self._late.append(meas)
        if len(self._late) >= self.config.reinit_after_rejections:
            self._rejected = self._late
            self._late = []
            self._reinitialize()

    # ---- telemetry (estimation/telemetry.py) ------------------------------------------------------

    def learn_telemetry_bias(self, measurement: PlatformMeasurement) -> None:
        """A camera measurement that was used: a measurement of the telemetry bias when a fix near its
        capture time exists (nothing happens without telemetry)."""
        if self.telemetry.has_fix:
            self.telemetry.on_camera(float(measurement.t), measurement.p_WP, measurement.cov_p_WP)

    def update_telemetry(self, t_stamp: float, p_WP: FloatArray, v_WP: FloatArray, cov: FloatArray) -> bool:
        """Fuse the platform's own fix taken at ``t_stamp`` (position (3,) m, velocity (3,) m/s, the
        receiver's covariance (3, 3) m^2); it may arrive late. True when fused or buffered.

        The fix is carried on its velocity to the time it is fused at, ``max(filter time, t_stamp -
        time_guard_s)`` (the filter's time never moves past what a later camera measurement may have been
        captured at), the bias estimate removed and its covariance added. Before the filter has a track
        the fix goes into the initial line fit like a camera measurement; after, it is fused as a position
        measurement unless the filter is already more certain than the bias is known
        (:func:`telemetry_adds_information`). A gated-out fix is skipped, never counted toward
        re-initialisation: the camera, not the telemetry, decides that the track is lost."""
        # the camera path's rules (alight.estimation.guards), and no fix from beyond the clock's tolerance
        where = "PlatformEkf.update_telemetry"
        t_stamp = check_clock(t_stamp, self._t_now, where)
        p = check_vector(p_WP, 3, MAX_POSITION_M, "p_WP", where)
        v = check_vector(v_WP, 3, MAX_SPEED_MPS, "v_WP", where)
        c = check_covariance(cov, 3, where, "cov")
        tc = self.telemetry.config
        self.telemetry.add_fix(t_stamp, p, v, c)
        t_fuse = t_stamp - tc.time_guard_s
        if math.isfinite(self._t):
            t_fuse = max(t_fuse, self._t)
        if abs(t_fuse - t_stamp) > tc.max_carry_s:
            self.n_telemetry_skipped += 1
            return False
        # carried along the estimated turn: its position on the arc and its heading turned with it
        omega = float(self._x[I_OMEGA]) if self.config.use_turn_rate and self._initialized else 0.0
        p_c, v, c_c = carry_fix_on_turn(t_stamp, p, v, c, t_fuse, tc.velocity_std_mps, omega)
        z, R = self.telemetry.corrected(p_c, c_c, t_fuse)
        if not self._initialized:
            was = self._initialized
            used = self.update(PlatformMeasurement(t=t_fuse, p_WP=z, cov_p_WP=R))
            if self._initialized and not was:
                # the fit treated the fixes' common bias as independent noise: put it back
                self._P[0:3, 0:3] += self.telemetry.P
            return used
        dt = t_fuse - self._t
        platform_propagate(self._x, self._P, dt, self._q, self.config.max_step, self._xo, self._Po)
        if not telemetry_adds_information(self._Po[0:2, 0:2], self.telemetry.P[0:2, 0:2]):
            self.n_telemetry_skipped += 1
            # not fused, but heard: if it agrees with the estimate (within the gate), the estimate is
            # confirmed as of its time (the mission's estimate age)
            r = z - self._xo[0:3]
            S = self._Po[0:3, 0:3] + R
            if not self.config.gating or float(r @ np.linalg.solve(S, r)) <= self._gate3:
                self._t_heard = max(self._t_heard, t_fuse)
            self._fuse_fix(t_fuse, z, R, v, position=False)
            return True
        return self._fuse_fix(t_fuse, z, R, v, position=True)

    def _fuse_fix(
        self, t_fuse: float, z: FloatArray, R: FloatArray, v_WP: FloatArray, *, position: bool
    ) -> bool:
        """Fuse a fix at ``t_fuse``: its position ``z`` (3,) with covariance ``R`` unless not
        ``position``, and its horizontal velocity as heading and speed when it is fast enough for a
        heading (``telemetry_velocity_min_mps``). The velocity carries no bias, so it is fused even when
        the position adds nothing; the kernel measures the first m states, so a position left out gets a
        variance large enough to carry no weight."""
        tc = self.telemetry.config
        speed = float(math.hypot(v_WP[0], v_WP[1]))
        m = 5 if speed >= tc.velocity_min_mps else 3
        if m == 3 and not position:
            return False
        zz = np.empty(m)
        zz[0:3] = z
        Rm = np.zeros((m, m))
        Rm[0:3, 0:3] = R if position else np.eye(3) * 1e6
        if m == 5:
            sv2 = tc.velocity_std_mps**2
            zz[3] = math.atan2(v_WP[1], v_WP[0])
            zz[4] = speed
            Rm[3, 3] = sv2 / speed**2  # the heading's variance, linearised: sigma_v^2 / |v|^2
            Rm[4, 4] = sv2
        gate = float(chdtri(m, 1.0 - self.config.gate_probability)) if self.config.gating else 0.0
        status = platform_update_kernel(
            self._x, self._P, t_fuse - self._t, zz, Rm, m, self._q, self.config.max_step, 2.0 * math.pi,
            gate, not self.config.allow_reverse, self._xo, self._Po, self._info,
        )  # fmt: skip
        if status != OK:
            self.n_telemetry_skipped += 1
            return False
        self._x, self._xo = self._xo, self._x
        self._P, self._Po = self._Po, self._P
        self._t = t_fuse
        if position:
            self._last = _Buffered(t_fuse, z, R)
        self.n_telemetry_fused += 1
        return True

    def _reinitialize(self) -> None:
        rejected = self._rejected
        self.n_reinitializations += 1
        self._innovations.clear()
        self._initialized = False
        self._consecutive_rejections = 0
        self._rejected = []
        self._buffer = list(rejected)
        self._last = rejected[-1]
        self._t = rejected[-1].t
        self._try_initialize()

    def _try_initialize(self) -> None:
        """Weighted least-squares line fit over the buffer (constant velocity in xy, constant z)."""
        c = self.config
        buf = self._buffer
        t_ref = buf[-1].t
        while t_ref - buf[0].t > c.init_max_span:
            buf.pop(0)
        if len(buf) < c.init_min_measurements:
            return
        spanned = t_ref - buf[0].t >= c.init_min_span
        if not spanned and c.init_max_speed_std_mps is None:
            return
        ts = np.array([b.t for b in buf])
        ps = np.array([b.p for b in buf])
        covs = np.array([b.cov for b in buf])
        fit = fit_constant_velocity(ts, ps, covs, t_ref)
        if fit is None:
            return
        beta, C, d2 = fit
        # an outlier among the first measurements would bend the fit: drop the worst and wait
        if c.gating and d2.max() > self._gate3:
            buf.pop(int(np.argmax(d2)))
            return
        if not spanned:
            # the short window is enough only when it pins the velocity down (largest eigenvalue of the
            # fit's velocity covariance, so no direction is left unknown)
            assert c.init_max_speed_std_mps is not None
            if float(np.linalg.eigvalsh(C[3:5, 3:5])[-1]) > c.init_max_speed_std_mps**2:
                return
        x5, P5 = unicycle_from_fit(beta, C)
        n = self._n
        x = np.zeros(n)
        x[0:5] = x5
        P = np.zeros((n, n))
        P[0:5, 0:5] = P5
        if n == 6:
            P[5, 5] = c.init_turn_rate_std**2
        # the fit assumes constant velocity over the window; add what the process noise did meanwhile
        Q = np.zeros((n, n))
        unicycle_process_noise(x, t_ref - buf[0].t, self._q, Q)
        P += Q
        self._x[:] = x
        self._P[:, :] = 0.5 * (P + P.T)
        self._t = t_ref
        self._initialized = True
        self._buffer = []

    # ---- outputs ----------------------------------------------------------------------------------

    @property
    def initialized(self) -> bool:
        """True once heading and speed are estimated (after the initial fit)."""
        return self._initialized

    @property
    def has_measurement(self) -> bool:
        """True once any measurement arrived since the last reset (:meth:`state` works)."""
        return self._last is not None

    @property
    def t_filter(self) -> float:
        """Internal time (s): capture time of the last measurement used (NaN before any)."""
        return self._t

    @property
    def t_now(self) -> float:
        """The clock last given to :meth:`predict` (s)."""
        return self._t_now

    @property
    def x(self) -> FloatArray:
        """State at ``t_filter``: ``[p_x, p_y, p_z, theta, v_t(, omega)]``."""
        return self._x.copy()

    @property
    def covariance(self) -> FloatArray:
        """State covariance at ``t_filter``, (n, n)."""
        return self._P.copy()

    def propagated(self, t: float) -> tuple[FloatArray, FloatArray]:
        """State ``x`` (n,) and covariance (n, n) extrapolated to ``t`` (s), filter unchanged."""
        if not self._initialized:
            raise EstimationError("PlatformEkf.propagated: not initialised")
        check_time(t, "PlatformEkf")
        xo = np.empty(self._n)
        Po = np.empty((self._n, self._n))
        dt = t - self._t
        # bounded work for any gap: integrate up to the horizon, grow the uncertainty beyond it
        excess = abs(dt) - MAX_HORIZON_S
        if excess > 0.0:
            dt = math.copysign(MAX_HORIZON_S, dt)
        q = self._q_maneuver if self.maneuvering else self._q
        platform_propagate(self._x, self._P, dt, q, self.config.max_step, xo, Po)
        if excess > 0.0:
            grow = (self.config.init_speed_prior_std * excess) ** 2
            Po[0, 0] += grow
            Po[1, 1] += grow
        return xo, Po

    def state(self, t: float) -> PlatformEstimate:
        """The platform at time ``t`` (s), extrapolated from the last measurement with the model.

        Before initialisation: stationary at the last measurement, with its covariance plus
        ``(init_speed_prior_std * age)^2`` horizontally and yaw 0 (unknown). Raises EstimationError
        before any measurement.
        """
        last = self._last
        if last is None:
            raise EstimationError("PlatformEkf.state: no measurement yet")
        t = check_time(t, "PlatformEkf.state")
        if not self._initialized:
            cov = last.cov.copy()
            grow = (self.config.init_speed_prior_std * abs(t - last.t)) ** 2
            cov[0, 0] += grow
            cov[1, 1] += grow
            z = np.zeros(3)
            return PlatformEstimate(
                t=t, p_WP=last.p, v_WP=z, a_WP=z, yaw=0.0, cov_p_WP=cov, t_last_measurement=last.t
            )
        x, P = self.propagated(t)
        p, v, a, yaw = self._ahead(x, np.zeros(1))
        # fresh arrays of this call, owned by nobody else: no copies needed
        return PlatformEstimate.trusted(
            t, p[0].copy(), v[0].copy(), a[0].copy(), float(yaw[0]), P[0:3, 0:3].copy(),
            max(self._t, self._t_heard),
        )  # fmt: skip

    @staticmethod
    def _ahead(x: FloatArray, dts: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        k = dts.shape[0]
        p = np.empty((k, 3))
        v = np.empty((k, 3))
        a = np.empty((k, 3))
        yaw = np.empty(k)
        unicycle_predict_ahead(x, dts, p, v, a, yaw)
        return p, v, a, yaw

    def predict_ahead(self, times: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Platform at the absolute times ``times`` (k,) (s) by the closed-form model (eq. 2), from the
        last measurement: positions (k, 3) m, velocities (k, 3) m/s, accelerations (k, 3) m/s^2,
        headings (k,) rad. Before initialisation: stationary at the last measurement."""
        ts = check_times(times, "PlatformEkf.predict_ahead")
        last = self._last
        if last is None:
            raise EstimationError("PlatformEkf.predict_ahead: no measurement yet")
        if not self._initialized:
            k = ts.shape[0]
            return np.tile(last.p, (k, 1)), np.zeros((k, 3)), np.zeros((k, 3)), np.zeros(k)
        # closed form, so any horizon costs the same; clipped so that no time overflows the model
        return self._ahead(self._x, np.clip(ts - self._t, -MAX_HORIZON_S, MAX_HORIZON_S))

    def position_covariance_ahead(self, times: FloatArray) -> FloatArray:
        """Position covariance (k, 3, 3) (m^2) at the absolute ``times`` (k,), for planners that weigh
        the prediction's uncertainty."""
        if not self._initialized:
            raise EstimationError("PlatformEkf.position_covariance_ahead: not initialised")
        ts = check_times(times, "PlatformEkf.position_covariance_ahead")
        dts = ts - self._t
        out = np.empty((ts.shape[0], 3, 3))
        _position_covariance_ahead(self._x, self._P, dts, np.argsort(dts), self._q, self.config.max_step, out)
        return out

    def diagnostics(self) -> dict[str, Any]:
        """Counters for logs."""
        return {
            "n_updates": self.n_updates,
            "n_rejected": self.n_rejected,
            "n_out_of_order": self.n_out_of_order,
            "n_reinitializations": self.n_reinitializations,
            "n_future": self.n_future,
            "n_telemetry_fused": self.n_telemetry_fused,
            "n_telemetry_skipped": self.n_telemetry_skipped,
        }
