"""alight's world as PX4's simulator, without PX4: every message decoded back with pymavlink (fields,
units, frames), the motors driven by PX4's outputs, the accelerometer feeling the ground, and the
lockstep against a fake PX4 client that connects to the TCP port and answers HIL_SENSOR with
HIL_ACTUATOR_CONTROLS as PX4 v1.16.0 does."""

from __future__ import annotations

import math
import socket
import threading
import time
from typing import Any

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as mavlink
from tests.interfaces.tests_interfaces_ports import free_port_pair

from alight.evaluation.runner import world_for_scenario
from alight.interfaces import frames
from alight.interfaces.camera_source import SocketCameraSource
from alight.interfaces.px4_airframe import hover_command
from alight.interfaces.px4_sim import (
    SIM_PORT_BASE,
    Px4Sensors,
    Px4SimConfig,
    Px4Simulator,
    Px4World,
    magnetic_field_ned_gauss,
    pressure_hPa,
)
from alight.scenario import Scenario
from alight.sim.quadrotor import SL_P, SL_Q, SL_W, initial_state
from alight.types import Outcome, quat_to_rotmat


class _Capture:
    """pymavlink's output file: keeps the bytes, decodes them back."""

    def __init__(self) -> None:
        self.data = bytearray()
        self.mav = mavlink.MAVLink(self, srcSystem=1, srcComponent=25)

    def write(self, b: bytes) -> None:
        self.data += b

    def messages(self) -> list[Any]:
        rx = mavlink.MAVLink(None)
        out = rx.parse_buffer(bytes(self.data)) or []
        self.data.clear()
        return out


def _world(**extra: Any) -> Px4World:
    s = Scenario.model_validate({"preset": "groundtruth", "duration_s": 3.0, "seed": 4, **extra})
    return Px4World(world_for_scenario(s))


def test_hil_sensor_at_rest_on_the_ground_reads_gravity_field_and_pressure() -> None:
    w = _world()
    cap = _Capture()
    imu = w.step()  # standing on the ground, motors off: the feet hold the weight
    Px4Sensors(w, 4).hil_sensor(cap.mav, 5000, imu)
    (msg,) = cap.messages()
    assert msg.get_type() == "HIL_SENSOR" and msg.time_usec == 5000 and msg.id == 0
    assert msg.fields_updated == 0x1BFF
    # specific force FRD at rest, level: (0, 0, -g), the contact force felt (IMU noise and bias ~0.1)
    assert [msg.xacc, msg.yacc, msg.zacc] == pytest.approx([0.0, 0.0, -9.81], abs=0.2)
    assert [msg.xgyro, msg.ygyro, msg.zgyro] == pytest.approx([0.0, 0.0, 0.0], abs=0.02)
    # alight's yaw 0 faces east (ENU x): body x = east, body y (right) = south, body z = down
    m_ned = magnetic_field_ned_gauss()
    assert [msg.xmag, msg.ymag, msg.zmag] == pytest.approx([m_ned[1], -m_ned[0], m_ned[2]], abs=0.005)
    assert np.linalg.norm([msg.xmag, msg.ymag, msg.zmag]) == pytest.approx(0.4824, abs=0.005)
    assert msg.abs_pressure == pytest.approx(pressure_hPa(488.0 + w.x[2]), abs=0.05)
    # the ISA table: 1013.25 hPa at sea level, 954.61 hPa at 500 m, 898.76 hPa at 1000 m
    isa = [pressure_hPa(h) for h in (0.0, 500.0, 1000.0)]
    assert isa == pytest.approx([1013.25, 954.61, 898.76], abs=0.02)


def test_magnetic_field_matches_declination_and_inclination() -> None:
    n, e, d = magnetic_field_ned_gauss()
    assert math.degrees(math.atan2(e, n)) == pytest.approx(3.41)
    assert math.degrees(math.atan2(d, math.hypot(n, e))) == pytest.approx(63.16)


def test_hil_gps_distance_sensor_and_ground_truth_fields() -> None:
    w = _world()
    cap = _Capture()
    w.x = initial_state(np.array([3.0, 4.0, 2.5]), yaw=0.3)
    w.x[3:6] = [1.0, -2.0, 0.5]  # v_WB ENU
    sensors = Px4Sensors(w, 4)
    sensors.hil_gps(cap.mav, 100_000)
    sensors.distance_sensor(cap.mav, 100)
    sensors.ground_truth(cap.mav, 100_000)
    gps, rng, truth = cap.messages()
    assert gps.get_type() == "HIL_GPS" and gps.fix_type == 3 and gps.satellites_visible == 12
    east, north = sensors.geo.to_east_north(gps.lat * 1e-7, gps.lon * 1e-7)
    assert (east, north) == pytest.approx((3.0, 4.0), abs=0.1)
    assert gps.alt == pytest.approx((488.0 + 2.5) * 1000.0, abs=100)  # mm AMSL
    assert [gps.vn, gps.ve, gps.vd] == pytest.approx([-200, 100, -50], abs=8)  # cm/s NED
    assert gps.eph == 30 and gps.epv == 40  # cm
    assert gps.cog == pytest.approx(math.degrees(math.atan2(100, -200)) * 100, abs=300)
    assert rng.get_type() == "DISTANCE_SENSOR" and rng.orientation == mavlink.MAV_SENSOR_ROTATION_PITCH_270
    assert rng.current_distance == pytest.approx(100 * (2.5 - w.airframe.gear_height), abs=10)  # cm
    assert rng.min_distance == 20 and rng.max_distance == 1400
    q = np.array(truth.attitude_quaternion)
    R = frames.rotmat_ned_frd_to_enu_flu(_R_of_wxyz(q))
    assert R == pytest.approx(quat_to_rotmat(w.x[SL_Q]), abs=1e-6)
    assert [truth.vx, truth.vy, truth.vz] == [-200, 100, -50]


def _R_of_wxyz(q: np.ndarray) -> np.ndarray:
    return quat_to_rotmat(np.array([q[1], q[2], q[3], q[0]]))


def test_motors_follow_px4_outputs_hover_and_yaw() -> None:
    w = _world(duration_s=4.0)
    w.x = initial_state(np.array([0.0, 0.0, 3.0]), motor_thrust_N=w.airframe.weight_N / 4)
    w.airborne = True
    u = hover_command(w.airframe)
    controls = np.zeros(16)
    controls[:4] = u
    w.apply_controls(controls, armed=True)
    for _ in range(100):
        w.step()
    assert w.x[2] == pytest.approx(3.0, abs=0.02)  # held: 0.5 s at PX4's hover command
    controls[:2] += 0.02  # Motors 1 and 2 spin counter-clockwise: the body yaws clockwise (FRD +z)
    controls[2:4] -= 0.02
    w.apply_controls(controls, armed=True)
    for _ in range(40):
        w.step()
    w_frd = frames.flu_to_frd(w.x[SL_W])
    assert w_frd[2] > 0.05 and abs(w_frd[0]) < 0.01 and abs(w_frd[1]) < 0.01
    w.apply_controls(controls, armed=False)  # disarmed: the rotors stop
    for _ in range(40):
        w.step()
    assert w.x[5] < -0.5 and not w.motors_on and w.t_motors_off is not None


class FakePx4:
    """A PX4 stand-in on the simulator's TCP port: sends PX4's HEARTBEAT, answers each HIL_SENSOR with
    a HIL_ACTUATOR_CONTROLS of the same ``time_usec`` from the ``first_answer``-th on (PX4 starts its
    modules first), with ``controls``; ``pause_after`` steps it stops answering for ``pause_s``."""

    def __init__(
        self, port: int, *, first_answer: int = 20, stop_after: int | None = None, arm_at: int | None = 1
    ) -> None:
        self.port, self.first_answer, self.stop_after = port, first_answer, stop_after
        self.arm_at = arm_at  # armed from this HIL_SENSOR on (the companion's arming); None: never
        self.times: list[int] = []
        self.gaps: list[float] = []
        self.controls = np.zeros(16)
        self.armed = False
        self.pause_at: int | None = None
        self.pause_s = 0.0
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        deadline = time.monotonic() + 60.0
        while True:
            try:
                sock = socket.create_connection(("127.0.0.1", self.port), timeout=1.0)
                break
            except OSError:
                if time.monotonic() > deadline:
                    return
                time.sleep(0.02)
        sock.settimeout(60.0)  # the simulator warms its kernels up before its first step
        tx = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
        rx = mavlink.MAVLink(None)
        sock.sendall(tx.heartbeat_encode(mavlink.MAV_TYPE_GENERIC, 12, 0, 0, 0).pack(tx))
        last = time.monotonic()
        with sock:
            while self.stop_after is None or len(self.times) < self.stop_after:
                try:
                    data = sock.recv(65536)
                except OSError:
                    return
                if not data:
                    return
                for msg in rx.parse_buffer(data) or []:
                    if msg.get_type() != "HIL_SENSOR" or msg.id != 0:
                        continue
                    now = time.monotonic()
                    self.gaps.append(now - last)
                    last = now
                    self.times.append(msg.time_usec)
                    if len(self.times) == self.pause_at:
                        time.sleep(self.pause_s)
                    if self.arm_at is not None and len(self.times) >= self.arm_at:
                        self.armed = True
                    if len(self.times) >= self.first_answer:
                        mode = 129 if self.armed else 1
                        reply = tx.hil_actuator_controls_encode(msg.time_usec, list(self.controls), mode, 1)
                        sock.sendall(reply.pack(tx))


def _simulator(duration_s: float, **config: Any) -> tuple[Px4Simulator, int]:
    s = Scenario.model_validate({"preset": "groundtruth", "duration_s": duration_s, "seed": 1})
    port = free_port_pair()
    instance = port - SIM_PORT_BASE
    return Px4Simulator(s, Px4SimConfig(instance=instance, speed=0.0, **config)), port


def _fly(sim: Px4Simulator, with_companion: bool = True) -> tuple[dict[str, Any], SocketCameraSource | None]:
    cam = SocketCameraSource("127.0.0.1", sim.camera_port) if with_companion else None
    try:
        result = sim.run()
        sim.send_outcome(result)
    finally:
        sim.close()
    return result, cam


def test_lockstep_with_a_fake_px4() -> None:
    # PX4 answers from its 20th step and is armed (by the companion) at its 60th: the world stands still
    # for those 60 steps (0.3 s of PX4's clock), then the 2 s mission runs, 400 steps more
    sim, port = _simulator(2.0, lockstep_timeout_s=5.0)
    px4 = FakePx4(port, first_answer=20, arm_at=60)
    px4.pause_at, px4.pause_s = 200, 0.4  # PX4 busy for 0.4 s: the simulator must wait, not run on
    result, cam = _fly(sim)
    px4.thread.join(5.0)
    t = np.array(px4.times)
    assert t.size == 460 and np.all(np.diff(t) == 5000) and t[0] == 5000  # 200 Hz, strictly increasing
    assert px4.gaps[200] > 0.35  # the step after the pause came only once PX4 had answered
    stats = next(e for e in result["sitl_events"] if e["kind"] == "px4_lockstep")
    assert stats["steps"] == 460 and stats["actuator_messages"] == 441
    assert stats["first_actuator_t_s"] == pytest.approx(0.1)
    assert result["px4_boot_s"] == pytest.approx(0.3) and result["simulated_time_s"] == pytest.approx(2.0)
    start = next(e for e in result["sitl_events"] if e["kind"] == "mission_start")
    assert start["t"] == 0.0 and start["t_px4"] == pytest.approx(0.3)
    assert result["outcome"] == Outcome.TIMEOUT.value  # armed but never flown: the mission's time ran out
    assert result["sitl_flavour"] == "px4-sitl"
    assert cam is not None
    deadline = time.monotonic() + 5.0
    while cam.result is None and time.monotonic() < deadline:
        cam.poll()
        time.sleep(0.01)
    assert cam.scenario is not None and cam.result is not None and cam.result["outcome"] == "timeout"
    assert cam.truth_log is not None and cam.truth_log["t"][-1] == pytest.approx(2.3)  # PX4's clock
    cam.close()


def test_the_world_waits_at_rest_for_px4_to_be_armed() -> None:
    # while PX4 is not armed the platform stays where it is at t = 0 and the vehicle feels gravity through
    # its feet; a PX4 that is never armed ends as an error with the reason, after arm_timeout_s of its clock
    sim, port = _simulator(20.0, arm_timeout_s=0.5)
    p0 = sim.world.truths.p_WP[0].copy()
    FakePx4(port, first_answer=5, arm_at=None)
    result, cam = _fly(sim)
    assert cam is not None
    cam.close()
    assert result["outcome"] == "error" and "not armed within 0.5 s" in result["outcome_reason"]
    assert sim.world.t == 0.0 and sim.world.k == 0 and result["px4_boot_s"] is None
    np.testing.assert_array_equal(sim.world.truths.p_WP[sim.world.k], p0)
    imu = sim._imu_at_rest()
    assert imu[2] == pytest.approx(9.81, abs=0.3) and np.abs(imu[3:6]).max() < 0.05


def test_px4_that_exits_ends_the_mission_as_error() -> None:
    sim, port = _simulator(20.0, lockstep_timeout_s=5.0)
    FakePx4(port, first_answer=5, stop_after=50)
    t0 = time.monotonic()
    result, cam = _fly(sim)
    assert cam is not None
    cam.close()
    assert result["outcome"] == "error" and "closed" in result["outcome_reason"]
    # armed in its first answer (step 5), which the simulator reads at that step or a few later
    # (before the first answer it does not wait for one); gone after its 50th step: the mission is the
    # rest of the 0.25 s of PX4's clock
    boot = result["px4_boot_s"]
    assert 0.025 <= boot <= 0.1 and time.monotonic() - t0 < 30
    assert result["simulated_time_s"] + boot == pytest.approx(0.25, abs=0.011)


def test_px4_that_hangs_ends_the_mission_as_error() -> None:
    sim, port = _simulator(20.0, lockstep_timeout_s=0.5)
    px4 = FakePx4(port, first_answer=5)
    px4.pause_at, px4.pause_s = 30, 3.0
    result, cam = _fly(sim)
    assert result["outcome"] == "error" and "stopped answering" in result["outcome_reason"]
    assert cam is not None
    cam.close()


def test_px4_that_never_connects_and_no_companion() -> None:
    sim, _ = _simulator(5.0, connect_timeout_s=0.3)
    result, _cam = _fly(sim, with_companion=False)
    assert result["outcome"] == "error" and "did not connect" in result["outcome_reason"]
    sim, port = _simulator(5.0, companion_timeout_s=0.3)
    FakePx4(port)
    result, _cam = _fly(sim, with_companion=False)
    assert result["outcome"] == "error" and "companion" in result["outcome_reason"]


def test_armed_outputs_lift_the_vehicle_off() -> None:
    sim, port = _simulator(3.0)
    px4 = FakePx4(port, first_answer=1)
    px4.armed = True
    px4.controls[:4] = 0.75  # above PX4's hover command of the F450 (0.54): it climbs
    result, cam = _fly(sim)
    assert sim.world.x[SL_P][2] > 1.0 and sim.world.airborne
    assert any(e["kind"] == "armed" for e in result["sitl_events"])
    assert cam is not None
    cam.close()
