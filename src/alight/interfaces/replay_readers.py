"""Readers of recorded flights: PX4 ULog (pyulog) and ROS 1 / ROS 2 bags (sqlite3 or MCAP storage, rosbags).

A reader turns a log into one time-ordered stream of :data:`Sample` s in alight's frames (W ENU, B FLU,
SI, quaternions (x, y, z, w)), which :mod:`alight.interfaces.replay` feeds to a Pipeline. Which topic feeds
which stream is set by a :class:`ReplayMapping` (defaults in ``replay_mapping.yaml``, see docs/replay.md).

Time: seconds. ULog: ``(timestamp - first timestamp of the log) * 1e-6``. Bags: header stamps (the
reader's log time where a message has no header or a zero stamp), relative to the bag's start, except
when the bag's clock is a simulated one (start below 1e6 s, e.g. a bag written by ``alight fly --bag``),
which is kept as it is.

Everything a damaged file can make the parsers raise is turned into one :class:`ReplayError` naming the
file: a truncated or corrupted log gives one line, never a traceback.
"""

from __future__ import annotations

import contextlib
import heapq
import io
import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from importlib import resources
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from alight.errors import ReplayError
from alight.evaluation.recorded_flight import LogMessage
from alight.interfaces.frames import frd_to_flu, mavlink_to_q_WB_many, ned_to_enu
from alight.perception.image_decode import decode_image_bytes

FloatArray = NDArray[np.float64]

SIM_CLOCK_LIMIT_NS = 10**15
"""A bag whose first message is stamped before this (1e6 s, 11.6 days after the epoch) runs on a
simulated clock: its times are kept as they are instead of being made relative to its start."""


MAX_POSITION_M = 1.0e7
"""Positions farther than this from the origin (m) are not a flight (a damaged value): dropped."""
MAX_SPEED_MPS = 1.0e4
MAX_IMU = 1.0e4
"""Specific forces (m/s^2) or rates (rad/s) beyond this are dropped as damaged."""
MAX_TIME_FROM_MEDIAN_S = 86400.0
"""Samples stamped more than a day from the log's median time are dropped as damaged stamps."""


def _ok(v: FloatArray | None, limit: float) -> bool:
    return v is None or bool(np.isfinite(v).all() and np.abs(v).max() <= limit)


def _plausible(s: Sample) -> bool:
    """Finite, and within physical limits: a damaged log's garbage never reaches the Pipeline."""
    if not math.isfinite(s.t):
        return False
    if isinstance(s, OdometrySample):
        return _ok(s.p_WB, MAX_POSITION_M) and _ok(s.q_WB, 1.5) and _ok(s.v_WB, MAX_SPEED_MPS)
    if isinstance(s, TruthSample):
        return _ok(s.p_W, MAX_POSITION_M) and _ok(s.q_W, 1.5) and _ok(s.v_W, MAX_SPEED_MPS)
    if isinstance(s, ImuSample):
        return _ok(s.f_B, MAX_IMU) and _ok(s.w_B, MAX_IMU)
    return True


def _clean(samples: list[Sample]) -> tuple[list[Sample], int]:
    """The plausible samples, sorted by time, and how many were dropped."""
    kept = [s for s in samples if _plausible(s)]
    if kept:
        median = float(np.median([s.t for s in kept]))
        kept = [s for s in kept if abs(s.t - median) <= MAX_TIME_FROM_MEDIAN_S]
    kept.sort(key=lambda s: s.t)
    return kept, len(samples) - len(kept)


class Stream(StrEnum):
    """The inputs a recorded flight can give the Pipeline, and the truth it can be judged against."""

    ODOMETRY = "odometry"
    IMU = "imu"
    RANGE = "range"
    IMAGE = "image"
    TRUTH_EGO = "truth_ego"
    TRUTH_PLATFORM = "truth_platform"


@dataclass(frozen=True)
class OdometrySample:
    t: float
    """capture time (s)"""
    p_WB: FloatArray
    """(3,) position of the body in W (m)"""
    q_WB: FloatArray
    """(4,) attitude, (x, y, z, w)"""
    v_WB: FloatArray | None
    """(3,) velocity in W (m/s), when the log has it"""
    reset_counter: int | None = None
    """the estimator's position reset counter, when the log has it (PX4: ``xy_reset_counter`` +
    ``z_reset_counter``): a change means its frame jumped"""


@dataclass(frozen=True)
class ImuSample:
    t: float
    f_B: FloatArray
    """(3,) specific force in B (m/s^2)"""
    w_B: FloatArray
    """(3,) body rates in B (rad/s)"""


@dataclass(frozen=True)
class RangeSample:
    t: float
    range_m: float | None
    """distance to the surface below (m), None when the reading is invalid"""


@dataclass(frozen=True)
class ImageSample:
    t: float
    """when the frame reaches the Pipeline (s): the bag's receive time (the capture time where that is
    earlier or more than 1 s later), plus the mapping's ``image_latency_s``"""
    t_capture: float
    """capture time (s)"""
    image: NDArray[np.uint8]
    """(H, W) grey or (H, W, 3) BGR"""


@dataclass(frozen=True)
class TruthSample:
    t: float
    stream: Stream
    """TRUTH_EGO (the vehicle) or TRUTH_PLATFORM (the pad centre)"""
    p_W: FloatArray
    """(3,) position in W (m)"""
    q_W: FloatArray | None
    """(4,) attitude (x, y, z, w), when known"""
    v_W: FloatArray | None
    """(3,) velocity in W (m/s), when known"""


Sample = OdometrySample | ImuSample | RangeSample | ImageSample | TruthSample


# --------------------------------------------------------------------------------------------------
# mapping
# --------------------------------------------------------------------------------------------------


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class UlogMapping(_Strict):
    """uORB topic names (PX4). An empty string switches a stream off."""

    position: str = "vehicle_local_position"
    attitude: str = "vehicle_attitude"
    imu: str = "sensor_combined"
    range: str = "distance_sensor"
    truth_position: str = "vehicle_local_position_groundtruth"
    truth_attitude: str = "vehicle_attitude_groundtruth"
    multi_id: int = Field(default=0, ge=0)


class RosMapping(_Strict):
    """Candidate topic names per stream, first present wins; ENU/FLU (REP-103)."""

    odometry: list[str] = Field(default_factory=list)
    imu: list[str] = Field(default_factory=list)
    range: list[str] = Field(default_factory=list)
    image: list[str] = Field(default_factory=list)
    truth_ego: list[str] = Field(default_factory=list)
    truth_platform: list[str] = Field(default_factory=list)
    log: list[str] = Field(default_factory=list)
    """the nodes' text messages (``/rosout``): every one of these topics the bag has"""
    image_latency_s: float = Field(default=0.0, ge=0.0, le=10.0)


class ReplayMapping(_Strict):
    """Which topics of a log feed which :class:`Stream` (see docs/replay.md)."""

    ulog: UlogMapping = UlogMapping()
    ros: RosMapping = RosMapping()


DEFAULT_MAPPING_FILE = "replay_mapping.yaml"


def load_mapping(path: str | Path | None = None) -> ReplayMapping:
    """The packaged default mapping, or the file at ``path`` (sections left out keep the defaults'
    values only where the file does not name the section; a section given replaces the default one).

    Raises:
        ReplayError: the file is missing, not YAML, or has unknown or ill-typed keys.
    """
    default = yaml.safe_load(
        resources.files("alight.interfaces").joinpath(DEFAULT_MAPPING_FILE).read_text(encoding="utf-8")
    )
    data: dict[str, Any] = dict(default)
    source = "default mapping"
    if path is not None:
        p = Path(path)
        source = str(p)
        try:
            user = yaml.safe_load(p.read_text(encoding="utf-8"))
        except OSError as err:
            raise ReplayError(f"{p}: cannot read the mapping file ({err.strerror})") from None
        except yaml.YAMLError as err:
            raise ReplayError(f"{p}: not a YAML mapping file ({str(err).splitlines()[0]})") from None
        if user is None:
            user = {}
        if not isinstance(user, dict):
            raise ReplayError(f"{p}: a mapping file must be a YAML mapping with 'ulog' and/or 'ros'")
        data.update(user)
    try:
        return ReplayMapping.model_validate(data)
    except ValidationError as err:
        e = err.errors()[0]
        where = ".".join(str(x) for x in e["loc"])
        raise ReplayError(f"{source}: {where}: {e['msg']}") from None


# --------------------------------------------------------------------------------------------------
# the recording interface
# --------------------------------------------------------------------------------------------------


@dataclass
class Recording:
    """A recorded flight opened for replay."""

    path: Path
    format: str
    """``ulog``, ``ros1`` or ``ros2``"""
    topics: dict[str, str]
    """stream value -> the topic that feeds it"""
    counts: dict[str, int] = field(default_factory=dict)
    """stream value -> messages read so far"""
    bad_frames: int = 0
    """images that could not be decoded (skipped)"""
    warnings: list[str] = field(default_factory=list)
    """what the reader noticed but could read past (a damaged ULog's lost data)"""
    dropped: int = 0
    """messages dropped as damaged (non-finite, beyond physical limits, or stamped far from the rest)"""
    messages: list[LogMessage] = field(default_factory=list)
    """the log's own text messages (PX4's logged messages), on the replay's clock"""
    vehicle: str = ""
    """the autopilot and board the log names (PX4: ``sys_name`` and ``ver_hw``), when it does"""
    _fast: list[Sample] = field(default_factory=list, repr=False)
    _reader: Any = field(default=None, repr=False)
    _image_conns: list[Any] = field(default_factory=list, repr=False)
    _origin_ns: int = 0
    _latency_s: float = 0.0
    _t_mid: float = 0.0

    def samples(self) -> Iterator[Sample]:
        """Every sample, in time order (images streamed from the file, the rest held in memory)."""
        images = self._images() if self._image_conns else iter(())
        merged = heapq.merge(self._fast, images, key=lambda s: s.t)
        try:
            yield from merged
        except ReplayError:
            raise
        except Exception as err:  # noqa: BLE001 - a damaged file makes rosbags raise anything
            raise ReplayError(f"{self.path}: cannot read the images ({_describe(err)})") from None

    def _images(self) -> Iterator[ImageSample]:
        reader = self._reader
        for conn, t_ns, raw in reader.messages(connections=self._image_conns):
            msg = reader.deserialize(raw, conn.msgtype)
            image = decode_image(msg, conn.msgtype)
            if image is None:
                self.bad_frames += 1
                continue
            t_cap = _stamp_s(msg, t_ns, self._origin_ns)
            # The frame reaches the Pipeline when the bag received it (after the camera's processing),
            # unless the two clocks disagree by more than a second (a driver stamping on its own clock).
            t_rx = (int(t_ns) - self._origin_ns) * 1e-9
            t_in = t_rx if t_cap <= t_rx <= t_cap + 1.0 else t_cap
            if not (math.isfinite(t_cap) and abs(t_cap - self._t_mid) <= MAX_TIME_FROM_MEDIAN_S):
                self.dropped += 1
                continue
            self.counts[Stream.IMAGE.value] = self.counts.get(Stream.IMAGE.value, 0) + 1
            yield ImageSample(t_in + self._latency_s, t_cap, image)

    def close(self) -> None:
        if self._reader is not None:
            try:
                self._reader.close()
            except Exception:  # noqa: BLE001, S110 - closing a damaged file must not hide the real error
                pass
            self._reader = None


def open_recording(path: str | Path, mapping: ReplayMapping | None = None) -> Recording:
    """Open a PX4 ULog (``.ulg``), a ROS 1 bag (``.bag``), or a ROS 2 bag (its directory, or its
    ``.db3`` / ``.mcap`` file).

    Raises:
        ReplayError: the file is missing, of an unknown kind, damaged, or has none of the mapped topics.
    """
    p = Path(path)
    m = load_mapping() if mapping is None else mapping
    if not p.exists():
        raise ReplayError(f"{p}: no such file or directory")
    if p.is_file() and p.stat().st_size == 0:
        raise ReplayError(f"{p}: empty file")
    if p.is_dir():
        _check_bag_dir(p)
    if p.suffix.lower() == ".ulg":
        return _open_ulog(p, m.ulog)
    if p.is_dir() or p.suffix.lower() in (".bag", ".db3", ".mcap"):
        return _open_bag(p, m.ros)
    raise ReplayError(
        f"{p}: unknown log type (expected a .ulg, a .bag, a ROS 2 bag directory, .db3 or .mcap)"
    )


def need(module: str) -> Any:
    """Import an optional dependency of replay and export, or say how to install it (one line)."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        raise ReplayError(
            f"{module.split('.')[0]} is not installed: pip install 'alight[replay]' for replay and export"
        ) from None


def _describe(err: BaseException) -> str:
    text = str(err).strip().splitlines()
    first = text[0] if text else ""
    if len(first) > 160:
        first = first[:157] + "..."
    return f"{type(err).__name__}: {first}" if first else type(err).__name__


# --------------------------------------------------------------------------------------------------
# PX4 ULog
# --------------------------------------------------------------------------------------------------


def _open_ulog(path: Path, m: UlogMapping) -> Recording:
    ULog = need("pyulog").ULog

    wanted = [n for n in (m.position, m.attitude, m.imu, m.range, m.truth_position, m.truth_attitude) if n]
    chatter = io.StringIO()
    try:
        # pyulog prints its warnings about damaged data, and leaves a file it opened itself open when
        # it raises: it gets an open file, and its chatter goes to the recording's warnings
        with open(path, "rb") as f, contextlib.redirect_stdout(chatter):
            ulog = ULog(f, wanted)
    except Exception as err:  # noqa: BLE001 - pyulog raises anything on damaged bytes
        raise ReplayError(f"{path}: not a readable ULog ({_describe(err)})") from None
    try:
        rec = _ulog_recording(path, ulog, m)
    except ReplayError:
        raise
    except Exception as err:  # noqa: BLE001 - fields missing or ill-shaped in a damaged log
        raise ReplayError(f"{path}: cannot use the ULog's topics ({_describe(err)})") from None
    if getattr(ulog, "file_corruption", False):
        rec.warnings.append("pyulog found the file damaged (truncated or corrupt); replayed what it read")
    cut = ulog_cut_at(path)
    if cut is not None:
        rec.warnings.append(
            f"the log ends early: its last message is cut off at byte {cut} of {path.stat().st_size} (a "
            "copy or a recording stopped short); replayed what precedes it"
        )
    rec.warnings += sorted({line.strip() for line in chatter.getvalue().splitlines() if line.strip()})[:5]
    rec.messages = _ulog_messages(ulog)
    rec.vehicle = _ulog_vehicle(ulog)
    return rec


def _ulog_messages(ulog: Any) -> list[LogMessage]:
    """PX4's logged messages (``[commander] Takeoff detected``, preflight failures ...), tagged ones
    included, in time order on the replay's clock; none when the log's records are damaged."""
    t0 = int(ulog.start_timestamp)
    records = list(ulog.logged_messages)
    for tagged in dict(ulog.logged_messages_tagged).values():
        records += list(tagged)
    try:
        out = [
            LogMessage((int(m.timestamp) - t0) * 1e-6, str(m.log_level_str()), str(m.message).strip())
            for m in records
        ]
    except Exception:  # noqa: BLE001 - a damaged record: the messages are a courtesy, the replay goes on
        return []
    return sorted(out, key=lambda m: m.t)


def _ulog_vehicle(ulog: Any) -> str:
    """``PX4 on <board>`` from the log's info messages, or what of it the log has."""
    info = dict(ulog.msg_info_dict)
    name, board = str(info.get("sys_name", "")).strip(), str(info.get("ver_hw", "")).strip()
    return f"{name} on {board}" if name and board else name or board


ULOG_HEADER_BYTES = 16
"""A ULog file starts with a 16-byte header (magic, version, timestamp); then messages, each a 3-byte
header (``uint16`` payload size, ``uint8`` type) and its payload."""


def ulog_cut_at(path: Path) -> int | None:
    """The offset of the last, incomplete message of the ULog at ``path`` when the file ends inside it (a
    log cut short: pyulog reads up to there and says nothing), else None. Walks the message headers only;
    a file cut exactly between two messages cannot be told from a complete one."""
    try:
        data = path.read_bytes()
    except OSError:
        return None
    offset = ULOG_HEADER_BYTES
    while offset + 3 <= len(data):
        size = int.from_bytes(data[offset : offset + 2], "little")
        if offset + 3 + size > len(data):
            return offset
        offset += 3 + size
    return None if offset == len(data) else offset


def _ulog_topic(ulog: Any, name: str, multi_id: int) -> Mapping[str, np.ndarray] | None:
    if not name:
        return None
    for d in ulog.data_list:
        if d.name == name and d.multi_id == multi_id:
            data: Mapping[str, np.ndarray] = d.data
            if len(data.get("timestamp", ())) == 0:
                return None
            return data
    return None


def _times(data: Mapping[str, np.ndarray], t0: int) -> FloatArray:
    """A ULog topic's timestamps (us since boot) as seconds since the log's first one."""
    us = np.asarray(data["timestamp"], dtype=np.int64) - t0
    return us.astype(np.float64) * 1e-6


def _fields(data: Mapping[str, np.ndarray], names: Sequence[str], topic: str) -> FloatArray:
    missing = [n for n in names if n not in data]
    if missing:
        raise ReplayError(f"topic {topic!r} has no field {missing[0]!r}")
    return np.column_stack([np.asarray(data[n], dtype=np.float64) for n in names])


def _ulog_pose(
    data_p: Mapping[str, np.ndarray] | None,
    data_q: Mapping[str, np.ndarray] | None,
    topic_p: str,
    topic_q: str,
    t0: int,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray | None] | None:
    """(t, p_WB, q_WB, v_WB) at the position topic's times, the attitude interpolated onto them."""
    if data_p is None:
        return None
    t = _times(data_p, t0)
    p = ned_to_enu(_fields(data_p, ("x", "y", "z"), topic_p))
    v = ned_to_enu(_fields(data_p, ("vx", "vy", "vz"), topic_p)) if "vx" in data_p else None
    if data_q is None:
        return None
    tq = _times(data_q, t0)
    q = mavlink_to_q_WB_many(_fields(data_q, ("q[0]", "q[1]", "q[2]", "q[3]"), topic_q))
    ok = np.isfinite(q).all(axis=1)
    order = np.argsort(tq[ok], kind="stable")
    tq, q = tq[ok][order], q[ok][order]
    if tq.size == 0:
        return None
    q_at = _nlerp(tq, q, t)
    keep = np.isfinite(p).all(axis=1) & np.isfinite(q_at).all(axis=1)
    return t[keep], p[keep], q_at[keep], None if v is None else v[keep]


def _ulog_reset_counters(data_p: Mapping[str, np.ndarray]) -> np.ndarray | None:
    """PX4's position reset counters summed per sample (``xy_reset_counter`` + ``z_reset_counter``), or
    None when the topic has neither."""
    names = [n for n in ("xy_reset_counter", "z_reset_counter") if n in data_p]
    if not names:
        return None
    total: np.ndarray = np.sum([np.asarray(data_p[n], dtype=np.int64) for n in names], axis=0)
    return total


def _nlerp(tq: FloatArray, q: FloatArray, t: FloatArray) -> FloatArray:
    """Quaternions at times ``t``, normalised linear interpolation between the samples around each
    (the nearer end outside ``tq``'s span, NaN more than 0.5 s outside it)."""
    q = q.copy()
    for i in range(1, q.shape[0]):  # one hemisphere, so neighbours interpolate the short way
        if np.dot(q[i - 1], q[i]) < 0:
            q[i] = -q[i]
    out = np.column_stack([np.interp(t, tq, q[:, k]) for k in range(4)])
    out /= np.linalg.norm(out, axis=1, keepdims=True)
    far = (t < tq[0] - 0.5) | (t > tq[-1] + 0.5)
    out[far] = np.nan
    return out


@dataclass
class _UlogStreams:
    """What the ULog's topics give, stream by stream, as they are read."""

    t0: int
    """the log's first timestamp (us since boot)"""
    topics: dict[str, str] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    samples: list[Sample] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    def add(self, stream: Stream, topic: str, samples: list[Sample]) -> None:
        self.topics[stream.value] = topic
        self.counts[stream.value] = len(samples)
        self.samples += samples


def _ulog_recording(path: Path, ulog: Any, m: UlogMapping) -> Recording:
    out = _UlogStreams(int(ulog.start_timestamp))
    data_p = _ulog_topic(ulog, m.position, m.multi_id)
    if data_p is not None:
        out.warnings += _ulog_validity_warnings(data_p, m.position)
    _add_ulog_odometry(out, data_p, _ulog_topic(ulog, m.attitude, m.multi_id), m)
    _add_ulog_imu(out, _ulog_topic(ulog, m.imu, m.multi_id), m.imu)
    _add_ulog_range(out, _ulog_topic(ulog, m.range, m.multi_id), m.range)
    _add_ulog_truth(out, ulog, m)
    if Stream.ODOMETRY.value not in out.topics:
        raise ReplayError(
            f"{path}: no ego state: the ULog has no usable {m.position!r} with {m.attitude!r} "
            "(set ulog.position / ulog.attitude in a --mapping file)"
        )
    fast, dropped = _clean(out.samples)
    return Recording(
        path=path,
        format="ulog",
        topics=out.topics,
        counts=out.counts,
        warnings=out.warnings,
        dropped=dropped,
        _fast=fast,
    )


def _ulog_validity_warnings(data_p: Mapping[str, np.ndarray], topic: str) -> list[str]:
    """PX4 flags what its estimator did not know (no GPS: no horizontal position); the values are
    replayed as logged, and the report says so."""
    warnings = []
    for flag, what in (("xy_valid", "x, y"), ("z_valid", "z"), ("v_xy_valid", "vx, vy")):
        if flag in data_p:
            bad = int(np.count_nonzero(np.asarray(data_p[flag]) == 0))
            if bad:
                n = len(data_p[flag])
                warnings.append(f"{topic}: {flag} is false in {bad} of {n} samples ({what} as logged)")
    return warnings


def _add_ulog_odometry(
    out: _UlogStreams,
    data_p: Mapping[str, np.ndarray] | None,
    data_q: Mapping[str, np.ndarray] | None,
    m: UlogMapping,
) -> None:
    """The odometry stream: the position topic with the attitude interpolated onto its times, and
    PX4's reset counters."""
    pose = _ulog_pose(data_p, data_q, m.position, m.attitude, out.t0)
    if pose is None or data_p is None:
        return
    t, p, q, v = pose
    # the counters at the kept samples' times (the pose keeps a subset of the topic's, in order)
    counters = _ulog_reset_counters(data_p)
    if counters is not None:
        idx = np.searchsorted(_times(data_p, out.t0), t)
        counters = counters[np.minimum(idx, counters.size - 1)]
    samples: list[Sample] = [
        OdometrySample(
            float(t[i]),
            p[i],
            q[i],
            None if v is None or not np.isfinite(v[i]).all() else v[i],
            None if counters is None else int(counters[i]),
        )
        for i in range(t.shape[0])
    ]
    out.add(Stream.ODOMETRY, f"{m.position} + {m.attitude}", samples)


def _add_ulog_imu(out: _UlogStreams, imu: Mapping[str, np.ndarray] | None, topic: str) -> None:
    """The IMU stream: ``sensor_combined``'s gyro and accelerometer, FRD turned to FLU; samples with a
    non-finite value left out."""
    if imu is None:
        return
    t = _times(imu, out.t0)
    w = frd_to_flu(_fields(imu, ("gyro_rad[0]", "gyro_rad[1]", "gyro_rad[2]"), topic))
    f = frd_to_flu(
        _fields(imu, ("accelerometer_m_s2[0]", "accelerometer_m_s2[1]", "accelerometer_m_s2[2]"), topic)
    )
    ok = np.isfinite(w).all(axis=1) & np.isfinite(f).all(axis=1)
    out.add(Stream.IMU, topic, [ImuSample(float(t[i]), f[i], w[i]) for i in np.flatnonzero(ok)])


def _add_ulog_range(out: _UlogStreams, rng: Mapping[str, np.ndarray] | None, topic: str) -> None:
    """The range stream: ``current_distance``, None where it is not a finite, non-negative distance."""
    if rng is None:
        return
    t = _times(rng, out.t0)
    d: FloatArray = _fields(rng, ("current_distance",), topic)[:, 0]
    samples: list[Sample] = [
        RangeSample(float(t[i]), float(d[i]) if math.isfinite(d[i]) and d[i] >= 0 else None)
        for i in range(t.shape[0])
    ]
    out.add(Stream.RANGE, topic, samples)


def _add_ulog_truth(out: _UlogStreams, ulog: Any, m: UlogMapping) -> None:
    """The vehicle's ground truth, when the log has it (PX4's simulators log it)."""
    truth = _ulog_pose(
        _ulog_topic(ulog, m.truth_position, m.multi_id),
        _ulog_topic(ulog, m.truth_attitude, m.multi_id),
        m.truth_position,
        m.truth_attitude,
        out.t0,
    )
    if truth is None:
        return
    t, p, q, v = truth
    samples: list[Sample] = [
        TruthSample(float(t[i]), Stream.TRUTH_EGO, p[i], q[i], None if v is None else v[i])
        for i in range(t.shape[0])
    ]
    out.add(Stream.TRUTH_EGO, m.truth_position, samples)


# --------------------------------------------------------------------------------------------------
# ROS 1 / ROS 2 bags
# --------------------------------------------------------------------------------------------------

_POSE_TYPES = (
    "nav_msgs/msg/Odometry",
    "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
)
_ACCEPTED: dict[Stream, tuple[str, ...]] = {
    Stream.ODOMETRY: _POSE_TYPES,
    Stream.TRUTH_EGO: _POSE_TYPES,
    Stream.TRUTH_PLATFORM: _POSE_TYPES,
    Stream.IMU: ("sensor_msgs/msg/Imu",),
    Stream.RANGE: ("sensor_msgs/msg/Range",),
    Stream.IMAGE: ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage"),
}


def _check_bag_dir(p: Path) -> None:
    """Refuse, in one line, a directory that cannot be a ROS 2 bag: unreadable, empty, or without the
    ``metadata.yaml`` rosbags reads first (it raised a 34-line traceback)."""
    try:
        names = sorted(e.name for e in p.iterdir())
    except OSError as err:
        raise ReplayError(f"{p}: cannot read the directory ({err.strerror})") from None
    if not names:
        raise ReplayError(f"{p}: empty directory (expected a ROS 2 bag: metadata.yaml and its .db3 or .mcap)")
    if "metadata.yaml" not in names:
        raise ReplayError(f"{p}: not a ROS 2 bag directory (no metadata.yaml)")


def _bag_paths(p: Path) -> tuple[list[Path], str]:
    if p.suffix.lower() == ".bag":
        return [p], "ros1"
    if p.is_dir():
        return [p], "ros2"
    # a lone .db3 / .mcap: rosbags reads a ROS 2 bag from its directory (metadata.yaml) when there is one
    if (p.parent / "metadata.yaml").is_file():
        return [p.parent], "ros2"
    return [p], "ros2"


def _open_bag(path: Path, m: RosMapping) -> Recording:
    AnyReader = need("rosbags.highlevel").AnyReader

    paths, fmt = _bag_paths(path)
    salvaged = ""
    try:
        reader: Any = AnyReader(paths)
        reader.open()
    except Exception as err:  # noqa: BLE001 - rosbags raises its own errors, sqlite3's, mcap's, OSError
        reason = _describe(err)
        reader = _salvage(paths[0]) if fmt == "ros2" else None
        if reader is None:
            raise ReplayError(
                f"{path}: not a readable {'ROS 1' if fmt == 'ros1' else 'ROS 2'} bag ({reason})"
            ) from None
        salvaged = (
            f"the MCAP file is damaged ({reason}); replayed the {reader.message_count} messages before "
            f"the damage{f' ({reader.stopped_by})' if reader.stopped_by else ''}"
        )
    try:
        rec = _bag_recording(path, fmt, reader, m)
        if salvaged:
            rec.warnings.append(salvaged)
        return rec
    except ReplayError:
        _close_quietly(reader)
        raise
    except Exception as err:  # noqa: BLE001 - a damaged file makes rosbags raise anything
        _close_quietly(reader)
        raise ReplayError(f"{path}: cannot read the bag's messages ({_describe(err)})") from None


def _salvage(path: Path) -> Any:
    """A :class:`~alight.interfaces.mcap_salvage.McapSalvage` of a ROS 2 bag's MCAP file (or a lone
    ``.mcap``) cut short, when it holds messages; None otherwise (sqlite3, nothing readable)."""
    from alight.interfaces.mcap_salvage import McapSalvage

    files = [path] if path.is_file() else sorted(path.glob("*.mcap"))
    if len(files) != 1 or files[0].suffix.lower() != ".mcap":
        return None
    zstd = False
    meta = files[0].parent / "metadata.yaml"
    if meta.is_file():
        try:
            info = yaml.safe_load(meta.read_text(encoding="utf-8"))["rosbag2_bagfile_information"]
            zstd = info.get("compression_mode") == "message" and info.get("compression_format") == "zstd"
        except Exception:  # noqa: BLE001 - a damaged metadata.yaml: no salvage
            return None
    try:
        salvage = McapSalvage(files[0], zstd_messages=zstd)
    except Exception:  # noqa: BLE001 - not even a readable start
        return None
    return salvage if salvage.message_count > 0 else None


def _close_quietly(reader: Any) -> None:
    try:
        reader.close()
    except Exception:  # noqa: BLE001, S110 - the error being reported matters more
        pass


def _bag_recording(path: Path, fmt: str, reader: Any, m: RosMapping) -> Recording:
    by_topic: dict[str, list[Any]] = {}
    for conn in reader.connections:
        by_topic.setdefault(conn.topic, []).append(conn)
    chosen: dict[Stream, list[Any]] = {}
    for stream in Stream:
        for topic in getattr(m, stream.value):
            conns = [c for c in by_topic.get(topic, []) if c.msgtype in _ACCEPTED[stream]]
            if conns:
                chosen[stream] = conns
                break
    if Stream.ODOMETRY not in chosen and Stream.IMAGE not in chosen:
        have = ", ".join(f"{t} ({cs[0].msgtype})" for t, cs in sorted(by_topic.items())) or "no topics"
        raise ReplayError(
            f"{path}: none of the mapped odometry or image topics is in the bag (it has: {have}); "
            "name them in a --mapping file"
        )
    start = int(reader.start_time) if reader.message_count else 0
    origin = 0 if start < SIM_CLOCK_LIMIT_NS else start
    fast_conns = [c for s, cs in chosen.items() if s is not Stream.IMAGE for c in cs]
    stream_of = {id(c): s for s, cs in chosen.items() for c in cs}
    fast: list[Sample] = []
    counts: dict[str, int] = {}
    if fast_conns:
        for conn, t_ns, raw in reader.messages(connections=fast_conns):
            stream = stream_of[id(conn)]
            msg = reader.deserialize(raw, conn.msgtype)
            s = _sample(stream, msg, conn.msgtype, _stamp_s(msg, t_ns, origin))
            if s is not None:
                fast.append(s)
                counts[stream.value] = counts.get(stream.value, 0) + 1
    fast, dropped = _clean(fast)
    messages = _ros_log_messages(reader, [c for t in m.log for c in by_topic.get(t, [])], origin)
    # frames stamped far from the other messages (or, without them, from the bag's middle) are damaged
    if fast:
        t_mid = float(np.median([x.t for x in fast]))
    else:
        t_mid = ((int(reader.start_time) + int(reader.end_time)) // 2 - origin) * 1e-9
    return Recording(
        path=path,
        format=fmt,
        topics={s.value: cs[0].topic for s, cs in chosen.items()},
        counts=counts,
        dropped=dropped,
        _fast=fast,
        _reader=reader,
        _image_conns=chosen.get(Stream.IMAGE, []),
        _origin_ns=origin,
        _latency_s=m.image_latency_s,
        _t_mid=t_mid,
        messages=messages,
    )


ROS_LOG_TYPES = ("rcl_interfaces/msg/Log", "rosgraph_msgs/msg/Log")
ROS_LOG_LEVELS: dict[str, dict[int, str]] = {
    "rcl_interfaces/msg/Log": {10: "DEBUG", 20: "INFO", 30: "WARN", 40: "ERROR", 50: "FATAL"},
    "rosgraph_msgs/msg/Log": {1: "DEBUG", 2: "INFO", 4: "WARN", 8: "ERROR", 16: "FATAL"},
}
"""The level numbers of ROS 2's and ROS 1's log messages."""


def _ros_log_messages(reader: Any, conns: list[Any], origin_ns: int) -> list[LogMessage]:
    """The text messages of the bag's log topics (``/rosout``), ``[node] text``, in time order on the
    replay's clock (the message's own stamp, else the bag's)."""
    conns = [c for c in conns if c.msgtype in ROS_LOG_TYPES]
    out: list[LogMessage] = []
    if not conns:
        return out
    for conn, t_ns, raw in reader.messages(connections=conns):
        msg = reader.deserialize(raw, conn.msgtype)
        stamp = msg.stamp if conn.msgtype == ROS_LOG_TYPES[0] else msg.header.stamp
        ns = int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)
        t = ((ns if ns else int(t_ns)) - origin_ns) * 1e-9
        level = ROS_LOG_LEVELS[conn.msgtype].get(int(msg.level), str(int(msg.level)))
        name = str(msg.name).strip()
        text = str(msg.msg).strip()
        out.append(LogMessage(t, level, f"[{name}] {text}" if name else text))
    return sorted(out, key=lambda m: m.t)


def _stamp_s(msg: Any, t_ns: int, origin_ns: int) -> float:
    header = getattr(msg, "header", None)
    stamp = getattr(header, "stamp", None)
    if stamp is not None:
        sec = getattr(stamp, "sec", None)
        nsec = getattr(stamp, "nanosec", None)
        if sec is not None and nsec is not None and (sec or nsec):
            return (int(sec) * 1_000_000_000 + int(nsec) - origin_ns) * 1e-9
    return (int(t_ns) - origin_ns) * 1e-9


def _vec(v: Any) -> FloatArray:
    return np.array([v.x, v.y, v.z], dtype=np.float64)


def _quat(q: Any) -> FloatArray:
    return np.array([q.x, q.y, q.z, q.w], dtype=np.float64)


def _sample(stream: Stream, msg: Any, msgtype: str, t: float) -> Sample | None:
    if stream is Stream.IMU:
        f, w = _vec(msg.linear_acceleration), _vec(msg.angular_velocity)
        return ImuSample(t, f, w) if np.isfinite(f).all() and np.isfinite(w).all() else None
    if stream is Stream.RANGE:
        r = float(msg.range)
        ok = math.isfinite(r) and float(msg.min_range) <= r <= float(msg.max_range)
        return RangeSample(t, r if ok else None)
    pose = msg.pose.pose if msgtype != "geometry_msgs/msg/PoseStamped" else msg.pose
    p, q = _vec(pose.position), _quat(pose.orientation)
    n = float(np.linalg.norm(q))
    if not (np.isfinite(p).all() and math.isfinite(n) and abs(n - 1.0) < 0.1):
        return None
    q = q / n
    v = None
    if msgtype == "nav_msgs/msg/Odometry":
        # REP-103: an Odometry's twist is expressed in its child frame (the body): v_W = R_WB v_B
        from alight.types import quat_to_rotmat

        v_B = _vec(msg.twist.twist.linear)
        v = quat_to_rotmat(q) @ v_B if np.isfinite(v_B).all() else None
    if stream is Stream.ODOMETRY:
        return OdometrySample(t, p, q, v)
    return TruthSample(t, stream, p, q, v)


def _u8(a: Any) -> NDArray[np.uint8]:
    return np.ascontiguousarray(a, dtype=np.uint8)


def decode_image(msg: Any, msgtype: str) -> NDArray[np.uint8] | None:
    """A ``sensor_msgs/Image`` (mono8, bgr8, rgb8, bgra8, rgba8, mono16) or ``CompressedImage`` (any
    format OpenCV decodes) as an (H, W) grey or (H, W, 3) BGR uint8 array; None when it cannot be."""
    if msgtype == "sensor_msgs/msg/CompressedImage":
        # a damaged frame (a JPEG that libjpeg flags) is dropped like any undecodable one
        img: Any = decode_image_bytes(bytes(msg.data))[0]
        if img is None or img.dtype not in (np.uint8, np.uint16):
            return None
        if img.dtype == np.uint16:
            img = img >> 8
        if img.ndim == 3 and img.shape[2] == 4:
            img = cv2.cvtColor(_u8(img), cv2.COLOR_BGRA2BGR)
        return _u8(img)
    channels = {"mono8": 1, "8uc1": 1, "bgr8": 3, "rgb8": 3, "8uc3": 3, "bgra8": 4, "rgba8": 4, "mono16": 2}
    enc = str(msg.encoding).lower()
    c = channels.get(enc)
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    data = np.asarray(msg.data, dtype=np.uint8)
    if c is None or h <= 0 or w <= 0 or step < w * c or data.size < h * step:
        return None
    rows = data[: h * step].reshape(h, step)[:, : w * c]
    if enc == "mono16":
        dt = ">u2" if msg.is_bigendian else "<u2"
        return _u8(rows.copy().view(dt).reshape(h, w) >> 8)
    img = rows.reshape(h, w, c) if c > 1 else rows.reshape(h, w)
    conversion = {"rgb8": cv2.COLOR_RGB2BGR, "bgra8": cv2.COLOR_BGRA2BGR, "rgba8": cv2.COLOR_RGBA2BGR}.get(
        enc
    )
    return _u8(img if conversion is None else cv2.cvtColor(img, conversion))
