"""Presets: named choices of one implementation per block.

- ``falanga2017``: paper 000 end to end (camera, tag detector, PnP, unicycle EKF, candidate planner,
  Faessler controller, state machine).
- ``groundtruth``: the falanga2017 blocks (IMU + odometry EKF, unicycle EKF, minimum-jerk candidate
  planner, Faessler controller, paper 000's state machine) with the camera and detector replaced by the
  ground-truth perception sensor. It is the "perfect perception" ablation of every other preset.

Each builder takes the scenario, the airframe and a Generator, and returns the pipeline plus what the
runner needs to drive it (the camera mount, the low-level gains). Any block can be swapped by editing
the builder's choice; the scenario's per-block sections set their parameters.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from alight.airframe import Airframe
from alight.cameras.pinhole import CameraMount, PinholeCamera
from alight.control.high_level import HighLevelController, HighLevelGains
from alight.control.rate import RateControllerGains
from alight.estimation.ego_ekf import EgoEkf, EgoEkfConfig
from alight.estimation.platform_ekf import PlatformEkf, PlatformEkfConfig
from alight.mission.guidance import Guidance, GuidanceConfig
from alight.mission.pipeline import Pipeline
from alight.mission.state_machine import Mission, MissionConfig
from alight.pads.falanga_tag import FalangaTag
from alight.perception.falanga_tag import FalangaTagDetector
from alight.perception.geolocation import DirectGeolocator, PnpGeolocator
from alight.planning.candidates import CandidatePlanner, PlannerConfig
from alight.planning.min_jerk import EndConstraint

# The ego EKF's noise model: the data sheet of the vehicle's IMU and the VIO's reported accuracy. These
# are the numbers the simulated sensors use by default (sim/sensors.py), as a real integrator would copy
# them from the IMU data sheet and the VIO's calibration.
_EGO_EKF_CONFIG = EgoEkfConfig(
    accel_noise_density=3.0e-3,
    gyro_noise_density=3.0e-4,
    accel_bias_random_walk=5.0e-4,
    gyro_bias_random_walk=2.0e-5,
    odometry_position_std=0.01,
    odometry_attitude_std=0.005,
    odometry_velocity_std=0.02,
)


@dataclass
class Preset:
    name: str
    pipeline: Pipeline
    mount: CameraMount
    rate_gains: RateControllerGains
    uses_camera: bool
    camera: PinholeCamera | None = None
    """The camera model the runner renders through (vision presets)."""
    pad: object | None = None
    """The pad design the runner draws on the platform (vision presets)."""


def _mission_config(s: object) -> MissionConfig:
    m = s.mission  # type: ignore[attr-defined]
    return MissionConfig(
        takeoff_altitude_m=m.takeoff_altitude_m,
        explore_altitude_m=m.explore_altitude_m,
        track_height_m=m.track_height_m,
        land_speed_mps=m.land_speed_mps,
        motor_cutoff_range_m=m.motor_cutoff_range_m,
        land_commit_height_m=m.land_commit_height_m,
        lost_timeout_s=m.lost_timeout_s,
        max_go_arounds=m.max_go_arounds,
        time_budget_s=m.time_budget_s,
    )


def _flight_core(
    s: object, airframe: Airframe, fov_rad: float
) -> tuple[Mission, Guidance, HighLevelController, EgoEkf]:
    sc = s  # the Scenario; typed loosely to keep this module free of the scenario's import cycle
    mission = Mission(_mission_config(sc))
    p = sc.planner  # type: ignore[attr-defined]
    planner = CandidatePlanner(
        PlannerConfig.from_airframe(
            airframe,
            n_candidates=p.n_candidates,
            horizon_min_s=p.horizon_min_s,
            horizon_max_s=p.horizon_max_s,
            adopt_threshold_m=p.adopt_threshold_m,
            end_constraint=EndConstraint.POS_VEL_ACC
            if p.end_acceleration == "platform"
            else EndConstraint.POS_VEL,
        )
    )
    area = sc.search_area  # type: ignore[attr-defined]
    guidance = Guidance(
        mission.config,
        planner,
        GuidanceConfig(
            search_area=(area.x_min, area.x_max, area.y_min, area.y_max),
            camera_fov_rad=fov_rad,
            search_pattern=sc.mission.search_pattern,  # type: ignore[attr-defined]
        ),
    )
    gains = HighLevelGains.from_bandwidth(sc.controller.position_bandwidth_rad_s)  # type: ignore[attr-defined]
    controller = HighLevelController(airframe, gains)
    ego = EgoEkf(_EGO_EKF_CONFIG)
    return mission, guidance, controller, ego


def build_groundtruth(s: object, airframe: Airframe, rng: np.random.Generator) -> Preset:
    perception = s.perception  # type: ignore[attr-defined]
    fov = math.radians(min(perception.fov_deg))
    mission, guidance, controller, ego = _flight_core(s, airframe, fov)
    mount = CameraMount.downward()
    platform_estimator = _platform_estimator(s)
    pipeline = Pipeline(
        ego_estimator=ego,
        geolocator=DirectGeolocator(mount),
        platform_estimator=platform_estimator,
        mission=mission,
        guidance=guidance,
        controller=controller,
    )
    return Preset("groundtruth", pipeline, mount, RateControllerGains(), uses_camera=False)


def _platform_estimator(s: object) -> PlatformEkf:
    est = s.estimator  # type: ignore[attr-defined]
    return PlatformEkf(
        PlatformEkfConfig(
            use_turn_rate=est.use_turn_rate,
            gating=est.gating,
            accel_noise=est.accel_noise,
            heading_noise=est.heading_noise,
            turn_accel_noise=est.turn_accel_noise,
            # Initialise from sightings up to 4 s apart: while searching, the platform is often seen in
            # short bursts (a pass of the coverage pattern), and two bursts give its velocity well.
            init_max_span=4.0,
        )
    )


def load_preset_camera(s: object) -> PinholeCamera:
    """The scenario's camera model (the default downward 752x480 camera unless a calibration is given)."""
    path = s.camera.calibration  # type: ignore[attr-defined]
    return PinholeCamera.default_downward() if path is None else PinholeCamera.from_opencv_yaml(path)


def build_falanga2017(s: object, airframe: Airframe, rng: np.random.Generator) -> Preset:
    """Paper 000 end to end: the downward camera's images, the cross-and-circle tag detector (Alg. 1),
    PnP and geolocation with the ego estimate at the capture time, the unicycle EKF, the candidate
    planner, the Faessler controller and the state machine."""
    camera = load_preset_camera(s)
    h_fov, v_fov = camera.fov_rad()
    mission, guidance, controller, ego = _flight_core(s, airframe, min(h_fov, v_fov))
    mount = CameraMount.downward()
    tag = FalangaTag.default(size_m=s.platform.pad_size_m)  # type: ignore[attr-defined]
    pipeline = Pipeline(
        ego_estimator=ego,
        detector=FalangaTagDetector(tag),
        geolocator=PnpGeolocator(
            camera, mount, sigma_px=1.0, sigma_ego_pos_m=0.02, sigma_ego_att_rad=0.005, yaw_fold=4
        ),
        platform_estimator=_platform_estimator(s),
        mission=mission,
        guidance=guidance,
        controller=controller,
    )
    return Preset(
        "falanga2017", pipeline, mount, RateControllerGains(), uses_camera=True, camera=camera, pad=tag
    )


PRESETS: dict[str, Callable[[object, Airframe, np.random.Generator], Preset]] = {
    "groundtruth": build_groundtruth,
    "falanga2017": build_falanga2017,
}


def build_preset(scenario: object, airframe: Airframe, rng: np.random.Generator) -> Preset:
    name = scenario.preset  # type: ignore[attr-defined]
    try:
        builder = PRESETS[name]
    except KeyError:
        raise KeyError(f"unknown preset '{name}', expected one of {sorted(PRESETS)}") from None
    return builder(scenario, airframe, rng)
