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
* Modes. PX4: POSCTL (3) and AUTO.LOITER (4/3) hold position, OFFBOARD (6), AUTO.TAKEOFF (4/2),
  AUTO.LAND (4/6), AUTO.PRECLAND (4/9); MANUAL (1) is treated as a hold (there is no RC). ArduCopter:
  STABILIZE (0), LOITER (5), POSHOLD (16) hold, GUIDED (4) takes setpoints, LAND (9) is a precision
  land when LANDING_TARGET messages arrive (as with ``PLND_ENABLED`` = 1), a plain land otherwise.
* ``MAV_CMD_DO_SET_MODE`` (176) and ``MAV_CMD_COMPONENT_ARM_DISARM`` (400), ``MAV_CMD_NAV_TAKEOFF`` (22,
  param7 = height above the take-off point; a real PX4 reads param7 as AMSL), each answered with
  COMMAND_ACK. Disarming in the air is refused unless forced (param2 = 21196), as on PX4.
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
  land detector or a disarm after the flight), and answers to TIMESYNC requests.
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
import time
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
PX4_SUB_TAKEOFF, PX4_SUB_LOITER, PX4_SUB_LAND, PX4_SUB_PRECLAND = 2, 3, 6, 9
# ArduCopter mode numbers (COPTER_MODE).
AP_STABILIZE, AP_GUIDED, AP_LOITER, AP_LAND, AP_POSHOLD = 0, 4, 5, 9, 16


def px4_custom_mode(main: int, sub: int = 0) -> int:
    return (main << 16) | (sub << 24)


class FlightMode(enum.StrEnum):
    """What the emulated autopilot does, whatever the flavour calls it."""

    HOLD = "hold"
    OFFBOARD = "offboard"
    TAKEOFF = "takeoff"
    LAND = "land"
    PRECLAND = "precland"


_PX4_MODES: dict[tuple[int, int], FlightMode] = {
    (PX4_MAIN_MANUAL, 0): FlightMode.HOLD,
    (PX4_MAIN_POSCTL, 0): FlightMode.HOLD,
    (PX4_MAIN_OFFBOARD, 0): FlightMode.OFFBOARD,
    (PX4_MAIN_AUTO, PX4_SUB_TAKEOFF): FlightMode.TAKEOFF,
    (PX4_MAIN_AUTO, PX4_SUB_LOITER): FlightMode.HOLD,
    (PX4_MAIN_AUTO, PX4_SUB_LAND): FlightMode.LAND,
    (PX4_MAIN_AUTO, PX4_SUB_PRECLAND): FlightMode.PRECLAND,
}
_AP_MODES: dict[int, FlightMode] = {
    AP_STABILIZE: FlightMode.HOLD,
    AP_LOITER: FlightMode.HOLD,
    AP_POSHOLD: FlightMode.HOLD,
    AP_GUIDED: FlightMode.OFFBOARD,
    AP_LAND: FlightMode.PRECLAND,
}


def encode_mode(flavour: str, mode: FlightMode) -> int:
    """The HEARTBEAT ``custom_mode`` of ``mode``."""
    if flavour == "ardupilot":
        return {
            FlightMode.HOLD: AP_LOITER,
            FlightMode.OFFBOARD: AP_GUIDED,
            FlightMode.TAKEOFF: AP_GUIDED,
            FlightMode.LAND: AP_LAND,
            FlightMode.PRECLAND: AP_LAND,
        }[mode]
    main, sub = {
        FlightMode.HOLD: (PX4_MAIN_POSCTL, 0),
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


class EmulatedAutopilot:
    """The MAVLink endpoint and the autopilot's logic around a :class:`~alight.sim.world.World`."""

    def __init__(self, scenario: Scenario, config: SitlConfig, airframe: Airframe | None = None) -> None:
        if config.flavour not in ("px4", "ardupilot"):
            raise ConfigError(f"sitl: flavour must be px4 or ardupilot, got {config.flavour!r}")
        if scenario.platform.telemetry is not None:
            # The emulator has no MAVLink stream for the platform's GNSS fix, so it would not reach the
            # companion: refuse it rather than fly without it.
            raise ConfigError("platform.telemetry: not available through alight sitl (no MAVLink stream)")
        if scenario.optical_flow is not None:
            # likewise: the emulator does not send OPTICAL_FLOW_RAD
            raise ConfigError("optical_flow: not available through alight sitl (no MAVLink stream)")
        self.config = config
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
        self.takeoff_height_m = config.takeoff_height_m
        self.target: dict[str, Any] | None = None  # alpha-beta state of the landing target
        self.peer_seen = False
        self._px4 = config.flavour == "px4"
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
        self.mav.command_ack_send(command, result)

    def _set_mode(self, mode: FlightMode, why: str) -> None:
        if mode is self.mode:
            return
        p = self.world.x[SL_P]
        self.mode = mode
        if mode is FlightMode.TAKEOFF:
            self.takeoff_z = None
        if mode is FlightMode.HOLD:
            self.hold_p = p.copy()
            self.hold_p[2] = max(p[2], self.airframe.gear_height)
        if mode in (FlightMode.HOLD, FlightMode.LAND, FlightMode.PRECLAND, FlightMode.TAKEOFF):
            self.hold_yaw = yaw_of(quat_to_rotmat(self.world.x[SL_Q]))
            self.hold_p = p.copy()
        # a failsafe's land ends wherever the vehicle is: touching the ground is its safe end (aborted)
        # a failsafe's land: touching the ground is its safe end, and a safe settling scores aborted
        self.world.ground_ok = self.world.aborting = mode is FlightMode.LAND and why == "offboard loss"
        self._event("mode", mode=mode.value, reason=why)

    @property
    def landed(self) -> bool:
        """What the emulated autopilot believes (EXTENDED_SYS_STATE): on the ground before take-off,
        after its land detector said landed, or disarmed after a flight; in the air otherwise."""
        w = self.world
        return not w.airborne or self._land_detected or (not self.armed and w.t_motors_off is not None)

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
        landing = self.mode in (FlightMode.LAND, FlightMode.PRECLAND)
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
        return self.setpoint is not None and t - self.setpoint.t <= self.config.loss_s

    def handle(self, msg: Any) -> None:
        kind = msg.get_type()
        t = self.world.t
        if kind == "HEARTBEAT":
            if not self.peer_seen:
                self._event("peer", sysid=msg.get_srcSystem())
            self.peer_seen = True
        elif kind == "NAMED_VALUE_INT":
            name = msg.name.encode() if isinstance(msg.name, str) else bytes(msg.name)
            if name.rstrip(b"\0") == LOCKSTEP_ACK_NAME:
                self.peer_lockstep = True
                self.ack_t = max(self.ack_t, msg.time_boot_ms * 1e-3)
        elif kind == "COMMAND_LONG":
            self._command(msg)
        elif kind == "SET_ATTITUDE_TARGET":
            self._attitude_target(msg, t)
        elif kind == "SET_POSITION_TARGET_LOCAL_NED":
            self._position_target(msg, t)
        elif kind == "LANDING_TARGET":
            self._landing_target(msg, t)
        elif kind == "TIMESYNC" and msg.tc1 == 0:
            self.mav.timesync_send(int(t * 1e9), msg.ts1)

    def _note_setpoint(self, sp: Setpoint) -> None:
        if self.setpoint is None or sp.t - self.setpoint.t > 0.5:
            self.stream_start = sp.t  # a new stream (PX4 wants a continuous one before the switch)
        self.setpoint = sp
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

    def _command(self, msg: Any) -> None:
        cmd, t = msg.command, self.world.t
        if cmd == mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
            if msg.param1 == 1.0:
                if self.world.t_motors_off is not None or self.world.done:  # one flight per mission
                    self._ack(cmd, mavlink.MAV_RESULT_DENIED)
                    return
                if self.mode is FlightMode.OFFBOARD and self._px4 and not self._stream_alive(t):
                    self._ack(cmd, mavlink.MAV_RESULT_DENIED)
                    return
                self.armed = True
                self.hold_p = self.world.x[SL_P].copy()
                self._event("armed")
            elif msg.param1 == 0.0:
                # PX4 refuses a disarm unless its land detector says landed, or the disarm is forced
                on_ground = not self.world.airborne or self.landed
                if not on_ground and int(msg.param2) != FORCE_DISARM:
                    self._ack(cmd, mavlink.MAV_RESULT_DENIED)
                    return
                self._disarm("forced" if int(msg.param2) == FORCE_DISARM else "commanded")
            else:
                self._ack(cmd, mavlink.MAV_RESULT_DENIED)
                return
            self._ack(cmd, mavlink.MAV_RESULT_ACCEPTED)
        elif cmd == mavlink.MAV_CMD_DO_SET_MODE:
            if not (int(msg.param1) & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED):
                self._ack(cmd, mavlink.MAV_RESULT_DENIED)
                return
            if self.config.flavour == "ardupilot":
                cm = int(msg.param2) if math.isfinite(msg.param2) else -1
            else:
                main = int(msg.param2) if math.isfinite(msg.param2) else -1
                sub = int(msg.param3) if math.isfinite(msg.param3) else 0
                cm = px4_custom_mode(main & 0xFF, sub & 0xFF) if main >= 0 else -1
            mode = decode_mode(self.config.flavour, cm) if cm >= 0 else None
            if mode is None:
                self._ack(cmd, mavlink.MAV_RESULT_UNSUPPORTED)
                return
            if mode is FlightMode.OFFBOARD and self.config.flavour == "px4":
                streaming = self._stream_alive(t) and self.stream_start is not None
                if not streaming or t - (self.stream_start or t) < self.config.offboard_min_stream_s:
                    self._ack(cmd, mavlink.MAV_RESULT_TEMPORARILY_REJECTED)
                    self._statustext("REJECT OFFBOARD: no setpoint stream", mavlink.MAV_SEVERITY_WARNING)
                    return
            self._set_mode(mode, "commanded")
            self._ack(cmd, mavlink.MAV_RESULT_ACCEPTED)
        elif cmd == mavlink.MAV_CMD_NAV_TAKEOFF:
            height = msg.param7 if math.isfinite(msg.param7) and 0.5 <= msg.param7 <= 50.0 else 2.5
            if not self.armed:
                self._ack(cmd, mavlink.MAV_RESULT_TEMPORARILY_REJECTED)
                return
            self._set_mode(FlightMode.TAKEOFF, "takeoff command")
            self.takeoff_z = self.hold_p[2] + height
            self._ack(cmd, mavlink.MAV_RESULT_ACCEPTED)
        else:
            self._ack(cmd, mavlink.MAV_RESULT_UNSUPPORTED)

    # -- control ---------------------------------------------------------------------------------------
    def _control(self) -> None:
        t, x = self.world.t, self.world.x
        p, v, R = x[SL_P], x[SL_V], quat_to_rotmat(x[SL_Q])
        guided_stopped = False
        if self.mode is FlightMode.OFFBOARD and not self._px4:
            # ArduCopter GUIDED: without setpoints (none yet, or none for GUID_TIMEOUT) the vehicle stops
            # and holds where it is, and stays in GUIDED.
            guided_stopped = self.setpoint is None or t - self.setpoint.t > self.config.loss_s
            if guided_stopped and not self._guided_stopped:
                self.hold_p = p.copy()
                self.hold_yaw = yaw_of(R)
                self._event("guided_timeout", last_setpoint_t=self.setpoint.t if self.setpoint else None)
            self._guided_stopped = guided_stopped
        elif self.mode is FlightMode.OFFBOARD and self.armed and not self._stream_alive(t):
            self._statustext(f"Offboard lost: failsafe {self.config.failsafe}", mavlink.MAV_SEVERITY_WARNING)
            self._event(
                "failsafe",
                action=self.config.failsafe,
                last_setpoint_t=self.setpoint.t if self.setpoint else None,
            )
            self._set_mode(
                FlightMode.LAND if self.config.failsafe == "land" else FlightMode.HOLD, "offboard loss"
            )
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
            p_ref: FloatArray | None = self.hold_p
            v_ref: FloatArray | None = None
            a_ref: FloatArray | None = None
            yaw = self.hold_yaw
            if self.mode is FlightMode.OFFBOARD and self.setpoint is not None and not guided_stopped:
                sp = self.setpoint
                p_ref, v_ref, a_ref = sp.p, sp.v, sp.a
                yaw = self.hold_yaw if sp.yaw is None else sp.yaw
            elif self.mode is FlightMode.TAKEOFF:
                z = self.hold_p[2] + self.takeoff_height_m if self.takeoff_z is None else self.takeoff_z
                p_ref = np.array([self.hold_p[0], self.hold_p[1], z])
                if p[2] > z - 0.1 and abs(v[2]) < 0.2:
                    self._set_mode(FlightMode.HOLD, "takeoff done")
            elif self.mode in (FlightMode.LAND, FlightMode.PRECLAND):
                descent = self.config.land_descent_mps
                xy = self.hold_p[0:2]
                v_xy = np.zeros(2)
                tg = self.target
                if (
                    self.mode is FlightMode.PRECLAND
                    and tg is not None
                    and t - tg["t"] <= self.config.precland_lost_s
                ):
                    xy = tg["p"] + tg["v"] * (t - tg["t"])
                    v_xy = tg["v"]
                    self.hold_p[0:2] = xy  # a lost target leaves a plain land where it was last seen
                    if math.dist(xy, p[0:2]) > self.config.precland_accept_m:
                        descent = 0.0
                    else:
                        descent = self.config.precland_descent_mps
                p_ref = np.array([xy[0], xy[1], p[2]])
                v_ref = np.array([v_xy[0], v_xy[1], -descent])
                self._descending = descent > 0.0
            # (land: p_ref's height is the current one, so the vertical is a pure rate of descent)
            thrust, w = position_control(
                p, v, R, p_ref=p_ref, v_ref=v_ref, a_ref=a_ref, yaw_ref=yaw, airframe=self.airframe
            )
        self.thrust_N, self.w_cmd = thrust, np.asarray(w, dtype=float)
        self.world.set_command(thrust, self.w_cmd, True)

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
        odo = w.odometry_message() if k % 5 == 0 else None  # 40 Hz, odometry faults applied
        if odo is not None:
            p, v = frames.enu_to_ned(odo.p_WB), frames.enu_to_ned(odo.v_WB)
            q = frames.q_WB_to_mavlink(odo.q_WB)
            rates = frames.flu_to_frd(x[SL_W])
            nan21 = [math.nan] * 21
            mav.local_position_ned_send(t_ms, *p, *v)
            mav.odometry_send(
                t_us, mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_FRAME_LOCAL_NED, *p, q, *v, *rates,
                nan21, nan21, w.faults.odometry_reset_counter, mavlink.MAV_ESTIMATOR_TYPE_VIO, 100,
            )  # fmt: skip
        if k % 2 == 0:  # 100 Hz
            lo, hi, cm, quality = distance_sensor_fields(w.range_m(), w.rangefinder.config)
            mav.distance_sensor_send(t_ms, lo, hi, cm, mavlink.MAV_DISTANCE_SENSOR_LASER, 0,
                                     mavlink.MAV_SENSOR_ROTATION_PITCH_270, 255, 0.0, 0.0, [0.0] * 4,
                                     quality)  # fmt: skip
        if k % 40 == 0:  # 5 Hz
            landed = mavlink.MAV_LANDED_STATE_ON_GROUND if self.landed else mavlink.MAV_LANDED_STATE_IN_AIR
            mav.extended_sys_state_send(mavlink.MAV_VTOL_STATE_UNDEFINED, landed)

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
        self.mav.heartbeat_send(
            mavlink.MAV_TYPE_QUADROTOR, ap, base, encode_mode(self.config.flavour, self.mode), status
        )
        if self.config.lockstep:
            self.mav.named_value_int_send(int(self.world.t * 1e3), LOCKSTEP_NAME, 1)
        self._last_hb_wall = time.monotonic()
        self._last_hb_t = self.world.t

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
            while True:
                try:
                    msg = self.conn.recv_msg()
                except (OSError, mavlink.MAVError):
                    msg = None
                if msg is None:
                    break
                if msg.get_type() != "BAD_DATA":
                    self.handle(msg)
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
        return self._finish(time.monotonic() - wall_start)

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
        self.frames.close()
        self.conn.close()


def serve(scenario: Scenario, config: SitlConfig, airframe: Airframe | None = None) -> dict[str, Any]:
    """Run the emulated autopilot for one mission: wait for a companion, fly, send it the verdict and the
    ground-truth log on the camera stream, and return the verdict. ``airframe``: None flies the
    scenario's ``airframe:``."""
    ap = EmulatedAutopilot(scenario, config, airframe)
    try:
        result = ap.run()
        ap.frames.send_result(json.loads(json.dumps(result, default=float)))
        ap.frames.send_truth_log(ap.truth_arrays())
        # A few heartbeats after the end, so the peer sees the final state before the link goes quiet.
        for _ in range(3):
            ap._heartbeat()
            ap._poll(0.05)
        return result
    finally:
        ap.close()
