"""Rotations and angles: each formula written once, for numba kernels and Python callers alike.

Conventions (alight's, see :mod:`alight.types`): a quaternion is stored as SciPy stores it, ``(x, y, z,
w)``, scalar last; the product is Hamilton's; ``q_WB`` rotates B-vectors into W (``v_W = R(q_WB) v_B``,
an active rotation). Angles are radians, and :func:`wrap_angle` maps them to ``[-pi, pi)``.

Why one formula with a scale: ``R(q) = I + s [...]`` with ``s = 2 / |q|^2`` is the rotation of any
non-zero ``q``. Callers differ in what they know about ``q``, and each keeps its own arithmetic (so the
simulated missions stay bit-for-bit what they were): the rigid-body model passes ``s = 2 / |q|^2`` (its
RK4 stages leave the unit sphere by O(dt^5)); :func:`quat_to_R` and :func:`quat_to_rotmat` divide ``q``
by its norm and pass ``s = 2``; the sensor models, whose ``q`` is the simulator's normalised state, pass
``s = 2`` on ``q`` as it is.

Kernels and their Python twins: the kernels here are ``@njit`` and may be called from other kernels. A
Python caller of a *leaf* kernel (one that calls no other kernel) calls its ``py_func``, the same source
run by the interpreter: on a handful of floats numba's dispatch costs more than the arithmetic, and a
Python call into a kernel would make it one of the warm-up's outermost kernels
(:mod:`alight.compile.parallel`). Both execute the same IEEE double operations in the same order
(numba compiles without fast-math, so nothing is fused), hence the same bits; the tests check it.
Hand-written rather than ``scipy.spatial.transform`` because these run at 200 Hz-1 kHz on single
vectors, where SciPy's object construction costs ~20x the arithmetic.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, cast, overload

import numpy as np
from numba import njit

from alight.numerics import FloatArray

TWO_PI = 2.0 * math.pi
"""``2 pi``, the period of :func:`wrap_angle` (exactly twice the double ``math.pi``)."""

Entries = tuple[float, float, float, float, float, float, float, float, float]
"""The nine entries of a rotation matrix, row by row."""


# --------------------------------------------------------------------------------------------------
# Angles
# --------------------------------------------------------------------------------------------------


@njit(cache=True)
def wrap_period(a: float, period: float) -> float:  # pragma: no cover - numba
    """``a`` wrapped to ``[-period/2, period/2)`` (an angle modulo ``period``, e.g. the yaw of a pad
    that looks the same after a quarter turn). Python's, numpy's and numba's float ``%`` all take the
    sign of the divisor the same way, so the boundary is the same in all three."""
    half = 0.5 * period
    return (a + half) % period - half


# The leaf kernels' Python twins, for floats and, element by element, for arrays (numpy's operators are
# the same IEEE operations as Python's, so a twin gives the same bits on a whole column).
_wrap_period: Callable[..., Any] = wrap_period.py_func


@overload
def wrap_angle(a: float) -> float: ...
@overload
def wrap_angle(a: FloatArray) -> FloatArray: ...
def wrap_angle(a: float | FloatArray) -> float | FloatArray:
    """Angle ``a`` (rad, a float or an array) wrapped to ``[-pi, pi)``: ``pi`` becomes ``-pi``.
    Kernels call ``wrap_period(a, TWO_PI)``, which is this."""
    return cast(float | FloatArray, _wrap_period(a, TWO_PI))


# --------------------------------------------------------------------------------------------------
# Quaternion <-> rotation matrix
# --------------------------------------------------------------------------------------------------


@njit(cache=True)
def rotmat_entries(x: float, y: float, z: float, w: float, s: float) -> Entries:  # pragma: no cover - numba
    """The nine entries, row by row, of ``R = I + s [...]`` for the quaternion ``(x, y, z, w)``: its
    rotation matrix when ``s = 2 / |q|^2`` (``s = 2`` for a unit quaternion). See the module docstring."""
    return (
        1.0 - s * (y * y + z * z),
        s * (x * y - z * w),
        s * (x * z + y * w),
        s * (x * y + z * w),
        1.0 - s * (x * x + z * z),
        s * (y * z - x * w),
        s * (x * z - y * w),
        s * (y * z + x * w),
        1.0 - s * (x * x + y * y),
    )


_rotmat_entries = rotmat_entries.py_func
_rotmat_entries_any: Callable[..., Any] = rotmat_entries.py_func


@njit(cache=True)
def quat_to_R_scaled(
    x: float, y: float, z: float, w: float, s: float, R: FloatArray
) -> None:  # pragma: no cover - numba
    """Write :func:`rotmat_entries` ``(x, y, z, w, s)`` into ``R`` (3, 3)."""
    e = rotmat_entries(x, y, z, w, s)
    R[0, 0], R[0, 1], R[0, 2] = e[0], e[1], e[2]
    R[1, 0], R[1, 1], R[1, 2] = e[3], e[4], e[5]
    R[2, 0], R[2, 1], R[2, 2] = e[6], e[7], e[8]


@njit(cache=True)
def quat_to_R(q: FloatArray, R: FloatArray) -> None:  # pragma: no cover - numba
    """Write the rotation matrix of the quaternion ``q`` (x, y, z, w), normalised here, into ``R``
    (3, 3); it costs nothing inside a compiled loop. :func:`quat_to_rotmat` is its Python twin."""
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    quat_to_R_scaled(q[0] / n, q[1] / n, q[2] / n, q[3] / n, 2.0, R)


def quat_to_rotmat(q_xyzw: FloatArray) -> FloatArray:
    """Rotation matrix (3, 3) of the quaternion ``(x, y, z, w)`` (normalised here): :func:`quat_to_R`'s
    arithmetic on Python floats (for one (4,) quaternion ~3x faster than on array elements)."""
    x, y, z, w = q_xyzw.tolist() if isinstance(q_xyzw, np.ndarray) else (float(c) for c in q_xyzw)
    n = math.sqrt(x * x + y * y + z * z + w * w)
    return np.array(_rotmat_entries(x / n, y / n, z / n, w / n, 2.0)).reshape(3, 3)


def unit_quats_to_rotmats(q_xyzw: FloatArray) -> FloatArray:
    """Rotation matrices (N, 3, 3) of N unit quaternions (N, 4), taken as they are (``s = 2``, no
    normalisation: the sensor models' arithmetic), evaluated column-wise with numpy."""
    q = np.asarray(q_xyzw, dtype=np.float64)
    e = _rotmat_entries_any(q[:, 0], q[:, 1], q[:, 2], q[:, 3], 2.0)
    return np.stack(e, axis=1).reshape(q.shape[0], 3, 3)


@njit(cache=True)
def R_to_quat(m: FloatArray, q: FloatArray) -> None:  # pragma: no cover - numba
    """The unit quaternion ``(x, y, z, w)`` with ``w >= 0`` of the rotation matrix ``m`` (3, 3), written
    into ``q`` (4,): Shepperd's method (the largest of the four pivots, so no division by a small one)."""
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    if tr > 0.0:
        s = math.sqrt(tr + 1.0) * 2.0
        q[0] = (m[2, 1] - m[1, 2]) / s
        q[1] = (m[0, 2] - m[2, 0]) / s
        q[2] = (m[1, 0] - m[0, 1]) / s
        q[3] = 0.25 * s
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2]) * 2.0
        q[0] = 0.25 * s
        q[1] = (m[0, 1] + m[1, 0]) / s
        q[2] = (m[0, 2] + m[2, 0]) / s
        q[3] = (m[2, 1] - m[1, 2]) / s
    elif m[1, 1] > m[2, 2]:
        s = math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2]) * 2.0
        q[0] = (m[0, 1] + m[1, 0]) / s
        q[1] = 0.25 * s
        q[2] = (m[1, 2] + m[2, 1]) / s
        q[3] = (m[0, 2] - m[2, 0]) / s
    else:
        s = math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1]) * 2.0
        q[0] = (m[0, 2] + m[2, 0]) / s
        q[1] = (m[1, 2] + m[2, 1]) / s
        q[2] = 0.25 * s
        q[3] = (m[1, 0] - m[0, 1]) / s
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    sgn = 1.0 if q[3] >= 0.0 else -1.0
    for k in range(4):
        q[k] = sgn * q[k] / n


_R_to_quat = R_to_quat.py_func


def rotmat_to_quat(R: FloatArray) -> FloatArray:
    """Unit quaternion ``(x, y, z, w)`` with ``w >= 0`` of a rotation matrix: :func:`R_to_quat` run by
    Python."""
    q = np.empty(4)
    _R_to_quat(np.asarray(R, dtype=np.float64), q)
    return q


# --------------------------------------------------------------------------------------------------
# Heading, products, exponential and logarithm
# --------------------------------------------------------------------------------------------------


def yaw_of(R_WB: FloatArray) -> float:
    """Heading of the body x axis projected on the world xy plane (rad, from world x, counter-clockwise):
    the ZYX yaw."""
    return math.atan2(float(R_WB[1, 0]), float(R_WB[0, 0]))


def yaw_of_quat(q_xyzw: FloatArray) -> float:
    """:func:`yaw_of` of the quaternion's rotation matrix (the same bits as ``yaw_of(quat_to_rotmat(q))``),
    without building the matrix."""
    x, y, z, w = q_xyzw.tolist() if isinstance(q_xyzw, np.ndarray) else (float(c) for c in q_xyzw)
    n = math.sqrt(x * x + y * y + z * z + w * w)
    e = _rotmat_entries(x / n, y / n, z / n, w / n, 2.0)
    return math.atan2(e[3], e[0])


def rot_z(yaw: float) -> FloatArray:
    """The rotation by ``yaw`` (rad) about z, (3, 3)."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@njit(cache=True)
def quat_mul(a: FloatArray, b: FloatArray, out: FloatArray) -> None:  # pragma: no cover - numba
    """Hamilton product ``a * b`` of (x, y, z, w) quaternions (``out`` may not alias the inputs)."""
    ax, ay, az, aw = a[0], a[1], a[2], a[3]
    bx, by, bz, bw = b[0], b[1], b[2], b[3]
    out[0] = aw * bx + ax * bw + ay * bz - az * by
    out[1] = aw * by - ax * bz + ay * bw + az * bx
    out[2] = aw * bz + ax * by - ay * bx + az * bw
    out[3] = aw * bw - ax * bx - ay * by - az * bz


@njit(cache=True)
def quat_exp(phi: FloatArray, out: FloatArray) -> None:  # pragma: no cover - numba
    """Unit quaternion of the rotation vector ``phi`` (rad), i.e. ``Exp(phi)``."""
    th = math.sqrt(phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2])
    if th < 1e-8:
        s = 0.5 - th * th / 48.0  # sin(th/2)/th
        c = 1.0 - th * th / 8.0
    else:
        s = math.sin(0.5 * th) / th
        c = math.cos(0.5 * th)
    out[0] = s * phi[0]
    out[1] = s * phi[1]
    out[2] = s * phi[2]
    out[3] = c


@njit(cache=True)
def quat_log(q: FloatArray, out: FloatArray) -> None:  # pragma: no cover - numba
    """Rotation vector (rad) of a unit quaternion, i.e. ``Log(q)``, angle in [0, pi]."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    if w < 0.0:  # q and -q are the same rotation; take the short way
        x, y, z, w = -x, -y, -z, -w
    n = math.sqrt(x * x + y * y + z * z)
    if n < 1e-8:
        k = 2.0 / w  # 2 atan2(n, w) / n for small n
    else:
        k = 2.0 * math.atan2(n, w) / n
    out[0] = k * x
    out[1] = k * y
    out[2] = k * z


__all__ = [
    "TWO_PI",
    "R_to_quat",
    "quat_exp",
    "quat_log",
    "quat_mul",
    "quat_to_R",
    "quat_to_R_scaled",
    "quat_to_rotmat",
    "rot_z",
    "rotmat_entries",
    "rotmat_to_quat",
    "unit_quats_to_rotmats",
    "wrap_angle",
    "wrap_period",
    "yaw_of",
    "yaw_of_quat",
]
