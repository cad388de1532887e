"""The parts of the emulated autopilot's MAVLink service that are not flight: defensive reading of command
fields, the geodetic frame of its GLOBAL_POSITION_INT / HOME_POSITION / GPS_RAW_INT, its parameter table
(PARAM_* protocol) and the replies to the FTP and mission protocols where nothing is emulated.

Written from MAVLink's common.xml and the parameter and mission protocol pages of mavlink.io; no autopilot
code was read. What real clients send and expect, found with MAVSDK 4.1, MAVProxy 1.8.75 and pymavlink 2.4.50:
unused command parameters are NaN (MAVSDK), a ground station downloads the parameter list and the
mission on connecting and retries until it gets an answer, and integer parameters travel in the float
field either as their bytes (PX4, ``MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE``) or cast to float
(ArduPilot, ``..._C_CAST``)."""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from typing import Literal

EARTH_RADIUS_M = 6378137.0  # WGS-84 equatorial radius
# PX4 SITL's default home (PX4_HOME_LAT / _LON / _ALT): where the emulator's world origin lies on Earth.
HOME_LAT_DEG, HOME_LON_DEG, HOME_ALT_M = 47.397742, 8.545594, 488.0


def finite_or(value: object, default: float) -> float:
    """``value`` as a float when it is a finite number, else ``default`` (NaN, inf, garbage)."""
    try:
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError, OverflowError):
        return default
    return v if math.isfinite(v) else default


def int_or_none(value: object, lo: int = -(2**31), hi: int = 2**31 - 1) -> int | None:
    """``value`` truncated to an int (a C cast, as autopilots read command parameters) when it is finite
    and within [lo, hi]; None otherwise."""
    v = finite_or(value, math.nan)
    if math.isnan(v) or not lo <= v <= hi:
        return None
    return int(v)


@dataclass(frozen=True)
class Geodetic:
    """The local-tangent-plane map between the world frame W (ENU, metres, origin at home) and WGS-84
    latitude/longitude, equirectangular about home: within a few kilometres of home its error is below
    a centimetre per 100 m, far below a GNSS fix's."""

    lat0_deg: float = HOME_LAT_DEG
    lon0_deg: float = HOME_LON_DEG
    alt0_m: float = HOME_ALT_M

    def to_lat_lon(self, east_m: float, north_m: float) -> tuple[float, float]:
        lat = self.lat0_deg + math.degrees(north_m / EARTH_RADIUS_M)
        lon = self.lon0_deg + math.degrees(east_m / (EARTH_RADIUS_M * math.cos(math.radians(self.lat0_deg))))
        return lat, lon

    def to_east_north(self, lat_deg: float, lon_deg: float) -> tuple[float, float]:
        north = math.radians(lat_deg - self.lat0_deg) * EARTH_RADIUS_M
        east = math.radians(lon_deg - self.lon0_deg) * EARTH_RADIUS_M * math.cos(math.radians(self.lat0_deg))
        return east, north

    def e7(self, east_m: float, north_m: float) -> tuple[int, int]:
        """Latitude and longitude in degE7, as GLOBAL_POSITION_INT carries them."""
        lat, lon = self.to_lat_lon(east_m, north_m)
        return int(round(lat * 1e7)), int(round(lon * 1e7))


# MAV_PARAM_TYPE
PARAM_INT8, PARAM_INT16, PARAM_INT32, PARAM_REAL32 = 2, 4, 6, 9
Encoding = Literal["bytewise", "cast"]


@dataclass
class Param:
    """One emulated parameter: its MAVLink type, value (SI unless the autopilot's unit says otherwise),
    allowed span and, for an enumeration, its allowed values."""

    name: str
    mav_type: int
    value: float
    lo: float
    hi: float
    allowed: tuple[float, ...] | None = None

    @property
    def is_int(self) -> bool:
        return self.mav_type != PARAM_REAL32

    def accepts(self, value: float) -> bool:
        if not math.isfinite(value) or not self.lo <= value <= self.hi:
            return False
        if self.is_int and value != int(value):
            return False
        return self.allowed is None or value in self.allowed


def encode_param_value(param: Param, encoding: Encoding) -> float:
    """The float PARAM_VALUE.param_value carries for ``param``: an integer's bytes (bytewise, PX4) or the
    integer cast to float (ArduPilot)."""
    if not param.is_int or encoding == "cast":
        return float(param.value)
    return float(struct.unpack("<f", struct.pack("<i", int(param.value)))[0])


def decode_param_value(raw: float, mav_type: int, encoding: Encoding) -> float:
    """The value a PARAM_SET carries, by the type it declares; NaN when it cannot be one."""
    if mav_type == PARAM_REAL32 or encoding == "cast":
        return finite_or(raw, math.nan)
    if mav_type not in (PARAM_INT8, PARAM_INT16, PARAM_INT32):
        return math.nan
    try:
        return float(struct.unpack("<i", struct.pack("<f", raw))[0])
    except (struct.error, OverflowError, TypeError):
        return math.nan


def param_table(flavour: str) -> list[Param]:
    """The parameters the emulator has, with the autopilot's own names, units and defaults, each acting on
    the emulator's behaviour (``EmulatedAutopilot`` reads them): offboard-loss timeout and action,
    take-off height, landing descent rate, return altitude. Everything else a real autopilot has is
    absent, so a client reading another name gets no answer, as from an autopilot without it."""
    if flavour == "ardupilot":
        return [
            Param("GUID_TIMEOUT", PARAM_REAL32, 3.0, 0.1, 5.0),
            Param("LAND_SPEED", PARAM_INT16, 50.0, 30.0, 200.0),  # cm/s
            Param("RTL_ALT", PARAM_INT32, 1500.0, 200.0, 300000.0),  # cm
            Param("PLND_ENABLED", PARAM_INT8, 1.0, 1.0, 1.0),  # the emulator's LAND is a precision land
        ]
    return [
        Param("COM_OF_LOSS_T", PARAM_REAL32, 1.0, 0.0, 60.0),
        Param("COM_OBL_RC_ACT", PARAM_INT32, 0.0, 0.0, 7.0, allowed=(0.0, 4.0, 5.0)),  # position, land, hold
        Param("MIS_TAKEOFF_ALT", PARAM_REAL32, 2.5, 0.0, 80.0),
        Param("MPC_LAND_SPEED", PARAM_REAL32, 0.7, 0.6, 4.0),
        Param("RTL_RETURN_ALT", PARAM_REAL32, 60.0, 0.0, 150.0),
    ]


def param_name(raw: object) -> str:
    """PARAM_* ``param_id``: up to 16 characters, NUL-padded unless it is 16 long; '' when unreadable."""
    if isinstance(raw, bytes | bytearray):
        raw = bytes(raw).split(b"\0", 1)[0].decode("ascii", "replace")
    return raw.split("\0", 1)[0][:16] if isinstance(raw, str) else ""


# MAVLink FTP (https://mavlink.io/en/services/ftp.html): opcodes and error codes of the replies
FTP_ACK, FTP_NAK = 128, 129
FTP_ERR_INVALID_SESSION, FTP_ERR_UNKNOWN_COMMAND, FTP_ERR_FILE_NOT_FOUND = 4, 7, 10
_FTP_SESSION_RESETS = (1, 2)  # TerminateSession, ResetSessions: nothing open, so done
_FTP_SESSION_OPS = (5, 7, 12, 15)  # ReadFile, WriteFile, TruncateFile, BurstReadFile: need an open file
_FTP_FILE_OPS = (3, 4, 6, 8, 9, 10, 11, 13, 14)  # ListDirectory, OpenFileRO, CreateFile, ... : need a file


def ftp_reply(payload: bytes | list[int]) -> list[int] | None:
    """The 251-byte FTP payload answering request ``payload`` (the emulator has no file system): an ACK
    to a session reset, a NAK with InvalidSession to a read or write, FileNotFound to a file or directory
    operation, UnknownCommand otherwise; None for a payload too short to be a request, or a reply."""
    data = bytes(payload)
    if len(data) < 12:
        return None
    seq, session, opcode = data[0] | data[1] << 8, data[2], data[3]
    if opcode in (0, FTP_ACK, FTP_NAK):
        return None
    reply = bytearray(251)
    reply[0:2] = ((seq + 1) & 0xFFFF).to_bytes(2, "little")
    reply[2], reply[5] = session, opcode
    if opcode in _FTP_SESSION_RESETS:
        reply[3] = FTP_ACK
        return list(reply)
    if opcode in _FTP_SESSION_OPS:
        error = FTP_ERR_INVALID_SESSION
    elif opcode in _FTP_FILE_OPS:
        error = FTP_ERR_FILE_NOT_FOUND
    else:
        error = FTP_ERR_UNKNOWN_COMMAND
    reply[3], reply[4], reply[12] = FTP_NAK, 1, error
    return list(reply)
