"""A scripted autopilot for tests and the fuzzer: it encodes the messages a PX4 would send (HEARTBEAT,
HIGHRES_IMU, ODOMETRY, DISTANCE_SENSOR, ...) for a vehicle standing still or hovering, and decodes what
the bridge sends back, without sockets, threads or the simulator."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

os.environ.setdefault("MAVLINK20", "1")

from pymavlink.dialects.v20 import common as mavlink  # noqa: E402

from alight.interfaces import frames  # noqa: E402
from alight.interfaces.sitl import PX4_MAIN_OFFBOARD, px4_custom_mode  # noqa: E402


class Capture:
    """A ``write(bytes)`` sink that decodes every message written to it."""

    def __init__(self) -> None:
        self._parser = mavlink.MAVLink(None, 0, 0)
        self._parser.robust_parsing = True
        self.messages: list[Any] = []

    def write(self, data: bytes) -> None:
        self.messages.extend(self._parser.parse_buffer(data) or [])

    @staticmethod
    def decode(data: bytes) -> list[Any]:
        parser = mavlink.MAVLink(None, 0, 0)
        parser.robust_parsing = True
        return [m for m in parser.parse_buffer(data) or [] if m.get_type() != "BAD_DATA"]

    def of_type(self, kind: str) -> list[Any]:
        return [m for m in self.messages if m.get_type() == kind]


class _Sink:
    def __init__(self) -> None:
        self.buf = bytearray()

    def write(self, data: bytes) -> None:
        self.buf += data


@dataclass
class FakeAutopilot:
    """Encodes one 200 Hz tick at a time of a vehicle at ``p_ned`` (m, NED), attitude ``q`` (w, x, y, z)."""

    sysid: int = 1
    compid: int = 1
    p_ned: tuple[float, float, float] = (0.0, 0.0, -2.0)
    q: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    custom_mode: int = field(default_factory=lambda: px4_custom_mode(3))
    armed: bool = False
    heartbeat: bool = True
    odometry: bool = True
    t: float = 0.0

    def __post_init__(self) -> None:
        self._sink = _Sink()
        self.mav = mavlink.MAVLink(self._sink, self.sysid, self.compid)
        self.k = 0
        self.announce = False  # send a HEARTBEAT on the next tick (a mode or arming change)

    def offboard(self, armed: bool = True) -> None:
        self.custom_mode, self.armed = px4_custom_mode(PX4_MAIN_OFFBOARD), armed
        self.announce = True

    def set_armed(self, armed: bool) -> None:
        self.armed = armed
        self.announce = True

    def tick(self) -> bytes:
        """The bytes of the next 5 ms: IMU every tick, odometry at 40 Hz, range at 100 Hz, heartbeat 1 Hz."""
        self.k += 1
        self.t = self.k * 0.005
        t_us, t_ms = int(round(self.t * 1e6)), int(round(self.t * 1e3))
        m = self.mav
        f_frd = frames.flu_to_frd(np.array([0.0, 0.0, 9.81]))
        m.highres_imu_send(t_us, *f_frd, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1013.0, 0.0, 0.0, 20.0, 63)
        if self.k % 5 == 0 and self.odometry:
            nan21 = [math.nan] * 21
            m.odometry_send(
                t_us, 1, 1, *self.p_ned, list(self.q), 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, nan21, nan21, 0, 0, 100
            )
        if self.k % 2 == 0:
            cm = int(round(-self.p_ned[2] * 100))
            m.distance_sensor_send(t_ms, 0, 1400, cm, 0, 0, mavlink.MAV_SENSOR_ROTATION_PITCH_270, 0)
        if (self.k % 200 == 1 or self.announce) and self.heartbeat:
            self.announce = False
            base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (
                mavlink.MAV_MODE_FLAG_SAFETY_ARMED if self.armed else 0
            )
            m.heartbeat_send(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4, base, self.custom_mode, 4)
        out = bytes(self._sink.buf)
        self._sink.buf.clear()
        return out

    def encode(self, msg: Any) -> bytes:
        """A message packed (with its CRC) as this autopilot."""
        return bytes(msg.pack(self.mav))
