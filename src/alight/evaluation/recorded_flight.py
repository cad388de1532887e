"""What a recorded flight gives its replay report: the log's own streams at their own rates, the log's
messages, a few camera frames with what the detector found, and the comparison of alight's ego
estimate with the log's own estimate (and with the log's ground truth, when it has one).

Frames and units as everywhere in alight: W ENU, B FLU, SI, quaternions (x, y, z, w). The log's own
estimate is what the recording calls its odometry (PX4: ``vehicle_local_position`` with
``vehicle_attitude``, EKF2's output); it is not ground truth, and the report never calls it that.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from alight.types import Observation

FloatArray = NDArray[np.float64]

FRAMES_SHOWN = 6
"""Camera frames the report shows at most (frames with detections first, spread over the flight)."""
FRAME_WIDTH_PX = 480
"""Frames are kept downscaled to at most this width, so that a long bag costs little memory."""


@dataclass(frozen=True)
class PoseTrack:
    """A pose stream at its own rate: (N,) times, (N, 3) positions, (N, 4) attitudes, (N, 3) velocities
    (NaN where the log has none)."""

    t: FloatArray
    p_W: FloatArray
    q_W: FloatArray
    v_W: FloatArray

    @staticmethod
    def empty() -> PoseTrack:
        return PoseTrack(np.zeros(0), np.zeros((0, 3)), np.zeros((0, 4)), np.zeros((0, 3)))


@dataclass(frozen=True)
class LogMessage:
    """A text message the recording carries (PX4's logged messages, ROS' /rosout)."""

    t: float
    """time on the replay's clock (s)"""
    level: str
    """``EMERGENCY`` ... ``DEBUG`` as the log names it"""
    text: str


WARNING_LEVELS = frozenset(
    {"EMERGENCY", "EMERG", "ALERT", "CRITICAL", "CRIT", "ERROR", "ERR", "WARNING", "WARN"}
)
"""Levels the report shows as warnings (the names PX4's and ROS' logs use)."""


@dataclass(frozen=True)
class CameraFrame:
    """A camera frame, downscaled to at most :data:`FRAME_WIDTH_PX`, and what the detector found in it
    (pixels scaled with the image)."""

    t: float
    image: NDArray[np.uint8]
    observations: list[Observation]


@dataclass
class RecordedFlight:
    """Everything the recorded flight's report shows besides ``result.json`` and the mission log."""

    estimate_label: str
    """what the log's own estimate is, for the plots' legends (e.g. ``PX4 (vehicle_local_position)``)"""
    odometry: PoseTrack
    truth: PoseTrack | None = None
    """the vehicle's ground truth, when the log has it (simulators write it)"""
    truth_label: str = ""
    imu_t: FloatArray = field(default_factory=lambda: np.zeros(0))
    f_B: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    """specific force in B (m/s^2)"""
    w_B: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    """body rates in B (rad/s)"""
    range_t: FloatArray = field(default_factory=lambda: np.zeros(0))
    range_m: FloatArray = field(default_factory=lambda: np.zeros(0))
    """range-finder readings (m), NaN where invalid"""
    messages: list[LogMessage] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    """what the reader noticed (PX4's validity flags, a damaged or cut file)"""
    vehicle: str = ""
    """the autopilot and board the log names, when it does"""
    frames: list[CameraFrame] = field(default_factory=list)


class FrameSampler:
    """Keeps at most ``2 * keep`` of a stream of unknown length, evenly spaced: every ``stride``-th item,
    the stride doubling (and every other kept item dropped) when the store is full. Deterministic."""

    def __init__(self, keep: int) -> None:
        self.keep = max(int(keep), 1)
        self.stride = 1
        self.seen = 0
        self.items: list[CameraFrame] = []

    def offer(self, make: Callable[[], CameraFrame]) -> None:
        """Count one more item of the stream and keep it (``make()``, called only then) when it falls
        on the stride."""
        if self.seen % self.stride == 0:
            self.items.append(make())
            if len(self.items) > 2 * self.keep:
                self.items = self.items[::2]
                self.stride *= 2
        self.seen += 1

    def spread(self, n: int) -> list[CameraFrame]:
        """``n`` of the kept items spread over them (all when there are no more than ``n``)."""
        if len(self.items) <= n:
            return list(self.items)
        idx = np.linspace(0, len(self.items) - 1, n).round().astype(int)
        return [self.items[i] for i in idx]


def frames_to_show(
    with_detections: FrameSampler, without: FrameSampler, n: int = FRAMES_SHOWN
) -> list[CameraFrame]:
    """Frames with detections first, the rest of ``n`` from the others, in time order."""
    chosen = with_detections.spread(n)
    chosen += without.spread(n - len(chosen))
    return sorted(chosen, key=lambda f: f.t)


def held_at(t_src: FloatArray, values: FloatArray, t: FloatArray) -> FloatArray:
    """``values`` (rows at ``t_src``, increasing) held at times ``t``: the latest row stamped before each
    (by more than 1 ns), NaN before the first. That is the sample the replay had handed the Pipeline when
    it logged the row at ``t``: a sample stamped at a tick arrives after that tick has run."""
    out = np.full((t.shape[0], values.shape[1]), np.nan)
    if t_src.size == 0:
        return out
    k = np.searchsorted(t_src, t - 1e-9, side="left") - 1
    ok = k >= 0
    out[ok] = values[k[ok]]
    return out


def euler_rpy(q_xyzw: FloatArray) -> FloatArray:
    """(N, 3) roll, pitch, yaw (rad) of attitudes q_WB: yaw about W's z (from east, anticlockwise), then
    pitch about the turned y (B's left: positive is nose down), then roll about B's x; NaN rows kept."""
    out = np.full((q_xyzw.shape[0], 3), np.nan)
    ok = np.isfinite(q_xyzw).all(axis=1) & (np.linalg.norm(q_xyzw, axis=1) > 0.5)
    if ok.any():
        out[ok] = Rotation.from_quat(q_xyzw[ok]).as_euler("ZYX")[:, ::-1]
    return out


def attitude_angle(q_a: FloatArray, q_b: FloatArray) -> FloatArray:
    """(N,) the angle (rad) of the rotation between two attitudes, row by row: 2 acos |<q_a, q_b>|; NaN
    where either is missing."""
    na = np.linalg.norm(q_a, axis=1)
    nb = np.linalg.norm(q_b, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        dot = np.abs(np.sum(q_a * q_b, axis=1)) / (na * nb)
    return np.asarray(2.0 * np.arccos(np.clip(dot, 0.0, 1.0)), dtype=np.float64)


def rms(x: FloatArray) -> float | None:
    """Root mean square of the finite values, None when there are none."""
    a = np.asarray(x, dtype=np.float64).reshape(-1)
    a = a[np.isfinite(a)]
    return float(np.sqrt(np.mean(a**2))) if a.size else None


@dataclass(frozen=True)
class EstimateDifference:
    """alight's ego estimate against another track, at the mission log's times."""

    t: FloatArray
    position_m: FloatArray
    """(N,) |p_est - p|"""
    velocity_mps: FloatArray
    """(N,) |v_est - v| (NaN where the track has no velocity)"""
    attitude_rad: FloatArray
    """(N,) the angle between the two attitudes"""

    def summary(self) -> dict[str, float | None]:
        att = rms(self.attitude_rad)
        return {
            "position_rms_m": rms(self.position_m),
            "velocity_rms_mps": rms(self.velocity_mps),
            "attitude_rms_deg": None if att is None else float(np.degrees(att)),
        }


def difference(
    t: FloatArray, p_est: FloatArray, v_est: FloatArray, q_est: FloatArray, track: PoseTrack
) -> EstimateDifference:
    """alight's estimate (rows at ``t``) against ``track`` held at the same times."""
    p = held_at(track.t, track.p_W, t)
    v = held_at(track.t, track.v_W, t)
    q = held_at(track.t, track.q_W, t)
    return EstimateDifference(
        t,
        np.linalg.norm(p_est - p, axis=1),
        np.linalg.norm(v_est - v, axis=1),
        attitude_angle(q_est, q),
    )


def estimate_differences(
    rec: RecordedFlight, log: Mapping[str, np.ndarray]
) -> list[tuple[str, EstimateDifference]]:
    """alight's ego estimate (the mission log's ``*_est`` channels) against the log's own estimate, and
    against the log's ground truth when it has one, at the mission log's times."""
    t = np.asarray(log.get("t", np.zeros(0)), dtype=np.float64).reshape(-1)

    def channel(name: str, width: int) -> FloatArray:
        return np.asarray(log.get(name, np.full((t.size, width), np.nan)), dtype=np.float64).reshape(
            -1, width
        )

    est = (channel("p_WB_est", 3), channel("v_WB_est", 3), channel("q_WB_est", 4))
    out = [("the log's estimate", difference(t, *est, rec.odometry))]
    if rec.truth is not None:
        out.append(("ground truth", difference(t, *est, rec.truth)))
    return out
