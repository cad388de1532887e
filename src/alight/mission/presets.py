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
from alight.cameras import load_camera
from alight.cameras.omni import OmniCamera
from alight.cameras.pinhole import CameraMount, PinholeCamera
from alight.control import Controller
from alight.control.high_level import HighLevelController, HighLevelGains
from alight.control.l1_adaptive import L1AugmentedController, L1Config
from alight.control.rate import RateControllerGains
from alight.energy.qos import DEFAULT_PHASE_POLICY, PhasePolicy, QosDetector, QosEnergyModel, QosSetting
from alight.estimation.ego_ekf import EgoEkf, EgoEkfConfig
from alight.estimation.kim_ukf import KimUkf, KimUkfConfig
from alight.estimation.platform_ekf import PlatformEkf, PlatformEkfConfig
from alight.estimation.platform_velocity import PlatformVelocityConfig
from alight.estimation.sdu_kf import SduKalmanFilter, SduKfConfig
from alight.mission.guidance import Guidance, GuidanceConfig
from alight.mission.pipeline import Pipeline
from alight.mission.state_machine import Mission, MissionConfig
from alight.mission.touchdown_detector import TouchdownConfig
from alight.pads.falanga_tag import FalangaTag
from alight.pads.red_target import RedTarget
from alight.pads.sdu_pad import SduPad
from alight.perception.color_filter import RedTargetDetector, RedTargetDetectorConfig
from alight.perception.falanga_tag import FalangaTagDetector
from alight.perception.flat_earth import FlatEarthGeolocator
from alight.perception.geolocation import DirectGeolocator, PnpGeolocator
from alight.perception.homography_geolocation import HomographyGeolocator
from alight.perception.sdu_marker import SduMarkerDetector
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
    camera: PinholeCamera | OmniCamera | None = None
    """The camera model the runner renders through (vision presets)."""
    pad: object | None = None
    """The pad design the runner draws on the platform (vision presets)."""
    color_camera: bool = False
    """The detector needs colour (BGR) images."""
    energy_model: QosEnergyModel | None = None
    """The compute-energy model of the detector's quality-of-service settings, when it has one."""


_MISSION_OPTIONAL = (
    "takeoff_timeout_s",
    "search_timeout_s",
    "max_target_losses",
    "land_position_tolerance_m",
    "land_velocity_tolerance_mps",
    "max_estimate_age_s",
    "land_max_position_std_m",
    "land_hold_offset_m",
    "land_hold_rel_speed_mps",
    "land_abort_offset_m",
    "land_abort_rel_speed_mps",
    "land_lost_timeout_s",
    "land_abort_position_std_m",
    "land_hold_timeout_s",
    "final_action",
)
"""Scenario mission keys whose None means the MissionConfig default."""


def _mission_config(s: object, land_speed_mps: float = 0.4, hover_thrust_N: float = 9.81) -> MissionConfig:
    m = s.mission  # type: ignore[attr-defined]
    td = {k: v for k, v in m.touchdown.model_dump().items() if v is not None}
    optional = {k: getattr(m, k) for k in _MISSION_OPTIONAL if getattr(m, k) is not None}
    return MissionConfig(
        takeoff_altitude_m=m.explore_altitude_m if m.takeoff_altitude_m is None else m.takeoff_altitude_m,
        explore_altitude_m=m.explore_altitude_m,
        track_height_m=m.track_height_m,
        land_speed_mps=land_speed_mps if m.land_speed_mps is None else m.land_speed_mps,
        land_commit_height_m=m.land_commit_height_m,
        lost_timeout_s=m.lost_timeout_s,
        max_go_arounds=m.max_go_arounds,
        time_budget_s=m.time_budget_s,
        touchdown=TouchdownConfig(hover_thrust_N=hover_thrust_N, **td),
        **optional,
    )


def _flight_core(
    s: object,
    airframe: Airframe,
    fov_rad: float,
    *,
    land_speed_mps: float = 0.4,
    l1: bool = False,
    integral_gain: float = 0.0,
) -> tuple[Mission, Guidance, Controller, EgoEkf]:
    sc = s  # the Scenario; typed loosely to keep this module free of the scenario's import cycle
    mission = Mission(_mission_config(sc, land_speed_mps, airframe.weight_N))
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
            aim_camera=sc.mission.aim_camera,  # type: ignore[attr-defined]
            intercept=sc.mission.intercept,  # type: ignore[attr-defined]
            adaptive_horizon=sc.mission.adaptive_horizon,  # type: ignore[attr-defined]
            no_feasible=sc.mission.no_feasible,  # type: ignore[attr-defined]
            max_platform_speed_mps=sc.mission.max_platform_speed_mps,  # type: ignore[attr-defined]
            max_tilt_rad=airframe.max_tilt_rad,
            rotor_drag_per_s=airframe.rotor_drag[0],
            **(
                {}
                if sc.mission.search_speed_uncertainty_mps is None  # type: ignore[attr-defined]
                else {"search_speed_uncertainty_mps": sc.mission.search_speed_uncertainty_mps}  # type: ignore[attr-defined]
            ),
        ),
    )
    cs = sc.controller  # type: ignore[attr-defined]
    ki = integral_gain if cs.integral_gain is None else cs.integral_gain
    gains = HighLevelGains.from_bandwidth(
        cs.position_bandwidth_rad_s, ki=(ki, ki, ki), integral_limit=cs.integral_limit_mps2
    )
    controller: Controller = HighLevelController(airframe, gains)
    use_l1 = l1 if sc.controller.l1_adaptive is None else sc.controller.l1_adaptive  # type: ignore[attr-defined]
    if use_l1:
        controller = L1AugmentedController(controller, L1Config())  # type: ignore[arg-type]
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


def build_zamanakos_sdu(s: object, airframe: Airframe, rng: np.random.Generator) -> Preset:
    """Paper 004 end to end: the landing marker of an n-fold marker and three ArUco landmarks
    (adaptive kernel size), pixel to ground by the homography of the camera's field of view at the
    altitude (the 8 steps of Sec. IV-A), the Kalman filter on the relative position with the vehicle's
    velocity and acceleration as input and the detection delay compensated (Sec. IV-B), with the platform
    velocity estimator. Guidance, planning and control are the flight core's."""
    camera = load_preset_camera(s)
    h_fov, v_fov = camera.fov_rad()
    # PX4's position and velocity loops, which paper 004 flies on, integrate: without it a 12 m/s gust
    # holds the vehicle ~0.9 m downwind of its reference.
    mission, guidance, controller, ego = _flight_core(s, airframe, min(h_fov, v_fov), integral_gain=2.0)
    mount = CameraMount.downward()
    pad = SduPad.default(size_m=s.platform.pad_size_m)  # type: ignore[attr-defined]
    es = s.energy  # type: ignore[attr-defined]
    if es.qos == "fixed":
        f = es.fixed
        policy = PhasePolicy.fixed(QosSetting(f.rate_hz, f.image_scale, f.max_kernel_px))
    else:
        policy = DEFAULT_PHASE_POLICY
    energy_model = QosEnergyModel.load(device=es.device, mode=es.mode, include_idle=es.include_idle)
    pipeline = Pipeline(
        ego_estimator=ego,
        detector=QosDetector(SduMarkerDetector(pad, camera=camera), policy),
        # The deck's height above the ground is known to the operator of the vehicle that carries it; the
        # paper intersects with the ground (z = 0), which biases every fix radially by d * h_deck / h.
        geolocator=HomographyGeolocator(camera, mount, plane_z_W=s.platform.pad_height_m),  # type: ignore[attr-defined]
        # "the moving platform's yaw orientation will be taken into account" (Sec. IV-B): the marker's
        # yaw changes turn the velocity's heading at once (known modulo the n-fold order when the ArUco
        # markers are out of view, hence increments, not values)
        platform_estimator=SduKalmanFilter(
            SduKfConfig(
                velocity=PlatformVelocityConfig(measured_yaw_increments=True, yaw_fold=pad.nfold_order)
            )
        ),
        mission=mission,
        guidance=guidance,
        controller=controller,
    )
    return Preset(
        "zamanakos_sdu",
        pipeline,
        mount,
        RateControllerGains(),
        uses_camera=True,
        camera=camera,
        pad=pad,
        energy_model=energy_model,
    )


def build_kim_kaist(s: object, airframe: Airframe, rng: np.random.Generator) -> Preset:
    """Paper 003 end to end: a downward 186 deg fisheye (Scaramuzza model), the red target found by the
    colour filter (Alg. 1-2, biggest red contour), its pixel fused by the UKF with the fisheye
    measurement model (eq. 10-27), flat-earth geolocation (eq. 5-9) for what the pipeline reports, the
    L1 adaptive augmentation of the outer loop, and the paper's descent: a -0.1 m/s altitude ramp while
    holding over the target. Planning and control below the L1 loop are the flight core's."""
    sc = s
    path = sc.camera.calibration  # type: ignore[attr-defined]
    if path is None:
        # No resolution is given in the paper; 640 x 480 with the 186 deg circle inscribed, like the real
        # fisheye calibration in the test data.
        camera = OmniCamera.synthetic(640, 480, fov_deg=186.0)
    else:
        camera = load_camera(path)
    # The omnidirectional view sees the whole search area's width from the exploration altitude: the
    # coverage pattern is spaced by a 120 deg footprint (the target is too small to find beyond it).
    mission, guidance, controller, ego = _flight_core(
        s, airframe, math.radians(120.0), land_speed_mps=0.1, l1=True
    )
    mount = CameraMount.downward()
    pad_height = sc.platform.pad_height_m  # type: ignore[attr-defined]
    target = RedTarget.default(size_m=sc.platform.pad_size_m)  # type: ignore[attr-defined]
    # With shape checks the target is a disc: a disc's circularity (4 pi A / P^2) is 1 and stays above
    # 0.8 for the ellipses a fisheye makes of it up to ~60 deg off axis, while every rectangle, a square
    # included (pi / 4 = 0.785), is below it: red boxes and tarpaulins are not taken for the target.
    detector = RedTargetDetector(
        RedTargetDetectorConfig(mitigation=sc.perception.mitigation, min_circularity=0.8)  # type: ignore[attr-defined]
    )
    pipeline = Pipeline(
        ego_estimator=ego,
        detector=detector,
        geolocator=FlatEarthGeolocator(camera, mount, deck_height_m=pad_height),
        # With the mitigation on, a track must be confirmed by 5 gated pixels in a row (0.25 s at 20 Hz)
        # before the vehicle follows it; the paper's version trusts the first sighting.
        platform_estimator=KimUkf(
            KimUkfConfig(
                deck_height=pad_height,
                confirm_updates=0 if sc.perception.mitigation == "none" else 5,  # type: ignore[attr-defined]
            ),
            camera=camera,
            mount=mount,
        ),
        mission=mission,
        guidance=guidance,
        controller=controller,
    )
    return Preset(
        "kim_kaist",
        pipeline,
        mount,
        RateControllerGains(),
        uses_camera=True,
        camera=camera,
        pad=target,
        color_camera=True,
    )


PRESETS: dict[str, Callable[[object, Airframe, np.random.Generator], Preset]] = {
    "groundtruth": build_groundtruth,
    "falanga2017": build_falanga2017,
    "zamanakos_sdu": build_zamanakos_sdu,
    "kim_kaist": build_kim_kaist,
}


def build_preset(scenario: object, airframe: Airframe, rng: np.random.Generator) -> Preset:
    name = scenario.preset  # type: ignore[attr-defined]
    try:
        builder = PRESETS[name]
    except KeyError:
        raise KeyError(f"unknown preset '{name}', expected one of {sorted(PRESETS)}") from None
    return builder(scenario, airframe, rng)
