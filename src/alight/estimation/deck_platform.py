"""The deck estimator as a platform-estimator block (issue 37, point 3): :class:`DeckPlatformEstimator`.

It wraps :class:`alight.estimation.deck_estimator.DeckEstimator` behind the
:class:`alight.estimation.PlatformEstimator` Protocol, so that the mission and the guidance fly on it as on
any platform estimator: the pad's horizontal track is the deck estimator's unicycle EKF, its height and
vertical speed are the heave channel's (not a constant deck height), and :meth:`predict_ahead` predicts
both. Two capabilities more, declared as Protocols:

- :class:`DeckMotionFusing`: the ship's motion reference unit (MRU) broadcast, the deck's roll and pitch
  and the heave rate at the pad (``platform.sea.motion_telemetry``), fused at its stamps;
- :class:`DeckPredicting`: the deck's heave, roll and pitch predicted with their covariance, which the
  quiet-window touchdown reads (:mod:`alight.mission.quiet_window`).

**The deck's attitude from PnP.** A geolocator that solves the pad's pose gives the pad's normal n in W
(``PlatformMeasurement.n_WP``), which a pad symmetric under rotations about its normal (the Falanga tag's
4-fold yaw) does not make ambiguous. The deck's roll and pitch are n's ZYX angles in the vessel's heading
frame H (the horizontal track's heading psi, FLU: roll port up, pitch bow down): with ``n_H = Rz(-psi)
n``, ``Ry(theta) Rx(phi) e_z = (sin theta cos phi, -sin phi, cos theta cos phi)`` gives

    phi = asin(-n_H,y),   theta = atan2(n_H,x, n_H,z)

and their covariance is n's through that map plus the heading's (``HEADING_STD_RAD``) through
``d n_H / d psi = (n_H,y, -n_H,x, 0)``. Before the track has a heading, only the height is fused.

Bad measurements (a tilt beyond :data:`alight.estimation.deck_estimator.MAX_ANGLE_RAD`, a degenerate
covariance) are refused (``update`` returns False), as a gated measurement is.
"""

from __future__ import annotations

import math
from typing import Protocol, runtime_checkable

import numpy as np

from alight.errors import MeasurementError
from alight.estimation.deck_estimator import DeckEstimator, DeckEstimatorConfig, DeckPrediction
from alight.estimation.guards import check_measurement
from alight.types import FloatArray, PlatformEstimate, PlatformMeasurement

__all__ = [
    "HEADING_STD_RAD",
    "DeckMotionFusing",
    "DeckPlatformEstimator",
    "DeckPredicting",
    "deck_roll_pitch",
]

HEADING_STD_RAD = 0.1
"""Standard deviation of the heading the deck's tilt is resolved in (rad, 6 deg): the track's heading
error plus the vessel's yaw with the waves (the packaged classes yaw a few degrees at sea state 5). At a
5 deg tilt it adds 0.5 deg across it."""


@runtime_checkable
class DeckMotionFusing(Protocol):
    """A platform estimator that fuses a ship's motion reference unit broadcast."""

    def update_deck_motion(
        self, t_stamp: float, roll_pitch: FloatArray, heave_rate: float, cov: FloatArray
    ) -> bool:
        """Fuse an MRU sample taken at ``t_stamp`` (s): the deck's (roll, pitch) (2,) rad in its heading
        frame and the pad's vertical speed (m/s), covariance (3, 3). True when used."""
        ...


@runtime_checkable
class DeckPredicting(Protocol):
    """A platform estimator that predicts the deck's heave, roll and pitch with their covariance."""

    def predict_deck(self, times: FloatArray) -> DeckPrediction | None:
        """The deck at the absolute ``times`` (k,) s; None before any measurement of it."""
        ...


def deck_roll_pitch(
    n_W: FloatArray, cov_n_W: FloatArray, heading: float, heading_var: float
) -> tuple[FloatArray, FloatArray]:
    """The deck's (roll, pitch) (rad) from its normal ``n_W`` (3,) in W and the heading (rad), and their
    covariance (2, 2) (module docstring)."""
    c, s = math.cos(heading), math.sin(heading)
    Rt = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # Rz(-heading)
    n = Rt @ np.asarray(n_W, dtype=np.float64)
    n = n / float(np.linalg.norm(n))
    roll = math.asin(max(-1.0, min(1.0, -float(n[1]))))
    pitch = math.atan2(float(n[0]), float(n[2]))
    cos_roll = max(math.sqrt(max(1.0 - float(n[1]) ** 2, 0.0)), 1e-9)
    hxz = max(float(n[0]) ** 2 + float(n[2]) ** 2, 1e-18)
    J = np.array([[0.0, -1.0 / cos_roll, 0.0], [float(n[2]) / hxz, 0.0, -float(n[0]) / hxz]])
    g = J @ np.array([float(n[1]), -float(n[0]), 0.0])
    cov = J @ Rt @ np.asarray(cov_n_W, dtype=np.float64) @ Rt.T @ J.T + heading_var * np.outer(g, g)
    return np.array([roll, pitch]), 0.5 * (cov + cov.T)


class DeckPlatformEstimator:
    """The deck estimator as a :class:`alight.estimation.PlatformEstimator` (module docstring)."""

    def __init__(self, config: DeckEstimatorConfig | None = None) -> None:
        self.config = config if config is not None else DeckEstimatorConfig()
        self.deck = DeckEstimator(self.config)
        self.n_refused = 0
        """Measurements refused as bad input (MeasurementError)."""

    @property
    def initialized(self) -> bool:
        return self.deck.horizontal.initialized and self.deck.initialized

    @property
    def has_measurement(self) -> bool:
        return self.deck.horizontal.has_measurement and self.deck.initialized

    def reset(self) -> None:
        self.deck = DeckEstimator(self.config)

    def predict(self, t: float) -> None:
        self.deck.set_clock(t)
        self.deck.horizontal.predict(t)

    def update(self, measurement: PlatformMeasurement) -> bool:
        m = measurement
        # the camera path's one rule for every platform estimator: an absurd measurement is refused
        # (MeasurementError) before anything is read from it; a late or future one returns False below
        check_measurement(m, "deck_kf.update")
        rp: FloatArray | None = None
        cov_rp: FloatArray | None = None
        h = self.deck.horizontal
        if m.n_WP is not None and m.cov_n_WP is not None and h.initialized:
            rp, cov_rp = deck_roll_pitch(m.n_WP, m.cov_n_WP, h.state(m.t).yaw, HEADING_STD_RAD**2)
            if float(np.linalg.eigvalsh(cov_rp).min()) <= 0.0:
                rp = cov_rp = None  # a degenerate attitude covariance: the position alone
        try:
            return self.deck.update_pose(m.t, m.p_WP, m.cov_p_WP, rp, cov_rp)
        except MeasurementError:
            self.n_refused += 1
            return False

    def update_deck_motion(
        self, t_stamp: float, roll_pitch: FloatArray, heave_rate: float, cov: FloatArray
    ) -> bool:
        try:
            return self.deck.update_mru(t_stamp, roll_pitch, heave_rate, cov)
        except MeasurementError:
            self.n_refused += 1
            return False

    def predict_deck(self, times: FloatArray) -> DeckPrediction | None:
        if not self.deck.initialized:
            return None
        return self.deck.predict(times)

    def state(self, t: float) -> PlatformEstimate:
        h = self.deck.horizontal_state(t)
        if not self.deck.initialized:
            return h
        pred = self.deck.predict(np.array([t]))
        p = h.p_WP.copy()
        v = h.v_WP.copy()
        a = h.a_WP.copy()
        cov = h.cov_p_WP.copy()
        p[2], v[2], a[2] = pred.state[0, 0], pred.state[0, 1], 0.0
        cov[2, :] = cov[:, 2] = 0.0
        cov[2, 2] = pred.cov[0, 0, 0]
        t_last = max(h.t_last_measurement, self.deck.t_filter)
        return PlatformEstimate(
            t=h.t, p_WP=p, v_WP=v, a_WP=a, yaw=h.yaw, cov_p_WP=cov, t_last_measurement=t_last
        )

    def predict_ahead(self, times: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        p, v, a, yaw = self.deck.horizontal.predict_ahead(times)
        p, v, a = p.copy(), v.copy(), a.copy()
        if self.deck.initialized:
            pred = self.deck.predict(np.asarray(times, dtype=np.float64))
            p[:, 2], v[:, 2], a[:, 2] = pred.state[:, 0], pred.state[:, 1], 0.0
        return p, v, a, yaw

    def diagnostics(self) -> dict[str, object]:
        """The deck estimator's counters and the refused measurements."""
        return {**self.deck.diagnostics(), "n_refused": self.n_refused}
