"""Missions flown through an autopilot, for ``alight campaign --autopilot emulator|px4`` and ``alight fly
--autopilot emulator``: the same scenario, the pipeline as the companion behind the MAVLink bridge.

- ``emulator``: alight's own emulated autopilot (:mod:`alight.interfaces.sitl`, PX4 or ArduPilot
  flavour) in a child process, in lockstep with the bridge in this one, on ports the kernel picks;
- ``px4``: the user's PX4 SITL build with alight's world as its simulator (:func:`fly_px4`), one PX4
  instance per mission, claimed under a lock so that a campaign's workers never share one.

A campaign's sandboxes are separate processes that know a mission only by its scenario, so the setting
reaches them in the environment variable :data:`AUTOPILOT_ENV` (JSON of :class:`AutopilotSetting`),
which ``alight campaign`` sets for its own children; the campaign's lock file records the same setting,
and a resume with another is refused. Each result carries the setting under ``autopilot``.

What a mission keeps: a landed mission only its ``result.json`` (as a simulated campaign keeps nothing
but the results row), any other its whole directory: the bridge's log and report, and for PX4 the
console log and PX4's own ULog, to study the failure with PX4's tools.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import shutil
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Literal

from alight.errors import ConfigError
from alight.scenario import Scenario

AUTOPILOT_ENV = "ALIGHT_CAMPAIGN_AUTOPILOT"
AutopilotKind = Literal["sim", "emulator", "px4"]
AUTOPILOT_KINDS: tuple[str, ...] = ("sim", "emulator", "px4")
MISSION_FNS = {
    "emulator": "alight.interfaces.autopilot_missions:fly_emulator_mission",
    "px4": "alight.interfaces.autopilot_missions:fly_px4_mission",
}
EMULATOR_READY_S = 120.0
"""The emulator's process must be listening within this (wall s): building its world loads kernels."""


@dataclass(frozen=True, kw_only=True)
class AutopilotSetting:
    """Which autopilot flies a campaign's missions, and how."""

    kind: AutopilotKind = "sim"
    """``sim``: alight's own simulator, no autopilot (the default); ``emulator``; ``px4``."""
    mode: Literal["offboard", "landing-target"] = "offboard"
    setpoint: Literal["rates", "position"] = "position"
    """Offboard setpoints: ``position`` lets the autopilot's own controllers fly the reference."""
    flavour: Literal["px4", "ardupilot"] = "px4"
    """The emulator's flavour (``emulator`` only)."""
    speed: float = 1.0
    """``px4``: simulated seconds per wall second at most (:class:`Px4FlyConfig`)."""
    px4_dir: str | None = None
    """``px4``: the SITL build (None: ``$ALIGHT_PX4_DIR``)."""

    def __post_init__(self) -> None:
        if self.kind not in AUTOPILOT_KINDS:
            raise ConfigError(f"autopilot must be one of {', '.join(AUTOPILOT_KINDS)}, got {self.kind!r}")
        if not (self.speed >= 0.0 and self.speed < 1e3):
            raise ConfigError(f"px4: --px4-speed must be in [0, 1000), got {self.speed}")

    def record(self) -> dict[str, Any]:
        """What a result and the campaign's lock say of it (the build's path is the machine's, not the
        experiment's, and is left out of the comparison on resume)."""
        return asdict(self)

    @classmethod
    def from_env(cls) -> AutopilotSetting:
        raw = os.environ.get(AUTOPILOT_ENV)
        if not raw:
            raise ConfigError(f"autopilot mission: {AUTOPILOT_ENV} is not set (alight campaign sets it)")
        try:
            return cls(**json.loads(raw))
        except (ValueError, TypeError) as err:
            raise ConfigError(f"autopilot mission: {AUTOPILOT_ENV} is not a valid setting ({err})") from None

    def to_env(self) -> str:
        return json.dumps(asdict(self))


def _keep(out_dir: Path, result: dict[str, Any]) -> dict[str, Any]:
    """A landed mission keeps its result.json only (module docstring)."""
    if result.get("outcome") == "landed":
        for p in list(out_dir.iterdir()):
            if p.name != "result.json":
                shutil.rmtree(p) if p.is_dir() else p.unlink()
    return result


def fly_px4_mission(scenario: Scenario, out_dir: Path) -> dict[str, Any]:
    """The campaign's mission with PX4 SITL (:data:`AUTOPILOT_ENV` gives the build and the mode)."""
    from alight.interfaces.px4_run import Px4FlyConfig, fly_px4

    setting = AutopilotSetting.from_env()
    config = Px4FlyConfig(mode=setting.mode, setpoint=setting.setpoint, speed=setting.speed)
    result = fly_px4(scenario, out_dir, setting.px4_dir, config)
    result["autopilot"] = setting.record()
    return _keep(Path(out_dir), result)


def fly_emulator_mission(scenario: Scenario, out_dir: Path) -> dict[str, Any]:
    """The campaign's mission with alight's emulated autopilot (:data:`AUTOPILOT_ENV`)."""
    setting = AutopilotSetting.from_env()
    result = fly_emulator(scenario, out_dir, setting)
    result["autopilot"] = setting.record()
    return _keep(Path(out_dir), result)


def _serve_emulator(scenario_json: dict[str, Any], config: Any, ready: Any, ports: Any) -> None:
    """The emulator's process: listen on ports the kernel picks, tell the parent, fly, linger, close."""
    from alight.interfaces.sitl import EmulatedAutopilot, serve_autopilot

    ap = EmulatedAutopilot(Scenario.model_validate(scenario_json), config)
    ports[0], ports[1] = int(ap.conn.port.getsockname()[1]), ap.frames.port
    ready.set()
    serve_autopilot(ap)


def fly_emulator(scenario: Scenario, out_dir: str | Path, setting: AutopilotSetting) -> dict[str, Any]:
    """Fly ``scenario`` with the emulated autopilot in a child process and the bridge here; writes
    ``out_dir`` as ``alight bridge`` does and returns its result. An emulator that does not start or
    dies ends the mission as the bridge sees it (a lost link), never as a hang."""
    from alight.interfaces.bridge_run import run_bridge
    from alight.interfaces.mavlink_bridge import BridgeConfig
    from alight.interfaces.px4_run import search_height_m
    from alight.interfaces.sitl import SitlConfig

    takeoff = search_height_m(scenario) if setting.mode == "landing-target" else SitlConfig().takeoff_height_m
    config = SitlConfig(port=0, camera_port=0, flavour=setting.flavour, lockstep=True,
                        takeoff_height_m=takeoff)  # fmt: skip
    ctx = multiprocessing.get_context("spawn")
    ready, ports = ctx.Event(), ctx.Array("i", 2)
    emulator = ctx.Process(
        target=_serve_emulator, args=(scenario.model_dump(mode="json"), config, ready, ports)
    )
    emulator.start()
    try:
        deadline = time.monotonic() + EMULATOR_READY_S
        while not ready.wait(0.2):
            if not emulator.is_alive() or time.monotonic() > deadline:
                raise ConfigError(
                    f"emulator: its process {'exited' if not emulator.is_alive() else 'was not listening'}"
                    f" before the mission (exit code {emulator.exitcode})"
                )
        bridge = BridgeConfig(
            mode=setting.mode, autopilot=setting.flavour, setpoint=setting.setpoint, arm=True
        )
        return run_bridge(
            f"udp:127.0.0.1:{ports[0]}", out_dir, bridge, camera=f"tcp:127.0.0.1:{ports[1]}",
            max_wall_s=scenario.duration_s * 10.0 + 300.0,
        )  # fmt: skip
    finally:
        emulator.join(30.0)
        if emulator.is_alive():
            emulator.terminate()
            emulator.join(5.0)


def fly_through_command(scenario: Scenario, out: Path, args: Any) -> int:
    """``alight fly --autopilot emulator|px4``: fly, print one line, return the exit status. ``args``: the
    command's parsed arguments (``autopilot``, ``px4``, ``px4_mode``, ``px4_speed``, ``setpoint``;
    ``replay``, ``mcap`` and ``bag`` are refused: those outputs are written for alight's own simulator
    only)."""
    from alight.interfaces.px4_run import Px4FlyConfig, fly_px4

    if args.replay or args.mcap or args.bag:
        raise ConfigError(f"{args.autopilot}: --replay, --mcap and --bag are for --autopilot sim only")
    setting = AutopilotSetting(
        kind=args.autopilot, mode=args.px4_mode, setpoint=args.setpoint, speed=args.px4_speed,
        px4_dir=args.px4,
    )  # fmt: skip
    if setting.kind == "px4":
        config = Px4FlyConfig(mode=setting.mode, setpoint=setting.setpoint, speed=setting.speed)
        r = fly_px4(scenario, out, setting.px4_dir, config)
    else:
        r = fly_emulator(scenario, out, setting)
    err = r.get("touchdown_error_m")
    err_txt = "-" if err is None else f"{err:.3f} m"
    lockstep: dict[str, Any] = next(
        (e for e in (r.get("sitl") or {}).get("events") or [] if e.get("kind") == "px4_lockstep"), {}
    )
    pace = f" at {lockstep.get('sim_s_per_wall_s')} x real time" if lockstep else ""
    reason = f" ({r.get('outcome_reason')})" if r["outcome"] == "error" else ""
    print(
        f"{setting.kind} {r['preset']} seed {r['seed']} ({setting.mode}): {r['outcome']}{reason}, touchdown "
        f"error {err_txt}, {r.get('simulated_time_s') or 0.0:.1f} s simulated{pace} -> {out / 'report.html'}"
    )
    return 0
