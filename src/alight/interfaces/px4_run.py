"""``alight fly SCENARIO --autopilot px4 --px4 DIR``: a mission with the user's PX4 SITL build as autopilot.

Three processes meet on loopback:

1. **the world** (:class:`alight.interfaces.px4_sim.Px4Simulator`, in a child process): listens on TCP
   ``4560 + instance`` for PX4 and on a free TCP port for the companion's camera stream;
2. **PX4** (``DIR/bin/px4 -d -i INSTANCE -w WORKDIR DIR/etc``, with ``PX4_SIM_MODEL`` and the airframe's
   parameters of :func:`alight.interfaces.px4_airframe.px4_environment`): the unmodified flight stack,
   its clock driven by the world's sensor messages (lockstep);
3. **the companion** (this process): the pipeline through the MAVLink bridge
   (:func:`alight.interfaces.bridge_run.run_bridge`) on PX4's offboard link (PX4 sends to UDP
   ``14540 + instance``), which writes ``result.json``, the log and the report as ``alight fly`` does,
   with the world's verdict and ground truth.

PX4 binds fixed ports shifted by its instance number (TCP 4560 as a client; UDP 14540, 14550, 14580,
18570, 14280, 13030, 14030, 13280 + instance): the first instance whose ports are all free is taken, so
several missions (a campaign's workers) can fly side by side. PX4's working directory (parameters, ULog
logs) and console output are kept in ``OUT/px4/``.

A PX4 that does not start, stops answering or exits ends the mission as ``error`` with its reason (the
world's bounded waits, :class:`~alight.interfaces.px4_sim.Px4SimConfig`); PX4 is stopped by its process
id (SIGINT, then SIGKILL) whatever happens.
"""

from __future__ import annotations

import contextlib
import fcntl
import multiprocessing
import os
import signal
import socket
import subprocess
import tempfile
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import IO, Any, Literal

from alight.airframe import Airframe
from alight.errors import ConfigError
from alight.evaluation.mission_io import write_result
from alight.interfaces.bridge_run import run_bridge
from alight.interfaces.mavlink_bridge import BridgeConfig
from alight.interfaces.px4_airframe import px4_airframe_for, px4_environment, px4_parameters
from alight.interfaces.px4_sim import SIM_PORT_BASE, Px4SimConfig, Px4Simulator, check_px4_scenario
from alight.scenario import Scenario

PX4_DIR_ENV = "ALIGHT_PX4_DIR"
PX4_UDP_PORTS = (14540, 14550, 14580, 18570, 14280, 13030, 14030, 13280)
"""The UDP ports PX4 SITL instance 0 uses (its MAVLink links and their peers); instance i adds i."""
MAX_INSTANCES = 100
SIMULATOR_READY_S = 120.0
"""The world's process must be listening within this (wall s): building the world loads its kernels."""


@dataclass(frozen=True)
class Px4Build:
    """A PX4-Autopilot SITL build directory: ``bin/px4`` and the ``etc`` start-up files beside it."""

    root: Path

    @property
    def binary(self) -> Path:
        return self.root / "bin" / "px4"

    @property
    def etc(self) -> Path:
        return self.root / "etc"


def find_px4_build(path: str | None) -> Px4Build:
    """The build at ``path`` (else ``$ALIGHT_PX4_DIR``): a build directory with ``bin/px4`` (e.g.
    ``PX4-Autopilot/build/px4_sitl_default``), or a PX4-Autopilot checkout with one ``build/px4_sitl*``."""
    raw = path or os.environ.get(PX4_DIR_ENV)
    if not raw:
        raise ConfigError(
            f"px4: give --px4 DIR (a PX4 SITL build with bin/px4) or set {PX4_DIR_ENV} (docs/px4.md)"
        )
    base = Path(raw).expanduser()
    candidates = [base, *sorted(base.glob("build/px4_sitl*"))]
    for cand in candidates:
        build = Px4Build(cand)
        if (
            build.binary.is_file()
            and os.access(build.binary, os.X_OK)
            and (build.etc / "init.d-posix").is_dir()
        ):
            return build
    raise ConfigError(f"px4: {base} has no PX4 SITL build (bin/px4 and etc/init.d-posix); see docs/px4.md")


def _port_free(kind: int, port: int) -> bool:
    with socket.socket(socket.AF_INET, kind) as s:
        try:
            s.bind(("0.0.0.0", port))  # PX4 binds every address
        except OSError:
            return False
    return True


def free_instance(first: int = 0) -> int:
    """The first PX4 instance number from ``first`` on whose ports are all free."""
    for i in range(first, first + MAX_INSTANCES):
        if _instance_ports_free(i):
            return i
    raise ConfigError(f"px4: no free PX4 instance among {first}..{first + MAX_INSTANCES - 1} (ports in use)")


def _instance_ports_free(i: int) -> bool:
    return _port_free(socket.SOCK_STREAM, SIM_PORT_BASE + i) and all(
        _port_free(socket.SOCK_DGRAM, p + i) for p in PX4_UDP_PORTS
    )


def instance_lock_path(instance: int) -> Path:
    return Path(tempfile.gettempdir()) / f"alight-px4-instance-{instance}.lock"


def claim_instance(first: int = 0, wanted: int | None = None) -> tuple[int, IO[str]]:
    """A PX4 instance number for this mission and its lock, held until the returned file is closed.

    Free ports alone do not make an instance this mission's: between the check and the binds (the
    world's TCP port, PX4's UDP ports, seconds later) a campaign's other worker would see the same ports
    free and take the same number. Each mission therefore takes an exclusive ``flock`` on
    :func:`instance_lock_path` first (released by the kernel if the process dies), then checks the ports
    (another program may hold them). ``wanted``: that instance only, refused in one line if taken."""
    numbers = [wanted] if wanted is not None else list(range(first, first + MAX_INSTANCES))
    for i in numbers:
        f = instance_lock_path(i).open("a")
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            f.close()
            continue
        if _instance_ports_free(i):
            return i, f
        f.close()
    if wanted is not None:
        raise ConfigError(f"px4: instance {wanted} is in use (another mission or program holds its ports)")
    raise ConfigError(f"px4: no free PX4 instance among {first}..{first + MAX_INSTANCES - 1} (ports in use)")


def _serve(
    scenario_json: dict[str, Any], config: Px4SimConfig, ready: Any, camera_port: Any, linger_s: float
) -> None:
    """The world's process: listen (the camera stream on a port the kernel picks, so no other process
    can take it between a check and the bind), tell the parent the port, fly, send the verdict, linger,
    close."""
    sim = Px4Simulator(Scenario.model_validate(scenario_json), config)
    camera_port.value = sim.camera_port
    ready.set()
    try:
        result = sim.run()
        sim.send_outcome(result)
        end = time.monotonic() + linger_s
        while time.monotonic() < end and sim.frames.connected:
            sim.link.receive(0.05)  # keep PX4 frozen but connected while the companion reads the verdict
    finally:
        sim.close()


def _die_with_parent() -> None:
    """In PX4's child before exec: the kernel kills PX4 when this process dies (Linux's
    ``PR_SET_PDEATHSIG``). PX4 runs in a session of its own, so that a terminal's Ctrl-C reaches the
    companion, which then stops PX4 itself; but a campaign kills a sandbox that overran its time with
    SIGKILL, and PX4 must not outlive it holding its instance's ports."""
    import ctypes

    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG = 1


def start_px4(
    build: Px4Build, instance: int, workdir: Path, env_extra: dict[str, str]
) -> subprocess.Popen[bytes]:
    """PX4 SITL as a daemon (``-d``: no shell) in ``workdir``, its console into ``workdir/px4.log``."""
    workdir.mkdir(parents=True, exist_ok=True)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PX4_SIMULATOR", "PX4_SYS_AUTOSTART"))}
    env.update(env_extra)
    log = (workdir / "px4.log").open("wb")
    cmd = [str(build.binary), "-d", "-i", str(instance), "-w", str(workdir), str(build.etc)]
    try:
        return subprocess.Popen(
            cmd, cwd=workdir, env=env, stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
            start_new_session=True, preexec_fn=_die_with_parent,
        )  # fmt: skip
    except OSError as err:
        raise ConfigError(f"px4: cannot start {build.binary} ({err.strerror})") from None
    finally:
        log.close()


def stop_process(proc: subprocess.Popen[bytes], grace_s: float = 5.0) -> int | None:
    """Stop ``proc`` and its process group (SIGINT, then SIGKILL after ``grace_s``); its exit code, or
    None when even SIGKILL has not ended it within 30 s (a machine loaded beyond that; never raises,
    so that the mission's result is still written)."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(grace_s)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(OSError):
                os.killpg(proc.pid, signal.SIGKILL)  # PX4 leads a session of its own (start_px4)
            proc.kill()
            try:
                proc.wait(30.0)
            except subprocess.TimeoutExpired:
                return None
    return proc.returncode


@dataclass(frozen=True, kw_only=True)
class Px4FlyConfig:
    """How ``alight fly --autopilot px4`` flies."""

    mode: Literal["offboard", "landing-target"] = "offboard"
    setpoint: Literal["rates", "position"] = "position"
    """``position``: PX4's own position and attitude controllers fly the pipeline's reference."""
    speed: float = 1.0
    """Simulated seconds per wall second at most (0: as fast as it goes; PX4's timeouts count sim time,
    the companion's heartbeat wall time)."""
    instance: int | None = None
    """PX4's instance number (None: the first free one)."""
    connect_timeout_s: float = 60.0
    """PX4 must connect to the world within this (wall s) after it is started."""


def fly_px4(scenario: Scenario, out: str | Path, px4_dir: str | None, config: Px4FlyConfig) -> dict[str, Any]:
    """Fly ``scenario`` with the PX4 SITL build at ``px4_dir`` (module docstring); writes ``out`` as
    ``alight fly`` does and returns the result (with a ``px4`` record: build, instance, airframe
    mapping, PX4's exit code)."""
    from alight.airframes import load_airframe

    build = find_px4_build(px4_dir)
    check_px4_scenario(scenario)
    px4_frame = px4_airframe_for(scenario.airframe)
    airframe = load_airframe(scenario.airframe)
    out = Path(out)
    instance, lock = claim_instance(wanted=config.instance)
    try:
        result = _fly_on_instance(scenario, out, build, airframe, instance, config)
    finally:
        lock.close()
    result["px4"]["airframe"] = {"alight": scenario.airframe, **asdict(px4_frame)}
    write_result(out, result)
    return result


def _fly_on_instance(
    scenario: Scenario, out: Path, build: Px4Build, airframe: Airframe, instance: int, config: Px4FlyConfig
) -> dict[str, Any]:
    """The mission on PX4 instance ``instance`` (held by the caller): the world, PX4, the bridge."""
    sim_config = Px4SimConfig(instance=instance, camera_port=0, speed=config.speed,
                              connect_timeout_s=config.connect_timeout_s)  # fmt: skip
    takeoff_m = _takeoff_altitude_m(scenario, config)
    env = px4_environment(airframe, takeoff_altitude_m=takeoff_m)
    if config.speed > 0 and config.speed != 1.0:
        env["PX4_SIM_SPEED_FACTOR"] = f"{config.speed:g}"  # rcS scales PX4's link-loss timeouts by it
    ctx = multiprocessing.get_context("spawn")
    ready, camera_port = ctx.Event(), ctx.Value("i", 0)
    world = ctx.Process(
        target=_serve, args=(scenario.model_dump(mode="json"), sim_config, ready, camera_port, 10.0)
    )
    world.start()
    px4: subprocess.Popen[bytes] | None = None
    try:
        if not ready.wait(SIMULATOR_READY_S):
            raise ConfigError(f"px4: the world's process was not listening within {SIMULATOR_READY_S:g} s")
        px4 = start_px4(build, instance, out / "px4", env)
        bridge = BridgeConfig(mode=config.mode, autopilot="px4", setpoint=config.setpoint, arm=True)
        result = run_bridge(
            f"udpin:127.0.0.1:{PX4_UDP_PORTS[0] + instance}", out, bridge,
            camera=f"tcp:127.0.0.1:{camera_port.value}", max_wall_s=_max_wall_s(scenario, config),
        )  # fmt: skip
    finally:
        code = None if px4 is None else stop_process(px4)
        world.join(15.0)
        if world.is_alive():
            world.terminate()
            world.join(5.0)
    result["px4"] = {
        "build": str(build.root), "instance": instance, "exit_code": code,
        "parameters": px4_parameters(airframe, takeoff_altitude_m=takeoff_m),
        "config": asdict(replace(config, instance=instance)), "console_log": str(out / "px4" / "px4.log"),
    }  # fmt: skip
    return result


def _takeoff_altitude_m(scenario: Scenario, config: Px4FlyConfig) -> float | None:
    """PX4's take-off height (``MIS_TAKEOFF_ALT``) for this mission: in ``landing-target`` mode PX4's own
    take-off climbs and the camera must see the platform from there, so it is :func:`search_height_m`,
    as a user would set it (PX4's default 2.5 m never saw the platform, docs/px4.md). Offboard: None (the
    pipeline flies its own climb)."""
    return search_height_m(scenario) if config.mode == "landing-target" else None


def search_height_m(scenario: Scenario) -> float:
    """The height from which ``scenario``'s preset searches for the platform: its take-off height
    (``mission.explore_altitude_m`` unless ``mission.takeoff_altitude_m``), m above the take-off point."""
    import numpy as np

    from alight.airframes import load_airframe
    from alight.mission.presets import build_preset

    preset = build_preset(scenario, load_airframe(scenario.airframe), np.random.default_rng(0))
    c = preset.pipeline.mission.config
    return float(c.explore_altitude_m if c.takeoff_altitude_m is None else c.takeoff_altitude_m)


def _max_wall_s(scenario: Scenario, config: Px4FlyConfig) -> float:
    """The companion's wall-clock bound: the mission at the slower of its speed and 1/5 of real time,
    plus the start-up, so that nothing keeps a campaign waiting for ever."""
    speed = config.speed if config.speed > 0 else 1.0
    return scenario.duration_s / min(speed, 1.0) * 5.0 + 600.0
