"""Velocity of the moving platform from its successive positions (paper 004, Sec. IV-B, last paragraphs).

The paper: "The magnitude is calculated by differentiating two sequential X,Y position measurements of the
moving platform and taking into consideration the UAV's NED velocities ... A low-pass filter is used to
provide a smoothest estimation of the magnitude. ... the moving platform is likely to change its direction
up to 180 degrees ... the moving platform's yaw orientation will be taken into account and based on the
velocity's magnitude, the moving platform's velocity in X, Y NED frame can be obtained."

alight's measurements are already in W (the geolocator used the UAV's pose at the capture time), so the
UAV's own motion is out of them and differencing gives the platform's velocity directly. The estimate is
kept as a speed and a heading, each low-passed on its own, and recombined as
``v = speed (cos(heading), sin(heading), 0)``:

- raw velocity ``v_k = (p_k - p_j) / (t_k - t_j)``, ``j`` the newest earlier measurement at least
  ``min_baseline_s`` older (0: the sequential measurement, as the paper; a longer baseline divides the
  position noise by it) and at most ``max_baseline_s`` (a longer gap restarts the differencing);
- speed: a first-order low-pass filter ``y += alpha (u - y)``, ``alpha = 1 - exp(-2 pi f_c dt)`` with
  ``dt`` the time between updates, on ``u = |v_k|^2 - tr(Sigma_v)`` when the measurements carry
  covariances (the noise adds ``tr(Sigma_v)`` to the mean of ``|v_k|^2``; subtracting it makes the squared
  speed unbiased), speed ``= sqrt(max(y, 0))``;
- heading: the same filter on the circle, ``psi += alpha_h wrap(u_psi - psi)``, with ``u_psi`` the measured
  pad yaw when ``use_measured_yaw`` (its ``2 pi / yaw_fold`` ambiguity resolved to the candidate nearest
  the current heading) or else ``atan2`` of the raw velocity when it is above ``heading_min_speed_mps``
  (below that its direction is noise and the heading is held).

Measured yaw as increments (``measured_yaw_increments``): a complementary filter. The marker's orientation
is fast and its change between two frames is unambiguous (far below half the fold period at any turn
rate a ground vehicle reaches), but its value is known only modulo ``2 pi / yaw_fold`` (the n-fold marker
alone: 2 pi / n) and only up to how the pad was mounted on the vehicle; the direction of travel is slow
(the lag below) but absolute. So every measured yaw change turns the heading at once and the low-pass on
the travel direction then only corrects the slow part. The travel direction itself is the chord's, the
heading at the middle of the baseline; the measured turn over the chord's second half brings it to the
newest time. In a steady turn the heading then has no lag at all (against ``omega (B / 2 + dt (1 - alpha)
/ alpha)`` without), and neither a fold ambiguity nor a mounting offset reaches the estimate.

Why not low-pass the velocity vector: through a U-turn its components reverse and a vector filter shrinks
the speed by ``1 / sqrt(1 + (omega tau)^2)`` (``tau = 1 / (2 pi f_c)``, ``omega`` the turn rate) while the
wrapped heading filter turns through 180 degrees with a constant lag and the speed stays whole. In a
steady turn at rate ``omega`` with measurements every ``dt`` the heading lags the truth (at the capture
time) by exactly ``omega (B / 2 + dt (1 - alpha_h) / alpha_h)``: the chord over the baseline ``B`` points
along the tangent at its middle, and a first-order filter trails a ramp by ``(1 - alpha) / alpha`` steps
(``test_platform_velocity.py`` checks both).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np

from alight.errors import EstimationError
from alight.types import FloatArray, wrap_angle


def lowpass_alpha(cutoff_hz: float, dt: float) -> float:
    """Gain of the discrete first-order low-pass filter with cut-off ``cutoff_hz`` (Hz) over ``dt`` (s)
    (exact discretisation of ``tau dy/dt = u - y``, ``tau = 1 / (2 pi cutoff_hz)``)."""
    return 1.0 - math.exp(-2.0 * math.pi * cutoff_hz * dt)


@dataclass(frozen=True, kw_only=True)
class PlatformVelocityConfig:
    """Parameters of :class:`PlatformVelocityEstimator`."""

    cutoff_hz: float = 0.5
    """Cut-off of the speed's first-order low-pass filter (Hz). The paper gives no value."""
    heading_cutoff_hz: float | None = None
    """Cut-off of the heading's filter (Hz); None: ``cutoff_hz``."""
    min_baseline_s: float = 0.2
    """Shortest time between the two positions differenced (s); 0 differences sequential measurements."""
    max_baseline_s: float = 1.0
    """Longest time between them (s): after a longer gap the differencing restarts."""
    heading_min_speed_mps: float = 0.3
    """A raw velocity slower than this (m/s) does not move the heading."""
    debias: bool = True
    """Subtract the position noise's share of ``|v|^2`` (needs measurement covariances)."""
    use_measured_yaw: bool = False
    """Use the measured pad yaw, when a measurement has one, as the heading's input."""
    measured_yaw_increments: bool = False
    """Turn the heading at once by the change of the measured pad yaw between consecutive measurements
    (modulo ``2 pi / yaw_fold``), the direction of travel still setting the heading's value (see the
    module docstring). Exclusive with ``use_measured_yaw``."""
    yaw_fold: int = 1
    """Rotational symmetry of the measured yaw (it is known modulo ``2 pi / yaw_fold``)."""

    def __post_init__(self) -> None:
        for name in ("cutoff_hz", "max_baseline_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{name} must be finite and > 0, got {v}")
        if self.heading_cutoff_hz is not None and not (
            math.isfinite(self.heading_cutoff_hz) and self.heading_cutoff_hz > 0.0
        ):
            raise ValueError(
                f"heading_cutoff_hz must be finite and > 0 or None, got {self.heading_cutoff_hz}"
            )
        if not (math.isfinite(self.min_baseline_s) and 0.0 <= self.min_baseline_s < self.max_baseline_s):
            raise ValueError("min_baseline_s must be finite, >= 0 and below max_baseline_s")
        if not (math.isfinite(self.heading_min_speed_mps) and self.heading_min_speed_mps >= 0.0):
            raise ValueError(f"heading_min_speed_mps must be >= 0, got {self.heading_min_speed_mps}")
        if int(self.yaw_fold) != self.yaw_fold or self.yaw_fold < 1:
            raise ValueError(f"yaw_fold must be a positive integer, got {self.yaw_fold}")
        if self.use_measured_yaw and self.measured_yaw_increments:
            raise ValueError("use_measured_yaw and measured_yaw_increments are exclusive: pick one")


class PlatformVelocityEstimator:
    """Speed and heading of the platform from its positions in W (see the module docstring)."""

    def __init__(self, config: PlatformVelocityConfig | None = None) -> None:
        self.config = config if config is not None else PlatformVelocityConfig()
        c = self.config
        self._fh = c.heading_cutoff_hz if c.heading_cutoff_hz is not None else c.cutoff_hz
        self.reset()

    def reset(self) -> None:
        """Forget everything."""
        # recent positions: times, and (t, x, y, trace of the horizontal covariance or NaN, yaw turned)
        self._bt: list[float] = []
        self._buf: list[tuple[float, float, float, float, float]] = []
        self._s2 = math.nan
        self._psi = math.nan
        self._t_speed = math.nan
        self._t_heading = math.nan
        self._t_last = math.nan
        self._yaw_prev = math.nan
        self._t_yaw_prev = math.nan
        self._turned = 0.0  # sum of the measured yaw increments (rad)
        self.n_samples = 0
        """Raw velocities formed so far."""

    # ---- input ------------------------------------------------------------------------------------

    def update(
        self, t: float, p_WP: FloatArray, cov_p_WP: FloatArray | None = None, yaw: float | None = None
    ) -> bool:
        """A platform position ``p_WP`` (m, W; (2,) or (3,), only x and y are used) at time ``t`` (s), with
        its covariance ((2, 2) or (3, 3), m^2) and the measured pad yaw (rad) when known. True when it gave
        a new raw velocity. Measurements must come in time order (older ones are ignored)."""
        p = p_WP.tolist() if isinstance(p_WP, np.ndarray) and p_WP.ndim == 1 else list(np.ravel(p_WP))
        if len(p) < 2 or not math.isfinite(t + p[0] + p[1]):
            raise EstimationError(f"PlatformVelocityEstimator.update: bad position {p_WP} at t={t}")
        x, y = float(p[0]), float(p[1])
        tr = math.nan
        if cov_p_WP is not None:
            tr = float(cov_p_WP[0, 0] + cov_p_WP[1, 1])
        if not t > self._t_last and math.isfinite(self._t_last):
            return False
        c = self.config
        if yaw is not None and c.use_measured_yaw and math.isfinite(yaw):
            self._heading_input(t, float(yaw), measured=True)
        if c.measured_yaw_increments:
            self._turn_by_measured_yaw(t, yaw)
        bt, buf = self._bt, self._buf
        k0 = bisect.bisect_left(bt, t - c.max_baseline_s)
        if k0 > 0:
            del bt[:k0]
            del buf[:k0]
        # the newest entry at least min_baseline_s older (t is above every buffered time)
        k = bisect.bisect_right(bt, t - c.min_baseline_s) - 1
        j = buf[k] if k >= 0 else None
        bt.append(t)
        buf.append((t, x, y, tr, self._turned))
        self._t_last = t
        if j is None:
            return False
        dt = t - j[0]
        vx, vy = (x - j[1]) / dt, (y - j[2]) / dt
        v2 = vx * vx + vy * vy
        u = v2
        if c.debias and math.isfinite(tr) and math.isfinite(j[3]):
            u = v2 - (tr + j[3]) / (dt * dt)
        if math.isnan(self._s2):
            self._s2 = u
        else:
            self._s2 += lowpass_alpha(c.cutoff_hz, t - self._t_speed) * (u - self._s2)
        self._t_speed = t
        self.n_samples += 1
        if not (c.use_measured_yaw and yaw is not None) and math.sqrt(v2) >= c.heading_min_speed_mps:
            # the chord points along the heading at the baseline's middle; with measured yaw increments
            # the turn since then is known, and adding it removes the lag omega B / 2 as well
            psi_travel = math.atan2(vy, vx) + 0.5 * (self._turned - j[4])
            self._heading_input(t, psi_travel, measured=False)
        return True

    def _turn_by_measured_yaw(self, t: float, yaw: float | None) -> None:
        if yaw is None or not math.isfinite(yaw):
            return
        prev, t_prev = self._yaw_prev, self._t_yaw_prev
        self._yaw_prev, self._t_yaw_prev = float(yaw), t
        # an increment across a long gap could have wrapped past half the fold period: skip it
        if math.isnan(prev) or t - t_prev > self.config.max_baseline_s:
            return
        period = 2.0 * math.pi / self.config.yaw_fold
        turn = (yaw - prev + 0.5 * period) % period - 0.5 * period
        self._turned += turn
        if not math.isnan(self._psi):
            self._psi = wrap_angle(self._psi + turn)

    def _heading_input(self, t: float, psi_in: float, measured: bool) -> None:
        if measured and self.config.yaw_fold > 1 and math.isfinite(self._psi):
            period = 2.0 * math.pi / self.config.yaw_fold
            psi_in = self._psi + ((psi_in - self._psi + 0.5 * period) % period - 0.5 * period)
        if math.isnan(self._psi):
            self._psi = wrap_angle(psi_in)
        else:
            a = lowpass_alpha(self._fh, t - self._t_heading)
            self._psi = wrap_angle(self._psi + a * wrap_angle(psi_in - self._psi))
        self._t_heading = t

    # ---- output -----------------------------------------------------------------------------------

    @property
    def initialized(self) -> bool:
        """True once there is a speed and a heading (or a speed below ``heading_min_speed_mps``: a parked
        platform has no heading to find)."""
        if math.isnan(self._s2):
            return False
        return not math.isnan(self._psi) or self.speed < self.config.heading_min_speed_mps

    @property
    def speed(self) -> float:
        """Low-passed speed (m/s); 0 before the first raw velocity."""
        return math.sqrt(self._s2) if self._s2 > 0.0 else 0.0

    @property
    def heading(self) -> float:
        """Heading (rad, from W x counter-clockwise, in [-pi, pi)); 0 before it is known."""
        return self._psi if math.isfinite(self._psi) else 0.0

    @property
    def t_last(self) -> float:
        """Time of the last position used (s), NaN before any."""
        return self._t_last

    def velocity_xy(self) -> tuple[float, float]:
        """The horizontal components of :attr:`velocity` (m/s), as floats."""
        if math.isnan(self._s2) or math.isnan(self._psi):
            return 0.0, 0.0
        s = self.speed
        return s * math.cos(self._psi), s * math.sin(self._psi)

    @property
    def velocity(self) -> FloatArray:
        """``speed (cos heading, sin heading, 0)`` (m/s, W), shape (3,); zeros until the heading is known."""
        vx, vy = self.velocity_xy()
        return np.array([vx, vy, 0.0])


__all__ = ["PlatformVelocityConfig", "PlatformVelocityEstimator", "lowpass_alpha"]
