"""The only place where alight's ENU/FLU frames meet MAVLink's NED/FRD frames.

alight: world W is ENU (x east, y north, z up), body B is FLU (x forward, y left, z up), quaternions are
stored ``(x, y, z, w)`` like SciPy. MAVLink / PX4 / ArduPilot: local frame NED, body frame FRD,
quaternions sent ``(w, x, y, z)``.

A world vector goes ENU -> NED by ``M = [[0,1,0],[1,0,0],[0,0,-1]]`` (swap x and y, negate z; a proper
rotation, det +1); a body vector goes FLU -> FRD by ``F = diag(1, -1, -1)``. Both maps are their own
inverse, so every function here works in both directions. The attitude matrix maps as
``R_NED_FRD = M R_ENU_FLU F`` (REP 103, and PX4's "ROS 2 & PX4 frame conventions").

Each function takes and returns float64 numpy arrays (or floats) and never mutates its input.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from alight.types import FloatArray, wrap_angle

M_ENU_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
"""World-vector map ENU <-> NED (its own inverse)."""
M_FLU_FRD = np.diag([1.0, -1.0, -1.0])
"""Body-vector map FLU <-> FRD (its own inverse)."""
for _m in (M_ENU_NED, M_FLU_FRD):
    _m.setflags(write=False)

_S = 1.0 / math.sqrt(2.0)


def enu_to_ned(v: FloatArray) -> FloatArray:
    """A world position, velocity or acceleration, ENU -> NED (and NED -> ENU): (x, y, z) -> (y, x, -z).
    Works on shape (3,) or (N, 3)."""
    a = np.asarray(v, dtype=np.float64)
    return np.stack([a[..., 1], a[..., 0], -a[..., 2]], axis=-1)


ned_to_enu = enu_to_ned


def flu_to_frd(v: FloatArray) -> FloatArray:
    """A body vector (rates, specific force, thrust), FLU -> FRD (and back): (x, y, z) -> (x, -y, -z)."""
    a = np.asarray(v, dtype=np.float64)
    return np.stack([a[..., 0], -a[..., 1], -a[..., 2]], axis=-1)


frd_to_flu = flu_to_frd


def rotmat_enu_flu_to_ned_frd(R_WB: FloatArray) -> FloatArray:
    """Attitude matrix: ``R_NED_FRD = M R_ENU_FLU F`` (and back, by the same formula)."""
    return M_ENU_NED @ np.asarray(R_WB, dtype=np.float64) @ M_FLU_FRD


rotmat_ned_frd_to_enu_flu = rotmat_enu_flu_to_ned_frd


def quat_wxyz_swap(q_wxyz: FloatArray) -> FloatArray:
    """``q_NED_FRD`` from ``q_ENU_FLU`` (and back), both scalar first ``(w, x, y, z)``:
    ``(w+z, x+y, x-y, w-z)/sqrt(2)``, the quaternion form of ``M R F``."""
    w, x, y, z = (float(c) for c in np.asarray(q_wxyz, dtype=np.float64))
    return np.array([_S * (w + z), _S * (x + y), _S * (x - y), _S * (w - z)])


def q_WB_to_mavlink(q_WB: FloatArray) -> FloatArray:
    """alight's ``q_WB`` (ENU/FLU, stored ``(x, y, z, w)``) -> MAVLink ``q`` (NED/FRD, ``(w, x, y, z)``)."""
    x, y, z, w = (float(c) for c in np.asarray(q_WB, dtype=np.float64))
    return quat_wxyz_swap(np.array([w, x, y, z]))


def mavlink_to_q_WB(q_wxyz_ned_frd: FloatArray) -> FloatArray:
    """MAVLink ``q`` (NED/FRD, ``(w, x, y, z)``) -> alight's ``q_WB`` (ENU/FLU, ``(x, y, z, w)``),
    normalised with ``w >= 0``. Raises ``ValueError`` for a non-finite or zero quaternion."""
    q = np.asarray(q_wxyz_ned_frd, dtype=np.float64)
    n = float(np.linalg.norm(q)) if q.shape == (4,) else math.nan
    if not math.isfinite(n) or n < 1e-6:
        raise ValueError(f"not a usable quaternion: {q!r}")
    w, x, y, z = quat_wxyz_swap(q / n)
    out = np.array([x, y, z, w])
    return out if w >= 0 else -out


def yaw_enu_to_ned(yaw_enu: float) -> float:
    """Heading: ENU yaw (from east, counter-clockwise) <-> NED yaw (from north, clockwise), wrapped to
    [-pi, pi)."""
    return wrap_angle(math.pi / 2.0 - yaw_enu)


yaw_ned_to_enu = yaw_enu_to_ned


def yaw_rate_enu_to_ned(yaw_rate_enu: float) -> float:
    """Rate of the heading about the vertical: the vertical axis flips, so the sign flips."""
    return -yaw_rate_enu


yaw_rate_ned_to_enu = yaw_rate_enu_to_ned


def euler_ned_frd_to_q_WB(roll: float, pitch: float, yaw: float) -> FloatArray:
    """MAVLink ATTITUDE (ZYX intrinsic Euler angles of the FRD body in NED, rad) -> ``q_WB`` (ENU/FLU,
    ``(x, y, z, w)``)."""
    cr, sr = math.cos(0.5 * roll), math.sin(0.5 * roll)
    cp, sp = math.cos(0.5 * pitch), math.sin(0.5 * pitch)
    cy, sy = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    q_ned = np.array(
        [
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ]
    )
    return mavlink_to_q_WB(q_ned)


def mavlink_q_to_euler_ned_frd(q: FloatArray) -> tuple[float, float, float]:
    """A MAVLink quaternion ``(w, x, y, z)`` of the FRD body in NED -> ATTITUDE's roll, pitch, yaw (ZYX
    intrinsic Euler angles, rad): the inverse of :func:`euler_ned_frd_to_q_WB`'s angles (pitch clipped to
    +-pi/2 where rounding takes the sine past 1)."""
    w, x, y, z = (float(c) for c in q)
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(min(max(2.0 * (w * y - z * x), -1.0), 1.0))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw


def cov_enu_to_ned(P: FloatArray) -> FloatArray:
    """A 3x3 world covariance, ENU <-> NED: ``M P M^T``."""
    out: FloatArray = M_ENU_NED @ np.asarray(P, dtype=np.float64) @ M_ENU_NED.T
    return out


def mavlink_to_q_WB_many(q_wxyz_ned_frd: FloatArray) -> FloatArray:
    """Many PX4/MAVLink attitudes at once (a recorded flight's ``vehicle_attitude``): (N, 4) ``(w, x, y, z)``
    NED/FRD -> (N, 4) ``q_WB`` ENU/FLU ``(x, y, z, w)``. Unlike :func:`mavlink_to_q_WB`, a row that is not a
    unit quaternion (zeros, NaN, a norm off by more than 10 %) does not raise: it comes out as NaN, so a log
    reader can drop it and count it."""
    q = np.atleast_2d(np.asarray(q_wxyz_ned_frd, dtype=np.float64))
    out = np.full(q.shape, np.nan)
    norm = np.linalg.norm(q, axis=1)
    ok = np.isfinite(norm) & (np.abs(norm - 1.0) < 0.1)
    if ok.any():
        R_NED_FRD = Rotation.from_quat(q[ok][:, [1, 2, 3, 0]]).as_matrix()
        out[ok] = Rotation.from_matrix(M_ENU_NED @ R_NED_FRD @ M_FLU_FRD).as_quat()
    return out
