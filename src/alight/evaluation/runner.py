"""The runner: steps the simulated world and a preset's pipeline together, and judges the outcome.

Rates (simulated clock): dynamics and the body-rate loop at 1 kHz (fused, ``sim.physics.advance``), IMU
at 200 Hz (the base tick); the rest are whole multiples of the tick, as data (:data:`RATES_HZ`, and the
scenario's optical-flow module and the preset's planner rate): odometry at 40 Hz, range finder at
100 Hz, optical flow at its rate, mission and planner at the planner's rate (50 Hz), controller at
100 Hz, log at 50 Hz; the camera is polled every tick (it takes frames at the scenario's rate and
delivers them after its latency). Within a tick the handlers run in the order of :func:`_schedules`.

The world (physics, contact and its judging, sensors, camera, faults, randomness) is
``sim/world.py``'s :class:`~alight.sim.world.World`, the same one ``alight sitl`` steps
behind MAVLink. The runner is the only place that sees both the truth and the pipeline: it passes the
world's sensor data to the pipeline, the pipeline's commands to the world, and scores what only the
truth can tell (false detections, false locks).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

import alight
from alight.airframe import Airframe
from alight.airframes import load_airframe
from alight.energy import flight_energy_J
from alight.errors import ConfigError
from alight.evaluation.log import MissionLog
from alight.mission.presets import Preset, build_preset
from alight.scenario import Scenario
from alight.sim.quadrotor import IX_F, SL_P, SL_Q, SL_V, SL_W
from alight.sim.touchdown import Contact
from alight.sim.world import SEED_PIPELINE, TICK_DT, Shot, World, mission_seeds
from alight.types import Mode, Observation, Outcome, PlatformMeasurement

FALSE_LOCK_S = 1.0  # tracking or landing on an estimate > 2 pad sizes from the pad this long: a false lock

RATES_HZ = {"odometry": 40.0, "range": 100.0, "control": 100.0, "log": 50.0}
"""The runner's fixed rates (Hz), each a whole number of ticks (:data:`~alight.sim.world.TICK_DT`)."""


@dataclass
class MissionRun:
    """What one mission produced."""

    result: dict[str, Any]
    log: dict[str, np.ndarray] | None
    events: dict[str, float | None]
    contact: Contact | None = None
    mode_history: list[tuple[float, str, str]] = field(default_factory=list)


FrameSink = Callable[[float, np.ndarray, list[Observation]], None]
"""Receives each camera frame a vision preset processed: capture time (s), the image, the detections."""

Handler = Callable[[int], "bool | None"]
"""What runs at a tick ``k`` when its rate is due; True ends the mission there."""


def _composed(
    scenario: Scenario, airframe: Airframe | None
) -> tuple[Airframe, Preset, list[np.random.SeedSequence]]:
    """The airframe (``airframe``, else the scenario's), the scenario's preset built for it and the
    mission's seeds, the preset's draws from its own child (:data:`~alight.sim.world.SEED_PIPELINE`)."""
    if airframe is None:
        airframe = load_airframe(scenario.airframe)
    seeds = mission_seeds(scenario.seed)
    preset = build_preset(scenario, airframe, np.random.default_rng(seeds[SEED_PIPELINE]))
    return airframe, preset, seeds


def world_for_scenario(scenario: Scenario, airframe: Airframe | None = None) -> World:
    """The world of ``scenario`` for its preset, seeded as :func:`run_mission` seeds it, for a flight
    whose pipeline runs elsewhere (``alight sitl``): the preset is built only for its camera, pad, mount
    and rate gains."""
    airframe, preset, seeds = _composed(scenario, airframe)
    return World(scenario, airframe, preset, seeds)


def run_mission(
    scenario: Scenario,
    *,
    airframe: Airframe | None = None,
    record: bool = True,
    frame_sink: FrameSink | None = None,
    frame_wanted: Callable[[float], bool] | None = None,
    render_every_frame: bool = False,
) -> MissionRun:
    """Fly one mission of ``scenario`` and return its result (and log when ``record``). ``airframe``
    overrides the scenario's ``airframe:``; the simulator, the wind's drag and the preset's controller
    and planner all read this one. ``frame_sink`` sees every camera frame with its detections (for
    replays); it must not modify them. With ``frame_wanted(t_capture)``, the sink sees only the frames
    the pipeline reads or that predicate asks for (a replay's :class:`FrameRecorder` keeps 10 per
    second), so a gated detector's skipped frames need not be rendered for it.

    Camera frames are rendered only when the pipeline will look at them: not when lost, not when dark
    (a blackout), not when the detector skips them (:class:`~alight.perception.FrameGate`); the mission
    is the same as with every frame rendered (``render_every_frame``, for tests and measurements)."""
    wall0 = time.perf_counter()
    s = scenario
    airframe, preset, seeds = _composed(s, airframe)
    if s.platform.telemetry is not None and not preset.pipeline.fuses_telemetry:
        raise ConfigError(
            f"platform.telemetry: preset {s.preset}'s platform estimator "
            f"({type(preset.pipeline.platform_estimator).__name__}) cannot fuse telemetry"
        )
    world = World(s, airframe, preset, seeds)
    render_all = (
        render_every_frame
        or (frame_sink is not None and frame_wanted is None)
        or world.faults.remembers_frames
    )
    flight = _Flight(world, preset, MissionLog() if record else None, frame_sink, frame_wanted, render_all)
    _fly(flight, *_schedules(flight))
    return _scored(flight, time.perf_counter() - wall0)


class _Schedule:
    """Handlers at whole multiples of the tick, in table order: ``phases[k % period]`` are those due at
    tick ``k`` (whose period divides ``k``), looked up instead of testing every rate at every tick."""

    def __init__(self, table: list[tuple[int, Handler]], n_ticks: int) -> None:
        table = [(n, h) for n, h in table if n > 0]  # 0 ticks: the sensor is not fitted
        # the common period of the rates; past the mission's last tick, the ticks themselves
        self.period = min(math.lcm(*(n for n, _ in table)) if table else 1, n_ticks + 1)
        self.phases = [tuple(h for n, h in table if k % n == 0) for k in range(self.period)]


def _ticks(rate_hz: float) -> int:
    return round(1.0 / (rate_hz * TICK_DT))


def _schedules(f: _Flight) -> tuple[_Schedule, _Schedule]:
    """What runs at each tick after the IMU sample, as (every so many ticks, handler): the messages that
    initialise the ego estimate, and what waits for it."""
    before_ego: list[tuple[int, Handler]] = [(_ticks(RATES_HZ["odometry"]), f.odometry)]
    after_ego: list[tuple[int, Handler]] = [
        (_ticks(RATES_HZ["range"]), f.range),
        (f.world.flow_every_ticks, f.flow),  # 0: no optical-flow module
        (1, f.arrivals),
        (max(1, _ticks(f.planner_rate_hz)), f.decide),
        (_ticks(RATES_HZ["control"]), f.control),
        (f.every_log, f.motors),
    ]
    if f.log is not None:
        after_ego.append((f.every_log, f.record))
    n = f.world.n_ticks
    return _Schedule(before_ego, n), _Schedule(after_ego, n)


def _fly(f: _Flight, before_ego: _Schedule, after_ego: _Schedule) -> None:
    """Step the world to the mission's end: each tick the IMU sample into the pipeline, then what is due
    (the rest only once the ego estimate has its first pose)."""
    world, pipeline = f.world, f.pipeline
    early, n_early = before_ego.phases, before_ego.period
    late, n_late = after_ego.phases, after_ego.period
    ego_ready = False  # an ego estimate once initialised stays so (EgoEkf has no way back): asked until then
    for k in range(1, world.n_ticks + 1):
        # an abort's descent ends on the ground (or wherever it is): there a touch is its safe end
        world.ground_ok = world.aborting and pipeline.in_final_descent
        imu_out = world.step()
        if world.outcome is not None:
            return
        pipeline.on_imu(world.t, imu_out[0:3], imu_out[3:6])
        for handler in early[k % n_early]:
            handler(k)
        if not ego_ready:
            ego_ready = pipeline.ego_initialized
            if not ego_ready:
                continue
        for handler in late[k % n_late]:
            if handler(k):
                return


class _Flight:
    """One mission in flight: the world, the pipeline, and what the runner keeps between ticks (the
    command, the mode, the scores only the truth can tell, the log). Its methods are the handlers of
    :func:`_schedules`, each at its rate."""

    def __init__(
        self,
        world: World,
        preset: Preset,
        log: MissionLog | None,
        frame_sink: FrameSink | None,
        frame_wanted: Callable[[float], bool] | None,
        render_all: bool,
    ) -> None:
        self.world, self.preset, self.pipeline, self.log = world, preset, preset.pipeline, log
        self.planner_rate_hz = preset.planner_rate_hz
        self.frame_sink, self.frame_wanted, self.render_all = frame_sink, frame_wanted, render_all
        self.camera_frames = world.renderer is not None
        self.pad_m = world.scenario.platform.pad_size_m
        self.every_log = _ticks(RATES_HZ["log"])
        self.every_mission_s = max(1, _ticks(self.planner_rate_hz)) * TICK_DT
        self.thrust_N, self.w_cmd = 0.0, np.zeros(3)
        self.mode = Mode.IDLE
        self.t_abort: float | None = None
        self.false_detections = 0
        self.off_target_s = 0.0
        # Motor thrusts at the log rate, for the flight energy whether or not the mission is recorded.
        self.motor_t = np.empty(world.n_ticks // self.every_log + 1)
        self.motor_N = np.empty((self.motor_t.size, 4))
        self.n_motor = 0

    # -- sensors into the pipeline --------------------------------------------------------------------------
    def odometry(self, k: int) -> None:
        odo = self.world.odometry_message()
        if odo is not None:
            reset_counter = self.world.faults.odometry_reset_counter
            self.pipeline.on_odometry(self.world.t, odo.p_WB, odo.q_WB, odo.v_WB, reset_counter)

    def range(self, k: int) -> None:
        self.pipeline.on_range(self.world.t, self.world.range_m())

    def flow(self, k: int) -> None:
        flow = self.world.flow_sample()
        if flow is not None:
            self.pipeline.on_flow(flow.t, flow.flow_B_rad_s, flow.distance_m)

    def arrivals(self, k: int) -> None:
        """What arrives at any tick: the platform's telemetry fixes, then the camera's frames."""
        world = self.world
        for fix in world.telemetry_arrivals():
            self.pipeline.on_telemetry(fix.t_stamp, fix.p_WP, fix.v_WP, fix.cov_p_WP)
        for mru in world.motion_telemetry_arrivals():  # a vessel's motion broadcast (platform.sea)
            self.pipeline.on_deck_motion(
                mru.t_stamp, mru.attitude, mru.cov_attitude, mru.heave_rate, mru.heave_rate_var
            )
        world.capture()
        for t_cap, frame in world.deliveries():
            if self.camera_frames:
                assert isinstance(frame, Shot)
                measurements = self._develop(t_cap, frame)
            else:
                measurements = self.pipeline.on_observations(t_cap, frame)  # type: ignore[arg-type]
            # A measurement farther from the pad's true centre than the pad's size (at its capture
            # time) comes from something else in the image: a false detection.
            p_WP = world.truths.p_WP[min(int(round(t_cap / TICK_DT)), world.n_ticks)]
            for meas in measurements:
                if math.dist(meas.p_WP[0:2], p_WP[0:2]) > self.pad_m:
                    self.false_detections += 1
                if self.log is not None:
                    self.log.add_detection(meas.t, meas.p_WP)

    def _develop(self, t_cap: float, shot: Shot) -> list[PlatformMeasurement]:
        """A camera frame into the pipeline, rendered only when someone reads it."""
        used = self.render_all or self.pipeline.will_process_image(t_cap)
        # A frame the detector skips is rendered for the sink only where it asks for it (and that changes
        # nothing in the flight: the frame's noise is drawn in the shot).
        asked = not used and self.frame_wanted is not None and self.frame_wanted(t_cap)
        for_sink = self.frame_sink is not None and (used or asked)
        image = self.world.develop(shot, t_cap, used=used or for_sink)
        observations, measurements = self.pipeline.on_image(t_cap, image)
        if for_sink and self.frame_sink is not None:
            self.frame_sink(t_cap, image, observations)
        return measurements

    # -- decisions ------------------------------------------------------------------------------------------
    def decide(self, k: int) -> bool:
        """The mission step; True when an abort's hover ends the mission."""
        world, pipeline, t = self.world, self.pipeline, self.world.t
        self.mode = mode = pipeline.step(t).mode
        if mode is Mode.ABORT and self.t_abort is None:
            self.t_abort = t
            world.aborting = pipeline.final_action_lands
        if mode is Mode.ABORT and not world.aborting and pipeline.final_action_complete:
            # hovering steadily at the hold point (its own estimate says so; the truth agrees when nothing
            # touches): the abort's safe end
            if not (world.on_deck or world.on_ground):
                world.end(Outcome.ABORTED)
                return True
        if mode is Mode.TRACK or mode is Mode.LAND:
            # Locked onto something else: the estimate the vehicle follows is far from the pad.
            est = pipeline.target(t)
            if est is not None and math.dist(est.p_WP[0:2], world.truths.p_WP[k][0:2]) > 2.0 * self.pad_m:
                self.off_target_s += self.every_mission_s
        return False

    def control(self, k: int) -> None:
        cmd = self.pipeline.command(self.world.t)
        self.thrust_N, self.w_cmd = cmd.thrust_N, cmd.w_WB_B_cmd
        self.world.set_command(self.thrust_N, self.w_cmd, not cmd.motors_off)

    # -- records --------------------------------------------------------------------------------------------
    def motors(self, k: int) -> None:
        self.motor_t[self.n_motor] = self.world.t
        self.motor_N[self.n_motor] = self.world.x[IX_F : IX_F + 4]
        self.n_motor += 1

    def record(self, k: int) -> None:
        assert self.log is not None
        world, pipeline, x, t = self.world, self.pipeline, self.world.x, self.world.t
        ego = pipeline.ego()
        target = pipeline.target(t)
        ref = pipeline.last_reference
        self.log.append(
            t,
            mode=self.mode.value,
            p_WB=x[SL_P],
            v_WB=x[SL_V],
            p_WB_est=ego.p_WB,
            v_WB_est=ego.v_WB,
            q_WB=x[SL_Q],
            q_WB_est=ego.q_WB,
            p_WP=world.truths.p_WP[k],
            v_WP=world.truths.v_WP[k],
            p_WP_est=None if target is None else target.p_WP,
            v_WP_est=None if target is None else target.v_WP,
            p_ref=None if ref is None else ref.p,
            v_ref=None if ref is None else ref.v,
            thrust_N=self.thrust_N,
            w_cmd=self.w_cmd,
            w_WB_B=x[SL_W],
            range_m=pipeline.range_m,
            f_wind_W=world.f_wind,
            motor_N=x[IX_F : IX_F + 4],
        )


def _scored(f: _Flight, wall_s: float) -> MissionRun:
    """The mission's result: the world's verdict, the pipeline's summary, and the runner's own scores."""
    world, s, t = f.world, f.world.scenario, f.world.t
    arrays = f.log.finalize() if f.log is not None else None
    summary = f.pipeline.summary(f.preset.energy_model, duration_s=t)
    events = {
        "t_first_detection": summary.time_first_detection_s,
        "t_landing_start": summary.time_landing_start_s,
        "t_touchdown": world.t_contact,
    }
    n = f.n_motor
    energy = flight_energy_J(f.motor_t[:n], f.motor_N[:n]) if n > 1 else None
    rmse = None
    if arrays is not None and len(arrays["t"]) > 1:
        err = np.linalg.norm(arrays["p_WP_est"] - arrays["p_WP"], axis=1)
        err = err[np.isfinite(err)]
        rmse = float(np.sqrt(np.mean(err**2))) if err.size else None
    history = [(tt, m.value, why) for tt, m, why in summary.mode_history]
    result: dict[str, Any] = {
        "scenario": s.model_dump(mode="json"),
        "seed": s.seed,
        "preset": s.preset,
        **world.verdict(),
        "time_touchdown_onboard_s": summary.time_touchdown_onboard_s,
        "time_first_detection_s": summary.time_first_detection_s,
        "time_landing_start_s": summary.time_landing_start_s,
        "energy_flight_J": energy,
        "energy_compute_J": summary.energy_compute_J,
        "frames_processed": summary.frames_processed,
        "detections": summary.detections,
        "rejected_measurements": summary.rejected_measurements,
        "go_arounds": summary.go_arounds,
        "target_losses": summary.target_losses,
        "abort_reason": summary.abort_reason,
        "failsafe_events": [{"t": e.t, "kind": e.kind, "reason": e.reason} for e in summary.failsafe_events],
        "final_mode": summary.final_mode.value,
        "platform_estimate_rmse_m": rmse,
        "false_detections": f.false_detections,
        "false_lock": f.off_target_s > FALSE_LOCK_S,
        "off_target_s": f.off_target_s,
        "simulated_time_s": t,
        "wall_time_s": wall_s,
        "block_time_s": {k: round(v, 6) for k, v in summary.block_time_s.items()},
        "alight_version": alight.__version__,
        "mode_history": [{"t": tt, "mode": m, "reason": why} for tt, m, why in history],
    }
    return MissionRun(result=result, log=arrays, events=events, contact=world.contact, mode_history=history)
