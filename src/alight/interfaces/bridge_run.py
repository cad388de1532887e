"""``alight bridge``: connect a :class:`~alight.interfaces.mavlink_bridge.MavlinkBridge` to an autopilot,
fly, and write ``result.json``, the log and ``report.html`` like ``alight fly``.

Against the emulated autopilot (``alight sitl``) the scenario comes from the emulator (on its camera
stream, so both sides build the same camera, pad and preset), and so do the verdict (landed / crashed /
timeout, judged from ground truth) and the ground-truth log, which is merged with the bridge's own log
of estimates. Against a real autopilot the scenario file given with ``--scenario`` chooses the preset,
there is no ground truth, and ``outcome`` is ``null`` unless the link was lost.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import numpy as np

import alight
from alight.airframes import load_airframe
from alight.errors import ConfigError, InputError
from alight.evaluation.log import MissionLog, save_arrays
from alight.evaluation.mission_io import write_result
from alight.evaluation.report import write_mission_report
from alight.interfaces.camera_source import CameraSource, SocketCameraSource, open_camera
from alight.interfaces.mavlink_bridge import BridgeConfig, MavlinkBridge, Phase, open_link, pump
from alight.mission.presets import build_preset
from alight.scenario import Scenario, load_scenario

_TRUTH = ("p_WB", "v_WB", "p_WP", "v_WP", "thrust_N", "w_cmd", "w_WB_B", "f_wind_W", "motor_N")


def _default_camera(connect: str) -> str | None:
    # The emulated autopilot serves its camera on the MAVLink port + 1.
    if connect.startswith("udp:"):
        host, _, port = connect[4:].rpartition(":")
        if port.isdigit():
            return f"tcp:{host or '127.0.0.1'}:{int(port) + 1}"
    return None


def run_bridge(
    connect: str,
    out_dir: str | Path,
    config: BridgeConfig,
    *,
    scenario_path: str | Path | None = None,
    camera: str | None = None,
    max_wall_s: float | None = None,
    report: bool = True,
) -> dict[str, Any]:
    """Fly through the autopilot at ``connect`` and write the outputs into ``out_dir``; returns the result."""
    wall0 = time.perf_counter()
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise InputError(f"{out}: cannot create the output directory ({err.strerror})") from None
    cam_spec = camera or _default_camera(connect)
    if cam_spec is None:
        raise ConfigError("bridge: give --camera (a device index, file, URL or tcp:HOST:PORT)")
    cam: CameraSource = open_camera(cam_spec)
    emulator = isinstance(cam, SocketCameraSource)
    try:
        scenario = _scenario(cam, scenario_path)
        # the runner's seeding: nine children of the scenario's seed, the eighth for the pipeline
        seeds = np.random.SeedSequence(scenario.seed).spawn(9)
        airframe = load_airframe(scenario.airframe)
        preset = build_preset(scenario, airframe, np.random.default_rng(seeds[7]))
        if not preset.uses_camera:
            raise ConfigError(
                f"bridge: preset {scenario.preset!r} has no camera; the bridge needs a vision preset"
            )
        if scenario.platform.telemetry is not None and not preset.pipeline.fuses_telemetry:
            raise ConfigError(
                f"platform.telemetry: preset {scenario.preset}'s platform estimator "
                f"({type(preset.pipeline.platform_estimator).__name__}) cannot fuse telemetry"
            )
        # Compile the pipeline's numba kernels before taking the link: a first compile takes tens of
        # seconds on a fresh install, during which a companion would not answer the autopilot (a lost
        # offboard stream) or, in lockstep with the emulator, would let its world run on without us.
        from alight.compile.warmup import presets_to_warm_up, warm_up

        warm_up(presets_to_warm_up([scenario.model_dump(mode="json")]))
        conn = open_link(connect)
        bridge = MavlinkBridge(
            preset.pipeline,
            config,
            link=conn,
            camera=cam,
            airframe=airframe,
            planner_rate_hz=preset.planner_rate_hz,
        )
        try:
            _loop(bridge, conn, cam, emulator, max_wall_s)
        finally:
            conn.close()
        verdict = None
        truth = None
        if isinstance(cam, SocketCameraSource):
            # A simulator sends its verdict once its world has ended, and then lingers: while its stream
            # is open, wait for the verdict (the autopilot's link may have gone quiet first, as PX4's does
            # once the world stops stepping it), else only a moment.
            cam.wait_closed(10.0 if cam.result is not None else VERDICT_WAIT_S if cam.open else 0.5)
            verdict, truth = cam.result, cam.truth_log
    finally:
        cam.close()
    result, log_arrays, events = _outputs(
        scenario, bridge, config, verdict, truth, time.perf_counter() - wall0, simulated=emulator
    )
    save_arrays(log_arrays, out)
    if report:
        write_mission_report(out, result, log_arrays, events)
    write_result(out, result)
    return result


VERDICT_WAIT_S = 30.0
"""How long the bridge waits for a simulator's verdict after its loop ended with the stream still open
(wall s): the world sends it after its end, which a loaded machine delays by seconds."""
EMULATOR_SCENARIO_WAIT_S = 300.0
"""How long the bridge waits for the emulator's scenario once its camera stream is connected (s). The
emulator sends it when it accepts the stream, after warming its own kernels up, which takes minutes on a
cold numba cache and a busy machine (10 s was too short for four emulator-bridge pairs started together
on 2 cores). An emulator that ends closes the stream, and that ends the wait at once."""


def _scenario(cam: CameraSource, path: str | Path | None) -> Scenario:
    if path is not None:
        return load_scenario(path)
    if isinstance(cam, SocketCameraSource):
        deadline = time.monotonic() + EMULATOR_SCENARIO_WAIT_S
        while cam.scenario is None and time.monotonic() < deadline and cam.open:
            cam.poll()
            time.sleep(0.01)
        if cam.scenario is not None:
            try:
                return Scenario.model_validate(cam.scenario)
            except ValueError as err:
                raise InputError(f"bridge: the emulator's scenario is invalid ({err})") from None
        if not cam.open:
            raise InputError("bridge: the emulator closed its camera stream before sending its scenario")
        raise InputError(
            f"bridge: the emulator sent no scenario within {EMULATOR_SCENARIO_WAIT_S:g} s of its camera"
            " stream opening"
        )
    raise ConfigError("bridge: give --scenario (the emulated autopilot sends its own; this source did not)")


def _loop(
    bridge: MavlinkBridge, conn: Any, cam: CameraSource, emulator: bool, max_wall_s: float | None
) -> None:
    start = time.monotonic()
    last_hb = -math.inf
    while True:
        now = time.monotonic()
        if now - last_hb >= 1.0:
            bridge.send_heartbeat()
            last_hb = now
        pump(bridge, conn, 0.02)
        bridge.note_wall_clock()
        if isinstance(cam, SocketCameraSource):
            cam.poll()
            if cam.result is not None:
                return
        if bridge.link_lost():
            return
        if bridge.phase in (Phase.DONE, Phase.RELEASED) and not emulator:
            return
        if max_wall_s is not None and now - start > max_wall_s:
            bridge._event("stopped", reason="max wall time")
            return


def _outputs(
    scenario: Scenario,
    bridge: MavlinkBridge,
    config: BridgeConfig,
    verdict: dict[str, Any] | None,
    truth: dict[str, np.ndarray] | None,
    wall_s: float,
    simulated: bool = False,
) -> tuple[dict[str, Any], dict[str, np.ndarray], dict[str, float | None]]:
    arrays, rmse = _merged_log(bridge, truth)
    stats, summary = bridge.pipeline.stats, bridge.pipeline.summary()
    v = verdict or {}
    # The bridge keeps the autopilot's clock; with PX4 as the autopilot the mission began px4_boot_s
    # into it (the world waited for the arming): every time written is the mission's, as the verdict's
    boot = float(v.get("px4_boot_s") or 0.0)
    arrays["t"] = arrays["t"] - boot

    def mission_t(t: float | None) -> float | None:
        return None if t is None else t - boot

    outcome, reason = v.get("outcome"), v.get("outcome_reason")
    if bridge.phase is Phase.LINK_LOST and outcome is None:
        # no verdict: a simulated mission without one is an error (the campaign's outcomes); a real
        # vehicle's flight has no judge (outcome None) but says that its link was lost
        outcome = "error" if simulated else "link_lost"
        reason = "the autopilot's link was lost and the simulator sent no verdict"
    result: dict[str, Any] = {
        "scenario": scenario.model_dump(mode="json"),
        "seed": scenario.seed,
        "preset": scenario.preset,
        "outcome": outcome,
        "success": v.get("success", False if outcome in ("link_lost", "error") else None),
        "touchdown_error_m": v.get("touchdown_error_m"),
        "touchdown_rel_speed_mps": v.get("touchdown_rel_speed_mps"),
        "touchdown_rel_vertical_speed_mps": v.get("touchdown_rel_vertical_speed_mps"),
        "touchdown_rel_horizontal_speed_mps": v.get("touchdown_rel_horizontal_speed_mps"),
        "touchdown_tilt_deg": v.get("touchdown_tilt_deg"),
        "touchdown_platform_speed_mps": v.get("touchdown_platform_speed_mps"),
        "touchdown_platform_turn_rate_rad_s": v.get("touchdown_platform_turn_rate_rad_s"),
        "contact_surface": v.get("contact_surface"),
        "contact_reason": v.get("contact_reason"),
        "outcome_reason": reason,
        "time_first_contact_s": v.get("time_first_contact_s"),
        "time_touchdown_onboard_s": mission_t(summary.time_touchdown_onboard_s),
        "time_motors_off_s": v.get("time_motors_off_s"),
        "bounces": v.get("bounces"),
        "time_first_detection_s": mission_t(stats.t_first_detection),
        "time_landing_start_s": mission_t(stats.t_landing_start),
        "time_to_land_s": v.get("time_to_land_s"),
        "energy_flight_J": v.get("energy_flight_J"),
        "energy_compute_J": None,
        "frames_processed": stats.frames,
        "detections": stats.measurements,
        "rejected_measurements": stats.rejected_measurements,
        "go_arounds": summary.go_arounds,
        "final_mode": summary.final_mode.value,
        "platform_estimate_rmse_m": rmse,
        "simulated_time_s": v.get("simulated_time_s"),
        "wall_time_s": wall_s,
        "block_time_s": {k: round(x, 6) for k, x in stats.block_time_s.items()},
        "alight_version": alight.__version__,
        "mode_history": [
            {"t": mission_t(t), "mode": m.value, "reason": why} for t, m, why in summary.mode_history
        ],
        "bridge": _bridge_record(bridge, config, boot),
        "sitl": None
        if verdict is None
        else {
            "flavour": v.get("sitl_flavour"),
            "events": v.get("sitl_events"),
            # PX4's time at the mission's t = 0 (PX4 as the autopilot: the world waited for its arming)
            "px4_boot_s": v.get("px4_boot_s"),
        },
    }
    events = {
        "t_first_detection": mission_t(stats.t_first_detection),
        "t_landing_start": mission_t(stats.t_landing_start),
        "t_touchdown": v.get("time_to_land_s"),
    }
    return result, arrays, events


def _merged_log(
    bridge: MavlinkBridge, truth: dict[str, np.ndarray] | None
) -> tuple[dict[str, np.ndarray], float | None]:
    """The bridge's log rows with the emulator's ground truth interpolated onto them (on a real flight,
    without truth, the estimate stands in for it), and the platform estimate's RMSE against the truth."""
    log = MissionLog()
    rows = bridge.log_rows
    t_rows = np.array([r["t"] for r in rows]) if rows else np.zeros(0)
    truth_at: dict[str, np.ndarray] = {}
    if truth is not None and "t" in truth and truth["t"].size > 1 and t_rows.size:
        for name in _TRUTH:
            col = truth.get(name)
            if col is None:
                continue
            col2 = col.reshape(col.shape[0], -1)
            truth_at[name] = np.column_stack(
                [np.interp(t_rows, truth["t"], col2[:, j]) for j in range(col2.shape[1])]
            )
    for i, r in enumerate(rows):
        ch = {k: v for k, v in r.items() if k not in ("t", "mode") and v is not None}
        for name, arr in truth_at.items():
            ch[name] = arr[i] if arr.shape[1] > 1 else float(arr[i, 0])
        if not truth_at:  # no ground truth (a real flight): the estimate is the best there is
            ch["p_WB"], ch["v_WB"] = r["p_WB_est"], r["v_WB_est"]
        log.append(r["t"], mode=r["mode"], **ch)
    arrays = log.finalize()
    rmse = None
    if truth_at and len(arrays["t"]) > 1:
        err = np.linalg.norm(arrays["p_WP_est"] - arrays["p_WP"], axis=1)
        err = err[np.isfinite(err)]
        rmse = float(np.sqrt(np.mean(err**2))) if err.size else None
    return arrays, rmse


def _bridge_record(bridge: MavlinkBridge, config: BridgeConfig, boot_s: float = 0.0) -> dict[str, Any]:
    """What the bridge did: its settings, its final phase and its message counts (its events' times
    the mission's: the autopilot's clock less ``boot_s``)."""
    return {
        "mode": config.mode,
        "autopilot": config.autopilot,
        "setpoint": config.setpoint,
        "arm": config.arm,
        "final_phase": bridge.phase.value,
        "lockstep": bridge.lockstep,
        "accepted": bridge.stats.accepted,
        "rejected": bridge.stats.rejected,
        "parse_errors": bridge.stats.parse_errors,
        "foreign_messages": bridge.stats.foreign,
        "setpoints_sent": bridge.stats.setpoints_sent,
        "hold_setpoints_sent": bridge.stats.holds,
        "landing_targets_sent": bridge.stats.landing_targets_sent,
        "events": [
            {**e, "t": e["t"] - boot_s} if e.get("t") is not None else e for e in bridge.events[-200:]
        ],
    }
