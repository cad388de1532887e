"""The platform-estimator stage's registry: :data:`PLATFORM_ESTIMATORS`, the blocks a scenario's
``blocks.platform_estimator`` names, with their parameters and factories
(:class:`alight.blockspec.BlockSpec`)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from alight.blockspec import BlockSpec, ResolveContext
from alight.cameras import MountedCamera
from alight.estimation.deck_estimator import DeckEstimatorConfig
from alight.estimation.deck_platform import DeckPlatformEstimator
from alight.estimation.kim_ukf import KimUkf, KimUkfConfig
from alight.estimation.platform_ekf import PlatformEkf, PlatformEkfConfig
from alight.estimation.platform_velocity import PlatformVelocityConfig
from alight.estimation.sdu_kf import SduKalmanFilter, SduKfConfig

if TYPE_CHECKING:
    from alight.estimation import PlatformEstimator

MANEUVER_ACCEL_NOISE = 2.0
"""The unicycle EKF's process noise while the platform brakes or accelerates (m/s^2/sqrt(Hz)): a road
vehicle brakes at up to 8 m/s^2 and accelerates at up to 4 (``platform.speed_profile``'s limits); with the
fixed 0.1 the speed estimate lagged a 6 m/s^2 stop by a second and the vehicle landed beside the pad."""


def _unicycle_ekf(p: PlatformEkfConfig, ctx: MountedCamera) -> PlatformEstimator:
    return PlatformEkf(p)


def _deck_kf(p: DeckEstimatorConfig, ctx: MountedCamera) -> PlatformEstimator:
    return DeckPlatformEstimator(p)


def _kim_ukf(p: KimUkfConfig, ctx: MountedCamera) -> PlatformEstimator:
    return KimUkf(p, camera=ctx.camera, mount=ctx.mount)


def _sdu_kf(p: SduKfConfig, ctx: MountedCamera) -> PlatformEstimator:
    return SduKalmanFilter(p)


def _kim_ukf_context(ctx: ResolveContext) -> dict[str, Any]:
    cam = ctx.upstream.get("camera")
    omni = cam is not None and cam.provides.get("model") == "omni"
    return {
        "deck_height": ctx.pad_height_m,
        "confirm_updates": 0 if ctx.mitigation == "none" else 5,
        "measurement_model": "quartic" if omni else "camera",
    }


def _sdu_kf_context(ctx: ResolveContext) -> dict[str, Any]:
    pad = ctx.upstream.get("pad")
    fold = 1 if pad is None else int(pad.provides.get("yaw_fold", 1))
    return {"velocity": PlatformVelocityConfig(measured_yaw_increments=True, yaw_fold=fold)}


DECK_HORIZONTAL = PlatformEkfConfig(
    use_turn_rate=True,
    accel_noise=0.5,
    heading_noise=0.1,
    turn_accel_noise=0.1,
    turn_jerk_noise=4.5,
    init_max_span=4.0,
    init_max_speed_std_mps=1.0,
    maneuver_accel_noise=MANEUVER_ACCEL_NOISE,
    horizontal_noise=0.5,
    vertical_noise=0.0,
)
"""The deck estimator's horizontal track: the unicycle EKF as the ``alight`` preset flies it
(``mission/preset_data/alight.yaml`` gives each value's reason), with the pad's horizontal random walk
raised to 0.5 m/s/sqrt(Hz) for the sway of a pad above a rolling deck (deck_estimator.py), and no
vertical channel (the heave channel is the height)."""

PlatformEstimatorSpec = BlockSpec[MountedCamera, "PlatformEstimator"]
"""A platform-estimator block: parameters and the camera with its mount -> a platform estimator."""

PLATFORM_ESTIMATORS: dict[str, PlatformEstimatorSpec] = {
    "unicycle_ekf": BlockSpec(
        "platform_estimator",
        "unicycle_ekf",
        "paper 000's unicycle EKF, with a turn-rate state (ours) unless use_turn_rate is false",
        PlatformEkfConfig,
        build=_unicycle_ekf,
        # What every mission has flown (the scenario's former defaults and the presets' choice).
        defaults={
            "use_turn_rate": True,
            "accel_noise": 0.1,
            "heading_noise": 0.1,
            "turn_accel_noise": 0.1,
            # Initialise from sightings up to 4 s apart: while searching, the platform is often seen
            # in short bursts (a pass of the coverage pattern), and two bursts give its velocity well.
            "init_max_span": 4.0,
            "maneuver_accel_noise": MANEUVER_ACCEL_NOISE,
        },
    ),
    "deck_kf": BlockSpec(
        "platform_estimator",
        "deck_kf",
        "a ship's deck: the unicycle EKF's track plus heave, roll and pitch as fitted CAR(4) oscillators,"
        " predicted ahead, fed by the pad's pose and the ship's motion telemetry (issue 37)",
        DeckEstimatorConfig,
        build=_deck_kf,
        defaults={"horizontal": DECK_HORIZONTAL},
    ),
    "kim_ukf": BlockSpec(
        "platform_estimator",
        "kim_ukf",
        "paper 003's UKF on the target's pixel through the camera model (eq. 10-27)",
        KimUkfConfig,
        build=_kim_ukf,
        context={
            "deck_height": "platform.pad_height_m",
            "confirm_updates": "perception.mitigation (0 for none, else 5)",
            "measurement_model": "camera (quartic for fisheye, the model's project otherwise)",
        },
        context_values=_kim_ukf_context,
        defaults={"deck_height": None, "confirm_updates": None, "measurement_model": None},
        needs={"detector.image": (True,)},
    ),
    "sdu_kf": BlockSpec(
        "platform_estimator",
        "sdu_kf",
        "paper 004's Kalman filter on the relative position, delay compensated, with the velocity estimator",
        SduKfConfig,
        build=_sdu_kf,
        context={"velocity": "pad (n-fold order as the yaw fold, measured yaw increments)"},
        context_values=_sdu_kf_context,
        defaults={"velocity": None},
    ),
}
"""The platform-estimator stage's blocks by name."""

__all__ = ["DECK_HORIZONTAL", "MANEUVER_ACCEL_NOISE", "PLATFORM_ESTIMATORS", "PlatformEstimatorSpec"]
