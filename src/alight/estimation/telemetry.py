"""Fusing the platform's own GNSS telemetry with the camera: the telemetry bias and the fixes.

The platform broadcasts fixes ``(t_stamp, p_WP, v_WP, cov)`` that arrive late and carry a bias the
receiver does not know (GNSS: metres, slowly varying). The bias is estimated here, from the camera: each
camera measurement of the pad, compared with the telemetry fix at its capture time, is a measurement of
the bias,

    y = p_tel(t_c) - z_cam(t_c) = b + n_tel + n_cam + (carry error),

so the bias is observable only while the camera sees the pad, and without the camera it stays at its
prior (zero, with ``bias_prior_std_m``). The bias is a random walk (``bias_walk``), which covers a slowly
wandering bias as well as a constant one.

Why a separate filter rather than augmenting the platform filter's state: the bias measurement above uses
the raw camera measurement and the raw fix, never the platform estimate, so the bias filter is fed nothing
that the telemetry itself has already pulled toward the fix (an augmented state with an identity telemetry
model would be exact too, but needs the bias inside every estimator's numba kernels; this way one small
filter serves every estimator). What it gives up: the correlation between the bias estimate and the
platform estimate, which both use the same camera measurements; the platform filter compensates by never
letting telemetry make it more certain than the bias is known (:func:`telemetry_adds_information`).

A fix is used by the platform filter corrected, ``p - b``, with covariance ``cov + P_b``, after being
carried in time on its own velocity, along the filter's turn, to the filter's time
(:func:`carry_fix_on_turn`).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from alight.types import FloatArray


@dataclass(frozen=True, kw_only=True)
class TelemetryFusionConfig:
    """How an estimator uses telemetry."""

    bias_prior_std_m: float = 2.0
    """Prior standard deviation of the telemetry bias per axis, before the camera has seen the pad (m)."""
    bias_walk: float = 0.02
    """Random-walk density of the bias (m/sqrt(s)): a GNSS bias drifts by centimetres per minute."""
    velocity_std_mps: float = 0.2
    """Uncertainty of a fix's velocity (m/s): its noise and the platform's unmodelled acceleration; for
    carrying a fix in time and for fusing the velocity as heading and speed."""
    velocity_min_mps: float = 1.0
    """A fix's velocity is fused (as heading and speed) only above this speed (m/s): below, its heading
    is noise."""
    time_guard_s: float = 0.25
    """A fix is fused no later than this before its stamp (s), so that a camera measurement arriving
    afterwards (captured up to the camera's latency earlier) is still in time order for the filter. Keep
    it at least the camera's latency."""
    max_carry_s: float = 1.0
    """A fix is not carried further in time than this (s): it is stale."""

    def __post_init__(self) -> None:
        for name in ("bias_prior_std_m", "velocity_std_mps", "max_carry_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"telemetry.{name} must be positive, got {v}")
        for name in ("bias_walk", "time_guard_s", "velocity_min_mps"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"telemetry.{name} must be >= 0, got {v}")


def carry_fix(
    t_stamp: float, p_WP: FloatArray, v_WP: FloatArray, cov: FloatArray, t: float, velocity_std_mps: float
) -> tuple[FloatArray, FloatArray]:
    """The fix taken at ``t_stamp`` carried to ``t`` (s) on its own velocity: position (3,) (m) and its
    covariance (3, 3) (m^2), grown by ``(velocity_std_mps dt)^2`` per axis."""
    p, _, c = carry_fix_on_turn(t_stamp, p_WP, v_WP, cov, t, velocity_std_mps, 0.0)
    return p, c


def carry_fix_on_turn(
    t_stamp: float,
    p_WP: FloatArray,
    v_WP: FloatArray,
    cov: FloatArray,
    t: float,
    velocity_std_mps: float,
    turn_rate_rad_s: float,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The fix taken at ``t_stamp`` carried to ``t`` (s) along a turn at ``turn_rate_rad_s`` (rad/s,
    counter-clockwise) at its own speed: position (3,) (m), velocity (3,) (m/s, its horizontal part
    turned by ``omega dt``) and the position's covariance (3, 3) (m^2), grown by ``(velocity_std_mps
    dt)^2`` per axis. Exact on a circle (the constant-turn-rate model of the unicycle filter), the
    straight line at ``omega = 0``. Why: a fix is fused up to ``time_guard_s`` before its stamp, and
    carried straight its heading is ``omega dt`` off: on a 30 m circle at 8.5 m/s, 0.07 rad, 0.6 m/s
    of velocity across the track, fused as if exact (the heading's variance is ``0.2^2 / v^2``)."""
    dt = t - t_stamp
    v = np.asarray(v_WP, dtype=np.float64)
    phi = float(turn_rate_rad_s) * dt
    if abs(phi) < 1e-4:
        s_over, c_over = 1.0 - phi * phi / 6.0, 0.5 * phi
    else:
        s_over, c_over = math.sin(phi) / phi, (1.0 - math.cos(phi)) / phi
    vx, vy = float(v[0]), float(v[1])
    # the chord of the arc: dt (S v + C J v), J the quarter turn counter-clockwise
    p = np.asarray(p_WP, dtype=np.float64) + dt * np.array(
        [s_over * vx - c_over * vy, s_over * vy + c_over * vx, float(v[2])]
    )
    cp, sp = math.cos(phi), math.sin(phi)
    v_t = np.array([cp * vx - sp * vy, sp * vx + cp * vy, float(v[2])])
    c = np.asarray(cov, dtype=np.float64) + np.eye(3) * (velocity_std_mps * dt) ** 2
    return p, v_t, c


def bias_update(b: FloatArray, P: FloatArray, y: FloatArray, R: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Kalman update of the bias ``b`` (3,), covariance ``P`` (3, 3) with a direct measurement ``y`` of it,
    covariance ``R``: K = P (P + R)^-1, b + K (y - b), (I - K) P (I - K)^T + K R K^T (Joseph form: stays
    symmetric positive definite under round-off)."""
    S = P + R
    K = np.linalg.solve(S, P).T  # P symmetric, S symmetric: K = P S^-1 = (S^-1 P)^T
    b_new = b + K @ (y - b)
    A = np.eye(3) - K
    P_new = A @ P @ A.T + K @ R @ K.T
    return b_new, 0.5 * (P_new + P_new.T)


def telemetry_adds_information(P_pos_xy: FloatArray, P_bias_xy: FloatArray) -> bool:
    """True when a fix can still tell the filter something: its horizontal position variance (trace of the
    (2, 2) block) exceeds the bias's. Every fix shares the same unknown bias, so fusing fix after fix as if
    their errors were independent would make the filter more certain than the bias is known (and then
    reject the camera when it sees the pad where the bias put it); below that floor fixes are skipped."""
    return float(np.trace(P_pos_xy)) > float(np.trace(P_bias_xy))


class TelemetryBias:
    """The bias filter and the recent fixes (see the module docstring)."""

    def __init__(self, config: TelemetryFusionConfig | None = None) -> None:
        self.config = config if config is not None else TelemetryFusionConfig()
        self.reset()

    def reset(self) -> None:
        self.b = np.zeros(3)
        """Bias estimate (m), (3,): telemetry minus truth."""
        self.P = np.eye(3) * self.config.bias_prior_std_m**2
        """Its covariance (m^2), (3, 3)."""
        self._t_b = math.nan
        self._fixes: deque[tuple[float, FloatArray, FloatArray, FloatArray]] = deque(maxlen=64)
        self.n_fixes = 0
        self.n_bias_updates = 0

    @property
    def has_fix(self) -> bool:
        return bool(self._fixes)

    def add_fix(self, t_stamp: float, p_WP: FloatArray, v_WP: FloatArray, cov: FloatArray) -> None:
        """Keep a fix (stamps need not be in order; the nearest in time is used)."""
        self._fixes.append(
            (float(t_stamp), np.array(p_WP, float), np.array(v_WP, float), np.array(cov, float))
        )
        self.n_fixes += 1

    def fix_at(self, t: float) -> tuple[FloatArray, FloatArray] | None:
        """The fix nearest in time to ``t`` carried to ``t`` (position, covariance), or None when the
        nearest is more than ``max_carry_s`` away."""
        if not self._fixes:
            return None
        ts, p, v, c = min(self._fixes, key=lambda f: abs(f[0] - t))
        if abs(ts - t) > self.config.max_carry_s:
            return None
        return carry_fix(ts, p, v, c, t, self.config.velocity_std_mps)

    def _walk_to(self, t: float) -> None:
        if math.isfinite(self._t_b) and t > self._t_b:
            self.P = self.P + np.eye(3) * self.config.bias_walk**2 * (t - self._t_b)
        if not (math.isfinite(self._t_b) and t < self._t_b):
            self._t_b = t

    def on_camera(self, t_capture: float, z_WP: FloatArray, R_cam: FloatArray) -> bool:
        """Learn the bias from a camera measurement ``z_WP`` (3,) with covariance ``R_cam`` (3, 3) captured
        at ``t_capture``; True when a fix near that time existed."""
        carried = self.fix_at(t_capture)
        if carried is None:
            return False
        p_tel, R_tel = carried
        self._walk_to(t_capture)
        self.b, self.P = bias_update(self.b, self.P, p_tel - np.asarray(z_WP, float), R_tel + R_cam)
        self.n_bias_updates += 1
        return True

    def corrected(self, p_WP: FloatArray, cov: FloatArray, t: float) -> tuple[FloatArray, FloatArray]:
        """A fix (already carried to ``t``) with the bias removed: ``p - b``, ``cov + P_b``."""
        self._walk_to(t)
        return np.asarray(p_WP, float) - self.b, np.asarray(cov, float) + self.P
