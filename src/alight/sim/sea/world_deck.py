"""A vessel's deck in the simulated world: the platform's path and speed profile carried on a seeded sea.

The World (``sim/world.py``) keeps the platform's true states at every 200 Hz tick in one table; with a
``platform.sea`` section, :class:`SeaDeck` replaces that table by the pad's exact kinematics on the vessel
(:meth:`alight.sim.sea.deck.DeckMotion.pad`): the vessel follows the platform's path and speed profile
with its pad's mean position on the path (:func:`centre_path`: the pad is where the mission expects the
platform, as on land, also 55 m aft on a frigate), its centre of motion at the waterline (the world's
z = 0, the sea's mean level; the path's own height is not used), and the sea adds heave, roll, pitch,
surge, sway and yaw. It also holds what the flat world did not need: the
deck's orientation R_WP and angular velocity at every tick, the deck's extent (the plane of the pad over
the hull's footprint), the deck rows of the physics kernel, and the vessel's motion reference unit (MRU)
broadcast.

The deck's future is in these tables: they are the truth for the World, the judge and the tests, never
handed to the pipeline (which gets the MRU's delayed, noisy messages and the camera's images).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from alight.sim.platform import PlatformStates
from alight.sim.quadrotor import (
    DK_A,
    DK_EXT,
    DK_HALF,
    DK_ON,
    DK_P,
    DK_R,
    DK_TILTED,
    DK_V,
    DK_W,
    DK_YAW,
    DK_YAW_RATE,
    N_DK,
)
from alight.sim.sea.config import MotionTelemetryConfig, SeaConfig
from alight.sim.sea.deck import DeckMotion, PadKinematics, VesselPath
from alight.types import FloatArray

__all__ = [
    "MAX_DECK_HALF_M",
    "deck_extent",
    "DeckPose",
    "MruMessage",
    "MruStream",
    "SeaDeck",
    "deck_attitude",
]

MAX_DECK_HALF_M = 6.0
"""The deck around the pad reaches at most this far from its centre along each axis (m): a landing
that misses the pad by metres is judged off it anyway, and the camera's deck texture stays a few
thousand texels wide."""


@dataclass(frozen=True, slots=True)
class DeckPose:
    """The deck at one tick, as the judge and the sensors need it (ground truth)."""

    p_WP: FloatArray
    """Pad centre in W (m), (3,)."""
    R_WP: FloatArray
    """Deck orientation (P to W), (3, 3); its third column is the deck's upward normal."""
    v_WP: FloatArray
    """Pad centre velocity in W (m/s), (3,)."""
    w_WP_W: FloatArray
    """Deck angular velocity in W (rad/s), (3,)."""
    extent_P: tuple[float, float, float, float]
    """The deck's extent in P: x_min, x_max, y_min, y_max (m)."""

    def surface_velocity(self, p_W: FloatArray) -> FloatArray:
        """Velocity of the deck's material point nearest ``p_W`` (on the deck's plane) (m/s), (3,)."""
        d = np.asarray(p_W, dtype=np.float64) - self.p_WP
        n = self.R_WP[:, 2]
        s = d - float(d @ n) * n
        out: FloatArray = self.v_WP + np.cross(self.w_WP_W, s)
        return out

    def local(self, p_W: FloatArray) -> FloatArray:
        """``p_W`` in the deck's frame P (m), (3,)."""
        out: FloatArray = self.R_WP.T @ (np.asarray(p_W, dtype=np.float64) - self.p_WP)
        return out


def deck_extent(config: SeaConfig, pad_half_m: float) -> tuple[float, float, float, float]:
    """The deck's extent in P (x_min, x_max, y_min, y_max) (m): the pad's plane over the largest rectangle
    centred on the pad inside the hull's footprint, at most :data:`MAX_DECK_HALF_M` each way and at least
    the pad. The contact, the range finder, the optical flow and the camera all see this one deck."""
    v = config.load_vessel()
    r = v.pad_offset_m if config.pad_offset_m is None else config.pad_offset_m
    hx = max(min(0.5 * v.length_m - abs(float(r[0])), MAX_DECK_HALF_M), pad_half_m)
    hy = max(min(0.5 * v.beam_m - abs(float(r[1])), MAX_DECK_HALF_M), pad_half_m)
    return (-hx, hx, -hy, hy)


def centre_path(path: PlatformStates, yaw_accel: FloatArray, r_B: FloatArray) -> VesselPath:
    """The vessel's centre of motion for a pad whose mean position follows ``path``: in still water the
    pad (at ``r_B``, FLU from the centre) is exactly on the platform's path, as a pad on land is, and the
    centre is at the waterline, ``Rz(yaw) r_xy`` behind it. With ``u = Rz(yaw) r_xy``, ``u' = yaw' J u``
    and ``u'' = yaw'' J u - yaw'^2 u`` (J a quarter turn): p_c = p - u, v_c = v - u', a_c = a - u''."""
    c, s = np.cos(path.yaw), np.sin(path.yaw)
    ux, uy = c * r_B[0] - s * r_B[1], s * r_B[0] + c * r_B[1]
    dy, ddy = path.yaw_rate, yaw_accel
    p = path.p_WP.copy()
    v = path.v_WP.copy()
    a = path.a_WP.copy()
    p[:, 0] -= ux
    p[:, 1] -= uy
    p[:, 2] = 0.0  # the centre of motion at the waterline
    v[:, 0] += dy * uy
    v[:, 1] -= dy * ux
    a[:, 0] -= -ddy * uy - dy * dy * ux
    a[:, 1] -= ddy * ux - dy * dy * uy
    return VesselPath(p, v, a, path.yaw, path.yaw_rate, np.asarray(yaw_accel, dtype=np.float64))


def deck_attitude(R_WP: FloatArray) -> tuple[float, float]:
    """(roll, pitch) of R_WP = Rz Ry Rx (ZYX; FLU: roll port up, pitch bow down) (rad)."""
    return math.atan2(float(R_WP[2, 1]), float(R_WP[2, 2])), -math.asin(
        max(-1.0, min(1.0, float(R_WP[2, 0])))
    )


@dataclass(frozen=True, slots=True)
class MruMessage:
    """One MRU message as the aircraft receives it."""

    t_stamp: float
    """Time of the sample (s)."""
    t_arrival: float
    """Time it reaches the aircraft (s)."""
    attitude: FloatArray
    """Deck (roll, pitch) (rad), (2,)."""
    cov_attitude: FloatArray
    """Its covariance (rad^2), (2, 2)."""
    heave_rate: float
    """The pad's vertical speed (m/s)."""
    heave_rate_var: float
    """Its variance ((m/s)^2)."""


class MruStream:
    """The vessel's MRU broadcast (``platform.sea.motion_telemetry``): samples of the deck's truth at the
    configured rate, with white noise from its own seeded generator, delivered after the latency."""

    def __init__(self, config: MotionTelemetryConfig, rng: np.random.Generator) -> None:
        self.config = config
        self._rng = rng
        self.next_sample_s = 0.0
        self._pending: deque[MruMessage] = deque()
        sa = math.radians(config.attitude_noise_deg)
        self._cov_att = np.eye(2) * sa * sa
        self._var_heave = config.heave_rate_noise_mps**2

    def arrivals(self, t: float, R_WP: FloatArray, vz_WP: float) -> tuple[MruMessage, ...]:
        """Sample the deck now if a sample is due (its truth ``R_WP``, the pad's vertical speed
        ``vz_WP``), and return the messages that reach the aircraft now, in stamp order."""
        c = self.config
        if t + 1e-9 >= self.next_sample_s:
            noise = self._rng.standard_normal(3)
            roll, pitch = deck_attitude(R_WP)
            sa = math.radians(c.attitude_noise_deg)
            att = np.array([roll + sa * noise[0], pitch + sa * noise[1]])
            rate = float(vz_WP) + c.heave_rate_noise_mps * float(noise[2])
            self._pending.append(MruMessage(t, t + c.latency_s, att, self._cov_att, rate, self._var_heave))
            self.next_sample_s += 1.0 / c.rate_hz
        out = []
        while self._pending and self._pending[0].t_arrival <= t + 1e-9:
            out.append(self._pending.popleft())
        return tuple(out)


class SeaDeck:
    """The deck of a vessel at sea over a mission's ticks (module docstring).

    ``path``: the platform's states at every tick (its planar path and speed profile); ``rng``: the sea's
    own generator (a child of the scenario seed); ``tick_dt``: the tick (s), for the heading's acceleration
    (the platform paths give the heading rate, not its derivative: a central difference of the rate at
    200 Hz, an input of the vessel's planar motion, not of the sea's, which is exact); ``pad_half_m``: half
    the pad's side (m), the least the deck reaches around the pad."""

    def __init__(self, config: SeaConfig, rng: np.random.Generator, speed_mps: float, path: PlatformStates,
                 tick_dt: float, pad_half_m: float) -> None:  # fmt: skip
        self.config = config
        self.motion = DeckMotion.from_config(config, rng, speed_mps)
        yaw_accel = np.gradient(path.yaw_rate, tick_dt) if len(path) > 1 else np.zeros(len(path))
        vessel_path = centre_path(path, yaw_accel, self.motion.r_B)
        self.pad: PadKinematics = self.motion.pad(path.t, vessel_path)
        R = self.pad.R_WP
        psi = np.arctan2(R[:, 1, 0], R[:, 0, 0])
        self.truths = PlatformStates(
            path.t, self.pad.p_WP, self.pad.v_WP, self.pad.a_WP, psi, self.pad.w_WP_W[:, 2].copy()
        )
        """The pad's states in the flat world's terms (heading: the deck's ZYX yaw; its rate: the z
        component of the angular velocity)."""
        self.extent_P = deck_extent(config, pad_half_m)
        """The deck's extent in P (:func:`deck_extent`)."""

    def pose(self, k: int) -> DeckPose:
        """The deck at tick ``k``."""
        p = self.pad
        return DeckPose(p.p_WP[k], p.R_WP[k], p.v_WP[k], p.w_WP_W[k], self.extent_P)

    def deck_rows(self, pad_half_m: float) -> FloatArray:  # the pad's half side, as the level deck's
        """The physics kernel's deck inputs at every tick (layout ``DK_*``), shape (N, N_DK)."""
        n = self.pad.t.shape[0]
        rows = np.zeros((n, N_DK))
        rows[:, DK_ON] = 1.0
        rows[:, DK_HALF] = pad_half_m
        rows[:, DK_P : DK_P + 3] = self.pad.p_WP
        rows[:, DK_V : DK_V + 3] = self.pad.v_WP
        rows[:, DK_A : DK_A + 3] = self.pad.a_WP
        rows[:, DK_YAW] = self.truths.yaw
        rows[:, DK_YAW_RATE] = self.truths.yaw_rate
        rows[:, DK_TILTED] = 1.0
        rows[:, DK_R : DK_R + 9] = self.pad.R_WP.reshape(n, 9)
        rows[:, DK_W : DK_W + 3] = self.pad.w_WP_W
        rows[:, DK_EXT : DK_EXT + 4] = self.extent_P
        return rows

    def highest_point_m(self) -> float:
        """The highest any point of the deck gets over the mission (m)."""
        R = self.pad.R_WP
        x0, x1, y0, y1 = self.extent_P
        z = self.pad.p_WP[:, 2]
        corners = [z + R[:, 2, 0] * x + R[:, 2, 1] * y for x in (x0, x1) for y in (y0, y1)]
        return float(np.max(corners))

    def surface_z(self, k: int, p_W: FloatArray) -> float:
        """Height of the deck's plane at tick ``k`` below (or above) the point ``p_W`` (m)."""
        n = self.pad.R_WP[k, :, 2]
        p = self.pad.p_WP[k]
        return float(p[2] - (n[0] * (p_W[0] - p[0]) + n[1] * (p_W[1] - p[1])) / n[2])
