"""Kalman filter on the UAV's position relative to the platform, with the UAV's velocity and acceleration
and the platform's estimated velocity as inputs, and compensation of the detection delay (paper 004,
Sec. IV-B, eq. 1-2).

State (eq. 1): ``x = [x, y]``, the UAV's horizontal position relative to the landing marker
(``x = p_WB - p_WP``, the paper's "position of the UAV in the landing site's local coordinate system").
The paper writes it in NED, alight in W (ENU): the equations are the same in any fixed axes, only the
names change (``x_NED`` -> ``x_W[1]``, ``y_NED`` -> ``x_W[0]``). The vertical is not filtered (the paper
takes Z from the altitude): the platform's height is the last measurement's, with its variance.

Prediction (eq. 1), over each interval ``dt`` between ego samples, with the inputs at its start
(``u = [v_x, v_y, a_x, a_y, vm_x, vm_y]``: UAV velocity and acceleration, platform velocity from
:class:`alight.estimation.platform_velocity.PlatformVelocityEstimator`)::

    x += G u = v dt + a dt^2 / 2 - vm dt,     P += Q = dt sigma_IMU^2 I          (F = I)

(exact for a UAV at constant acceleration over the interval and a platform at constant velocity).
Correction (eq. 2), ``H = I``, ``R = sigma_obs^2 I``, ``P = (I - K H) P``, with the measurement shifted by
what the relative position did during the detection delay ``dt_obs``::

    z = x_obs + (dx_obs, dy_obs),     (dx_obs, dy_obs) = v_mean,obs dt_obs

``v_mean,obs dt_obs`` is taken as the integral of ``G u`` over the delay: the filter's own prediction of the
relative motion between the capture time and the filter's time. The paper names only the UAV's
relocation during ``dt_obs``; for a relative state the platform's motion during the delay counts as much
(1.5 m/s x 250 ms = 0.375 m when tracking), so ``compensation_velocity="relative"`` (default) shifts by
the relative motion and ``"uav"`` by the UAV's alone, the paper's words read literally. Without
compensation the estimate trails by (relative velocity) x delay: the platform's whole speed under a
hovering UAV, much less under one that follows the platform (``test_latency_compensation_at_1_5_mps``).

Gain at the capture time. The shifted measurement says where the relative position was at ``t_c``,
moved on by the known inputs; the process noise of the delay window is in the prior at the filter's time
``t_f`` but not in the measurement, so the two errors are correlated and eq. (2) with ``P(t_f)``
over-weighs a delayed measurement (mean NEES over twice its 2 at 200 ms in ``test_sdu_kf.py``). Fusing at
``t_c`` and predicting on to ``t_f`` gives the same innovation (``x(t_f) = x(t_c) + integral of G u``) with
the gain ``K = P_c (P_c + R)^-1``, ``P_c = P(t_c)``; with ``F = I`` and measurements in capture order the
filter only has to keep ``P`` at the last capture time (``P(t_f) = P_c + (t_f - t_c) sigma_IMU^2 I``).
That is the default (``capture_time_gain``); without delay both are eq. (2) exactly.

Frames and the PlatformEstimator protocol. Measurements arrive in W (``PlatformMeasurement.p_WP``, made
with the ego pose at the capture time ``t_c``); the relative observation is
``x_obs = p_WB(t_c) - p_WP`` with ``p_WB(t_c)`` interpolated from the ego samples the filter was given, so
the ego position cancels as it does in the paper's camera-relative measurement. Outputs go back to W with
the ego position at the filter's time: ``p_WP = p_WB(t_f) - x``; the velocity is the velocity estimator's,
the heading its heading; ``state`` and ``predict_ahead`` extrapolate along the platform's turn
(``turn_model``, :mod:`alight.estimation.turn_rate`; the paper's constant velocity with it off). Position
covariance ``P + |t - t_f| sigma_IMU^2 I`` horizontally (the ego position is taken as known: relative
guidance does not need it).

Driving it. Call :meth:`SduKalmanFilter.set_ego` with every ego estimate (the paper's ~33 ms PX4 EKF
output; in alight the pipeline's controller tick) - each call runs the prediction up to the ego's time
with the inputs of the previous call and then holds the new ones. :meth:`predict` moves the filter on to a
later time with the held inputs (for callers without an ego stream: without any ``set_ego`` the UAV is
taken at rest at the origin and the state is minus the pad's position). :meth:`update` fuses a
measurement: a capture time later than the filter's first moves the filter there; one earlier (the usual
case: detection latency) is brought to the filter's time by the shift above. ``delay_s`` replaces
``t_f - t_c`` by a fixed delay as the paper does with a measured processing time.

Initialisation: the first measurement sets ``x`` (shifted like the others) and ``P = p0 I`` (the paper's
``P = I``). ``initialized`` (the protocol's "has a heading and speed") follows the velocity estimator.

Bad input (:mod:`alight.estimation.guards`; the paper has no gating). A measurement whose time, position
or covariance is out of bounds (non-finite, beyond ``MAX_TIME_S`` / ``MAX_POSITION_M``, a covariance that
is not symmetric positive semi-definite) raises :class:`alight.errors.MeasurementError` and changes
nothing. One stamped more than ``FUTURE_TOLERANCE_S`` after the filter's clock (the latest time given by
:meth:`SduKalmanFilter.set_ego` or :meth:`SduKalmanFilter.predict`) is refused (``n_future``); without a
clock it is taken, but cannot block the filter: ``reinit_after_rejections`` measurements in a row, in
order among themselves, that are too old for the kept history mean the filter's time was the fault, and
the filter restarts from them (``n_restarts``). Innovation gate: a measurement whose innovation is more
than ``GATE_SIGMA`` (10) standard deviations from the prediction (``e^T S^-1 e > 100``) is refused
(``n_gated``) before it touches the filter or the velocity estimator; after ``reinit_after_rejections``
refusals in a row the track is taken as lost and the filter restarts from the next measurement (``P = p0
I``), so a moved platform is not locked out.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from alight.errors import EstimationError
from alight.estimation.guards import (
    FUTURE_TOLERANCE_S,
    GATE_SIGMA,
    MAX_POSITION_M,
    check_covariance,
    check_measurement,
    check_time,
    check_times,
    check_vector,
)
from alight.estimation.platform_velocity import PlatformVelocityConfig, PlatformVelocityEstimator
from alight.estimation.turn_rate import TurnRateConfig, TurnRateTracker, turn_predict
from alight.types import EgoState, FloatArray, PlatformEstimate, PlatformMeasurement, wrap_angle


@dataclass(frozen=True, kw_only=True)
class SduKfConfig:
    """Parameters of :class:`SduKalmanFilter` (the paper gives the forms of Q and R, not their values)."""

    sigma_imu_mps: float = 0.1
    """``sigma_IMU`` of eq. (1), ``Q = dt sigma_IMU^2 I`` (m/s; a random walk of the relative position
    of this density, m/sqrt(s)): the standard deviation of the PX4 EKF's velocity."""
    sigma_obs_m: float = 0.1
    """``sigma_obs`` of eq. (2), ``R = sigma_obs^2 I`` (m)."""
    p0_m2: float = 1.0
    """Initial covariance ``P = p0 I`` (m^2); the paper's ``P = I``."""
    compensate_delay: bool = True
    """Shift measurements by the relative motion during the detection delay (eq. 2's dx_obs, dy_obs)."""
    delay_s: float | None = None
    """Fixed detection delay ``dt_obs`` (s); None: the filter's time minus the capture time."""
    compensation_velocity: Literal["relative", "uav"] = "relative"
    """Shift by the relative motion (UAV minus platform) or by the UAV's alone (the paper's wording)."""
    use_measurement_covariance: bool = False
    """Use the measurement's horizontal covariance as ``R`` instead of ``sigma_obs^2 I``."""
    capture_time_gain: bool = True
    """With compensation, compute the gain from ``P`` at the capture time (exact, see the module
    docstring); False: from ``P`` at the filter's time, as eq. (2) reads."""
    use_acceleration: bool = True
    """Use the UAV's acceleration in ``G u`` (the paper does)."""
    history_s: float = 2.0
    """How far back the ego samples are kept (s): the longest usable detection delay."""
    velocity: PlatformVelocityConfig = field(default_factory=PlatformVelocityConfig)
    """The platform velocity estimator's parameters."""
    turn_model: bool = True
    """Extrapolate ``state`` and ``predict_ahead`` along the platform's turn (the turn rate of the
    velocity estimator's heading, :mod:`alight.estimation.turn_rate`; our extension). False: constant
    velocity, the paper's model."""
    turn: TurnRateConfig = field(default_factory=TurnRateConfig)
    """The turn-rate tracker's parameters."""
    gating: bool = True
    """Refuse innovations beyond ``GATE_SIGMA`` standard deviations (not in the paper; see the module
    docstring)."""
    reinit_after_rejections: int = 5
    """Gate refusals in a row after which the filter restarts from the next measurement."""

    def __post_init__(self) -> None:
        for name in ("sigma_imu_mps", "sigma_obs_m", "p0_m2", "history_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{name} must be finite and > 0, got {v}")
        if self.delay_s is not None and not (math.isfinite(self.delay_s) and self.delay_s >= 0.0):
            raise ValueError(f"delay_s must be finite and >= 0 or None, got {self.delay_s}")
        if self.reinit_after_rejections < 1:
            raise ValueError(f"reinit_after_rejections must be >= 1, got {self.reinit_after_rejections}")
        if self.compensation_velocity not in ("relative", "uav"):
            raise ValueError(
                f"compensation_velocity must be 'relative' or 'uav', got {self.compensation_velocity}"
            )


class SduKalmanFilter:
    """Paper 004's relative-position Kalman filter as a :class:`alight.estimation.PlatformEstimator`."""

    def __init__(self, config: SduKfConfig | None = None) -> None:
        self.config = config if config is not None else SduKfConfig()
        self.velocity_estimator = PlatformVelocityEstimator(self.config.velocity)
        self.turn_rate = TurnRateTracker(self.config.turn)
        self.reset()

    # ---- lifecycle --------------------------------------------------------------------------------

    def reset(self) -> None:
        """Forget everything."""
        self.velocity_estimator.reset()
        self.turn_rate.reset()
        self._x0 = self._x1 = 0.0
        # P at the capture time of the last measurement (t_cap); at the filter's time it is
        # P + (t_f - t_cap) sigma_IMU^2 I, as eq. (1) adds Q = dt sigma_IMU^2 I with F = I
        self._p00 = self._p01 = self._p11 = 0.0
        self._tcap = math.nan
        self._has = False
        self._tf = math.nan
        self._t_meas = math.nan
        self._z = 0.0
        self._var_z = 0.0
        # held inputs: UAV velocity and acceleration (horizontal), platform velocity
        self._u = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
        # knots of the prediction: times, and at each the cumulative UAV and platform displacements and
        # the inputs that hold from it on (for the displacement at any past time)
        self._kt: list[float] = []
        self._kd: list[tuple[float, float, float, float, float, float, float, float, float, float]] = []
        # ego samples: times and positions (for p_WB at a capture time)
        self._et: list[float] = []
        self._ep: list[tuple[float, float, float]] = []
        self._ev = (0.0, 0.0, 0.0)
        self._ea = (0.0, 0.0, 0.0)
        self._du = [0.0, 0.0]
        self._dp = [0.0, 0.0]
        self.n_updates = 0
        """Measurements fused."""
        self.n_too_old = 0
        """Measurements captured before the kept history, ignored."""
        self.last_innovation = np.zeros(2)
        """Innovation ``e`` of the last update (m), (2,)."""
        self.last_nis = math.nan
        """``e^T S^-1 e`` of the last update (chi-square with 2 dof when consistent)."""
        self.last_delay_s = math.nan
        """``dt_obs`` of the last update (s)."""
        self.n_gated = 0
        """Measurements refused by the innovation gate."""
        self.n_future = 0
        """Measurements stamped more than ``FUTURE_TOLERANCE_S`` after the filter's clock, refused."""
        self._consecutive_gated = 0
        self.n_restarts = 0
        """Restarts after a run of measurements too old for the filter's time (a future stamp)."""
        self._t_clock = math.nan
        self._late_t: list[float] = []

    # ---- inputs -----------------------------------------------------------------------------------

    def set_ego(self, ego: EgoState) -> None:
        """The UAV's state at ``ego.t``: predicts up to ``ego.t`` with the inputs held so far, then holds
        ``ego.v_WB`` and ``ego.a_WB`` (and the velocity estimator's current output) as the new inputs."""
        t = float(ego.t)
        p = ego.p_WB.tolist()
        v = ego.v_WB.tolist()
        a = ego.a_WB.tolist() if self.config.use_acceleration else [0.0, 0.0, 0.0]
        # one sum catches any NaN or inf (at 50-200 Hz the per-array checks cost more than the filter)
        if not math.isfinite(t + sum(p) + sum(v) + sum(a)):
            raise EstimationError(f"SduKalmanFilter.set_ego: non-finite ego state at t={t}")
        check_time(t, "SduKalmanFilter.set_ego")
        self._t_clock = t if not t < self._t_clock else self._t_clock
        if math.isnan(self._tf):
            self._tf = t
        elif t > self._tf:
            self._advance(t)
        self._ev = (v[0], v[1], v[2])
        self._ea = (a[0], a[1], a[2])
        if not self._et or t > self._et[-1]:
            self._et.append(t)
            self._ep.append((p[0], p[1], p[2]))
        self._hold_inputs()
        self._trim()

    def _hold_inputs(self) -> None:
        mx, my = self.velocity_estimator.velocity_xy()
        self._u = [self._ev[0], self._ev[1], self._ea[0], self._ea[1], mx, my]
        u = self._u
        knot = (self._du[0], self._du[1], self._dp[0], self._dp[1], u[0], u[1], u[2], u[3], u[4], u[5])
        if self._kt and self._kt[-1] == self._tf:
            self._kd[-1] = knot
        else:
            self._kt.append(self._tf)
            self._kd.append(knot)

    def _trim(self) -> None:
        horizon = self._tf - self.config.history_s
        # keep one entry at or before the horizon so the whole window can be interpolated
        k = bisect.bisect_right(self._kt, horizon) - 1
        if k > 0:
            del self._kt[:k]
            del self._kd[:k]
        k = bisect.bisect_right(self._et, horizon) - 1
        if k > 0:
            del self._et[:k]
            del self._ep[:k]

    def _advance(self, t: float) -> None:
        """Eq. (1) from the filter's time to ``t`` with the held inputs (one step)."""
        dt = t - self._tf
        vx, vy, ax, ay, mx, my = self._u
        hx = vx * dt + 0.5 * ax * dt * dt
        hy = vy * dt + 0.5 * ay * dt * dt
        self._du[0] += hx
        self._du[1] += hy
        self._dp[0] += mx * dt
        self._dp[1] += my * dt
        if self._has:
            self._x0 += hx - mx * dt
            self._x1 += hy - my * dt
        self._tf = t
        self._kt.append(t)
        u = self._u
        self._kd.append(
            (self._du[0], self._du[1], self._dp[0], self._dp[1], u[0], u[1], u[2], u[3], u[4], u[5])
        )

    def predict(self, t: float) -> None:
        """Move the filter on to ``t`` (s) with the held inputs; earlier times are ignored."""
        t = check_time(t, "SduKalmanFilter.predict")
        self._t_clock = t if not t < self._t_clock else self._t_clock
        self._move_to(t)

    def _move_to(self, t: float) -> None:
        """:meth:`predict` without setting the clock (a measurement's own time is no clock)."""
        if math.isnan(self._tf):
            self._tf = float(t)
            self._hold_inputs()
        elif t > self._tf:
            self._advance(float(t))
            self._trim()

    # ---- history lookups --------------------------------------------------------------------------

    def _displacement(self, t: float) -> tuple[float, float, float, float]:
        """Cumulative UAV and platform displacements (m) at ``t`` inside the kept window (exact for the
        piecewise-constant inputs the prediction used)."""
        k = bisect.bisect_right(self._kt, t) - 1
        k = max(k, 0)
        d = self._kd[k]
        tau = t - self._kt[k]
        return (
            d[0] + d[4] * tau + 0.5 * d[6] * tau * tau,
            d[1] + d[5] * tau + 0.5 * d[7] * tau * tau,
            d[2] + d[8] * tau,
            d[3] + d[9] * tau,
        )

    def _ego_position(self, t: float) -> tuple[float, float, float]:
        """``p_WB`` at ``t``: linear between ego samples (as the pipeline's ego history), extrapolated with
        the held velocity and acceleration after the last one; the origin without ego samples."""
        et = self._et
        if not et:
            return (0.0, 0.0, 0.0)
        if t >= et[-1]:
            tau = t - et[-1]
            p, v, a = self._ep[-1], self._ev, self._ea
            return (
                p[0] + v[0] * tau + 0.5 * a[0] * tau * tau,
                p[1] + v[1] * tau + 0.5 * a[1] * tau * tau,
                p[2] + v[2] * tau + 0.5 * a[2] * tau * tau,
            )
        k = bisect.bisect_right(et, t) - 1
        if k < 0:
            return self._ep[0]
        s = (t - et[k]) / (et[k + 1] - et[k])
        p0, p1 = self._ep[k], self._ep[k + 1]
        return (p0[0] + s * (p1[0] - p0[0]), p0[1] + s * (p1[1] - p0[1]), p0[2] + s * (p1[2] - p0[2]))

    # ---- correction -------------------------------------------------------------------------------

    def update(self, measurement: PlatformMeasurement) -> bool:
        """Eq. (2) with a measurement (``measurement.t`` its capture time). True when fused; False when
        it was captured before the kept history (``history_s``)."""
        check_measurement(measurement, "SduKalmanFilter.update")  # alight.estimation.guards
        c = self.config
        t_c = float(measurement.t)
        p = measurement.p_WP.tolist()
        cov = measurement.cov_p_WP
        self._check_measurement(measurement, t_c)
        if t_c > self._t_clock + FUTURE_TOLERANCE_S:  # False without a clock (NaN)
            self.n_future += 1
            return False
        if math.isnan(self._tf):
            self._move_to(t_c)
        elif t_c > self._tf:
            self._move_to(t_c)
        if t_c < self._tf - c.history_s:
            return self._too_old(measurement, t_c)
        self._late_t.clear()
        zx, zy, dt_obs = self._relative_observation(t_c, p)
        if c.use_measurement_covariance:
            r00, r01, r11 = float(cov[0, 0]), float(cov[0, 1]), float(cov[1, 1])
        else:
            r00, r01, r11 = c.sigma_obs_m**2, 0.0, c.sigma_obs_m**2
        # the time the (shifted) measurement is weighed at: its capture time, or the filter's time
        t_gain = self._tf
        if c.compensate_delay and c.capture_time_gain:
            t_gain = max(self._tf - max(dt_obs, 0.0), self._tcap if self._has else -math.inf)
        if self._has and c.gating and self._gated(zx, zy, t_gain, r00, r01, r11):
            return False
        self._consecutive_gated = 0
        self.velocity_estimator.update(t_c, measurement.p_WP, cov, measurement.yaw)
        if c.turn_model and self.velocity_estimator.initialized:
            self.turn_rate.update(t_c, *self.velocity_estimator.velocity_xy())
        self._z = p[2]
        self._var_z = float(cov[2, 2])
        self._t_meas = t_c
        self.n_updates += 1
        if not self._has:
            self._x0, self._x1 = zx, zy
            self._p00, self._p01, self._p11 = c.p0_m2, 0.0, c.p0_m2
            self._tcap = t_gain
            self._has = True
            self._hold_inputs()
            return True
        self._fuse(zx, zy, t_gain, r00, r01, r11, t_c)
        # the platform velocity just changed: hold it from now on
        self._hold_inputs()
        return True

    def _check_measurement(self, measurement: PlatformMeasurement, t_c: float) -> None:
        """A clear EstimationError for a non-finite time, an out-of-range position or a bad covariance."""
        if not math.isfinite(t_c):  # PlatformMeasurement itself refuses non-finite arrays
            raise EstimationError(f"SduKalmanFilter.update: non-finite capture time {t_c}")
        check_time(t_c, "SduKalmanFilter.update")
        check_vector(measurement.p_WP, 3, MAX_POSITION_M, "p_WP", "SduKalmanFilter.update")
        check_covariance(measurement.cov_p_WP, 3, "SduKalmanFilter.update", "cov_p_WP")

    def _too_old(self, measurement: PlatformMeasurement, t_c: float) -> bool:
        """A measurement captured before the kept history: refused, unless a run of them (in order) says
        the filter's time came from a measurement stamped in the future; then the filter restarts from it."""
        self.n_too_old += 1
        if self._late_t and t_c < self._late_t[-1]:
            self._late_t.clear()
        self._late_t.append(t_c)
        if len(self._late_t) < self.config.reinit_after_rejections:
            return False
        counters = (self.n_updates, self.n_too_old, self.n_gated, self.n_future, self.n_restarts + 1)
        self.reset()
        self.n_updates, self.n_too_old, self.n_gated, self.n_future, self.n_restarts = counters
        return self.update(measurement)

    def _relative_observation(self, t_c: float, p: list[float]) -> tuple[float, float, float]:
        """x_obs, the UAV relative to the pad at t_c, shifted to the filter's time when the delay is
        compensated; and the delay used (s)."""
        c = self.config
        pb = self._ego_position(t_c)
        zx, zy = pb[0] - p[0], pb[1] - p[1]
        dt_obs = (self._tf - t_c) if c.delay_s is None else c.delay_s
        self.last_delay_s = dt_obs
        if c.compensate_delay and dt_obs > 0.0:
            t_from = self._tf - dt_obs
            if t_from < self._kt[0]:
                t_from = self._kt[0]
            a = self._displacement(t_from)
            b = self._displacement(self._tf)
            dx, dy = b[0] - a[0], b[1] - a[1]
            if c.compensation_velocity == "relative":
                dx -= b[2] - a[2]
                dy -= b[3] - a[3]
            zx += dx
            zy += dy
        return zx, zy, dt_obs

    def _gated(self, zx: float, zy: float, t_gain: float, r00: float, r01: float, r11: float) -> bool:
        """The gate, before the measurement touches anything (the shift reads only the past): True (and
        counted) when the innovation is beyond GATE_SIGMA; a run of them drops the track."""
        c = self.config
        q = (t_gain - self._tcap) * c.sigma_imu_mps**2
        g00, g01, g11 = self._p00 + q + r00, self._p01 + r01, self._p11 + q + r11
        gdet = g00 * g11 - g01 * g01
        e0, e1 = zx - self._x0, zy - self._x1
        if gdet > 0.0 and (e0 * (g11 * e0 - g01 * e1) + e1 * (g00 * e1 - g01 * e0)) > GATE_SIGMA**2 * gdet:
            self.n_gated += 1
            self._consecutive_gated += 1
            if self._consecutive_gated >= c.reinit_after_rejections:
                self._has = False  # the track is lost: the next measurement starts it again
                self._consecutive_gated = 0
            return True
        return False

    def _fuse(
        self, zx: float, zy: float, t_gain: float, r00: float, r01: float, r11: float, t_c: float
    ) -> None:
        """Eq. (2): e = z - H x, S = H P H^T + R, K = P H^T S^-1, x += K e, P = (I - K H) P, with P
        (eq. 1) at t_gain."""
        e0, e1 = zx - self._x0, zy - self._x1
        q = (t_gain - self._tcap) * self.config.sigma_imu_mps**2
        P00, P01, P11 = self._p00 + q, self._p01, self._p11 + q
        s00, s01, s11 = P00 + r00, P01 + r01, P11 + r11
        det = s00 * s11 - s01 * s01
        if not det > 0.0:
            raise EstimationError(f"SduKalmanFilter.update: innovation covariance not positive at t={t_c}")
        i00, i01, i11 = s11 / det, -s01 / det, s00 / det
        k00 = P00 * i00 + P01 * i01
        k01 = P00 * i01 + P01 * i11
        k10 = P01 * i00 + P11 * i01
        k11 = P01 * i01 + P11 * i11
        self._x0 += k00 * e0 + k01 * e1
        self._x1 += k10 * e0 + k11 * e1
        n00 = (1.0 - k00) * P00 - k01 * P01
        n01 = (1.0 - k00) * P01 - k01 * P11
        n10 = -k10 * P00 + (1.0 - k11) * P01
        n11 = -k10 * P01 + (1.0 - k11) * P11
        self._p00, self._p01, self._p11 = n00, 0.5 * (n01 + n10), n11
        self._tcap = t_gain
        self.last_innovation = np.array([e0, e1])
        self.last_nis = e0 * (i00 * e0 + i01 * e1) + e1 * (i01 * e0 + i11 * e1)

    # ---- outputs ----------------------------------------------------------------------------------

    @property
    def initialized(self) -> bool:
        """True once the platform's heading and speed are estimated (the velocity estimator's)."""
        return self._has and self.velocity_estimator.initialized

    @property
    def has_measurement(self) -> bool:
        """True once a measurement was fused (``state`` gives a position)."""
        return self._has

    @property
    def t_filter(self) -> float:
        """The filter's time (s): the latest of the ego samples, ``predict`` and capture times."""
        return self._tf

    @property
    def x(self) -> FloatArray:
        """Relative position ``p_WB - p_WP`` (m, W axes), (2,), at ``t_filter``."""
        return np.array([self._x0, self._x1])

    @property
    def covariance(self) -> FloatArray:
        """``P`` (m^2), (2, 2), at ``t_filter``."""
        q = (self._tf - self._tcap) * self.config.sigma_imu_mps**2 if self._has else 0.0
        return np.array([[self._p00 + q, self._p01], [self._p01, self._p11 + q]])

    @property
    def platform_velocity(self) -> FloatArray:
        """The platform velocity the prediction uses from now on (m/s, W), (3,)."""
        return np.array([self._u[4], self._u[5], 0.0])

    def _pad_at_filter_time(self) -> tuple[float, float]:
        pb = self._ego_position(self._tf)
        return pb[0] - self._x0, pb[1] - self._x1

    def state(self, t: float) -> PlatformEstimate:
        """The platform at ``t`` (s): at the filter's time from the ego position and the relative state,
        moved by the platform velocity to ``t``. Raises EstimationError before any measurement."""
        if not self._has:
            raise EstimationError("SduKalmanFilter.state: no measurement yet")
        t = check_time(t, "SduKalmanFilter.state")
        tau = t - self._tf
        px, py = self._pad_at_filter_time()
        mx, my = self._u[4], self._u[5]
        q = (self._tf - self._tcap + abs(tau)) * self.config.sigma_imu_mps**2
        cov = np.array(
            [[self._p00 + q, self._p01, 0.0], [self._p01, self._p11 + q, 0.0], [0.0, 0.0, self._var_z]]
        )
        if self.config.turn_model and self.turn_rate.rate != 0.0:
            pk, vk, ak, _ = turn_predict(
                np.array([px, py, self._z]), np.array([mx, my, 0.0]), self.turn_rate.rate, np.array([tau])
            )
            p_WP, v_WP, a_WP = pk[0], vk[0], ak[0]
            yaw = math.remainder(self.velocity_estimator.heading + self.turn_rate.rate * tau, 2.0 * math.pi)
        else:
            p_WP = np.array([px + mx * tau, py + my * tau, self._z])
            v_WP, a_WP = np.array([mx, my, 0.0]), np.zeros(3)
            yaw = self.velocity_estimator.heading
        return PlatformEstimate(
            t=t,
            p_WP=p_WP,
            v_WP=v_WP,
            a_WP=a_WP,
            yaw=yaw,
            cov_p_WP=cov,
            t_last_measurement=self._t_meas,
        )

    def predict_ahead(self, times: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Positions (k, 3) m, velocities (k, 3) m/s, accelerations (k, 3) m/s^2 and headings (k,) rad at
        the absolute ``times`` (k,) (s): from the filter's time along the platform's turn (``turn_model``),
        else at constant velocity (zero acceleration)."""
        ts = check_times(times, "SduKalmanFilter.predict_ahead")  # alight.estimation.guards
        if not self._has:
            raise EstimationError("SduKalmanFilter.predict_ahead: no measurement yet")
        px, py = self._pad_at_filter_time()
        mx, my = self._u[4], self._u[5]
        k = ts.shape[0]
        tau = ts - self._tf
        if self.config.turn_model and self.turn_rate.rate != 0.0:
            p, v, a, _ = turn_predict(
                np.array([px, py, self._z]), np.array([mx, my, 0.0]), self.turn_rate.rate, tau
            )
            yaw = self.velocity_estimator.heading + self.turn_rate.rate * tau
            return p, v, a, wrap_angle(yaw)
        p = np.empty((k, 3))
        p[:, 0] = px + mx * tau
        p[:, 1] = py + my * tau
        p[:, 2] = self._z
        v = np.zeros((k, 3))
        v[:, 0] = mx
        v[:, 1] = my
        return p, v, np.zeros((k, 3)), np.full(k, self.velocity_estimator.heading)


__all__ = ["SduKalmanFilter", "SduKfConfig"]
