"""Platform telemetry: a GNSS receiver on the ground vehicle broadcasting its position and velocity.

People who land on fast vehicles give the aircraft a coarse prior of where the vehicle is: Borowczyk et
al. 2017 landed on a car at 50 km/h with the car's phone broadcasting its GNSS fix; PX4's Vision Target
Estimator fuses a target's GNSS with vision. This models such a link, as the aircraft receives it:

- fixes at ``rate_hz``, stamped with the time of the fix (the receiver's clock, GNSS-synchronised);
- white noise of ``noise_m`` per axis on the position and ``velocity_noise_mps`` on the velocity;
- a constant bias vector of the position, drawn once per mission with ``bias_m`` per horizontal axis
  (and half that vertically): a standalone receiver's error is dominated by slowly varying atmospheric
  and multipath errors, which over a landing (minutes) are close to constant. A constant bias is the
  harder case for the estimator only in that it never averages out; the estimator models it as a
  random walk, so a slowly wandering bias is covered too;
- the radio link's ``latency_s`` (the fix reaches the aircraft that long after it was taken) and
  ``dropout_prob`` (each fix independently lost).

The reported covariance is the receiver's own claim, ``noise_m^2 I``: a receiver does not know its bias.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

import numpy as np
from pydantic import Field
from pydantic.dataclasses import dataclass as pydantic_dataclass

from alight.settings import SETTINGS, NonNegFloat, Probability, RateHz
from alight.types import FloatArray


@pydantic_dataclass(frozen=True, kw_only=True, config=SETTINGS)
class TelemetryConfig:
    """The platform's own GNSS fix, broadcast to the aircraft; the scenario's ``platform.telemetry``."""

    rate_hz: RateHz = 10.0
    """Fixes per second (Hz)."""
    noise_m: NonNegFloat = 0.5
    """Per-axis standard deviation of the white position noise (m)."""
    velocity_noise_mps: NonNegFloat = 0.1
    """Per-axis standard deviation of the white velocity noise (m/s)."""
    latency_s: Annotated[float, Field(ge=0, le=5.0, allow_inf_nan=False)] = 0.2
    """Delay from the fix to its arrival on the aircraft (s), at most 5."""
    bias_m: NonNegFloat = 1.0
    """Standard deviation of the constant position bias per horizontal axis, half of it vertically (m)."""
    dropout_prob: Probability = 0.0
    """Probability that a fix is lost."""


@dataclass(frozen=True, slots=True)
class TelemetryFix:
    """One fix as the aircraft receives it."""

    t_stamp: float
    """Time of the fix (s)."""
    t_arrival: float
    """Time it reaches the aircraft (s)."""
    p_WP: FloatArray
    """Reported position of the pad centre in W (m), (3,)."""
    v_WP: FloatArray
    """Reported velocity in W (m/s), (3,)."""
    cov_p_WP: FloatArray
    """The receiver's claimed position covariance (m^2), (3, 3)."""


class PlatformTelemetry:
    """Produces the fixes of one mission; every draw comes from ``rng`` (a child of the scenario seed of
    its own, so switching telemetry on changes no other component's random numbers)."""

    def __init__(self, config: TelemetryConfig, rng: np.random.Generator) -> None:
        self.config = config
        self.rng = rng
        b = config.bias_m
        self.bias_W = rng.normal(0.0, 1.0, 3) * np.array([b, b, 0.5 * b])
        """The constant position bias of this mission (m), (3,): truth, for tests and logs only."""
        self._period = 1.0 / config.rate_hz
        self.next_fix_s = 0.0
        """Time of the next fix (s)."""
        self._cov = np.eye(3) * max(config.noise_m, 1e-3) ** 2
        self._cov.flags.writeable = False

    def fix(self, t: float, p_WP: FloatArray, v_WP: FloatArray) -> TelemetryFix | None:
        """The fix taken at ``t`` from the true pad state, or None when the link loses it. Call when
        ``t >= next_fix_s``; it schedules the next one."""
        c = self.config
        self.next_fix_s += self._period
        # draw the noise whether or not the fix is lost, so dropouts do not shift later fixes' noise
        n_p = self.rng.normal(0.0, c.noise_m, 3)
        n_v = self.rng.normal(0.0, c.velocity_noise_mps, 3)
        lost = c.dropout_prob > 0.0 and self.rng.random() < c.dropout_prob
        if lost:
            return None
        p = np.asarray(p_WP, dtype=np.float64) + self.bias_W + n_p
        v = np.asarray(v_WP, dtype=np.float64) + n_v
        return TelemetryFix(t, t + c.latency_s, p, v, self._cov)
