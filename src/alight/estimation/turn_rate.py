"""Turn rate of the platform from the heading of its estimated velocity, and prediction along a turn.

For the estimators whose own motion model is constant velocity (paper 003's UKF, paper 004's Kalman filter
with its velocity estimator). Their predictions run along the tangent: on a circle of radius ``R`` the point
``tau`` seconds ahead is off the circle by ``(v tau)^2 / (2 R)``, outward (0.2-1.8 m at 2 m/s, R = 10 m, 1-3 s
ahead). The tracking planner aims at those predictions, so the vehicle orbits outside the platform and
never gets above it to land (every kim_kaist and zamanakos_sdu mission on a 2 m/s circle timed out in the
paper_conditions campaign). **Our extension, not in papers 003 and 004**; their models are recovered
with ``turn_model=False`` in each estimator's config.

Turn rate: the heading ``psi = atan2(v_y, v_x)`` of the estimator's velocity is differenced over a
baseline of at least ``baseline_s`` (a shorter one divides the heading noise by too little) and low-passed
(first order, ``cutoff_hz``); below ``min_speed_mps`` the heading is noise and nothing is updated, and
after a gap longer than ``max_gap_s`` the differencing restarts. Prediction: the constant turn rate and
speed model (paper 000's unicycle, eq. 2, :func:`alight.estimation.platform_ekf.unicycle_predict_ahead`)
from the estimator's position and velocity.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from alight.estimation.platform_ekf import unicycle_predict_ahead
from alight.estimation.platform_velocity import lowpass_alpha
from alight.types import FloatArray


@dataclass(frozen=True, kw_only=True)
class TurnRateConfig:
    baseline_s: float = 0.5
    """Shortest time between the two headings differenced (s)."""
    cutoff_hz: float = 0.3
    """Cut-off of the first-order low-pass filter on the differenced rate (Hz)."""
    min_speed_mps: float = 0.5
    """Slower than this the heading is not used (m/s)."""
    max_gap_s: float = 1.5
    """A longer gap between updates restarts the differencing (s)."""
    max_rate_rad_s: float = 1.0
    """Bound on the rate (rad/s): a ground vehicle at speed turns slower than this."""

    def __post_init__(self) -> None:
        for name in ("baseline_s", "cutoff_hz", "max_gap_s", "max_rate_rad_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{name} must be finite and > 0, got {v}")
        if not (math.isfinite(self.min_speed_mps) and self.min_speed_mps >= 0.0):
            raise ValueError(f"min_speed_mps must be >= 0, got {self.min_speed_mps}")


class TurnRateTracker:
    """Low-passed rate of change of a heading (see the module docstring)."""

    def __init__(self, config: TurnRateConfig | None = None) -> None:
        self.config = config if config is not None else TurnRateConfig()
        self.reset()

    def reset(self) -> None:
        self._hist: deque[tuple[float, float]] = deque()  # (t, unwrapped heading)
        self._rate = 0.0
        self._t_rate = math.nan

    @property
    def rate(self) -> float:
        """Turn rate (rad/s, counter-clockwise positive); 0 until known."""
        return self._rate

    def update(self, t: float, v_x: float, v_y: float) -> None:
        """The estimated horizontal velocity (m/s, W) at time ``t`` (s). Older or non-finite input is
        ignored (an estimator's output can go back in time only through a reset, which resets this)."""
        c = self.config
        if not math.isfinite(t + v_x + v_y) or math.hypot(v_x, v_y) < c.min_speed_mps:
            return
        hist = self._hist
        if hist and (t <= hist[-1][0] or t - hist[-1][0] > c.max_gap_s):
            if t <= hist[-1][0]:
                return
            hist.clear()
        psi = math.atan2(v_y, v_x)
        if hist:  # unwrap against the previous heading so differences never jump by 2 pi
            prev = hist[-1][1]
            psi = prev + math.remainder(psi - prev, 2.0 * math.pi)
        hist.append((t, psi))
        while len(hist) > 2 and t - hist[1][0] >= c.baseline_s:
            hist.popleft()  # keep the newest sample at least baseline_s old as the first
        t0, psi0 = hist[0]
        if t - t0 < c.baseline_s:
            return
        raw = (psi - psi0) / (t - t0)
        raw = min(max(raw, -c.max_rate_rad_s), c.max_rate_rad_s)
        if math.isnan(self._t_rate):
            self._rate = raw
        else:
            self._rate += lowpass_alpha(c.cutoff_hz, t - self._t_rate) * (raw - self._rate)
        self._t_rate = t


def turn_predict(
    p_WP: FloatArray, v_WP: FloatArray, turn_rate: float, taus: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Positions (k, 3) m, velocities (k, 3) m/s, accelerations (k, 3) m/s^2 and headings (k,) rad ``taus``
    (k,) seconds from the platform at ``p_WP`` (3,) with horizontal velocity ``v_WP[:2]``, turning at
    ``turn_rate`` (rad/s) at constant speed. ``taus`` may be negative (back along the same arc)."""
    x = np.empty(6)
    x[0:3] = p_WP
    x[3] = math.atan2(float(v_WP[1]), float(v_WP[0]))
    x[4] = math.hypot(float(v_WP[0]), float(v_WP[1]))
    x[5] = float(turn_rate)
    dts = np.ascontiguousarray(taus, dtype=np.float64).reshape(-1)
    k = dts.shape[0]
    p, v, a, yaw = np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3)), np.empty(k)
    unicycle_predict_ahead(x, dts, p, v, a, yaw)
    return p, v, a, yaw


__all__ = ["TurnRateConfig", "TurnRateTracker", "turn_predict"]
