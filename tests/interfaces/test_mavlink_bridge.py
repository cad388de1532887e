"""The MAVLink bridge against a scripted autopilot (no sockets): the offboard start-up rules, arming only
when allowed, hold on a stalled camera or estimator, a lost link, the output conversions, and a receive
path that drops bad fields."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as mavlink

from alight.airframe import DEFAULT_AIRFRAME
from alight.errors import ConfigError
from alight.interfaces.camera_source import PlatformFix
from alight.interfaces.fake_autopilot import Capture, FakeAutopilot
from alight.interfaces.mavlink_bridge import (
    MASK_P_YAW,
    MASK_RATES_THRUST,
    BridgeConfig,
    MavlinkBridge,
    Phase,
    optical_flow_rad_B,
)
from alight.mission.presets import build_preset
from alight.scenario import load_scenario
from alight.types import Command

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "examples" / "falanga2017_straight.yaml"
MAX_THRUST = DEFAULT_AIRFRAME.thrust_to_weight * DEFAULT_AIRFRAME.weight_N


class FakeCamera:
    clock = "autopilot"

    def __init__(self) -> None:
        self.frames: list[tuple[float, np.ndarray]] = []

    def read(self) -> tuple[float, np.ndarray] | None:
        return self.frames.pop(0) if self.frames else None

    def close(self) -> None:
        pass


def make_bridge(**cfg: Any) -> tuple[MavlinkBridge, Capture, FakeCamera]:
    s = load_scenario(SCENARIO)
    preset = build_preset(s, DEFAULT_AIRFRAME, np.random.default_rng(0))
    cap, cam = Capture(), FakeCamera()
    bridge = MavlinkBridge(preset.pipeline, BridgeConfig(**cfg), link=cap, camera=cam)
    return bridge, cap, cam


def fly(
    bridge: MavlinkBridge,
    cap: Capture,
    cam: FakeCamera,
    ap: FakeAutopilot,
    until_s: float,
    *,
    frames_until_s: float = math.inf,
    heartbeat_until_s: float = math.inf,
    odometry_until_s: float = math.inf,
) -> None:
    """Run the scripted autopilot to ``until_s``; it obeys DO_SET_MODE (OFFBOARD) and arm commands."""
    seen = 0
    blank = np.zeros((480, 752), dtype=np.uint8)
    while ap.t < until_s:
        ap.heartbeat = ap.t < heartbeat_until_s
        ap.odometry = ap.t < odometry_until_s
        data = ap.tick()
        if ap.k % 10 == 0 and ap.t < frames_until_s:
            cam.frames.append((ap.t - 0.02, blank))
        bridge.feed_bytes(data)
        for msg in cap.messages[seen:]:
            if msg.get_type() == "COMMAND_LONG" and msg.command == 176 and msg.param2 == 6:
                ap.offboard(armed=ap.armed)
            if msg.get_type() == "COMMAND_LONG" and msg.command == 400:
                ap.set_armed(msg.param1 == 1.0)
        seen = len(cap.messages)


def commands(cap: Capture, command: int) -> list[Any]:
    return [m for m in cap.of_type("COMMAND_LONG") if m.command == command]


@pytest.mark.parametrize("arm", [False, True])
def test_streams_before_offboard_and_arms_only_when_allowed(arm: bool) -> None:
    bridge, cap, cam = make_bridge(arm=arm)
    ap = FakeAutopilot()
    fly(bridge, cap, cam, ap, 4.0)
    holds = [m for m in cap.of_type("SET_POSITION_TARGET_LOCAL_NED") if m.type_mask == MASK_P_YAW]
    mode_requests = commands(cap, 176)
    assert holds and mode_requests
    t_stream = holds[0].time_boot_ms * 1e-3
    t_mode = next(e["t"] for e in bridge.events if e["event"] == "command" and e["command"] == 176)
    assert t_mode - t_stream >= 1.0  # PX4 wants more than a second of setpoints before OFFBOARD
    times = np.array([m.time_boot_ms for m in holds if m.time_boot_ms * 1e-3 <= t_mode]) * 1e-3
    assert np.max(np.diff(times)) < 0.5  # > 2 Hz
    # the hold is at the vehicle's position (2 m up, NED z = -2)
    assert holds[0].z == pytest.approx(-2.0, abs=0.05) and holds[0].x == pytest.approx(0.0, abs=0.05)
    arms = [m for m in commands(cap, 400) if m.param1 == 1.0]
    if arm:
        assert arms and bridge.phase is Phase.ENGAGED
    else:
        assert not arms and not ap.armed and bridge.phase is Phase.ARM


def test_stalled_camera_sends_hold_within_200_ms() -> None:
    bridge, cap, cam = make_bridge(arm=True)
    ap = FakeAutopilot()
    fly(bridge, cap, cam, ap, 4.0, frames_until_s=3.0)
    assert bridge.phase is Phase.ENGAGED
    last_frame = max(bridge.frame_times)
    rates = cap.of_type("SET_ATTITUDE_TARGET")
    assert rates and min(m.time_boot_ms for m in rates) * 1e-3 < last_frame  # it was flying on rates
    holds_after = [t for t in bridge.hold_times if t > last_frame]
    assert holds_after and holds_after[0] - last_frame <= 0.2
    assert all(m.time_boot_ms * 1e-3 <= holds_after[0] for m in rates)  # no rates once holding


def test_stalled_estimator_sends_hold_within_200_ms() -> None:
    bridge, cap, cam = make_bridge(arm=True)
    ap = FakeAutopilot()
    fly(bridge, cap, cam, ap, 4.0, odometry_until_s=3.0)
    last_odo = 3.0 - 0.025
    holds_after = [t for t in bridge.hold_times if t > 3.0]
    assert bridge.phase is Phase.ENGAGED and holds_after and holds_after[0] - last_odo <= 0.2


def test_lost_link_stops_commanding() -> None:
    bridge, cap, cam = make_bridge(arm=True, link_timeout_s=2.0)
    ap = FakeAutopilot()
    fly(bridge, cap, cam, ap, 7.0, heartbeat_until_s=3.0)
    assert bridge.phase is Phase.LINK_LOST
    t_last_hb = 2.005  # the last heartbeat before 3 s (they go out at k % 200 == 1)
    sent = [m.time_boot_ms * 1e-3 for m in cap.of_type("SET_ATTITUDE_TARGET")]
    sent += [m.time_boot_ms * 1e-3 for m in cap.of_type("SET_POSITION_TARGET_LOCAL_NED")]
    assert max(sent) <= t_last_hb + 2.0 + 0.011


def test_rates_setpoint_is_frd_and_normalised(monkeypatch: pytest.MonkeyPatch) -> None:
    bridge, cap, cam = make_bridge(arm=True)
    pipe = bridge.pipeline
    monkeypatch.setattr(pipe, "command", lambda t: Command(t, 9.81, np.array([0.1, 0.2, 0.3])))
    monkeypatch.setattr(pipe, "step", lambda t: pipe.status)
    ap = FakeAutopilot()
    fly(bridge, cap, cam, ap, 2.5)
    sp = cap.of_type("SET_ATTITUDE_TARGET")[-1]
    assert sp.type_mask == MASK_RATES_THRUST
    assert sp.thrust == pytest.approx(9.81 / MAX_THRUST, rel=1e-6)
    np.testing.assert_allclose(
        [sp.body_roll_rate, sp.body_pitch_rate, sp.body_yaw_rate], [0.1, -0.2, -0.3], rtol=1e-6
    )


def test_receive_path_drops_bad_fields() -> None:
    bridge, cap, cam = make_bridge()
    fed: list[tuple[str, tuple[Any, ...]]] = []
    pipe = bridge.pipeline
    for name in ("on_imu", "on_odometry", "on_range"):
        original = getattr(pipe, name)

        def spy(*args: Any, _name: str = name, _orig: Any = original) -> Any:
            fed.append((_name, args))
            return _orig(*args)

        setattr(pipe, name, spy)
    ap = FakeAutopilot()
    fly(bridge, cap, cam, ap, 0.5)
    n_before = len(fed)
    m = ap.mav
    bad = [
        m.highres_imu_encode(int(0.6e6), math.nan, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 63),
        m.highres_imu_encode(int(0.1e6), 0, 0, -9.81, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 63),  # backwards
        m.highres_imu_encode(int(90e6), 0, 0, -9.81, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 63),  # 90 s jump
        m.highres_imu_encode(int(0.6e6), 1e9, 0, -9.81, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 63),  # beyond 16 g
        m.odometry_encode(
            int(0.6e6), 1, 1, math.inf, 0, 0, [1, 0, 0, 0], 0, 0, 0, 0, 0, 0, [0] * 21, [0] * 21
        ),
        m.odometry_encode(int(0.6e6), 1, 1, 0, 0, 0, [0, 0, 0, 0], 0, 0, 0, 0, 0, 0, [0] * 21, [0] * 21),
        m.odometry_encode(int(0.6e6), 12, 1, 0, 0, 0, [1, 0, 0, 0], 0, 0, 0, 0, 0, 0, [0] * 21, [0] * 21),
        m.distance_sensor_encode(600, 0, 1400, 200, 0, 0, 0, 0),  # facing forward, not down
    ]
    for msg in bad:
        bridge.feed_bytes(ap.encode(msg))
    foreign = FakeAutopilot(sysid=42)
    bridge.feed_bytes(
        foreign.encode(
            foreign.mav.highres_imu_encode(int(0.7e6), 0, 0, -9.81, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 63)
        )
    )
    assert len(fed) == n_before
    assert bridge.stats.rejected["HIGHRES_IMU"] == 4 and bridge.stats.rejected["ODOMETRY"] == 3
    assert bridge.stats.rejected["DISTANCE_SENSOR"] == 1 and bridge.stats.foreign >= 1
    for name, args in fed:
        for a in args:
            if a is not None:
                v = np.asarray(a, dtype=float)
                # a range is +-inf out of range (ROS REP 117, as the sensor reports it), never NaN
                assert not np.any(np.isnan(v)) if name == "on_range" else np.all(np.isfinite(v))


def test_optical_flow_rad_becomes_flow_along_the_flu_body_axes() -> None:
    """MAVLink's integrated_y (around the FRD y axis) is positive for a motion along +x: over the ground
    at 2 m, moving forward at 1 m/s for 20 ms, integrated_y = 0.01 rad; alight's flow along x_B is
    -v_x / d = -0.5 rad/s. A roll (right-hand about x) gives a positive integrated_x; alight's flow along
    y_B is -w_x."""
    mav = FakeAutopilot().mav
    fwd = mav.optical_flow_rad_encode(1_000_000, 0, 20_000, 0.0, 0.01, 0, 0, 0, 0, 255, 0, 2.0)
    np.testing.assert_allclose(optical_flow_rad_B(fwd), [-0.5, 0.0])
    roll = mav.optical_flow_rad_encode(1_000_000, 0, 20_000, 0.004, 0.0, 0, 0, 0, 0, 255, 0, 2.0)
    np.testing.assert_allclose(optical_flow_rad_B(roll), [0.0, -0.2])
    for bad in (
        mav.optical_flow_rad_encode(1_000_000, 0, 20_000, 0.0, 0.01, 0, 0, 0, 0, 0, 0, 2.0),  # quality 0
        mav.optical_flow_rad_encode(1_000_000, 0, 0, 0.0, 0.01, 0, 0, 0, 0, 255, 0, 2.0),  # no integration
        mav.optical_flow_rad_encode(1_000_000, 0, 20_000, math.nan, 0.01, 0, 0, 0, 0, 255, 0, 2.0),
        mav.optical_flow_rad_encode(1_000_000, 0, 20_000, 0.0, 0.01, 0, 0, 0, 0, 255, 0, -1.0),  # no range
        mav.optical_flow_rad_encode(1_000_000, 0, 20_000, 0.0, 5.0, 0, 0, 0, 0, 255, 0, 2.0),  # 250 rad/s
    ):
        assert optical_flow_rad_B(bad) is None


def test_the_bridge_feeds_optical_flow_to_the_pipeline() -> None:
    bridge, cap, cam = make_bridge()
    ap = FakeAutopilot()
    fly(bridge, cap, cam, ap, 0.5)
    pipe = bridge.pipeline
    assert pipe.ego_estimator.initialized and pipe.deck_slip_W is None
    t_us = int(bridge.t_ap * 1e6)
    ok = ap.mav.optical_flow_rad_encode(t_us, 0, 20_000, 0.0, 0.01, 0, 0, 0, 0, 255, 0, 2.0)
    bridge.feed_bytes(ap.encode(ok))
    assert bridge.stats.rejected.get("OPTICAL_FLOW_RAD", 0) == 0
    # hovering level, 2 m up: 0.5 rad/s of flow is 1 m/s forward over the surface (in W, along the heading)
    assert pipe.deck_slip_mps(bridge.t_ap) == pytest.approx(1.0, abs=0.1)
    stale = ap.mav.optical_flow_rad_encode(t_us, 0, 20_000, 0.0, 0.01, 0, 0, 0, 0, 255, 0, 2.0)
    bridge.feed_bytes(ap.encode(stale))  # the same timestamp again
    assert bridge.stats.rejected["OPTICAL_FLOW_RAD"] == 1


def test_short_fuzz_run() -> None:
    spec = importlib.util.spec_from_file_location("fuzz_mavlink", ROOT / "benchmarks" / "fuzz_mavlink.py")
    assert spec is not None and spec.loader is not None
    fuzz = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(fuzz)
    report = fuzz.run(n=1500, seed=5)
    assert report["uncaught_exceptions"] == 0
    assert report["non_finite_inputs"] == 0
    assert report["max_buffer_s"] < 2.0
    assert report["accepted_messages"] > 100  # the valid part of the stream still gets through


def test_cli_reports_an_unopenable_camera_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from alight.cli import main

    missing = tmp_path / "no_such_video.mp4"
    rc = main(
        ["bridge", "--connect", "udp:127.0.0.1:9", "--out", str(tmp_path / "o"), "--camera", str(missing)]
    )
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "cannot open" in err and str(missing) in err


def test_scaled_imu_and_local_position_paths_convert_to_enu_flu() -> None:
    bridge, cap, cam = make_bridge()
    seen: dict[str, list[tuple[Any, ...]]] = {"on_imu": [], "on_odometry": []}
    pipe = bridge.pipeline
    for name in seen:
        original = getattr(pipe, name)

        def spy(*args: Any, _name: str = name, _orig: Any = original) -> Any:
            seen[_name].append(args)
            return _orig(*args)

        setattr(pipe, name, spy)
    ap = FakeAutopilot()
    m = ap.mav
    bridge.feed_bytes(ap.encode(m.heartbeat_encode(2, 12, 1, 3 << 16, 3)))
    for k in range(1, 41):
        t_ms = 5 * k
        bridge.feed_bytes(ap.encode(m.scaled_imu_encode(t_ms, 0, 0, -1000, 10, 0, 0, 0, 0, 0)))
        if k % 5 == 0:  # level, nose north; 1 m north, 2 m east, 3 m up; moving 0.5 m/s north
            bridge.feed_bytes(ap.encode(m.attitude_quaternion_encode(t_ms, 1, 0, 0, 0, 0, 0, 0)))
            bridge.feed_bytes(ap.encode(m.local_position_ned_encode(t_ms, 1.0, 2.0, -3.0, 0.5, 0.0, 0.0)))
    t, p, q, v, reset_counter = seen["on_odometry"][0]
    assert reset_counter is None  # LOCAL_POSITION_NED carries no reset counter
    np.testing.assert_allclose(p, [2.0, 1.0, 3.0])
    np.testing.assert_allclose(v, [0.0, 0.5, 0.0])
    np.testing.assert_allclose(q, [0.0, 0.0, math.sqrt(0.5), math.sqrt(0.5)], atol=1e-12)  # ENU yaw 90 deg
    t, f, w = seen["on_imu"][-1]
    np.testing.assert_allclose(f, [0.0, 0.0, 9.81])  # 1000 mG up in FLU
    np.testing.assert_allclose(w, [0.01, 0.0, 0.0])  # 10 mrad/s roll
    assert pipe.ego_estimator.initialized


@pytest.mark.parametrize("autopilot", ["px4", "ardupilot"])
def test_landing_target_fields(autopilot: str, monkeypatch: pytest.MonkeyPatch) -> None:
    from alight.types import EgoState, PlatformEstimate

    bridge, cap, cam = make_bridge(mode="landing-target", autopilot=autopilot)
    bridge.target_sys, bridge.target_comp = 1, 1
    pipe = bridge.pipeline
    # level, nose east (ENU yaw 0), 4 m up; the pad 1 m ahead (east), 0.5 m up, seen 0.1 s ago
    ego = EgoState(2.0, np.array([0.0, 0.0, 4.0]), np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3))
    est = PlatformEstimate(
        2.0,
        np.array([1.0, 0.0, 0.5]),
        np.zeros(3),
        np.zeros(3),
        0.0,
        np.eye(3) * 0.01,
        t_last_measurement=1.9,
    )
    monkeypatch.setattr(pipe, "ego", lambda: ego)
    monkeypatch.setattr(pipe, "target", lambda t: est)
    bridge._send_landing_target(2.0)
    lt = cap.of_type("LANDING_TARGET")[-1]
    assert lt.time_usec == 2_000_000 and lt.position_valid == 1
    assert lt.angle_x == pytest.approx(0.0, abs=1e-7)
    assert lt.angle_y == pytest.approx(math.atan2(-1.0, 3.5), rel=1e-6)  # ahead: negative (+ is aft)
    assert lt.distance == pytest.approx(math.hypot(1.0, 3.5), rel=1e-6)
    if autopilot == "px4":  # the pad's absolute position in local NED
        assert lt.frame == 1 and (lt.x, lt.y, lt.z) == pytest.approx((0.0, 1.0, -0.5))
    else:  # the vector to the pad in body FRD
        assert lt.frame == 12 and (lt.x, lt.y, lt.z) == pytest.approx((1.0, 0.0, 3.5))


def test_silent_link_is_lost_on_the_wall_clock() -> None:
    # Nothing at all arrives (the autopilot's clock stops too): only the wall clock can tell.
    bridge, cap, cam = make_bridge(link_timeout_s=0.2)
    ap = FakeAutopilot()
    fly(bridge, cap, cam, ap, 0.5)
    assert not bridge.link_lost()
    bridge._t_heartbeat_wall -= 5.0  # as if 5 s had passed without a byte
    bridge._t_any_wall -= 5.0
    assert bridge.link_lost() and bridge.phase is Phase.LINK_LOST
    n = len(cap.messages)
    fly(bridge, cap, cam, ap, 1.0)  # even if traffic resumes, it stays stopped
    assert not [m for m in cap.messages[n:] if m.get_type().startswith("SET_")]


def test_odometry_reset_counter_keeps_the_pipelines_frame() -> None:
    """PX4 (or a VIO) raises ODOMETRY's reset_counter when its frame jumps: the bridge hands it on and
    the pipeline's ego position stays continuous across a 0.5 m jump north."""
    bridge, cap, cam = make_bridge()
    ap = FakeAutopilot()
    m = ap.mav
    bridge.feed_bytes(ap.encode(m.heartbeat_encode(2, 12, 1, 3 << 16, 3)))
    z21 = [0.0] * 21
    heights = []
    for k in range(1, 201):
        t_ms = 5 * k
        bridge.feed_bytes(ap.encode(m.scaled_imu_encode(t_ms, 0, 0, -1000, 0, 0, 0, 0, 0, 0)))
        if k % 5 == 0:  # 40 Hz; level, 3 m up; the frame jumps 0.5 m north at 0.5 s
            jumped = t_ms > 500
            north = 1.0 + (0.5 if jumped else 0.0)
            bridge.feed_bytes(
                ap.encode(
                    m.odometry_encode(
                        t_ms * 1000, 1, 1, north, 2.0, -3.0, [1, 0, 0, 0], 0, 0, 0, 0, 0, 0, z21, z21,
                        int(jumped),
                    )
                )
            )  # fmt: skip
            pipe = bridge.pipeline
            if pipe.ego_estimator.initialized:
                heights.append(pipe.ego().p_WB.copy())
    assert bridge.pipeline.ego_estimator.n_relocalizations == 1
    p = np.array(heights)
    np.testing.assert_allclose(p[:, 1], 1.0, atol=0.02)  # ENU y = north, no jump


def test_a_frame_read_ahead_of_the_autopilots_clock_waits_for_it() -> None:
    # the camera stream is read before the link's queued IMU messages: a frame stamped up to
    # max_time_jump_s after the bridge's clock waits and is used when the clock reaches its stamp; one
    # further ahead, out of order, too old or past the waiting room is refused, counted by its reason
    bridge, cap, cam = make_bridge(arm=True)
    ap = FakeAutopilot()
    fly(bridge, cap, cam, ap, 1.0)
    used0, t0 = bridge.stats.accepted.get("frame", 0), bridge.t_ap
    blank = np.zeros((480, 752), dtype=np.uint8)
    cam.frames += [(t0 + 0.05, blank), (t0 + 0.10, blank), (t0 + 0.10, blank), (t0 + 5.0, blank)]
    bridge._read_camera(t0)
    assert bridge.stats.accepted.get("frame", 0) == used0 and len(bridge._waiting_frames) == 2
    assert bridge.stats.rejected["frame_order"] == 1 and bridge.stats.rejected["frame_ahead"] == 1
    bridge._read_camera(t0 + 0.06)
    assert bridge.stats.accepted["frame"] == used0 + 1 and len(bridge._waiting_frames) == 1
    bridge._read_camera(t0 + 0.2)
    assert bridge.stats.accepted["frame"] == used0 + 2 and not bridge._waiting_frames
    assert bridge.frame_times[-2:] == [t0 + 0.06, t0 + 0.2]
    cam.frames += [(t0 + 0.2 + 0.01 * (i + 1), blank) for i in range(10)] + [(t0 - 3.0, blank)]
    bridge._read_camera(t0 + 0.2)
    assert len(bridge._waiting_frames) == 8 and bridge.stats.rejected["frame_ahead"] == 3
    assert bridge.stats.rejected["frame_late"] == 1
    assert bridge.stats.rejected["frame"] == sum(
        bridge.stats.rejected[k] for k in ("frame_order", "frame_ahead", "frame_late")
    )


def test_the_bridge_asks_the_autopilot_for_its_stream_rates() -> None:
    # PX4's onboard defaults (HIGHRES_IMU 50 Hz, ODOMETRY 30 Hz, DISTANCE_SENSOR 10 Hz) are below the
    # bridge's 100 Hz control: it asks for its rates, with each of the first three HEARTBEATs
    bridge, cap, cam = make_bridge(arm=True)
    fly(bridge, cap, cam, FakeAutopilot(), 6.0)
    asked = commands(cap, 511)  # MAV_CMD_SET_MESSAGE_INTERVAL
    want = {
        int(getattr(mavlink, f"MAVLINK_MSG_ID_{n}")): 1e6 / hz for n, hz in BridgeConfig().stream_rates_hz
    }
    assert len(asked) == 3 * len(want)
    assert {(int(m.param1), m.param2) for m in asked} == set(want.items())
    assert want[int(mavlink.MAVLINK_MSG_ID_HIGHRES_IMU)] == 5000.0
    bridge, cap, cam = make_bridge(arm=True, stream_rates_hz=())
    fly(bridge, cap, cam, FakeAutopilot(), 3.0)
    assert commands(cap, 511) == []
    with pytest.raises(ConfigError, match="stream_rates_hz"):
        BridgeConfig(stream_rates_hz=(("NOT_A_MESSAGE", 10.0),))


def test_with_px4_the_written_times_are_the_missions() -> None:
    # the bridge runs on the autopilot's clock; PX4's world starts the mission at the arming, px4_boot_s
    # into that clock: the log, the mode history and the events are written in the mission's time
    from alight.interfaces.bridge_run import _outputs

    bridge, cap, cam = make_bridge(arm=True)
    fly(bridge, cap, cam, FakeAutopilot(), 3.0)
    s = load_scenario(SCENARIO)
    plain, arrays0, _ = _outputs(s, bridge, bridge.config, {"outcome": "timeout"}, None, 1.0)
    boot = 1.25
    shifted, arrays1, _ = _outputs(
        s, bridge, bridge.config, {"outcome": "timeout", "px4_boot_s": boot}, None, 1.0
    )
    np.testing.assert_allclose(arrays1["t"], arrays0["t"] - boot)
    assert [m["t"] for m in shifted["mode_history"]] == pytest.approx(
        [m["t"] - boot for m in plain["mode_history"]]
    )
    timed = [
        (a["t"], b["t"])
        for a, b in zip(plain["bridge"]["events"], shifted["bridge"]["events"], strict=True)
        if a["t"] is not None
    ]
    assert timed and all(b == pytest.approx(a - boot) for a, b in timed)
    assert shifted["sitl"]["px4_boot_s"] == boot and plain["sitl"]["px4_boot_s"] is None


def test_on_ground_contact_the_pipelines_thrust_flies_also_with_position_setpoints() -> None:
    # the land detector's test of a contact is its thrust spool-down: with PX4's position controller
    # flying it would not happen (the vehicle disarmed 0.2 m above the deck); from ground contact on the
    # bridge sends the pipeline's thrust and rates, and position setpoints again once it lets go
    from alight.mission.touchdown_detector import TouchdownState

    bridge, cap, cam = make_bridge(arm=True, setpoint="position")
    ap = FakeAutopilot()
    fly(bridge, cap, cam, ap, 3.0)
    assert bridge.phase is Phase.ENGAGED
    n_att = len(cap.of_type("SET_ATTITUDE_TARGET"))
    assert n_att == 0 and cap.of_type("SET_POSITION_TARGET_LOCAL_NED")
    bridge.pipeline.touchdown.state = TouchdownState.GROUND_CONTACT
    bridge._control(bridge.t_ap + 0.01)
    assert cap.messages[-1].get_type() == "SET_ATTITUDE_TARGET"
    bridge.pipeline.touchdown.state = TouchdownState.AIRBORNE
    bridge._control(bridge.t_ap + 0.02)
    assert cap.messages[-1].get_type() == "SET_POSITION_TARGET_LOCAL_NED"


def test_platform_fixes_reach_the_estimator_when_the_clock_reaches_their_stamp() -> None:
    # platform.telemetry crosses the camera's stream (a radio of the platform's own): a fix waits for the
    # autopilot's clock, goes to on_telemetry once, in order; a late, repeated or far-ahead one is refused
    bridge, cap, cam = make_bridge(arm=True)
    ap = FakeAutopilot()
    fly(bridge, cap, cam, ap, 1.0)
    got: list[tuple[float, np.ndarray]] = []
    bridge.pipeline.on_telemetry = lambda t, p, v, cov, now=None: got.append((t, p)) or True  # type: ignore[method-assign]
    t0, cov = bridge.t_ap, np.eye(3) * 0.25

    def fix(t: float) -> PlatformFix:
        return PlatformFix(t, np.full(3, t), np.zeros(3), cov)

    bridge._platform_fixes(t0, [fix(t0 - 0.2), fix(t0 + 0.05), fix(t0 + 9.0)])
    assert [t for t, _ in got] == [t0 - 0.2] and np.array_equal(got[0][1], np.full(3, t0 - 0.2))
    assert bridge.stats.rejected["platform_fix_ahead"] == 1 and len(bridge._waiting_fixes) == 1
    bridge._platform_fixes(t0 + 0.06, [fix(t0 - 0.2), fix(t0 - 7.0)])  # repeated; older than 5 s
    assert [t for t, _ in got] == [t0 - 0.2, t0 + 0.05]
    rejected = bridge.stats.rejected
    assert rejected["platform_fix_order"] == 1 and rejected["platform_fix_late"] == 1
    assert bridge.stats.accepted["platform_fix"] == 2 and rejected["platform_fix"] == 3


def test_a_platform_fix_between_the_pipelines_steps_is_fused_not_taken_for_the_future() -> None:
    # the bridge does not step the pipeline while it holds (here: the camera stalls after 3 s) or waits
    # for the arming: a fix seconds after the estimator's last clock would be "from the future"
    # (MeasurementError) unless the estimator's clock is first brought to the bridge's
    bridge, cap, cam = make_bridge(arm=True)
    fly(bridge, cap, cam, FakeAutopilot(), 6.0, frames_until_s=3.0)
    t, pipe = bridge.t_ap, bridge.pipeline
    assert bridge.holding and pipe.fuses_telemetry and pipe.stats.telemetry_fixes == 0
    assert pipe._platform_clock < t - 2.0  # stepped while engaged, not since the stall
    fix = PlatformFix(t - 0.2, np.array([5.0, 0.0, 0.5]), np.array([1.0, 0.0, 0.0]), np.eye(3) * 0.25)
    bridge._platform_fixes(t, [fix])
    assert pipe.stats.telemetry_fixes == 1 and "pipeline" not in bridge.stats.rejected
    target = pipe.target(t)
    assert target is not None and np.linalg.norm(target.p_WP[:2] - [5.2, 0.0]) < 0.5


def test_the_autopilots_land_detector_is_logged_as_it_changes() -> None:
    # what PX4's land detector says on a moving deck (PX4 #14873) is read from the bridge's events
    bridge, cap, cam = make_bridge(arm=True)
    ap = FakeAutopilot()
    fly(bridge, cap, cam, ap, 0.5)
    before = [e for e in bridge.events if e["event"] == "autopilot_landed_state"]
    for state in (2, 2, 4, 1, 1, 9):  # in air, in air, landing, on ground, on ground, not an enum value
        bridge.feed_bytes(ap.encode(ap.mav.extended_sys_state_encode(0, state)))
    said = [e["state"] for e in bridge.events if e["event"] == "autopilot_landed_state"][len(before) :]
    assert said == ["in_air", "landing", "on_ground"] and bridge.was_airborne
