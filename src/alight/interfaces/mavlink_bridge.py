"""The MAVLink bridge: the same :class:`~alight.mission.pipeline.Pipeline` as ``alight fly``, on a companion
computer beside a PX4 or ArduPilot flight controller.

Inputs (validated field by field, converted NED/FRD -> ENU/FLU by :mod:`alight.interfaces.frames`, then fed
to the pipeline): HIGHRES_IMU (or SCALED_IMU) -> ``on_imu``; ODOMETRY (or LOCAL_POSITION_NED with the
latest ATTITUDE_QUATERNION / ATTITUDE) -> ``on_odometry``; DISTANCE_SENSOR facing down -> ``on_range``;
OPTICAL_FLOW_RAD (a downward flow module, when the autopilot streams it) -> ``on_flow``; camera frames
-> ``on_image``. The pipeline runs on the autopilot's clock: every sample is stamped with
the autopilot's ``time_usec`` / ``time_boot_ms``, and ``step`` (planner rate) and ``command`` (100 Hz)
run when that clock crosses their period (each IMU message advances it).

Outputs, by ``BridgeConfig.mode``:

* ``offboard``: PX4 OFFBOARD or ArduPilot GUIDED. The pipeline's command as SET_ATTITUDE_TARGET (body
  rates FRD + thrust normalised by the airframe's maximum thrust, ``type_mask`` 128) or its reference as
  SET_POSITION_TARGET_LOCAL_NED (p + v + a + yaw, ``type_mask`` 2048), by ``setpoint``. The setpoint
  stream (a hold at the current position) runs for ``stream_before_s`` before OFFBOARD / GUIDED is
  requested; the bridge arms only when ``arm`` is set (otherwise it waits for the pilot to arm); a
  camera or estimator that stalls (no frame / odometry for ``camera_timeout_s`` / ``ego_timeout_s`` of
  autopilot time) makes it send a hold-position setpoint at once; a lost link (no HEARTBEAT for
  ``link_timeout_s``) stops all commanding and ends the run with ``link_lost``.
* ``landing-target``: alight only detects and estimates; it asks the autopilot to take off and hold,
  then to precision-land (PX4 AUTO.PRECLAND, ArduPilot LAND with PLND), and sends LANDING_TARGET
  (position of the platform estimate, with line-of-sight angles and distance) after every camera frame.

The receive path never raises: bytes go through pymavlink's parser in robust mode, messages from
anything but the autopilot (its system and component id, learnt from its HEARTBEAT) are dropped, every
field is checked (finite, in physical range, timestamps strictly increasing per stream and no more than
``max_time_jump_s`` ahead), and a rejected message is counted in ``BridgeStats`` instead.

Camera frames come on their own stream (TCP from the simulator, or a camera of the companion's own), and
the autopilot's clock is the time of its latest IMU message, which reaches the bridge through the link's
queue. A frame read before the IMU messages of its time have been handled is stamped after the bridge's
clock; it waits (at most :data:`FRAME_WAIT_MAX` frames, and no more than ``max_time_jump_s`` ahead) and is
handled when the clock reaches its stamp, rather than refused. Refused frames are counted by reason
(``frame_ahead``, ``frame_late``, ``frame_order``, ``frame_bad_time``) beside the total ``frame``.

The platform's own GNSS fixes (``platform.telemetry``) come on the camera's stream too, as a real
vehicle's come by a radio of their own rather than through the autopilot: each goes to ``on_telemetry``
once the clock has reached its stamp, in order (``platform_fix``; refused: out of order, more than
``PLATFORM_FIX_MAX_AGE_S`` old, or more than ``max_time_jump_s`` ahead).
"""

from __future__ import annotations

import enum
import math
import os
import select
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

os.environ.setdefault("MAVLINK20", "1")  # LANDING_TARGET's position fields exist only in MAVLink 2

from pymavlink import mavutil  # noqa: E402
from pymavlink.dialects.v20 import common as mavlink  # noqa: E402

from alight.airframe import DEFAULT_AIRFRAME, Airframe  # noqa: E402
from alight.errors import ConfigError, EstimationError  # noqa: E402
from alight.interfaces import frames  # noqa: E402
from alight.interfaces.camera_source import CameraSource, PlatformFix, SocketCameraSource  # noqa: E402
from alight.mission.pipeline import Pipeline  # noqa: E402
from alight.mission.touchdown_detector import TouchdownState  # noqa: E402
from alight.types import Command, FloatArray, Mode, quat_to_rotmat, yaw_of  # noqa: E402

GRAVITY = 9.81
MAX_ACCEL = 16 * GRAVITY  # a +-16 g accelerometer's range (m/s^2)
MAX_RATE = 35.0  # +-2000 deg/s gyroscope (rad/s)
MAX_POSITION = 1.0e5  # a local frame spans at most 100 km (m)
MAX_SPEED = 100.0  # m/s
FORCE_DISARM = 21196
LOCKSTEP_NAME = "LOCKSTEP"
LOCKSTEP_ACK_NAME = "LSACK"
FRAME_SEQ_NAME = "FRAMESEQ"
MASK_RATES_THRUST = 128  # SET_ATTITUDE_TARGET: ignore the attitude, use body rates and thrust
MASK_PVA_YAW = 2048  # SET_POSITION_TARGET_LOCAL_NED: position, velocity, acceleration and yaw
MASK_P_YAW = 2552  # position and yaw only
PX4_OFFBOARD = (6, 0)
PX4_TAKEOFF = (4, 2)
PX4_PRECLAND = (4, 9)
AP_GUIDED, AP_LAND = 4, 9


@dataclass(frozen=True, kw_only=True)
class BridgeConfig:
    """How the bridge flies."""

    mode: Literal["offboard", "landing-target"] = "offboard"
    autopilot: Literal["px4", "ardupilot"] = "px4"
    setpoint: Literal["rates", "position"] = "rates"
    arm: bool = False
    """Arm the vehicle. Off by default: the bridge then waits for the pilot to arm."""
    control_rate_hz: float = 100.0
    stream_before_s: float = 1.2
    """Setpoints stream this long (PX4 wants > 1 s) before OFFBOARD / GUIDED is requested."""
    camera_timeout_s: float = 0.15
    ego_timeout_s: float = 0.15
    link_timeout_s: float = 3.0
    """No HEARTBEAT from the autopilot for this long (autopilot clock, or wall clock when nothing at all
    arrives) is a lost link."""
    takeoff_height_m: float = 4.0
    """landing-target mode, ArduPilot: height of the take-off before the precision landing (PX4 climbs
    to its own MIS_TAKEOFF_ALT)."""
    max_time_jump_s: float = 1.0
    camera_latency_s: float = 0.0
    """Subtracted from a companion-clock camera's timestamps (driver latency)."""
    stop_setpoints_after_s: float | None = None
    """Fault injection (tests): stop sending setpoints this long (autopilot time) after engaging."""
    stream_rates_hz: tuple[tuple[str, float], ...] = (
        ("HIGHRES_IMU", 200.0),
        ("ODOMETRY", 50.0),
        ("LOCAL_POSITION_NED", 50.0),
        ("ATTITUDE_QUATERNION", 50.0),
        ("DISTANCE_SENSOR", 50.0),
    )
    """The rates the bridge asks the autopilot for (``MAV_CMD_SET_MESSAGE_INTERVAL``, sent with its first
    :data:`INTERVAL_REQUESTS` HEARTBEATs), as a companion computer does: PX4's onboard defaults are
    HIGHRES_IMU 50 Hz, ODOMETRY 30 Hz, DISTANCE_SENSOR 10 Hz, too slow for the 100 Hz control and the
    descent's range finder. Empty: the autopilot's own rates."""

    def __post_init__(self) -> None:
        if self.mode not in ("offboard", "landing-target"):
            raise ConfigError(f"bridge: mode must be offboard or landing-target, got {self.mode!r}")
        if self.autopilot not in ("px4", "ardupilot"):
            raise ConfigError(f"bridge: autopilot must be px4 or ardupilot, got {self.autopilot!r}")
        if self.setpoint not in ("rates", "position"):
            raise ConfigError(f"bridge: setpoint must be rates or position, got {self.setpoint!r}")
        for name in ("control_rate_hz", "camera_timeout_s", "ego_timeout_s", "link_timeout_s"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"bridge: {name} must be > 0")
        for name, hz in self.stream_rates_hz:
            if getattr(mavlink, f"MAVLINK_MSG_ID_{name}", None) is None or not (0.0 < hz <= 1000.0):
                raise ConfigError(f"bridge: stream_rates_hz: {name} at {hz} Hz is not a MAVLink message rate")


class Phase(enum.StrEnum):
    WAIT_EGO = "wait_ego"
    STREAM = "stream"
    SWITCH = "switch"
    ARM = "arm"
    ENGAGED = "engaged"
    TAKEOFF = "takeoff"
    SEARCH = "search"
    PRECLAND = "precland"
    DONE = "done"
    RELEASED = "released"
    LINK_LOST = "link_lost"


@dataclass
class BridgeStats:
    """What the bridge accepted and refused."""

    accepted: dict[str, int] = field(default_factory=dict)
    rejected: dict[str, int] = field(default_factory=dict)
    parse_errors: int = 0
    foreign: int = 0
    holds: int = 0
    setpoints_sent: int = 0
    landing_targets_sent: int = 0

    def ok(self, kind: str) -> None:
        self.accepted[kind] = self.accepted.get(kind, 0) + 1

    def bad(self, kind: str) -> None:
        self.rejected[kind] = self.rejected.get(kind, 0) + 1


INTERVAL_REQUESTS = 3
"""The bridge asks for its stream rates with each of the autopilot's first this many HEARTBEATs."""
FRAME_WAIT_MAX = 8
"""Frames stamped ahead of the autopilot's clock that wait for it (module docstring); a ninth is refused:
the clock has stopped, not lagged (at 20 Hz, 0.4 s of frames)."""


LANDED_STATE_NAMES = ("undefined", "on_ground", "in_air", "takeoff", "landing")
"""MAV_LANDED_STATE by value, as the bridge logs the autopilot's land detector (PX4 #14873: on a moving
deck)."""
PLATFORM_FIX_MAX_AGE_S = 5.0
"""A platform fix older than this on arrival is refused (the telemetry model's latency is at most 5 s)."""


def _finite(*values: float) -> bool:
    return all(isinstance(v, int | float) and math.isfinite(v) for v in values)


def _vec_ok(v: FloatArray, limit: float) -> bool:
    return bool(np.all(np.isfinite(v)) and np.max(np.abs(v)) <= limit)


class _NullLink:
    def write(self, data: bytes) -> None:
        pass


class MavlinkBridge:
    """Feeds MAVLink messages into a pipeline and turns its decisions into setpoints (see the module doc).

    ``link`` has a ``write(bytes)`` method (a pymavlink connection, or anything for tests); ``camera`` may
    be None (the bridge then never sees a frame: a camera stall in offboard mode)."""

    def __init__(
        self,
        pipeline: Pipeline,
        config: BridgeConfig,
        *,
        link: Any = None,
        camera: CameraSource | None = None,
        airframe: Airframe = DEFAULT_AIRFRAME,
        planner_rate_hz: float = 50.0,
        sysid: int = 1,
        compid: int = mavlink.MAV_COMP_ID_ONBOARD_COMPUTER,
    ) -> None:
        self.pipeline = pipeline
        self.config = config
        self.camera = camera
        self.airframe = airframe
        self.max_thrust_N = airframe.thrust_to_weight * airframe.weight_N
        self.mav = mavlink.MAVLink(_NullLink() if link is None else link, sysid, compid)
        self.mav.robust_parsing = True
        self._parser = mavlink.MAVLink(_NullLink(), 0, 0)
        self._parser.robust_parsing = True
        self.stats = BridgeStats()
        self.phase = Phase.WAIT_EGO
        self.events: list[dict[str, Any]] = []
        self.target_sys: int | None = None
        self.target_comp: int | None = None
        self.ap_armed = False
        self.ap_custom_mode: int | None = None
        self.landed_state = 0
        self.was_airborne = False
        self.t_ap = -math.inf  # the autopilot's clock (s), the latest accepted IMU time
        self._last: dict[str, float] = {}
        self._t_heartbeat_ap = -math.inf
        self._t_heartbeat_wall = time.monotonic()
        self._t_any_wall = time.monotonic()
        self._att_t = -math.inf
        self._q_WB: FloatArray | None = None
        self._odo_t = -math.inf
        self._ekf_t = -math.inf  # the latest time given to the ego filter by an odometry message
        self._frame_t = -math.inf
        self._next_control = -math.inf
        self._next_step = -math.inf
        self._control_dt = 1.0 / config.control_rate_hz
        self._step_dt = 1.0 / planner_rate_hz
        self._phase_t = 0.0
        self._last_cmd_t = -math.inf
        self._engaged_t: float | None = None
        self._hold_p: FloatArray | None = None
        self._hold_yaw = 0.0
        self.holding = False
        self.lockstep = False
        self.frame_seq_expected = 0
        self._clock_offset: float | None = None  # autopilot time - companion monotonic time
        self.log_rows: list[dict[str, Any]] = []
        self._next_log = -math.inf
        self.hold_times: list[float] = []
        self._disarm_sent = False
        self.frame_times: list[float] = []
        self._waiting_frames: list[tuple[float, np.ndarray]] = []  # stamped ahead of the clock (docstring)
        self._waiting_fixes: deque[PlatformFix] = deque()  # platform fixes waiting for the clock
        self._detector_state = TouchdownState.AIRBORNE
        # with position setpoints the autopilot's controller flies until ground contact (see _control)
        pipeline.touchdown.thrust_flown = config.setpoint == "rates"

    # -- bookkeeping -----------------------------------------------------------------------------------
    def _event(self, kind: str, **info: Any) -> None:
        t = self.t_ap if math.isfinite(self.t_ap) else None
        self.events.append({"t": t, "event": kind, **info})

    def _go(self, phase: Phase, why: str) -> None:
        if phase is not self.phase:
            self.phase = phase
            self._phase_t = self.t_ap
            self._event("phase", phase=phase.value, reason=why)

    def _fresh(self, kind: str, t: float) -> bool:
        """Timestamps of each stream strictly increase and do not run ahead of the autopilot's clock."""
        last = self._last.get(kind, -math.inf)
        if not t > last:
            return False
        if math.isfinite(self.t_ap) and t > self.t_ap + self.config.max_time_jump_s and kind != "imu":
            return False
        if kind == "imu" and math.isfinite(last) and t > last + self.config.max_time_jump_s:
            return False
        self._last[kind] = t
        return True

    # -- receive ---------------------------------------------------------------------------------------
    def feed_bytes(self, data: bytes) -> None:
        """Parse raw bytes from the link and handle every message in them."""
        try:
            msgs = self._parser.parse_buffer(data) or []
        except (mavlink.MAVError, ValueError, TypeError, IndexError, OverflowError, UnicodeDecodeError):
            # pymavlink's robust mode still raises on some corrupt payloads (a bad unpack, an invalid
            # enum string); the message is lost, the parser resynchronises on the next start byte.
            self.stats.parse_errors += 1
            return
        for msg in msgs:
            self.handle(msg)

    def handle(self, msg: Any) -> None:
        """One decoded message; anything unusable is counted and dropped."""
        self._t_any_wall = time.monotonic()
        kind = msg.get_type()
        if kind == "BAD_DATA":
            self.stats.parse_errors += 1
            return
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        if kind == "HEARTBEAT":
            self._on_heartbeat(msg, src)
            return
        if self.target_sys is None or src != (self.target_sys, self.target_comp):
            self.stats.foreign += 1
            return
        handler = _HANDLERS.get(kind)
        if handler is not None:
            handler(self, msg)

    def _on_heartbeat(self, msg: Any, src: tuple[int, int]) -> None:
        ap = msg.autopilot
        if ap == mavlink.MAV_AUTOPILOT_INVALID or msg.type in (
            mavlink.MAV_TYPE_GCS,
            mavlink.MAV_TYPE_ONBOARD_CONTROLLER,
        ):
            return  # a ground station or another companion
        if self.target_sys is None:
            self.target_sys, self.target_comp = src
            self._event("autopilot", sysid=src[0], compid=src[1], autopilot=int(ap))
        elif src != (self.target_sys, self.target_comp):
            self.stats.foreign += 1
            return
        self.stats.ok("HEARTBEAT")
        if self.stats.accepted["HEARTBEAT"] <= INTERVAL_REQUESTS:
            # sent again with the next HEARTBEATs: a command on UDP can be lost, and the rates are idempotent
            for name, hz in self.config.stream_rates_hz:
                msg_id = getattr(mavlink, f"MAVLINK_MSG_ID_{name}")
                self._command_long(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, float(msg_id), 1e6 / hz)
        self.ap_armed = bool(msg.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
        self.ap_custom_mode = int(msg.custom_mode)
        self._t_heartbeat_ap = self.t_ap
        self._t_heartbeat_wall = time.monotonic()

    def _on_highres_imu(self, msg: Any) -> None:
        t = msg.time_usec * 1e-6
        f = np.array([msg.xacc, msg.yacc, msg.zacc], dtype=float)
        w = np.array([msg.xgyro, msg.ygyro, msg.zgyro], dtype=float)
        self._imu("HIGHRES_IMU", t, f, w)

    def _on_scaled_imu(self, msg: Any) -> None:
        t = msg.time_boot_ms * 1e-3
        f = np.array([msg.xacc, msg.yacc, msg.zacc], dtype=float) * (GRAVITY / 1000.0)  # mG
        w = np.array([msg.xgyro, msg.ygyro, msg.zgyro], dtype=float) * 1e-3  # mrad/s
        self._imu("SCALED_IMU", t, f, w)

    def _imu(self, kind: str, t: float, f_FRD: FloatArray, w_FRD: FloatArray) -> None:
        if not (_finite(t) and _vec_ok(f_FRD, MAX_ACCEL) and _vec_ok(w_FRD, MAX_RATE)) or not self._fresh(
            "imu", t
        ):
            self.stats.bad(kind)
            return
        self.stats.ok(kind)
        self.t_ap = t
        if t > self._ekf_t:
            # An odometry message newer than this sample has already moved the filter past it (the
            # autopilot's streams are not ordered with each other): the sample is skipped.
            self._feed(self.pipeline.on_imu, t, frames.frd_to_flu(f_FRD), frames.frd_to_flu(w_FRD))
        self._advance(t)

    def _feed(self, fn: Any, t: float, *args: Any) -> None:
        try:
            fn(t, *args)
        except EstimationError as err:  # the filter refused it (its own checks): counted, not fatal
            self.stats.bad("pipeline")
            self._event("pipeline_rejected", error=str(err)[:120])

    def _same_attitude(self, t: float) -> bool:
        """An attitude stamped like the one just taken: the same estimate in the other message (an
        autopilot sends both ATTITUDE_QUATERNION and ATTITUDE of each time); skipped, not an error."""
        return self._last.get("attitude") == t

    def _on_attitude_quaternion(self, msg: Any) -> None:
        t = msg.time_boot_ms * 1e-3
        if self._same_attitude(t):
            return
        q = np.array([msg.q1, msg.q2, msg.q3, msg.q4], dtype=float)
        n = float(np.linalg.norm(q)) if np.all(np.isfinite(q)) else math.nan
        if not (0.9 < n < 1.1) or not self._fresh("attitude", t):
            self.stats.bad("ATTITUDE_QUATERNION")
            return
        self.stats.ok("ATTITUDE_QUATERNION")
        self._att_t, self._q_WB = t, frames.mavlink_to_q_WB(q)

    def _on_attitude(self, msg: Any) -> None:
        t = msg.time_boot_ms * 1e-3
        if self._same_attitude(t):
            return
        e = (msg.roll, msg.pitch, msg.yaw)
        if not (_finite(*e) and max(abs(v) for v in e) <= 2 * math.pi) or not self._fresh("attitude", t):
            self.stats.bad("ATTITUDE")
            return
        self.stats.ok("ATTITUDE")
        self._att_t, self._q_WB = t, frames.euler_ned_frd_to_q_WB(*e)

    def _on_odometry(self, msg: Any) -> None:
        t = msg.time_usec * 1e-6
        p = np.array([msg.x, msg.y, msg.z], dtype=float)
        v = np.array([msg.vx, msg.vy, msg.vz], dtype=float)
        q = np.array(msg.q, dtype=float)
        n = float(np.linalg.norm(q)) if q.shape == (4,) and np.all(np.isfinite(q)) else math.nan
        frames_ok = msg.frame_id == mavlink.MAV_FRAME_LOCAL_NED and msg.child_frame_id in (
            mavlink.MAV_FRAME_LOCAL_NED,
            mavlink.MAV_FRAME_BODY_FRD,
        )
        if not (
            frames_ok and _finite(t) and _vec_ok(p, MAX_POSITION) and _vec_ok(v, MAX_SPEED) and 0.9 < n < 1.1
        ):
            self.stats.bad("ODOMETRY")
            return
        if not self._fresh("odometry", t):
            self.stats.bad("ODOMETRY")
            return
        q_WB = frames.mavlink_to_q_WB(q)
        if msg.child_frame_id == mavlink.MAV_FRAME_BODY_FRD:  # PX4 sends the velocity in the body frame
            v_W = quat_to_rotmat(q_WB) @ frames.frd_to_flu(v)
        else:
            v_W = frames.ned_to_enu(v)
        self.stats.ok("ODOMETRY")
        # reset_counter (a MAVLink 2 extension; 0 from a sender that does not fill it): when it changes,
        # the autopilot's or the VIO's frame jumped, and the pipeline keeps its own frame continuous
        counter = getattr(msg, "reset_counter", None)
        self._odometry(t, frames.ned_to_enu(p), q_WB, v_W, counter if isinstance(counter, int) else None)

    def _on_local_position(self, msg: Any) -> None:
        t = msg.time_boot_ms * 1e-3
        p = np.array([msg.x, msg.y, msg.z], dtype=float)
        v = np.array([msg.vx, msg.vy, msg.vz], dtype=float)
        if not (_finite(t) and _vec_ok(p, MAX_POSITION) and _vec_ok(v, MAX_SPEED)) or not self._fresh(
            "local_position", t
        ):
            self.stats.bad("LOCAL_POSITION_NED")
            return
        self.stats.ok("LOCAL_POSITION_NED")
        # Used only when the autopilot sends no ODOMETRY, with an attitude of about the same time.
        if (
            t - self._last.get("odometry", -math.inf) < 0.5
            or self._q_WB is None
            or abs(t - self._att_t) > 0.1
        ):
            return
        self._odometry(t, frames.ned_to_enu(p), self._q_WB, frames.ned_to_enu(v))

    def _odometry(
        self, t: float, p_WB: FloatArray, q_WB: FloatArray, v_WB: FloatArray, reset_counter: int | None = None
    ) -> None:
        self._odo_t = t
        self._ekf_t = max(self._ekf_t, t)
        self._feed(self.pipeline.on_odometry, t, p_WB, q_WB, v_WB, reset_counter)

    def _on_distance(self, msg: Any) -> None:
        t = msg.time_boot_ms * 1e-3
        if msg.orientation != mavlink.MAV_SENSOR_ROTATION_PITCH_270 or not self._fresh("range", t):
            self.stats.bad("DISTANCE_SENSOR")
            return
        self.stats.ok("DISTANCE_SENSOR")
        if self.pipeline.ego_initialized:
            self.pipeline.on_range(t, distance_sensor_range_m(msg))

    def _on_optical_flow_rad(self, msg: Any) -> None:
        t = msg.time_usec * 1e-6
        flow = optical_flow_rad_B(msg)
        if flow is None or not self._fresh("flow", t):
            self.stats.bad("OPTICAL_FLOW_RAD")
            return
        self.stats.ok("OPTICAL_FLOW_RAD")
        if self.pipeline.ego_initialized:
            self.pipeline.on_flow(t, flow, float(msg.distance))

    def _on_extended_sys_state(self, msg: Any) -> None:
        if msg.landed_state in (0, 1, 2, 3, 4):
            if int(msg.landed_state) != self.landed_state:  # the autopilot's land detector, as it says
                self._event("autopilot_landed_state", state=LANDED_STATE_NAMES[int(msg.landed_state)])
            self.landed_state = int(msg.landed_state)
            if msg.landed_state == mavlink.MAV_LANDED_STATE_IN_AIR:
                self.was_airborne = True

    def _on_named_value_int(self, msg: Any) -> None:
        name = msg.name if isinstance(msg.name, str) else ""
        name = name.rstrip("\0")
        if name == LOCKSTEP_NAME and not self.lockstep:
            self.lockstep = True
            self._event("lockstep")
        elif name == FRAME_SEQ_NAME and msg.value > self.frame_seq_expected:
            self.frame_seq_expected = int(msg.value)

    def _on_timesync(self, msg: Any) -> None:
        if msg.tc1 == 0 and math.isfinite(self.t_ap):  # a request: answer with our (the autopilot's) clock
            self.mav.timesync_send(int(self.t_ap * 1e9), msg.ts1)

    def _on_command_ack(self, msg: Any) -> None:
        self._event("ack", command=int(msg.command), result=int(msg.result))

    def _on_statustext(self, msg: Any) -> None:
        text = msg.text if isinstance(msg.text, str) else ""
        self._event("statustext", text=text.rstrip("\0")[:50])

    # -- time advances ---------------------------------------------------------------------------------
    def _advance(self, t: float) -> None:
        self._read_camera(t)
        if t >= self._next_control:
            self._next_control = max(self._next_control + self._control_dt, t - 1e-9 + 0.5 * self._control_dt)
            self._control(t)
        if self.lockstep:
            self.mav.named_value_int_send(int(round(t * 1e3)), LOCKSTEP_ACK_NAME.encode(), 0)

    def _read_camera(self, t: float) -> None:
        cam = self.camera
        if cam is None:
            return
        while self._waiting_frames and self._waiting_frames[0][0] <= t + 1e-6:
            self._use_frame(t, *self._waiting_frames.pop(0))
        if isinstance(cam, SocketCameraSource) and self.lockstep:
            # The emulator announced a frame on MAVLink: wait for it on the camera stream (lockstep).
            deadline = time.monotonic() + 1.0
            while cam.last_seq < self.frame_seq_expected and time.monotonic() < deadline:
                frame = cam.read()
                if frame is not None:
                    self._on_frame(t, *frame)
                else:
                    time.sleep(0.0005)
        while True:
            frame = cam.read()
            if frame is None:
                break
            self._on_frame(t, *frame)
        if isinstance(cam, SocketCameraSource):
            self._platform_fixes(t, cam.read_platform_fixes())

    def _platform_fixes(self, t: float, arrived: list[PlatformFix]) -> None:
        """Hand the platform fixes whose stamp the clock has reached to the pipeline (module docstring)."""
        for fix in arrived:
            if fix.t_stamp > t + self.config.max_time_jump_s:
                self.stats.bad("platform_fix")
                self.stats.bad("platform_fix_ahead")
            else:
                self._waiting_fixes.append(fix)
        waiting = self._waiting_fixes
        while waiting and waiting[0].t_stamp <= t + 1e-6:
            fix = waiting.popleft()
            if t - fix.t_stamp > PLATFORM_FIX_MAX_AGE_S:
                self.stats.bad("platform_fix")
                self.stats.bad("platform_fix_late")
            elif not self._fresh("platform_fix", fix.t_stamp):
                self.stats.bad("platform_fix")
                self.stats.bad("platform_fix_order")
            else:
                self.stats.ok("platform_fix")
                self._feed(self._on_telemetry, fix.t_stamp, fix, t)

    def _on_telemetry(self, t_stamp: float, fix: PlatformFix, now: float) -> None:
        self.pipeline.on_telemetry(t_stamp, fix.p_WP, fix.v_WP, fix.cov_p_WP, now=now)

    def _on_frame(self, t: float, t_cap: float, image: np.ndarray) -> None:
        if cam_clock_is_companion(self.camera):
            if self._clock_offset is None:
                return
            t_cap = t_cap + self._clock_offset - self.config.camera_latency_s
        why = self._frame_refusal(t, t_cap)
        if why is not None:
            self.stats.bad("frame")
            self.stats.bad(why)
            return
        if t_cap > t + 1e-6:
            self._waiting_frames.append((t_cap, image))
            return
        self._use_frame(t, t_cap, image)

    def _frame_refusal(self, t: float, t_cap: float) -> str | None:
        """Why a frame stamped ``t_cap`` is refused at autopilot time ``t``, or None (it is used, or waits
        for the clock to reach its stamp)."""
        if not _finite(t_cap):
            return "frame_bad_time"
        if t - t_cap >= 2.0:
            return "frame_late"
        last = self._waiting_frames[-1][0] if self._waiting_frames else self._last.get("frame", -math.inf)
        if not t_cap > last:
            return "frame_order"
        if t_cap > t + 1e-6 and (
            t_cap > t + self.config.max_time_jump_s or len(self._waiting_frames) >= FRAME_WAIT_MAX
        ):
            return "frame_ahead"
        return None

    def _use_frame(self, t: float, t_cap: float, image: np.ndarray) -> None:
        if not self._fresh("frame", t_cap):  # the stamps were checked in _frame_refusal; kept in order
            self.stats.bad("frame")
            self.stats.bad("frame_order")
            return
        self.stats.ok("frame")
        self._frame_t = t
        self.frame_times.append(t)
        if not self.pipeline.ego_initialized:
            return
        self._feed(self.pipeline.on_image, t_cap, image)
        if self.config.mode == "landing-target" and self.phase in (Phase.SEARCH, Phase.PRECLAND):
            self._send_landing_target(t)

    def note_wall_clock(self) -> None:
        """Refresh the companion-to-autopilot clock offset (for a companion-clock camera)."""
        if math.isfinite(self.t_ap):
            off = self.t_ap - time.monotonic()
            self._clock_offset = off if self._clock_offset is None else max(self._clock_offset, off)

    # -- control ---------------------------------------------------------------------------------------
    def link_lost(self) -> bool:
        cfg = self.config
        if self.phase is Phase.LINK_LOST:
            return True
        # Wall time counts only while nothing at all arrives: after a stall of the bridge's own (a kernel
        # compiling, a loaded machine) the backlog is handled in order, and its IMU messages must not
        # find the link lost before the HEARTBEAT queued behind them is read.
        quiet_wall = time.monotonic() - max(self._t_heartbeat_wall, self._t_any_wall)
        quiet_ap = self.t_ap - self._t_heartbeat_ap if math.isfinite(self._t_heartbeat_ap) else 0.0
        if quiet_ap > cfg.link_timeout_s:
            self._go(Phase.LINK_LOST, f"no HEARTBEAT for {quiet_ap:.1f} s of autopilot time")
            return True
        if quiet_wall > max(cfg.link_timeout_s, 5.0):
            self._go(Phase.LINK_LOST, f"nothing received for {quiet_wall:.1f} s")
            return True
        return False

    def _custom_mode_is(self, want: tuple[int, int] | int) -> bool:
        cm = self.ap_custom_mode
        if cm is None:
            return False
        if isinstance(want, tuple):
            main, sub = (cm >> 16) & 0xFF, (cm >> 24) & 0xFF
            return (main, sub if main == 4 else 0) == want
        return cm == want

    def _request_mode(self, px4: tuple[int, int], ardupilot: int) -> None:
        if self.config.autopilot == "px4":
            p1, p2, p3 = float(mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), float(px4[0]), float(px4[1])
        else:
            p1, p2, p3 = float(mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), float(ardupilot), 0.0
        self._command_long(mavlink.MAV_CMD_DO_SET_MODE, p1, p2, p3)

    def _command_long(self, command: int, *params: float) -> None:
        p = list(params) + [0.0] * (7 - len(params))
        self.mav.command_long_send(self.target_sys or 1, self.target_comp or 1, command, 0, *p)
        self._event("command", command=int(command), params=[float(x) for x in p[:3]])

    def _arm(self) -> None:
        if not self.config.arm:  # never: the configuration forbids it
            raise RuntimeError("the bridge must not arm when the configuration does not allow it")
        self._command_long(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1.0)

    def _retry(self, t: float, every_s: float = 1.0, what: str = "") -> bool:
        """True once every ``every_s`` per phase and ``what`` (to resend an unanswered command)."""
        key = f"retry_{self.phase.value}_{what}"
        if t - self._last.get(key, -math.inf) >= every_s:
            self._last[key] = t
            return True
        return False

    def _control(self, t: float) -> None:
        if self.phase in (Phase.LINK_LOST, Phase.DONE, Phase.RELEASED) or self.link_lost():
            return
        pipe = self.pipeline
        if not pipe.ego_initialized or self.target_sys is None:
            return
        ego = pipe.ego()
        cfg = self.config
        if self.phase is Phase.WAIT_EGO:
            self._go(Phase.STREAM if cfg.mode == "offboard" else Phase.TAKEOFF, "ego estimate ready")
        self._log(t)
        if cfg.mode == "landing-target":
            pipe.history.add(t, ego.p_WB, ego.q_WB, ego.v_WB)
            self._landing_target_phases(t, ego.p_WB)
            return
        if self.phase is not Phase.ENGAGED:
            pipe.history.add(t, ego.p_WB, ego.q_WB, ego.v_WB)
            self._send_hold(t, ego.p_WB, ego.q_WB)
            offboard_mode = self._custom_mode_is(PX4_OFFBOARD if cfg.autopilot == "px4" else AP_GUIDED)
            if self.phase is Phase.STREAM and t - self._phase_t >= cfg.stream_before_s:
                self._go(Phase.SWITCH, "setpoints streaming")
            if self.phase is Phase.SWITCH:
                if offboard_mode:
                    self._go(Phase.ARM, "in offboard")
                elif self._retry(t):
                    self._request_mode(PX4_OFFBOARD, AP_GUIDED)
            if self.phase is Phase.ARM:
                if self.ap_armed:
                    self._engaged_t = t
                    self.holding = False
                    self._go(Phase.ENGAGED, "armed in offboard")
                elif cfg.arm and self._retry(t):
                    self._arm()
            return
        # ENGAGED
        if not self._custom_mode_is(PX4_OFFBOARD if cfg.autopilot == "px4" else AP_GUIDED):
            self._go(Phase.RELEASED, "the autopilot left offboard (failsafe or pilot)")
            return
        if self._touched_down():
            self._motors_off(t)
            return
        stalled = t - self._frame_t > cfg.camera_timeout_s or t - self._odo_t > cfg.ego_timeout_s
        if stalled:
            if not self.holding:
                self._event("hold", camera_age_s=t - self._frame_t, ego_age_s=t - self._odo_t)
                self._hold_p = None
            self.holding = True
            pipe.history.add(t, ego.p_WB, ego.q_WB, ego.v_WB)
            self._send_hold(t, ego.p_WB, ego.q_WB)
            return
        if self.holding:
            self._event("resume")
            self.holding = False
        if t >= self._next_step:
            self._next_step = max(self._next_step + self._step_dt, t + 0.5 * self._step_dt - 1e-9)
            pipe.step(t)
        cmd = pipe.command(t)
        if cmd.motors_off and self._touched_down():
            self._motors_off(t)
            return
        if self._suppressed(t):
            return
        self._send_command(t, cmd)

    def _send_command(self, t: float, cmd: Command) -> None:
        """The pipeline's command to the autopilot as body rates and thrust, or as its reference's position,
        velocity and acceleration (``setpoint``)."""
        cfg, pipe = self.config, self.pipeline
        # On ground contact the land detector tests the contact by spooling the thrust down (a vehicle in
        # the air sinks and the detector lets go; one on the deck stays): with position setpoints PX4's
        # controller would hold the descent and the test would pass in the air (a disarm 0.2 m above the
        # deck with real PX4), so from ground contact on the pipeline's own thrust and rates fly
        detector = pipe.touchdown
        contact = detector.state is not TouchdownState.AIRBORNE
        if detector.state is not self._detector_state:  # what the land detector saw, for the log
            self._detector_state = detector.state
            self._event("land_detector", state=detector.state.value, **detector.evidence)
        if cfg.setpoint == "rates" or cmd.motors_off or contact:
            thrust = 0.0 if cmd.motors_off else min(max(cmd.thrust_N / self.max_thrust_N, 0.0), 1.0)
            w = np.zeros(3) if cmd.motors_off else frames.flu_to_frd(cmd.w_WB_B_cmd)
            self.mav.set_attitude_target_send(
                int(round(t * 1e3)), self.target_sys, self.target_comp or 0, MASK_RATES_THRUST,
                [1.0, 0.0, 0.0, 0.0], float(w[0]), float(w[1]), float(w[2]), float(thrust),
            )  # fmt: skip
        else:
            ref = pipe.last_reference
            if ref is None:
                return
            p, v, a = frames.enu_to_ned(ref.p), frames.enu_to_ned(ref.v), frames.enu_to_ned(ref.a)
            self.mav.set_position_target_local_ned_send(
                int(round(t * 1e3)), self.target_sys, self.target_comp or 0, mavlink.MAV_FRAME_LOCAL_NED,
                MASK_PVA_YAW, *p, *v, *a, frames.yaw_enu_to_ned(ref.yaw), 0.0,
            )  # fmt: skip
        self.stats.setpoints_sent += 1
        self._last_cmd_t = t

    def _touched_down(self) -> bool:
        """The pipeline's land detector decided the touchdown (or its mission says landed): from now on
        its command is ``motors_off``."""
        pipe = self.pipeline
        return pipe.status.mode is Mode.LANDED or pipe.touchdown.state is TouchdownState.LANDED

    def _motors_off(self, t: float) -> None:
        """The pipeline stopped its motors after touchdown: tell the autopilot. What PX4 users do after an
        offboard landing is disarm (MAV_CMD_COMPONENT_ARM_DISARM param1 = 0): a thrust of 0 in OFFBOARD
        only idles the motors (PX4 keeps them spinning at idle while armed), and PX4's own land detector,
        which would disarm by itself after ``COM_DISARM_LAND``, does not know the deck moves. The bridge
        forces it (param2 = 21196: PX4 refuses a plain disarm until its land detector agrees), resent
        every 0.5 s until the HEARTBEAT shows the vehicle disarmed, and meanwhile keeps the offboard
        stream alive with zero thrust and zero rates, so no offboard-loss failsafe takes over."""
        if not self.ap_armed and self._disarm_sent:
            self._go(Phase.DONE, "landed and disarmed")
            return
        if self._suppressed(t):
            return
        self.mav.set_attitude_target_send(
            int(round(t * 1e3)), self.target_sys or 1, self.target_comp or 0, MASK_RATES_THRUST,
            [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, 0.0,
        )  # fmt: skip
        self.stats.setpoints_sent += 1
        self._last_cmd_t = t
        if self.ap_armed and self._retry(t, 0.5, "disarm"):
            if not self._disarm_sent:
                self._event("motors_off", reason="the pipeline's land detector")
            self._command_long(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0.0, float(FORCE_DISARM))
            self._disarm_sent = True

    def _suppressed(self, t: float) -> bool:
        stop = self.config.stop_setpoints_after_s
        return stop is not None and self._engaged_t is not None and t - self._engaged_t >= stop

    def _send_hold(self, t: float, p_WB: FloatArray, q_WB: FloatArray) -> None:
        if self._hold_p is None:
            self._hold_p = np.array(p_WB, dtype=float)
            self._hold_yaw = yaw_of(quat_to_rotmat(q_WB))
        if self._suppressed(t):
            return
        p = frames.enu_to_ned(self._hold_p)
        self.mav.set_position_target_local_ned_send(
            int(round(t * 1e3)), self.target_sys or 1, self.target_comp or 0, mavlink.MAV_FRAME_LOCAL_NED,
            MASK_P_YAW, *p, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, frames.yaw_enu_to_ned(self._hold_yaw), 0.0,
        )  # fmt: skip
        self.stats.holds += 1
        self.hold_times.append(t)

    # -- landing-target mode ---------------------------------------------------------------------------
    def _landing_target_phases(self, t: float, p_WB: FloatArray) -> None:
        cfg = self.config
        if self.phase is Phase.TAKEOFF:
            guided = self._custom_mode_is(PX4_TAKEOFF if cfg.autopilot == "px4" else AP_GUIDED)
            if not guided and not self.ap_armed:
                if self._retry(t):
                    self._request_mode(PX4_TAKEOFF, AP_GUIDED)
            elif not self.ap_armed:
                if cfg.arm and self._retry(t):
                    self._arm()
            elif cfg.autopilot == "ardupilot":
                # ArduCopter takes off in GUIDED on MAV_CMD_NAV_TAKEOFF, param7 = height above home (m).
                if p_WB[2] < 0.8 * cfg.takeoff_height_m and self._retry(t, 2.0, "takeoff"):
                    self._command_long(mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan,
                                       float(cfg.takeoff_height_m))  # fmt: skip
                if p_WB[2] > 0.8 * cfg.takeoff_height_m:
                    self._go(Phase.SEARCH, "took off")
            elif not guided and p_WB[2] > 1.0:
                # PX4 AUTO.TAKEOFF climbs by itself once armed, to MIS_TAKEOFF_ALT (its param7 would be
                # AMSL, which the bridge does not know), then switches to AUTO.LOITER.
                self._go(Phase.SEARCH, "took off")
        elif self.phase is Phase.SEARCH:
            target = self.pipeline.target(t)
            if target is not None and t - target.t_last_measurement < 0.5:
                self._go(Phase.PRECLAND, "target found")
        elif self.phase is Phase.PRECLAND:
            if not self._custom_mode_is(PX4_PRECLAND if cfg.autopilot == "px4" else AP_LAND) and self._retry(
                t
            ):
                self._request_mode(PX4_PRECLAND, AP_LAND)
            if self.was_airborne and (
                self.landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND or not self.ap_armed
            ):
                self._go(Phase.DONE, "landed")

    def _send_landing_target(self, t: float) -> None:
        target = self.pipeline.target(t)
        if target is None or t - target.t_last_measurement > 3.0:  # the estimate carries short gaps
            return
        ego = self.pipeline.ego()
        rel_W = target.p_WP - ego.p_WB
        rel_FRD = frames.flu_to_frd(quat_to_rotmat(ego.q_WB).T @ rel_W)
        dist = float(np.linalg.norm(rel_FRD))
        if not (math.isfinite(dist) and dist > 1e-3 and rel_FRD[2] > 1e-3):
            return
        # +angle_x: target to the right, +angle_y: target aft, for a downward camera with image top forward.
        angle_x = math.atan2(rel_FRD[1], rel_FRD[2])
        angle_y = math.atan2(-rel_FRD[0], rel_FRD[2])
        if self.config.autopilot == "px4":
            frame, xyz = mavlink.MAV_FRAME_LOCAL_NED, frames.enu_to_ned(target.p_WP)
        else:
            frame, xyz = mavlink.MAV_FRAME_BODY_FRD, rel_FRD
        self.mav.landing_target_send(
            int(round(t * 1e6)), 0, frame, angle_x, angle_y, dist, 0.0, 0.0,
            float(xyz[0]), float(xyz[1]), float(xyz[2]), [1.0, 0.0, 0.0, 0.0],
            mavlink.LANDING_TARGET_TYPE_VISION_FIDUCIAL, 1,
        )  # fmt: skip
        self.stats.landing_targets_sent += 1

    # -- log ---------------------------------------------------------------------------------------------
    def _log(self, t: float) -> None:
        if t < self._next_log:
            return
        self._next_log = t + 0.02 - 1e-9
        pipe = self.pipeline
        ego = pipe.ego()
        target = pipe.target(t)
        ref = pipe.last_reference
        self.log_rows.append(
            {
                "t": t,
                "mode": pipe.status.mode.value if self.config.mode == "offboard" else self.phase.value,
                "p_WB_est": ego.p_WB,
                "v_WB_est": ego.v_WB,
                "p_WP_est": None if target is None else target.p_WP,
                "v_WP_est": None if target is None else target.v_WP,
                "p_ref": None if ref is None else ref.p,
                "v_ref": None if ref is None else ref.v,
                "range_m": pipe.range_m,
            }
        )

    def send_heartbeat(self) -> None:
        self.mav.heartbeat_send(mavlink.MAV_TYPE_ONBOARD_CONTROLLER, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)


def distance_sensor_range_m(msg: Any) -> float:
    """A DISTANCE_SENSOR reading (m) as the pipeline takes it, the range finder's ROS REP 117 convention:
    ``-inf`` closer than the sensor's minimum (``current_distance`` below ``min_distance``), ``+inf`` beyond
    its maximum or without a return (above ``max_distance``, UINT16_MAX); with ``signal_quality`` 1
    ("invalid signal") a reading at or below the minimum is ``-inf`` and any other ``+inf``. The emulated
    autopilot encodes its sensor's +-inf this way (``alight.interfaces.sitl.distance_sensor_fields``)."""
    cm, lo, hi = int(msg.current_distance), int(msg.min_distance), int(msg.max_distance)
    invalid = getattr(msg, "signal_quality", 0) == 1
    if cm == 65535 or cm > hi or (invalid and cm > lo):
        return math.inf
    if cm < lo or invalid:
        return -math.inf
    return cm / 100.0


MAX_FLOW_RATE_RAD_S = 50.0
"""An OPTICAL_FLOW_RAD whose mean flow rate is above this (rad/s) is not a reading but garbage."""


def optical_flow_rad_B(msg: Any) -> FloatArray | None:
    """An OPTICAL_FLOW_RAD sample as the pipeline takes it (``Pipeline.on_flow``): the mean flow rate over
    the integration along x_B and y_B of alight's FLU body frame (rad/s, not gyro-compensated), or None
    for a sample to drop (quality 0, no integration time, no distance, a field not finite or out of
    range). MAVLink's integrated_x is the flow *around* the FRD x axis (a right-hand rotation about x or
    a motion along -y gives a positive flow), integrated_y around the FRD y axis (a rotation about y or
    a motion along +x); alight's flow along x_B is minus the rate around y_FRD, along y_B minus the rate
    around x_FRD."""
    dt = msg.integration_time_us * 1e-6
    ix, iy, d = float(msg.integrated_x), float(msg.integrated_y), float(msg.distance)
    if not (0.0 < dt <= 1.0 and msg.quality > 0 and math.isfinite(ix) and math.isfinite(iy)):
        return None
    if not (math.isfinite(d) and d > 0.0):
        return None
    rate = np.array([-iy / dt, -ix / dt])
    if float(np.max(np.abs(rate))) > MAX_FLOW_RATE_RAD_S:
        return None
    return rate


def cam_clock_is_companion(camera: CameraSource | None) -> bool:
    return camera is not None and camera.clock == "companion"


_HANDLERS = {
    "HIGHRES_IMU": MavlinkBridge._on_highres_imu,
    "SCALED_IMU": MavlinkBridge._on_scaled_imu,
    "ATTITUDE_QUATERNION": MavlinkBridge._on_attitude_quaternion,
    "ATTITUDE": MavlinkBridge._on_attitude,
    "ODOMETRY": MavlinkBridge._on_odometry,
    "LOCAL_POSITION_NED": MavlinkBridge._on_local_position,
    "DISTANCE_SENSOR": MavlinkBridge._on_distance,
    "OPTICAL_FLOW_RAD": MavlinkBridge._on_optical_flow_rad,
    "EXTENDED_SYS_STATE": MavlinkBridge._on_extended_sys_state,
    "NAMED_VALUE_INT": MavlinkBridge._on_named_value_int,
    "TIMESYNC": MavlinkBridge._on_timesync,
    "COMMAND_ACK": MavlinkBridge._on_command_ack,
    "STATUSTEXT": MavlinkBridge._on_statustext,
}


def open_link(url: str, *, sysid: int = 1, compid: int = mavlink.MAV_COMP_ID_ONBOARD_COMPUTER) -> Any:
    """A pymavlink connection. ``udp:HOST:PORT`` connects to an autopilot listening there (the emulated
    one); ``udpin:HOST:PORT`` listens (PX4's onboard link sends to the companion's port 14540); a serial
    device ``/dev/ttyACM0:921600`` or ``serial:/dev/ttyUSB0:921600``; ``tcp:HOST:PORT``."""
    if url.startswith("udp:"):
        device = "udpout:" + url[4:]
    elif url.startswith("serial:"):
        device = url[7:]
    else:
        device = url
    try:
        return mavutil.mavlink_connection(
            device, source_system=sysid, source_component=compid, dialect="common"
        )
    except (OSError, ValueError) as err:
        raise ConfigError(f"bridge: cannot open {url!r} ({err})") from None


def pump(bridge: MavlinkBridge, conn: Any, timeout_s: float) -> None:
    """Wait up to ``timeout_s`` for bytes on ``conn`` and feed everything that is there to the bridge."""
    port = getattr(conn, "port", None)
    if port is not None and hasattr(port, "fileno"):
        select.select([port], [], [], timeout_s)
    while True:
        try:
            data = conn.recv()
        except OSError:
            return
        if not data:
            return
        bridge.feed_bytes(bytes(data))
