"""The simulated world of one mission, stepped one 200 Hz tick at a time.

One piece, used by everything that flies a scenario in simulation: ``run_mission`` (the pipeline in
the same process) and ``alight sitl`` (the pipeline behind MAVLink). It holds what a real vehicle
would not hand its pipeline: the truth of both vehicles, the contact with the deck and the ground and
its judging, the sensors' and the camera's models with their faults.

- Physics: the vehicle's rigid body, motors and the autopilot's 1 kHz body-rate loop in compiled
  batches (``sim.physics.tick_batch``) that end at the 100 Hz command ticks, where the command
  can change, or earlier where a first contact is to be judged or an IMU bias step is due. Wind and
  the deck's state are stamped at each batch's start.
- Contact: the feet on the moving deck and the ground are a spring-damper with friction inside the
  kernel; nothing here stops the motors. The first contact after take-off is judged from the truth
  (DESIGN.md's limits) when it happens, every touchdown after a lift-off again, and the rest
  ``contact.settle_s`` after the motors stopped (:meth:`World.set_command`).
- Sensors: the IMU sample of each tick; odometry, range finder, the platform's GNSS telemetry and the
  camera (rendered frames, or the ground-truth sensor's observations) on demand, each with its faults
  (``sim/faults.py``), delivered after their latencies.

Randomness: one ``SeedSequence`` from the scenario seed and one child per component
(:data:`SEED_CHILDREN`), so changing one component's settings does not change another's random
numbers; the faults draw from a child of their own, so a mission without faults flies exactly as
before they existed.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import typing
from collections import deque
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from alight.airframe import Airframe
from alight.cameras import CameraModel
from alight.cameras.pinhole import CameraMount, camera_pose_W
from alight.control.rate import RateControllerGains, pack_low_level_params
from alight.pads import PadDesign
from alight.scenario import Scenario
from alight.sim.faults import Faults, FrameFate, speed_profile
from alight.sim.physics import (
    IN_DECK,
    IN_F_EXT,
    IN_MOTORS_ON,
    IN_THRUST,
    IN_V_WIND,
    IN_W_CMD,
    N_IN,
    tick_batch,
)
from alight.sim.platform import PathKind, Platform, PlatformConfig, SpeedProfile
from alight.sim.quadrotor import (
    CP_K,
    DK_A,
    DK_HALF,
    DK_ON,
    DK_P,
    DK_V,
    DK_YAW,
    DK_YAW_RATE,
    N_DK,
    SL_P,
    SL_Q,
    SL_V,
    SL_W,
    initial_state,
    pack_contact_params,
    pack_params,
)
from alight.sim.render import Renderer, RenderOptions
from alight.sim.sea.world_deck import DeckPose, MruMessage, MruStream, SeaDeck, deck_extent
from alight.sim.sensors import (
    FlowSample,
    Imu,
    ImuConfig,
    Odometry,
    OdometryConfig,
    OpticalFlowConfig,
    OpticalFlowSensor,
    RangeFinder,
    RangeFinderConfig,
)
from alight.sim.telemetry import PlatformTelemetry, TelemetryFix
from alight.sim.textures import make_ground_texture
from alight.sim.touchdown import Contact, ContactLimits, judge_contact, judge_settled, judge_settled_on_deck
from alight.sim.truth_perception import TruthPerception, TruthPerceptionConfig
from alight.sim.wind import (
    TURBULENCE_W20_MPS,
    DrydenWind,
    GustWind,
    NoWind,
    SteadyWind,
    WindDirection,
    WindModel,
)
from alight.types import EgoState, FloatArray, Observation, Outcome, quat_to_rotmat

PHYSICS_DT = 0.001
TICK_DT = 0.005  # the IMU period; every other rate is a multiple of it
CONTROL_DT = 0.01  # the command ticks: a physics batch ends at each
WIND_DT = 0.01  # the wind is updated where the physics batches start: at the 100 Hz control ticks
LIFT_OFF_M = 0.005  # feet this far above the surface they touched, touching nothing: a lift-off (bounce)

SEED_CHILDREN = 13
"""Children of the scenario seed, by index: 0 platform placement, 1 rendering, 2 wind, 3 IMU,
4 odometry, 5 range finder, 6 ground-truth perception, 7 the pipeline's own draws, 8 faults,
9 platform telemetry, 10 optical flow, 11 the sea, 12 the vessel's motion telemetry (MRU).
``spawn(10)[:9]`` equals ``spawn(9)``: a component added at the end leaves every other component's random
numbers as they were."""
SEED_PIPELINE = 7


def mission_seeds(seed: int) -> list[np.random.SeedSequence]:
    """The children of a scenario's seed (:data:`SEED_CHILDREN`)."""
    return np.random.SeedSequence(seed).spawn(SEED_CHILDREN)


def call_every_platform_path() -> None:
    """Evaluate each platform path kind once (one time and many, with and without a speed profile), so
    that its kernels are compiled or loaded: which path a mission drives is its scenario's choice, and
    a warm-up flight (``alight.compile.warmup``) drives one."""
    ts = np.linspace(0.0, 2.0, 5)
    profile = SpeedProfile.brake_stop(1.0, t_s=0.5, decel_mps2=2.0, wait_s=0.5, accel_mps2=1.0)
    for path in typing.get_args(PathKind):
        for changes in (None, profile):
            config = PlatformConfig(path=path, speed_mps=1.0, speed_profile=changes)
            platform = Platform(config, np.random.default_rng(0))
            platform.state(0.5)
            platform.states(ts)


def place_platform(s: Scenario, rng: np.random.Generator) -> Platform:
    """The platform of the scenario, placed where the scenario says or drawn from ``rng``.

    Unless the scenario fixes them, the start point is drawn inside the search area (away from its edges)
    and the heading points toward the area's centre (+-30 deg): the platform drives through the area, as
    in the papers' experiments, instead of often leaving it before the coverage pattern gets there. A
    draw whose path passes within 4 m of the take-off point during the first 15 s is redrawn: an operator
    does not launch where the vehicle is about to drive over the drone.
    """
    spec, area = s.platform, s.search_area
    cx, cy = 0.5 * (area.x_min + area.x_max), 0.5 * (area.y_min + area.y_max)
    wx, wy = area.x_max - area.x_min, area.y_max - area.y_min
    platform = None
    for _ in range(200):
        if spec.start_xy is None:
            start = (
                float(rng.uniform(area.x_min + 0.2 * wx, area.x_max - 0.2 * wx)),
                float(rng.uniform(area.y_min + 0.2 * wy, area.y_max - 0.2 * wy)),
            )
        else:
            start = spec.start_xy
        if spec.heading_rad is None:
            heading = math.atan2(cy - start[1], cx - start[0]) + float(rng.uniform(-math.pi / 6, math.pi / 6))
        else:
            heading = spec.heading_rad
        config = PlatformConfig(
            path=spec.path,
            speed_mps=spec.speed_mps,
            pad_size_m=spec.pad_size_m,
            pad_height_m=spec.pad_height_m,
            start_xy_m=start,
            start_heading=heading,
            circle_radius_m=spec.circle_radius_m,
            figure8_length_m=spec.figure8_length_m,
            tractor_row_length_m=spec.tractor_row_length_m,
            tractor_turn_radius_m=spec.tractor_turn_radius_m,
            random_max_curvature=spec.random_max_curvature,
            speed_profile=speed_profile(spec.speed_profile, spec.speed_mps),
        )
        platform = Platform(config, np.random.default_rng(rng.integers(2**63)))
        if spec.start_xy is not None and spec.heading_rad is not None:
            break  # fully specified: the scenario's choice stands
        early = platform.states(np.linspace(0.0, 15.0, 151)).p_WP
        if np.min(np.hypot(early[:, 0], early[:, 1])) > 4.0:
            break
    if platform is None:  # the loop runs at least once; this is for the type checker
        raise RuntimeError("no platform placed")
    return platform


def make_wind(s: Scenario, rng: np.random.Generator, airframe: Airframe) -> WindModel:
    """The scenario's wind. The drag models push on the airframe's body drag area; paper 004's gust
    model is a force with its own power and stays as the paper writes it."""
    w = s.wind
    direction = WindDirection(w.direction_rate_rad_s, [(t, d) for t, d in w.direction_changes])
    area = airframe.body_drag_area_m2
    if w.model == "steady":
        return SteadyWind(np.array(w.velocity_mps, dtype=float), area_m2=area, direction=direction)
    if w.model == "dryden":
        return DrydenWind(
            rng,
            np.array(w.velocity_mps, dtype=float),
            TURBULENCE_W20_MPS[w.turbulence],
            dt=WIND_DT,
            min_airspeed_mps=w.turbulence_min_airspeed_mps,
            area_m2=area,
            direction=direction,
        )
    if w.model == "gust":
        return GustWind(rng, power_init_N=w.gust_power_N)
    return NoWind()


@dataclass(frozen=True)
class Shot:
    """A camera frame taken and not yet rendered: what it shows is fixed at its capture time."""

    p_WC: np.ndarray
    R_WC: np.ndarray
    p_WP: np.ndarray
    yaw: float
    w_WB_B: np.ndarray
    fate: FrameFate
    noise_offset: tuple[int, int] | None
    R_WP: np.ndarray | None = None
    """The deck's orientation on a vessel at sea (None: level, turned by ``yaw``)."""


Frame = Shot | list[Observation]
"""What the camera took: a :class:`Shot` for a camera preset, the ground-truth sensor's observations
otherwise."""

_NOTHING: tuple[()] = ()


class VehicleSetup(Protocol):
    """What the world simulates of the vehicle that flies in it, from the flying side's composition
    (``alight.mission.presets.Preset`` is one): the world needs it for the camera's images and the
    autopilot's rate loop, and nothing else of the pipeline."""

    @property
    def name(self) -> str: ...

    @property
    def mount(self) -> CameraMount:
        """The camera's pose on the body."""

    @property
    def rate_gains(self) -> RateControllerGains:
        """The autopilot's body-rate loop, which the physics runs at 1 kHz."""

    @property
    def uses_camera(self) -> bool:
        """Rendered camera frames (True) or the ground-truth sensor's observations."""

    @property
    def camera(self) -> CameraModel | None:
        """The camera model to render through (required when ``uses_camera``)."""

    @property
    def pad(self) -> PadDesign | None:
        """The pad drawn on the platform (required when ``uses_camera``)."""

    @property
    def color_camera(self) -> bool:
        """The camera delivers colour (BGR) images unless the scenario says otherwise."""


class World:
    """The world of ``scenario`` (module docstring), for the preset that will fly it.

    The caller commands it (:meth:`set_command`) and advances it (:meth:`step`); between steps it reads
    the sensors it wants (:meth:`odometry_message`, :meth:`range_m`, :meth:`telemetry_arrivals`,
    :meth:`capture` and :meth:`deliveries`). ``outcome`` is set when a step decides the mission's end.
    Two flags come from the flying side: ``ground_ok`` (a ground contact is the safe end of a failsafe's
    descent) and ``aborting`` (a safe settling then scores ``aborted``)."""

    def __init__(
        self,
        scenario: Scenario,
        airframe: Airframe,
        preset: VehicleSetup,
        seeds: list[np.random.SeedSequence],
    ) -> None:
        s = scenario
        self.scenario = s
        self.airframe = airframe
        self.mount = preset.mount
        rngs = [np.random.default_rng(c) for c in seeds[:7]]
        rng_place, rng_render, rng_wind, rng_imu, rng_odo, rng_range, rng_perc = rngs
        self.platform = place_platform(s, rng_place)
        self.wind = make_wind(s, rng_wind, airframe)
        self.windless = isinstance(self.wind, NoWind)
        self._init_sensors(rng_imu, rng_odo, rng_range)
        self._init_contact()
        self._init_perception(preset, rng_perc, seeds[8])
        self._init_platform_and_flow_sensors(seeds[9], seeds[10])
        self._init_camera(preset, rng_render)
        self._init_physics(preset, seeds)
        self._init_flight()

    def _init_sensors(
        self, rng_imu: np.random.Generator, rng_odo: np.random.Generator, rng_range: np.random.Generator
    ) -> None:
        self.imu = Imu(ImuConfig(), rng_imu)
        self.odometry = Odometry(OdometryConfig(), rng_odo)
        rf = self.scenario.rangefinder
        self.rangefinder = RangeFinder(
            RangeFinderConfig(
                origin_B=self.airframe.feet_B,
                min_range_m=rf.min_range_m,
                max_range_m=rf.max_range_m,
                noise_std_m=rf.noise_m,
            ),
            rng_range,
        )

    def _init_contact(self) -> None:
        c = self.scenario.contact
        self.contact_params = pack_contact_params(
            self.airframe,
            stiffness_N_per_m=c.stiffness_N_per_m,
            damping_Ns_per_m=c.damping_Ns_per_m,
            friction=c.friction,
            gear_half_width_m=c.gear_half_width_m,
        )
        self.limits = ContactLimits(
            gear_half_width=c.gear_half_width_m,
            max_vertical_speed_mps=c.max_vertical_speed_mps,
            max_horizontal_speed_mps=c.max_horizontal_speed_mps,
            max_tilt_deg=c.max_tilt_deg,
        )

    def _init_perception(
        self, preset: VehicleSetup, rng_perc: np.random.Generator, seed_faults: np.random.SeedSequence
    ) -> None:
        """The ground-truth perception sensor and the faults on the data's way into the pipeline."""
        s = self.scenario
        pc, rf = s.perception, s.rangefinder
        self.truth_perception = TruthPerception(
            TruthPerceptionConfig(
                rate_hz=pc.rate_hz,
                noise_m=pc.noise_m,
                latency_s=pc.latency_s,
                dropout_prob=min(1.0, pc.dropout_prob + s.faults.dropout_prob),
                blackouts=tuple(tuple(b) for b in s.faults.blackouts),  # type: ignore[misc]
                hfov_rad=math.radians(pc.fov_deg[0]),
                vfov_rad=math.radians(pc.fov_deg[1]),
                max_range_m=pc.max_range_m,
            ),
            preset.mount.R_BC,
            preset.mount.p_BC,
            rng_perc,
        )
        self.faults = Faults(
            s.faults,
            seed_faults,
            camera=preset.uses_camera,
            latency_s=pc.latency_s,
            extra_dropout_prob=pc.dropout_prob,
            range_span_m=(rf.min_range_m, rf.max_range_m),
            tick_dt=TICK_DT,
        )
        self.faults.check_preset(s.preset, preset.uses_camera)

    def _init_platform_and_flow_sensors(
        self, seed_telemetry: np.random.SeedSequence, seed_flow: np.random.SeedSequence
    ) -> None:
        """The platform's GNSS telemetry and the optical-flow module, when the scenario has them."""
        s = self.scenario
        self.telemetry: PlatformTelemetry | None = None
        if s.platform.telemetry is not None:
            tel = s.platform.telemetry
            self.telemetry = PlatformTelemetry(tel, np.random.default_rng(seed_telemetry))
        self._tel_pending: deque[TelemetryFix] = deque()
        self.optical_flow: OpticalFlowSensor | None = None
        self.flow_every_ticks = 0
        """Ticks between two optical-flow samples (0: no module)."""
        if s.optical_flow is not None:
            # the scenario's section holds the sensor's own fields and its mount (at the feet unless set),
            # which the pipeline is told as PX4's EKF2_OF_POS_* tell its EKF, to compensate the lever arm
            spec = s.optical_flow
            flow = OpticalFlowConfig(
                **spec.model_dump(exclude={"position_B_m"}),
                origin_B=self.airframe.downward_sensor_B(spec.position_B_m, "optical_flow.position_B_m"),
            )
            self.optical_flow = OpticalFlowSensor(flow, np.random.default_rng(seed_flow))
            self.flow_every_ticks = round(1.0 / (flow.rate_hz * TICK_DT))

    def _init_camera(self, preset: VehicleSetup, rng_render: np.random.Generator) -> None:
        """The renderer of a camera preset (None: the ground-truth sensor reports), and the capture clock."""
        s = self.scenario
        self.renderer: Renderer | None = None
        if preset.uses_camera:
            if preset.camera is None or preset.pad is None:  # a camera preset builds both (presets.py)
                raise RuntimeError(f"preset {preset.name} uses a camera but has no camera model or pad")
            cs = s.camera
            color = preset.color_camera if cs.color is None else cs.color
            distractors = cs.distractors
            ground = make_ground_texture(cs.ground, rng_render, color=color, distractors=distractors)
            self.renderer = Renderer(
                preset.camera,
                ground,
                preset.pad,
                self._sea_deck_texture(
                    RenderOptions(
                        noise_sigma_dn=cs.noise_dn,
                        exposure_time_s=cs.exposure_s,
                        exposure_gain=cs.exposure_gain,
                        gamma=cs.gamma,
                        color=color,
                        illumination_gain_bgr=cs.illumination_gain_bgr,
                        brightness_drift=cs.brightness_drift,
                        brightness_drift_period_s=cs.brightness_drift_period_s,
                    )
                ),
                rng_render,
                R_BC=preset.mount.R_BC,
            )
        self.perception_period_s = 1.0 / s.perception.rate_hz
        self.next_capture_s = 0.0
        self._pending: deque[tuple[float, float, Frame]] = deque()  # (delivery, capture time, frame)

    def _sea_deck_texture(self, options: RenderOptions) -> RenderOptions:
        """On a vessel at sea the camera sees the deck's extent around the pad (``deck_extent``), at a
        texture resolution that keeps its finest level within 4096 texels a side."""
        s = self.scenario
        if s.platform.sea is None:
            return options
        x0, x1, y0, y1 = deck_extent(s.platform.sea, 0.5 * s.platform.pad_size_m)
        length, width = x1 - x0, y1 - y0
        px = min(options.pad_px_per_m, 4096.0 / max(length, width))
        return dataclasses.replace(options, deck_length_m=length, deck_width_m=width, pad_px_per_m=px)

    def _init_physics(self, preset: VehicleSetup, seeds: list[np.random.SeedSequence]) -> None:
        """The compiled loop's parameters and inputs, the vehicle at rest, and the platform's path (on a
        vessel at sea with ``platform.sea``: the sea's and the motion telemetry's seeds are children 11
        and 12)."""
        s, airframe = self.scenario, self.airframe
        self.sim_params = pack_params(airframe)
        self.ll_params = pack_low_level_params(airframe, preset.rate_gains)
        gear = airframe.gear_height
        # standing on the ground, the feet compressed by the weight
        self.x: FloatArray = initial_state(
            np.array([0.0, 0.0, gear - airframe.weight_N / (4 * self.contact_params[CP_K])])
        )
        self.x_prev = self.x
        self.inputs = np.zeros(N_IN)  # what the compiled tick reads; updated in place when something changes
        self.inputs[IN_DECK + DK_ON] = 1.0
        self.inputs[IN_DECK + DK_HALF] = 0.5 * s.platform.pad_size_m
        self.n_sub = round(TICK_DT / PHYSICS_DT)
        self.every_control = round(CONTROL_DT / TICK_DT)
        self.n_ticks = int(round(s.duration_s / TICK_DT))
        # The platform's path does not depend on the flight: its states at every tick, computed at once.
        self.truths = self.platform.states(np.arange(self.n_ticks + 1, dtype=np.float64) * TICK_DT)
        self.sea: SeaDeck | None = None
        """The vessel's deck at sea (None: a ground vehicle on level ground)."""
        self.mru: MruStream | None = None
        sea = s.platform.sea
        if sea is not None:
            self.sea = SeaDeck(
                sea, np.random.default_rng(seeds[11]), s.platform.speed_mps, self.truths, TICK_DT,
                0.5 * s.platform.pad_size_m,
            )  # fmt: skip
            self.truths = self.sea.truths
            self._deck_rows = self.sea.deck_rows(0.5 * s.platform.pad_size_m)
            self._extent_P = np.array(self.sea.extent_P)
            if sea.motion_telemetry is not None:
                self.mru = MruStream(sea.motion_telemetry, np.random.default_rng(seeds[12]))
            return
        # ... and the deck inputs of a physics batch starting at each tick (layout DK_*), packed once:
        # one row copy per batch instead of five small slice assignments.
        tr = self.truths
        self._deck_rows = deck_rows = np.zeros(
            (self.n_ticks + 1, N_DK)
        )  # a level deck: DK_TILTED and after 0
        deck_rows[:, DK_ON] = 1.0
        deck_rows[:, DK_HALF] = 0.5 * s.platform.pad_size_m
        deck_rows[:, DK_P : DK_P + 3] = tr.p_WP
        deck_rows[:, DK_V : DK_V + 3] = tr.v_WP
        deck_rows[:, DK_A : DK_A + 3] = tr.a_WP
        deck_rows[:, DK_YAW] = tr.yaw
        deck_rows[:, DK_YAW_RATE] = tr.yaw_rate

    def _init_flight(self) -> None:
        """The clock, the contact's record and the verdict before the first tick."""
        s = self.scenario
        self.k = 0
        self.t = 0.0
        self.airborne = False
        self.motors_on = bool(self.inputs[IN_MOTORS_ON])  # what the physics reads: off until commanded
        self.contact: Contact | None = None  # the first contact after take-off, judged from the truth
        self.t_contact: float | None = None
        self.t_motors_off: float | None = None  # the motors stopped in the air or after touching down
        self.outcome: Outcome | None = None
        self.outcome_reason = ""
        self.ground_ok = False
        self.aborting = False
        self.touching = False  # a foot touches the deck or the ground (after take-off)
        self.touch_z = 0.0  # height of the surface it touches (m)
        self.touch_deck = False  # ... a vessel's deck at sea, which moves: its height is taken each tick
        self.bounces = 0
        self.on_deck = 0
        self.on_ground = 0
        # the lowest a foot can be below the body origin (tilted 25 deg with the feet 0.2 m out), plus 1 cm
        reach = self.airframe.gear_height + s.contact.gear_half_width_m * 0.5 + 0.01
        self.low_z = s.platform.pad_height_m + reach
        if self.sea is not None:
            self.low_z = max(self.sea.highest_point_m(), 0.0) + reach
        self.f_wind: FloatArray = np.zeros(3)
        self.last_range_m = math.inf  # the latest reading as the sensor reported it (faults applied)
        self._batch_xs = self._batch_imu = np.empty((0, 0))
        self._batch_touch: list[list[float]] = []  # feet on (deck, ground) after each tick of the batch
        self._batch_i = self._batch_n = 0

    # -- stepping ----------------------------------------------------------------------------------------
    @property
    def done(self) -> bool:
        return self.outcome is not None or self.k >= self.n_ticks

    @property
    def final_outcome(self) -> Outcome:
        """The verdict: the judged one, or ``timeout`` (the motors never stopped, or the settling time
        ran past the end)."""
        return Outcome.TIMEOUT if self.outcome is None else self.outcome

    def set_command(self, thrust_N: float, w_cmd_B: FloatArray, motors_on: bool) -> None:
        """The collective thrust (N) and body-rate command (rad/s, B) from the next physics batch on;
        ``motors_on`` False stops the motors (the mission is judged ``contact.settle_s`` later)."""
        inputs = self.inputs
        inputs[IN_THRUST] = thrust_N
        inputs[IN_W_CMD : IN_W_CMD + 3] = w_cmd_B
        inputs[IN_MOTORS_ON] = 1.0 if motors_on else 0.0
        self.motors_on = motors_on
        if self.airborne and not motors_on and self.t_motors_off is None:
            self.t_motors_off = self.t  # judge once the vehicle has settled

    def verdict(self) -> dict[str, Any]:
        """The judged part of a mission's result (``evaluation/result.py`` documents each column): the
        outcome and why, the first contact's error, speeds and tilt, when it touched and when the motors
        stopped, the bounces."""
        c, outcome = self.contact, self.final_outcome
        return {
            "outcome": outcome.value,
            "success": outcome is Outcome.LANDED,
            "touchdown_error_m": None if c is None else c.touchdown_error_m,
            "touchdown_rel_speed_mps": None if c is None else c.rel_speed_mps,
            "touchdown_rel_vertical_speed_mps": None if c is None else c.rel_vertical_speed_mps,
            "touchdown_rel_horizontal_speed_mps": None if c is None else c.rel_horizontal_speed_mps,
            "touchdown_tilt_deg": None if c is None else math.degrees(c.tilt_rad),
            "touchdown_platform_speed_mps": None if c is None else c.platform_speed_mps,
            "touchdown_platform_turn_rate_rad_s": None if c is None else c.platform_turn_rate_rad_s,
            "contact_surface": None if c is None else c.surface,
            "contact_reason": None if c is None else c.reason,
            "outcome_reason": self.outcome_reason,
            "time_first_contact_s": self.t_contact,
            "time_motors_off_s": self.t_motors_off,
            "bounces": self.bounces,
            "time_to_land_s": self.t_contact if outcome is Outcome.LANDED else None,
            **({} if self.sea is None else self._deck_verdict()),
        }

    def _deck_verdict(self) -> dict[str, Any]:
        """On a vessel at sea: the first contact in the deck's frame (``evaluation/result.py``)."""
        fig = None if self.contact is None else self.contact.deck

        def deg(a: float | None) -> float | None:
            return None if a is None else math.degrees(a)

        return {
            "deck_touchdown_error_m": None if fig is None else fig.touchdown_error_m,
            "deck_normal_speed_mps": None if fig is None else fig.normal_speed_mps,
            "deck_tangential_speed_mps": None if fig is None else fig.tangential_speed_mps,
            "deck_relative_tilt_deg": None if fig is None else deg(fig.relative_tilt_rad),
            "deck_tilt_deg": None if fig is None else deg(fig.deck_tilt_rad),
        }

    def end(self, outcome: Outcome, reason: str = "") -> None:
        """Decide the mission's end from the flying side (an abort's hover that held)."""
        self.outcome, self.outcome_reason = outcome, reason

    def _physics_batch(self) -> None:
        # Up to the next command tick (the inputs are constant in between), cut short where a first
        # contact is to be judged or an IMU bias step is due; wind and deck stamped at the batch's start.
        x, inputs, k = self.x, self.inputs, self.k
        if not self.windless:
            self.f_wind = self.wind.force_W(self.t, x[SL_P], x[SL_V])
            inputs[IN_F_EXT : IN_F_EXT + 3] = self.f_wind
            inputs[IN_V_WIND : IN_V_WIND + 3] = self.wind.air_velocity_W(self.t)
        # the deck at the batch's start; the kernel carries it forward with its acceleration and turn
        inputs[IN_DECK : IN_DECK + N_DK] = self._deck_rows[k]
        m = min(self.every_control - k % self.every_control, self.n_ticks - k)
        m = self.faults.before_imu_batch(
            k + 1, m, self.imu
        )  # a bias step due now; a batch ends before the next
        bias, noise, scale = self.imu.kernel_inputs_many(m)
        gear = self.airframe.gear_height
        self._batch_xs, self._batch_imu, touch, self._batch_n = tick_batch(
            x, inputs, self.sim_params, self.ll_params, bias, noise, scale, PHYSICS_DT, self.n_sub,
            self.contact_params, m, self.low_z if self.airborne and self.contact is None else -math.inf,
            math.inf if self.airborne else gear + 0.05,
        )  # fmt: skip
        self.imu.used(self._batch_n)
        self._batch_i = 0
        # read per tick as (deck, ground) pairs of Python floats: cheaper than numpy scalars
        self._batch_touch = touch.tolist()

    def step(self) -> FloatArray:
        """Advance one tick; returns the IMU sample at the new time (specific force (m/s^2) and body rate
        (rad/s), FLU, (6,)). Judges the contact and sets ``outcome`` when the mission's end is decided."""
        if self._batch_i >= self._batch_n:
            self._physics_batch()
        i = self._batch_i
        self.x_prev = self.x
        self.x = x = self._batch_xs[i]
        sample: FloatArray = self._batch_imu[i]
        deck_ground = self._batch_touch[i]
        self.on_deck = on_deck = int(deck_ground[0])
        self.on_ground = on_ground = int(deck_ground[1])
        self._batch_i += 1
        self.k = k = self.k + 1
        self.t = t = k * TICK_DT
        if not self.airborne and x[2] - self.airframe.gear_height > 0.05:  # x[2]: the height of p_WB
            self.airborne = True
        if self.airborne and (on_deck or on_ground or self.touching):
            self._judge_contact(on_deck, on_ground)
            if self.outcome is not None:
                return sample
        if self.t_motors_off is not None and t - self.t_motors_off >= self.scenario.contact.settle_s:
            if self.sea is None:
                settled, self.outcome_reason = judge_settled(
                    x[SL_P], quat_to_rotmat(x[SL_Q]), self.truths.at(k), self.scenario.platform.pad_size_m,
                    self.limits, on_deck, on_ground, ground_ok=self.ground_ok,
                )  # fmt: skip
            else:
                settled, self.outcome_reason = judge_settled_on_deck(
                    x[SL_P], quat_to_rotmat(x[SL_Q]), self.sea.pose(k), self.scenario.platform.pad_size_m,
                    self.limits, on_deck, on_ground, ground_ok=self.ground_ok,
                )  # fmt: skip
            if settled is Outcome.CRASHED:
                self.outcome = Outcome.CRASHED
            else:
                self.outcome = Outcome.ABORTED if self.aborting else Outcome.LANDED
        return sample

    def _judge_contact(self, on_deck: int, on_ground: int) -> None:
        # From the truth: the first contact is judged (DESIGN.md's limits, on the approach: speeds and tilt
        # of the tick before the feet touched, before the contact force acted); every later touchdown
        # after a lift-off is judged again; the ground is a crash except at the end of a failsafe's descent.
        x, k = self.x, self.k
        p_WB = x[SL_P]
        gear = self.airframe.gear_height
        if on_deck or on_ground:
            surface = "ground" if on_ground and not on_deck else "pad"
            if not self.touching:
                truth = self.truths.at(k)
                self.touching = True
                self.touch_z = 0.0 if surface == "ground" else float(truth.p_WP[2])
                self.touch_deck = surface == "pad" and self.sea is not None
                judged = judge_contact(
                    p_WB, self.x_prev[SL_V], quat_to_rotmat(self.x_prev[SL_Q]), truth,
                    self.scenario.platform.pad_size_m, gear, self.limits, surface=surface,
                    ground_ok=self.ground_ok, deck=None if self.sea is None else self.sea.pose(k),
                )  # fmt: skip
                if judged is not None:
                    if self.contact is None:
                        self.contact, self.t_contact = judged, self.t
                    if judged.outcome is Outcome.CRASHED:
                        self.outcome, self.outcome_reason = Outcome.CRASHED, judged.reason
                        if self.contact is not judged:
                            self.outcome_reason = f"after a bounce: {judged.reason}"
            elif on_ground and not self.ground_ok:
                self.outcome, self.outcome_reason = Outcome.CRASHED, "ground"  # slid or tipped off the deck
        elif p_WB[2] - gear - self._touched_z(k, p_WB) > LIFT_OFF_M:
            self.touching = False
            self.bounces += 1

    def _touched_z(self, k: int, p_WB: FloatArray) -> float:
        # the height of the surface the feet touched: a deck at sea heaves, so its plane's height under
        # the vehicle now
        if self.touch_deck and self.sea is not None:
            return self.sea.surface_z(k, p_WB)
        return self.touch_z

    # -- sensors -----------------------------------------------------------------------------------------
    def odometry_message(self) -> EgoState | None:
        """The odometry model's message now, as delivered (odometry faults applied; None: withheld)."""
        x = self.x
        return self.faults.odometry(self.odometry.measure(self.t, x[SL_P], x[SL_V], x[SL_Q], x[SL_W]))

    def range_m(self) -> float:
        """A range-finder reading now, as the sensor reports it (``-inf`` in its blind zone, ``+inf``
        beyond its range or without a return, REP 117; range faults applied). Draws from the sensor's
        noise."""
        k = self.k
        if self.sea is not None:
            r = self.rangefinder.measure_on_deck(
                self.x[SL_P], self.x[SL_Q], self.truths.p_WP[k], self.sea.pad.R_WP[k], self._extent_P
            )
        else:
            r = self.rangefinder.measure_at(
                self.x[SL_P], self.x[SL_Q], self.truths.p_WP[k], float(self.truths.yaw[k]),
                self.scenario.platform.pad_size_m,
            )  # fmt: skip
        self.last_range_m = self.faults.range(self.t, r)
        return self.last_range_m

    def flow_sample(self) -> FlowSample | None:
        """An optical-flow sample now (None: no module, the surface out of its range, or a flow fault
        dropped it). Draws from the module's noise (and the fault's stream) either way."""
        if self.optical_flow is None:
            return None
        k, x, tr = self.k, self.x, self.truths
        if self.sea is not None:
            deck = (tr.p_WP[k], tr.v_WP[k], self.sea.pad.R_WP[k], self.sea.pad.w_WP_W[k], self._extent_P)
            on_deck = self.optical_flow.measure_on_deck(self.t, (x[SL_P], x[SL_V], x[SL_Q], x[SL_W]), deck)
            return on_deck if self.faults.flow_delivered(self.t) else None
        sample = self.optical_flow.measure_at(
            self.t,
            (x[SL_P], x[SL_V], x[SL_Q], x[SL_W]),
            (tr.p_WP[k], tr.v_WP[k], float(tr.yaw[k]), float(tr.yaw_rate[k])),
            self.scenario.platform.pad_size_m,
        )
        return sample if self.faults.flow_delivered(self.t) else None

    def motion_telemetry_arrivals(self) -> tuple[MruMessage, ...]:
        """The vessel's MRU messages that reach the aircraft now (``platform.sea.motion_telemetry``; none
        without it): the deck's roll and pitch and the pad's heave rate, sampled from the truth at the
        MRU's rate, delivered after its latency, with its noise."""
        if self.mru is None or self.sea is None:
            return ()
        k = self.k
        return self.mru.arrivals(self.t, self.sea.pad.R_WP[k], float(self.truths.v_WP[k][2]))

    def deck_pose(self) -> DeckPose | None:
        """The deck of a vessel at sea now (ground truth, for the judge and the logs; None on land)."""
        return None if self.sea is None else self.sea.pose(self.k)

    def telemetry_arrivals(self) -> tuple[TelemetryFix, ...]:
        """The platform's GNSS fixes that reach the aircraft now (stamped with the time of the fix): a fix
        is taken from the truth at the receiver's rate and arrives after the link's latency."""
        tel = self.telemetry
        if tel is None:
            return _NOTHING
        t, k = self.t, self.k
        if t + 1e-9 >= tel.next_fix_s:
            fix = tel.fix(t, self.truths.p_WP[k], self.truths.v_WP[k])
            if fix is not None:
                self._tel_pending.append(fix)
        pending = self._tel_pending
        if not pending or pending[0].t_arrival > t + 1e-9:
            return _NOTHING
        arrived = []
        while pending and pending[0].t_arrival <= t + 1e-9:
            arrived.append(pending.popleft())
        return tuple(arrived)

    def capture(self) -> None:
        """Take a camera frame (or the ground-truth sensor's report) now if one is due at the
        perception rate. What it shows is fixed now; it reaches the pipeline after the processing
        latency (:meth:`deliveries`). For a camera, only the frame's fate (lost, dark, corrupted) and its
        sensor noise are drawn now, in capture order: it is rendered only when delivered and used
        (:meth:`develop`)."""
        t, k = self.t, self.k
        if t + 1e-9 < self.next_capture_s:
            return
        x = self.x
        p_WB = x[SL_P]
        R_WB = quat_to_rotmat(x[SL_Q])
        p_WP = self.truths.p_WP[k]
        faults = self.faults
        if self.renderer is not None:
            p_WC, R_WC = camera_pose_W(p_WB, R_WB, self.mount)
            fate = faults.fate(t)
            shot = Shot(p_WC, R_WC, p_WP, float(self.truths.yaw[k]), x[SL_W].copy(), fate,
                        self.renderer.draw_noise_offset(),
                        None if self.sea is None else self.sea.pad.R_WP[k])  # fmt: skip
            if not fate.dropped:
                self._pending.append((faults.delivery_time(t), t, shot))
        else:
            obs = faults.frame(t, self.truth_perception.observe(t, p_WB, R_WB, p_WP))
            if obs is not None:
                self._pending.append((faults.delivery_time(t), t, obs))  # type: ignore[arg-type]
        self.next_capture_s += self.perception_period_s

    def deliveries(self) -> list[tuple[float, Frame]]:
        """The frames that reach the pipeline now, in capture order: (capture time (s), frame)."""
        pending, t = self._pending, self.t
        if not pending or pending[0][0] > t + 1e-9:
            return []
        out = []
        while pending and pending[0][0] <= t + 1e-9:
            _, t_cap, frame = pending.popleft()
            out.append((t_cap, frame))
        return out

    def develop(self, shot: Shot, t_cap: float, *, used: bool) -> np.ndarray:
        """The image of a delivered camera frame as the pipeline gets it. Rendered (and passed through
        the faults) only when ``used`` (the detector will read it, or someone looks at every frame): a
        dark frame is black without rendering, and an unused frame gets a blank stand-in."""
        renderer = self.renderer
        assert renderer is not None, "develop() is for camera frames"
        if shot.fate.dark:
            dark = self.faults.deliver(shot.fate, np.zeros(renderer.frame_shape, np.uint8))
            assert dark is not None
            return dark
        if not used:
            return np.zeros(renderer.frame_shape, np.uint8)
        img = renderer.render(
            shot.p_WC,
            shot.R_WC,
            (shot.p_WP, shot.yaw),
            shot.w_WB_B,
            t_s=t_cap,
            noise_offset=shot.noise_offset,
            R_WP=shot.R_WP,
        )
        out = self.faults.deliver(shot.fate, img)
        assert out is not None
        return out

    # -- before the clock starts ----------------------------------------------------------------------
    def warm_up(self) -> None:
        """Compile (or load from numba's cache) the kernels the first ticks, range readings and frames
        call, without drawing a random number or changing any state (the IMU's noise rows are only
        peeked, the range finder and the renderer are copies)."""
        bias, noise, scale = self.imu.kernel_inputs_many(self.every_control)
        tick_batch(
            self.x.copy(), self.inputs.copy(), self.sim_params, self.ll_params, bias.copy(), noise.copy(),
            scale.copy(), PHYSICS_DT, self.n_sub, self.contact_params, self.every_control,
            -math.inf, math.inf,
        )  # fmt: skip
        copy.deepcopy(self.rangefinder).measure_at(
            self.x[SL_P], self.x[SL_Q], self.truths.p_WP[0], float(self.truths.yaw[0]),
            self.scenario.platform.pad_size_m,
        )  # fmt: skip
        if self.renderer is not None:
            p_WC, R_WC = camera_pose_W(self.x[SL_P], quat_to_rotmat(self.x[SL_Q]), self.mount)
            pose = (self.truths.p_WP[0], float(self.truths.yaw[0]))
            copy.deepcopy(self.renderer).render(p_WC, R_WC, pose, self.x[SL_W], t_s=0.0)
