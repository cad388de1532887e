"""The runner: steps the simulated world and a preset's pipeline together, and judges the outcome.

Rates (simulated clock): dynamics and the body-rate loop at 1 kHz (fused, ``physics.advance``), IMU at
200 Hz (the base tick), odometry at 40 Hz, range finder at 100 Hz, controller at 100 Hz, mission and
planner at the planner's rate (50 Hz), perception at the scenario's rate with its latency, log at 50 Hz.

The runner is the only place that sees both the truth and the pipeline. Randomness: one
``SeedSequence`` from the scenario seed, one child per component, so changing one component's
settings does not change another's random numbers. Sensor and perception faults (``sim/faults.py``,
``docs/faults.md``) act on the sensor data on their way into the pipeline and draw from a child of
their own, so a mission without faults flies exactly as before they existed.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

import alight
from alight.airframe import Airframe
from alight.airframes import load_airframe
from alight.cameras.pinhole import camera_pose_W
from alight.control.rate import pack_low_level_params
from alight.energy import flight_energy_J
from alight.errors import ConfigError
from alight.estimation import TelemetryFusing
from alight.evaluation.log import MissionLog
from alight.evaluation.physics import (
    IN_DECK,
    IN_F_EXT,
    IN_MOTORS_ON,
    IN_THRUST,
    IN_V_WIND,
    IN_W_CMD,
    N_IN,
    tick_batch,
)
from alight.mission.pipeline import Pipeline
from alight.mission.presets import build_preset
from alight.scenario import Scenario
from alight.sim.faults import Faults, FrameFate, speed_profile
from alight.sim.platform import Platform, PlatformConfig
from alight.sim.quadrotor import (
    CP_K,
    DK_A,
    DK_HALF,
    DK_ON,
    DK_P,
    DK_V,
    DK_YAW,
    DK_YAW_RATE,
    IX_F,
    SL_P,
    SL_Q,
    SL_V,
    SL_W,
    initial_state,
    pack_contact_params,
    pack_params,
)
from alight.sim.render import Renderer, RenderOptions
from alight.sim.sensors import Imu, ImuConfig, Odometry, OdometryConfig, RangeFinder, RangeFinderConfig
from alight.sim.telemetry import PlatformTelemetry, TelemetryConfig, TelemetryFix
from alight.sim.textures import DistractorSpec, make_ground_texture
from alight.sim.touchdown import Contact, ContactLimits, judge_contact, judge_settled
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
from alight.types import Mode, Observation, Outcome, quat_to_rotmat

PHYSICS_DT = 0.001
TICK_DT = 0.005  # the IMU period; every other rate is a multiple of it
WIND_DT = 0.01  # the wind is updated where the physics batches start: at the 100 Hz control ticks
_LANDING_PHASES = ("descend", "done")  # the final action's phases where touching the ground is its end
LIFT_OFF_M = 0.005  # feet this far above the surface they touched, touching nothing: a lift-off (bounce)
FALSE_LOCK_S = 1.0  # tracking or landing on an estimate > 2 pad sizes from the pad this long: a false lock


@dataclass
class MissionRun:
    """What one mission produced."""

    result: dict[str, Any]
    log: dict[str, np.ndarray] | None
    events: dict[str, float | None]
    contact: Contact | None = None
    mode_history: list[tuple[float, str, str]] = field(default_factory=list)


def _place_platform(s: Scenario, rng: np.random.Generator) -> Platform:
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


def _wind(s: Scenario, rng: np.random.Generator, airframe: Airframe) -> WindModel:
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


FrameSink = Callable[[float, np.ndarray, list[Observation]], None]
"""Receives each camera frame a vision preset processed: capture time (s), the image, the detections."""


@dataclass(frozen=True)
class _Shot:
    """A camera frame taken and not yet rendered: what it shows is fixed at its capture time."""

    p_WC: np.ndarray
    R_WC: np.ndarray
    p_WP: np.ndarray
    yaw: float
    w_WB_B: np.ndarray
    fate: FrameFate
    noise_offset: tuple[int, int] | None


def _develop(
    shot: _Shot, t_cap: float, renderer: Renderer, faults: Faults, pipeline: Pipeline, render_all: bool
) -> np.ndarray:
    """The image of a delivered camera frame as the pipeline gets it. Rendered (and passed through the
    faults) only when the detector will read it: a dark frame is black without rendering, and a frame the
    detector will skip (its QoS rate) gets a blank stand-in it never reads. ``render_all``: render every
    delivered frame (a frame sink looks at them; a frozen-frame fault may deliver one again later)."""
    if shot.fate.dark:
        dark = faults.deliver(shot.fate, np.zeros(renderer.frame_shape, np.uint8))
        assert dark is not None
        return dark
    if not render_all and not pipeline.will_process_image(t_cap):
        return np.zeros(renderer.frame_shape, np.uint8)
    img = renderer.render(
        shot.p_WC, shot.R_WC, (shot.p_WP, shot.yaw), shot.w_WB_B, t_s=t_cap, noise_offset=shot.noise_offset
    )
    out = faults.deliver(shot.fate, img)
    assert out is not None
    return out


def run_mission(
    scenario: Scenario,
    *,
    airframe: Airframe | None = None,
    record: bool = True,
    frame_sink: FrameSink | None = None,
    render_every_frame: bool = False,
) -> MissionRun:
    """Fly one mission of ``scenario`` and return its result (and log when ``record``). ``airframe``
    overrides the scenario's ``airframe:``; the simulator, the wind's drag and the preset's controller
    and planner all read this one. ``frame_sink`` sees every camera frame with its detections (for
    replays); it must not modify them.

    Camera frames are rendered only when the pipeline will look at them: not when lost, not when dark
    (a blackout), not when the detector skips them (:class:`~alight.perception.FrameGate`); the mission
    is the same as with every frame rendered (``render_every_frame``, for tests and measurements)."""
    wall0 = time.perf_counter()
    s = scenario
    if airframe is None:
        airframe = load_airframe(s.airframe)
    # Children by index: spawn(10)[:9] are the same as spawn(9)'s, so adding a component (the tenth
    # child, telemetry) leaves every other component's random numbers as they were.
    seeds = np.random.SeedSequence(s.seed).spawn(10)
    rngs = [np.random.default_rng(c) for c in seeds[:8]]
    rng_place, rng_render, rng_wind, rng_imu, rng_odo, rng_range, rng_perc, rng_pipe = rngs

    platform = _place_platform(s, rng_place)
    wind = _wind(s, rng_wind, airframe)
    imu = Imu(ImuConfig(), rng_imu)
    odometry = Odometry(OdometryConfig(), rng_odo)
    rf = s.rangefinder
    rangefinder = RangeFinder(
        RangeFinderConfig(
            origin_B=(0.0, 0.0, -airframe.gear_height),
            min_range_m=rf.min_range_m,
            max_range_m=rf.max_range_m,
            noise_std_m=rf.noise_m,
        ),
        rng_range,
    )
    contact_params = pack_contact_params(
        airframe,
        stiffness_N_per_m=s.contact.stiffness_N_per_m,
        damping_Ns_per_m=s.contact.damping_Ns_per_m,
        friction=s.contact.friction,
        gear_half_width_m=s.contact.gear_half_width_m,
    )
    limits = ContactLimits(
        gear_half_width=s.contact.gear_half_width_m,
        max_vertical_speed_mps=s.contact.max_vertical_speed_mps,
        max_horizontal_speed_mps=s.contact.max_horizontal_speed_mps,
        max_tilt_deg=s.contact.max_tilt_deg,
    )
    preset = build_preset(s, airframe, rng_pipe)
    pipeline = preset.pipeline
    pc = s.perception
    truth_perception = TruthPerception(
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
    # The ninth child of the seed: faults never change the random numbers of the components above.
    faults = Faults(
        s.faults,
        seeds[8],
        camera=preset.uses_camera,
        latency_s=pc.latency_s,
        extra_dropout_prob=pc.dropout_prob,
        range_span_m=(rangefinder.config.min_range_m, rangefinder.config.max_range_m),
        tick_dt=TICK_DT,
    )
    faults.check_preset(s.preset, preset.uses_camera)
    telemetry = None
    if s.platform.telemetry is not None:
        if not isinstance(pipeline.platform_estimator, TelemetryFusing):
            raise ConfigError(
                f"platform.telemetry: preset {s.preset}'s platform estimator "
                f"({type(pipeline.platform_estimator).__name__}) cannot fuse telemetry"
            )
        tel = TelemetryConfig(**s.platform.telemetry.model_dump())
        telemetry = PlatformTelemetry(tel, np.random.default_rng(seeds[9]))
    tel_pending: deque[TelemetryFix] = deque()

    renderer = None
    if preset.uses_camera:
        cs = s.camera
        color = preset.color_camera if cs.color is None else cs.color
        distractors = None
        if cs.distractors is not None:
            distractors = DistractorSpec(**cs.distractors.model_dump())
        ground = make_ground_texture(cs.ground, rng_render, color=color, distractors=distractors)
        if preset.camera is None or preset.pad is None:  # a camera preset builds both (presets.py)
            raise RuntimeError(f"preset {preset.name} uses a camera but has no camera model or pad")
        renderer = Renderer(
            preset.camera,
            ground,
            preset.pad,
            RenderOptions(
                noise_sigma_dn=cs.noise_dn,
                exposure_time_s=cs.exposure_s,
                exposure_gain=cs.exposure_gain,
                gamma=cs.gamma,
                color=color,
                illumination_gain_bgr=cs.illumination_gain_bgr,
                brightness_drift=cs.brightness_drift,
                brightness_drift_period_s=cs.brightness_drift_period_s,
            ),
            rng_render,
            R_BC=preset.mount.R_BC,
        )

    sim_params = pack_params(airframe)
    ll_params = pack_low_level_params(airframe, preset.rate_gains)
    # standing on the ground, the feet compressed by the weight
    x = initial_state(
        np.array([0.0, 0.0, airframe.gear_height - airframe.weight_N / (4 * contact_params[CP_K])])
    )
    zero3 = np.zeros(3)

    n_sub = round(TICK_DT / PHYSICS_DT)
    every_odometry = round(1.0 / (40.0 * TICK_DT))
    every_range = round(1.0 / (100.0 * TICK_DT))
    every_control = round(1.0 / (100.0 * TICK_DT))
    every_mission = max(1, round(1.0 / (preset.planner_rate_hz * TICK_DT)))
    every_log = round(1.0 / (50.0 * TICK_DT))
    perception_period = 1.0 / pc.rate_hz
    next_capture = 0.0
    pending: deque[tuple[float, float, object]] = deque()  # (delivery time, capture time, frame)

    log = MissionLog() if record else None
    cmd = None
    thrust_N, w_cmd, motors_on = 0.0, zero3, False
    contact: Contact | None = None  # the first contact after take-off, judged from the truth
    t_contact: float | None = None
    inputs = np.zeros(N_IN)  # what the compiled tick reads; updated in place when something changes
    inputs[IN_DECK + DK_ON] = 1.0
    inputs[IN_DECK + DK_HALF] = 0.5 * s.platform.pad_size_m
    airborne = False
    t_abort: float | None = None
    outcome: Outcome | None = None
    settle_reason = ""
    n_ticks = int(round(s.duration_s / TICK_DT))
    # The platform's path does not depend on the flight: its states at every tick, computed at once.
    truths = platform.states(np.arange(n_ticks + 1, dtype=np.float64) * TICK_DT)
    truth_p, truth_v = truths.p_WP, truths.v_WP
    windless = isinstance(wind, NoWind)
    f_wind = v_air = zero3
    gear = airframe.gear_height
    # the lowest a foot can be below the body origin (tilted 25 deg with the feet 0.2 m out), plus 1 cm
    reach = gear + s.contact.gear_half_width_m * 0.5 + 0.01
    low_z = s.platform.pad_height_m + reach
    mode = Mode.IDLE
    pad = s.platform.pad_size_m
    touching = False  # a foot touches the deck or the ground (after take-off)
    touch_z = 0.0  # height of the surface it touches (m)
    bounces = 0
    t_motors_off: float | None = None
    abort_landing = False  # the final action's descent: a gentle ground contact is its safe end
    x_prev = x

    # Motor thrusts at the log rate, for the flight energy whether or not the mission is recorded.
    motor_t = np.empty(n_ticks // every_log + 1)
    motor_N = np.empty((motor_t.size, 4))
    n_motor = 0

    false_detections = 0
    off_target_s = 0.0
    k = 0
    t = 0.0
    batch_xs = batch_imu = batch_touch = np.empty((0, 0))
    batch_i = batch_n = 0
    for k in range(1, n_ticks + 1):
        if batch_i == batch_n:
            # The physics runs in batches that end where the controller issues its next command (the
            # inputs are constant in between), cut short where the runner has to judge a first contact.
            if not windless:
                f_wind = wind.force_W(t, x[SL_P], x[SL_V])
                v_air = wind.air_velocity_W(t)
                inputs[IN_F_EXT : IN_F_EXT + 3] = f_wind
                inputs[IN_V_WIND : IN_V_WIND + 3] = v_air
            # the deck at the batch's start; the kernel carries it forward with its acceleration and turn
            inputs[IN_DECK + DK_P : IN_DECK + DK_P + 3] = truth_p[k - 1]
            inputs[IN_DECK + DK_V : IN_DECK + DK_V + 3] = truth_v[k - 1]
            inputs[IN_DECK + DK_A : IN_DECK + DK_A + 3] = truths.a_WP[k - 1]
            inputs[IN_DECK + DK_YAW] = truths.yaw[k - 1]
            inputs[IN_DECK + DK_YAW_RATE] = truths.yaw_rate[k - 1]
            m = min(every_control - (k - 1) % every_control, n_ticks + 1 - k)
            m = faults.before_imu_batch(k, m, imu)  # an IMU bias step due now; a batch ends before the next
            imu_bias, imu_noise, imu_scale = imu.kernel_inputs_many(m)
            batch_xs, batch_imu, batch_touch, batch_n = tick_batch(
                x, inputs, sim_params, ll_params, imu_bias, imu_noise, imu_scale, PHYSICS_DT, n_sub,
                contact_params, m, low_z if airborne and contact is None else -math.inf,
                math.inf if airborne else gear + 0.05,
            )  # fmt: skip
            imu.used(batch_n)
            batch_i = 0
        x_prev = x
        x, imu_out = batch_xs[batch_i], batch_imu[batch_i]
        on_deck, on_ground = int(batch_touch[batch_i, 0]), int(batch_touch[batch_i, 1])
        batch_i += 1
        t = k * TICK_DT
        p_WB, v_WB, q_WB, w_WB_B = x[SL_P], x[SL_V], x[SL_Q], x[SL_W]

        if not airborne and p_WB[2] - gear > 0.05:
            airborne = True
        # an abort's descent ends on the ground (or wherever it is): there a touch is its safe end
        ground_ok = abort_landing and pipeline.mission.abort_phase in _LANDING_PHASES
        if airborne and (on_deck or on_ground or touching):
            # Contact bookkeeping from the truth: the first contact is judged (DESIGN.md's limits, on the
            # approach: speeds and tilt of the tick before the feet touched, before the contact force
            # acted); every later touchdown after a lift-off is judged again; the ground is a crash
            # except at the end of an abort's descent.
            truth = truths.at(k)
            if on_deck or on_ground:
                surface = "ground" if on_ground and not on_deck else "pad"
                if not touching:
                    touching = True
                    touch_z = 0.0 if surface == "ground" else float(truth.p_WP[2])
                    judged = judge_contact(
                        p_WB, x_prev[SL_V], quat_to_rotmat(x_prev[SL_Q]), truth, pad, gear, limits,
                        surface=surface, ground_ok=ground_ok,
                    )  # fmt: skip
                    if judged is not None:
                        if contact is None:
                            contact, t_contact = judged, t
                        if judged.outcome is Outcome.CRASHED:
                            outcome, settle_reason = Outcome.CRASHED, judged.reason
                            if contact is not judged:
                                settle_reason = f"after a bounce: {judged.reason}"
                            break
                elif on_ground and not ground_ok:
                    outcome, settle_reason = Outcome.CRASHED, "ground"  # slid or tipped off the deck
                    break
            elif p_WB[2] - gear - touch_z > LIFT_OFF_M:
                touching = False
                bounces += 1
        if t_motors_off is not None and t - t_motors_off >= s.contact.settle_s:
            truth = truths.at(k)
            settled, settle_reason = judge_settled(
                p_WB,
                quat_to_rotmat(q_WB),
                truth,
                pad,
                limits,
                on_deck,
                on_ground,
                ground_ok=ground_ok,
            )
            if settled is Outcome.CRASHED:
                outcome = Outcome.CRASHED
            else:
                outcome = Outcome.ABORTED if abort_landing else Outcome.LANDED
            break

        # -- sensors into the pipeline ------------------------------------------------------------------
        pipeline.on_imu(t, imu_out[0:3], imu_out[3:6])
        if k % every_odometry == 0:
            odo = faults.odometry(odometry.measure(t, p_WB, v_WB, q_WB, w_WB_B))
            if odo is not None:
                pipeline.on_odometry(t, odo.p_WB, odo.q_WB, odo.v_WB)
        if not pipeline.ego_estimator.initialized:
            continue
        if k % every_range == 0:
            r = faults.range(t, rangefinder.measure_at(p_WB, q_WB, truth_p[k], float(truths.yaw[k]), pad))
            # as the sensor reports it: -inf inside its blind zone, +inf beyond its range (REP 117)
            pipeline.on_range(t, r)
        if telemetry is not None:
            # The platform's GNSS fix, taken now from the truth, reaches the pipeline after the link's
            # latency stamped with the time of the fix.
            if t + 1e-9 >= telemetry.next_fix_s:
                fix = telemetry.fix(t, truth_p[k], truth_v[k])
                if fix is not None:
                    tel_pending.append(fix)
            while tel_pending and tel_pending[0].t_arrival <= t + 1e-9:
                fix = tel_pending.popleft()
                pipeline.on_telemetry(fix.t_stamp, fix.p_WP, fix.v_WP, fix.cov_p_WP)
        if t + 1e-9 >= next_capture:
            # An image (or the truth sensor's report) is taken now and reaches the pipeline after the
            # processing latency; what it shows is fixed at the capture time.
            R_WB = quat_to_rotmat(q_WB)
            if renderer is not None:
                # A frame is rendered only when it is delivered and then used (module docstring): here
                # its fate (lost, dark, corrupted) and its sensor noise are drawn, in capture order.
                p_WC, R_WC = camera_pose_W(p_WB, R_WB, preset.mount)
                fate = faults.fate(t)
                shot = _Shot(p_WC, R_WC, truth_p[k], float(truths.yaw[k]), w_WB_B.copy(), fate,
                             renderer.draw_noise_offset())  # fmt: skip
                if not fate.dropped:
                    pending.append((faults.delivery_time(t), t, shot))
            else:
                frame: object = faults.frame(t, truth_perception.observe(t, p_WB, R_WB, truth_p[k]))
                if frame is not None:
                    pending.append((faults.delivery_time(t), t, frame))
            next_capture += perception_period
        while pending and pending[0][0] <= t + 1e-9:
            _, t_cap, frame = pending.popleft()
            if renderer is not None:
                render_all = render_every_frame or frame_sink is not None or faults.remembers_frames
                image = _develop(frame, t_cap, renderer, faults, pipeline, render_all)  # type: ignore[arg-type]
                observations, measurements = pipeline.on_image(t_cap, image)
                if frame_sink is not None:
                    frame_sink(t_cap, image, observations)
            else:
                measurements = pipeline.on_observations(t_cap, frame)  # type: ignore[arg-type]
            # A measurement farther from the pad's true centre than the pad's size (at its capture
            # time) comes from something else in the image: a false detection.
            k_cap = min(int(round(t_cap / TICK_DT)), n_ticks)
            for meas in measurements:
                if math.dist(meas.p_WP[0:2], truth_p[k_cap][0:2]) > pad:
                    false_detections += 1
                if log is not None:
                    log.add_detection(meas.t, meas.p_WP)

        # -- decisions ----------------------------------------------------------------------------------
        if k % every_mission == 0:
            mode = pipeline.step(t).mode
            if mode is Mode.ABORT and t_abort is None:
                t_abort = t
                abort_landing = pipeline.mission.config.final_action != "hover"
            if mode is Mode.ABORT and not abort_landing and pipeline.mission.final_action_complete:
                # hovering steadily at the hold point (its own estimate says so; the truth agrees when
                # nothing touches): the abort's safe end
                if not (on_deck or on_ground):
                    outcome = Outcome.ABORTED
                    break
            if mode is Mode.TRACK or mode is Mode.LAND:
                # Locked onto something else: the estimate the vehicle follows is far from the pad.
                est = pipeline.target(t)
                if est is not None and math.dist(est.p_WP[0:2], truth_p[k][0:2]) > 2.0 * pad:
                    off_target_s += every_mission * TICK_DT
        if k % every_control == 0:
            cmd = pipeline.command(t)
            thrust_N, w_cmd, motors_on = cmd.thrust_N, cmd.w_WB_B_cmd, not cmd.motors_off
            if airborne and not motors_on and t_motors_off is None:
                t_motors_off = t  # the pipeline stopped its motors: judge once the vehicle has settled
            inputs[IN_THRUST] = thrust_N
            inputs[IN_W_CMD : IN_W_CMD + 3] = w_cmd
            inputs[IN_MOTORS_ON] = 1.0 if motors_on else 0.0
        if k % every_log == 0:
            motor_t[n_motor] = t
            motor_N[n_motor] = x[IX_F : IX_F + 4]
            n_motor += 1
        if log is not None and k % every_log == 0:
            ego = pipeline.ego()
            target = pipeline.target(t)
            ref = pipeline.last_reference
            log.append(
                t,
                mode=mode.value,
                p_WB=p_WB,
                v_WB=v_WB,
                p_WB_est=ego.p_WB,
                v_WB_est=ego.v_WB,
                q_WB=q_WB,
                q_WB_est=ego.q_WB,
                p_WP=truth_p[k],
                v_WP=truth_v[k],
                p_WP_est=None if target is None else target.p_WP,
                v_WP_est=None if target is None else target.v_WP,
                p_ref=None if ref is None else ref.p,
                v_ref=None if ref is None else ref.v,
                thrust_N=thrust_N,
                w_cmd=w_cmd,
                w_WB_B=w_WB_B,
                range_m=pipeline.range_m,
                f_wind_W=f_wind,
                motor_N=x[IX_F : IX_F + 4],
            )

    if outcome is None:
        outcome = Outcome.TIMEOUT  # the motors never stopped (or the settling time ran past the end)
    wall = time.perf_counter() - wall0
    arrays = log.finalize() if log is not None else None
    stats = pipeline.stats
    events = {
        "t_first_detection": stats.t_first_detection,
        "t_landing_start": stats.t_landing_start,
        "t_touchdown": t_contact,
    }
    energy = flight_energy_J(motor_t[:n_motor], motor_N[:n_motor]) if n_motor > 1 else None
    compute_J = None
    if preset.energy_model is not None and hasattr(pipeline.detector, "energy_J"):
        compute_J = pipeline.detector.energy_J(preset.energy_model, duration_s=t)  # type: ignore[union-attr]
    rmse = None
    if arrays is not None and len(arrays["t"]) > 1:
        err = np.linalg.norm(arrays["p_WP_est"] - arrays["p_WP"], axis=1)
        err = err[np.isfinite(err)]
        rmse = float(np.sqrt(np.mean(err**2))) if err.size else None
    result: dict[str, Any] = {
        "scenario": s.model_dump(mode="json"),
        "seed": s.seed,
        "preset": s.preset,
        "outcome": outcome.value,
        "success": outcome is Outcome.LANDED,
        "touchdown_error_m": None if contact is None else contact.touchdown_error_m,
        "touchdown_rel_speed_mps": None if contact is None else contact.rel_speed_mps,
        "touchdown_rel_vertical_speed_mps": None if contact is None else contact.rel_vertical_speed_mps,
        "touchdown_rel_horizontal_speed_mps": None if contact is None else contact.rel_horizontal_speed_mps,
        "touchdown_tilt_deg": None if contact is None else math.degrees(contact.tilt_rad),
        "contact_surface": None if contact is None else contact.surface,
        "contact_reason": None if contact is None else contact.reason,
        "outcome_reason": settle_reason,
        "time_first_contact_s": t_contact,
        "time_touchdown_onboard_s": pipeline.touchdown.t_landed,
        "time_motors_off_s": t_motors_off,
        "bounces": bounces,
        "time_first_detection_s": stats.t_first_detection,
        "time_landing_start_s": stats.t_landing_start,
        "time_to_land_s": t_contact if outcome is Outcome.LANDED else None,
        "energy_flight_J": energy,
        "energy_compute_J": compute_J,
        "frames_processed": getattr(pipeline.detector, "frames_processed", stats.frames),
        "detections": stats.measurements,
        "rejected_measurements": stats.rejected_measurements,
        "go_arounds": pipeline.mission.go_arounds,
        "target_losses": pipeline.mission.target_losses,
        "abort_reason": pipeline.mission.abort_reason,
        "failsafe_events": [{"t": e.t, "kind": e.kind, "reason": e.reason} for e in pipeline.mission.events],
        "final_mode": pipeline.status.mode.value,
        "platform_estimate_rmse_m": rmse,
        "false_detections": false_detections,
        "false_lock": off_target_s > FALSE_LOCK_S,
        "off_target_s": off_target_s,
        "simulated_time_s": t,
        "wall_time_s": wall,
        "block_time_s": {k: round(v, 6) for k, v in stats.block_time_s.items()},
        "alight_version": alight.__version__,
    }
    history = [(tt, m.value, why) for tt, m, why in pipeline.mission.history]
    result["mode_history"] = [{"t": tt, "mode": m, "reason": why} for tt, m, why in history]
    return MissionRun(result=result, log=arrays, events=events, contact=contact, mode_history=history)
