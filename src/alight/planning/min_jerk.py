"""The minimum-jerk motion primitive of Mueller, Hehn and D'Andrea ("A computationally efficient motion
primitive for quadrocopter trajectory generation", IEEE T-RO 31(6), 2015), which paper 000 (Falanga et al.
2017, Sec. II-D) plans with, and its two feasibility tests.

Written from the verified reference sheet ``shared/references/min_jerk_primitive.md`` (the paper's
symbols alpha, beta, gamma are kept). Per axis, with the initial state (p0, v0, a0) and duration T::

    jerk(t) = gamma + beta t + alpha t^2 / 2
    acc(t)  = a0 + gamma t + beta t^2 / 2 + alpha t^3 / 6
    vel(t)  = v0 + a0 t + gamma t^2 / 2 + beta t^3 / 6 + alpha t^4 / 24
    pos(t)  = p0 + v0 t + a0 t^2 / 2 + gamma t^3 / 6 + beta t^4 / 24 + alpha t^5 / 120

Everything that runs per candidate is a numba kernel over arrays of N candidates (coefficients ``(N, 3)``,
durations ``(N,)``); the Python functions here only check shapes and allocate the outputs.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from alight.numerics.poly import positive_real_roots_into, quadratic_roots
from alight.types import GRAVITY_MPS2, FloatArray

__all__ = [
    "EndConstraint",
    "InputFeasibility",
    "CandidateBatch",
    "MinJerkTrajectory",
    "min_jerk_coefficients",
    "min_jerk_cost",
    "input_feasibility",
    "floor_feasibility",
    "evaluate_candidates",
]


class EndConstraint(enum.IntEnum):
    """Which final-state components a primitive fixes (the others are left free and optimised)."""

    POS_VEL_ACC = 0
    """Final position, velocity and acceleration fixed."""
    POS_VEL = 1
    """Final position and velocity fixed, final acceleration free (paper 000's tracking case)."""
    POS = 2
    """Final position fixed, velocity and acceleration free."""


class InputFeasibility(enum.IntEnum):
    """Verdict of the recursive input-feasibility test (Mueller et al. 2015, Sec. III-A).

    There is no "infeasible because of the body rates" verdict: ``|jerk| / f`` only bounds the rates from
    above, so exceeding it never proves a violation. A section whose rate bound is too large is split, and
    the test ends as INDETERMINABLE once the sections reach the minimum length.
    """

    FEASIBLE = 0
    """Proven to keep the thrust in [f_min, f_max] and the rate bound |jerk|/f <= w_max throughout."""
    INDETERMINABLE = 1
    """Ran out of resolution (minimum section length) before proving or disproving."""
    INFEASIBLE_THRUST_HIGH = 2
    """The thrust exceeds f_max somewhere (proven)."""
    INFEASIBLE_THRUST_LOW = 3
    """The thrust falls below f_min somewhere (proven)."""


# --------------------------------------------------------------------------------------------------
# Kernels. Starting states come as (M, 3) arrays with M = 1 (shared by all candidates) or M = N.
# --------------------------------------------------------------------------------------------------

_G = (0.0, 0.0, -GRAVITY_MPS2)  # g_W in the z-up world; thrust is |acc - g|
_STACK_SIZE = 128  # enough for T / min_section up to 2^60: the stack holds at most depth + 1 sections


@njit(cache=True)
def _coefficients_kernel(p0, v0, a0, T, pf, vf, af, mode, alpha, beta, gamma):  # pragma: no cover
    """Closed-form optimal coefficients (sheet, "The trajectory, per axis"). Writes alpha/beta/gamma."""
    n = T.shape[0]
    ms = p0.shape[0] > 1
    me = af.shape[0] > 1
    for i in range(n):
        s = i if ms else 0
        e = i if me else 0
        t = T[i]
        t2 = t * t
        t3 = t2 * t
        t4 = t3 * t
        it5 = 1.0 / (t4 * t)
        for k in range(3):
            dp = pf[i, k] - p0[s, k] - v0[s, k] * t - 0.5 * a0[s, k] * t2
            if mode == 2:
                alpha[i, k] = 20.0 * dp * it5
                beta[i, k] = -20.0 * dp * it5 * t
                gamma[i, k] = 10.0 * dp * it5 * t2
                continue
            dv = vf[i, k] - v0[s, k] - a0[s, k] * t
            if mode == 1:
                alpha[i, k] = (320.0 * dp - 120.0 * t * dv) * it5
                beta[i, k] = (-200.0 * t * dp + 72.0 * t2 * dv) * it5
                gamma[i, k] = (40.0 * t2 * dp - 12.0 * t3 * dv) * it5
            else:
                da = af[e, k] - a0[s, k]
                alpha[i, k] = (720.0 * dp - 360.0 * t * dv + 60.0 * t2 * da) * it5
                beta[i, k] = (-360.0 * t * dp + 168.0 * t2 * dv - 24.0 * t3 * da) * it5
                gamma[i, k] = (60.0 * t2 * dp - 24.0 * t3 * dv + 3.0 * t4 * da) * it5


@njit(cache=True)
def _cost_one(alpha, beta, gamma, i, t):  # pragma: no cover
    """J = (1/T) int_0^T |jerk|^2 dt, summed over the axes (sheet, "Cost")."""
    t2 = t * t
    j = 0.0
    for k in range(3):
        a = alpha[i, k]
        b = beta[i, k]
        g = gamma[i, k]
        j += (
            g * g
            + b * g * t
            + b * b * t2 / 3.0
            + a * g * t2 / 3.0
            + a * b * t2 * t / 4.0
            + a * a * t2 * t2 / 20.0
        )
    return j


@njit(cache=True)
def _cost_kernel(alpha, beta, gamma, T, out):  # pragma: no cover
    for i in range(T.shape[0]):
        out[i] = _cost_one(alpha, beta, gamma, i, T[i])


@njit(cache=True)
def _thrust_sq(a0, s, alpha, beta, gamma, i, t):  # pragma: no cover
    """|acc(t) - g|^2, the squared mass-normalised collective thrust."""
    f2 = 0.0
    for k in range(3):
        a = a0[s, k] + t * (gamma[i, k] + t * (0.5 * beta[i, k] + t * alpha[i, k] / 6.0)) - _G[k]
        f2 += a * a
    return f2


@njit(cache=True)
def _section_verdict(a0, s, alpha, beta, gamma, i, t1, t2, fmin, fmax, wmax):  # pragma: no cover
    """Steps 2-7 of the sheet's input test on the section [t1, t2]; -1 means "split"."""
    fmin2 = fmin * fmin
    fmax2 = fmax * fmax
    # Step 2: the thrust at the section's ends.
    ft1 = _thrust_sq(a0, s, alpha, beta, gamma, i, t1)
    ft2 = _thrust_sq(a0, s, alpha, beta, gamma, i, t2)
    if ft1 > fmax2 or ft2 > fmax2:
        return 2
    if ft1 < fmin2 or ft2 < fmin2:
        return 3
    up2 = 0.0  # upper bound on f^2
    lo2 = 0.0  # lower bound on f^2
    jm2 = 0.0  # upper bound on |jerk|^2
    for k in range(3):
        al = alpha[i, k]
        be = beta[i, k]
        ga = gamma[i, k]
        a0k = a0[s, k] - _G[k]
        # Step 3: bound acc_k - g_k by its values at t1, t2 and at the roots of jerk_k inside.
        x1 = a0k + t1 * (ga + t1 * (0.5 * be + t1 * al / 6.0))
        x2 = a0k + t2 * (ga + t2 * (0.5 * be + t2 * al / 6.0))
        lo = min(x1, x2)
        hi = max(x1, x2)
        # roots of jerk_k = (al/2) t^2 + be t + ga (cancellation-free; a double root at 0 is never
        # inside since t1 >= 0)
        _, r1, r2 = quadratic_roots(0.5 * al, be, ga)
        for r in (r1, r2):
            if t1 < r < t2:  # False for a missing root (NaN)
                x = a0k + r * (ga + r * (0.5 * be + r * al / 6.0))
                lo = min(lo, x)
                hi = max(hi, x)
        if hi > fmax or -lo > fmax:
            return 2  # one axis alone already needs more thrust than f_max
        up2 += max(lo * lo, hi * hi)
        if lo > 0.0:
            lo2 += lo * lo
        elif hi < 0.0:
            lo2 += hi * hi
        # Step 4: |jerk_k| is largest at an end or at its extremum t = -beta/alpha.
        j1 = ga + t1 * (be + 0.5 * al * t1)
        j2 = ga + t2 * (be + 0.5 * al * t2)
        jm = max(j1 * j1, j2 * j2)
        if al != 0.0:
            te = -be / al
            if t1 < te < t2:
                je = ga + te * (be + 0.5 * al * te)
                jm = max(jm, je * je)
        jm2 += jm
    # Step 5
    if up2 < fmin2:
        return 3
    if lo2 > fmax2:
        return 2
    # Step 6: inconclusive thrust bounds, or rate bound sqrt(jm2 / lo2) > wmax (infinite when lo2 ~ 0)
    if lo2 < fmin2 or up2 > fmax2 or lo2 <= 1e-12 or jm2 > wmax * wmax * lo2:
        return -1
    return 0  # Step 7


@njit(cache=True)
def _input_one(a0, s, alpha, beta, gamma, i, T, fmin, fmax, wmax, min_section, stack):  # pragma: no cover
    """The recursive test, run iteratively. The recursion answers the first half's verdict unless it is
    FEASIBLE, in which case the second half's: that is the first non-FEASIBLE leaf in time order, so a
    depth-first walk (left half popped first) that stops at the first such leaf gives the same answer."""
    top = 0
    stack[0, 0] = 0.0
    stack[0, 1] = T
    while top >= 0:
        t1 = stack[top, 0]
        t2 = stack[top, 1]
        top -= 1
        if t2 - t1 < min_section:  # Step 1
            return 1
        v = _section_verdict(a0, s, alpha, beta, gamma, i, t1, t2, fmin, fmax, wmax)
        if v > 0:
            return v
        if v < 0:
            tm = 0.5 * (t1 + t2)
            if top + 2 >= stack.shape[0]:  # cannot happen for min_section > T * 2^-120; be safe anyway
                return 1
            top += 1
            stack[top, 0] = tm  # second half, examined after the first
            stack[top, 1] = t2
            top += 1
            stack[top, 0] = t1
            stack[top, 1] = tm
    return 0


@njit(cache=True)
def _input_kernel(a0, alpha, beta, gamma, T, fmin, fmax, wmax, min_section, out):  # pragma: no cover
    stack = np.empty((_STACK_SIZE, 2))
    ms = a0.shape[0] > 1
    for i in range(T.shape[0]):
        out[i] = _input_one(
            a0, i if ms else 0, alpha, beta, gamma, i, T[i], fmin, fmax, wmax, min_section, stack
        )


@njit(cache=True)
def _floor_one(p0, v0, a0, s, alpha, beta, gamma, i, T, q, nrm, work, D):  # pragma: no cover
    """d(t) = n . (pos(t) - q) > 0 on [0, T] (sheet, "Floor feasibility").

    A quick accept first: d on [0, T] is a convex combination of its Bernstein coefficients, so all of
    them positive proves d > 0 (most candidates fly well above the plane and stop here). Otherwise d's
    minimum on [0, T] is at an end (both checked positive first) or at a stationary point inside: d is
    checked at every real root of d' (a quartic) in (0, T] (:mod:`alight.numerics.poly`, which only ever
    produces real roots inside the interval). Checking the maxima too changes nothing: d <= 0 at any
    point means the candidate is infeasible. ``work`` (>= 13) and ``D`` (>= (4, 5)) are work arrays.
    """
    e0 = 0.0
    e1 = 0.0
    e2 = 0.0
    e3 = 0.0
    e4 = 0.0
    e5 = 0.0
    for k in range(3):
        nk = nrm[k]
        e0 += nk * (p0[s, k] - q[k])
        e1 += nk * v0[s, k]
        e2 += nk * a0[s, k]
        e3 += nk * gamma[i, k]
        e4 += nk * beta[i, k]
        e5 += nk * alpha[i, k]
    c0 = e0
    c1 = e1
    c2 = e2 / 2.0
    c3 = e3 / 6.0
    c4 = e4 / 24.0
    c5 = e5 / 120.0
    if c0 <= 0.0:
        return False
    dT = c0 + T * (c1 + T * (c2 + T * (c3 + T * (c4 + T * c5))))
    if dT <= 0.0:
        return False
    # Bernstein coefficients on [0, T] (b0 = d(0), b5 = d(T) are already positive)
    s1 = c1 * T
    s2 = c2 * T * T
    s3 = c3 * T * T * T
    s4 = c4 * T * T * T * T
    if (
        c0 + s1 / 5.0 > 0.0
        and c0 + 2.0 * s1 / 5.0 + s2 / 10.0 > 0.0
        and c0 + 3.0 * s1 / 5.0 + 3.0 * s2 / 10.0 + s3 / 10.0 > 0.0
        and c0 + 4.0 * s1 / 5.0 + 3.0 * s2 / 5.0 + 2.0 * s3 / 5.0 + s4 / 5.0 > 0.0
    ):
        return True
    # d' = c1 + 2 c2 t + 3 c3 t^2 + 4 c4 t^3 + 5 c5 t^4
    d1 = work[0:5]
    roots = work[5:9]
    crit = work[9:13]
    d1[0] = c1
    d1[1] = 2.0 * c2
    d1[2] = 3.0 * c3
    d1[3] = 4.0 * c4
    d1[4] = 5.0 * c5
    nr = positive_real_roots_into(d1, T, roots, D, crit)
    for j in range(nr):
        r = roots[j]
        if c0 + r * (c1 + r * (c2 + r * (c3 + r * (c4 + r * c5)))) <= 0.0:
            return False
    return True


@njit(cache=True)
def _floor_kernel(p0, v0, a0, alpha, beta, gamma, T, q, nrm, out):  # pragma: no cover
    work = np.empty(13)
    D = np.empty((4, 5))
    ms = p0.shape[0] > 1
    for i in range(T.shape[0]):
        out[i] = _floor_one(p0, v0, a0, i if ms else 0, alpha, beta, gamma, i, T[i], q, nrm, work, D)


@njit(cache=True)
def _evaluate_kernel(  # pragma: no cover
    p0, v0, a0, T, pf, vf, af, mode, limits, check_floor, q, nrm, alpha, beta, gamma, cost, codes, floor_ok
):
    """Generation, cost, input test and floor test in one pass. limits = (f_min, f_max, w_max, min_sec)."""
    _coefficients_kernel(p0, v0, a0, T, pf, vf, af, mode, alpha, beta, gamma)
    stack = np.empty((_STACK_SIZE, 2))
    work = np.empty(13)
    D = np.empty((4, 5))
    fmin = limits[0]
    fmax = limits[1]
    wmax = limits[2]
    msec = limits[3]
    ms = p0.shape[0] > 1
    for i in range(T.shape[0]):
        s = i if ms else 0
        t = T[i]
        cost[i] = _cost_one(alpha, beta, gamma, i, t)
        codes[i] = _input_one(a0, s, alpha, beta, gamma, i, t, fmin, fmax, wmax, msec, stack)
        if check_floor:
            floor_ok[i] = _floor_one(p0, v0, a0, s, alpha, beta, gamma, i, t, q, nrm, work, D)
        else:
            floor_ok[i] = True


# A trajectory is stored packed, shape (9, 3): rows p0, v0, a0, alpha, beta, gamma, pf, vf, af.
_P0, _V0, _A0, _AL, _BE, _GA, _PF, _VF, _AF = range(9)


@njit(cache=True)
def _state_at(c, t, out, m):  # pragma: no cover
    """out[m, 0..3] = p, v, a, j of the packed primitive c at 0 <= t <= T."""
    for k in range(3):
        al = c[3, k]
        be = c[4, k]
        ga = c[5, k]
        out[m, 3, k] = ga + t * (be + t * al / 2.0)
        out[m, 2, k] = c[2, k] + t * (ga + t * (be / 2.0 + t * al / 6.0))
        out[m, 1, k] = c[1, k] + t * (c[2, k] + t * (ga / 2.0 + t * (be / 6.0 + t * al / 24.0)))
        out[m, 0, k] = c[0, k] + t * (
            c[1, k] + t * (c[2, k] / 2.0 + t * (ga / 6.0 + t * (be / 24.0 + t * al / 120.0)))
        )


@njit(cache=True)
def _pack_end(c, T):  # pragma: no cover
    """Fill rows pf, vf, af of the packed primitive c from its coefficients."""
    out = np.empty((1, 4, 3))
    _state_at(c, T, out, 0)
    for k in range(3):
        c[6, k] = out[0, 0, k]
        c[7, k] = out[0, 1, k]
        c[8, k] = out[0, 2, k]


@njit(cache=True)
def _sample_into(c, t0, T, t, out, m):  # pragma: no cover
    """out[m] = p, v, a, j at absolute time t. Decided on absolute time, so that t = t0 + T (as the caller
    computes t_end) gives the end state itself: clamped to the start before t0; past t0 + T straight on at
    the final velocity with zero acceleration and jerk."""
    te = t0 + T
    if t > te:
        dt = t - te
        for k in range(3):
            out[m, 0, k] = c[6, k] + c[7, k] * dt
            out[m, 1, k] = c[7, k]
            out[m, 2, k] = 0.0
            out[m, 3, k] = 0.0
    else:
        _state_at(c, min(max(t - t0, 0.0), T), out, m)


@njit(cache=True)
def _sample_packed(c, t0, T, ts):  # pragma: no cover
    out = np.empty((ts.shape[0], 4, 3))
    for m in range(ts.shape[0]):
        _sample_into(c, t0, T, ts[m], out, m)
    return out


@njit(cache=True)
def _sample_one(c, t0, T, t):  # pragma: no cover
    out = np.empty((1, 4, 3))
    _sample_into(c, t0, T, t, out, 0)
    return out[0]


# --------------------------------------------------------------------------------------------------
# Python API
# --------------------------------------------------------------------------------------------------


def _states(x: ArrayLike, name: str, n: int | None = None) -> FloatArray:
    """A (3,) or (M, 3) state as a C-contiguous (M, 3) float64 array (M = 1 or n)."""
    a = np.ascontiguousarray(x, dtype=np.float64)
    if a.ndim == 1:
        a = a.reshape(1, -1)
    if a.ndim != 2 or a.shape[1] != 3 or (n is not None and a.shape[0] not in (1, n)):
        want = "(3,)" if n is None else f"(3,) or ({n}, 3)"
        raise ValueError(f"{name} must have shape {want}, got {np.shape(x)}")
    if not np.isfinite(a).all():
        raise ValueError(f"{name} must be finite")
    if not a.flags.writeable:
        # a writable copy: numba compiles a kernel once per mix of read-only and writable arguments, and
        # callers pass both (the guidance's frozen states, fresh arrays)
        a = a.copy()
    return a


def _durations(T: object) -> FloatArray:
    t = np.ascontiguousarray(T, dtype=np.float64).reshape(-1)
    if t.size == 0 or not np.isfinite(t).all() or not (t > 0.0).all():
        raise ValueError("durations T must be finite and > 0")
    return t


def _coeffs(x: object, name: str, n: int) -> FloatArray:
    a = np.ascontiguousarray(x, dtype=np.float64)
    if a.shape != (n, 3):
        raise ValueError(f"{name} must have shape ({n}, 3), got {a.shape}")
    return a


def _boundary_arrays(
    p0: ArrayLike,
    v0: ArrayLike,
    a0: ArrayLike,
    T: object,
    pf: ArrayLike,
    vf: ArrayLike | None,
    af: ArrayLike | None,
    mode: EndConstraint,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Validated durations (N,) and start/end states as the kernels take them (see the callers)."""
    t = _durations(T)
    n = t.size
    P0, V0, A0 = _states(p0, "p0", n), _states(v0, "v0", n), _states(a0, "a0", n)
    if not (P0.shape[0] == V0.shape[0] == A0.shape[0]):
        raise ValueError("p0, v0 and a0 must have the same shape")
    PF = _states(pf, "pf", n)
    if PF.shape[0] != n:
        raise ValueError(f"pf must have shape ({n}, 3)")
    if mode != EndConstraint.POS and vf is None:
        raise ValueError(f"vf is required for mode {mode.name}")
    if mode == EndConstraint.POS_VEL_ACC and af is None:
        raise ValueError("af is required for mode POS_VEL_ACC")
    VF = _states(vf, "vf", n) if vf is not None else np.zeros((n, 3))
    if VF.shape[0] != n:
        VF = np.ascontiguousarray(np.broadcast_to(VF, (n, 3)))
    AF = _states(af, "af", n) if af is not None else np.zeros((1, 3))
    return t, P0, V0, A0, PF, VF, AF


def min_jerk_coefficients(
    p0: FloatArray,
    v0: FloatArray,
    a0: FloatArray,
    T: FloatArray,
    pf: FloatArray,
    vf: FloatArray | None = None,
    af: FloatArray | None = None,
    mode: EndConstraint = EndConstraint.POS_VEL_ACC,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Coefficients (alpha, beta, gamma), each (N, 3), of the N minimum-jerk primitives.

    Args:
        p0, v0, a0: initial position (m), velocity (m/s), acceleration (m/s^2), (3,) or (N, 3).
        T: durations (s), (N,), > 0.
        pf: final positions (m), (N, 3) (or (3,) when N = 1).
        vf: final velocities (m/s), (N, 3); needed unless ``mode`` is POS.
        af: final accelerations (m/s^2), (3,) or (N, 3); needed for POS_VEL_ACC.
        mode: which final-state components are fixed.
    """
    mode = EndConstraint(mode)
    t, P0, V0, A0, PF, VF, AF = _boundary_arrays(p0, v0, a0, T, pf, vf, af, mode)
    n = t.size
    alpha, beta, gamma = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
    _coefficients_kernel(P0, V0, A0, t, PF, VF, AF, int(mode), alpha, beta, gamma)
    return alpha, beta, gamma


def min_jerk_cost(alpha: FloatArray, beta: FloatArray, gamma: FloatArray, T: FloatArray) -> FloatArray:
    """The cost J = (1/T) int_0^T |jerk|^2 dt (m^2/s^6) of each primitive, shape (N,)."""
    t = _durations(T)
    n = t.size
    out = np.empty(n)
    _cost_kernel(_coeffs(alpha, "alpha", n), _coeffs(beta, "beta", n), _coeffs(gamma, "gamma", n), t, out)
    return out


def input_feasibility(
    a0: FloatArray,
    alpha: FloatArray,
    beta: FloatArray,
    gamma: FloatArray,
    T: FloatArray,
    *,
    f_min: float,
    f_max: float,
    w_max: float,
    min_section_s: float,
) -> NDArray[np.int64]:
    """The recursive input-feasibility test of each primitive (codes of :class:`InputFeasibility`, (N,)).

    Args:
        a0: initial acceleration (m/s^2), (3,) or (N, 3).
        alpha, beta, gamma: coefficients, (N, 3).
        T: durations (s), (N,).
        f_min, f_max: mass-normalised collective thrust limits (m/s^2), 0 <= f_min < f_max.
        w_max: bound on the body rates (rad/s), tested through |jerk| / f <= w_max.
        min_section_s: the shortest section the test splits down to (s) before it answers INDETERMINABLE.
    """
    _check_limits(f_min, f_max, w_max, min_section_s)
    t = _durations(T)
    n = t.size
    out = np.empty(n, dtype=np.int64)
    _input_kernel(
        _states(a0, "a0", n),
        _coeffs(alpha, "alpha", n),
        _coeffs(beta, "beta", n),
        _coeffs(gamma, "gamma", n),
        t,
        float(f_min),
        float(f_max),
        float(w_max),
        float(min_section_s),
        out,
    )
    return out


def _check_limits(f_min: float, f_max: float, w_max: float, min_section_s: float) -> None:
    if not (0.0 <= f_min < f_max and math.isfinite(f_max)):
        raise ValueError(f"need 0 <= f_min < f_max < inf, got f_min={f_min}, f_max={f_max}")
    if not (w_max > 0.0):
        raise ValueError(f"w_max must be > 0, got {w_max}")
    if not (min_section_s > 0.0 and math.isfinite(min_section_s)):
        raise ValueError(f"min_section_s must be > 0, got {min_section_s}")


def _plane(point: ArrayLike, normal: ArrayLike) -> tuple[FloatArray, FloatArray]:
    q = np.asarray(point, dtype=np.float64).reshape(-1)
    nrm = np.asarray(normal, dtype=np.float64).reshape(-1)
    if q.shape != (3,) or nrm.shape != (3,) or not (np.isfinite(q).all() and np.isfinite(nrm).all()):
        raise ValueError("plane point and normal must be finite (3,) vectors")
    ln = math.sqrt(float(nrm @ nrm))
    if ln == 0.0:
        raise ValueError("plane normal must be non-zero")
    return np.ascontiguousarray(q), nrm / ln


def floor_feasibility(
    p0: FloatArray,
    v0: FloatArray,
    a0: FloatArray,
    alpha: FloatArray,
    beta: FloatArray,
    gamma: FloatArray,
    T: FloatArray,
    *,
    point: FloatArray,
    normal: FloatArray,
) -> NDArray[np.bool_]:
    """True where the primitive stays strictly on the normal's side of the plane through ``point`` over
    [0, T] (touching counts as infeasible). Shape (N,), bool. ``normal`` need not be unit length."""
    t = _durations(T)
    n = t.size
    P0, V0, A0 = _states(p0, "p0", n), _states(v0, "v0", n), _states(a0, "a0", n)
    if not (P0.shape[0] == V0.shape[0] == A0.shape[0]):
        raise ValueError("p0, v0 and a0 must have the same shape")
    q, nrm = _plane(point, normal)
    out = np.empty(n, dtype=np.bool_)
    _floor_kernel(
        P0,
        V0,
        A0,
        _coeffs(alpha, "alpha", n),
        _coeffs(beta, "beta", n),
        _coeffs(gamma, "gamma", n),
        t,
        q,
        nrm,
        out,
    )
    return out


class CandidateBatch(NamedTuple):
    """Everything :func:`evaluate_candidates` computes for N candidates."""

    alpha: FloatArray
    """(N, 3) coefficient of t^2/2 in the jerk (m/s^5)."""
    beta: FloatArray
    """(N, 3) coefficient of t in the jerk (m/s^4)."""
    gamma: FloatArray
    """(N, 3) initial jerk (m/s^3)."""
    cost: FloatArray
    """(N,) J (m^2/s^6)."""
    codes: NDArray[np.int64]
    """(N,) int64 :class:`InputFeasibility` codes."""
    floor_ok: NDArray[np.bool_]
    """(N,) bool, floor test passed (all True when no plane is given)."""

    @property
    def feasible(self) -> NDArray[np.bool_]:
        """(N,) bool: input test FEASIBLE and floor test passed (INDETERMINABLE counts as infeasible)."""
        # a typed local: numpy types ndarray == Any
        ok: NDArray[np.bool_] = (self.codes == InputFeasibility.FEASIBLE) & self.floor_ok
        return ok


def evaluate_candidates(
    p0: FloatArray,
    v0: FloatArray,
    a0: FloatArray,
    T: FloatArray,
    pf: FloatArray,
    vf: FloatArray | None = None,
    af: FloatArray | None = None,
    *,
    mode: EndConstraint = EndConstraint.POS_VEL,
    f_min: float,
    f_max: float,
    w_max: float,
    min_section_s: float,
    plane_point: FloatArray | None = None,
    plane_normal: FloatArray | None = None,
) -> CandidateBatch:
    """Generate N primitives from one start (p0, v0, a0 as (3,) or (N, 3)) and evaluate their cost and
    both feasibility tests in a single numba call. Shapes and units as in the functions above; the floor
    test runs when ``plane_point`` is given (``plane_normal`` defaults to +z)."""
    mode = EndConstraint(mode)
    _check_limits(f_min, f_max, w_max, min_section_s)
    t, P0, V0, A0, PF, VF, AF = _boundary_arrays(p0, v0, a0, T, pf, vf, af, mode)
    n = t.size
    check = plane_point is not None
    if plane_point is not None:
        q, nrm = _plane(plane_point, plane_normal if plane_normal is not None else (0.0, 0.0, 1.0))
    else:
        q, nrm = np.zeros(3), np.array([0.0, 0.0, 1.0])
    limits = np.array([f_min, f_max, w_max, min_section_s], dtype=np.float64)
    out = CandidateBatch(
        np.empty((n, 3)),
        np.empty((n, 3)),
        np.empty((n, 3)),
        np.empty(n),
        np.empty(n, np.int64),
        np.empty(n, np.bool_),
    )
    _evaluate_kernel(P0, V0, A0, t, PF, VF, AF, int(mode), limits, check, q, nrm, *out)
    return out


# --------------------------------------------------------------------------------------------------
# One trajectory
# --------------------------------------------------------------------------------------------------


def _vec3(x: ArrayLike, name: str) -> FloatArray:
    a = np.asarray(x, dtype=np.float64).reshape(-1)
    if a.shape != (3,) or not np.isfinite(a).all():
        raise ValueError(f"{name} must be a finite (3,) vector, got shape {np.shape(x)}")
    return a


@dataclass(frozen=True, eq=False)
class MinJerkTrajectory:
    """One minimum-jerk primitive, starting at absolute time ``t0`` and lasting ``T``.

    Outside [t0, t0 + T]: before t0 it is clamped to the initial state; after t0 + T it continues in a
    straight line at the final velocity with zero acceleration and jerk (``p = pf + vf (t - t0 - T)``),
    which is what a vehicle that reached a platform moving at constant velocity should keep doing. With a
    free final acceleration (paper 000's case) the acceleration steps to zero there.

    Instances compare by identity (arrays make field-wise equality ambiguous). The arrays are read-only.
    """

    t0: float
    """Start time (s)."""
    T: float
    """Duration (s), > 0."""
    p0: FloatArray
    """Initial position (m), (3,)."""
    v0: FloatArray
    """Initial velocity (m/s), (3,)."""
    a0: FloatArray
    """Initial acceleration (m/s^2), (3,)."""
    alpha: FloatArray
    """Coefficient of t^2/2 in the jerk (m/s^5), (3,)."""
    beta: FloatArray
    """Coefficient of t in the jerk (m/s^4), (3,)."""
    gamma: FloatArray
    """Initial jerk (m/s^3), (3,)."""
    _packed: FloatArray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.t0) and math.isfinite(self.T) and self.T > 0.0):
            raise ValueError(f"need finite t0 and T > 0, got t0={self.t0}, T={self.T}")
        c = np.empty((9, 3))
        for row, name in enumerate(("p0", "v0", "a0", "alpha", "beta", "gamma")):
            c[row] = _vec3(getattr(self, name), name)
        _pack_end(c, float(self.T))
        self._set(float(self.t0), float(self.T), c)

    def _set(self, t0: float, T: float, c: FloatArray) -> None:
        c.setflags(write=False)
        d = self.__dict__  # frozen: fill the fields directly, as dataclasses' own __init__ does
        d["t0"] = t0
        d["T"] = T
        d["p0"], d["v0"], d["a0"], d["alpha"], d["beta"], d["gamma"] = c[0], c[1], c[2], c[3], c[4], c[5]
        d["_packed"] = c

    @classmethod
    def _from_packed(cls, t0: float, T: float, c: FloatArray) -> MinJerkTrajectory:
        """Trusted fast path for the planner: ``c`` is a fresh, finite (9, 3) array with the end rows set."""
        obj = object.__new__(cls)
        obj._set(t0, T, c)
        return obj

    @classmethod
    def from_boundary(
        cls,
        t0: float,
        T: float,
        p0: FloatArray,
        v0: FloatArray,
        a0: FloatArray,
        pf: FloatArray,
        vf: FloatArray | None = None,
        af: FloatArray | None = None,
    ) -> MinJerkTrajectory:
        """The optimal primitive to (pf, vf, af); components passed as None are left free."""
        if vf is None and af is not None:
            raise ValueError("a fixed final acceleration needs a fixed final velocity")
        mode = (
            EndConstraint.POS
            if vf is None
            else (EndConstraint.POS_VEL if af is None else EndConstraint.POS_VEL_ACC)
        )
        al, be, ga = min_jerk_coefficients(p0, v0, a0, np.array([T]), pf, vf, af, mode)
        return cls(t0, T, p0, v0, a0, al[0], be[0], ga[0])

    @property
    def t_end(self) -> float:
        """Absolute end time t0 + T (s)."""
        return self.t0 + self.T

    @property
    def cost(self) -> float:
        """J = (1/T) int_0^T |jerk|^2 dt (m^2/s^6)."""
        return float(
            min_jerk_cost(self.alpha[None], self.beta[None], self.gamma[None], np.array([self.T]))[0]
        )

    def end_state(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Position (m), velocity (m/s) and acceleration (m/s^2) reached at t0 + T (before the
        acceleration drops to zero), each (3,) read-only."""
        c = self._packed
        return c[_PF], c[_VF], c[_AF]

    def sample(self, t: float) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Position (m), velocity (m/s), acceleration (m/s^2) and jerk (m/s^3) at absolute time t, (3,)."""
        o = _sample_one(self._packed, self.t0, self.T, float(t))
        return o[0], o[1], o[2], o[3]

    def sample_packed(self, t: float) -> FloatArray:
        """As :meth:`sample`, stacked in one new array (4, 3): rows p, v, a, j."""
        o: FloatArray = _sample_one(self._packed, self.t0, self.T, float(t))
        return o

    def sample_many(self, ts: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """As :meth:`sample` at the absolute times ``ts`` (n,): four (n, 3) arrays."""
        o = _sample_packed(
            self._packed, self.t0, self.T, np.ascontiguousarray(ts, dtype=np.float64).reshape(-1)
        )
        return o[:, 0], o[:, 1], o[:, 2], o[:, 3]
