"""Client conformance: ``alight sitl`` flown by clients nobody here wrote, from PyPI: MAVSDK-Python (the
native C++ MAVSDK inside it), MAVProxy (as a subprocess with scripted commands) and pymavlink's own
connection helpers, against both emulator flavours. Each connects, reads the telemetry a ground station
waits for, reads and sets parameters, downloads the (empty) mission, arms, takes off, flies (offboard
and goto), is refused a disarm in the air, lands on the parked pad with its land command and is found
disarmed on the ground. The emulator runs at 8x real time (no lockstep peer: its ``speed`` paces it), so
each client's flight takes a few seconds of wall time. MAVSDK's script also flies stock PX4 SITL with
alight's world as its simulator, where a build is found (``ALIGHT_PX4_DIR``, docs/px4.md), and must pass
there unchanged but for the waits (PX4 runs at real time)."""

from __future__ import annotations

import contextlib
import math
import os
import re
import shutil
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

os.environ.setdefault("MAVLINK20", "1")
from tests_interfaces_ports import free_port_pair  # noqa: E402

from alight.interfaces.sitl import EmulatedAutopilot, SitlConfig, serve  # noqa: E402
from alight.interfaces.sitl_protocol import Geodetic  # noqa: E402
from alight.scenario import Scenario  # noqa: E402

PAD_EN = (3.0, 2.0)  # the parked platform's centre (east, north), m
SPEED = 8.0
FLAVOURS = ["px4", "ardupilot"]


def _scenario() -> Scenario:
    return Scenario.model_validate(
        {
            "preset": "groundtruth",
            "duration_s": 400.0,
            "seed": 5,
            "platform": {"path": "straight", "speed_mps": 0.0, "start_xy": list(PAD_EN), "heading_rad": 0.0},
        }
    )


@dataclass
class Emulator:
    port: int
    thread: threading.Thread
    result: dict[str, Any] = field(default_factory=dict)
    error: list[BaseException] = field(default_factory=list)
    ap: list[EmulatedAutopilot] = field(default_factory=list)


@pytest.fixture
def emulator(request: pytest.FixtureRequest) -> Iterator[Callable[..., Emulator]]:
    started: list[Emulator] = []

    def start(flavour: str, speed: float = SPEED) -> Emulator:
        port = free_port_pair()
        config = SitlConfig(
            port=port, flavour=flavour, lockstep=False, speed=speed, linger_s=3.0, wait_for_peer_s=60.0
        )  # type: ignore[arg-type]
        emu = Emulator(port, threading.Thread(daemon=True))

        def run() -> None:
            try:
                emu.result.update(serve(_scenario(), config))
            except BaseException as err:  # noqa: BLE001 - reported by the test
                emu.error.append(err)

        emu.thread = threading.Thread(target=run, daemon=True)
        emu.thread.start()
        started.append(emu)
        return emu

    yield start
    for emu in started:
        emu.thread.join(timeout=60)


def wait_for(what: str, check: Callable[[], bool], timeout_s: float = 20.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if check():
            return
        time.sleep(0.02)
    raise AssertionError(f"timed out waiting for {what}")


def finish(emu: Emulator) -> dict[str, Any]:
    emu.thread.join(timeout=60)
    assert not emu.error, emu.error
    assert emu.result, "the emulator returned no result"
    return emu.result


# -- MAVSDK --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Pace:
    """How long the client waits for the autopilot (wall s): the emulator runs at 8x real time, PX4 SITL
    at real time."""

    move_s: float = 4.0
    wait_s: float = 20.0


def mavsdk_flight(url: str, flavour: str, pace: Pace = Pace()) -> list[str]:
    """MAVSDK flies the autopilot at ``url`` (module docstring); returns what differs from the
    emulator's conventions (empty where everything is as asserted)."""
    mavsdk = pytest.importorskip("mavsdk")
    from mavsdk.plugins.action import Action, ActionError
    from mavsdk.plugins.mission_raw import MissionRaw
    from mavsdk.plugins.offboard import Offboard, PositionNedYaw
    from mavsdk.plugins.param import Param
    from mavsdk.plugins.telemetry import FlightMode, LandedState, Telemetry

    gcs = mavsdk.Configuration.create_with_component_type(mavsdk.ComponentType.GROUND_STATION)
    drone = mavsdk.Mavsdk(gcs)
    try:
        drone.add_any_connection(url)
        system = drone.first_autopilot(30.0)
        assert system is not None
        tel, action, param = Telemetry(system), Action(system), Param(system)
        offboard, mission = Offboard(system), MissionRaw(system)

        # the telemetry a ground station waits for
        def has_fix() -> bool:
            pos, home, gps = tel.position(), tel.home(), tel.gps_info()
            located = math.isfinite(pos.latitude_deg) and math.isfinite(home.latitude_deg)
            return located and gps.num_satellites > 0

        wait_for("position, home and GPS", has_fix, pace.wait_s)
        geo = Geodetic()
        assert tel.home().latitude_deg == pytest.approx(geo.lat0_deg, abs=1e-6)
        assert tel.home().absolute_altitude_m == pytest.approx(geo.alt0_m, abs=0.5)
        wait_for("attitude", lambda: math.isfinite(tel.attitude_euler().yaw_deg))
        wait_for("battery", lambda: tel.battery().id == 0)
        assert tel.landed_state() == LandedState.ON_GROUND and not tel.armed()

        # parameters: read, set, read back, list; the (empty) mission
        loss = "COM_OF_LOSS_T" if flavour == "px4" else "GUID_TIMEOUT"
        assert param.get_param_float(loss) == pytest.approx(1.0 if flavour == "px4" else 3.0)
        param.set_param_float(loss, 2.0)
        assert param.get_param_float(loss) == pytest.approx(2.0)
        names = {p.name for p in param.get_all_params().float_params} | {
            p.name for p in param.get_all_params().int_params
        }
        assert loss in names and len(names) >= 4
        assert mission.download_mission() == []

        # arm, take off, fly offboard
        action.set_takeoff_altitude(3.0)
        action.arm()
        action.takeoff()
        wait_for("take-off", lambda: tel.position().relative_altitude_m > 2.7, pace.wait_s)
        # PX4 holds in AUTO.LOITER after AUTO.TAKEOFF; ArduCopter stays in GUIDED (MAVSDK: "offboard")
        after_takeoff = FlightMode.HOLD if flavour == "px4" else FlightMode.OFFBOARD
        wait_for("the mode after take-off", lambda: tel.flight_mode() == after_takeoff, pace.wait_s)
        with pytest.raises(ActionError):  # a disarm in the air is refused (its unused params are NaN)
            action.disarm()
        goal = PositionNedYaw(1.0, -1.0, -3.0, 90.0)
        for _ in range(10):  # a setpoint stream before the switch (1 s of it, as PX4 advises)
            offboard.set_position_ned(goal)
            time.sleep(0.05)
        offboard.start()
        wait_for("offboard", lambda: tel.flight_mode() == FlightMode.OFFBOARD)
        deadline = time.monotonic() + pace.move_s
        while time.monotonic() < deadline:  # a stream, as offboard needs (MAVSDK re-sends it itself too)
            offboard.set_position_ned(goal)
            pv = tel.position_velocity_ned().position
            if math.dist((pv.north_m, pv.east_m, pv.down_m), (1.0, -1.0, -3.0)) < 0.15:
                break
            time.sleep(0.02)
        pv = tel.position_velocity_ned().position
        assert math.dist((pv.north_m, pv.east_m, pv.down_m), (1.0, -1.0, -3.0)) < 0.15
        assert tel.heading().heading_deg == pytest.approx(90.0, abs=3.0)
        offboard.stop()

        # return to launch is taken (then interrupted by a goto, a COMMAND_INT, above the pad)
        action.return_to_launch()
        wait_for("RTL mode", lambda: tel.flight_mode() == FlightMode.RETURN_TO_LAUNCH)
        lat, lon = geo.to_lat_lon(*PAD_EN)
        action.goto_location(lat, lon, geo.alt0_m + 3.0, 0.0)

        def over_pad() -> bool:
            p = tel.position()
            east, north = geo.to_east_north(p.latitude_deg, p.longitude_deg)
            return math.dist((east, north), PAD_EN) < 0.2 and abs(p.relative_altitude_m - 3.0) < 0.3

        wait_for("goto over the pad", over_pad, pace.wait_s)
        action.land()
        wait_for("landed and disarmed", lambda: not tel.armed(), timeout_s=max(30.0, pace.wait_s))
        assert tel.landed_state() == LandedState.ON_GROUND
        action.disarm()  # already disarmed: accepted
    finally:
        drone.destroy()
    return []


@pytest.mark.slow
@pytest.mark.parametrize("flavour", FLAVOURS)
def test_mavsdk_flies_the_emulator(flavour: str, emulator: Callable[..., Emulator]) -> None:
    pytest.importorskip("mavsdk")
    emu = emulator(flavour)
    mavsdk_flight(f"udpout://127.0.0.1:{emu.port}", flavour)
    result = finish(emu)
    assert result["outcome"] == "landed" and result["contact_surface"] == "pad", result["outcome_reason"]
    events = result["sitl_events"]
    assert [e for e in events if e["event"] == "param"][0]["value"] == pytest.approx(2.0)
    assert not [e for e in events if e["event"] == "bad_message"]


@pytest.mark.slow
def test_mavsdk_flies_real_px4_as_it_flies_the_emulator(tmp_path: Path) -> None:
    # the same client script against stock PX4 SITL with alight's world as its simulator (docs/px4.md);
    # skipped where no build is found (no package registry ships one)
    pytest.importorskip("mavsdk")
    from alight.interfaces.px4_run import find_px4_build

    try:
        build = find_px4_build(None)
    except Exception as err:  # noqa: BLE001 - the reason is the skip's
        pytest.skip(f"no PX4 SITL build: {err}")
    with px4_with_world(build, _scenario(), tmp_path) as (instance, verdict):
        mavsdk_flight(f"udpin://127.0.0.1:{14540 + instance}", "px4", Pace(move_s=20.0, wait_s=90.0))
        result = verdict()  # the world ends once the vehicle has stood on the pad for contact.settle_s
    assert result["outcome"] == "landed" and result["contact_surface"] == "pad", result["outcome_reason"]


@contextlib.contextmanager
def px4_with_world(
    build: Any, scenario: Scenario, workdir: Path
) -> Iterator[tuple[int, Callable[[], dict[str, Any]]]]:
    """Stock PX4 on a claimed instance, alight's world as its simulator in a thread, a companion's camera
    stream held open (the world waits for one) that receives the verdict; yields the instance and a
    function that waits for the world's verdict."""
    from alight.airframes import load_airframe
    from alight.interfaces.camera_source import SocketCameraSource
    from alight.interfaces.px4_airframe import px4_environment
    from alight.interfaces.px4_run import claim_instance, start_px4, stop_process
    from alight.interfaces.px4_sim import Px4SimConfig, Px4Simulator

    instance, lock = claim_instance()
    sim = Px4Simulator(scenario, Px4SimConfig(instance=instance))
    out: dict[str, Any] = {}
    world = threading.Thread(target=lambda: out.update(sim.run()), daemon=True)
    world.start()
    cam = SocketCameraSource("127.0.0.1", sim.camera_port)
    px4 = start_px4(build, instance, workdir / "px4", px4_environment(load_airframe(scenario.airframe)))

    def verdict() -> dict[str, Any]:
        world.join(timeout=120.0)
        assert out, "the world returned no verdict"
        return out

    try:
        yield instance, verdict
    finally:
        stop_process(px4)
        world.join(timeout=30.0)
        cam.close()
        sim.close()
        lock.close()


# -- MAVProxy --------------------------------------------------------------------------------------------
class MavProxy:
    """MAVProxy as a subprocess (its own console, commands on stdin), and what it prints."""

    def __init__(self, port: int, state_dir: str) -> None:
        exe = shutil.which("mavproxy.py", path=os.path.dirname(sys.executable)) or "mavproxy.py"
        self.proc = subprocess.Popen(
            [sys.executable, exe, f"--master=udpout:127.0.0.1:{port}", "--nowait",
             f"--state-basedir={state_dir}", "--default-modules=param,wp,mode,arm,cmdlong,misc"],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1,
        )  # fmt: skip
        self.lines: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append(line.rstrip("\n"))

    def send(self, command: str) -> int:
        """Type ``command``; returns the output line count before it (for :meth:`expect`)."""
        n = len(self.lines)
        assert self.proc.stdin is not None
        self.proc.stdin.write(command + "\n")
        self.proc.stdin.flush()
        return n

    def expect(self, pattern: str, since: int = 0, timeout_s: float = 20.0) -> re.Match[str]:
        deadline = time.monotonic() + timeout_s
        rx = re.compile(pattern)
        while time.monotonic() < deadline:
            for line in self.lines[since:]:
                if m := rx.search(line):
                    return m
            time.sleep(0.05)
        tail = "\n".join(self.lines[-30:])
        raise AssertionError(f"MAVProxy never printed {pattern!r}; its last lines:\n{tail}")

    def command(self, command: str, pattern: str, timeout_s: float = 30.0) -> re.Match[str]:
        """Type ``command`` until MAVProxy prints ``pattern`` (every 3 s, as a ground station retries: on
        a loaded machine MAVProxy's socket buffer may overflow and lose a reply; every command used here
        may be repeated)."""
        deadline = time.monotonic() + timeout_s
        while True:
            try:
                return self.expect(pattern, self.send(command), min(3.0, deadline - time.monotonic()))
            except AssertionError:
                if time.monotonic() >= deadline:
                    raise

    def global_position(self) -> dict[str, float]:
        m = self.command("status GLOBAL_POSITION_INT", r"GLOBAL_POSITION_INT \{(.*)\}")
        return {k.strip(): float(v) for k, v in (kv.split(":") for kv in m.group(1).split(","))}

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self._reader.join(timeout=5)
        for f in (self.proc.stdin, self.proc.stdout):
            if f is not None:
                f.close()


@pytest.mark.slow
@pytest.mark.parametrize("flavour", FLAVOURS)
def test_mavproxy_flies_the_emulator(flavour: str, emulator: Callable[..., Emulator], tmp_path: Path) -> None:
    pytest.importorskip("MAVProxy")
    emu = emulator(flavour, 4.0)  # MAVProxy is Python: at 4x it reads everything even on a loaded machine
    mp = MavProxy(emu.port, str(tmp_path))
    geo = Geodetic()
    try:
        # on connecting it downloads the parameters by itself
        n_params = 5 if flavour == "px4" else 4
        mp.expect(rf"Received {n_params} parameters", timeout_s=30.0)
        mp.command("wp list", r"Requesting 0 waypoints")
        loss = "COM_OF_LOSS_T" if flavour == "px4" else "GUID_TIMEOUT"

        def param_set() -> bool:
            mp.send(f"param set {loss} 2")
            time.sleep(0.5)
            return mp.command(f"param show {loss}", rf"{loss}\s+\S+").group(0).split()[-1] == "2.0"

        wait_for("the parameter set", param_set, timeout_s=30.0)
        # take off: PX4 with NAV_TAKEOFF at an altitude AMSL, ArduCopter in GUIDED to a height above home
        if flavour == "px4":
            mp.command("arm throttle", r"COMPONENT_ARM_DISARM: ACCEPTED")
            mp.command(
                f"long MAV_CMD_NAV_TAKEOFF 0 0 0 nan nan nan {geo.alt0_m + 3.2}", r"NAV_TAKEOFF: ACCEPTED"
            )
        else:
            mp.command("mode GUIDED", r"DO_SET_MODE: ACCEPTED")
            mp.command("arm throttle", r"COMPONENT_ARM_DISARM: ACCEPTED")
            mp.command("takeoff 3", r"NAV_TAKEOFF: ACCEPTED")
        wait_for("take-off", lambda: mp.global_position()["relative_alt"] > 2700)
        mp.command("disarm", r"COMPONENT_ARM_DISARM: DENIED")  # in the air, not forced
        # (MAVProxy's "mode" command fails on PX4's two-part modes: PX4 gets the MAVLink commands)
        if flavour == "px4":
            mp.command("long MAV_CMD_NAV_RETURN_TO_LAUNCH", r"NAV_RETURN_TO_LAUNCH: ACCEPTED")
        else:
            mp.command("mode RTL", r"DO_SET_MODE: ACCEPTED")
        mp.expect(r"Mode RTL")
        lat, lon = (round(c * 1e7) for c in geo.to_lat_lon(*PAD_EN))
        mp.command(f"command_int GLOBAL MAV_CMD_DO_REPOSITION 0 0 -1 1 0 nan {lat} {lon} {geo.alt0_m + 3.0}",
                   r"DO_REPOSITION: ACCEPTED")  # fmt: skip

        def over_pad() -> bool:
            g = mp.global_position()
            east, north = geo.to_east_north(g["lat"] * 1e-7, g["lon"] * 1e-7)
            return math.dist((east, north), PAD_EN) < 0.2

        wait_for("goto over the pad", over_pad)
        if flavour == "px4":
            mp.command("long MAV_CMD_NAV_LAND 0 0 0 nan nan nan nan", r"NAV_LAND: ACCEPTED")
        else:
            mp.command("mode LAND", r"DO_SET_MODE: ACCEPTED")
        mp.expect(r"DISARMED", timeout_s=30.0)
    finally:
        mp.close()
    result = finish(emu)
    assert result["outcome"] == "landed" and result["contact_surface"] == "pad", result["outcome_reason"]


# -- pymavlink -------------------------------------------------------------------------------------------
def _ack(conn: Any, command: int, timeout_s: float = 10.0) -> int:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        msg = conn.recv_match(type="COMMAND_ACK", blocking=True, timeout=0.5)
        if msg is not None and msg.command == command:
            return int(msg.result)
    raise AssertionError(f"no COMMAND_ACK for {command}")


def _long(conn: Any, command: int, *params: float) -> int:
    p = list(params) + [math.nan] * (7 - len(params))  # unused parameters NaN, as MAVSDK sends them
    conn.mav.command_long_send(conn.target_system, conn.target_component, command, 0, *p)
    return _ack(conn, command)


def _int(conn: Any, command: int, frame: int, *params: float, x: int = 0, y: int = 0, z: float = 0.0) -> int:
    p = list(params) + [math.nan] * (4 - len(params))
    conn.mav.command_int_send(conn.target_system, conn.target_component, frame, command, 0, 0, *p, x, y, z)
    return _ack(conn, command)


def _wait_msg(conn: Any, kind: str, check: Callable[[Any], bool], timeout_s: float = 20.0) -> Any:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        msg = conn.recv_match(type=kind, blocking=True, timeout=0.5)
        if msg is not None and check(msg):
            return msg
    raise AssertionError(f"no {kind} as expected")


@pytest.mark.slow
@pytest.mark.parametrize("flavour", FLAVOURS)
def test_pymavlink_flies_the_emulator(flavour: str, emulator: Callable[..., Emulator]) -> None:
    from pymavlink import mavutil
    from pymavlink.dialects.v20 import common as mavlink

    emu = emulator(flavour)
    conn = mavutil.mavlink_connection(f"udpout:127.0.0.1:{emu.port}", source_system=255, source_component=190)
    geo = Geodetic()
    ok = mavlink.MAV_RESULT_ACCEPTED
    try:
        deadline = time.monotonic() + 60.0  # a ground station's 1 Hz heartbeat until the autopilot answers
        while time.monotonic() < deadline:
            conn.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            if conn.wait_heartbeat(timeout=1.0) is not None:
                break
        assert conn.target_system == 1, "no HEARTBEAT from the emulator"
        # requests: the version and its capabilities, a command it does not have, a message it does not send
        assert _long(conn, mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION) == ok
        version = _wait_msg(conn, "AUTOPILOT_VERSION", lambda m: True)
        assert version.capabilities & mavlink.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
        assert _long(conn, mavlink.MAV_CMD_DO_SET_SERVO, 1, 1500) == mavlink.MAV_RESULT_UNSUPPORTED
        assert _long(conn, mavlink.MAV_CMD_REQUEST_MESSAGE, 9999) == mavlink.MAV_RESULT_UNSUPPORTED
        # the parameters and the mission
        conn.param_fetch_all()
        n = 5 if flavour == "px4" else 4
        _wait_msg(conn, "PARAM_VALUE", lambda m: len(conn.params) >= n and m.param_count == n)
        name = "MIS_TAKEOFF_ALT" if flavour == "px4" else "GUID_TIMEOUT"
        conn.param_set_send(name, 3.0, mavlink.MAV_PARAM_TYPE_REAL32)
        _wait_msg(conn, "PARAM_VALUE", lambda m: m.param_id == name and m.param_value == 3.0)
        conn.waypoint_request_list_send()
        assert _wait_msg(conn, "MISSION_COUNT", lambda m: True).count == 0
        # take off (PX4: AUTO.TAKEOFF to MIS_TAKEOFF_ALT, set above; ArduCopter: GUIDED and NAV_TAKEOFF)
        if flavour == "px4":
            assert _long(conn, mavlink.MAV_CMD_DO_SET_MODE, 1, 4, 2) == ok  # AUTO.TAKEOFF
            assert _long(conn, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == ok
        else:
            conn.set_mode("GUIDED")
            assert _ack(conn, mavlink.MAV_CMD_DO_SET_MODE) == ok
            assert _long(conn, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == ok
            assert _long(conn, mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, 3.0) == ok
        _wait_msg(conn, "GLOBAL_POSITION_INT", lambda m: m.relative_alt > 2700)
        assert _long(conn, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0) == mavlink.MAV_RESULT_DENIED  # in the air
        # COMMAND_INT: return to launch, then goto above the pad (degE7), then land there
        assert _int(conn, mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH, mavlink.MAV_FRAME_GLOBAL) == ok
        lat, lon = (round(c * 1e7) for c in geo.to_lat_lon(*PAD_EN))
        frame = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
        assert _int(conn, mavlink.MAV_CMD_DO_REPOSITION, frame, -1, 1, 0, math.nan, x=lat, y=lon, z=3.0) == ok

        def over_pad(m: Any) -> bool:
            east, north = geo.to_east_north(m.lat * 1e-7, m.lon * 1e-7)
            return math.dist((east, north), PAD_EN) < 0.2 and abs(m.relative_alt - 3000) < 300

        _wait_msg(conn, "GLOBAL_POSITION_INT", over_pad)
        assert _int(conn, mavlink.MAV_CMD_NAV_LAND, mavlink.MAV_FRAME_GLOBAL, x=lat, y=lon, z=math.nan) == ok
        _wait_msg(conn, "HEARTBEAT", lambda m: not m.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
        landed = mavlink.MAV_LANDED_STATE_ON_GROUND
        _wait_msg(conn, "EXTENDED_SYS_STATE", lambda m: m.landed_state == landed)
    finally:
        conn.close()
    result = finish(emu)
    assert result["outcome"] == "landed" and result["contact_surface"] == "pad", result["outcome_reason"]
