"""Compiled rotation helpers shared by the numba kernels of several stages (the controller, the ego
EKF). ``types.quat_to_rotmat`` is the same formula for Python callers; this one writes into a given
array so it costs nothing inside a compiled loop."""

from __future__ import annotations

import math

from numba import njit

from alight.types import FloatArray


@njit(cache=True)
def quat_to_R(q: FloatArray, R: FloatArray) -> None:
    """Write the rotation matrix of the quaternion ``q`` (x, y, z, w), normalised here, into ``R`` (3, 3)."""
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    x, y, z, w = q[0] / n, q[1] / n, q[2] / n, q[3] / n
    R[0, 0] = 1.0 - 2.0 * (y * y + z * z)
    R[0, 1] = 2.0 * (x * y - z * w)
    R[0, 2] = 2.0 * (x * z + y * w)
    R[1, 0] = 2.0 * (x * y + z * w)
    R[1, 1] = 1.0 - 2.0 * (x * x + z * z)
    R[1, 2] = 2.0 * (y * z - x * w)
    R[2, 0] = 2.0 * (x * z - y * w)
    R[2, 1] = 2.0 * (y * z + x * w)
    R[2, 2] = 1.0 - 2.0 * (x * x + y * y)
