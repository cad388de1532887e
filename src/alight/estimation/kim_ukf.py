"""UKF of paper 003 (Kim et al., Sec. IV, eq. 10-27): the target's position and velocity relative to the
camera, with the omnidirectional camera's pixel as the measurement.

**State** (eq. 14) ``x = [x, y, v_x, v_y, phi_C, theta_C, psi_C]``: the horizontal position of the target
relative to the camera (``x'_CT``, m), its rate (``v'_CT``, m/s) and the Euler angles of the camera frame
in the navigation frame (rad). The paper's navigation frame is NED; ours is alight's world W (ENU, z up),
so ``x_CT = [x, y, -H]`` in W (the target ``H`` below the camera) and ``eta_C`` are the ZYX angles of
``R_WC = Rz(psi) Ry(theta) Rx(phi)`` (a downward camera sits at ``phi = pi``, ``theta = 0``, far from
the singularity at ``theta = +-pi/2``, which would need the camera's x axis vertical).

**Process model** (eq. 10-16): the target moves at constant velocity in W (eq. 10, 11), so with the
camera's velocity change ``Delta v_C`` between two steps the relative velocity obeys
``v_CT,k = v_CT,k-1 - Delta v_C`` (eq. 12), and

    x_k = A x_k-1 + u_k,  A = [[I, dt I, 0], [0, I, 0], [0, 0, 0]],  u = [delta_p, -Delta v'_C, eta_C].  (16)

The attitude block of ``A`` is zero: the attitude is the measured one, fed as the input (eq. 15) with the
attitude noise as its process noise, so the sigma points carry the attitude's uncertainty into the
measurement model. The position slot of ``u`` is 0 in eq. 15; we put there the part of the camera's
displacement that ``dt v_C,k-1`` misses, ``delta_p = -(Delta p_C - dt v_C,k-1)`` (0 when the camera
moves at constant velocity), so the state stays exactly ``p_target - p_camera`` under any camera motion.
Process noise: white acceleration of the target (``accel_noise``, m/s^2/sqrt(Hz)) on the position and
velocity blocks, ``attitude_std^2`` on the attitude block.

**Measurement model** (eq. 17-27): the pixel ``(u, v)`` of the target. In the camera frame
``x_C = R_WC^T x_CT``; with ``r = |(X_C, Y_C)|`` the omnidirectional model (eq. 22, 23) gives eq. 24,

    a0 + a1 rho + a2 rho^2 + a3 rho^3 + a4 rho^4 = rho K,   K = z_OCam / r = -Z_C / r,      (24)

a quartic in ``rho`` (any degree here: all of ``ss``). Root selection as the paper says: the root must be
positive and real; among several, the one nearest ``rho_prev``, the radius of the previous (most recent)
measurement (before the first measurement: the current one's). Then (eq. 25-27) the ideal sensor-plane
point ``rho (X_C, Y_C) / r`` goes through the calibration's affine and centre to the pixel (OpenCV
``(u, v)``, see :mod:`alight.cameras.omni`, whose :func:`~alight.cameras.omni.project_exact_point` this
is). The real roots come from :mod:`alight.numerics.poly` (isolated between the real roots of the
polynomial's derivatives, polished by safeguarded Newton: exact, any degree, ~1 us per sigma point). With
``measurement_model="camera"`` the pixel is any camera model's ``project`` instead (a pinhole preset).

The camera height ``H`` (eq. 18) comes from the ego estimate: ``H = p_WC[2] - deck_height`` (the paper
uses the altitude above the ground); its uncertainty (``height_std``) enters as measurement noise through
``dh/dH`` at the predicted state.

**What the preset feeds it.** The paper feeds pixels into the UKF; :meth:`KimUkf.update_pixel` does that
(it needs the ego state at the capture time for ``H``, the attitude input and ``Delta v_C``) and is what the
``kim_kaist`` preset should use. :meth:`KimUkf.update` takes world-frame
:class:`~alight.types.PlatformMeasurement` s (e.g. from the flat-earth geolocator) through the linear model
``z = p_anchor + x'_CT``, so the filter also works in the generic pipeline and as a like-for-like
comparison with the other estimators.

**World frame outputs.** The filter keeps the camera's position and velocity at its time (the *anchor*,
``p_a``, ``v_a``), so ``p_WP = p_a + [x, y]`` and ``v_WP = v_a + [v_x, v_y]``; with no ego given (world
measurements), the anchor continues at constant velocity. The pad height is not in the paper's state:
it is ``deck_height`` for pixel measurements and a scalar random walk fed by the world measurements' z
otherwise. Like :class:`~alight.estimation.platform_ekf.PlatformEkf`, the filter stays at the last
measurement's capture time; :meth:`KimUkf.state` and :meth:`KimUkf.predict_ahead` extrapolate (constant
velocity) and measurements captured before the filter time are rejected (``n_out_of_order``).

**Initialisation.** From the first pixel by flat-earth geolocation (eq. 5-9) with the covariance of
(position, attitude) from an unscented transform of the pixel, attitude and height noise; the velocity
prior is a target at rest (``v_CT = -v_C``) with ``init_speed_std``. ``initialized`` turns True when the
velocity's standard deviation drops below ``init_velocity_std``. With ``gating``, an innovation whose NIS
exceeds the chi-square quantile is rejected; ``reinit_after_rejections`` consecutive rejections restart
the track from the last one.

**Speed.** The filter is the generic :mod:`alight.estimation.ukf` with the models above; for pixel
updates with the quartic model, :func:`kim_pixel_step` does the same predict + update in one compiled
call (any scheme with ``unit_points``; a test checks it against the generic path to 1e-10), about 5x
faster than the Python path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Protocol, cast

import numpy as np
from numba import njit
from scipy.special import chdtri

from alight.cameras import CameraModel
from alight.cameras.omni import OmniCamera, project_exact_point, project_exact_work
from alight.cameras.pinhole import CameraMount, camera_pose_W
from alight.errors import ConfigError, EstimationError, MeasurementError
from alight.estimation.guards import (
    FUTURE_TOLERANCE_S,
    MAX_HORIZON_S,
    MAX_POSITION_M,
    MAX_SPEED_MPS,
    MAX_TIME_S,
    StampRun,
    as_real_array,
    as_time,
    check_measurement,
    check_rotation,
    check_time,
    check_times,
    check_vector,
)
from alight.estimation.sigma_points import (
    CubatureSigmaPoints,
    MerweScaledSigmaPoints,
    SigmaPointScheme,
    SimplexSigmaPoints,
)
from alight.estimation.turn_rate import TurnRateConfig, TurnRateTracker, turn_predict
from alight.estimation.ukf import (
    CORRECT_GATED,
    CORRECT_NOT_PD,
    CORRECT_OK,
    COVARIANCE_UPDATES,
    GATED,
    INVALID,
    NOT_POSITIVE_DEFINITE,
    OK,
    UpdateResult,
    ukf_correct,
    ukf_predict,
    ukf_update,
    unscented_transform,
)
from alight.numerics.linalg import cholesky
from alight.types import EgoState, FloatArray, PlatformEstimate, PlatformMeasurement

N_STATE = 7
_MIN_ATT_STD = 1e-9
"""Floor of the attitude noise (rad): an exactly known attitude would make the covariance singular."""
I_X, I_Y, I_VX, I_VY, I_PHI, I_THETA, I_PSI = range(7)

# --------------------------------------------------------------------------------------------------
# The fisheye measurement per sigma point (numba; the lens model is alight.cameras.omni's)
# --------------------------------------------------------------------------------------------------


@njit(cache=True)
def kim_measurement_kernel(
    X: FloatArray,
    H: float,
    ss: FloatArray,
    xc: float,
    yc: float,
    c: float,
    d: float,
    e: float,
    rho_ref: float,
    rho_max: float,
    out: FloatArray,
) -> None:
    """``h(x, H)`` of eq. 18-27 for every sigma point: ``X`` (m, 7) -> pixels ``out`` (m, 2).
    ``x_C = R_WC(eta)^T [x, y, -H]`` with ``R_WC = Rz(psi) Ry(theta) Rx(phi)``."""
    coef, roots, D, crit = project_exact_work(ss.shape[0])
    for i in range(X.shape[0]):
        cf = math.cos(X[i, I_PHI])
        sf = math.sin(X[i, I_PHI])
        ct = math.cos(X[i, I_THETA])
        st = math.sin(X[i, I_THETA])
        cp = math.cos(X[i, I_PSI])
        sp = math.sin(X[i, I_PSI])
        w0 = X[i, I_X]
        w1 = X[i, I_Y]
        w2 = -H
        # columns of R_WC dotted with x_CT (= R_WC^T x_CT)
        Xc = cp * ct * w0 + sp * ct * w1 - st * w2
        Yc = (cp * st * sf - sp * cf) * w0 + (sp * st * sf + cp * cf) * w1 + ct * sf * w2
        Zc = (cp * st * cf + sp * sf) * w0 + (sp * st * cf - cp * sf) * w1 + ct * cf * w2
        u, v = project_exact_point(Xc, Yc, Zc, ss, xc, yc, c, d, e, rho_ref, rho_max, coef, roots, D, crit)
        out[i, 0] = u
        out[i, 1] = v


# --------------------------------------------------------------------------------------------------
# Attitude helpers
# --------------------------------------------------------------------------------------------------


def euler_zyx(R: FloatArray) -> FloatArray:
    """ZYX Euler angles ``(phi, theta, psi)`` (rad) of ``R = Rz(psi) Ry(theta) Rx(phi)``, (3,)."""
    return np.array(
        [
            math.atan2(R[2, 1], R[2, 2]),
            -math.asin(min(1.0, max(-1.0, R[2, 0]))),
            math.atan2(R[1, 0], R[0, 0]),
        ]
    )


def rotation_zyx(eta: FloatArray) -> FloatArray:
    """``Rz(psi) Ry(theta) Rx(phi)`` for angles ``eta`` (m, 3) -> (m, 3, 3) (or (3,) -> (3, 3))."""
    e = np.asarray(eta, dtype=np.float64)
    single = e.ndim == 1
    e = e.reshape(-1, 3)
    cf, sf = np.cos(e[:, 0]), np.sin(e[:, 0])
    ct, st = np.cos(e[:, 1]), np.sin(e[:, 1])
    cp, sp = np.cos(e[:, 2]), np.sin(e[:, 2])
    R = np.empty((e.shape[0], 3, 3))
    R[:, 0, 0] = cp * ct
    R[:, 0, 1] = cp * st * sf - sp * cf
    R[:, 0, 2] = cp * st * cf + sp * sf
    R[:, 1, 0] = sp * ct
    R[:, 1, 1] = sp * st * sf + cp * cf
    R[:, 1, 2] = sp * st * cf - cp * sf
    R[:, 2, 0] = -st
    R[:, 2, 1] = ct * sf
    R[:, 2, 2] = ct * cf
    return R[0] if single else R


# --------------------------------------------------------------------------------------------------
# The paper's models, vectorised over sigma points
# --------------------------------------------------------------------------------------------------


def kim_transition(X: FloatArray, dt: float, u: FloatArray) -> FloatArray:
    """Eq. 16, ``A x + u``, for sigma points ``X`` (m, 7); ``u`` (7,) = ``[delta_p (2), -Delta v'_C (2),
    eta_C (3)]``."""
    Y = np.empty_like(X)
    Y[:, 0:2] = X[:, 0:2] + dt * X[:, 2:4] + u[0:2]
    Y[:, 2:4] = X[:, 2:4] + u[2:4]
    Y[:, 4:7] = u[4:7]  # A's attitude block is zero: the attitude is the input
    return Y


def kim_process_noise(dt: float, accel_noise: float, attitude_std: float) -> FloatArray:
    """Process noise (7, 7): white target acceleration of density ``accel_noise`` (m/s^2/sqrt(Hz)) over
    ``|dt|`` (s) on each horizontal axis, ``attitude_std^2`` (rad^2) on the attitude (the input's noise)."""
    h = abs(dt)
    q = accel_noise * accel_noise
    Q = np.zeros((N_STATE, N_STATE))
    for i in range(2):
        Q[i, i] = q * h**3 / 3.0
        Q[i, i + 2] = Q[i + 2, i] = q * h**2 / 2.0
        Q[i + 2, i + 2] = q * h
    for i in range(4, 7):
        Q[i, i] = attitude_std * attitude_std
    return Q


def kim_fisheye_h(X: FloatArray, H: float, lens: OmniCamera, rho_ref: float) -> FloatArray:
    """Eq. 18-27 for sigma points ``X`` (m, 7) -> pixels (m, 2)."""
    out = np.empty((X.shape[0], 2))
    kim_measurement_kernel(
        np.ascontiguousarray(X),
        H,
        lens.ss,
        lens.xc,
        lens.yc,
        lens.c,
        lens.d,
        lens.e,
        rho_ref,
        cast(float, lens.rho_max),  # always a float once the camera is built
        out,
    )
    return out


def kim_camera_h(X: FloatArray, H: float, camera: CameraModel) -> FloatArray:
    """The measurement through any camera model's ``project``: sigma points (m, 7) -> pixels (m, 2)."""
    R = rotation_zyx(X[:, 4:7])
    x_W = np.stack([X[:, 0], X[:, 1], np.full(X.shape[0], -H)], axis=1)
    x_C = np.einsum("mji,mj->mi", R, x_W)
    return np.asarray(camera.project(x_C), dtype=np.float64)


def _world_h(X: FloatArray, offset: FloatArray) -> FloatArray:
    """World-frame horizontal position: anchor + relative position, (m, 2)."""
    return X[:, 0:2] + offset


# --------------------------------------------------------------------------------------------------
# One predict + pixel update compiled: ukf_predict with the models above written as loops (a test checks
# it agrees with the generic path to 1e-10), then the generic filter's own update kernel, ukf_correct:
# ~30x less Python overhead per camera frame
# --------------------------------------------------------------------------------------------------

STEP_OK, STEP_GATED, STEP_NOT_PD = CORRECT_OK, CORRECT_GATED, CORRECT_NOT_PD  # ukf_correct's codes
STEP_INVALID, STEP_FALLBACK = 2, 4


@njit(cache=True)
def _sigma(x: FloatArray, L: FloatArray, U: FloatArray, X: FloatArray) -> None:
    """``X = x + U L^T``."""
    m, n = U.shape
    for i in range(m):
        for j in range(n):
            s = x[j]
            for k in range(j + 1):  # L lower triangular
                s += U[i, k] * L[j, k]
            X[i, j] = s


@njit(cache=True)
def _kim_predict(
    X: FloatArray,
    dt: float,
    u: FloatArray,
    Wm: FloatArray,
    Wc: FloatArray,
    Q: FloatArray,
    xm: FloatArray,
    Pm: FloatArray,
) -> None:  # pragma: no cover - numba
    """ukf_predict with kim_transition (eq. 16) on the sigma points ``X`` (m, 7): the prior mean into
    ``xm`` and covariance (symmetrised, plus ``Q``) into ``Pm``, both given as zeros."""
    m, n = X.shape
    Y = np.empty((m, n))
    for i in range(m):
        Y[i, 0] = X[i, 0] + dt * X[i, 2] + u[0]
        Y[i, 1] = X[i, 1] + dt * X[i, 3] + u[1]
        Y[i, 2] = X[i, 2] + u[2]
        Y[i, 3] = X[i, 3] + u[3]
        Y[i, 4] = u[4]
        Y[i, 5] = u[5]
        Y[i, 6] = u[6]
    for i in range(m):
        for j in range(n):
            xm[j] += Wm[i] * Y[i, j]
    for i in range(m):
        for j in range(n):
            dj = Wc[i] * (Y[i, j] - xm[j])
            for k in range(n):
                Pm[j, k] += dj * (Y[i, k] - xm[k])
    for j in range(n):
        for k in range(j, n):
            s = 0.5 * (Pm[j, k] + Pm[k, j])
            Pm[j, k] = s + Q[j, k]
            Pm[k, j] = s + Q[k, j]


@njit(cache=True)
def kim_pixel_step(
    x: FloatArray,
    P: FloatArray,
    U: FloatArray,
    Wm: FloatArray,
    Wc: FloatArray,
    dt: float,
    u: FloatArray,
    Q: FloatArray,
    z: FloatArray,
    pixel_var: float,
    H: float,
    height_var: float,
    ss: FloatArray,
    xc: float,
    yc: float,
    c: float,
    d: float,
    e: float,
    rho_ref: float,
    rho_max: float,
    gate: float,
    joseph: bool,
    xo: FloatArray,
    Po: FloatArray,
    info: FloatArray,
) -> int:
    """Eq. 16 (predict by ``dt`` with input ``u`` and noise ``Q``) and eq. 18-27 (update with the pixel
    ``z`` (2,)) on the sigma points ``x + U sqrt(P)^T`` (weights ``Wm``, ``Wc``); the posterior goes to
    ``xo, Po`` and the NIS to ``info[0]``. Returns a ``STEP_*`` code; ``STEP_FALLBACK`` when a covariance
    is not numerically positive definite (the Python path then takes its symmetric square root)."""
    m, n = U.shape
    info[0] = np.nan
    L = np.empty((n, n))
    X = np.empty((m, n))
    if not cholesky(P, L):
        return STEP_FALLBACK
    _sigma(x, L, U, X)
    xm = np.zeros(n)
    Pm = np.zeros((n, n))
    _kim_predict(X, dt, u, Wm, Wc, Q, xm, Pm)
    # update (ukf_update with kim_fisheye_h)
    if not cholesky(Pm, L):
        return STEP_FALLBACK
    _sigma(xm, L, U, X)
    Z = np.empty((m, 2))
    kim_measurement_kernel(X, H, ss, xc, yc, c, d, e, rho_ref, rho_max, Z)
    for i in range(m):
        if not (np.isfinite(Z[i, 0]) and np.isfinite(Z[i, 1])):
            return STEP_INVALID
    R00 = pixel_var
    R01 = 0.0
    R11 = pixel_var
    if height_var > 0.0:
        dH = 1e-4 * max(H, 1.0)
        xr = np.empty((2, n))
        for j in range(n):
            xr[0, j] = xm[j]
            xr[1, j] = xm[j]
        zp = np.empty((1, 2))
        zm = np.empty((1, 2))
        kim_measurement_kernel(xr[0:1], H + dH, ss, xc, yc, c, d, e, rho_ref, rho_max, zp)
        kim_measurement_kernel(xr[1:2], H - dH, ss, xc, yc, c, d, e, rho_ref, rho_max, zm)
        J0 = (zp[0, 0] - zm[0, 0]) / (2.0 * dH)
        J1 = (zp[0, 1] - zm[0, 1]) / (2.0 * dH)
        if np.isfinite(J0) and np.isfinite(J1):
            R00 += height_var * J0 * J0
            R01 += height_var * J0 * J1
            R11 += height_var * J1 * J1
    Rz = np.empty((2, 2))
    Rz[0, 0] = R00
    Rz[0, 1] = R01
    Rz[1, 0] = R01
    Rz[1, 1] = R11
    return ukf_correct(X, Z, Wm, Wc, xm, Pm, L, z, Rz, gate, joseph, xo, Po, info)


# --------------------------------------------------------------------------------------------------
# The filter
# --------------------------------------------------------------------------------------------------

SIGMA_POINTS = ("merwe", "cubature", "simplex")
MEASUREMENT_MODELS = ("quartic", "camera")


@dataclass(frozen=True, kw_only=True)
class KimUkfConfig:
    """Parameters of :class:`KimUkf`. Noise densities are of continuous white noise."""

    accel_noise: float = 0.5
    """Target acceleration noise on eq. 10 (m/s^2/sqrt(Hz)); the paper's target is at constant velocity.
    0.5 as the EKF's ``accel_noise``: a 1 m/s^2 turn is followed with a small lag, and the velocity from
    5 cm position noise at 20 Hz stays within ~0.2 m/s."""
    attitude_std: float = 0.01
    """Standard deviation of the measured camera attitude, per Euler angle (rad)."""
    pixel_std: float = 2.0
    """Standard deviation of the measured pixel, per axis (px): the blob centroid's noise and bias."""
    height_std: float = 0.1
    """Standard deviation of the camera's height above the deck, H (m)."""
    deck_height: float = 0.0
    """Height of the pad surface in W (m): ``H = p_WC[2] - deck_height`` for pixel measurements."""
    vertical_noise: float = 0.05
    """Random walk of the pad height for world measurements (m/s/sqrt(Hz))."""
    init_speed_std: float = 3.0
    """Standard deviation of the initial target velocity around rest (m/s)."""
    init_velocity_std: float = 0.5
    """``initialized`` once the largest velocity standard deviation is below this (m/s)."""
    gating: bool = True
    """Reject measurements whose NIS exceeds the chi-square gate."""
    gate_probability: float = 0.999
    """Probability mass of the chi-square gate (2 dof)."""
    reinit_after_rejections: int = 5
    """Re-initialise from the measurement after this many consecutive gate rejections."""
    confirm_updates: int = 0
    """Track confirmation (ours; the paper trusts the first sighting): a new track is tentative until this
    many measurements in a row (the first included) pass the gate, each pixel within ``confirm_window_s``
    of the previous one, and
    ``has_measurement`` is False until then. A tentative track that misses is replaced by the new pixel.
    A red object that passes the detector's checks on a frame or two then never steers the vehicle."""
    confirm_window_s: float = 0.5
    """Longest gap between the updates that confirm a track (s)."""
    turn_model: bool = True
    """Extrapolate ``state`` and ``predict_ahead`` along the platform's turn (the turn rate of the estimated
    velocity's heading, :mod:`alight.estimation.turn_rate`; ours). False: constant velocity, eq. 10."""
    turn: TurnRateConfig = field(default_factory=TurnRateConfig)
    """The turn-rate tracker's parameters."""
    sigma_points: str = "merwe"
    """Sigma-point scheme: ``merwe`` (scaled, 2n+1), ``cubature`` (2n) or ``simplex`` (n+2)."""
    alpha: float = 1.0
    """Merwe scaled points: spread alpha in (0, 1]."""
    beta: float = 2.0
    """Merwe scaled points: beta (2 for a Gaussian)."""
    kappa: float = 0.0
    """Merwe scaled points: kappa."""
    simplex_w0: float = 0.0
    """Simplex points: weight of the centre point, in [0, 1)."""
    covariance_update: str = "standard"
    """``standard`` (P - K S K^T) or ``joseph`` (see :mod:`alight.estimation.ukf`)."""
    measurement_model: str = "quartic"
    """``quartic`` (eq. 24 with the paper's root selection; needs an omnidirectional camera) or ``camera``
    (the camera model's ``project``)."""
    max_nadir_angle: float = math.radians(85.0)
    """Initialisation: a first pixel whose ray is further than this from straight down is not used (rad)."""

    def __post_init__(self) -> None:
        for name in ("accel_noise", "attitude_std", "height_std", "vertical_noise"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"{name} must be finite and >= 0, got {v}")
        for name in ("pixel_std", "init_speed_std", "init_velocity_std"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{name} must be finite and > 0, got {v}")
        if not math.isfinite(self.deck_height):
            raise ValueError(f"deck_height must be finite, got {self.deck_height}")
        if not 0.0 < self.gate_probability < 1.0:
            raise ValueError(f"gate_probability must be in (0, 1), got {self.gate_probability}")
        if self.confirm_updates < 0 or not (
            math.isfinite(self.confirm_window_s) and self.confirm_window_s > 0
        ):
            raise ValueError("confirm_updates must be >= 0 and confirm_window_s finite and > 0")
        if self.reinit_after_rejections < 1:
            raise ValueError(f"reinit_after_rejections must be >= 1, got {self.reinit_after_rejections}")
        if self.sigma_points not in SIGMA_POINTS:
            raise ValueError(f"sigma_points must be one of {SIGMA_POINTS}, got {self.sigma_points!r}")
        if self.covariance_update not in COVARIANCE_UPDATES:
            raise ValueError(f"covariance_update must be one of {COVARIANCE_UPDATES}")
        if self.measurement_model not in MEASUREMENT_MODELS:
            raise ValueError(f"measurement_model must be one of {MEASUREMENT_MODELS}")
        if not 0.0 < self.max_nadir_angle < math.pi / 2:
            raise ValueError(f"max_nadir_angle must be in (0, pi/2), got {self.max_nadir_angle}")
        self.scheme()  # validates alpha, kappa, simplex_w0

    def scheme(self) -> SigmaPointScheme:
        """The configured sigma-point scheme."""
        if self.sigma_points == "cubature":
            return CubatureSigmaPoints()
        if self.sigma_points == "simplex":
            return SimplexSigmaPoints(self.simplex_w0)
        return MerweScaledSigmaPoints(self.alpha, self.beta, self.kappa)


class EgoPose(Protocol):
    """What the filter reads of the ego state at a capture time: the Pipeline's
    :class:`~alight.mission.pipeline.CapturePose`, or an :class:`~alight.types.EgoState` (whose body rates
    then add the camera lever arm's velocity)."""

    @property
    def p_WB(self) -> FloatArray: ...
    @property
    def R_WB(self) -> FloatArray: ...
    @property
    def v_WB(self) -> FloatArray: ...


def camera_state_W(ego: EgoPose, mount: CameraMount) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``p_WC`` (3,), ``R_WC`` (3, 3) and ``v_WC`` (3,) from an ego state; with an :class:`EgoState`, the
    lever arm's velocity ``R_WB (w x p_BC)`` is added. An ego state that is not one (a missing field, a
    wrong shape, not finite, beyond the bounds of :mod:`alight.estimation.guards`, ``R_WB`` not a rotation)
    raises :class:`~alight.errors.MeasurementError`."""
    where = "KimUkf: ego state"
    try:
        p_in, R_in, v_in = ego.p_WB, ego.R_WB, ego.v_WB
    except AttributeError:
        raise MeasurementError(f"{where}: p_WB, R_WB and v_WB are needed, got {type(ego).__name__}") from None
    p_WB = check_vector(p_in, 3, MAX_POSITION_M, "p_WB", where)
    R_WB = check_rotation(R_in, "R_WB", where)
    v_WB = check_vector(v_in, 3, MAX_SPEED_MPS, "v_WB", where)
    p_WC, R_WC = camera_pose_W(p_WB, R_WB, mount)
    w = ego.w_WB_B if isinstance(ego, EgoState) else None
    v_WC = v_WB if w is None else v_WB + R_WB @ np.cross(np.asarray(w, dtype=np.float64), mount.p_BC)
    if not (np.isfinite(p_WC).all() and np.isfinite(R_WC).all() and np.isfinite(v_WC).all()):
        raise MeasurementError(f"{where}: not finite")
    return p_WC, R_WC, v_WC


def _check_n_sigma(n_sigma: Any) -> float:
    """``n_sigma`` of :meth:`KimUkf.predict_pixel` as a float in (0, 100]; :class:`MeasurementError` else."""
    try:
        value = math.nan if isinstance(n_sigma, (str, bytes)) else float(n_sigma)
    except (TypeError, ValueError):  # None, complex, an array
        value = math.nan
    if not 0.0 < value <= 100.0:  # also NaN
        raise MeasurementError(f"KimUkf.predict_pixel: n_sigma must be in (0, 100], got {n_sigma!r}")
    return value


class KimUkf:
    """Paper 003's UKF as a :class:`~alight.estimation.PlatformEstimator` (see the module docstring).

    Parameters
    ----------
    config:
        :class:`KimUkfConfig`.
    camera:
        For pixel measurements: an omnidirectional camera (``ss``, ``xc``, ``yc``...; e.g.
        :class:`alight.cameras.omni.OmniCamera`, whose model eq. 22-27 use) with ``quartic``, any camera model
        with ``camera``. None: world measurements only.
    mount:
        Camera mount (default :meth:`alight.cameras.CameraMount.downward`).
    """

    def __init__(
        self,
        config: KimUkfConfig | None = None,
        *,
        camera: CameraModel | None = None,
        mount: CameraMount | None = None,
    ) -> None:
        self.config = config if config is not None else KimUkfConfig()
        c = self.config
        self.mount = mount if mount is not None else CameraMount.downward()
        self.camera = camera
        self.lens: OmniCamera | None = None
        """The omnidirectional camera behind eq. 22-27 (``quartic``); None for ``camera`` or no camera."""
        if camera is not None and c.measurement_model == "quartic":
            if not isinstance(camera, OmniCamera):
                raise ConfigError(
                    f"{type(camera).__name__} is not an omnidirectional camera (OmniCamera): use "
                    "measurement_model='camera' for other models"
                )
            self.lens = camera
        self.scheme = c.scheme()
        self._gate = float(chdtri(2, 1.0 - c.gate_probability)) if c.gating else math.inf
        self.use_compiled = self.lens is not None
        """Pixel updates run :func:`kim_pixel_step` (the generic UKF compiled; every
        :class:`~alight.estimation.sigma_points.SigmaPointScheme` gives its ``unit_points``)."""
        if self.use_compiled:
            # writable copies: numba compiles read-only arrays (the schemes' caches) as another type
            self._U = np.array(self.scheme.unit_points(N_STATE), dtype=np.float64)
            Wm, Wc = self.scheme.weights(N_STATE)
            self._Wm, self._Wc = np.array(Wm, dtype=np.float64), np.array(Wc, dtype=np.float64)
        self._info = np.zeros(1)
        self.turn_rate = TurnRateTracker(self.config.turn)
        self.reset()

    # ---- lifecycle --------------------------------------------------------------------------------

    def reset(self) -> None:
        """Forget everything."""
        self.turn_rate.reset()
        self._x = np.zeros(N_STATE)
        self._P = np.eye(N_STATE)
        self._has = False
        self._confirmed_n = 0  # pixel updates in a row that passed the gate since the track started
        self._t = math.nan
        self._t_now = math.nan
        self._p_a = np.zeros(3)
        self._v_a = np.zeros(3)
        self._z = math.nan
        self._z_var = math.nan
        self._rho_prev = math.nan
        self._consecutive_rejections = 0
        self._late_run = StampRun(self.config.reinit_after_rejections)
        self.n_updates = 0
        """Measurements fused (not counting initialisations)."""
        self.n_rejected = 0
        """Measurements rejected by the gate."""
        self.n_invalid = 0
        """Measurements that could not be used (non-finite, no image of a sigma point, camera below deck)."""
        self.n_out_of_order = 0
        """Measurements captured before the filter time, ignored."""
        self.n_reinitializations = 0
        """Times the track restarted after consecutive rejections."""
        self.last_nis = math.nan
        """NIS of the last update attempt (chi-square with 2 dof when consistent)."""

    # ---- filter steps -----------------------------------------------------------------------------

    def predict(self, t: float) -> None:
        """Record the caller's clock ``t`` (s); the filter stays at its last measurement (see the module
        docstring)."""
        self._t_now = check_time(t, "KimUkf.predict")

    def _prior(
        self, t: float, p_new: FloatArray, v_new: FloatArray, eta: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """Eq. 16 from the filter time to ``t`` with the camera's new position/velocity (the new anchor)."""
        dt = t - self._t
        u = np.empty(N_STATE)
        u[0:2] = -(p_new[:2] - self._p_a[:2] - dt * self._v_a[:2])
        u[2:4] = -(v_new[:2] - self._v_a[:2])
        u[4:7] = eta
        Q = kim_process_noise(dt, self.config.accel_noise, max(self.config.attitude_std, _MIN_ATT_STD))
        return ukf_predict(self._x, self._P, self.scheme, kim_transition, Q, dt, u)

    def _commit(self, t: float, x: FloatArray, P: FloatArray, p_new: FloatArray, v_new: FloatArray) -> None:
        self._x = x
        self._P = P
        self._t = t
        self._p_a = p_new.copy()
        self._v_a = v_new.copy()
        self._has = True
        self._consecutive_rejections = 0
        self._late_run.clear()
        self._confirmed_n += 1
        if self.config.turn_model:
            self.turn_rate.update(t, float(v_new[0] + x[2]), float(v_new[1] + x[3]))

    def _rejected(self, res: UpdateResult) -> bool:
        """Book-keeping of a refused update; True when the track should restart."""
        if res.status == GATED:
            self.n_rejected += 1
            self._consecutive_rejections += 1
            if self._consecutive_rejections >= self.config.reinit_after_rejections:
                self.n_reinitializations += 1
                return True
        else:
            self.n_invalid += 1
        return False

    def update(self, measurement: PlatformMeasurement) -> bool:
        """Fuse a world-frame measurement (``t`` = capture time): ``z = p_anchor + [x, y]`` for the
        horizontal position, the scalar height filter for z. True when used."""
        t, p, cov = check_measurement(measurement, "KimUkf.update")  # alight.estimation.guards
        if p.shape != (3,) or cov.shape != (3, 3) or not (np.isfinite(p).all() and np.isfinite(cov).all()):
            raise EstimationError("KimUkf.update: a finite p_WP (3,) and cov_p_WP (3, 3) are needed")
        if not math.isfinite(t):
            raise EstimationError(f"KimUkf.update: non-finite time {t}")
        # bounds of alight.estimation.guards: time, position, covariance; a measurement from the future
        # (after the clock given to predict, beyond the tolerance) is refused like one out of order
        if t > self._t_now + FUTURE_TOLERANCE_S:
            self.n_invalid += 1
            return False
        if self._has and t < self._t and not self._out_of_order(t):
            return False
        c = self.config
        if not self._has:
            self._init_world(t, p, cov, self._p_a, self._v_a)
            return True
        dt = t - self._t
        p_new = self._p_a + dt * self._v_a  # no ego: the anchor keeps its velocity
        v_new = self._v_a
        xm, Pm = self._prior(t, p_new, v_new, self._x[4:7])
        x, P, res = ukf_update(
            xm, Pm, p[:2], cov[:2, :2], self.scheme, _world_h, p_new[:2],
            gate=self._gate, covariance_update=c.covariance_update,
        )  # fmt: skip
        self.last_nis = res.nis
        if not res.accepted:
            if self._rejected(res):
                self._init_world(t, p, cov, p_new, v_new)
            return False
        self._z_predict_update(dt, p[2], cov[2, 2])
        self._commit(t, x, P, p_new, v_new)
        self.n_updates += 1
        return True

    def _out_of_order(self, t: float) -> bool:
        """Count a measurement captured before the filter time. True when it completes a run of
        ``reinit_after_rejections`` far before it (by more than ``FUTURE_TOLERANCE_S``), in order among
        themselves (:class:`alight.estimation.guards.StampRun`): the filter's time came from a
        measurement stamped in the future, and the track is dropped, to restart from this one (the
        recovery rule of ``PlatformEkf``; nothing of the wrong track is kept)."""
        self.n_out_of_order += 1
        if t >= self._t - FUTURE_TOLERANCE_S or not self._late_run.add(t):
            return False
        self.n_reinitializations += 1
        self._has = False
        self._confirmed_n = 0
        self._p_a = np.zeros(3)
        self._v_a = np.zeros(3)
        self._late_run.clear()
        return True

    def _init_world(self, t: float, p: FloatArray, cov: FloatArray, p_a: FloatArray, v_a: FloatArray) -> None:
        c = self.config
        x = np.zeros(N_STATE)
        x[0:2] = p[:2] - p_a[:2]
        x[2:4] = -v_a[:2]  # a target at rest
        x[4:7] = self._x[4:7] if self._has else 0.0
        P = np.zeros((N_STATE, N_STATE))
        P[0:2, 0:2] = cov[:2, :2]
        P[2, 2] = P[3, 3] = c.init_speed_std**2
        P[4:7, 4:7] = np.eye(3) * max(c.attitude_std, _MIN_ATT_STD) ** 2
        self._z = float(p[2])
        self._z_var = float(cov[2, 2]) if cov[2, 2] > 0 else 1e-12
        self.turn_rate.reset()  # a new track
        self._commit(t, x, P, p_a, v_a)

    def _z_predict_update(self, dt: float, z: float, var: float) -> None:
        pv = self._z_var + self.config.vertical_noise**2 * abs(dt)
        if not var > 0:
            self._z, self._z_var = z, 1e-12
            return
        k = pv / (pv + var)
        self._z += k * (z - self._z)
        self._z_var = (1.0 - k) * pv

    # ---- pixel measurements (the paper) ----------------------------------------------------------

    def _require_camera(self) -> None:
        if self.camera is None:
            raise ConfigError("KimUkf: pixel measurements need a camera (KimUkf(camera=...))")

    def _h(self, H: float, rho_ref: float) -> tuple[Any, tuple[Any, ...]]:
        if self.lens is not None:
            return kim_fisheye_h, (H, self.lens, rho_ref)
        return kim_camera_h, (H, self.camera)

    def _rho(self, px: FloatArray) -> float:
        """:meth:`OmniCamera.ideal_radius` of one pixel, in scalar arithmetic (called every frame)."""
        lens = self.lens
        if lens is None:
            return math.nan
        du = float(px[0]) - lens.yc
        dv = float(px[1]) - lens.xc
        det = lens.c - lens.d * lens.e
        return math.hypot((lens.c * du - lens.e * dv) / det, (dv - lens.d * du) / det)

    def _pixel_noise(self, x: FloatArray, H: float, rho_ref: float) -> FloatArray:
        """``pixel_std^2 I + height_std^2 J_H J_H^T`` with ``J_H = dh/dH`` at ``x`` (central difference)."""
        c = self.config
        R = np.eye(2) * c.pixel_std**2
        if c.height_std > 0:
            dH = 1e-4 * max(H, 1.0)
            hx, args = self._h(H + dH, rho_ref)
            zp = hx(x[None, :], *args)[0]
            hx, args = self._h(H - dH, rho_ref)
            zm = hx(x[None, :], *args)[0]
            J = (zp - zm) / (2 * dH)
            if np.isfinite(J).all():
                R += c.height_std**2 * np.outer(J, J)
        return R

    def update_pixel(self, t: float, px: FloatArray, ego: EgoPose) -> bool:
        """Fuse the target's pixel ``px`` (u, v) seen at capture time ``t`` (s) with the ego state at that
        time (``p_WB``, ``v_WB``, ``q_WB``/``R_WB``, optional ``w_WB_B``; e.g. an
        :class:`~alight.types.EgoState`). True when used; a non-finite pixel, a camera at or below the
        deck, a sigma point without an image or a gated innovation return False and leave the state
        unchanged; an ego state that is not one raises :class:`~alight.errors.MeasurementError`
        (:func:`camera_state_W`)."""
        self._require_camera()
        t = as_time(t, "KimUkf.update_pixel")  # guards: not finite is counted below, not a number refused
        z = as_real_array(px, "px", "KimUkf.update_pixel").ravel()
        if z.shape != (2,) or not np.isfinite(z).all() or not math.isfinite(t):
            self.n_invalid += 1
            return False
        if abs(t) > MAX_TIME_S or t > self._t_now + FUTURE_TOLERANCE_S:  # alight.estimation.guards
            self.n_invalid += 1
            return False
        if self._has and t < self._t and not self._out_of_order(t):
            return False
        p_WC, R_WC, v_WC = camera_state_W(ego, self.mount)
        H = float(p_WC[2] - self.config.deck_height)
        if not H > 0:
            self.n_invalid += 1
            return False
        eta = euler_zyx(R_WC)
        tentative = self._confirmed_n < self.config.confirm_updates
        if not self._has or (tentative and t - self._t > self.config.confirm_window_s):
            self._confirmed_n = 0
            return self._init_pixel(t, z, p_WC, v_WC, eta, H)
        rho = self._rho(z)
        rho_ref = self._rho_prev if math.isfinite(self._rho_prev) else rho
        res = None
        if self.use_compiled:
            x, P, res = self._compiled_step(t, z, p_WC, v_WC, eta, H, rho_ref)
        if res is None:
            xm, Pm = self._prior(t, p_WC, v_WC, eta)
            R = self._pixel_noise(xm, H, rho_ref)
            hx, args = self._h(H, rho_ref)
            x, P, res = ukf_update(
                xm,
                Pm,
                z,
                R,
                self.scheme,
                hx,
                *args,
                gate=self._gate,
                covariance_update=self.config.covariance_update,
            )
        self.last_nis = res.nis
        if not res.accepted:
            if tentative or self._rejected(res):
                self._confirmed_n = 0
                self._init_pixel(t, z, p_WC, v_WC, eta, H)
            return False
        self._commit(t, x, P, p_WC, v_WC)
        self._rho_prev = rho
        self._z = self.config.deck_height
        self._z_var = max(self.config.height_std**2, 1e-12)
        self.n_updates += 1
        return True

    def _compiled_step(
        self,
        t: float,
        z: FloatArray,
        p_WC: FloatArray,
        v_WC: FloatArray,
        eta: FloatArray,
        H: float,
        rho_ref: float,
    ) -> tuple[FloatArray, FloatArray, UpdateResult | None]:
        """:func:`kim_pixel_step` with the filter's state; result None: use the Python path."""
        c = self.config
        lens = cast(OmniCamera, self.lens)  # use_compiled implies a lens
        dt = t - self._t
        u = np.empty(N_STATE)
        u[0:2] = -(p_WC[:2] - self._p_a[:2] - dt * self._v_a[:2])
        u[2:4] = -(v_WC[:2] - self._v_a[:2])
        u[4:7] = eta
        Q = kim_process_noise(dt, c.accel_noise, max(c.attitude_std, _MIN_ATT_STD))
        x = np.empty(N_STATE)
        P = np.empty((N_STATE, N_STATE))
        code = kim_pixel_step(
            self._x, self._P, self._U, self._Wm, self._Wc, dt, u, Q, z, c.pixel_std**2, H, c.height_std**2,
            lens.ss, lens.xc, lens.yc, lens.c, lens.d, lens.e, rho_ref, cast(float, lens.rho_max), self._gate,
            c.covariance_update == "joseph", x, P, self._info,
        )  # fmt: skip
        nis = float(self._info[0])
        if code == STEP_FALLBACK:
            return x, P, None
        if code == STEP_OK:
            return x, P, UpdateResult(True, nis, OK)
        status = {STEP_GATED: GATED, STEP_INVALID: INVALID, STEP_NOT_PD: NOT_POSITIVE_DEFINITE}[code]
        return self._x, self._P, UpdateResult(False, nis, status)

    def _unproject(self, pixels: FloatArray) -> FloatArray:
        cam = self.lens if self.lens is not None else self.camera
        if cam is None:
            raise ConfigError("KimUkf: pixel rays need a camera model (camera=...)")
        return np.asarray(cam.unproject(pixels), dtype=np.float64)

    def flat_earth_prior(
        self, px: FloatArray, eta: FloatArray, H: float
    ) -> tuple[FloatArray, FloatArray] | None:
        """Eq. 5-9 through the unscented transform of the pixel, attitude and height noise: the mean and
        covariance (5,), (5, 5) of ``[x, y, phi, theta, psi]``; None when a sigma point's ray misses the
        plane (within ``max_nadir_angle``)."""
        c = self.config
        sd = np.array(
            [c.pixel_std, c.pixel_std, c.attitude_std, c.attitude_std, c.attitude_std, c.height_std]
        )
        W = self.scheme.points(np.zeros(6), np.diag(np.maximum(sd, 1e-9) ** 2))
        pix = px + W[:, 0:2]
        etas = eta + W[:, 2:5]
        Hs = H + W[:, 5]
        rays = self._unproject(pix)
        d = np.einsum("mij,mj->mi", rotation_zyx(etas), rays)
        norm = np.linalg.norm(d, axis=1)
        if not (
            np.isfinite(d).all() and (Hs > 0).all() and (-d[:, 2] > math.cos(c.max_nadir_angle) * norm).all()
        ):
            return None
        Y = np.empty((W.shape[0], 5))
        Y[:, 0:2] = -Hs[:, None] * d[:, 0:2] / d[:, 2:3]
        Y[:, 2:5] = etas
        Wm, Wc = self.scheme.weights(6)
        mean, cov, _ = unscented_transform(Y, Wm, Wc)
        return mean, cov

    def _init_pixel(
        self, t: float, px: FloatArray, p_WC: FloatArray, v_WC: FloatArray, eta: FloatArray, H: float
    ) -> bool:
        c = self.config
        prior = self.flat_earth_prior(px, eta, H)
        if prior is None:
            self.n_invalid += 1
            return False
        mean, cov = prior
        x = np.zeros(N_STATE)
        P = np.zeros((N_STATE, N_STATE))
        idx = [I_X, I_Y, I_PHI, I_THETA, I_PSI]
        x[idx] = mean
        x[I_PHI : I_PSI + 1] = eta  # the attitude state is the measured attitude
        P[np.ix_(idx, idx)] = cov
        x[2:4] = -v_WC[:2]
        P[2, 2] = P[3, 3] = c.init_speed_std**2
        self.turn_rate.reset()  # a new track
        self._commit(t, x, P, p_WC, v_WC)
        self._rho_prev = self._rho(px)
        self._z = c.deck_height
        self._z_var = max(c.height_std**2, 1e-12)
        return True

    def predict_pixel(self, t: float, ego: EgoPose, n_sigma: float = 3.0) -> tuple[FloatArray, float] | None:
        """The predicted pixel of the target at ``t`` (s) for the ego state then, and a gate radius (px):
        ``n_sigma`` times the square root of the innovation covariance's largest eigenvalue. For the
        detector's gating (:meth:`alight.perception.color_filter.RedTargetDetector.set_prediction`). None
        before the first measurement, when the target has no image or when the track is older than
        ``MAX_HORIZON_S`` at ``t`` (:mod:`alight.estimation.guards`; a time that is not one, an ego state
        that is not one and an ``n_sigma`` outside (0, 100] raise :class:`~alight.errors.MeasurementError`).
        """
        t = check_time(t, "KimUkf.predict_pixel")
        n_sigma = _check_n_sigma(n_sigma)
        if not self._has or self.camera is None or not (0.0 <= t - self._t <= MAX_HORIZON_S):
            return None
        p_WC, R_WC, v_WC = camera_state_W(ego, self.mount)
        H = float(p_WC[2] - self.config.deck_height)
        if not H > 0:
            return None
        xm, Pm = self._prior(float(t), p_WC, v_WC, euler_zyx(R_WC))
        rho_ref = self._rho_prev
        hx, args = self._h(H, rho_ref)
        Z = hx(self.scheme.points(xm, Pm), *args)
        if not np.isfinite(Z).all():
            return None
        Wm, Wc = self.scheme.weights(N_STATE)
        zhat, S, _ = unscented_transform(Z, Wm, Wc, self._pixel_noise(xm, H, rho_ref))
        return zhat, float(n_sigma * math.sqrt(np.linalg.eigvalsh(S)[-1]))

    # ---- outputs ----------------------------------------------------------------------------------

    @property
    def initialized(self) -> bool:
        """True once the velocity's largest standard deviation is below ``init_velocity_std``."""
        if not self._has:
            return False
        return bool(np.linalg.eigvalsh(self._P[2:4, 2:4])[-1] <= self.config.init_velocity_std**2)

    @property
    def has_measurement(self) -> bool:
        """True once a measurement initialised the filter (:meth:`state` works) and, with
        ``confirm_updates``, the track is confirmed."""
        return self._has and self._confirmed_n >= self.config.confirm_updates

    @property
    def t_filter(self) -> float:
        """Internal time (s): capture time of the last measurement used (NaN before any)."""
        return self._t

    @property
    def t_now(self) -> float:
        """The clock last given to :meth:`predict` (s)."""
        return self._t_now

    @property
    def x(self) -> FloatArray:
        """The paper's state at ``t_filter`` (eq. 14), (7,)."""
        return self._x.copy()

    @property
    def covariance(self) -> FloatArray:
        """Its covariance (7, 7)."""
        return self._P.copy()

    @property
    def anchor(self) -> tuple[FloatArray, FloatArray]:
        """Camera position and velocity in W at ``t_filter`` that the relative state refers to."""
        return self._p_a.copy(), self._v_a.copy()

    def _world_pv(self, t: float) -> tuple[FloatArray, FloatArray]:
        """Position and velocity in W at ``t``, constant velocity from the filter's time."""
        if not self._has:
            raise EstimationError("KimUkf: no measurement yet")
        if not math.isfinite(t):
            raise EstimationError(f"KimUkf: query time must be finite, got {t}")
        dt = t - self._t
        v = np.zeros(3)
        v[:2] = self._v_a[:2] + self._x[2:4]
        p = np.empty(3)
        p[:2] = self._p_a[:2] + self._x[0:2] + dt * v[:2]
        p[2] = self._z
        return p, v

    def _world(self, t: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        p, v = self._world_pv(t)
        dt = t - self._t
        F = np.eye(4)
        F[0, 2] = F[1, 3] = dt
        P4 = F @ self._P[0:4, 0:4] @ F.T + kim_process_noise(dt, self.config.accel_noise, 0.0)[0:4, 0:4]
        cov = np.zeros((3, 3))
        cov[0:2, 0:2] = 0.5 * (P4[0:2, 0:2] + P4[0:2, 0:2].T)
        cov[2, 2] = self._z_var + self.config.vertical_noise**2 * abs(dt)
        return p, v, cov

    def state(self, t: float) -> PlatformEstimate:
        """The platform at ``t`` (s) in W, extrapolated from the last measurement along its turn
        (``turn_model``) or at constant velocity."""
        t = check_time(t, "KimUkf.state")
        p, v, cov = self._world(t)
        a = np.zeros(3)
        if self.config.turn_model and self.turn_rate.rate != 0.0:
            p_f, v_f = self._world_pv(self._t)
            pk, vk, ak, _ = turn_predict(p_f, v_f, self.turn_rate.rate, np.array([t - self._t]))
            p, v, a = pk[0], vk[0], ak[0]
        return PlatformEstimate(
            t=t,
            p_WP=p,
            v_WP=v,
            a_WP=a,
            yaw=math.atan2(v[1], v[0]),
            cov_p_WP=cov,
            t_last_measurement=self._t,
        )

    def predict_ahead(self, times: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Positions (k, 3), velocities (k, 3), accelerations (k, 3) and headings (k,) at the absolute
        ``times`` (k,) (s) from the last measurement: along the platform's turn (``turn_model``), else at
        constant velocity (zero acceleration)."""
        ts = check_times(times, "KimUkf.predict_ahead")
        p0, v = self._world_pv(self._t)
        k = ts.shape[0]
        dts = np.clip(ts - self._t, -MAX_HORIZON_S, MAX_HORIZON_S)  # as PlatformEkf: no overflow
        if self.config.turn_model and self.turn_rate.rate != 0.0:
            return turn_predict(p0, v, self.turn_rate.rate, dts)
        p = p0 + dts[:, None] * v
        return p, np.tile(v, (k, 1)), np.zeros((k, 3)), np.full(k, math.atan2(v[1], v[0]))

    def diagnostics(self) -> dict[str, Any]:
        """Counters for logs."""
        return {
            "n_updates": self.n_updates,
            "n_rejected": self.n_rejected,
            "n_invalid": self.n_invalid,
            "n_out_of_order": self.n_out_of_order,
            "n_reinitializations": self.n_reinitializations,
        }


__all__ = [
    "KimUkf",
    "KimUkfConfig",
    "EgoPose",
    "camera_state_W",
    "euler_zyx",
    "kim_camera_h",
    "kim_fisheye_h",
    "kim_measurement_kernel",
    "kim_pixel_step",
    "kim_process_noise",
    "kim_transition",
    "rotation_zyx",
]
