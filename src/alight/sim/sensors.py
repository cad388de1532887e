"""Simulated onboard sensors: IMU, VIO-like odometry, a downward range finder and an optical-flow module.

Each sensor takes ground truth and a ``numpy.random.Generator``; it splits a child generator off it at
construction (one draw from the caller's generator) and draws its noise from the child in blocks, so a
sample costs a few microseconds and the noise sequence does not depend on how calls are batched. The
sensors do not schedule themselves: the runner calls ``measure`` once per sample period
(``config.rate_hz``); random walks advance by one nominal period per call.

Attitudes come in as ``q_WB`` (x, y, z, w), as the quadrotor state stores them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated

import numpy as np
from numba import njit
from pydantic import Field
from pydantic.dataclasses import dataclass as pydantic_dataclass

from alight.numerics.rotation import rotmat_entries, unit_quats_to_rotmats
from alight.settings import SETTINGS, NonNegFloat, PositiveFloat
from alight.types import GRAVITY_MPS2, EgoState, FloatArray, quat_to_rotmat

from .platform import PlatformTruth


class _NormalStream:
    """Standard normal rows of a fixed width, drawn in blocks from a child generator."""

    def __init__(self, rng: np.random.Generator, width: int, block: int = 512) -> None:
        self._rng = np.random.default_rng(rng.integers(0, 2**63 - 1))
        self._width = width
        self._block = block
        self._buf = np.empty((0, width))
        self._next: FloatArray | None = None  # the block after _buf, when a peek already drew it
        self._i = 0

    def _advance_block(self) -> None:
        self._buf = (
            self._next if self._next is not None else self._rng.standard_normal((self._block, self._width))
        )
        self._next = None
        self._i = 0

    def row(self) -> FloatArray:
        if self._i >= self._buf.shape[0]:
            self._advance_block()
        r: FloatArray = self._buf[self._i]
        self._i += 1
        return r

    def take(self, n: int) -> FloatArray:
        """The next n rows, shape (n, width): the same numbers n calls of :meth:`row` would give."""
        out = np.empty((n, self._width))
        k = 0
        while k < n:
            if self._i >= self._buf.shape[0]:
                self._advance_block()
            m = min(n - k, self._buf.shape[0] - self._i)
            out[k : k + m] = self._buf[self._i : self._i + m]
            self._i += m
            k += m
        return out

    def peek(self, n: int) -> FloatArray:
        """The next n rows (n <= block) without using them up (:meth:`skip` does): shape (n, width)."""
        if n > self._block:
            raise ValueError(f"peek of {n} rows: at most one block ({self._block})")
        if self._i >= self._buf.shape[0]:
            self._advance_block()
        left = self._buf.shape[0] - self._i
        if n <= left:
            return self._buf[self._i : self._i + n].copy()
        if self._next is None:
            self._next = self._rng.standard_normal((self._block, self._width))
        return np.concatenate([self._buf[self._i :], self._next[: n - left]])

    def skip(self, n: int) -> None:
        """Use up the next n rows (at most the n of the last :meth:`peek`)."""
        left = self._buf.shape[0] - self._i
        if n <= left:
            self._i += n
        else:
            self._advance_block()
            self._i = n - left


def _f64(a: FloatArray) -> FloatArray:
    return np.ascontiguousarray(a, dtype=np.float64)


@njit(cache=True)
def _body_axis(q: FloatArray, k: int | np.int64) -> tuple[float, float, float]:
    """Column k of R_WB for the unit quaternion q = (x, y, z, w): the body axis k in W."""
    e = rotmat_entries(q[0], q[1], q[2], q[3], 2.0)
    if k == 0:
        return e[0], e[3], e[6]
    if k == 1:
        return e[1], e[4], e[7]
    return e[2], e[5], e[8]


def _positive(name: str, v: float) -> None:
    if not (v > 0.0 and math.isfinite(v)):
        raise ValueError(f"{name} must be positive and finite, got {v}")


def _non_negative(obj: object, names: tuple[str, ...]) -> None:
    for name in names:
        v = getattr(obj, name)
        if not (v >= 0.0 and math.isfinite(v)):
            raise ValueError(f"{name} must be >= 0 and finite, got {v}")


# --------------------------------------------------------------------------------------------------
# IMU
# --------------------------------------------------------------------------------------------------


@njit(cache=True)
def _imu_sample(
    a_WB: FloatArray, q_WB: FloatArray, w_WB_B: FloatArray, bias: FloatArray, n: FloatArray, scale: FloatArray
) -> FloatArray:
    """(specific force, body rate) stacked (6,); steps the biases (6,) in place."""
    out = np.empty(6)
    fx, fy, fz = a_WB[0], a_WB[1], a_WB[2] + GRAVITY_MPS2  # a_WB - g_W
    for k in range(3):
        ax, ay, az = _body_axis(q_WB, k)
        out[k] = ax * fx + ay * fy + az * fz + bias[k] + scale[k] * n[k]
        out[3 + k] = w_WB_B[k] + bias[3 + k] + scale[3 + k] * n[3 + k]
    for k in range(6):
        bias[k] += scale[6 + k] * n[6 + k]
    return out


imu_sample_kernel = _imu_sample
"""The IMU model as a numba function, for compiled loops (see :meth:`Imu.kernel_inputs`)."""


@dataclass(frozen=True, kw_only=True)
class ImuConfig:
    """A consumer MEMS IMU (orders of magnitude of the Bosch BMI088 / TDK ICM-42688 / MPU-6000 data
    sheets, 100-400 ug/sqrt(Hz) and 0.004-0.014 deg/s/sqrt(Hz), and of Kalibr's example IMU models)."""

    rate_hz: float = 200.0
    """Sample rate (Hz)."""
    accel_noise_density: float = 0.003
    """White noise of the accelerometer (m/s^2/sqrt(Hz)); per-sample std = density * sqrt(rate)."""
    gyro_noise_density: float = 3.0e-4
    """White noise of the gyroscope (rad/s/sqrt(Hz))."""
    accel_bias_random_walk: float = 5.0e-4
    """Accelerometer bias random walk (m/s^3/sqrt(Hz)); per-sample std = rw * sqrt(1 / rate)."""
    gyro_bias_random_walk: float = 2.0e-5
    """Gyroscope bias random walk (rad/s^2/sqrt(Hz))."""
    accel_bias_init_std: float = 0.05
    """Std of the accelerometer's turn-on bias per axis (m/s^2)."""
    gyro_bias_init_std: float = 0.003
    """Std of the gyroscope's turn-on bias per axis (rad/s)."""

    def __post_init__(self) -> None:
        _positive("rate_hz", self.rate_hz)
        _non_negative(
            self,
            (
                "accel_noise_density",
                "gyro_noise_density",
                "accel_bias_random_walk",
                "gyro_bias_random_walk",
                "accel_bias_init_std",
                "gyro_bias_init_std",
            ),
        )


class Imu:
    """Specific force ``R_WB^T (a_WB - g_W) + b_a + n_a`` and body rate ``w_WB_B + b_g + n_g``, both in B.

    ``b_a``, ``b_g`` start at a random turn-on bias and random-walk; the noise is white with the
    per-sample std ``density * sqrt(rate_hz)`` (the discrete equivalent of a continuous white noise of
    that density sampled at that rate).
    """

    def __init__(self, config: ImuConfig, rng: np.random.Generator) -> None:
        self.config = config
        self._stream = _NormalStream(rng, 12)
        b0 = self._stream.row()
        self._bias = np.concatenate(
            [config.accel_bias_init_std * b0[0:3], config.gyro_bias_init_std * b0[3:6]]
        )
        sq = math.sqrt(config.rate_hz)
        sq_dt = 1.0 / sq
        self._scale = np.array(
            [config.accel_noise_density * sq] * 3
            + [config.gyro_noise_density * sq] * 3
            + [config.accel_bias_random_walk * sq_dt] * 3
            + [config.gyro_bias_random_walk * sq_dt] * 3
        )

    @property
    def accel_bias(self) -> FloatArray:
        """Current accelerometer bias (m/s^2), shape (3,) (truth, for logs and tests)."""
        return self._bias[0:3].copy()

    @property
    def gyro_bias(self) -> FloatArray:
        """Current gyroscope bias (rad/s), shape (3,)."""
        return self._bias[3:6].copy()

    @property
    def accel_noise_std(self) -> float:
        """Per-sample std of the accelerometer noise (m/s^2)."""
        return self.config.accel_noise_density * math.sqrt(self.config.rate_hz)

    @property
    def gyro_noise_std(self) -> float:
        """Per-sample std of the gyroscope noise (rad/s)."""
        return self.config.gyro_noise_density * math.sqrt(self.config.rate_hz)

    def measure(
        self, a_WB: FloatArray, q_WB: FloatArray, w_WB_B: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """One sample from the true acceleration a_WB (3,) m/s^2 in W, attitude q_WB (4,) and body rate
        w_WB_B (3,) rad/s (float64 arrays). Returns (specific force in B (3,) m/s^2, body rate in B (3,)
        rad/s); the biases then take one random-walk step."""
        out = _imu_sample(_f64(a_WB), _f64(q_WB), _f64(w_WB_B), self._bias, self._stream.row(), self._scale)
        return out[0:3], out[3:6]

    def step_bias(self, delta: FloatArray) -> None:
        """Add a step to the biases: ``delta`` (6,), accelerometer (m/s^2) then gyroscope (rad/s), in B
        (a fault: a temperature jump or a knock). In place, so a caller of :meth:`kernel_inputs_many`
        holding the bias vector sees it."""
        self._bias += np.asarray(delta, dtype=np.float64).reshape(6)

    def kernel_inputs(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """For a caller that samples the IMU inside its own compiled loop with :func:`imu_sample_kernel`:
        the bias vector (6,) that the kernel steps in place, the next noise row (12,) and the scales
        (12,). One call per sample; the same numbers as :meth:`measure`."""
        return self._bias, self._stream.row(), self._scale

    def kernel_inputs_many(self, m: int) -> tuple[FloatArray, FloatArray, FloatArray]:
        """As :meth:`kernel_inputs` for up to ``m`` samples: the next noise rows (m, 12), which stay
        unused until :meth:`used` says how many the kernel took (the rest go to the next samples)."""
        return self._bias, self._stream.peek(m), self._scale

    def used(self, n: int) -> None:
        """The compiled loop took ``n`` of the rows :meth:`kernel_inputs_many` gave."""
        self._stream.skip(n)

    def measure_many(
        self, a_WB: FloatArray, q_WB: FloatArray, w_WB_B: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """N consecutive samples at once (the same numbers as N calls of :meth:`measure`): a_WB (N, 3),
        q_WB (N, 4), w_WB_B (N, 3) -> (specific forces (N, 3), body rates (N, 3))."""
        a = np.asarray(a_WB, dtype=np.float64)
        n_s = a.shape[0]
        n = self._stream.take(n_s) * self._scale
        # bias of sample k: initial + the first k increments
        ba = self._bias[0:3] + np.cumsum(n[:, 6:9], axis=0) - n[:, 6:9]
        bg = self._bias[3:6] + np.cumsum(n[:, 9:12], axis=0) - n[:, 9:12]
        R = unit_quats_to_rotmats(q_WB)
        f = a.copy()
        f[:, 2] += GRAVITY_MPS2
        acc = np.einsum("nji,nj->ni", R, f) + ba + n[:, 0:3]
        gyr = np.asarray(w_WB_B, dtype=np.float64) + bg + n[:, 3:6]
        self._bias[0:3] = ba[-1] + n[-1, 6:9]
        self._bias[3:6] = bg[-1] + n[-1, 9:12]
        return acc, gyr


# --------------------------------------------------------------------------------------------------
# Odometry
# --------------------------------------------------------------------------------------------------


@njit(cache=True)
def _odometry_sample(
    p: FloatArray,
    v: FloatArray,
    q: FloatArray,
    w: FloatArray,
    drift: FloatArray,
    n: FloatArray,
    scale: FloatArray,
) -> FloatArray:
    """(p, v, q, w) of the odometry stacked (13,); steps the drift (4,) in place."""
    out = np.empty(13)
    c, s = math.cos(drift[3]), math.sin(drift[3])
    out[0] = c * p[0] - s * p[1] + drift[0] + scale[0] * n[0]
    out[1] = s * p[0] + c * p[1] + drift[1] + scale[1] * n[1]
    out[2] = p[2] + drift[2] + scale[2] * n[2]
    out[3] = c * v[0] - s * v[1] + scale[3] * n[3]
    out[4] = s * v[0] + c * v[1] + scale[4] * n[4]
    out[5] = v[2] + scale[5] * n[5]
    # q_z(psi) (x) q: a rotation about W z
    sz, cz = math.sin(0.5 * drift[3]), math.cos(0.5 * drift[3])
    ax = cz * q[0] - sz * q[1]
    ay = cz * q[1] + sz * q[0]
    az = cz * q[2] + sz * q[3]
    aw = cz * q[3] - sz * q[2]
    # (x) exp(theta / 2): body-frame rotation noise
    tx, ty, tz = scale[6] * n[6], scale[7] * n[7], scale[8] * n[8]
    ang = math.sqrt(tx * tx + ty * ty + tz * tz)
    k = 0.5 if ang == 0.0 else math.sin(0.5 * ang) / ang
    bx, by, bz, bw = k * tx, k * ty, k * tz, math.cos(0.5 * ang)
    qx = aw * bx + ax * bw + ay * bz - az * by
    qy = aw * by - ax * bz + ay * bw + az * bx
    qz = aw * bz + ax * by - ay * bx + az * bw
    qw = aw * bw - ax * bx - ay * by - az * bz
    nq = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    out[6] = qx / nq
    out[7] = qy / nq
    out[8] = qz / nq
    out[9] = qw / nq
    for j in range(3):
        out[10 + j] = w[j] + scale[9 + j] * n[9 + j]
    for j in range(4):
        drift[j] += scale[12 + j] * n[12 + j]
    # The heading's step turns the motion from now on, not the path already flown: the offset takes up
    # (R_z(psi_old) - R_z(psi_new)) p, so the position stays continuous and consistent with the velocity.
    # Rotating the whole path about W's origin instead would jump the position by |p| dpsi per sample,
    # across the track and without a matching velocity (0.1-0.5 m at 500 m from take-off).
    c1, s1 = math.cos(drift[3]), math.sin(drift[3])
    drift[0] += (c - c1) * p[0] - (s - s1) * p[1]
    drift[1] += (s - s1) * p[0] + (c - c1) * p[1]
    return out


@dataclass(frozen=True, kw_only=True)
class OdometryConfig:
    """A visual-inertial odometry pipeline's output (40 Hz as in paper 000 Sec. III-A)."""

    rate_hz: float = 40.0
    """Output rate (Hz)."""
    position_noise_m: float = 0.01
    """White noise on the position per axis (m)."""
    velocity_noise_mps: float = 0.02
    """White noise on the velocity per axis (m/s)."""
    attitude_noise_rad: float = 0.005
    """White rotation noise per body axis (rad)."""
    rate_noise_radps: float = 0.005
    """White noise on the body rates per axis (rad/s)."""
    position_drift_density: float = 0.005
    """Random walk of the position offset per axis (m/sqrt(s)): 3.9 cm std after 60 s."""
    yaw_drift_density: float = 5.0e-4
    """Random walk of the odometry frame's heading (rad/sqrt(s)): 0.22 deg std after 60 s."""

    def __post_init__(self) -> None:
        _positive("rate_hz", self.rate_hz)
        _non_negative(
            self,
            (
                "position_noise_m",
                "velocity_noise_mps",
                "attitude_noise_rad",
                "rate_noise_radps",
                "position_drift_density",
                "yaw_drift_density",
            ),
        )


class Odometry:
    """VIO-like ego state: the truth seen from an odometry frame that drifts away from W.

    The drift is a heading ``psi_d`` and an offset ``b_p``, both random walks (VIO is unobservable in
    position and yaw, so those drift; roll and pitch stay anchored by gravity). A step of the heading
    turns the motion from then on, as a VIO's heading error does, not the path already flown: the offset
    takes up ``(R_z(psi_old) - R_z(psi_new)) p_WB`` at each step, so the position is continuous::

        p = R_z(psi_d) p_WB + b_p + n_p,   v = R_z(psi_d) v_WB + n_v,
        q = q_z(psi_d) (x) q_WB (x) exp(n_theta / 2),   w = w_WB_B + n_w

    The rotation of the frame is about W's origin (the take-off point, where VIO starts).
    """

    def __init__(self, config: OdometryConfig, rng: np.random.Generator) -> None:
        self.config = config
        self._stream = _NormalStream(rng, 16)
        self._drift = np.zeros(4)  # position offset (3), heading (1)
        c = config
        sq_dt = 1.0 / math.sqrt(c.rate_hz)
        self._scale = np.array(
            [c.position_noise_m] * 3
            + [c.velocity_noise_mps] * 3
            + [c.attitude_noise_rad] * 3
            + [c.rate_noise_radps] * 3
            + [c.position_drift_density * sq_dt] * 3
            + [c.yaw_drift_density * sq_dt]
        )

    @property
    def drift_p(self) -> FloatArray:
        """Current position offset of the odometry frame (m), shape (3,)."""
        return self._drift[0:3].copy()

    @property
    def drift_yaw(self) -> float:
        """Current heading of the odometry frame relative to W (rad)."""
        return float(self._drift[3])

    def measure(
        self, t: float, p_WB: FloatArray, v_WB: FloatArray, q_WB: FloatArray, w_WB_B: FloatArray
    ) -> EgoState:
        """One odometry output at time t (s) from the truth p_WB (3,) m, v_WB (3,) m/s, q_WB (4,),
        w_WB_B (3,) rad/s; the drift then takes one random-walk step."""
        out = _odometry_sample(
            _f64(p_WB), _f64(v_WB), _f64(q_WB), _f64(w_WB_B), self._drift, self._stream.row(), self._scale
        )
        # The kernel's output is finite with a unit quaternion: the unchecked constructor is safe.
        return EgoState.trusted(t, out[0:3], out[3:6], out[6:10], out[10:13])


# --------------------------------------------------------------------------------------------------
# Range finder
# --------------------------------------------------------------------------------------------------


@pydantic_dataclass(frozen=True, kw_only=True, config=SETTINGS)
class RangeFinderConfig:
    """A TeraRanger One-like time-of-flight distance sensor pointing along -z_B, measured from the
    landing-gear feet (the scenario's ``rangefinder``).

    The real sensor measures 0.2 to 14 m, and so does this one by default: closer than ``min_range_m``
    (the blind zone) it reports ``-inf``, never a number, so the onboard land detector cannot rely on a
    reading of ~0 at touchdown (set 0 for an ideal sensor).
    """

    rate_hz: PositiveFloat = 100.0
    """Sample rate (Hz)."""
    max_range_m: PositiveFloat = 14.0
    """Beyond this it reports ``+inf`` (m)."""
    min_range_m: NonNegFloat = 0.2
    """Blind zone (m): closer than this the sensor reports ``-inf`` (ROS REP 117), as a real
    TeraRanger One (0.2 m) does; 0 for an ideal sensor."""
    noise_std_m: NonNegFloat = 0.02
    """White noise on the range (m)."""
    origin_B: tuple[float, float, float] = (0.0, 0.0, -0.10)
    """Sensor position in B (m): by default at the landing-gear feet under the body origin (the
    default airframe's gear height)."""

    def __post_init__(self) -> None:
        if self.min_range_m >= self.max_range_m:
            raise ValueError("rangefinder.max_range_m must be above min_range_m")


PAD_THICKNESS_M = 0.05
"""Thickness of the pad (m): a ray starting less than this below its surface, over it, hits it at 0."""


@njit(cache=True)
def range_to_surface(
    o_W: FloatArray, d_W: FloatArray, p_WP: FloatArray, yaw: float, pad_size_m: float
) -> float:
    """Distance (m) along the unit ray o_W + lambda d_W, lambda >= 0, to the first surface: the pad
    square (at height p_WP[2], centred at p_WP, heading ``yaw``) or the ground z = 0. ``inf`` when the
    ray does not point down. The platform's body under the pad is not modelled."""
    dz: float = d_W[2]
    if dz >= 0.0:
        return math.inf
    h: float = p_WP[2]
    oz: float = o_W[2]
    # a sensor at the feet of a vehicle standing on the pad sits a millimetre into it (the contact
    # model's compression): within the pad's thickness it still sees the pad, at range 0
    if oz >= h - PAD_THICKNESS_M:
        lam = max(oz - h, 0.0) / -dz
        hx = o_W[0] + lam * d_W[0] - p_WP[0]
        hy = o_W[1] + lam * d_W[1] - p_WP[1]
        c, s = math.cos(yaw), math.sin(yaw)
        half = 0.5 * pad_size_m
        if abs(c * hx + s * hy) <= half and abs(-s * hx + c * hy) <= half:
            return lam
    return max(oz, 0.0) / -dz


@njit(cache=True)
def range_to_deck(
    o_W: FloatArray, d_W: FloatArray, p_WP: FloatArray, R_WP: FloatArray, extent_P: FloatArray
) -> float:
    """Distance (m) along the unit ray o_W + lambda d_W, lambda >= 0, to the first surface: a tilted deck
    (the plane through ``p_WP`` with normal ``R_WP[:, 2]``, over ``extent_P`` = x_min, x_max, y_min, y_max
    on its own axes: a vessel at sea) or the sea's mean level z = 0. ``inf`` when the ray does not point
    down. A ray from above the deck's plane that meets it inside the extent hits the deck."""
    dz: float = d_W[2]
    if dz >= 0.0:
        return math.inf
    nx, ny, nz = R_WP[0, 2], R_WP[1, 2], R_WP[2, 2]
    ox, oy, oz = o_W[0] - p_WP[0], o_W[1] - p_WP[1], o_W[2] - p_WP[2]
    h = ox * nx + oy * ny + oz * nz  # the origin's height above the deck's plane
    dn = d_W[0] * nx + d_W[1] * ny + d_W[2] * nz
    if h >= -PAD_THICKNESS_M and dn < 0.0:
        lam: float = max(h, 0.0) / -dn
        hx, hy, hz = ox + lam * d_W[0], oy + lam * d_W[1], oz + lam * d_W[2]
        lx = R_WP[0, 0] * hx + R_WP[1, 0] * hy + R_WP[2, 0] * hz
        ly = R_WP[0, 1] * hx + R_WP[1, 1] * hy + R_WP[2, 1] * hz
        if extent_P[0] <= lx <= extent_P[1] and extent_P[2] <= ly <= extent_P[3]:
            return lam
    sea: float = max(o_W[2], 0.0) / -dz
    return sea


@njit(cache=True, inline="always")
def _sensor_ray(p_WB: FloatArray, q_WB: FloatArray, origin_B: FloatArray) -> tuple[FloatArray, FloatArray]:
    # the sensor's origin in W and its ray along -z_B (inlined into its callers: as a call it cost the
    # range reading 42 ns, its two arrays returned through the call boundary)
    o = np.empty(3)
    d = np.empty(3)
    for k in range(3):
        o[k] = p_WB[k]
    for k in range(3):
        ax, ay, az = _body_axis(q_WB, k)
        o[0] += ax * origin_B[k]
        o[1] += ay * origin_B[k]
        o[2] += az * origin_B[k]
    zx, zy, zz = _body_axis(q_WB, np.int64(2))  # an int64, not a literal 2: _body_axis compiles once
    d[0], d[1], d[2] = -zx, -zy, -zz
    return o, d


@njit(cache=True)
def true_range_to_deck(
    p_WB: FloatArray,
    q_WB: FloatArray,
    origin_B: FloatArray,
    p_WP: FloatArray,
    R_WP: FloatArray,
    extent_P: FloatArray,
) -> float:
    """:func:`range_to_deck` along the sensor's ray (at ``origin_B`` in B, along -z_B) (m)."""
    o, d = _sensor_ray(p_WB, q_WB, origin_B)
    return range_to_deck(o, d, p_WP, R_WP, extent_P)


@njit(cache=True)
def _true_range(
    p_WB: FloatArray, q_WB: FloatArray, origin_B: FloatArray, p_WP: FloatArray, yaw: float, pad_size_m: float
) -> float:
    o, d = _sensor_ray(p_WB, q_WB, origin_B)
    return range_to_surface(o, d, p_WP, yaw, pad_size_m)


class RangeFinder:
    """Range along -z_B to the pad or the ground, with white noise.

    Out-of-range readings follow ROS REP 117, as the TeraRanger ROS driver does: ``-inf`` when the
    true range is below ``min_range_m``, ``+inf`` when it is beyond ``max_range_m`` or nothing is hit
    (ray pointing up); use ``math.isfinite`` to test validity. Noisy in-range readings are clipped at 0.
    """

    def __init__(self, config: RangeFinderConfig, rng: np.random.Generator) -> None:
        self.config = config
        self._stream = _NormalStream(rng, 1, block=1024)
        self._origin_B = np.array(config.origin_B, dtype=np.float64)

    def true_range(
        self, p_WB: FloatArray, q_WB: FloatArray, platform: PlatformTruth, pad_size_m: float
    ) -> float:
        """Noise-free range (m) from the truth; ``inf`` when the ray does not hit anything."""
        return _true_range(_f64(p_WB), _f64(q_WB), self._origin_B, platform.p_WP, platform.yaw, pad_size_m)

    def measure(
        self, p_WB: FloatArray, q_WB: FloatArray, platform: PlatformTruth, pad_size_m: float
    ) -> float:
        """One reading (m) from the truth p_WB (3,), q_WB (4,), the platform's state and pad side (m)."""
        return self.measure_at(p_WB, q_WB, platform.p_WP, platform.yaw, pad_size_m)

    def measure_at(
        self, p_WB: FloatArray, q_WB: FloatArray, p_WP: FloatArray, yaw: float, pad_size_m: float
    ) -> float:
        """As :meth:`measure`, with the pad centre ``p_WP`` (3,) and heading ``yaw`` given directly (for a
        caller that holds the platform's states as arrays)."""
        r = _true_range(_f64(p_WB), _f64(q_WB), self._origin_B, _f64(p_WP), float(yaw), pad_size_m)
        noise = float(self._stream.row()[0]) * self.config.noise_std_m
        if r > self.config.max_range_m:
            return math.inf
        if r < self.config.min_range_m:
            return -math.inf
        return max(r + noise, 0.0)

    def measure_on_deck(
        self, p_WB: FloatArray, q_WB: FloatArray, p_WP: FloatArray, R_WP: FloatArray, extent_P: FloatArray
    ) -> float:
        """As :meth:`measure_at` over a vessel's tilted deck (:func:`range_to_deck`): the pad centre
        ``p_WP``, the deck's orientation ``R_WP`` and its extent on its own axes ``extent_P`` (4,)."""
        r = true_range_to_deck(_f64(p_WB), _f64(q_WB), self._origin_B, _f64(p_WP), _f64(R_WP), _f64(extent_P))
        noise = float(self._stream.row()[0]) * self.config.noise_std_m
        if r > self.config.max_range_m:
            return math.inf
        if r < self.config.min_range_m:
            return -math.inf
        return max(r + noise, 0.0)


SENSOR_TICK_HZ = 200.0
"""The simulator's sensor tick (Hz), the IMU's rate: every other sensor samples at a whole divisor of it."""


@pydantic_dataclass(frozen=True, config=SETTINGS)
class OpticalFlowConfig:
    """A downward optical-flow module with its own short-range distance sensor, as PX4 flies them (ARK
    Flow, Holybro H-Flow: a PAW3902 or PMW3901 flow sensor beside a VL53L1X time-of-flight ranger), at the
    landing-gear feet like the range finder. What it measures is the apparent angular rate of the surface
    under it, so over the deck it sees the vehicle's velocity *relative to the deck*, at tens of hertz and
    without the camera, which no longer sees the whole pad in the last half metre."""

    rate_hz: Annotated[float, Field(gt=0, le=1000.0, allow_inf_nan=False)] = 50.0
    """Sample rate (Hz); 200 Hz divided by a whole number (the simulator's sensor tick)."""
    noise_rad_s: NonNegFloat = 0.05
    """White noise on each flow axis (rad/s)."""
    min_range_m: NonNegFloat = 0.08
    """Closest surface the flow sensor resolves (m; ARK Flow: 80 mm); closer, no sample."""
    max_range_m: PositiveFloat = 4.0
    """Farthest surface of its ranger (m; VL53L1X long mode); farther, no sample."""
    range_noise_m: NonNegFloat = 0.01
    """White noise on the module's distance (m)."""
    origin_B: tuple[float, float, float] = (0.0, 0.0, -0.10)
    """Module position in B (m)."""

    def __post_init__(self) -> None:
        if not self.max_range_m > self.min_range_m:
            raise ValueError("optical_flow.max_range_m must be above min_range_m")
        ticks = SENSOR_TICK_HZ / self.rate_hz
        if abs(ticks - round(ticks)) > 1e-9:
            raise ValueError(
                f"optical_flow.rate_hz must divide 200 Hz (200, 100, 50, 40, 25, ...), got {self.rate_hz:g}"
            )


@dataclass(frozen=True)
class FlowSample:
    """One optical-flow sample, as the module reports it (not compensated for the body's rotation)."""

    t: float
    """Time of the sample (s)."""
    flow_B_rad_s: FloatArray
    """(2,) apparent angular rate of the surface's texture along x_B and y_B (rad/s): for a surface at
    distance d along -z_B moving at v_rel_B relative to the sensor, ``(-v_x / d + w_y, -v_y / d - w_x)``
    with the body rates w (what PX4's OPTICAL_FLOW_RAD integrates, before its gyro compensation)."""
    distance_m: float
    """The module's own range to the surface along -z_B (m)."""


class OpticalFlowSensor:
    """Flow of the surface under the module (the pad, moving with the platform, or the ground), with
    white noise; no sample outside its range. Its distance comes from the same ray as the range
    finder's (:func:`_true_range`), from the module's own origin."""

    def __init__(self, config: OpticalFlowConfig, rng: np.random.Generator) -> None:
        self.config = config
        self._stream = _NormalStream(rng, 3, block=512)
        self._origin_B = np.array(config.origin_B, dtype=np.float64)

    def measure_at(
        self,
        t: float,
        x_B: tuple[FloatArray, FloatArray, FloatArray, FloatArray],
        deck: tuple[FloatArray, FloatArray, float, float],
        pad_size_m: float,
    ) -> FlowSample | None:
        """A sample at ``t`` from the body's truth ``x_B = (p_WB, v_WB, q_WB, w_WB_B)`` and the deck's
        ``(p_WP, v_WP, yaw, yaw_rate)``; None when the surface is out of the module's range (a draw is made
        either way, so the noise of later samples does not depend on it)."""
        p_WB, v_WB, q_WB, w_B = (_f64(a) for a in x_B)
        p_WP, v_WP, yaw, yaw_rate = _f64(deck[0]), _f64(deck[1]), float(deck[2]), float(deck[3])
        noise = self._stream.row()
        cfg = self.config
        d = _true_range(p_WB, q_WB, self._origin_B, p_WP, yaw, pad_size_m)
        if not (cfg.min_range_m <= d <= cfg.max_range_m):
            return None
        R_WB = quat_to_rotmat(q_WB)
        o_W = p_WB + R_WB @ self._origin_B
        hit_W = o_W - d * R_WB[:, 2]
        # the surface's velocity where the ray meets it: the deck's (a rigid body turning at yaw_rate) on
        # the pad, else the ground's
        r = hit_W - p_WP
        c, s = math.cos(yaw), math.sin(yaw)
        half = 0.5 * pad_size_m
        on_pad = abs(r[2]) < 1e-6 and abs(c * r[0] + s * r[1]) <= half and abs(-s * r[0] + c * r[1]) <= half
        v_surface_W = v_WP + yaw_rate * np.array([-r[1], r[0], 0.0]) if on_pad else np.zeros(3)
        v_sensor_W = v_WB + R_WB @ np.cross(w_B, self._origin_B)
        v_rel_B = R_WB.T @ (v_sensor_W - v_surface_W)
        flow = np.array([-v_rel_B[0] / d + w_B[1], -v_rel_B[1] / d - w_B[0]])
        flow += cfg.noise_rad_s * noise[:2]
        return FlowSample(float(t), flow, max(d + cfg.range_noise_m * float(noise[2]), 0.0))

    def measure_on_deck(
        self,
        t: float,
        x_B: tuple[FloatArray, FloatArray, FloatArray, FloatArray],
        deck: tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray],
    ) -> FlowSample | None:
        """As :meth:`measure_at` over a vessel's tilted, moving deck ``(p_WP, v_WP, R_WP, w_WP_W,
        extent_P)``: the distance to the deck's plane (:func:`range_to_deck`), and where the ray meets
        the deck the surface's velocity ``v_WP + w x (hit - p_WP)``, else the sea's (still)."""
        p_WB, v_WB, q_WB, w_B = (_f64(a) for a in x_B)
        p_WP, v_WP, R_WP, w_WP, extent = (_f64(a) for a in deck)
        noise = self._stream.row()
        cfg = self.config
        d = true_range_to_deck(p_WB, q_WB, self._origin_B, p_WP, R_WP, extent)
        if not (cfg.min_range_m <= d <= cfg.max_range_m):
            return None
        R_WB = quat_to_rotmat(q_WB)
        o_W = p_WB + R_WB @ self._origin_B
        hit_W = o_W - d * R_WB[:, 2]
        r = hit_W - p_WP
        on_deck = abs(float(r @ R_WP[:, 2])) < 1e-6
        v_surface_W = v_WP + np.cross(w_WP, r) if on_deck else np.zeros(3)
        v_sensor_W = v_WB + R_WB @ np.cross(w_B, self._origin_B)
        v_rel_B = R_WB.T @ (v_sensor_W - v_surface_W)
        flow = np.array([-v_rel_B[0] / d + w_B[1], -v_rel_B[1] / d - w_B[0]])
        flow += cfg.noise_rad_s * noise[:2]
        return FlowSample(float(t), flow, max(d + cfg.range_noise_m * float(noise[2]), 0.0))
