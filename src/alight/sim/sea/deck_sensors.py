"""Simulated measurements of a deck at sea: the pad's pose as PnP gives it, and a ship's motion reference
unit (MRU) broadcast, both with noise and latency (seeded), for the deck estimator's tests and benchmarks.

- **Pose** (camera rate): the pad centre in W and the deck's roll and pitch (the ZYX angles of R_WP, FLU:
  roll port up, pitch bow down), each with Gaussian noise of the configured standard deviations, stamped
  at capture and delivered ``pose_latency_s`` later.
- **MRU** (its own rate): the deck's roll and pitch and the heave rate *at the pad* (an MRU outputs the
  motion of a configured monitoring point; here the pad), stamped at the sample and delivered
  ``mru_latency_s`` later.

The noise figures are [MODEL] values: a PnP pose of a 1 m pad from 5-10 m has centimetre position and
about a degree of attitude noise; a marine MRU's roll and pitch are good to a few hundredths of a degree,
its heave rate to a few cm/s. They are the defaults of a test bench, not data of a product.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from alight.sim.sea.deck import DeckMotion, VesselPath
from alight.types import FloatArray

__all__ = ["DeckReading", "DeckSensorConfig", "DeckTruth", "deck_truth", "simulate_deck_readings"]


@dataclass(frozen=True, kw_only=True)
class DeckSensorConfig:
    """Rates, latencies and noise of the simulated pose and MRU streams ([MODEL] values, module doc)."""

    pose_rate_hz: float = 30.0
    pose_latency_s: float = 0.1
    pose_position_std_m: tuple[float, float, float] = (0.03, 0.03, 0.05)
    pose_attitude_std_rad: float = math.radians(1.0)
    mru_rate_hz: float = 10.0
    mru_latency_s: float = 0.05
    mru_attitude_std_rad: float = math.radians(0.05)
    mru_heave_rate_std_mps: float = 0.03


@dataclass(frozen=True)
class DeckReading:
    """One delivered message: ``kind`` is ``"pose"`` or ``"mru"``."""

    kind: str
    t_stamp: float
    """Capture (pose) or sample (MRU) time (s)."""
    t_arrival: float
    """Time it reaches the estimator (s)."""
    p_WP: FloatArray
    """Pose: pad centre (m), (3,); MRU: empty."""
    cov_p_WP: FloatArray
    """Pose: its covariance (m^2), (3, 3); MRU: empty."""
    attitude: FloatArray
    """(roll, pitch) (rad), (2,)."""
    cov_attitude: FloatArray
    """Its covariance (rad^2), (2, 2)."""
    heave_rate: float
    """MRU: the pad's vertical speed (m/s); pose: NaN."""
    heave_rate_var: float
    """MRU: its variance ((m/s)^2); pose: NaN."""


@dataclass(frozen=True)
class DeckTruth:
    """The deck's true state at times t: pad height and vertical speed, roll, pitch and their rates."""

    t: FloatArray
    p_WP: FloatArray
    """(N, 3) m."""
    state: FloatArray
    """(N, 6): [z, dz/dt, roll, roll rate, pitch, pitch rate] (m, m/s, rad, rad/s)."""


def deck_truth(deck: DeckMotion, t: FloatArray, speed_mps: float, heading_rad: float = 0.0) -> DeckTruth:
    """The truth along a straight course at ``speed_mps`` and ``heading_rad``."""
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    pad = deck.pad(t, VesselPath.straight(t, speed_mps, heading_rad))
    q, dq, _ = deck.axes(t)
    state = np.column_stack([pad.p_WP[:, 2], pad.v_WP[:, 2], q[:, 3], dq[:, 3], q[:, 4], dq[:, 4]])
    return DeckTruth(t, pad.p_WP, state)


def simulate_deck_readings(
    deck: DeckMotion,
    t_end: float,
    rng: np.random.Generator,
    config: DeckSensorConfig | None = None,
    *,
    speed_mps: float,
    heading_rad: float = 0.0,
    mru: bool = True,
) -> list[DeckReading]:
    """Every message stamped in [0, t_end] on a straight course, sorted by arrival time (the order an
    estimator receives them). The pose noise is drawn first, then the MRU's, from ``rng``."""
    c = config if config is not None else DeckSensorConfig()
    out: list[DeckReading] = []
    t_pose = np.arange(0.0, t_end, 1.0 / c.pose_rate_hz)
    truth = deck_truth(deck, t_pose, speed_mps, heading_rad)
    sp = np.asarray(c.pose_position_std_m)
    cov_p = np.diag(sp**2)
    cov_a = np.eye(2) * c.pose_attitude_std_rad**2
    noise_p = rng.standard_normal((t_pose.shape[0], 3)) * sp
    noise_a = rng.standard_normal((t_pose.shape[0], 2)) * c.pose_attitude_std_rad
    empty = np.zeros(0)
    for i, t in enumerate(t_pose):
        att = truth.state[i, [2, 4]] + noise_a[i]
        out.append(
            DeckReading("pose", float(t), float(t) + c.pose_latency_s, truth.p_WP[i] + noise_p[i], cov_p,
                        att, cov_a, math.nan, math.nan)
        )  # fmt: skip
    if mru:
        t_mru = np.arange(0.0, t_end, 1.0 / c.mru_rate_hz)
        tm = deck_truth(deck, t_mru, speed_mps, heading_rad)
        na = rng.standard_normal((t_mru.shape[0], 2)) * c.mru_attitude_std_rad
        nv = rng.standard_normal(t_mru.shape[0]) * c.mru_heave_rate_std_mps
        cov_m = np.eye(2) * c.mru_attitude_std_rad**2
        for i, t in enumerate(t_mru):
            out.append(
                DeckReading("mru", float(t), float(t) + c.mru_latency_s, empty, empty,
                            tm.state[i, [2, 4]] + na[i], cov_m, float(tm.state[i, 1] + nv[i]),
                            c.mru_heave_rate_std_mps**2)
            )  # fmt: skip
    out.sort(key=lambda r: (r.t_arrival, r.t_stamp))
    return out
