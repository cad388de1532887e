"""An emulated autopilot: alight's simulated world behind a MAVLink endpoint on loopback UDP.

``alight sitl SCENARIO.yaml --port PORT`` runs the scenario's world (the same airframe, quadrotor with its
contact model, rate loop, wind, platform, sensors, faults, renderer and outcome judging as ``alight fly``:
the one :class:`~alight.sim.world.World` that ``run_mission`` steps too) and speaks MAVLink 2
like a PX4 (or, with ``flavour="ardupilot"``, an ArduCopter) flight controller would on its
companion-computer link. ``alight bridge`` connects to it and flies.

The world and the verdict
-------------------------
The feet touch the moving deck and the ground through the simulator's spring-damper contact with
friction; nothing in the world holds the vehicle up or stops its motors. The motors run while the
emulated autopilot is armed, and stop when it disarms: on the companion's MAV_CMD_COMPONENT_ARM_DISARM
(the bridge sends a forced disarm when its pipeline's land detector says landed), or after the
emulator's own land detector in its LAND / PRECLAND modes (below). The verdict is the runner's: the
first contact after take-off is judged (a crash ends the mission at once), a later touchdown after a
bounce is judged again, and ``contact.settle_s`` after the motors stopped the vehicle must still stand
on the pad (``landed``) or it ``crashed``; ``timeout`` when the motors never stopped. A land that the
offboard-loss failsafe started may end on the ground: it scores ``aborted`` when it settles safely.
Faults of the scenario act on what the emulator sends (IMU bias steps, odometry jumps and dropouts in
ODOMETRY / LOCAL_POSITION_NED, range dropouts and spurious returns in DISTANCE_SENSOR, camera frame
loss, blackouts, corruption and latency), drawn from the ninth child of the seed as in the runner.

What it emulates
----------------
* HEARTBEAT both ways (1 Hz; the autopilot's carries ``base_mode`` with the armed flag and the custom
  mode encoded as PX4 does, ``main << 16 | sub << 24``, or ArduCopter's mode number).
* Modes, reported as commanded. PX4: AUTO.LOITER (4/3, "Hold", also after a take-off, a goto or the
  hold failsafe), POSCTL (3), ALTCTL (2), STABILIZED (7) and MANUAL (1) hold position (there is no RC),
  OFFBOARD (6), AUTO.TAKEOFF (4/2), AUTO.LAND (4/6), AUTO.PRECLAND (4/9), AUTO.RTL (4/5: climb to
  ``RTL_RETURN_ALT``, fly home, land there); AUTO.MISSION (4/4) is refused (no mission). ArduCopter:
  STABILIZE (0), ALT_HOLD (2), LOITER (5), POSHOLD (16), BRAKE (17) hold, GUIDED (4) takes setpoints
  and stays GUIDED after its take-off, LAND (9) is a precision land when LANDING_TARGET messages arrive
  (as with ``PLND_ENABLED`` = 1), a plain land otherwise, RTL (6); AUTO (3) is refused.
* Commands, as COMMAND_LONG or COMMAND_INT (x, y in degE7), every field read defensively (MAVSDK sends
  NaN in unused parameters; NaN, inf and out-of-range values never raise), each answered with a
  COMMAND_ACK to its sender: DO_SET_MODE (176), COMPONENT_ARM_DISARM (400; a disarm in the air is
  refused unless forced, param2 = 21196, as on PX4), NAV_TAKEOFF (22; PX4 reads param7 as the altitude
  AMSL, NaN: ``MIS_TAKEOFF_ALT``; ArduCopter as the height above home, in GUIDED only), NAV_LAND (21),
  NAV_RETURN_TO_LAUNCH (20), DO_REPOSITION (192, MAVSDK's goto), REQUEST_MESSAGE (512),
  SET_MESSAGE_INTERVAL (511; accepted for the streamed messages, whose rates stay the emulator's),
  REQUEST_AUTOPILOT_CAPABILITIES (520), GET_HOME_POSITION (410); any other is answered UNSUPPORTED.
* Only the peer acts: the first HEARTBEAT from another system fixes it (address, system and component
  id); commands, setpoints, heartbeats, LANDING_TARGET, PARAM_SET, mission uploads and lockstep
  acknowledgements from anyone else are dropped and counted (``foreign``); read-only requests
  (parameters, mission list, TIMESYNC, FTP) are answered for any sender, and every sender receives the
  telemetry (a monitoring ground station). A lockstep acknowledgement of a time not yet simulated is
  ignored.
* Parameters (PARAM_REQUEST_LIST / _READ, PARAM_SET) with the autopilot's names, each acting on the
  emulator (:func:`alight.interfaces.sitl_protocol.param_table`; integers bytewise on PX4, cast on
  ArduPilot, as AUTOPILOT_VERSION's capabilities say); the mission protocol with an empty mission
  (MISSION_COUNT 0; an upload is refused with MAV_MISSION_UNSUPPORTED); FTP answered with NAKs (no
  file system).
* The telemetry ground stations wait for: GLOBAL_POSITION_INT 10 Hz (from the odometry estimate),
  GPS_RAW_INT 5 Hz (a 3D fix at the true position), ATTITUDE 50 Hz, SYS_STATUS and BATTERY_STATUS 1 Hz
  (no battery model: voltage and charge unknown, the motors' energy so far), HOME_POSITION 1 Hz and on
  request, AUTOPILOT_VERSION on request; the world origin lies at PX4 SITL's default home (47.397742 N,
  8.545594 E, 488 m), mapped on a local tangent plane. Messages go out in datagrams of up to 1400 bytes.
* The offboard rules: OFFBOARD (or GUIDED) is refused unless setpoints have streamed for more than
  ``offboard_min_stream_s`` (1 s); in OFFBOARD, no setpoint for ``offboard_loss_s`` (PX4's
  ``COM_OF_LOSS_T``, 1 s; ArduPilot's ``GUID_TIMEOUT`` is 3 s) triggers the failsafe action
  (``failsafe``: ``hold``, PX4's default "Position", or ``land``), announced in a STATUSTEXT. ArduCopter
  flavour: GUIDED without a setpoint (none yet, or none for GUID_TIMEOUT) stops and holds in place and
  stays in GUIDED (ArduCopter keeps position targets for ever; the emulator times them out too), and
  arming in GUIDED needs no stream.
  Accepted setpoints: SET_ATTITUDE_TARGET with body rates and thrust (``type_mask`` 128, thrust
  normalised 0..1 of the airframe's maximum thrust) and SET_POSITION_TARGET_LOCAL_NED in
  MAV_FRAME_LOCAL_NED with any per-axis combination of position, velocity and acceleration plus yaw.
* Its own position controller for hold, take-off, land and setpoints, and a precision land that flies
  toward the latest LANDING_TARGET (see "Precision landing" below).
* Sensor messages at the rates a companion asks PX4 for with ``MAV_CMD_SET_MESSAGE_INTERVAL``:
  HIGHRES_IMU 200 Hz (the simulator's IMU model), ATTITUDE_QUATERNION 50 Hz (true attitude, as an
  autopilot's EKF would give it), ODOMETRY and LOCAL_POSITION_NED 40 Hz (the VIO-like odometry model
  with noise and drift, in LOCAL_NED, velocity in the same frame), DISTANCE_SENSOR 100 Hz (the range
  finder, downward, cm, with the sensor's span in min/max_distance; out of range, see
  :func:`distance_sensor_fields`), EXTENDED_SYS_STATE 5 Hz (on the ground before take-off, after its
  land detector, or disarmed and resting on a surface after the flight, not while it falls; taking
  off, landing, in the air otherwise), and answers to TIMESYNC requests.
* A land detector in its LAND and PRECLAND modes (:meth:`EmulatedAutopilot._land_detector`): a descent
  commanded, no vertical motion and the range finder at the floor for 0.5 s, then it disarms. In
  OFFBOARD it leaves the decision to the companion (PX4 would idle the motors on a thrust of 0 and
  disarm after its own land detector and ``COM_DISARM_LAND``; the emulator does not emulate that).
* The camera: frames rendered exactly as ``alight fly`` renders them, stamped with their capture time on
  the simulated clock and delivered after the scenario's processing latency over
  :class:`alight.interfaces.camera_source.FrameServer` (loopback TCP, port ``PORT + 1`` by default).

The clock: lockstep
-------------------
The simulated clock advances one control period (10 ms) at a time. Once a peer has shown it takes part
(it answers the ``LOCKSTEP`` NAMED_VALUE_INT the emulator sends with each heartbeat by acknowledging the
times it has processed, NAMED_VALUE_INT ``LSACK``), the emulator waits for the acknowledgement of each
period before simulating the next, like PX4's lockstep with Gazebo. Why: the vision pipeline is Python and
may be slower than real time on a loaded CI machine (and much faster on an idle one); lockstep makes the
flight independent of the machine's load, and runs as fast as both sides can go (a 40 s mission takes
the time ``alight fly`` takes plus the MAVLink overhead, not 40 s of waiting). ``speed`` > 0 caps the
simulated-to-wall ratio (1.0 = real time, for watching it in a ground station). A peer that stops
acknowledging for ``lockstep_timeout_s`` of wall time is no longer waited for (the emulator then runs
free at the capped speed, real time by default), so a dead companion cannot freeze the world.

Precision landing: how it was written, and what it leaves out
---------------------------------------------------------------
Written from the behaviour PX4's documentation describes (precland: approach the target horizontally at
the current altitude, descend over it, fall back to a plain land when it is lost) and from the fields of
LANDING_TARGET; no autopilot code was read or copied. Each LANDING_TARGET with ``position_valid`` and
MAV_FRAME_LOCAL_NED (PX4 flavour) gives the target's position; BODY_FRD (ArduPilot flavour) is rotated
into the local frame with the true attitude. A constant-velocity alpha-beta filter (alpha 0.5, beta 0.2)
estimates the target's horizontal position and velocity. The controller tracks the predicted target
position with the velocity as feed-forward, descends at ``precland_descent_mps`` (0.5 m/s) while the
horizontal error is below ``precland_accept_m`` (0.3 m), holds altitude otherwise, and after
``precland_lost_s`` (1.5 s) without a target lands straight down. Not emulated, compared with PX4's
precland: the separate ``landing_target_estimator`` Kalman filter with IMU input and its
``LTEST_*`` noise parameters, the search climb (``PLD_SRCH_ALT``, ``PLD_SRCH_TOUT``), the final
approach altitude ``PLD_FAPPR_ALT`` and the ``PLD_MAX_SRCH`` retries, the angle-only (IR-LOCK) path that
needs a range finder, TIMESYNC-corrected target timestamps, and yaw alignment with the target.
"""

from __future__ import annotations

import enum
import json
import math
import os
import select
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

os.environ.setdefault("MAVLINK20", "1")  # LANDING_TARGET's position fields exist only in MAVLink 2

from pymavlink import mavutil  # noqa: E402
from pymavlink.dialects.v20 import common as mavlink  # noqa: E402

import alight  # noqa: E402
from alight.airframe import Airframe  # noqa: E402
from alight.energy import flight_energy_J  # noqa: E402
from alight.errors import ConfigError, InputError  # noqa: E402
from alight.evaluation.runner import world_for_scenario  # noqa: E402
from alight.interfaces import frames  # noqa: E402
from alight.interfaces.camera_source import KIND_SCENARIO, FrameServer, encode_message  # noqa: E402
from alight.interfaces.sitl_protocol import (  # noqa: E402
    Encoding,
    Geodetic,
    Param,
    decode_param_value,
    encode_param_value,
    finite_or,
    ftp_reply,
    int_or_none,
    param_name,
    param_table,
)
from alight.scenario import Scenario  # noqa: E402
from alight.sim.quadrotor import (  # noqa: E402
    IX_F,
    SL_P,
    SL_Q,
    SL_V,
    SL_W,
)
from alight.sim.sensors import RangeFinderConfig  # noqa: E402
from alight.sim.world import TICK_DT, Shot  # noqa: E402
from alight.types import FloatArray, quat_to_rotmat, yaw_of  # noqa: E402

CONTROL_DT = 0.01  # the autopilot's position loop and the lockstep period (s)
GRAVITY = 9.81
FORCE_DISARM = 21196  # MAV_CMD_COMPONENT_ARM_DISARM param2 that forces a disarm in the air (PX4)
LOCKSTEP_NAME = b"LOCKSTEP"
LOCKSTEP_ACK_NAME = b"LSACK"
FRAME_SEQ_NAME = b"FRAMESEQ"

# PX4 custom mode: main mode in bits 16-23, sub mode in bits 24-31 (px4_custom_mode.h).
PX4_MAIN_MANUAL, PX4_MAIN_POSCTL, PX4_MAIN_AUTO, PX4_MAIN_OFFBOARD = 1, 3, 4, 6
PX4_MAIN_ALTCTL, PX4_MAIN_STABILIZED = 2, 7
PX4_SUB_TAKEOFF, PX4_SUB_LOITER, PX4_SUB_MISSION, PX4_SUB_RTL = 2, 3, 4, 5
PX4_SUB_LAND, PX4_SUB_PRECLAND = 6, 9
# ArduCopter mode numbers (COPTER_MODE).
AP_STABILIZE, AP_ALT_HOLD, AP_AUTO, AP_GUIDED, AP_LOITER, AP_RTL, AP_LAND = 0, 2, 3, 4, 5, 6, 9
AP_POSHOLD, AP_BRAKE = 16, 17


def px4_custom_mode(main: int, sub: int = 0) -> int:
    return (main << 16) | (sub << 24)


class FlightMode(enum.StrEnum):
    """What the emulated autopilot does, whatever the flavour calls it."""

    HOLD = "hold"
    OFFBOARD = "offboard"
    TAKEOFF = "takeoff"
    LAND = "land"
    PRECLAND = "precland"
    RTL = "rtl"


_PX4_MODES: dict[tuple[int, int], FlightMode] = {
    (PX4_MAIN_MANUAL, 0): FlightMode.HOLD,
    (PX4_MAIN_ALTCTL, 0): FlightMode.HOLD,
    (PX4_MAIN_POSCTL, 0): FlightMode.HOLD,
    (PX4_MAIN_STABILIZED, 0): FlightMode.HOLD,
    (PX4_MAIN_OFFBOARD, 0): FlightMode.OFFBOARD,
    (PX4_MAIN_AUTO, PX4_SUB_TAKEOFF): FlightMode.TAKEOFF,
    (PX4_MAIN_AUTO, PX4_SUB_LOITER): FlightMode.HOLD,
    (PX4_MAIN_AUTO, PX4_SUB_LAND): FlightMode.LAND,
    (PX4_MAIN_AUTO, PX4_SUB_PRECLAND): FlightMode.PRECLAND,
    (PX4_MAIN_AUTO, PX4_SUB_RTL): FlightMode.RTL,
}
_AP_MODES: dict[int, FlightMode] = {
    AP_STABILIZE: FlightMode.HOLD,
    AP_ALT_HOLD: FlightMode.HOLD,
    AP_LOITER: FlightMode.HOLD,
    AP_POSHOLD: FlightMode.HOLD,
    AP_BRAKE: FlightMode.HOLD,
    AP_GUIDED: FlightMode.OFFBOARD,
    AP_LAND: FlightMode.PRECLAND,
    AP_RTL: FlightMode.RTL,
}
# Modes that fly a mission: refused, as by an autopilot without one (the emulator has no mission).
_PX4_MISSION_MODE, _AP_MISSION_MODE = px4_custom_mode(PX4_MAIN_AUTO, PX4_SUB_MISSION), AP_AUTO


def encode_mode(flavour: str, mode: FlightMode) -> int:
    """The HEARTBEAT ``custom_mode`` of ``mode``."""
    if flavour == "ardupilot":
        return {
            FlightMode.HOLD: AP_LOITER,
            FlightMode.OFFBOARD: AP_GUIDED,
            FlightMode.TAKEOFF: AP_GUIDED,
            FlightMode.LAND: AP_LAND,
            FlightMode.PRECLAND: AP_LAND,
            FlightMode.RTL: AP_RTL,
        }[mode]
    main, sub = {
        FlightMode.HOLD: (PX4_MAIN_AUTO, PX4_SUB_LOITER),  # "Hold" (a commanded POSCTL is reported as such)
        FlightMode.RTL: (PX4_MAIN_AUTO, PX4_SUB_RTL),
        FlightMode.OFFBOARD: (PX4_MAIN_OFFBOARD, 0),
        FlightMode.TAKEOFF: (PX4_MAIN_AUTO, PX4_SUB_TAKEOFF),
        FlightMode.LAND: (PX4_MAIN_AUTO, PX4_SUB_LAND),
        FlightMode.PRECLAND: (PX4_MAIN_AUTO, PX4_SUB_PRECLAND),
    }[mode]
    return px4_custom_mode(main, sub)


def decode_mode(flavour: str, custom_mode: int) -> FlightMode | None:
    """The mode a ``custom_mode`` asks for (PX4: main, sub; ArduCopter: the number), None if unknown."""
    cm = int(custom_mode) & 0xFFFFFFFF
    if flavour == "ardupilot":
        return _AP_MODES.get(cm)
    main, sub = (cm >> 16) & 0xFF, (cm >> 24) & 0xFF
    return _PX4_MODES.get((main, sub if main == PX4_MAIN_AUTO else 0))


@dataclass(frozen=True, kw_only=True)
class SitlConfig:
    """Settings of the emulated autopilot."""

    port: int = 14550
    """UDP port it listens on (loopback)."""
    host: str = "127.0.0.1"
    camera_port: int | None = None
    """TCP port of the camera stream; None: ``port + 1``."""
    flavour: Literal["px4", "ardupilot"] = "px4"
    lockstep: bool = True
    speed: float = 0.0
    """Largest simulated-to-wall time ratio; 0: as fast as the peer allows (lockstep) or real time
    (without lockstep, or after the peer stopped acknowledging)."""
    lockstep_timeout_s: float = 2.0
    """Wall time to wait for a period's acknowledgement before running free."""
    wait_for_peer_s: float = 60.0
    """Wall time to wait for the companion's first HEARTBEAT; the world starts when it arrives."""
    wait_for_warm_up_s: float = 600.0
    """Once a companion has opened the camera stream, the wall time it has to send its first HEARTBEAT:
    ``alight bridge`` reads the scenario from the stream and compiles its pipeline's kernels before it
    takes the link, which takes minutes on a cold numba cache with several processes to a core (60 s was
    too short for four emulator-bridge pairs started together on 2 cores)."""
    offboard_loss_s: float | None = None
    """COM_OF_LOSS_T (PX4, default 1 s) or GUID_TIMEOUT (ArduPilot, default 3 s); None: the flavour's."""
    offboard_min_stream_s: float = 1.0
    """Setpoints must have streamed this long before OFFBOARD is accepted."""
    failsafe: Literal["hold", "land"] = "hold"
    land_descent_mps: float = 0.5
    precland_descent_mps: float = 0.5
    precland_accept_m: float = 0.3
    precland_lost_s: float = 1.5
    land_detect_s: float = 0.5
    """The emulator's land detector (LAND / PRECLAND): the landed condition must hold this long (s)."""
    land_max_vz_mps: float = 0.25
    """... with |v_z| below this (m/s; PX4's LNDMC_Z_VEL_MAX) ..."""
    land_range_m: float = 0.3
    """... and the range finder below this (m) or inside its blind zone."""
    takeoff_height_m: float = 2.5
    """Height of a take-off without a MAV_CMD_NAV_TAKEOFF height (PX4's MIS_TAKEOFF_ALT default)."""
    camera_stall_after_s: float | None = None
    """Fault injection: no camera frame is sent after this simulated time."""
    sysid: int = 1
    compid: int = 1
    linger_s: float = 0.15
    """Wall time the endpoint stays up after the mission ends (heartbeats with the final state, answers
    to requests), so a client sees the disarm and the landed state before the link goes quiet."""

    @property
    def loss_s(self) -> float:
        if self.offboard_loss_s is not None:
            return self.offboard_loss_s
        return 3.0 if self.flavour == "ardupilot" else 1.0


@dataclass
class Setpoint:
    """The latest offboard setpoint, in W (ENU) / B (FLU)."""

    t: float
    kind: Literal["rates", "target"]
    thrust_N: float = 0.0
    w_B: FloatArray = field(default_factory=lambda: np.zeros(3))
    p: FloatArray | None = None
    v: FloatArray | None = None
    a: FloatArray | None = None
    yaw: float | None = None


DISTANCE_SIGNAL_INVALID = 1  # DISTANCE_SENSOR signal_quality: 0 unknown, 1 invalid signal, 100 perfect


def distance_sensor_fields(range_m: float, config: RangeFinderConfig) -> tuple[int, int, int, int]:
    """DISTANCE_SENSOR ``min_distance``, ``max_distance``, ``current_distance`` (cm) and
    ``signal_quality`` for a reading as the simulated sensor reports it (ROS REP 117: ``-inf`` inside its
    blind zone, ``+inf`` beyond its range or without a return).

    common.xml defines no value for an out-of-range reading; the message carries the sensor's span, and a
    reading outside [``min_distance``, ``max_distance``] is the convention receivers use (ArduPilot's
    "out of range low / high", PX4's validity test). So ``-inf`` is sent as ``min_distance - 1`` and
    ``+inf`` as ``max_distance + 1``, both with ``signal_quality`` 1 ("invalid signal"); a valid reading
    is clipped into the span (its noise may cross an edge) with ``signal_quality`` 0 ("unknown")."""
    lo = int(min(max(round(config.min_range_m * 100.0), 0), 65533))
    hi = int(min(max(round(config.max_range_m * 100.0), lo + 1), 65534))
    if math.isfinite(range_m):
        return lo, hi, int(min(max(round(range_m * 100.0), lo), hi)), 0
    if range_m < 0:
        return lo, hi, max(lo - 1, 0), DISTANCE_SIGNAL_INVALID
    return lo, hi, hi + 1, DISTANCE_SIGNAL_INVALID


def position_control(
    p: FloatArray,
    v: FloatArray,
    R_WB: FloatArray,
    *,
    p_ref: FloatArray | None,
    v_ref: FloatArray | None,
    a_ref: FloatArray | None,
    yaw_ref: float,
    airframe: Airframe,
    kp: tuple[float, float] = (2.5, 3.0),
    kv: tuple[float, float] = (3.0, 4.0),
    k_att: float = 8.0,
    max_tilt_rad: float = math.radians(35.0),
) -> tuple[float, FloatArray]:
    """Collective thrust (N) and body-rate command (rad/s, FLU) toward a position/velocity/acceleration
    reference in W: a PD on position and velocity (gains horizontal, vertical) with acceleration feed-forward,
    a thrust direction limited to ``max_tilt_rad``, and a proportional attitude loop on the rotation error
    ``vee(R_des^T R - R^T R_des) / 2`` (the geometric-control error, Lee et al. 2010). Missing parts of the
    reference are left out of the law (no position term without ``p_ref``)."""
    a = np.zeros(3) if a_ref is None else np.array(a_ref, dtype=float)
    gain_p = np.array([kp[0], kp[0], kp[1]])
    gain_v = np.array([kv[0], kv[0], kv[1]])
    if p_ref is not None:
        a += gain_p * (p_ref - p)
    a += gain_v * ((np.zeros(3) if v_ref is None else v_ref) - v)
    a_h = float(np.hypot(a[0], a[1]))
    a_z = max(a[2] + GRAVITY, 0.2 * GRAVITY)
    if a_h > a_z * math.tan(max_tilt_rad):  # keep the thrust direction within the tilt limit
        a[0:2] *= a_z * math.tan(max_tilt_rad) / a_h
    f_W = airframe.mass * np.array([a[0], a[1], a_z])
    z_B = R_WB[:, 2]
    thrust = float(np.clip(f_W @ z_B, 0.0, airframe.thrust_to_weight * airframe.weight_N))
    z_d = f_W / np.linalg.norm(f_W)
    x_c = np.array([math.cos(yaw_ref), math.sin(yaw_ref), 0.0])
    y_d = np.cross(z_d, x_c)
    y_d /= np.linalg.norm(y_d)
    R_d = np.column_stack([np.cross(y_d, z_d), y_d, z_d])
    E = R_d.T @ R_WB - R_WB.T @ R_d
    e_R = 0.5 * np.array([E[2, 1], E[0, 2], E[1, 0]])
    w_cmd = np.clip(-k_att * e_R, -airframe.max_body_rate, airframe.max_body_rate)
    return thrust, w_cmd


class Outbox:
    """The emulator's outgoing messages, sent in datagrams of up to ``max_bytes`` to every client: a 200 Hz
    IMU plus the other streams, one datagram per message, came to thousands of datagrams per second at 8x
    real time, more than a Python ground station (MAVProxy) reads before its socket buffer overflows and
    drops replies. MAVLink parsers take several messages per datagram."""

    def __init__(self, conn: Any, max_bytes: int = 1400) -> None:
        self.conn = conn
        self.max_bytes = max_bytes
        self.buf = bytearray()

    def write(self, data: bytes) -> None:
        if len(self.buf) + len(data) > self.max_bytes:
            self.flush()
        self.buf += data

    def flush(self) -> None:
        if not self.buf:
            return
        for addr in list(self.conn.clients):
            try:
                self.conn.port.sendto(self.buf, addr)
            except OSError:  # a client gone away (ICMP unreachable) or a full buffer: the datagram is lost
                pass
        self.buf.clear()


class EmulatedAutopilot:
    """The MAVLink endpoint and the autopilot's logic around a :class:`~alight.sim.world.World`."""

    def __init__(self, scenario: Scenario, config: SitlConfig, airframe: Airframe | None = None) -> None:
        if config.flavour not in ("px4", "ardupilot"):
            raise ConfigError(f"sitl: flavour must be px4 or ardupilot, got {config.flavour!r}")
        if scenario.optical_flow is not None:
            # likewise: the emulator does not send OPTICAL_FLOW_RAD
            raise ConfigError("optical_flow: not available through alight sitl (no MAVLink stream)")
        self.config = config
        self._px4 = config.flavour == "px4"
        self.world = world_for_scenario(scenario, airframe)
        self.airframe = self.world.airframe
        try:
            self.conn = mavutil.mavlink_connection(
                f"udpin:{config.host}:{config.port}",
                source_system=config.sysid,
                source_component=config.compid,
                dialect="common",
            )
        except OSError as err:
            raise InputError(f"sitl: cannot listen on udp {config.host}:{config.port} ({err})") from None
        self.mav = self.conn.mav
        self.outbox = Outbox(self.conn)
        self.mav.file = self.outbox  # pymavlink's MAVLink.send writes each packed message to its file
        cam_port = config.port + 1 if config.camera_port is None else config.camera_port
        # Also the side channel for the verdict and the truth log, so it exists without a camera too.
        self.frames = FrameServer(config.host, cam_port)
        self.frames.hello = encode_message(
            KIND_SCENARIO, json.dumps(scenario.model_dump(mode="json")).encode()
        )
        self.mode = FlightMode.HOLD
        self.armed = False
        self.setpoint: Setpoint | None = None
        self.stream_start: float | None = None
        self.hold_p = self.world.x[SL_P].copy()
        self.hold_yaw = 0.0
        self.takeoff_z: float | None = None  # set by MAV_CMD_NAV_TAKEOFF; None: the default height
        self.target: dict[str, Any] | None = None  # alpha-beta state of the landing target
        self.peer_seen = False
        self._ack_to = (0, 0)  # the sender of the command being answered
        self._after_ack: Callable[[EmulatedAutopilot], None] | None = None  # a reply due after the ACK
        self.peer: tuple[Any, int, int] | None = None  # (address, sysid, compid) of the accepted companion
        self.foreign = 0  # messages refused because they did not come from the peer
        self.parse_errors = 0
        self._parsers: dict[Any, Any] = {}  # one MAVLink parser per sender address
        self.custom_mode = encode_mode(config.flavour, FlightMode.HOLD)  # as the HEARTBEAT reports it
        self.geo = Geodetic()
        self.home_p = self.world.x[SL_P].copy()  # home: where the vehicle starts (W, m)
        self.params = {prm.name: prm for prm in param_table(config.flavour)}
        self._init_params()
        self._rtl_landing = False
        self._goto_keep = False  # ArduPilot: the GUIDED target is a goto, kept without a stream
        self._p_est_ned = frames.enu_to_ned(self.world.x[SL_P])  # the latest odometry estimate sent
        self._v_est_ned = np.zeros(3)
        self._guided_stopped = False
        self.peer_lockstep = False
        self.ack_t = -1.0
        self.events: list[dict[str, Any]] = []
        self.setpoint_times: list[tuple[float, str]] = []
        self.frame_seq = 0
        self._last_hb_wall = 0.0
        self._last_hb_t = -1.0
        self.motor_t: list[float] = []
        self.motor_N: list[FloatArray] = []
        channels = ("t", "p_WB", "v_WB", "p_WP", "v_WP", "thrust_N", "w_cmd", "w_WB_B", "f_wind_W", "motor_N")
        self.log: dict[str, list[Any]] = {k: [] for k in channels}
        self.thrust_N = 0.0
        self.w_cmd = np.zeros(3)
        self._land_detected = False  # the emulator's land detector (LAND / PRECLAND) said landed
        self._land_since: float | None = None
        self._descending = False  # LAND / PRECLAND commanded a descent this control period

    # -- events and messages ----------------------------------------------------------------------------
    def _event(self, kind: str, **info: Any) -> None:
        self.events.append({"t": round(self.world.t, 6), "event": kind, **info})

    def _statustext(self, text: str, severity: int = mavlink.MAV_SEVERITY_INFO) -> None:
        self.mav.statustext_send(severity, text.encode()[:50])

    def _ack(self, command: int, result: int) -> None:
        to_sys, to_comp = self._ack_to
        self.mav.command_ack_send(int(command) & 0xFFFF, result, 0, 0, to_sys, to_comp)

    def _set_mode(self, mode: FlightMode, why: str, custom_mode: int | None = None) -> None:
        """Switch to ``mode``, reported in the HEARTBEAT as ``custom_mode`` (the one commanded; None: the
        flavour's name of ``mode``: PX4's hold is AUTO.LOITER, ArduCopter's LOITER)."""
        self.custom_mode = encode_mode(self.config.flavour, mode) if custom_mode is None else custom_mode
        if mode is self.mode:
            return
        p = self.world.x[SL_P]
        self.mode = mode
        self._goto_keep = False
        if mode is FlightMode.TAKEOFF:
            self.takeoff_z = None
        if mode is FlightMode.RTL:
            self._rtl_landing = False
        if mode is FlightMode.HOLD:
            self.hold_p = p.copy()
            self.hold_p[2] = max(p[2], self.airframe.gear_height)
        if mode is not FlightMode.HOLD:
            self.hold_p = p.copy()
        self.hold_yaw = yaw_of(quat_to_rotmat(self.world.x[SL_Q]))
        # a failsafe's land ends wherever the vehicle is: touching the ground is its safe end (aborted)
        # a failsafe's land: touching the ground is its safe end, and a safe settling scores aborted
        self.world.ground_ok = self.world.aborting = mode is FlightMode.LAND and why == "offboard loss"
        self._event("mode", mode=mode.value, reason=why)

    @property
    def landed(self) -> bool:
        """What the emulated autopilot believes (EXTENDED_SYS_STATE): on the ground before take-off,
        after its land detector said landed, or disarmed after a flight and standing on a surface (not
        while it falls after a disarm in the air); in the air otherwise."""
        w = self.world
        if not w.airborne or self._land_detected:
            return True
        resting = w.touching and float(np.linalg.norm(w.x[SL_V])) < 0.3
        return not self.armed and w.t_motors_off is not None and resting

    def _landed_state(self) -> int:
        """EXTENDED_SYS_STATE ``landed_state``: on the ground, taking off, landing, or in the air."""
        if self.landed:
            return int(mavlink.MAV_LANDED_STATE_ON_GROUND)
        if self.armed and self.mode is FlightMode.TAKEOFF:
            return int(mavlink.MAV_LANDED_STATE_TAKEOFF)
        if self.armed and self._descending:
            return int(mavlink.MAV_LANDED_STATE_LANDING)
        return int(mavlink.MAV_LANDED_STATE_IN_AIR)

    # -- parameters: the PARAM_* table acts on these ----------------------------------------------------
    def _init_params(self) -> None:
        cfg, prm = self.config, self.params
        if self._px4:
            prm["COM_OF_LOSS_T"].value = cfg.loss_s
            prm["COM_OBL_RC_ACT"].value = 4.0 if cfg.failsafe == "land" else 0.0
            prm["MIS_TAKEOFF_ALT"].value = cfg.takeoff_height_m
            prm["MPC_LAND_SPEED"].value = cfg.land_descent_mps
            prm["MPC_LAND_SPEED"].lo = 0.1  # the emulator's own default (0.5 m/s) is below PX4's span
        else:
            prm["GUID_TIMEOUT"].value = cfg.loss_s
            prm["LAND_SPEED"].value = float(round(cfg.land_descent_mps * 100.0))

    def _loss_s(self) -> float:
        return self.params["COM_OF_LOSS_T" if self._px4 else "GUID_TIMEOUT"].value

    def _failsafe(self) -> str:
        if self._px4:
            return "land" if self.params["COM_OBL_RC_ACT"].value == 4.0 else "hold"
        return self.config.failsafe

    def _takeoff_height_m(self) -> float:
        return self.params["MIS_TAKEOFF_ALT"].value if self._px4 else self.config.takeoff_height_m

    def _land_speed_mps(self) -> float:
        return self.params["MPC_LAND_SPEED"].value if self._px4 else self.params["LAND_SPEED"].value / 100

    def _rtl_height_m(self) -> float:
        return self.params["RTL_RETURN_ALT"].value if self._px4 else self.params["RTL_ALT"].value / 100

    def _disarm(self, why: str) -> None:
        """Disarm: the motors stop at the next physics batch (the world judges the settling from then)."""
        if self.armed:
            self.armed = False
            self._event("disarmed", reason=why)
            self.world.set_command(0.0, np.zeros(3), False)
            self.thrust_N, self.w_cmd = 0.0, np.zeros(3)

    def _land_detector(self, t: float) -> None:
        """The emulator's land detector, in its own LAND and PRECLAND modes (PX4 disarms after its land
        detector says landed; ArduCopter's LAND disarms on touchdown too): landed when, for
        ``land_detect_s``, a descent is commanded but the vehicle does not move vertically
        (|v_z| < ``land_max_vz_mps``, its estimate taken as the truth) and the downward range finder
        sees a surface under the feet (its latest reading below ``land_range_m``, or inside its blind
        zone: ``-inf``). Then it disarms at once (PX4 idles the motors ``COM_DISARM_LAND`` first; the
        emulator does not)."""
        cfg = self.config
        landing = self.mode in (FlightMode.LAND, FlightMode.PRECLAND, FlightMode.RTL)
        if not (self.armed and self.world.airborne and landing):
            self._land_since = None
            return
        r = self.world.last_range_m
        near = r == -math.inf or (math.isfinite(r) and r < cfg.land_range_m)
        still = abs(float(self.world.x[SL_V][2])) < cfg.land_max_vz_mps
        if not (self._descending and near and still):
            self._land_since = None
            return
        if self._land_since is None:
            self._land_since = t
        if t - self._land_since >= cfg.land_detect_s:
            self._land_detected = True
            self._event("land_detected", mode=self.mode.value)
            self._statustext("Landing detected")
            self._disarm("land detector")

    def _stream_alive(self, t: float) -> bool:
        return self.setpoint is not None and t - self.setpoint.t <= self._loss_s()

    # -- receiving: one parser per sender, and only the peer commands ----------------------------------
    def receive(self, data: bytes, addr: Any = None) -> None:
        """Parse one datagram from ``addr`` and handle its messages. Each sender has its own parser, so a
        truncated frame from one cannot swallow another's; whatever fails to parse is counted."""
        parser = self._parsers.get(addr)
        if parser is None:
            if len(self._parsers) >= 64:  # a flood of senders: forget the oldest parser
                self._parsers.pop(next(iter(self._parsers)))
            parser = self._parsers[addr] = mavlink.MAVLink(None, self.config.sysid, self.config.compid)
            parser.robust_parsing = True
        try:
            msgs = parser.parse_buffer(data) or []
        except Exception:  # noqa: BLE001 - any parser failure on foreign bytes is a bad datagram, not an exit
            self.parse_errors += 1
            parser.buf, parser.buf_index = bytearray(), 0
            return
        for msg in msgs:
            self.handle(msg, addr)

    def handle(self, msg: Any, addr: Any = None) -> None:
        """One decoded message from ``addr``. The first HEARTBEAT from another system makes its sender the
        peer; from then on only the peer's commands, setpoints, heartbeats and lockstep acknowledgements
        act, while read-only requests (parameters, mission list, TIMESYNC) are answered for anyone."""
        kind = msg.get_type()
        if kind == "BAD_DATA":
            self.parse_errors += 1
            return
        src = (addr, msg.get_srcSystem(), msg.get_srcComponent())
        if src[1:] == (self.config.sysid, self.config.compid):
            self.foreign += 1  # our own ids: an echo or a spoof
            return
        if self.peer is None and kind == "HEARTBEAT":
            self.peer = src
            self.peer_seen = True
            self._event("peer", sysid=src[1], compid=src[2])
        try:
            if kind in _PUBLIC_HANDLERS:
                _PUBLIC_HANDLERS[kind](self, msg)
            elif src != self.peer:
                self.foreign += 1
            elif kind in _PEER_HANDLERS:
                _PEER_HANDLERS[kind](self, msg)
        except (ValueError, TypeError, OverflowError, struct.error) as err:
            # a field no check above anticipated: drop the message, never the mission
            self.parse_errors += 1
            self._event("bad_message", message=kind, error=f"{type(err).__name__}: {str(err)[:60]}")

    def _on_named_value_int(self, msg: Any) -> None:
        raw = msg.name
        name = raw.encode("latin-1", "replace") if isinstance(raw, str) else bytes(raw)
        if name.rstrip(b"\0") == LOCKSTEP_ACK_NAME:
            t_ack = finite_or(msg.time_boot_ms, -1.0) * 1e-3
            # an acknowledgement of a time not yet simulated is not one: it cannot run the world ahead
            if t_ack <= self.world.t + 1e-6:
                self.peer_lockstep = True
                self.ack_t = max(self.ack_t, t_ack)

    def _on_timesync(self, msg: Any) -> None:
        if msg.tc1 == 0:
            self.mav.timesync_send(int(self.world.t * 1e9), msg.ts1)

    def _addressed_to_me(self, msg: Any) -> bool:
        return msg.target_system in (0, self.config.sysid) and msg.target_component in (0, self.config.compid)

    def _on_command_long(self, msg: Any) -> None:
        if self._addressed_to_me(msg):
            params = [msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6, msg.param7]
            self._command(msg.command, params, msg, global_e7=False)

    def _on_command_int(self, msg: Any) -> None:
        if self._addressed_to_me(msg):
            params = [msg.param1, msg.param2, msg.param3, msg.param4, msg.x, msg.y, msg.z]
            self._command(msg.command, params, msg, global_e7=True, frame=int(msg.frame))

    def _note_setpoint(self, sp: Setpoint) -> None:
        if self.setpoint is None or sp.t - self.setpoint.t > 0.5:
            self.stream_start = sp.t  # a new stream (PX4 wants a continuous one before the switch)
        self.setpoint = sp
        self._goto_keep = False
        self.setpoint_times.append((sp.t, sp.kind))

    def _attitude_target(self, msg: Any, t: float) -> None:
        vals = [msg.body_roll_rate, msg.body_pitch_rate, msg.body_yaw_rate, msg.thrust]
        if not all(math.isfinite(v) for v in vals) or msg.type_mask & 0b111:
            self._statustext("SET_ATTITUDE_TARGET: only rates+thrust")
            return
        thrust_N = min(max(msg.thrust, 0.0), 1.0) * self.airframe.thrust_to_weight * self.airframe.weight_N
        w = frames.frd_to_flu(np.array(vals[:3]))
        self._note_setpoint(Setpoint(t, "rates", thrust_N=thrust_N, w_B=w))

    def _position_target(self, msg: Any, t: float) -> None:
        if msg.coordinate_frame != mavlink.MAV_FRAME_LOCAL_NED:
            self._statustext("SET_POSITION_TARGET: frame unsupported")
            return
        m = msg.type_mask

        def vec(bit: int, xyz: tuple[float, float, float]) -> FloatArray | None:
            if m & (bit | bit << 1 | bit << 2) == (bit | bit << 1 | bit << 2):
                return None
            v = np.array(xyz, dtype=float)
            return None if not np.all(np.isfinite(v)) else frames.ned_to_enu(v)

        p = vec(1, (msg.x, msg.y, msg.z))
        v = vec(8, (msg.vx, msg.vy, msg.vz))
        a = vec(64, (msg.afx, msg.afy, msg.afz))
        yaw = None if m & 1024 or not math.isfinite(msg.yaw) else frames.yaw_ned_to_enu(msg.yaw)
        if p is None and v is None and a is None:
            return
        self._note_setpoint(Setpoint(t, "target", p=p, v=v, a=a, yaw=yaw))

    def _landing_target(self, msg: Any, t: float) -> None:
        if not getattr(msg, "position_valid", 0):
            return
        xyz = np.array([msg.x, msg.y, msg.z], dtype=float)
        if not np.all(np.isfinite(xyz)):
            return
        if msg.frame == mavlink.MAV_FRAME_LOCAL_NED:
            p_W = frames.ned_to_enu(xyz)
        elif msg.frame == mavlink.MAV_FRAME_BODY_FRD:
            R = quat_to_rotmat(self.world.x[SL_Q])
            p_W = self.world.x[SL_P] + R @ frames.frd_to_flu(xyz)
        else:
            self._statustext("LANDING_TARGET: frame not supported")
            return
        tg = self.target
        if tg is None or t - tg["t"] > self.config.precland_lost_s:
            self.target = {"t": t, "p": p_W[0:2].copy(), "v": np.zeros(2), "z": float(p_W[2])}
            return
        dt = max(t - tg["t"], 1e-3)
        pred = tg["p"] + tg["v"] * dt
        r = p_W[0:2] - pred
        tg["p"] = pred + 0.5 * r
        tg["v"] = tg["v"] + 0.2 * r / dt
        tg["t"], tg["z"] = t, float(p_W[2])

    def _command(
        self, cmd: int, params: list[Any], msg: Any, *, global_e7: bool, frame: int | None = None
    ) -> None:
        """A COMMAND_LONG or COMMAND_INT (``global_e7``: params 5 and 6 are degE7 integers), every field
        read defensively (unused ones are NaN from MAVSDK); every command gets a COMMAND_ACK."""
        self._ack_to = (msg.get_srcSystem(), msg.get_srcComponent())
        handler = _COMMANDS.get(int(cmd))
        if handler is None:
            self._ack(cmd, mavlink.MAV_RESULT_UNSUPPORTED)
            return
        p = [finite_or(v, math.nan) for v in params]
        if global_e7:  # lat/lon as degE7 integers: degrees, the same as COMMAND_LONG carries
            p[4], p[5] = p[4] * 1e-7, p[5] * 1e-7
        self._ack(cmd, handler(self, p, frame))
        then, self._after_ack = self._after_ack, None
        if then is not None:  # a requested message follows its ACK, as the command protocol has it
            then(self)

    def _cmd_arm_disarm(self, p: list[float], frame: int | None) -> int:
        t = self.world.t
        force = int_or_none(p[1]) == FORCE_DISARM
        if p[0] == 1.0:
            if self.armed:
                return int(mavlink.MAV_RESULT_ACCEPTED)
            if self.world.t_motors_off is not None or self.world.done:  # one flight per mission
                return int(mavlink.MAV_RESULT_DENIED)
            if self.mode is FlightMode.OFFBOARD and self._px4 and not self._stream_alive(t):
                return int(mavlink.MAV_RESULT_DENIED)
            if self.mode is FlightMode.RTL or self.mode in (FlightMode.LAND, FlightMode.PRECLAND):
                return int(mavlink.MAV_RESULT_DENIED)  # (PX4 and ArduCopter refuse to arm in these)
            self.armed = True
            self.hold_p = self.world.x[SL_P].copy()
            self._event("armed")
            return int(mavlink.MAV_RESULT_ACCEPTED)
        if p[0] == 0.0:
            # PX4 refuses a disarm unless its land detector says landed, or the disarm is forced
            on_ground = not self.world.airborne or self.landed
            if self.armed and not on_ground and not force:
                return int(mavlink.MAV_RESULT_DENIED)
            self._disarm("forced" if force else "commanded")
            return int(mavlink.MAV_RESULT_ACCEPTED)
        return int(mavlink.MAV_RESULT_DENIED)

    def _requested_mode(self, p: list[float]) -> int | None:
        """The custom mode a MAV_CMD_DO_SET_MODE asks for (None: not a custom mode, or unreadable)."""
        base = int_or_none(p[0], 0, 255)
        if base is None or not base & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return None
        if not self._px4:
            return int_or_none(p[1], 0, 2**32 - 1)
        main, sub = int_or_none(p[1], 0, 255), int_or_none(p[2], 0, 255)
        if main is None:
            return None
        return px4_custom_mode(main, sub if main == PX4_MAIN_AUTO and sub is not None else 0)

    def _cmd_set_mode(self, p: list[float], frame: int | None) -> int:
        t = self.world.t
        cm = self._requested_mode(p)
        if cm is None:
            return int(mavlink.MAV_RESULT_DENIED)
        refused = mavlink.MAV_RESULT_DENIED if self._px4 else mavlink.MAV_RESULT_FAILED
        if cm == (_PX4_MISSION_MODE if self._px4 else _AP_MISSION_MODE):
            self._statustext("No mission available", mavlink.MAV_SEVERITY_WARNING)
            return int(refused)
        mode = decode_mode(self.config.flavour, cm)
        if mode is None:
            return int(mavlink.MAV_RESULT_UNSUPPORTED)
        if mode is FlightMode.OFFBOARD and self._px4:
            streaming = self._stream_alive(t) and self.stream_start is not None
            if not streaming or t - (self.stream_start or t) < self.config.offboard_min_stream_s:
                self._statustext("REJECT OFFBOARD: no setpoint stream", mavlink.MAV_SEVERITY_WARNING)
                return int(mavlink.MAV_RESULT_TEMPORARILY_REJECTED)
        self._set_mode(mode, "commanded", custom_mode=cm)
        return int(mavlink.MAV_RESULT_ACCEPTED)

    def _cmd_takeoff(self, p: list[float], frame: int | None) -> int:
        """MAV_CMD_NAV_TAKEOFF: PX4 reads param7 as the altitude AMSL (NaN: MIS_TAKEOFF_ALT above the
        take-off point) and takes off in AUTO.TAKEOFF; ArduCopter reads it as the height above home and
        takes off only in GUIDED."""
        if not self.armed:
            return int(mavlink.MAV_RESULT_TEMPORARILY_REJECTED if self._px4 else mavlink.MAV_RESULT_FAILED)
        if not self._px4 and self.mode is not FlightMode.OFFBOARD:
            return int(mavlink.MAV_RESULT_FAILED)
        z_now = float(self.world.x[SL_P][2])
        if not math.isfinite(p[6]):
            z_goal = z_now + self._takeoff_height_m()
        else:  # PX4: AMSL; ArduCopter: above home
            z_goal = p[6] - self.geo.alt0_m if self._px4 else float(self.home_p[2]) + p[6]
        if not 0.5 <= z_goal - z_now <= 80.0:
            return int(mavlink.MAV_RESULT_DENIED)
        self._set_mode(FlightMode.TAKEOFF, "takeoff command")
        self.takeoff_z = z_goal
        return int(mavlink.MAV_RESULT_ACCEPTED)

    def _cmd_land(self, p: list[float], frame: int | None) -> int:
        self._set_mode(FlightMode.LAND if self._px4 else FlightMode.PRECLAND, "land command")
        return int(mavlink.MAV_RESULT_ACCEPTED)

    def _cmd_rtl(self, p: list[float], frame: int | None) -> int:
        self._set_mode(FlightMode.RTL, "return command")
        return int(mavlink.MAV_RESULT_ACCEPTED)

    def _cmd_reposition(self, p: list[float], frame: int | None) -> int:
        """MAV_CMD_DO_REPOSITION (MAVSDK's goto): fly to param5/6 (lat/lon) at param7, AMSL or above home
        by the frame (NaN keeps the current value); PX4 then holds there (AUTO.LOITER), ArduCopter flies
        it in GUIDED."""
        if not (self.armed and self.world.airborne):
            return int(mavlink.MAV_RESULT_TEMPORARILY_REJECTED)
        x = self.world.x[SL_P]
        east, north = (float(x[0]), float(x[1]))
        if math.isfinite(p[4]) and math.isfinite(p[5]):
            if not (-90.0 <= p[4] <= 90.0 and -180.0 <= p[5] <= 180.0):
                return int(mavlink.MAV_RESULT_DENIED)
            east, north = self.geo.to_east_north(p[4], p[5])
        up = float(x[2])
        if math.isfinite(p[6]):
            relative = frame in (
                mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            )
            up = p[6] if relative else p[6] - self.geo.alt0_m
        goal = np.array([east, north, up])
        if np.linalg.norm(goal - x) > 1000.0 or up < 0.0:
            return int(mavlink.MAV_RESULT_DENIED)
        if self._px4:
            self._set_mode(FlightMode.HOLD, "reposition")
            self.hold_p = goal
        else:
            self._set_mode(FlightMode.OFFBOARD, "reposition")
            self.setpoint = Setpoint(self.world.t, "target", p=goal)
            self._goto_keep = True
        if math.isfinite(p[3]):
            self.hold_yaw = frames.yaw_enu_to_ned(math.radians(p[3]))  # (the map is its own inverse)
        return int(mavlink.MAV_RESULT_ACCEPTED)

    def _cmd_request_message(self, p: list[float], frame: int | None) -> int:
        msg_id = int_or_none(p[0], 0, 2**24)
        sender = _ON_REQUEST.get(msg_id) if msg_id is not None else None
        if sender is None:
            return int(mavlink.MAV_RESULT_UNSUPPORTED)
        self._after_ack = sender
        return int(mavlink.MAV_RESULT_ACCEPTED)

    def _cmd_message_interval(self, p: list[float], frame: int | None) -> int:
        """MAV_CMD_SET_MESSAGE_INTERVAL: accepted for the messages the emulator streams, at its own fixed
        rates (the module docstring lists them); refused for any other."""
        msg_id = int_or_none(p[0], 0, 2**24)
        return int(mavlink.MAV_RESULT_ACCEPTED if msg_id in _STREAMED else mavlink.MAV_RESULT_UNSUPPORTED)

    def _cmd_autopilot_capabilities(self, p: list[float], frame: int | None) -> int:
        self._after_ack = EmulatedAutopilot._send_autopilot_version
        return int(mavlink.MAV_RESULT_ACCEPTED)

    def _cmd_home_position(self, p: list[float], frame: int | None) -> int:
        self._after_ack = EmulatedAutopilot._send_home_position
        return int(mavlink.MAV_RESULT_ACCEPTED)

    # -- parameters, mission, FTP: what a ground station asks on connecting -------------------------
    def _encoding(self) -> Encoding:
        return "bytewise" if self._px4 else "cast"

    def _send_param(self, prm: Param) -> None:
        index, count = list(self.params).index(prm.name), len(self.params)
        value = encode_param_value(prm, self._encoding())
        self.mav.param_value_send(prm.name.encode(), value, prm.mav_type, count, index)

    def _on_param_request_list(self, msg: Any) -> None:
        if self._addressed_to_me(msg):
            for prm in self.params.values():
                self._send_param(prm)

    def _on_param_request_read(self, msg: Any) -> None:
        if not self._addressed_to_me(msg):
            return
        index = int_or_none(msg.param_index, -1, 65535)
        if index is not None and 0 <= index < len(self.params):
            self._send_param(list(self.params.values())[index])
        elif (prm := self.params.get(param_name(msg.param_id))) is not None:
            self._send_param(prm)

    def _on_param_set(self, msg: Any) -> None:
        """PARAM_SET: a known name with a value in its span is taken and echoed; otherwise the current value
        is echoed (how autopilots refuse a value); an unknown name gets no answer, as from an autopilot."""
        if not self._addressed_to_me(msg):
            return
        prm = self.params.get(param_name(msg.param_id))
        if prm is None:
            return
        value = decode_param_value(float(msg.param_value), int(msg.param_type), self._encoding())
        if prm.accepts(value):
            prm.value = value
            self._event("param", name=prm.name, value=value)
        self._send_param(prm)

    def _on_mission_request_list(self, msg: Any) -> None:
        if self._addressed_to_me(msg):
            to = (msg.get_srcSystem(), msg.get_srcComponent())
            self.mav.mission_count_send(*to, 0, int(getattr(msg, "mission_type", 0)))

    def _on_mission_request(self, msg: Any) -> None:
        if self._addressed_to_me(msg):  # no item exists
            to = (msg.get_srcSystem(), msg.get_srcComponent())
            self.mav.mission_ack_send(*to, mavlink.MAV_MISSION_INVALID_SEQUENCE, int(msg.mission_type))

    def _on_mission_count(self, msg: Any) -> None:
        """A mission upload: an empty one is taken, any other refused (the emulator flies no mission)."""
        if self._addressed_to_me(msg):
            to = (msg.get_srcSystem(), msg.get_srcComponent())
            result = mavlink.MAV_MISSION_ACCEPTED if msg.count == 0 else mavlink.MAV_MISSION_UNSUPPORTED
            self.mav.mission_ack_send(*to, result, int(msg.mission_type))

    def _on_mission_clear_all(self, msg: Any) -> None:
        if self._addressed_to_me(msg):
            to = (msg.get_srcSystem(), msg.get_srcComponent())
            self.mav.mission_ack_send(*to, mavlink.MAV_MISSION_ACCEPTED, int(msg.mission_type))

    def _on_ftp(self, msg: Any) -> None:
        if msg.target_system not in (0, self.config.sysid):
            return
        reply = ftp_reply(msg.payload)
        if reply is not None:
            self.mav.file_transfer_protocol_send(0, msg.get_srcSystem(), msg.get_srcComponent(), reply)

    # -- control ---------------------------------------------------------------------------------------
    def _control(self) -> None:
        t, x = self.world.t, self.world.x
        p, v, R = x[SL_P], x[SL_V], quat_to_rotmat(x[SL_Q])
        guided_stopped = self._supervise_setpoints(t, p, R)
        self._land_detector(t)
        self._descending = False
        if not self.armed:
            self.world.set_command(0.0, np.zeros(3), False)
            self.thrust_N, self.w_cmd = 0.0, np.zeros(3)
            return
        rates = self.setpoint is not None and self.setpoint.kind == "rates"
        if self.mode is FlightMode.OFFBOARD and rates and not guided_stopped and self.setpoint is not None:
            thrust, w = self.setpoint.thrust_N, self.setpoint.w_B
        else:
            p_ref, v_ref, a_ref, yaw = self._reference(t, p, v, guided_stopped)
            # (land: p_ref's height is the current one, so the vertical is a pure rate of descent)
            thrust, w = position_control(
                p, v, R, p_ref=p_ref, v_ref=v_ref, a_ref=a_ref, yaw_ref=yaw, airframe=self.airframe
            )
        self.thrust_N, self.w_cmd = thrust, np.asarray(w, dtype=float)
        self.world.set_command(thrust, self.w_cmd, True)

    def _supervise_setpoints(self, t: float, p: FloatArray, R: FloatArray) -> bool:
        """The setpoint stream's rules: ArduCopter GUIDED stops and holds without setpoints (returns True
        then); PX4 OFFBOARD without a live stream goes to its failsafe."""
        guided_stopped = False
        if self.mode is FlightMode.OFFBOARD and not self._px4:
            # ArduCopter GUIDED: without setpoints (none yet, or none for GUID_TIMEOUT) the vehicle stops
            # and holds where it is, and stays in GUIDED.
            guided_stopped = self.setpoint is None or (
                t - self.setpoint.t > self._loss_s() and not self._goto_keep
            )
            if guided_stopped and not self._guided_stopped:
                self.hold_p = p.copy()
                self.hold_yaw = yaw_of(R)
                self._event("guided_timeout", last_setpoint_t=self.setpoint.t if self.setpoint else None)
            self._guided_stopped = guided_stopped
        elif self.mode is FlightMode.OFFBOARD and self.armed and not self._stream_alive(t):
            failsafe = self._failsafe()
            self._statustext(f"Offboard lost: failsafe {failsafe}", mavlink.MAV_SEVERITY_WARNING)
            self._event(
                "failsafe",
                action=failsafe,
                last_setpoint_t=self.setpoint.t if self.setpoint else None,
            )
            self._set_mode(FlightMode.LAND if failsafe == "land" else FlightMode.HOLD, "offboard loss")
        return guided_stopped

    def _reference(
        self, t: float, p: FloatArray, v: FloatArray, guided_stopped: bool
    ) -> tuple[FloatArray | None, FloatArray | None, FloatArray | None, float]:
        """The position controller's reference ``(p_ref, v_ref, a_ref, yaw)`` in the current mode."""
        p_ref: FloatArray | None = self.hold_p
        v_ref: FloatArray | None = None
        a_ref: FloatArray | None = None
        yaw = self.hold_yaw
        if self.mode is FlightMode.OFFBOARD and self.setpoint is not None and not guided_stopped:
            sp = self.setpoint
            p_ref, v_ref, a_ref = sp.p, sp.v, sp.a
            yaw = self.hold_yaw if sp.yaw is None else sp.yaw
        elif self.mode is FlightMode.TAKEOFF:
            p_ref = self._takeoff_reference(t, p, v)
        elif self.mode is FlightMode.RTL and not self._rtl_landing:
            p_ref = self._rtl_reference(p, v)
        elif self.mode in (FlightMode.LAND, FlightMode.PRECLAND, FlightMode.RTL):
            p_ref, v_ref = self._land_reference(t, p)
        return p_ref, v_ref, a_ref, yaw

    def _takeoff_reference(self, t: float, p: FloatArray, v: FloatArray) -> FloatArray:
        z = self.hold_p[2] + self._takeoff_height_m() if self.takeoff_z is None else self.takeoff_z
        p_ref = np.array([self.hold_p[0], self.hold_p[1], z])
        if p[2] > z - 0.1 and abs(v[2]) < 0.2:
            # PX4 goes on to AUTO.LOITER; ArduCopter stays in GUIDED, holding where it got to
            self._set_mode(FlightMode.HOLD if self._px4 else FlightMode.OFFBOARD, "takeoff done")
            if not self._px4:
                self.setpoint = Setpoint(t, "target", p=p_ref)
                self._goto_keep = True
        return p_ref

    def _rtl_reference(self, p: FloatArray, v: FloatArray) -> FloatArray:
        z_rtl = max(float(self.hold_p[2]), float(self.home_p[2]) + self._rtl_height_m())
        climbed = p[2] > z_rtl - 0.3
        p_ref = np.array([self.home_p[0], self.home_p[1], z_rtl]) if climbed else self.hold_p.copy()
        if not climbed:
            p_ref[2] = z_rtl  # climb first, then return
        home_dist = math.dist(p[0:2], self.home_p[0:2])
        if climbed and home_dist < 0.3 and float(np.linalg.norm(v)) < 0.3:
            self._rtl_landing = True
            self.hold_p = p.copy()
        return p_ref

    def _land_reference(self, t: float, p: FloatArray) -> tuple[FloatArray, FloatArray]:
        descent = self._land_speed_mps()
        xy = self.hold_p[0:2]
        v_xy = np.zeros(2)
        tg = self.target
        if self.mode is FlightMode.PRECLAND and tg is not None and t - tg["t"] <= self.config.precland_lost_s:
            xy = tg["p"] + tg["v"] * (t - tg["t"])
            v_xy = tg["v"]
            self.hold_p[0:2] = xy  # a lost target leaves a plain land where it was last seen
            if math.dist(xy, p[0:2]) > self.config.precland_accept_m:
                descent = 0.0
            else:
                descent = self.config.precland_descent_mps
        self._descending = descent > 0.0
        return np.array([xy[0], xy[1], p[2]]), np.array([v_xy[0], v_xy[1], -descent])

    # -- sensors out -----------------------------------------------------------------------------------
    def _send_sensors(self, imu: FloatArray) -> None:
        w = self.world
        t, k, x = w.t, w.k, w.x
        t_us, t_ms = int(round(t * 1e6)), int(round(t * 1e3))
        mav = self.mav
        # The IMU first, as the runner feeds it before the odometry of the same tick.
        f, g = frames.flu_to_frd(imu[0:3]), frames.flu_to_frd(imu[3:6])
        mav.highres_imu_send(t_us, *f, *g, 0.0, 0.0, 0.0, 1013.25, 0.0, 0.0, 20.0, 0b111111)
        if k % 4 == 0:  # 50 Hz
            q = frames.q_WB_to_mavlink(x[SL_Q])
            rates = frames.flu_to_frd(x[SL_W])
            mav.attitude_quaternion_send(t_ms, *q, *rates)
            mav.attitude_send(t_ms, *frames.mavlink_q_to_euler_ned_frd(q), *rates)
        odo = w.odometry_message() if k % 5 == 0 else None  # 40 Hz, odometry faults applied
        if odo is not None:
            p, v = frames.enu_to_ned(odo.p_WB), frames.enu_to_ned(odo.v_WB)
            q = frames.q_WB_to_mavlink(odo.q_WB)
            rates = frames.flu_to_frd(x[SL_W])
            nan21 = [math.nan] * 21
            mav.local_position_ned_send(t_ms, *p, *v)
            self._p_est_ned, self._v_est_ned = p, v
            mav.odometry_send(
                t_us, mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_FRAME_LOCAL_NED, *p, q, *v, *rates,
                nan21, nan21, w.faults.odometry_reset_counter, mavlink.MAV_ESTIMATOR_TYPE_VIO, 100,
            )  # fmt: skip
        if k % 2 == 0:  # 100 Hz
            lo, hi, cm, quality = distance_sensor_fields(w.range_m(), w.rangefinder.config)
            mav.distance_sensor_send(t_ms, lo, hi, cm, mavlink.MAV_DISTANCE_SENSOR_LASER, 0,
                                     mavlink.MAV_SENSOR_ROTATION_PITCH_270, 255, 0.0, 0.0, [0.0] * 4,
                                     quality)  # fmt: skip
        if k % 20 == 0:  # 10 Hz
            self._send_global_position(t_ms)
        if k % 40 == 0:  # 5 Hz
            mav.extended_sys_state_send(mavlink.MAV_VTOL_STATE_UNDEFINED, self._landed_state())
            self._send_gps(t_us)
        if k % 200 == 100:  # 1 Hz
            self._send_status()
            self._send_home_position()

    # -- the standard telemetry a ground station waits for ----------------------------------------------
    def _send_global_position(self, t_ms: int) -> None:
        """GLOBAL_POSITION_INT from the latest odometry estimate (the one LOCAL_POSITION_NED carries)."""
        p, v = self._p_est_ned, self._v_est_ned
        if not (np.all(np.isfinite(p)) and np.all(np.isfinite(v))):
            return
        lat, lon = self.geo.e7(float(p[1]), float(p[0]))
        up = -float(p[2])
        yaw_ned = frames.yaw_enu_to_ned(yaw_of(quat_to_rotmat(self.world.x[SL_Q])))
        hdg = int(round(math.degrees(yaw_ned) * 100.0)) % 36000
        cm_s = [int(np.clip(round(c * 100.0), -32768, 32767)) for c in v]
        self.mav.global_position_int_send(
            t_ms, lat, lon, int(round((self.geo.alt0_m + up) * 1e3)),
            int(round((up - float(self.home_p[2])) * 1e3)), *cm_s, hdg,
        )  # fmt: skip

    def _send_gps(self, t_us: int) -> None:
        """GPS_RAW_INT: a 3D fix at the true position (the emulator has no GNSS error model)."""
        x = self.world.x
        lat, lon = self.geo.e7(float(x[0]), float(x[1]))
        v = x[SL_V]
        speed = float(np.hypot(v[0], v[1]))
        cog = int(round(math.degrees(math.atan2(v[0], v[1])) * 100.0)) % 36000 if speed > 0.2 else 65535
        self.mav.gps_raw_int_send(
            t_us, mavlink.GPS_FIX_TYPE_3D_FIX, lat, lon, int(round((self.geo.alt0_m + float(x[2])) * 1e3)),
            80, 120, int(round(speed * 100.0)), cog, 12,
        )  # fmt: skip

    def _send_status(self) -> None:
        """SYS_STATUS (sensors present, enabled and healthy, the pre-arm check passed) and BATTERY_STATUS
        (no battery is modelled: voltage, current and charge unknown; energy drawn by the motors so far)."""
        sensors = (
            mavlink.MAV_SYS_STATUS_SENSOR_3D_GYRO | mavlink.MAV_SYS_STATUS_SENSOR_3D_ACCEL
            | mavlink.MAV_SYS_STATUS_SENSOR_3D_MAG | mavlink.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
            | mavlink.MAV_SYS_STATUS_SENSOR_GPS | mavlink.MAV_SYS_STATUS_SENSOR_LASER_POSITION
            | mavlink.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS | mavlink.MAV_SYS_STATUS_PREARM_CHECK
        )  # fmt: skip
        self.mav.sys_status_send(sensors, sensors, sensors, 0, 65535, -1, -1, 0, 0, 0, 0, 0, 0)
        t = np.array(self.motor_t)
        energy_hJ = flight_energy_J(t, np.array(self.motor_N)) / 100.0 if t.size > 1 else 0.0
        self.mav.battery_status_send(
            0, mavlink.MAV_BATTERY_FUNCTION_ALL, mavlink.MAV_BATTERY_TYPE_LIPO, 32767, [65535] * 10, -1, -1,
            int(min(energy_hJ, 2**31 - 1)), -1,
        )  # fmt: skip

    def _send_home_position(self) -> None:
        h = self.home_p
        lat, lon = self.geo.e7(float(h[0]), float(h[1]))
        self.mav.home_position_send(
            lat, lon, int(round((self.geo.alt0_m + float(h[2])) * 1e3)), *frames.enu_to_ned(h),
            [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, int(round(self.world.t * 1e6)),
        )  # fmt: skip

    def _send_autopilot_version(self) -> None:
        caps = (
            mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2 | mavlink.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
            | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT
            | mavlink.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
            | mavlink.MAV_PROTOCOL_CAPABILITY_SET_ATTITUDE_TARGET
        )  # fmt: skip
        caps |= (
            mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE
            if self._px4
            else mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST
        )
        parts = (alight.__version__.split(".") + ["0", "0"])[:3]
        major, minor, patch = (int(n) if n.isdigit() else 0 for n in parts)
        version = major << 24 | minor << 16 | patch << 8 | mavlink.FIRMWARE_VERSION_TYPE_DEV
        self.mav.autopilot_version_send(
            caps, version, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0, 0, self.config.sysid,
        )  # fmt: skip

    def _heartbeat(self) -> None:
        base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        if self.armed:
            base |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED
        ap = (
            mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
            if self.config.flavour == "ardupilot"
            else mavlink.MAV_AUTOPILOT_PX4
        )
        status = mavlink.MAV_STATE_ACTIVE if self.armed else mavlink.MAV_STATE_STANDBY
        self.mav.heartbeat_send(mavlink.MAV_TYPE_QUADROTOR, ap, base, self.custom_mode, status)
        if self.config.lockstep:
            self.mav.named_value_int_send(int(self.world.t * 1e3), LOCKSTEP_NAME, 1)
        self._last_hb_wall = time.monotonic()
        self._last_hb_t = self.world.t

    def _platform_fixes(self) -> None:
        """The platform's GNSS fixes that reach the aircraft now go to the companion on the camera's
        stream (a real vehicle's come by a radio of their own, not through the autopilot)."""
        for fix in self.world.telemetry_arrivals():
            self.frames.send_platform_fix(fix.t_stamp, fix.p_WP, fix.v_WP, fix.cov_p_WP)

    def _camera(self) -> None:
        w = self.world
        if w.renderer is None:
            return
        stalled = self.config.camera_stall_after_s is not None and w.t >= self.config.camera_stall_after_s
        if not stalled:
            w.capture()  # when due; lost, dark, corrupted, frozen or as captured; delivered after the latency
        for t_cap, shot in w.deliveries():
            assert isinstance(shot, Shot)
            image = w.develop(shot, t_cap, used=True)  # the companion's detector decides what to skip
            if self.frames.send_frame(t_cap, image):
                self.frame_seq += 1
                self.mav.named_value_int_send(int(round(w.t * 1e3)), FRAME_SEQ_NAME, self.frame_seq)

    def _log(self) -> None:
        w, x = self.world, self.world.x
        k = w.k
        self.motor_t.append(w.t)
        self.motor_N.append(x[IX_F : IX_F + 4].copy())
        lg = self.log
        lg["t"].append(w.t)
        lg["p_WB"].append(x[SL_P].copy())
        lg["v_WB"].append(x[SL_V].copy())
        lg["p_WP"].append(w.truths.p_WP[k].copy())
        lg["v_WP"].append(w.truths.v_WP[k].copy())
        lg["thrust_N"].append(self.thrust_N)
        lg["w_cmd"].append(self.w_cmd.copy())
        lg["w_WB_B"].append(x[SL_W].copy())
        lg["f_wind_W"].append(np.array(w.f_wind, dtype=float))
        lg["motor_N"].append(x[IX_F : IX_F + 4].copy())

    # -- the loop --------------------------------------------------------------------------------------
    def _poll(self, timeout_s: float, *, until_acked: bool = False) -> None:
        """Handle every message that arrives within ``timeout_s`` (at least those already queued);
        ``until_acked``: return as soon as the lockstep acknowledgement of the current time is handled
        (checked right after the queued messages are handled: waiting in ``select`` for more data after
        the acknowledgement arrived cost a whole ``timeout_s`` per control period)."""
        sock = self.conn.port
        deadline = time.monotonic() + timeout_s
        self.frames.accept()  # the camera client receives the scenario at once
        while True:
            self.outbox.flush()
            while True:
                try:
                    data, addr = sock.recvfrom(65535)
                except OSError:  # nothing queued (or an ICMP error from a client gone away)
                    break
                self.conn.clients.add(addr)  # every sender receives the telemetry (a ground station too)
                self.conn.clients_last_alive[addr] = time.time()
                self.receive(data, addr)
            self.outbox.flush()  # the answers
            if until_acked and self._wait_satisfied():
                return
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return
            select.select([sock], [], [], remaining)

    def _wait_satisfied(self) -> bool:
        return self.peer_lockstep and self.ack_t >= self.world.t - 1e-6

    def _wait_for_peer(self) -> None:
        """Return when the companion's first HEARTBEAT has arrived: within ``wait_for_peer_s``, or within
        ``wait_for_warm_up_s`` of its opening the camera stream (it is there, compiling)."""
        cfg = self.config
        wall0 = time.monotonic()
        stream_t: float | None = None
        closed = False
        while not self.peer_seen:
            now = time.monotonic()
            connected = self.frames.connected
            if stream_t is None and connected:
                stream_t = now
            elif stream_t is not None and not connected:
                # The companion closed the camera stream before its first HEARTBEAT (it died or gave up):
                # its allowance ends, and another companion gets the ordinary wait.
                stream_t, wall0, closed = None, now, True
            where = f"udp {cfg.host}:{cfg.port}"
            if stream_t is None and now - wall0 > cfg.wait_for_peer_s:
                after = " after a companion closed the camera stream" if closed else ""
                raise InputError(
                    f"sitl: no companion HEARTBEAT on {where} within {cfg.wait_for_peer_s:g} s{after}"
                )
            if stream_t is not None and now - stream_t > cfg.wait_for_warm_up_s:
                raise InputError(
                    f"sitl: the companion opened the camera stream but sent no HEARTBEAT on {where} within"
                    f" {cfg.wait_for_warm_up_s:g} s"
                )
            self._poll(0.1)

    def run(self) -> dict[str, Any]:
        """Serve until the mission ends; returns the verdict (also sent to the peer)."""
        cfg = self.config
        self.world.warm_up()
        self._wait_for_peer()
        self._event("start")
        wall_start = time.monotonic()
        every_log = 4
        w = self.world
        while not w.done:
            self._poll(0.0)
            self._control()
            for _ in range(round(CONTROL_DT / TICK_DT)):
                imu = w.step()
                if w.k % every_log == 0:
                    self._log()
                self._platform_fixes()
                self._camera()
                if w.t - self._last_hb_t >= 1.0 or time.monotonic() - self._last_hb_wall > 0.5:
                    self._heartbeat()
                self._send_sensors(imu)
                if w.done:
                    break
            if cfg.lockstep and self.peer_lockstep:
                t_wait = time.monotonic()
                while not self._wait_satisfied():
                    self._poll(0.05, until_acked=True)
                    if time.monotonic() - self._last_hb_wall > 0.5:
                        self._heartbeat()
                    if time.monotonic() - t_wait > cfg.lockstep_timeout_s:
                        self.peer_lockstep = False  # run free until the peer acknowledges again
                        self._event("lockstep_lost")
                        break
            speed = cfg.speed if cfg.speed > 0 else (0.0 if cfg.lockstep and self.peer_lockstep else 1.0)
            if speed > 0:
                ahead = w.t / speed - (time.monotonic() - wall_start)
                if ahead > 0:
                    self._poll(ahead)
        result = self._finish(time.monotonic() - wall_start)
        self.outbox.flush()
        return result

    def _finish(self, wall_s: float) -> dict[str, Any]:
        w = self.world
        outcome = w.final_outcome
        motor_t = np.array(self.motor_t)
        energy = flight_energy_J(motor_t, np.array(self.motor_N)) if motor_t.size > 1 else None
        s = w.scenario
        result: dict[str, Any] = {
            "scenario": s.model_dump(mode="json"),
            "seed": s.seed,
            "preset": s.preset,
            **w.verdict(),
            "energy_flight_J": energy,
            "simulated_time_s": w.t,
            "sitl_wall_time_s": wall_s,
            "sitl_flavour": self.config.flavour,
            "sitl_events": self.events,
            "alight_version": alight.__version__,
        }
        self._statustext(f"alight sitl: {outcome.value}")
        return result

    def truth_arrays(self) -> dict[str, np.ndarray]:
        return {k: np.array(v, dtype=float) for k, v in self.log.items()}

    def close(self) -> None:
        self.outbox.flush()
        self.frames.close()
        self.conn.close()


_Handler = Callable[[EmulatedAutopilot, Any], None]
_PUBLIC_HANDLERS: dict[str, _Handler] = {  # read-only: answered for any sender
    "TIMESYNC": EmulatedAutopilot._on_timesync,
    "PARAM_REQUEST_LIST": EmulatedAutopilot._on_param_request_list,
    "PARAM_REQUEST_READ": EmulatedAutopilot._on_param_request_read,
    "MISSION_REQUEST_LIST": EmulatedAutopilot._on_mission_request_list,
    "MISSION_REQUEST_INT": EmulatedAutopilot._on_mission_request,
    "MISSION_REQUEST": EmulatedAutopilot._on_mission_request,
    "FILE_TRANSFER_PROTOCOL": EmulatedAutopilot._on_ftp,
}
_PEER_HANDLERS: dict[str, _Handler] = {  # act on the flight: the peer's only
    "HEARTBEAT": lambda ap, msg: None,
    "NAMED_VALUE_INT": EmulatedAutopilot._on_named_value_int,
    "COMMAND_LONG": EmulatedAutopilot._on_command_long,
    "COMMAND_INT": EmulatedAutopilot._on_command_int,
    "SET_ATTITUDE_TARGET": lambda ap, msg: ap._attitude_target(msg, ap.world.t),
    "SET_POSITION_TARGET_LOCAL_NED": lambda ap, msg: ap._position_target(msg, ap.world.t),
    "LANDING_TARGET": lambda ap, msg: ap._landing_target(msg, ap.world.t),
    "PARAM_SET": EmulatedAutopilot._on_param_set,
    "MISSION_COUNT": EmulatedAutopilot._on_mission_count,
    "MISSION_CLEAR_ALL": EmulatedAutopilot._on_mission_clear_all,
}
_Command = Callable[[EmulatedAutopilot, list[float], int | None], int]
_COMMANDS: dict[int, _Command] = {
    mavlink.MAV_CMD_COMPONENT_ARM_DISARM: EmulatedAutopilot._cmd_arm_disarm,
    mavlink.MAV_CMD_DO_SET_MODE: EmulatedAutopilot._cmd_set_mode,
    mavlink.MAV_CMD_NAV_TAKEOFF: EmulatedAutopilot._cmd_takeoff,
    mavlink.MAV_CMD_NAV_LAND: EmulatedAutopilot._cmd_land,
    mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH: EmulatedAutopilot._cmd_rtl,
    mavlink.MAV_CMD_DO_REPOSITION: EmulatedAutopilot._cmd_reposition,
    mavlink.MAV_CMD_REQUEST_MESSAGE: EmulatedAutopilot._cmd_request_message,
    mavlink.MAV_CMD_SET_MESSAGE_INTERVAL: EmulatedAutopilot._cmd_message_interval,
    mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES: EmulatedAutopilot._cmd_autopilot_capabilities,
    mavlink.MAV_CMD_GET_HOME_POSITION: EmulatedAutopilot._cmd_home_position,
}
# The messages the emulator streams (SET_MESSAGE_INTERVAL is accepted for these, at the fixed rates) ...
_STREAMED = frozenset(
    {
        mavlink.MAVLINK_MSG_ID_HEARTBEAT, mavlink.MAVLINK_MSG_ID_SYS_STATUS,
        mavlink.MAVLINK_MSG_ID_GPS_RAW_INT,
        mavlink.MAVLINK_MSG_ID_ATTITUDE, mavlink.MAVLINK_MSG_ID_ATTITUDE_QUATERNION,
        mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED, mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
        mavlink.MAVLINK_MSG_ID_HIGHRES_IMU, mavlink.MAVLINK_MSG_ID_DISTANCE_SENSOR,
        mavlink.MAVLINK_MSG_ID_BATTERY_STATUS, mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE,
        mavlink.MAVLINK_MSG_ID_HOME_POSITION, mavlink.MAVLINK_MSG_ID_ODOMETRY,
    }
)  # fmt: skip
# ... and what MAV_CMD_REQUEST_MESSAGE sends at once (a streamed message not listed comes within its period)
_ON_REQUEST: dict[int, Callable[[EmulatedAutopilot], None]] = {
    **{msg_id: (lambda ap: None) for msg_id in _STREAMED},
    mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION: EmulatedAutopilot._send_autopilot_version,
    mavlink.MAVLINK_MSG_ID_HOME_POSITION: EmulatedAutopilot._send_home_position,
    mavlink.MAVLINK_MSG_ID_SYS_STATUS: EmulatedAutopilot._send_status,
    mavlink.MAVLINK_MSG_ID_BATTERY_STATUS: EmulatedAutopilot._send_status,
    mavlink.MAVLINK_MSG_ID_HEARTBEAT: EmulatedAutopilot._heartbeat,
}


def serve(scenario: Scenario, config: SitlConfig, airframe: Airframe | None = None) -> dict[str, Any]:
    """Run the emulated autopilot for one mission: wait for a companion, fly, send it the verdict and the
    ground-truth log on the camera stream, and return the verdict. ``airframe``: None flies the
    scenario's ``airframe:``."""
    return serve_autopilot(EmulatedAutopilot(scenario, config, airframe))


def serve_autopilot(ap: EmulatedAutopilot) -> dict[str, Any]:
    """:func:`serve` with an emulator already listening (so that its caller can read the ports it took)."""
    try:
        result = ap.run()
        ap.frames.send_result(json.loads(json.dumps(result, default=float)))
        ap.frames.send_truth_log(ap.truth_arrays())
        # Heartbeats after the end, so the peer sees the final state before the link goes quiet.
        end = time.monotonic() + ap.config.linger_s
        while True:
            ap._heartbeat()
            ap.mav.extended_sys_state_send(mavlink.MAV_VTOL_STATE_UNDEFINED, ap._landed_state())
            ap._poll(min(0.05, max(end - time.monotonic(), 0.0)))
            if time.monotonic() >= end:
                break
        return result
    finally:
        ap.close()
