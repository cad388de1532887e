"""The emulated autopilot: mode numbers, its position controller in closed loop on the simulator, and the
offboard rules over a real loopback MAVLink link (stream before OFFBOARD, COM_OF_LOSS_T failsafe)."""

from __future__ import annotations

import math
import os
import select
import threading
import time
from typing import Any

import numpy as np
import pytest

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402
from pymavlink.dialects.v20 import common as mavlink  # noqa: E402
from tests_interfaces_ports import free_port_pair  # noqa: E402

from alight.airframe import DEFAULT_AIRFRAME  # noqa: E402
from alight.airframes import load_airframe  # noqa: E402
from alight.errors import InputError  # noqa: E402
from alight.evaluation.runner import world_for_scenario  # noqa: E402
from alight.interfaces import frames  # noqa: E402
from alight.interfaces.camera_source import SocketCameraSource  # noqa: E402
from alight.interfaces.sitl import (  # noqa: E402
    EmulatedAutopilot,
    FlightMode,
    SitlConfig,
    decode_mode,
    encode_mode,
    position_control,
)
from alight.scenario import Scenario  # noqa: E402
from alight.sim.quadrotor import IX_F, SL_P, SL_Q, SL_V  # noqa: E402
from alight.sim.world import World  # noqa: E402
from alight.types import quat_to_rotmat  # noqa: E402


@pytest.mark.parametrize("flavour", ["px4", "ardupilot"])
def test_mode_numbers_round_trip(flavour: str) -> None:
    for mode in FlightMode:
        decoded = decode_mode(flavour, encode_mode(flavour, mode))
        expected = {FlightMode.TAKEOFF: FlightMode.OFFBOARD, FlightMode.LAND: FlightMode.PRECLAND}
        assert decoded is (expected.get(mode, mode) if flavour == "ardupilot" else mode)
    if flavour == "px4":  # px4_custom_mode.h: main in bits 16-23, sub in bits 24-31
        assert encode_mode("px4", FlightMode.OFFBOARD) == 6 << 16
        assert encode_mode("px4", FlightMode.PRECLAND) == (4 << 16) | (9 << 24)
    else:
        assert (
            encode_mode("ardupilot", FlightMode.OFFBOARD) == 4
            and encode_mode("ardupilot", FlightMode.LAND) == 9
        )


def test_position_controller_takes_off_and_holds_a_point() -> None:
    scenario = Scenario.model_validate({"preset": "groundtruth", "duration_s": 10.0, "seed": 2})
    world = world_for_scenario(scenario)
    goal = np.array([1.0, -1.0, 3.0])
    for k in range(8 * 200):
        if k % 2 == 0:
            x = world.x
            thrust, w = position_control(
                x[SL_P], x[SL_V], quat_to_rotmat(x[SL_Q]), p_ref=goal, v_ref=None, a_ref=None, yaw_ref=0.3,
                airframe=DEFAULT_AIRFRAME,
            )  # fmt: skip
            world.set_command(thrust, w, True)
        world.step()
    x = world.x
    assert np.linalg.norm(x[SL_P] - goal) < 0.1 and np.linalg.norm(x[SL_V]) < 0.1
    R = quat_to_rotmat(x[SL_Q])
    assert math.atan2(R[1, 0], R[0, 0]) == pytest.approx(0.3, abs=0.02)
    assert world.contact is None


class Client:
    """A scripted companion on the loopback link."""

    def __init__(self, port: int) -> None:
        self.conn = mavutil.mavlink_connection(
            f"udpout:127.0.0.1:{port}", source_system=1, source_component=191, dialect="common"
        )
        self.acks: list[tuple[int, int]] = []
        self.heartbeats: list[Any] = []
        self.texts: list[str] = []

    def drain(self) -> None:
        while True:
            msg = self.conn.recv_match(blocking=False)
            if msg is None:  # a datagram without a whole message; stop only when the socket is empty
                if select.select([self.conn.port], [], [], 0)[0]:
                    continue
                return
            kind = msg.get_type()
            if kind == "COMMAND_ACK":
                self.acks.append((msg.command, msg.result))
            elif kind == "HEARTBEAT":
                self.heartbeats.append(msg)
            elif kind == "STATUSTEXT":
                self.texts.append(msg.text)

    def command(self, command: int, *params: float) -> int:
        """Send a COMMAND_LONG and wait for its ACK's result."""
        n = len(self.acks)
        p = list(params) + [0.0] * (7 - len(params))
        self.conn.mav.command_long_send(1, 1, command, 0, *p)
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline:
            self.drain()
            for c, r in self.acks[n:]:
                if c == command:
                    return r
            time.sleep(0.005)
        raise AssertionError(f"no COMMAND_ACK for {command}")

    def hold_setpoint(self) -> None:
        self.conn.mav.set_position_target_local_ned_send(
            0, 1, 1, mavlink.MAV_FRAME_LOCAL_NED, 2552, 0.0, 0.0, -2.0, 0, 0, 0, 0, 0, 0, math.pi / 2, 0
        )


def test_offboard_rules_and_loss_failsafe_within_com_of_loss_t() -> None:
    port = free_port_pair()
    scenario = Scenario.model_validate({"preset": "groundtruth", "duration_s": 7.0, "seed": 0})
    ap = EmulatedAutopilot(scenario, SitlConfig(port=port, lockstep=False, speed=1.0))
    result: dict[str, Any] = {}
    thread = threading.Thread(target=lambda: result.update(ap.run()), daemon=True)
    thread.start()
    client = Client(port)
    try:
        client.conn.mav.heartbeat_send(18, 8, 0, 0, 0)
        time.sleep(0.2)
        # OFFBOARD is refused without a setpoint stream
        assert client.command(176, 1, 6, 0) == mavlink.MAV_RESULT_TEMPORARILY_REJECTED
        t0 = time.monotonic()
        while time.monotonic() - t0 < 1.3:
            client.hold_setpoint()
            client.drain()
            time.sleep(0.02)
        # accepted once the stream has lasted > 1 s of simulated time (which may lag the wall clock on a
        # loaded machine, or while the compiled kernels load)
        accepted = mavlink.MAV_RESULT_ACCEPTED
        while (r := client.command(176, 1, 6, 0)) != accepted and time.monotonic() - t0 < 10:
            assert r == mavlink.MAV_RESULT_TEMPORARILY_REJECTED
            for _ in range(10):
                client.hold_setpoint()
                time.sleep(0.02)
        assert r == mavlink.MAV_RESULT_ACCEPTED
        assert client.command(400, 1) == mavlink.MAV_RESULT_ACCEPTED
        t0 = time.monotonic()
        while time.monotonic() - t0 < 2.5:  # fly up to the setpoint, then stop the stream
            client.hold_setpoint()
            client.drain()
            if time.monotonic() - t0 > 0.5:
                client.conn.mav.heartbeat_send(18, 8, 0, 0, 0)
            time.sleep(0.02)
        while thread.is_alive():  # the simulated clock may lag the wall clock on a loaded machine
            client.drain()
            time.sleep(0.01)
    finally:
        thread.join(timeout=30)
        ap.close()
        client.conn.close()
    assert result["outcome"] == "timeout"  # nobody landed it; it did not crash
    failsafe = [e for e in ap.events if e["event"] == "failsafe"]
    assert len(failsafe) == 1
    gap = failsafe[0]["t"] - failsafe[0]["last_setpoint_t"]
    assert 1.0 - 1e-6 <= gap <= 1.0 + 0.0101  # COM_OF_LOSS_T, checked every 10 ms (times rounded to 1 us)
    modes = [e for e in ap.events if e["event"] == "mode"]
    assert modes[-1]["mode"] == "hold" and modes[-1]["t"] == failsafe[0]["t"]
    assert any("Offboard lost" in t for t in client.texts), (
        client.texts,
        len(client.heartbeats),
        client.acks,
    )
    # It was flying when the stream stopped, and the failsafe hold kept it in the air, near where it was.
    log = ap.truth_arrays()
    k = int(np.searchsorted(log["t"], failsafe[0]["t"]))
    assert log["p_WB"][k, 2] > 1.0
    assert np.linalg.norm(log["p_WB"][-1] - log["p_WB"][k]) < 0.5


def test_a_companion_on_the_camera_stream_has_the_warm_up_allowance_for_its_heartbeat() -> None:
    # alight bridge opens the camera stream (to read the scenario), then compiles its kernels before its
    # first HEARTBEAT. Scaled down: 0.3 s for a companion that has not shown itself, 1.5 s once it has.
    scenario = Scenario.model_validate({"preset": "groundtruth", "duration_s": 2.0, "seed": 0})
    config = {"lockstep": False, "wait_for_peer_s": 0.3, "wait_for_warm_up_s": 1.5}
    port = free_port_pair()
    ap = EmulatedAutopilot(scenario, SitlConfig(port=port, **config))
    try:
        t0 = time.monotonic()
        with pytest.raises(InputError, match=r"no companion HEARTBEAT on udp 127\.0\.0\.1:\d+ within 0\.3 s"):
            ap._wait_for_peer()
        assert time.monotonic() - t0 < 10.0  # the short wait, not the allowance
        cam = SocketCameraSource("127.0.0.1", port + 1)
        client = Client(port)
        beat = threading.Timer(0.8, lambda: client.conn.mav.heartbeat_send(18, 8, 0, 0, 0))
        beat.start()
        t0 = time.monotonic()
        ap._wait_for_peer()  # the HEARTBEAT comes after 0.8 s: past 0.3 s, inside the allowance
        assert ap.peer_seen and time.monotonic() - t0 >= 0.8
        beat.join()
        cam.close()
        client.conn.close()
    finally:
        ap.close()
    port = free_port_pair()
    ap = EmulatedAutopilot(scenario, SitlConfig(port=port, **config))
    cam = SocketCameraSource("127.0.0.1", port + 1)
    try:
        t0 = time.monotonic()
        with pytest.raises(InputError, match="camera stream but sent no HEARTBEAT .* within 1.5 s"):
            ap._wait_for_peer()
        assert time.monotonic() - t0 >= 1.5
    finally:
        cam.close()
        ap.close()


def test_a_companion_that_closes_the_camera_stream_loses_its_allowance() -> None:
    # A bridge that dies while it compiles closes the camera stream: the emulator stops waiting for it
    # (0.3 s, the ordinary wait, from the moment it left) instead of keeping the 30 s allowance.
    scenario = Scenario.model_validate({"preset": "groundtruth", "duration_s": 2.0, "seed": 0})
    port = free_port_pair()
    ap = EmulatedAutopilot(
        scenario, SitlConfig(port=port, lockstep=False, wait_for_peer_s=0.3, wait_for_warm_up_s=30.0)
    )
    cam = SocketCameraSource("127.0.0.1", port + 1)
    closer = threading.Timer(0.6, cam.close)
    closer.start()
    try:
        t0 = time.monotonic()
        with pytest.raises(InputError, match=r"within 0\.3 s after a companion closed the camera stream"):
            ap._wait_for_peer()
        assert 0.6 + 0.3 <= time.monotonic() - t0 < 10.0
    finally:
        closer.join()
        cam.close()
        ap.close()


def test_ardupilot_guided_stops_after_guid_timeout_and_stays_guided() -> None:
    port = free_port_pair()
    scenario = Scenario.model_validate({"preset": "groundtruth", "duration_s": 7.0, "seed": 0})
    ap = EmulatedAutopilot(scenario, SitlConfig(port=port, lockstep=False, flavour="ardupilot", speed=1.0))
    thread = threading.Thread(target=ap.run, daemon=True)
    thread.start()
    client = Client(port)
    try:
        client.conn.mav.heartbeat_send(18, 8, 0, 0, 0)
        time.sleep(0.2)
        assert client.command(176, 1, 4) == mavlink.MAV_RESULT_ACCEPTED  # GUIDED needs no stream first
        assert client.command(400, 1) == mavlink.MAV_RESULT_ACCEPTED
        t0 = time.monotonic()
        while time.monotonic() - t0 < 2.0:
            client.hold_setpoint()
            client.drain()
            time.sleep(0.02)
        while thread.is_alive():
            client.drain()
            time.sleep(0.01)
    finally:
        thread.join(timeout=30)
        ap.close()
        client.conn.close()
    # (a stop before the first setpoint may or may not be seen, depending on when the stream started)
    stops = [e for e in ap.events if e["event"] == "guided_timeout" and e["last_setpoint_t"] is not None]
    assert len(stops) == 1
    gap = stops[0]["t"] - stops[0]["last_setpoint_t"]
    assert 3.0 - 1e-6 <= gap <= 3.0 + 0.0101  # GUID_TIMEOUT, 3 s by default (event times are rounded to 1 us)
    assert not [e for e in ap.events if e["event"] == "failsafe"] and ap.mode is FlightMode.OFFBOARD
    assert client.heartbeats[-1].custom_mode == 4  # still GUIDED
    log = ap.truth_arrays()
    k = int(np.searchsorted(log["t"], stops[0]["t"]))
    assert log["p_WB"][k, 2] > 1.0 and np.linalg.norm(log["p_WB"][-1] - log["p_WB"][k]) < 0.5


def test_distance_sensor_out_of_range_round_trip() -> None:
    """The range finder's +-inf (ROS REP 117) travel as a reading outside [min_distance, max_distance] with
    signal_quality 1, and the bridge decodes them back; valid readings are clipped into the span."""
    from alight.interfaces.mavlink_bridge import distance_sensor_range_m
    from alight.interfaces.sitl import distance_sensor_fields
    from alight.sim.sensors import RangeFinderConfig

    config = RangeFinderConfig(min_range_m=0.2, max_range_m=14.0)
    mav = mavlink.MAVLink(None, 1, 1)
    cases = [(-math.inf, -math.inf), (math.inf, math.inf), (1.234, 1.23), (0.199, 0.2), (14.004, 14.0)]
    for r, expected in cases:
        lo, hi, cm, quality = distance_sensor_fields(r, config)
        assert (lo, hi) == (20, 1400)
        assert (cm < lo or cm > hi) == (not math.isfinite(r)) and (quality == 1) == (not math.isfinite(r))
        packed = mav.distance_sensor_encode(100, lo, hi, cm, 0, 0, 25, 255, 0.0, 0.0, [0.0] * 4, quality)
        decoded = mav.decode(bytearray(packed.pack(mav)))
        assert distance_sensor_range_m(decoded) == pytest.approx(expected)
    # what other autopilots send: UINT16_MAX is no return
    assert distance_sensor_range_m(mav.distance_sensor_encode(0, 20, 1400, 65535, 0, 0, 25, 0)) == math.inf


def _climb_then(world: World, goal: np.ndarray, seconds: float) -> None:
    for k in range(round(seconds * 200)):
        if k % 2 == 0:
            x = world.x
            thrust, w = position_control(
                x[SL_P], x[SL_V], quat_to_rotmat(x[SL_Q]), p_ref=goal, v_ref=None, a_ref=None, yaw_ref=0.0,
                airframe=world.airframe,
            )  # fmt: skip
            world.set_command(thrust, w, True)
        world.step()


def test_world_cuts_no_motor_and_judges_after_settling() -> None:
    """The contact model holds the vehicle on the ground with its motors running (nothing in the world
    stops them); a descent the failsafe ends on the ground is judged ``aborted`` once settled after the
    disarm; motors stopped in the air end in a judged crash."""
    base = {"preset": "groundtruth", "duration_s": 20.0, "seed": 4, "contact": {"settle_s": 1.0}}
    world = world_for_scenario(Scenario.model_validate(base))
    assert world.airframe == load_airframe("f450")  # the scenario's airframe
    gear = world.airframe.gear_height
    _climb_then(world, np.array([0.0, 0.0, 1.5]), 3.0)
    assert world.airborne and world.contact is None
    world.ground_ok = world.aborting = True  # a failsafe's land: the ground is its safe end
    _climb_then(world, np.array([0.0, 0.0, gear - 0.3]), 4.0)  # pushes into the ground, motors on
    c = world.contact
    assert c is not None and c.surface == "ground" and c.outcome.value == "landed"
    assert world.outcome is None and world.motors_on and float(np.sum(world.x[IX_F : IX_F + 4])) > 1.0
    world.set_command(0.0, np.zeros(3), False)  # the disarm
    t_off = world.t
    while not world.done:
        world.step()
    assert world.t == pytest.approx(t_off + 1.0, abs=0.006)
    assert world.final_outcome.value == "aborted" and world.t_motors_off == t_off

    world = world_for_scenario(Scenario.model_validate(base))
    _climb_then(world, np.array([0.0, 0.0, 3.0]), 3.0)
    world.set_command(0.0, np.zeros(3), False)  # motors off in the air: it falls
    while not world.done:
        world.step()
    assert world.final_outcome.value == "crashed" and world.contact is not None
    assert world.contact.outcome.value == "crashed"


def test_precland_land_detector_disarms_on_the_pad() -> None:
    """PX4 flavour, AUTO.TAKEOFF then AUTO.PRECLAND onto a parked platform fed by LANDING_TARGET: the
    emulator's land detector disarms it on the deck and the run is judged landed after settling."""
    port = free_port_pair()
    scenario = Scenario.model_validate(
        {
            "preset": "groundtruth",
            "duration_s": 40.0,
            "seed": 1,
            "platform": {"path": "straight", "speed_mps": 0.0, "start_xy": [2.0, 1.0], "heading_rad": 0.0},
        }
    )
    ap = EmulatedAutopilot(scenario, SitlConfig(port=port, lockstep=False))
    mav = mavlink.MAVLink(None, 1, 191)

    def command(cmd: int, *params: float) -> None:
        p = list(params) + [0.0] * (7 - len(params))
        ap.handle(mav.decode(bytearray(mav.command_long_encode(1, 1, cmd, 0, *p).pack(mav))))

    try:
        # the companion shows itself first: only the peer's commands act
        ap.handle(mav.decode(bytearray(mav.heartbeat_encode(18, 8, 0, 0, 0).pack(mav))))
        command(176, 1, 4, 2)  # AUTO.TAKEOFF
        command(400, 1)
        w = ap.world
        while w.t < 30.0 and not w.done:
            if ap.mode is FlightMode.HOLD and w.x[SL_P][2] > 2.0:
                command(176, 1, 4, 9)  # AUTO.PRECLAND
            if ap.mode is FlightMode.PRECLAND and w.k % 10 == 0:
                p_ned = frames.enu_to_ned(w.truths.p_WP[w.k])
                msg = mav.landing_target_encode(
                    int(w.t * 1e6), 0, mavlink.MAV_FRAME_LOCAL_NED, 0, 0, 0, 0, 0, *p_ned, [1, 0, 0, 0], 2, 1
                )
                ap.handle(mav.decode(bytearray(msg.pack(mav))))
            ap._control()
            for _ in range(2):
                imu = w.step()
                ap._send_sensors(imu)
                if w.done:
                    break
    finally:
        ap.close()
    kinds = [e["event"] for e in ap.events]
    assert "land_detected" in kinds and not ap.armed
    assert w.contact is not None and w.contact.surface == "pad"
    assert w.final_outcome.value == "landed", (w.outcome_reason, ap.events[-5:])
    assert w.t_motors_off is not None and w.t_motors_off > w.t_contact  # type: ignore[operator]


def test_nan_inf_fields_spoofed_senders_and_every_command_answered() -> None:
    """What killed the emulator or fooled it before: NaN in DISARM's param2 (MAVSDK fills unused params
    with NaN), inf in DO_SET_MODE's param1, a lockstep acknowledgement from a sender that is not the
    peer (it ran the world ahead), a spoof of the peer's ids from another address; and a command it does
    not have gets an ACK (UNSUPPORTED), COMMAND_INT included."""
    scenario = Scenario.model_validate({"preset": "groundtruth", "duration_s": 5.0, "seed": 0})
    ap = EmulatedAutopilot(scenario, SitlConfig(port=0, camera_port=0))
    sent: list[Any] = []
    ap.mav.send = lambda m, force_mavlink1=False: sent.append(m)  # type: ignore[method-assign]
    peer, other = ("127.0.0.1", 40000), ("127.0.0.1", 40001)
    mav = mavlink.MAVLink(None, 1, 191)
    nan, inf = math.nan, math.inf

    def feed(msg: Any, addr: tuple[str, int] = peer) -> list[tuple[int, int]]:
        sent.clear()
        ap.receive(bytes(msg.pack(mav)), addr)
        return [(m.command, m.result) for m in sent if m.get_type() == "COMMAND_ACK"]

    try:
        assert feed(mav.command_long_encode(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0)) == []  # no peer yet
        feed(mav.heartbeat_encode(18, 8, 0, 0, 0))
        assert ap.peer == (peer, 1, 191)
        r = mavlink.MAV_RESULT_ACCEPTED
        assert feed(mav.command_long_encode(1, 1, 400, 0, 0, nan, nan, nan, nan, nan, nan)) == [(400, r)]
        assert feed(mav.command_long_encode(1, 1, 176, 0, inf, 4, 3, nan, nan, nan, nan)) == [
            (176, mavlink.MAV_RESULT_DENIED)
        ]
        unsupported = mavlink.MAV_RESULT_UNSUPPORTED
        assert feed(mav.command_long_encode(1, 1, 31000, 0, nan, nan, nan, nan, nan, nan, nan)) == [
            (31000, unsupported)
        ]
        assert feed(mav.command_int_encode(1, 1, 0, 31001, 0, 0, nan, nan, nan, nan, 0, 0, nan)) == [
            (31001, unsupported)
        ]
        # not the peer: ignored, whatever it claims
        acks_before = ap.ack_t
        feed(mav.named_value_int_encode(60_000, b"LSACK", 0), other)
        assert ap.ack_t == acks_before and not ap.peer_lockstep
        assert feed(mav.command_long_encode(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0), other) == []
        assert not ap.armed and ap.foreign == 3  # (with the command sent before there was a peer)
        # the peer cannot acknowledge a time not yet simulated either
        feed(mav.named_value_int_encode(60_000, b"LSACK", 0))
        assert ap.ack_t < 0.0
        # read-only requests are answered for anyone
        feed(mav.param_request_list_encode(1, 1), other)
        assert [m.get_type() for m in sent].count("PARAM_VALUE") == len(ap.params)
    finally:
        ap.close()


def test_short_fuzz_of_the_emulator_receive_path() -> None:
    """A short run of ``benchmarks/fuzz_mavlink.py --target emulator``: no exit, and senders that are not
    the peer change nothing (the 100,000-datagram run is in docs/interfaces.md)."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "benchmarks" / "fuzz_mavlink.py"
    spec = importlib.util.spec_from_file_location("fuzz_mavlink", path)
    assert spec is not None and spec.loader is not None
    fuzz = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(fuzz)
    r = fuzz.run_emulator(n=2000, seed=3)
    assert r["exits"] == 0, r["exits_by_type"]
    assert r["outcome_changes"] == 0 and r["final_state_equal"]
    assert r["refused_from_non_peers"] > 50 and r["senders"]["spoofed"] > 100
