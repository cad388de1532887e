"""Presets: named choices of one implementation per block.

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
from alight.cameras.pinhole import CameraMount
from alight.control.high_level import HighLevelController
from alight.control.rate import RateControllerGains
from alight.estimation.ego_ekf import EgoEkf, EgoEkfConfig
from alight.estimation.platform_ekf import PlatformEkf, PlatformEkfConfig
from alight.mission.guidance import Guidance, GuidanceConfig
from alight.mission.pipeline import Pipeline
from alight.mission.state_machine import Mission, MissionConfig
from alight.perception.geolocation import DirectGeolocator
from alight.planning.candidates import CandidatePlanner, PlannerConfig


@dataclass
class Preset:
    name: str
    pipeline: Pipeline
    mount: CameraMount
    rate_gains: RateControllerGains
    uses_camera: bool


def _mission_config(s: object) -> MissionConfig:
    m = s.mission  # type: ignore[attr-defined]
    return MissionConfig(
        takeoff_altitude_m=m.takeoff_altitude_m,
        explore_altitude_m=m.explore_altitude_m,
        track_height_m=m.track_height_m,
        land_speed_mps=m.land_speed_mps,
        motor_cutoff_range_m=m.motor_cutoff_range_m,
        lost_timeout_s=m.lost_timeout_s,
        max_go_arounds=m.max_go_arounds,
        time_budget_s=m.time_budget_s,
    )


def _flight_core(s: object, airframe: Airframe, fov_rad: float) -> tuple[Mission, Guidance, HighLevelController, EgoEkf]:
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
        )
    )
    area = sc.search_area  # type: ignore[attr-defined]
    guidance = Guidance(
        mission.config,
        planner,
        GuidanceConfig(search_area=(area.x_min, area.x_max, area.y_min, area.y_max), camera_fov_rad=fov_rad),
    )
    controller = HighLevelController(airframe)
    ego = EgoEkf(EgoEkfConfig())
    return mission, guidance, controller, ego


def build_groundtruth(s: object, airframe: Airframe, rng: np.random.Generator) -> Preset:
    perception = s.perception  # type: ignore[attr-defined]
    fov = math.radians(min(perception.fov_deg))
    mission, guidance, controller, ego = _flight_core(s, airframe, fov)
    mount = CameraMount.downward()
    est = s.estimator  # type: ignore[attr-defined]
    platform_estimator = PlatformEkf(PlatformEkfConfig(use_turn_rate=est.use_turn_rate, gating=est.gating))
    pipeline = Pipeline(
        ego_estimator=ego,
        geolocator=DirectGeolocator(mount),
        platform_estimator=platform_estimator,
        mission=mission,
        guidance=guidance,
        controller=controller,
    )
    return Preset("groundtruth", pipeline, mount, RateControllerGains(), uses_camera=False)


PRESETS: dict[str, Callable[[object, Airframe, np.random.Generator], Preset]] = {
    "groundtruth": build_groundtruth,
}


def build_preset(scenario: object, airframe: Airframe, rng: np.random.Generator) -> Preset:
    name = scenario.preset  # type: ignore[attr-defined]
    try:
        builder = PRESETS[name]
    except KeyError:
        raise KeyError(f"unknown preset '{name}', expected one of {sorted(PRESETS)}") from None
    return builder(scenario, airframe, rng)
