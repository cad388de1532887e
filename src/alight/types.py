"""Messages passed between the pipeline stages, and small frame helpers.

Conventions (see ``docs/conventions.md``): world ``W`` is ENU with z up, body ``B`` is FLU, camera ``C``
is OpenCV (x right, y down, z along the optical axis), pad ``P`` has its origin at the pad centre, z up and
x along the platform's heading. Names carry frames in monogram notation: ``p_WB`` is the position of B
in W, ``R_WB`` rotates B-vectors into W, ``w_WB_B`` is the angular velocity of B in W expressed in B.
Quaternions are stored as SciPy does, ``(x, y, z, w)``. SI units, radians, seconds of simulated time.

Every message is a frozen dataclass; arrays are made read-only float64 copies so that a message can be
shared between stages without one stage mutating another's data.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

# The frame helpers live in alight.numerics.rotation (one implementation for kernels and Python); they
# are re-exported here, where the messages that use them are.
from alight.numerics import FloatArray as FloatArray
from alight.numerics.rotation import quat_to_rotmat as quat_to_rotmat
from alight.numerics.rotation import rot_z as rot_z
from alight.numerics.rotation import rotmat_to_quat as rotmat_to_quat
from alight.numerics.rotation import wrap_angle as wrap_angle
from alight.numerics.rotation import yaw_of as yaw_of

U8Array = NDArray[np.uint8]
"""An 8-bit image or mask: grey (H, W) or BGR (H, W, 3)."""

Image = NDArray[Any]
"""A camera frame as handed to a detector: a numeric array, grey (H, W) or colour (H, W, C) with C in 1, 3
or 4 (BGR, BGRA), of any numeric dtype. :mod:`alight.perception.image_input` is the one reading of it
(uint8 unchanged; other dtypes scaled; anything that is not an image gives no observation)."""

GRAVITY_MPS2 = 9.81
"""Magnitude of gravity; ``g_W = (0, 0, -GRAVITY_MPS2)`` in the z-up world."""

G_W: FloatArray = np.array([0.0, 0.0, -GRAVITY_MPS2])
G_W.setflags(write=False)
_ZERO3: FloatArray = np.zeros(3)
_ZERO3.setflags(write=False)


def _frozen_base(a: FloatArray) -> bool:
    # A view into a read-only array that owns its data (a packed message, see EgoState.from_packed).
    base = a.base
    return type(base) is np.ndarray and base.flags.owndata and not base.flags.writeable


def _frozen(a: object, shape: tuple[int, ...], name: str) -> FloatArray:
    # An array that is already read-only, float64, owns its data and has the right shape cannot change
    # under us (messages pass such arrays on to one another): share it instead of copying.
    if (
        type(a) is np.ndarray
        and a.dtype == np.float64
        and a.shape == shape
        and not a.flags.writeable
        and (a.flags.owndata or _frozen_base(a))
    ):
        return a
    arr = np.array(a, dtype=np.float64)  # a copy, so the caller keeps ownership of its buffer
    if arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    arr.flags.writeable = False
    return arr


def _frozen_any(a: object, ndim: int, name: str) -> FloatArray:
    arr = np.array(a, dtype=np.float64)
    if arr.ndim != ndim:
        raise ValueError(f"{name} must have {ndim} dimensions, got shape {arr.shape}")
    arr.setflags(write=False)
    return arr


# --------------------------------------------------------------------------------------------------
# Messages
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class EgoState:
    """The vehicle's own state as the ego estimator (or the autopilot) reports it."""

    t: float
    """Time of validity (s)."""
    p_WB: FloatArray
    """Position of the body origin in W (m), shape (3,)."""
    v_WB: FloatArray
    """Velocity of the body origin in W, expressed in W (m/s), shape (3,)."""
    q_WB: FloatArray
    """Attitude, unit quaternion (x, y, z, w) rotating B-vectors into W, shape (4,)."""
    w_WB_B: FloatArray
    """Body rates, expressed in B (rad/s), shape (3,)."""
    a_WB: FloatArray = None  # type: ignore[assignment]  # None becomes a shared read-only zero
    """Acceleration of the body in W (m/s^2) where the estimator provides it, shape (3,)."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "p_WB", _frozen(self.p_WB, (3,), "p_WB"))
        object.__setattr__(self, "v_WB", _frozen(self.v_WB, (3,), "v_WB"))
        q = _frozen(self.q_WB, (4,), "q_WB")
        n = math.sqrt(float(q @ q))
        if not (abs(n - 1.0) < 1e-6):
            raise ValueError(f"q_WB must be a unit quaternion, norm is {n}")
        object.__setattr__(self, "q_WB", q)
        object.__setattr__(self, "w_WB_B", _frozen(self.w_WB_B, (3,), "w_WB_B"))
        if self.a_WB is None:
            object.__setattr__(self, "a_WB", _ZERO3)
        else:
            object.__setattr__(self, "a_WB", _frozen(self.a_WB, (3,), "a_WB"))

    @classmethod
    def from_packed(cls, t: float, packed: FloatArray) -> EgoState:
        """Construct without validation from one float64 array (16,) laid out as p_WB, v_WB, q_WB, w_WB_B,
        a_WB, which the message takes over (made read-only; the caller must not keep writing to it). For
        the ego estimator at 100-200 Hz: one array instead of five copies. The fields are views of it."""
        self = object.__new__(cls)
        packed.flags.writeable = False
        setattr_ = object.__setattr__
        setattr_(self, "t", float(t))
        setattr_(self, "p_WB", packed[0:3])
        setattr_(self, "v_WB", packed[3:6])
        setattr_(self, "q_WB", packed[6:10])
        setattr_(self, "w_WB_B", packed[10:13])
        setattr_(self, "a_WB", packed[13:16])
        return self

    @classmethod
    def trusted(
        cls,
        t: float,
        p_WB: FloatArray,
        v_WB: FloatArray,
        q_WB: FloatArray,
        w_WB_B: FloatArray,
        a_WB: FloatArray | None = None,
    ) -> EgoState:
        """Construct without validation, for producers that guarantee float64 arrays of the right shapes
        and a unit quaternion (the ego estimator at 100-200 Hz, where the checks cost more than the
        filter step). The arrays are still copied and made read-only."""
        self = object.__new__(cls)
        setattr_ = object.__setattr__
        setattr_(self, "t", float(t))
        for name, value in (("p_WB", p_WB), ("v_WB", v_WB), ("q_WB", q_WB), ("w_WB_B", w_WB_B)):
            arr = value.copy()
            arr.flags.writeable = False
            setattr_(self, name, arr)
        if a_WB is None:
            setattr_(self, "a_WB", _ZERO3)
        else:
            arr = a_WB.copy()
            arr.flags.writeable = False
            setattr_(self, "a_WB", arr)
        return self

    @property
    def R_WB(self) -> FloatArray:
        return quat_to_rotmat(self.q_WB)

    def is_finite(self) -> bool:
        return bool(
            np.isfinite(self.p_WB).all()
            and np.isfinite(self.v_WB).all()
            and np.isfinite(self.q_WB).all()
            and np.isfinite(self.w_WB_B).all()
        )


@dataclass(frozen=True, slots=True)
class Observation:
    """What a detector found in one image (or what the ground-truth sensor reports).

    Detectors fill ``pixels`` (and ``points_P`` when the points' positions on the pad are known, for
    PnP). Sensors that measure the relative pose directly (the ground-truth perception, a detector that
    runs PnP itself) fill ``p_CP`` and ``cov_p_CP``.
    """

    t: float
    """Capture time of the image (s)."""
    kind: str
    """What was found: ``circle``, ``cross``, ``quad``, ``blob``, ``nfold``, ``aruco:ID``, ``truth`` ..."""
    quality: float
    """Detector confidence in [0, 1]."""
    pixels: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))
    """Image points (u, v) in pixels, shape (N, 2)."""
    points_P: FloatArray | None = None
    """The matching points on the pad, in P (m), shape (N, 3), when known."""
    p_CP: FloatArray | None = None
    """Pad centre in the camera frame (m), shape (3,), when measured directly."""
    cov_p_CP: FloatArray | None = None
    """Covariance of ``p_CP`` (m^2), shape (3, 3)."""
    yaw_CP: float | None = None
    """Rotation of the pad x axis about the camera's optical axis (rad), when measured."""

    def __post_init__(self) -> None:
        if not (0.0 <= self.quality <= 1.0) or not math.isfinite(self.quality):
            raise ValueError(f"quality must be in [0, 1], got {self.quality}")
        px = _frozen_any(self.pixels, 2, "pixels") if np.size(self.pixels) else np.zeros((0, 2))
        object.__setattr__(self, "pixels", px)
        if self.points_P is not None:
            pts = _frozen_any(self.points_P, 2, "points_P")
            if pts.shape != (px.shape[0], 3):
                raise ValueError(f"points_P must have shape ({px.shape[0]}, 3), got {pts.shape}")
            object.__setattr__(self, "points_P", pts)
        if self.p_CP is not None:
            object.__setattr__(self, "p_CP", _frozen(self.p_CP, (3,), "p_CP"))
        if self.cov_p_CP is not None:
            object.__setattr__(self, "cov_p_CP", _frozen(self.cov_p_CP, (3, 3), "cov_p_CP"))


@dataclass(frozen=True, slots=True)
class PlatformMeasurement:
    """A measurement of the platform (pad centre) in the world frame, as a geolocator outputs it."""

    t: float
    """Capture time of the image the measurement comes from (s)."""
    p_WP: FloatArray
    """Pad centre in W (m), shape (3,)."""
    cov_p_WP: FloatArray
    """Covariance of ``p_WP`` (m^2), shape (3, 3), symmetric positive definite."""
    yaw: float | None = None
    """Heading of the pad x axis in W (rad), when measured."""
    yaw_var: float | None = None
    """Variance of ``yaw`` (rad^2)."""
    n_WP: FloatArray | None = None
    """The pad's normal (its z axis) in W, a unit vector (3,), when the pose is measured (PnP): a tilted
    deck's attitude, unambiguous for a pad symmetric under rotations about its normal."""
    cov_n_WP: FloatArray | None = None
    """Covariance of ``n_WP`` (3, 3), with ``n_WP``."""

    def __post_init__(self) -> None:
        p = _frozen(self.p_WP, (3,), "p_WP")
        c = _frozen(self.cov_p_WP, (3, 3), "cov_p_WP")
        if not (np.isfinite(p).all() and np.isfinite(c).all()):
            raise ValueError("PlatformMeasurement must be finite")
        object.__setattr__(self, "p_WP", p)
        object.__setattr__(self, "cov_p_WP", c)
        if (self.n_WP is None) != (self.cov_n_WP is None):
            raise ValueError("PlatformMeasurement: n_WP and cov_n_WP come together")
        if self.n_WP is not None and self.cov_n_WP is not None:
            n = _frozen(self.n_WP, (3,), "n_WP")
            cn = _frozen(self.cov_n_WP, (3, 3), "cov_n_WP")
            if not (np.isfinite(n).all() and np.isfinite(cn).all() and abs(float(n @ n) - 1.0) < 1e-6):
                raise ValueError("PlatformMeasurement: n_WP must be a finite unit vector, cov_n_WP finite")
            object.__setattr__(self, "n_WP", n)
            object.__setattr__(self, "cov_n_WP", cn)


@dataclass(frozen=True, slots=True)
class PlatformEstimate:
    """The platform estimator's belief at time ``t``."""

    t: float
    p_WP: FloatArray
    """Pad centre in W (m), shape (3,)."""
    v_WP: FloatArray
    """Pad velocity in W (m/s), shape (3,)."""
    a_WP: FloatArray
    """Pad acceleration in W (m/s^2), shape (3,) (centripetal for a turning unicycle)."""
    yaw: float
    """Heading of the platform (rad)."""
    cov_p_WP: FloatArray
    """Position covariance (m^2), shape (3, 3)."""
    t_last_measurement: float
    """Time of the last measurement used (s); ``t - t_last_measurement`` is the age of the estimate."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "p_WP", _frozen(self.p_WP, (3,), "p_WP"))
        object.__setattr__(self, "v_WP", _frozen(self.v_WP, (3,), "v_WP"))
        object.__setattr__(self, "a_WP", _frozen(self.a_WP, (3,), "a_WP"))
        object.__setattr__(self, "cov_p_WP", _frozen(self.cov_p_WP, (3, 3), "cov_p_WP"))

    @classmethod
    def trusted(
        cls,
        t: float,
        p_WP: FloatArray,
        v_WP: FloatArray,
        a_WP: FloatArray,
        yaw: float,
        cov_p_WP: FloatArray,
        t_last_measurement: float,
    ) -> PlatformEstimate:
        """Construct without validation, for estimators that pass float64 arrays of the right shapes which
        they own and never write again (queried at the planner's and the logger's rates). The arrays are
        made read-only, not copied."""
        self = object.__new__(cls)
        setattr_ = object.__setattr__
        setattr_(self, "t", float(t))
        for name, arr in (("p_WP", p_WP), ("v_WP", v_WP), ("a_WP", a_WP), ("cov_p_WP", cov_p_WP)):
            arr.flags.writeable = False
            setattr_(self, name, arr)
        setattr_(self, "yaw", float(yaw))
        setattr_(self, "t_last_measurement", float(t_last_measurement))
        return self


@dataclass(frozen=True, slots=True)
class Reference:
    """A point of the reference trajectory the controller tracks (all in W)."""

    t: float
    p: FloatArray
    """Position (m), shape (3,)."""
    v: FloatArray
    """Velocity (m/s), shape (3,)."""
    a: FloatArray
    """Acceleration (m/s^2), shape (3,)."""
    j: FloatArray
    """Jerk (m/s^3), shape (3,)."""
    yaw: float = 0.0
    """Heading (rad)."""
    yaw_rate: float = 0.0
    """Heading rate (rad/s)."""

    def __post_init__(self) -> None:
        for name in ("p", "v", "a", "j"):
            object.__setattr__(self, name, _frozen(getattr(self, name), (3,), name))

    @classmethod
    def from_packed(cls, t: float, pvaj: FloatArray, yaw: float = 0.0, yaw_rate: float = 0.0) -> Reference:
        """Construct without validation from one float64 array (4, 3) with rows p, v, a, j, which the
        message takes over (made read-only); the fields are views of it. For the guidance at 100 Hz."""
        self = object.__new__(cls)
        pvaj.flags.writeable = False
        setattr_ = object.__setattr__
        setattr_(self, "t", float(t))
        setattr_(self, "p", pvaj[0])
        setattr_(self, "v", pvaj[1])
        setattr_(self, "a", pvaj[2])
        setattr_(self, "j", pvaj[3])
        setattr_(self, "yaw", float(yaw))
        setattr_(self, "yaw_rate", float(yaw_rate))
        return self

    @classmethod
    def trusted(
        cls,
        t: float,
        p: FloatArray,
        v: FloatArray,
        a: FloatArray,
        j: FloatArray,
        yaw: float = 0.0,
        yaw_rate: float = 0.0,
    ) -> Reference:
        """Construct without validation, for producers that guarantee finite float64 (3,) arrays (the
        guidance at the controller's rate). The arrays are copied and made read-only."""
        self = object.__new__(cls)
        setattr_ = object.__setattr__
        setattr_(self, "t", float(t))
        for name, value in (("p", p), ("v", v), ("a", a), ("j", j)):
            if value.flags.writeable or not value.flags.owndata:
                value = value.copy()
                value.flags.writeable = False
            setattr_(self, name, value)
        setattr_(self, "yaw", float(yaw))
        setattr_(self, "yaw_rate", float(yaw_rate))
        return self


@dataclass(frozen=True, slots=True)
class Command:
    """What the high-level controller asks of the low level."""

    t: float
    thrust_N: float
    """Collective thrust along +z_B (N)."""
    w_WB_B_cmd: FloatArray
    """Commanded body rates, expressed in B (rad/s), shape (3,)."""
    motors_off: bool = False
    """True once the mission has stopped the motors (after touchdown)."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "w_WB_B_cmd", _frozen(self.w_WB_B_cmd, (3,), "w_WB_B_cmd"))
        if not math.isfinite(self.thrust_N):
            raise ValueError(f"thrust_N must be finite, got {self.thrust_N}")

    @classmethod
    def trusted(cls, t: float, thrust_N: float, w_WB_B_cmd: FloatArray) -> Command:
        """Construct without validation, for the controller at 100 Hz that has already checked its output
        is finite. ``w_WB_B_cmd`` is copied and made read-only."""
        self = object.__new__(cls)
        setattr_ = object.__setattr__
        w = w_WB_B_cmd.copy()
        w.flags.writeable = False
        setattr_(self, "t", float(t))
        setattr_(self, "thrust_N", float(thrust_N))
        setattr_(self, "w_WB_B_cmd", w)
        setattr_(self, "motors_off", False)
        return self


PIPELINE_BLOCKS = (
    "ego_estimator",
    "detector",
    "geolocator",
    "platform_estimator",
    "mission",
    "guidance",
    "controller",
)
"""The pipeline's blocks, in data-flow order: what a preset swaps, and what the pipeline times
(``result.json``'s ``block_time_s``, a campaign's ``<block>_time_s`` columns)."""


class Mode(enum.StrEnum):
    """Mission modes (paper 000 Sec. II-F plus the failsafe modes)."""

    IDLE = "idle"
    TAKEOFF = "takeoff"
    EXPLORE = "explore"
    TRACK = "track"
    SEARCH = "search"
    LAND = "land"
    GO_AROUND = "go_around"
    LANDED = "landed"
    ABORT = "abort"


class Outcome(enum.StrEnum):
    """How a mission ended, judged from ground truth by the simulator."""

    LANDED = "landed"
    CRASHED = "crashed"
    TIMEOUT = "timeout"
    ABORTED = "aborted"
    ERROR = "error"
