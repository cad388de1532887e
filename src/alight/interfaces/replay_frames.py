"""NED/FRD to ENU/FLU, for recorded PX4 flights (ULog) at the replay's boundary.

PX4 logs positions and velocities in a local NED frame (x north, y east, z down) and attitudes as the
rotation from the body's FRD axes (x forward, y right, z down) to NED, quaternion stored ``(w, x, y, z)``.
alight's world ``W`` is ENU and its body ``B`` is FLU (docs/conventions.md). The maths is the same as the
autopilot bridge's ``interfaces/frames.py``; it is kept here, small, until the two are unified.

With ``T = R_ENU_NED`` (swap x and y, negate z; its own inverse) and ``F = R_FRD_FLU = diag(1, -1, -1)``:

    p_W = T p_NED,   v_W = T v_NED,   R_WB = T R_NED_FRD F,   w_B = F w_FRD,   f_B = F f_FRD.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

FloatArray = NDArray[np.float64]

R_ENU_NED: FloatArray = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
"""Takes NED vectors to ENU (a reflection-free swap: its determinant is +1, and it is its own inverse)."""

R_FRD_FLU: FloatArray = np.diag([1.0, -1.0, -1.0])
"""Takes FLU body vectors to FRD (a rotation by pi about x; its own inverse)."""


def ned_to_enu(v_NED: FloatArray) -> FloatArray:
    """Positions or velocities, (..., 3) NED -> (..., 3) ENU."""
    v = np.asarray(v_NED, dtype=np.float64)
    return np.stack([v[..., 1], v[..., 0], -v[..., 2]], axis=-1)


def frd_to_flu(v_FRD: FloatArray) -> FloatArray:
    """Body vectors (rates, specific forces), (..., 3) FRD -> (..., 3) FLU."""
    v = np.asarray(v_FRD, dtype=np.float64)
    return np.stack([v[..., 0], -v[..., 1], -v[..., 2]], axis=-1)


def q_ned_frd_wxyz_to_q_WB(q_wxyz: FloatArray) -> FloatArray:
    """PX4 attitudes ``q`` (rotation FRD -> NED, (w, x, y, z)), (N, 4) -> ``q_WB`` (FLU -> ENU, SciPy's
    (x, y, z, w)), (N, 4). Rows that are not unit quaternions (zeros, NaN) come out as NaN."""
    q = np.atleast_2d(np.asarray(q_wxyz, dtype=np.float64))
    out = np.full(q.shape, np.nan)
    norm = np.linalg.norm(q, axis=1)
    ok = np.isfinite(norm) & (np.abs(norm - 1.0) < 0.1)
    if ok.any():
        R_NED_FRD = Rotation.from_quat(q[ok][:, [1, 2, 3, 0]]).as_matrix()
        R_WB = R_ENU_NED @ R_NED_FRD @ R_FRD_FLU
        out[ok] = Rotation.from_matrix(R_WB).as_quat()
    return out
