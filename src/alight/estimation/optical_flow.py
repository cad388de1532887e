"""The velocity across the surface under the vehicle, from a downward optical-flow sample.

An optical-flow module (PX4's ARK Flow, Holybro H-Flow) reports the apparent angular rate of the texture
under it along x_B and y_B, and its distance d to that surface along -z_B. For a surface point on the
sensor's axis, moving at ``v_rel_B`` relative to the sensor, and body rates ``w``, that rate is::

    flow_x = -v_x / d + w_y,    flow_y = -v_y / d - w_x

(the point at X_B = (0, 0, -d) moves in B as -v_rel_B - w x X_B). With the body rates and the distance
known, the flow gives v_x and v_y, two components in B. The horizontal velocity in W needs a third:
the vertical one, the descent rate over the surface, which the ego estimate and the platform estimate
give. PX4 does the same inversion (with the tilt neglected) in its EKF2's flow fusion; this is a few
lines of algebra on one sample, so it is written here rather than taken from a library.
"""

from __future__ import annotations

import math

import numpy as np

from alight.types import EgoState, FloatArray, quat_to_rotmat

MIN_LEVEL_COSINE = 0.5
"""Below this cosine of the tilt (60 deg) the flow says too little about the horizontal: no estimate."""


def horizontal_slip_W(
    flow_B_rad_s: FloatArray, distance_m: float, w_WB_B: FloatArray, q_WB: FloatArray, v_rel_z_W: float
) -> FloatArray | None:
    """The sensor's horizontal velocity relative to the surface under it, in W (m/s, (2,)), from one flow
    sample (``flow_B_rad_s`` (2,), not compensated for the rotation; ``distance_m`` along -z_B), the body
    rates ``w_WB_B`` (rad/s, (3,)), the attitude ``q_WB`` (x, y, z, w) and the relative velocity's
    vertical component in W (m/s). None when an input is not finite, the distance is not positive or the
    body is tilted past 60 deg."""
    fx, fy, d = float(flow_B_rad_s[0]), float(flow_B_rad_s[1]), float(distance_m)
    wx, wy = float(w_WB_B[0]), float(w_WB_B[1])
    if not all(math.isfinite(a) for a in (fx, fy, d, wx, wy, v_rel_z_W)) or d <= 0.0:
        return None
    v_x = -(fx - wy) * d
    v_y = -(fy + wx) * d
    # v_B = R_WB^T v_W: the rows of x_B and y_B, with v_W's vertical component known, leave a 2x2 system
    # for the horizontal ones; its determinant is the cosine of the tilt
    R = quat_to_rotmat(q_WB)
    a11, a12, a21, a22 = R[0, 0], R[1, 0], R[0, 1], R[1, 1]
    det = a11 * a22 - a12 * a21
    if det < MIN_LEVEL_COSINE:
        return None
    b1 = v_x - R[2, 0] * v_rel_z_W
    b2 = v_y - R[2, 1] * v_rel_z_W
    return np.array([(b1 * a22 - a12 * b2) / det, (a11 * b2 - a21 * b1) / det])


def module_velocity_W(
    v_WB: FloatArray, q_WB: FloatArray, w_WB_B: FloatArray, origin_B: tuple[float, float, float]
) -> tuple[float, float, float]:
    """The velocity in W (m/s) of a point fixed to the body at ``origin_B`` (m, in B): the body origin's
    ``v_WB`` plus ``R_WB (w_WB_B x origin_B)``. A flow module at the feet, 0.1-0.2 m under the origin,
    moves a few cm/s apart from it when the body turns at a fraction of a rad/s; PX4 corrects its flow
    for this lever arm too (``EKF2_OF_POS_X/Y/Z``)."""
    rx, ry, rz = origin_B
    vx, vy, vz = float(v_WB[0]), float(v_WB[1]), float(v_WB[2])
    if rx == 0.0 and ry == 0.0 and rz == 0.0:
        return vx, vy, vz
    wx, wy, wz = float(w_WB_B[0]), float(w_WB_B[1]), float(w_WB_B[2])
    cx, cy, cz = wy * rz - wz * ry, wz * rx - wx * rz, wx * ry - wy * rx  # w x r, in B
    R = quat_to_rotmat(q_WB)
    return (
        vx + float(R[0, 0] * cx + R[0, 1] * cy + R[0, 2] * cz),
        vy + float(R[1, 0] * cx + R[1, 1] * cy + R[1, 2] * cz),
        vz + float(R[2, 0] * cx + R[2, 1] * cy + R[2, 2] * cz),
    )


FLOW_MAX_AGE_S = 0.1
"""An optical-flow sample older than this (s) is not read (a module at 50 Hz gives five in that time)."""


class DeckFlow:
    """The surface under the feet as the latest optical-flow sample measures it: the feet's horizontal
    velocity across it (``slip_W``) and so its own horizontal velocity (``velocity_W``), both (2,) in W
    (m/s), None before a sample (a vehicle without a module); read only while younger than
    :data:`FLOW_MAX_AGE_S`.

    ``origin_B``: where the module sits in B (m), as PX4's ``EKF2_OF_POS_X/Y/Z`` give it; the module's
    velocity is the body's plus the lever arm's, w x r."""

    def __init__(self, origin_B: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> None:
        self.origin_B = (float(origin_B[0]), float(origin_B[1]), float(origin_B[2]))
        self.slip_W: FloatArray | None = None
        self.velocity_W: FloatArray | None = None
        """The module's velocity (the ego estimate's, plus the lever arm's) less the slip."""
        self.t = -math.inf
        """Time of the sample (s)."""

    def update(
        self, t: float, flow_B_rad_s: FloatArray, distance_m: float, ego: EgoState, v_z_WP: float
    ) -> None:
        """A sample at ``t`` (:meth:`alight.mission.pipeline.Pipeline.on_flow`) with the ego estimate's body
        rates, attitude and velocity, and the platform estimate's vertical speed ``v_z_WP`` (m/s; 0
        without one): the descent rate over the deck is the module's vertical speed less it. A sample
        that is not finite, from a non-positive distance, stamped in the future or taken tilted past
        60 deg is dropped."""
        if not (math.isfinite(t) and t <= ego.t + FLOW_MAX_AGE_S):
            return  # a sample from the future (a clock gone wrong) is not read
        v_S_W = module_velocity_W(ego.v_WB, ego.q_WB, ego.w_WB_B, self.origin_B)
        v_rel_z = float(v_S_W[2]) - v_z_WP
        slip = horizontal_slip_W(flow_B_rad_s, distance_m, ego.w_WB_B, ego.q_WB, v_rel_z)
        if slip is None:
            return
        self.slip_W = slip
        self.velocity_W = np.array([float(v_S_W[0]) - slip[0], float(v_S_W[1]) - slip[1]])
        self.t = t

    def slip_mps(self, t: float) -> float | None:
        """The feet's horizontal speed across the surface (m/s) from a sample of the last
        :data:`FLOW_MAX_AGE_S`; None without one."""
        if self.slip_W is None or t - self.t > FLOW_MAX_AGE_S:
            return None
        return math.hypot(float(self.slip_W[0]), float(self.slip_W[1]))

    def velocity_W_at(self, t: float) -> FloatArray | None:
        """The surface's horizontal velocity (m/s, (2,) in W) from a sample of the last
        :data:`FLOW_MAX_AGE_S`; None without one."""
        if self.velocity_W is None or t - self.t > FLOW_MAX_AGE_S:
            return None
        return self.velocity_W
