"""The runner: steps the simulated world and a preset's pipeline together, and judges the outcome.

Rates (simulated clock): dynamics and the body-rate loop at 1 kHz (fused, ``physics.advance``), IMU at
200 Hz (the base tick), odometry at 40 Hz, range finder at 100 Hz, optical flow (when the scenario has a
module) at its rate, controller at 100 Hz, mission and
planner at the planner's rate (50 Hz), perception at the scenario's rate with its latency, log at 50 Hz.

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
from alight.estimation import TelemetryFusing
from alight.evaluation.log import MissionLog
from alight.mission.presets import Preset, build_preset
from alight.scenario import Scenario
from alight.sim.quadrotor import IX_F, SL_P, SL_Q, SL_V, SL_W
from alight.sim.touchdown import Contact
from alight.sim.world import SEED_PIPELINE, TICK_DT, Shot, World, mission_seeds
from alight.types import Mode, Observation, Outcome

_LANDING_PHASES = ("descend", "done")  # the final action's phases where touching the ground is its end
FALSE_LOCK_S = 1.0  # tracking or landing on an estimate > 2 pad sizes from the pad this long: a false lock


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
    pipeline = preset.pipeline
    if s.platform.telemetry is not None and not isinstance(pipeline.platform_estimator, TelemetryFusing):
        raise ConfigError(
            f"platform.telemetry: preset {s.preset}'s platform estimator "
            f"({type(pipeline.platform_estimator).__name__}) cannot fuse telemetry"
        )
    world = World(s, airframe, preset, seeds)
    faults = world.faults
    truths = world.truths
    truth_p, truth_v = truths.p_WP, truths.v_WP
    n_ticks = world.n_ticks

    every_odometry = round(1.0 / (40.0 * TICK_DT))
    every_range = round(1.0 / (100.0 * TICK_DT))
    every_control = round(1.0 / (100.0 * TICK_DT))
    every_mission = max(1, round(1.0 / (preset.planner_rate_hz * TICK_DT)))
    every_log = round(1.0 / (50.0 * TICK_DT))
    every_flow = world.flow_every_ticks  # 0: no optical-flow module
    camera = world.renderer is not None
    render_all = (
        render_every_frame or (frame_sink is not None and frame_wanted is None) or faults.remembers_frames
    )

    log = MissionLog() if record else None
    thrust_N, w_cmd = 0.0, np.zeros(3)
    t_abort: float | None = None
    mode = Mode.IDLE
    pad = s.platform.pad_size_m
    abort_landing = False  # the final action's descent: a gentle ground contact is its safe end

    # Motor thrusts at the log rate, for the flight energy whether or not the mission is recorded.
    motor_t = np.empty(n_ticks // every_log + 1)
    motor_N = np.empty((motor_t.size, 4))
    n_motor = 0

    false_detections = 0
    off_target_s = 0.0
    t = 0.0
    for k in range(1, n_ticks + 1):
        # an abort's descent ends on the ground (or wherever it is): there a touch is its safe end
        world.ground_ok = abort_landing and pipeline.mission.abort_phase in _LANDING_PHASES
        imu_out = world.step()
        t = world.t
        if world.outcome is not None:
            break
        x = world.x

        # -- sensors into the pipeline ------------------------------------------------------------------
        pipeline.on_imu(t, imu_out[0:3], imu_out[3:6])
        if k % every_odometry == 0:
            odo = world.odometry_message()
            if odo is not None:
                pipeline.on_odometry(t, odo.p_WB, odo.q_WB, odo.v_WB, faults.odometry_reset_counter)
        if not pipeline.ego_estimator.initialized:
            continue
        if k % every_range == 0:
            pipeline.on_range(t, world.range_m())
        if every_flow and k % every_flow == 0:
            flow = world.flow_sample()
            if flow is not None:
                pipeline.on_flow(flow.t, flow.flow_B_rad_s, flow.distance_m)
        for fix in world.telemetry_arrivals():
            pipeline.on_telemetry(fix.t_stamp, fix.p_WP, fix.v_WP, fix.cov_p_WP)
        world.capture()
        for t_cap, frame in world.deliveries():
            if camera:
                assert isinstance(frame, Shot)
                used = render_all or pipeline.will_process_image(t_cap)
                # A frame the detector skips is rendered for the sink only where it asks for it (and
                # that changes nothing in the flight: the frame's noise is drawn in the shot).
                asked = not used and frame_wanted is not None and frame_wanted(t_cap)
                for_sink = frame_sink is not None and (used or asked)
                image = world.develop(frame, t_cap, used=used or for_sink)
                observations, measurements = pipeline.on_image(t_cap, image)
                if for_sink and frame_sink is not None:
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
                world.aborting = abort_landing
            if mode is Mode.ABORT and not abort_landing and pipeline.mission.final_action_complete:
                # hovering steadily at the hold point (its own estimate says so; the truth agrees when
                # nothing touches): the abort's safe end
                if not (world.on_deck or world.on_ground):
                    world.end(Outcome.ABORTED)
                    break
            if mode is Mode.TRACK or mode is Mode.LAND:
                # Locked onto something else: the estimate the vehicle follows is far from the pad.
                est = pipeline.target(t)
                if est is not None and math.dist(est.p_WP[0:2], truth_p[k][0:2]) > 2.0 * pad:
                    off_target_s += every_mission * TICK_DT
        if k % every_control == 0:
            cmd = pipeline.command(t)
            thrust_N, w_cmd = cmd.thrust_N, cmd.w_WB_B_cmd
            world.set_command(thrust_N, w_cmd, not cmd.motors_off)
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
                p_WB=x[SL_P],
                v_WB=x[SL_V],
                p_WB_est=ego.p_WB,
                v_WB_est=ego.v_WB,
                q_WB=x[SL_Q],
                q_WB_est=ego.q_WB,
                p_WP=truth_p[k],
                v_WP=truth_v[k],
                p_WP_est=None if target is None else target.p_WP,
                v_WP_est=None if target is None else target.v_WP,
                p_ref=None if ref is None else ref.p,
                v_ref=None if ref is None else ref.v,
                thrust_N=thrust_N,
                w_cmd=w_cmd,
                w_WB_B=x[SL_W],
                range_m=pipeline.range_m,
                f_wind_W=world.f_wind,
                motor_N=x[IX_F : IX_F + 4],
            )

    contact, t_contact = world.contact, world.t_contact
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
        **world.verdict(),
        "time_touchdown_onboard_s": pipeline.touchdown.t_landed,
        "time_first_detection_s": stats.t_first_detection,
        "time_landing_start_s": stats.t_landing_start,
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
