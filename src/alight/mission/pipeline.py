"""The Pipeline: one object that wires the blocks of a preset together, in the order of the data flow

    image -> detection -> geolocation -> platform estimate -> mission -> plan -> control

plus the ego-state estimator fed by the IMU and the odometry. It never sees ground truth: whatever drives
it (the simulator's runner, a recorded flight, an autopilot bridge) calls the ``on_*`` methods with sensor
data stamped with their capture times, ``step`` at the planner's rate and ``command`` at the
controller's rate.
"""

from __future__ import annotations

import bisect
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, cast

import numpy as np
from numpy.typing import NDArray

from alight.control import TiltLimited
from alight.energy import QosEnergyModel
from alight.estimation import EgoFed, PixelMeasured, PositionResetting, TelemetryFusing
from alight.estimation.deck_platform import DeckMotionFusing, DeckPredicting
from alight.estimation.ego_ekf import EgoEkf
from alight.estimation.optical_flow import DeckFlow
from alight.mission.guidance import Guidance
from alight.mission.quiet_window import QuietWindowConfig, QuietWindowGate
from alight.mission.range_filter import RangeFilter
from alight.mission.state_machine import FailsafeEvent, Mission, MissionStatus
from alight.mission.touchdown_detector import TouchdownDetector, TouchdownState
from alight.perception import ComputeMetered, FrameGate, ModeAware, PixelGated, RangeAware, TiltAware
from alight.perception.geolocation import pad_centre_pixel
from alight.types import (
    PIPELINE_BLOCKS,
    Command,
    EgoState,
    FloatArray,
    Mode,
    Observation,
    PlatformEstimate,
    PlatformMeasurement,
    Reference,
    quat_to_rotmat,
)

if TYPE_CHECKING:  # the Protocols, for annotations only
    from alight.control import Controller
    from alight.estimation import PlatformEstimator
    from alight.perception import Detector, Geolocator

_ZERO3 = np.zeros(3)
MRU_VARIANCE_FLOOR = 1e-10
"""Added to a motion reference unit's covariance (rad^2, (m/s)^2: 0.0006 deg, 1e-5 m/s): a simulated MRU
without noise has a zero covariance, which no filter can fuse."""
FINAL_DESCENT_PHASES = ("descend", "done")
"""The final action's phases that descend to a touchdown: the land detector runs, and touching the ground
is the descent's end."""


@dataclass(frozen=True)
class PipelineSummary:
    """What the onboard software reports of a flight when it ends (``result.json``'s pipeline fields)."""

    time_touchdown_onboard_s: float | None
    """When the land detector decided the touchdown."""
    time_first_detection_s: float | None
    time_landing_start_s: float | None
    frames_processed: int
    """Frames the detector processed (its own count when it meters itself, else the frames handed it)."""
    energy_compute_J: float | None
    """The detector's compute energy under the preset's energy model (None without one)."""
    detections: int
    rejected_measurements: int
    go_arounds: int
    target_losses: int
    abort_reason: str | None
    failsafe_events: tuple[FailsafeEvent, ...]
    final_mode: Mode
    block_time_s: dict[str, float]
    """Wall time per block (s), :data:`BLOCKS`."""
    mode_history: tuple[tuple[float, Mode, str], ...]
    """(time, mode entered, why), in order."""


class EgoHistory:
    """The recent ego estimates, to look up the camera pose at an image's capture time.

    A ring of poses; the pose at time t is interpolated between the two samples around it (positions
    linearly, attitudes by normalised linear interpolation, which is within 1e-4 rad of slerp for the
    few-degree steps between samples)."""

    def __init__(self, capacity: int = 512) -> None:
        self.t = np.full(capacity, -np.inf)
        self.p = np.zeros((capacity, 3))
        self.q = np.zeros((capacity, 4))
        self.q[:, 3] = 1.0
        self.v = np.zeros((capacity, 3))
        self._all = np.arange(capacity)
        self._i = 0
        self._n = 0

    def add(self, t: float, p_WB: FloatArray, q_WB: FloatArray, v_WB: FloatArray | None = None) -> None:
        i = self._i
        self.t[i], self.p[i], self.q[i] = t, p_WB, q_WB
        if v_WB is not None:
            self.v[i] = v_WB
        self._i = (i + 1) % self.t.size
        self._n = min(self._n + 1, self.t.size)

    def state_at(self, t: float) -> CapturePose | None:
        """Position, attitude and velocity at time t (interpolated as :meth:`pose_at`), or None."""
        pose = self.pose_at(t)
        if pose is None:
            return None
        order = self._order()
        ts = self.t[order]
        v = np.array([np.interp(t, ts, self.v[order, k]) for k in range(3)])
        return CapturePose(pose[0], pose[1], v)

    def _order(self) -> NDArray[np.intp]:
        """Indices of the stored samples, oldest first: the ring is written in time order, so this is a
        rotation (an argsort here cost more than the interpolation)."""
        size = self.t.size
        order: NDArray[np.intp] = (
            (np.arange(self._i - self._n, self._i) % size) if self._n < size else np.roll(self._all, -self._i)
        )
        return order

    def pose_at(self, t: float) -> tuple[FloatArray, FloatArray] | None:
        """(p_WB, R_WB) at time t, or None when t is outside the stored span by more than 50 ms."""
        n = self._n
        if n == 0:
            return None
        # The ring's samples oldest first are slots (start + j) % size, j < n: bisect on them in place
        # (the first j with a time >= t, as np.searchsorted on the ordered times, without ordering them).
        size = self.t.size
        start = (self._i - n) % size
        ring_t = self.t
        k = bisect.bisect_left(range(n), t, key=lambda j: ring_t[(start + j) % size])
        if k == 0:
            if ring_t[start] - t > 0.05:
                return None
            return self.p[start].copy(), quat_to_rotmat(self.q[start])
        last = (start + n - 1) % size
        if k == n:
            if t - ring_t[last] > 0.05:
                return None
            return self.p[last].copy(), quat_to_rotmat(self.q[last])
        i0, i1 = (start + k - 1) % size, (start + k) % size
        s = (t - ring_t[i0]) / max(ring_t[i1] - ring_t[i0], 1e-9)
        p = (1 - s) * self.p[i0] + s * self.p[i1]
        q1 = self.q[i1] if np.dot(self.q[i0], self.q[i1]) >= 0 else -self.q[i1]
        q = (1 - s) * self.q[i0] + s * q1
        return p, quat_to_rotmat(q / np.linalg.norm(q))


@dataclass(frozen=True)
class CapturePose:
    """The ego state at an image's capture time, as estimators of image measurements need it."""

    p_WB: FloatArray
    R_WB: FloatArray
    v_WB: FloatArray


BLOCKS = PIPELINE_BLOCKS
"""The blocks whose wall time :class:`PipelineStats` accumulates, in data-flow order."""


@dataclass
class PipelineStats:
    """Counts the runner reports in ``result.json``."""

    frames: int = 0
    observations: int = 0
    measurements: int = 0
    rejected_measurements: int = 0
    telemetry_fixes: int = 0
    """Platform telemetry fixes received."""
    t_first_detection: float | None = None
    t_landing_start: float | None = None
    block_time_s: dict[str, float] = field(default_factory=lambda: dict.fromkeys(BLOCKS, 0.0))
    """Wall-clock time spent in each block (s), keyed by :data:`BLOCKS`: what each algorithm costs on
    this machine, for comparing blocks' compute alongside their accuracy."""

    def charge(self, block: str, t0: float) -> float:
        """Add the time since ``t0`` (a ``time.perf_counter()`` reading) to ``block``; returns now."""
        now = time.perf_counter()
        self.block_time_s[block] += now - t0
        return now


class Pipeline:
    """The onboard software of one preset."""

    def __init__(
        self,
        *,
        ego_estimator: EgoEkf,
        geolocator: Geolocator,
        platform_estimator: PlatformEstimator,
        mission: Mission,
        guidance: Guidance,
        controller: Controller,
        detector: Detector | None = None,
        touchdown_detector: TouchdownDetector | None = None,
        flow_origin_B: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> None:
        """``flow_origin_B``: where an optical-flow module sits in B (m), as PX4's ``EKF2_OF_POS_X/Y/Z``
        give it; the feet's velocity is the body's plus the lever arm's, w x r."""
        self.ego_estimator = ego_estimator
        # an estimator that restarts at a jumped odometry pose reports the jumps to hand on one frame
        self._resets_position = isinstance(ego_estimator, PositionResetting)
        self.deck_flow = DeckFlow(flow_origin_B)
        """The surface under the feet as the optical-flow module measures it (:meth:`on_flow`)."""
        self.detector = detector
        self.geolocator = geolocator
        self.platform_estimator = platform_estimator
        self.mission = mission
        self.guidance = guidance
        self.controller = controller
        # The onboard land detector decides the touchdown and stops the motors; nothing outside the
        # pipeline does (the simulator only models the contact).
        self.touchdown = touchdown_detector or TouchdownDetector(mission.config.touchdown)
        self.history = EgoHistory()
        # The context a block declares it takes (alight.perception / alight.estimation Protocols),
        # checked once here; the hot path calls what was bound, or nothing.
        # Estimators of the relative position (paper 004's filter) take the vehicle's own motion as input.
        pe = platform_estimator
        self._feed_ego = pe.set_ego if isinstance(pe, EgoFed) else None
        # Estimators with an image measurement model (paper 003's UKF) take the pixel itself, and
        # predict where the target will be for a detector that gates its candidates.
        self._update_pixel: Callable[[float, FloatArray, Any], bool] | None = None
        self._predict_pixel: Callable[[float, Any], tuple[FloatArray, float] | None] | None = None
        if isinstance(pe, PixelMeasured):
            self._update_pixel, self._predict_pixel = pe.update_pixel, pe.predict_pixel
        self._set_prediction = detector.set_prediction if isinstance(detector, PixelGated) else None
        self._set_mode = detector.set_mode if isinstance(detector, ModeAware) else None
        self._set_view_tilt = detector.set_view_tilt if isinstance(detector, TiltAware) else None
        self._set_range = detector.set_range if isinstance(detector, RangeAware) else None
        self._set_tilt_limit = controller.set_tilt_limit if isinstance(controller, TiltLimited) else None
        # ... and the per-frame and per-measurement ones (an isinstance on a runtime-checkable Protocol
        # walks the Protocol's attributes: tens of microseconds at the camera's rate)
        self._fuses_telemetry = isinstance(pe, TelemetryFusing)
        self._platform_clock = math.nan  # the last time given to the platform estimator's predict
        # a ship's deck (issue 37): the estimator fuses the vessel's motion broadcast, and the landing
        # meets the deck in a quiet window of its predicted motion (mission/quiet_window.py)
        self._fuses_deck_motion = isinstance(pe, DeckMotionFusing)
        if isinstance(pe, DeckPredicting):
            gate = QuietWindowGate(pe, QuietWindowConfig(), mission.config.land_speed_mps)
            mission.attach_quiet_window(gate)
        self._will_process: Callable[[float], bool] | None = (
            detector.will_process if isinstance(detector, FrameGate) else None
        )
        self._tilt_limit: float | None = None  # the tilt limit set on the controller now (rad)
        self.stats = PipelineStats()
        self.status = MissionStatus(Mode.IDLE, False, "", 0.0)
        self.ranges = RangeFilter()
        """The range finder's last readings (:meth:`on_range`); ``range_m``, ``range_low_m`` and
        ``range_raw_m`` are its ``high_m``, ``low_m`` and ``raw_m``."""
        self.range_m: float | None = None
        self.range_low_m: float | None = None
        self.range_raw_m: float | None = None
        self.last_reference: Reference | None = None
        self.last_measurement: PlatformMeasurement | None = None
        self._ego: EgoState | None = None
        self._odometry_resets: int | None = None  # the odometry's last reset_counter
        self._target: PlatformEstimate | None = None
        self._imu_t = np.empty(32)
        self._imu_f = np.empty((32, 3))
        self._imu_w = np.empty((32, 3))
        self._imu_n = 0

    # -- sensors ----------------------------------------------------------------------------------------
    def on_imu(self, t: float, f_B: FloatArray, w_B: FloatArray) -> None:
        """An IMU sample (specific force and rate in B). Samples are buffered and handed to the ego
        estimator in one call when the estimate is next needed (same arithmetic as one call each: at
        200 Hz the per-call overhead, not the filter, is what costs)."""
        self.touchdown.on_imu(t, f_B)
        if not self.ego_estimator.initialized:  # the first odometry message initialises the filter
            return
        i = self._imu_n
        self._imu_t[i] = t
        self._imu_f[i] = f_B
        self._imu_w[i] = w_B
        self._imu_n = i + 1
        self._ego = None
        if self._imu_n == self._imu_t.size:
            self._flush_imu()

    def _flush_imu(self) -> None:
        n, self._imu_n = self._imu_n, 0
        if n:
            t0 = time.perf_counter()
            self.ego_estimator.predict_imu_many(self._imu_t, self._imu_f, self._imu_w, n)
            self.stats.charge("ego_estimator", t0)

    def on_odometry(
        self,
        t: float,
        p_WB: FloatArray,
        q_WB: FloatArray,
        v_WB: FloatArray | None = None,
        reset_counter: int | None = None,
    ) -> None:
        """An odometry message. ``reset_counter`` (MAVLink ODOMETRY's): when it changes, the odometry's
        frame has jumped (a VIO re-localised) and an estimator that can (:class:`PositionResetting`)
        restarts at the new pose while :meth:`ego` keeps handing on the old, continuous frame. None: the
        source does not say (a jump is then an outlier to the ego estimator's gate)."""
        self._ego = None
        self._flush_imu()
        t0 = time.perf_counter()
        est = self.ego_estimator
        jumped = reset_counter is not None and self._odometry_resets not in (None, reset_counter)
        if reset_counter is not None:
            self._odometry_resets = reset_counter
        if not est.initialized:
            est.initialize(t, p_WB, _ZERO3 if v_WB is None else v_WB, q_WB)
        elif jumped and isinstance(est, PositionResetting):
            est.relocalize(t, p_WB, q_WB, v_WB)
        else:
            est.update_odometry(t, p_WB, q_WB, v_WB)
        self.stats.charge("ego_estimator", t0)

    def on_range(self, t: float, range_m: float | None) -> None:
        """A range-finder reading (m, from the landing-gear feet) as the sensor reports it: None or
        non-finite when invalid (ROS REP 117: ``-inf`` closer than the minimum range, ``+inf`` beyond
        the maximum).

        ``range_m`` is the largest of the last three valid readings (None unless all three are valid),
        robust to one noisy low reading, which the detector reads; ``range_low_m`` the smallest, which
        the mission's ground check reads; the land detector reads the raw reading ``range_raw_m``, whose
        ``-inf`` (too close) is evidence of the floor (:class:`~alight.mission.range_filter.RangeFilter`)."""
        f = self.ranges
        f.update(range_m)
        self.range_raw_m, self.range_m, self.range_low_m = f.raw_m, f.high_m, f.low_m

    def on_flow(self, t: float, flow_B_rad_s: FloatArray, distance_m: float) -> None:
        """An optical-flow sample at ``t``: the apparent angular rate of the surface under the module along
        x_B and y_B (rad/s, (2,), not compensated for the body's rotation: ``(-v_x / d + w_y, -v_y / d -
        w_x)``, :class:`alight.sim.sensors.FlowSample`) and the module's distance to it along -z_B (m).

        With the ego estimate and the platform estimate's vertical speed it gives the feet's horizontal
        velocity across the surface and the deck's own velocity under them (:class:`DeckFlow`), which the
        committed descent compares with the platform estimate."""
        target = self._target  # the mission step's estimate, at most a step old (a deck's vertical speed)
        self.deck_flow.update(
            t, flow_B_rad_s, distance_m, self.ego(), 0.0 if target is None else float(target.v_WP[2])
        )

    @property
    def flow_origin_B(self) -> tuple[float, float, float]:
        """Where the optical-flow module sits in B (m)."""
        return self.deck_flow.origin_B

    @property
    def deck_slip_W(self) -> FloatArray | None:
        """The feet's horizontal velocity relative to the surface under them (m/s, (2,) in W), from the
        last optical-flow sample; None before one (a vehicle without a module)."""
        return self.deck_flow.slip_W

    def deck_slip_mps(self, t: float) -> float | None:
        """The feet's horizontal speed across the surface under them (m/s) from an optical-flow sample of
        the last :data:`~alight.estimation.optical_flow.FLOW_MAX_AGE_S`; None without one."""
        return self.deck_flow.slip_mps(t)

    def on_telemetry(
        self, t_stamp: float, p_WP: FloatArray, v_WP: FloatArray, cov: FloatArray, now: float | None = None
    ) -> bool:
        """The platform's own GNSS fix, taken at ``t_stamp`` and arriving now (later): position (3,) m,
        velocity (3,) m/s in W, the receiver's covariance (3, 3) m^2. The platform estimator fuses it
        when it can (:class:`alight.estimation.TelemetryFusing`; the runner refuses telemetry for one that
        cannot); True when used. ``now``: the receiver's clock, for a caller whose :meth:`step` does not
        run at every moment (the MAVLink bridge holds, or waits for the arming, without stepping): the
        estimator's clock is brought to it first, so that a fresh fix is not taken for one from the
        future. The simulator's runner steps at the planner's rate and leaves it None."""
        if not self._fuses_telemetry:
            return False
        est = cast(TelemetryFusing, self.platform_estimator)  # checked once, in __init__
        self.stats.telemetry_fixes += 1
        t0 = time.perf_counter()
        if now is not None and not now <= self._platform_clock:  # also while it has none (NaN)
            self.platform_estimator.predict(now)
            self._platform_clock = now
        used = est.update_telemetry(t_stamp, p_WP, v_WP, cov)
        self.stats.charge("platform_estimator", t0)
        self._target = None
        return used

    def on_deck_motion(
        self,
        t_stamp: float,
        roll_pitch: FloatArray,
        cov_roll_pitch: FloatArray,
        heave_rate: float,
        heave_rate_var: float,
    ) -> bool:
        """The vessel's motion reference unit sample taken at ``t_stamp`` and arriving now: the deck's
        (roll, pitch) (2,) rad with covariance (2, 2), and the pad's heave rate (m/s) with its variance.
        The platform estimator fuses it when it can
        (:class:`alight.estimation.deck_platform.DeckMotionFusing`); True when used."""
        if not self._fuses_deck_motion:
            return False
        est = cast(DeckMotionFusing, self.platform_estimator)  # checked once, in __init__
        cov = np.zeros((3, 3))
        cov[:2, :2] = cov_roll_pitch
        cov[2, 2] = heave_rate_var
        cov += np.eye(3) * MRU_VARIANCE_FLOOR  # a noiseless simulated MRU: still a proper covariance
        t0 = time.perf_counter()
        used = est.update_deck_motion(t_stamp, roll_pitch, heave_rate, cov)
        self.stats.charge("platform_estimator", t0)
        self._target = None
        return used

    def on_image(
        self, t_capture: float, image: np.ndarray
    ) -> tuple[list[Observation], list[PlatformMeasurement]]:
        """Run the detector on an image taken at ``t_capture`` and use what it finds; returns the
        observations and the platform measurements made from them."""
        if self.detector is None:
            raise RuntimeError("this pipeline has no detector; feed observations with on_observations")
        self.stats.frames += 1
        if self._set_prediction is not None:
            self._set_prediction(*self._pixel_prediction(t_capture))
        if self._set_range is not None:
            self._set_range(self.range_m)
        t0 = time.perf_counter()
        observations = self.detector.detect(image, t_capture)
        self.stats.charge("detector", t0)
        return observations, self.on_observations(t_capture, observations)

    def will_process_image(self, t_capture: float) -> bool:
        """Whether :meth:`on_image` on the image captured at ``t_capture``, called next, has the detector
        read the image: False only for a :class:`~alight.perception.FrameGate` detector that will skip
        it (then any stand-in image does, and the image need not be made)."""
        return self._will_process is None or self._will_process(t_capture)

    def _pixel_prediction(self, t_capture: float) -> tuple[FloatArray | None, float | None]:
        if self._predict_pixel is None or not self.platform_estimator.has_measurement:
            return None, None
        ego = self.history.state_at(t_capture)
        pred = None if ego is None else self._predict_pixel(t_capture, ego)
        return (None, None) if pred is None else pred

    def on_observations(self, t_capture: float, observations: list[Observation]) -> list[PlatformMeasurement]:
        """Geolocate observations of an image taken at ``t_capture`` and update the platform estimate."""
        out: list[PlatformMeasurement] = []
        if not observations:
            return out
        pose = self.history.pose_at(t_capture)
        if pose is None:
            return out
        p_WB, R_WB = pose
        self.stats.observations += len(observations)
        best = max(observations, key=lambda o: o.quality)
        t0 = time.perf_counter()
        measurement = self.geolocator.locate(best, p_WB, R_WB)
        self.stats.charge("geolocator", t0)
        if measurement is None:
            return out
        self._target = None
        ego = self.ego() if self._feed_ego is not None else None
        t0 = time.perf_counter()
        if self._feed_ego is not None and ego is not None:
            self._feed_ego(ego)
        centre = pad_centre_pixel(best) if self._update_pixel is not None else None
        if self._update_pixel is not None and centre is not None:
            # The estimator fuses the pad centre's pixel through its own camera model; the geolocated
            # point above is what the pipeline reports (logs, detections) for the same image.
            used = self._update_pixel(t_capture, centre, self.history.state_at(t_capture))
        else:
            used = self.platform_estimator.update(measurement)
        self.stats.charge("platform_estimator", t0)
        if used:
            if self._fuses_telemetry:
                cast(TelemetryFusing, self.platform_estimator).learn_telemetry_bias(measurement)
            self.stats.measurements += 1
            if self.stats.t_first_detection is None:
                self.stats.t_first_detection = t_capture
            self.last_measurement = measurement
            out.append(measurement)
        else:
            self.stats.rejected_measurements += 1
        return out

    # -- decisions ----------------------------------------------------------------------------------------
    def ego(self) -> EgoState:
        # Several consumers ask between two sensor messages (mission, controller, log): build it once;
        # on_imu and on_odometry drop the cached state.
        if self._ego is None:
            self._flush_imu()
            t0 = time.perf_counter()
            ego = self.ego_estimator.state()
            # PositionResetting: the estimator restarted at a jumped odometry pose; hand on one continuous
            # frame, in which the platform estimate, the plan and the pose history stay where they were
            d = self.ego_estimator.reset_delta_p_WB if self._resets_position else None
            if d is not None and any(d.tolist()):  # numpy's any() costs a microsecond per call here
                ego = EgoState.trusted(ego.t, ego.p_WB - d, ego.v_WB, ego.q_WB, ego.w_WB_B, ego.a_WB)
            self._ego = ego
            self.stats.charge("ego_estimator", t0)
        return self._ego

    def target(self, t: float) -> PlatformEstimate | None:
        # Before the estimator has a heading and speed it still knows where the platform was seen: the
        # mission tracks that (a brief sighting at the edge of the image must not be thrown away).
        if not self.platform_estimator.has_measurement:
            return None
        if self._target is None or self._target.t != t:  # the mission and the log ask at the same t
            t0 = time.perf_counter()
            self._target = self.platform_estimator.state(t)
            self.stats.charge("platform_estimator", t0)
        return self._target

    def step(self, t: float) -> MissionStatus:
        """Run the mission logic and replan (at the planner's rate)."""
        # The platform estimator's clock: a measurement stamped later than this (plus its tolerance)
        # is from the future and is refused, instead of blocking every real one after it.
        self.platform_estimator.predict(t)
        self._platform_clock = t
        ego = self.ego()
        target = self.target(t)
        t0 = time.perf_counter()
        landed = self.touchdown.state is TouchdownState.LANDED
        self.status = self.mission.step(
            t,
            ego,
            target,
            self.range_low_m,
            touchdown=landed,
            deck_velocity_W=self.deck_flow.velocity_W_at(t),
        )
        self.stats.charge("mission", t0)
        if self.status.changed and self.status.mode is not Mode.LANDED and not self._detector_armed():
            self.touchdown.reset()  # a go-around or a new approach starts airborne
        if self.status.changed and self._set_mode is not None:
            self._set_mode(self.status.mode)  # a detector whose quality of service follows the phase
        if self._set_view_tilt is not None:  # ... and the obliquity of the view
            x, y = ego.q_WB[0], ego.q_WB[1]
            self._set_view_tilt(t, math.acos(min(max(1.0 - 2.0 * float(x * x + y * y), -1.0), 1.0)))
        if self.status.changed and self.status.mode is Mode.TAKEOFF:
            # Standing on the ground is a disturbance to an adaptive or integrating controller (the
            # ground holds the vehicle against a reference below it): start the flight from zero.
            self.controller.reset()
        if self.status.changed and self.status.mode is Mode.LAND and self.stats.t_landing_start is None:
            self.stats.t_landing_start = t
        hover_W = self.mission.hover_point_W()
        t0 = time.perf_counter()
        self.guidance.update(t, self.status.mode, ego, target, self.platform_estimator, hover_W, self.mission)
        self.stats.charge("guidance", t0)
        return self.status

    def command(self, t: float) -> Command:
        """The command to the low level (at the controller's rate)."""
        ego = self.ego()
        self.history.add(t, ego.p_WB, ego.q_WB, ego.v_WB)
        if self._feed_ego is not None:
            t0 = time.perf_counter()
            self._feed_ego(ego)
            self.stats.charge("platform_estimator", t0)
            self._target = None
        mode = self.status.mode
        if mode in (Mode.LANDED, Mode.IDLE) or self.touchdown.state is TouchdownState.LANDED:
            return Command(t, 0.0, _ZERO3, motors_off=True)
        target = self.target(t) if mode in (Mode.LAND, Mode.GO_AROUND, Mode.SEARCH) else None
        t0 = time.perf_counter()
        ref = self.guidance.reference(t, mode, target)
        t0 = self.stats.charge("guidance", t0)
        self.last_reference = ref
        if self._set_tilt_limit is not None:
            # the mission's limit near the ground (take-off, touchdown), set on the controller when it changes
            limit = self.mission.tilt_limit_rad(mode, ego, self.range_raw_m)
            if limit != self._tilt_limit:
                self._set_tilt_limit(limit)
                self._tilt_limit = limit
        cmd = self.controller.command(ego, ref)
        self.stats.charge("controller", t0)
        self.touchdown.observe_attitude(t, ego.q_WB)
        if self._detector_armed():
            # the land detector spools the thrust down on ground contact and stops the motors once landed
            cmd = self.touchdown.command(t, ego, target, self.range_raw_m, cmd)
        return cmd

    def _detector_armed(self) -> bool:
        """The land detector runs during a descent: the landing, and a final action's descent."""
        mode = self.status.mode
        return mode is Mode.LAND or (mode is Mode.ABORT and self.mission.abort_phase in FINAL_DESCENT_PHASES)

    # -- status for the driver ------------------------------------------------------------------------------
    @property
    def ego_initialized(self) -> bool:
        """The ego estimator has its first pose (from the first odometry message)."""
        return self.ego_estimator.initialized

    @property
    def fuses_telemetry(self) -> bool:
        """The platform estimator fuses the platform's own GNSS fixes (:meth:`on_telemetry`)."""
        return self._fuses_telemetry

    @property
    def final_action_lands(self) -> bool:
        """The mission's final action (after an abort) ends on the ground, not in a hover."""
        return self.mission.config.final_action != "hover"

    @property
    def in_final_descent(self) -> bool:
        """The final action is in its descent (or done): a touch of the ground is its end."""
        return self.mission.abort_phase in FINAL_DESCENT_PHASES

    @property
    def final_action_complete(self) -> bool:
        """The final action has completed (a hover held at its hold point, or its descent ended)."""
        return self.mission.final_action_complete

    def summary(self, energy_model: QosEnergyModel | None = None, duration_s: float = 0.0) -> PipelineSummary:
        """What the flight's pipeline reports (:class:`PipelineSummary`); ``energy_model``: the preset's
        compute-energy model, for a detector that meters itself, over ``duration_s`` (s)."""
        stats, mission, detector = self.stats, self.mission, self.detector
        metered = detector if isinstance(detector, ComputeMetered) else None
        return PipelineSummary(
            time_touchdown_onboard_s=self.touchdown.t_landed,
            time_first_detection_s=stats.t_first_detection,
            time_landing_start_s=stats.t_landing_start,
            frames_processed=stats.frames if metered is None else metered.frames_processed,
            energy_compute_J=(
                None
                if energy_model is None or metered is None
                else metered.energy_J(energy_model, duration_s=duration_s)
            ),
            detections=stats.measurements,
            rejected_measurements=stats.rejected_measurements,
            go_arounds=mission.go_arounds,
            target_losses=mission.target_losses,
            abort_reason=mission.abort_reason,
            failsafe_events=tuple(mission.events),
            final_mode=self.status.mode,
            block_time_s=dict(stats.block_time_s),
            mode_history=tuple(mission.history),
        )
