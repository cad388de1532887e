"""State estimation: the vehicle's own state (IMU + odometry) and the landing platform's.

Two stages, one Protocol each:

- :class:`EgoEstimator` fuses IMU samples and odometry into an :class:`alight.types.EgoState`
  (:class:`EgoEkf`, the one the flight uses);
- :class:`PlatformEstimator` turns :class:`alight.types.PlatformMeasurement` s into a
  :class:`alight.types.PlatformEstimate` and predictions ahead.

:data:`PLATFORM_ESTIMATORS` (``estimation/registry.py``) is the platform-estimator stage's registry:
name -> :class:`alight.blockspec.BlockSpec` (parameters, needs/provides, factory). See ``README.md`` in
this folder.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from alight.estimation.ego_ekf import EgoEkf, EgoEkfConfig
from alight.estimation.kim_ukf import EgoPose, KimUkf, KimUkfConfig
from alight.estimation.platform_ekf import PlatformEkf, PlatformEkfConfig
from alight.estimation.registry import PLATFORM_ESTIMATORS, PlatformEstimatorSpec
from alight.estimation.sdu_kf import SduKalmanFilter, SduKfConfig
from alight.types import EgoState, FloatArray, PlatformEstimate, PlatformMeasurement


@runtime_checkable
class PlatformEstimator(Protocol):
    """Estimates the platform (pad centre) from measurements that arrive late but in capture order."""

    @property
    def initialized(self) -> bool:
        """True once the estimate has a heading and speed (not just a position)."""
        ...

    @property
    def has_measurement(self) -> bool:
        """True once any measurement was accepted: ``state`` then gives at least a position."""
        ...

    def reset(self) -> None:
        """Forget everything."""
        ...

    def predict(self, t: float) -> None:
        """Tell the estimator the current time (s); implementations may or may not move their state."""
        ...

    def update(self, measurement: PlatformMeasurement) -> bool:
        """Fuse a measurement (``measurement.t`` is its capture time). True when it was used."""
        ...

    def state(self, t: float) -> PlatformEstimate:
        """The estimate at time ``t`` (s)."""
        ...

    def predict_ahead(self, times: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Positions (k, 3), velocities (k, 3), accelerations (k, 3) and headings (k,) at ``times`` (k,)."""
        ...


@runtime_checkable
class EgoFed(Protocol):
    """A platform estimator that takes the vehicle's own state as input (paper 004's filter on the
    relative position): the Pipeline feeds it the ego estimate at each control tick and before each
    measurement."""

    def set_ego(self, ego: EgoState) -> None: ...


@runtime_checkable
class PixelMeasured(Protocol):
    """A platform estimator with an image measurement model (paper 003's UKF): it fuses the detection's
    pixel with the ego state at the capture time, and predicts the pixel for a gating detector."""

    def update_pixel(self, t: float, px: FloatArray, ego: EgoPose) -> bool:
        """Fuse the pixel ``(u, v)`` seen at capture time ``t`` (s); True when used."""
        ...

    def predict_pixel(self, t: float, ego: EgoPose, n_sigma: float = 3.0) -> tuple[FloatArray, float] | None:
        """The predicted pixel at ``t`` for the ego state then, and a gate radius (px); None without one."""
        ...


@runtime_checkable
class TelemetryFusing(Protocol):
    """A platform estimator that also fuses the platform's own GNSS telemetry (estimation/telemetry.py)."""

    def update_telemetry(self, t_stamp: float, p_WP: FloatArray, v_WP: FloatArray, cov: FloatArray) -> bool:
        """Fuse a fix taken at ``t_stamp`` (s): position (3,) m, velocity (3,) m/s in W, the receiver's
        covariance (3, 3) m^2. It may arrive late. True when used."""
        ...

    def learn_telemetry_bias(self, measurement: PlatformMeasurement) -> None:
        """A camera measurement the estimator used, to learn the telemetry's bias from."""
        ...


@runtime_checkable
class EgoEstimator(Protocol):
    """Estimates the vehicle's own state from IMU samples and odometry."""

    @property
    def initialized(self) -> bool: ...

    @property
    def covariance(self) -> FloatArray:
        """Error-state covariance."""
        ...

    def initialize(self, t: float, p_WB: FloatArray, v_WB: FloatArray, q_WB: FloatArray) -> None: ...

    def predict_imu(self, t: float, f_B: FloatArray, w_B: FloatArray) -> None:
        """Propagate with one IMU sample: specific force (m/s^2) and rate (rad/s) in B."""
        ...

    def predict_imu_many(
        self, ts: FloatArray, f_B: FloatArray, w_B: FloatArray, n: int | None = None
    ) -> None:
        """As ``n`` calls of ``predict_imu``: times (n,), forces and rates (n, 3)."""
        ...

    def update_odometry(
        self, t: float, p_WB: FloatArray, q_WB: FloatArray, v_WB: FloatArray | None = None
    ) -> bool: ...

    def state(self) -> EgoState: ...


@runtime_checkable
class PositionResetting(Protocol):
    """An ego estimator told when the odometry's frame jumps (a VIO re-localised; MAVLink ODOMETRY's
    ``reset_counter`` went up): :meth:`relocalize` restarts it at the new pose, and
    ``reset_delta_p_WB`` (3,) m in W is the sum of those jumps. The platform estimate, the references
    and the pose history live in the estimate's frame; the pipeline subtracts the sum so that a jump of
    the odometry does not move them all against the vehicle."""

    reset_delta_p_WB: FloatArray

    def relocalize(
        self, t: float, p_WB: FloatArray, q_WB: FloatArray, v_WB: FloatArray | None = None
    ) -> None: ...


__all__ = [
    "PLATFORM_ESTIMATORS",
    "PlatformEstimatorSpec",
    "EgoEkf",
    "EgoFed",
    "PixelMeasured",
    "EgoEkfConfig",
    "EgoEstimator",
    "KimUkf",
    "KimUkfConfig",
    "PlatformEkf",
    "PlatformEkfConfig",
    "PlatformEstimator",
    "PositionResetting",
    "TelemetryFusing",
    "SduKalmanFilter",
    "SduKfConfig",
]
