"""Presets: named choices of one implementation per block, and the builder of what flies from them.

A preset is data: ``mission/preset_data/<name>.yaml`` names a block per stage with its parameters
(``falanga2017``, ``groundtruth``, ``kim_kaist``, ``zamanakos_sdu``). :func:`build_preset` resolves a
scenario's blocks (its preset, its per-block sections and its ``blocks:`` overrides, checked by
:func:`alight.mission.blocks.resolve_blocks`) and builds the pipeline plus what the runner needs to drive
it (the camera model and mount, the pad to draw, the low-level gains).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np

from alight.airframe import Airframe
from alight.blockspec import BlockSpec, NoContext
from alight.cameras import CameraModel, MountedCamera
from alight.cameras.pinhole import CameraMount
from alight.control import CONTROLLERS
from alight.control.rate import RateControllerGains
from alight.energy.qos import DEFAULT_PHASE_POLICY, PhasePolicy, QosEnergyModel, QosSetting
from alight.estimation import PLATFORM_ESTIMATORS
from alight.estimation.ego_ekf import EgoEkf, EgoEkfConfig
from alight.mission.blocks import Block, EffectiveBlocks, preset_names, resolve_blocks
from alight.mission.guidance import Guidance, GuidanceConfig
from alight.mission.pipeline import Pipeline
from alight.mission.state_machine import Mission, MissionConfig
from alight.mission.touchdown_detector import TouchdownConfig
from alight.pads import PADS, PadDesign, WholeMarkerPad
from alight.perception import DETECTORS, GEOLOCATORS, Detector, DetectorContext
from alight.perception.qos_detector import QosDetector
from alight.planning import PLANNERS
from alight.settings import default_of, sources
from alight.types import GRAVITY_MPS2

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
    camera: CameraModel | None = None
    """The camera model the runner renders through (vision presets)."""
    pad: PadDesign | None = None
    """The pad design the runner draws on the platform (vision presets)."""
    color_camera: bool = False
    """The detector needs colour (BGR) images."""
    energy_model: QosEnergyModel | None = None
    """The compute-energy model of the detector's quality-of-service settings, when it has one."""
    planner_rate_hz: float = 50.0
    """Rate of the mission logic and the planner (Hz)."""
    blocks: EffectiveBlocks | None = None
    """The blocks it was built from (names and parameters)."""


_C = TypeVar("_C")
_T = TypeVar("_T")

PRESETS: tuple[str, ...] = preset_names()
"""The packaged presets (``mission/preset_data/*.yaml``)."""


VIEW_TILT_ALLOWANCE_RAD = math.radians(5.0)
"""How much of the camera's half field of view the descent's own tilt may take (rad), in
:func:`visibility_commit_height_m`."""


def visibility_commit_height_m(pad: Any, camera: CameraModel | None) -> float | None:
    """The height above the pad (m) below which ``camera`` (looking straight down) can no longer see the
    part of ``pad`` its detectors need whole, with :data:`VIEW_TILT_ALLOWANCE_RAD` of the half field of
    view kept for the vehicle's tilt: a descent must commit (go on blind, on the estimate) by then, or
    it loses the target above the commit height and goes around. None for pads whose detectors see them
    in part down to the ground (paper 000's tag has a close-range mode, the n-fold marker's centre and
    the red disc stay detectable); a :class:`~alight.pads.WholeMarkerPad` (the AprilTag pad) declares it."""
    if not isinstance(pad, WholeMarkerPad) or camera is None:
        return None
    half_fov = 0.5 * float(min(camera.fov_rad()))
    usable = max(half_fov - VIEW_TILT_ALLOWANCE_RAD, math.radians(5.0))
    return 0.5 * pad.min_view_side_m / math.tan(usable)


def _mission_value(s: Any, eff: EffectiveBlocks, key: str) -> Any:
    """A mission key as it flies: the scenario's, or where it leaves it None the preset's (its data's
    ``mission:`` section, checked by the scenario), or None: the block's default."""
    value = getattr(s.mission, key)
    return eff.mission.get(key) if value is None else value


def _mission_settings(s: Any, eff: EffectiveBlocks, cls: type) -> dict[str, Any]:
    """The fields of settings dataclass ``cls`` that the scenario's ``mission:`` section sets (its keys
    derive from ``cls``: ``alight.settings.sources``), as they fly: the scenario's value, else the
    preset's; a key both leave None is left out, so ``cls``'s own default applies."""
    keys = sources(type(s.mission))
    return {
        field: value
        for key, (owner, field) in keys.items()
        if owner is cls and (value := _mission_value(s, eff, key)) is not None
    }


def _mission_config(
    s: Any, eff: EffectiveBlocks, hover_thrust_N: float, commit_floor_m: float | None = None
) -> MissionConfig:
    td = dict(eff.mission.get("touchdown") or {})
    td.update({k: v for k, v in s.mission.touchdown.model_dump().items() if v is not None})
    given = _mission_settings(s, eff, MissionConfig)
    if commit_floor_m is not None and "land_commit_height_m" not in given:
        # the camera cannot see the pad below this: commit no lower (a scenario's or preset's value stands)
        given["land_commit_height_m"] = max(
            float(default_of(MissionConfig, "land_commit_height_m")), commit_floor_m
        )
    return MissionConfig(touchdown=TouchdownConfig(hover_thrust_N=hover_thrust_N, **td), **given)


def _coverage_fov_rad(s: Any, eff: EffectiveBlocks, camera: CameraModel | None) -> float:
    """The field of view that spaces the exploration pattern (the preset's ``coverage_fov_deg``: a value
    in deg, ``camera`` for the camera model's narrower field, ``perception`` for the ground-truth
    sensor's)."""
    fov = eff.mission.get("coverage_fov_deg", "camera")
    if fov == "perception" or camera is None:
        return math.radians(min(s.perception.fov_deg))
    if fov == "camera":
        # capped at 120 deg: beyond it a pad is too small and too oblique to find (an omnidirectional
        # camera's 186 deg would space the pattern wider than the search area)
        h_fov, v_fov = camera.fov_rad()
        return min(float(min(h_fov, v_fov)), math.radians(120.0))
    return math.radians(float(fov))


def _wide_view_axis_B_rad(s: Any, camera: CameraModel | None, mount: CameraMount) -> float:
    """Direction in the body's xy plane (rad from body x toward body y) of the camera's wider field of
    view: the image x axis (columns) when the horizontal field is the wider, else the image y axis,
    carried into B by the mount. For the ground-truth sensor its ``perception.fov_deg`` on the same
    mount. A round view (equal fields) has no wider axis; the weathervane then keeps the image x axis
    along the lean, which costs nothing."""
    h_fov, v_fov = (
        camera.fov_rad() if camera is not None else tuple(math.radians(f) for f in s.perception.fov_deg)
    )
    axis_B = mount.R_BC[:, 0] if h_fov >= v_fov else mount.R_BC[:, 1]
    return math.atan2(float(axis_B[1]), float(axis_B[0]))


def _qos_policy(s: Any) -> PhasePolicy:
    """The quality-of-service policy of the scenario's ``energy:`` section (a detector with ``qos``)."""
    es = s.energy
    if es.qos == "fixed":
        f = es.fixed
        return PhasePolicy.fixed(QosSetting(f.rate_hz, f.image_scale, f.max_kernel_px))
    return DEFAULT_PHASE_POLICY


def _energy_model(s: Any, detector: Detector | None) -> QosEnergyModel | None:
    """The compute-energy model of a quality-of-service detector (the scenario's ``energy:`` device)."""
    if not isinstance(detector, QosDetector):
        return None
    es = s.energy
    return QosEnergyModel.load(device=es.device, mode=es.mode, include_idle=es.include_idle)


def _vision(s: Any, eff: EffectiveBlocks) -> tuple[CameraModel | None, PadDesign | None, Detector | None]:
    """The camera model, the pad and the detector of a vision preset."""
    d = eff["detector"]
    camera = eff.camera_model
    pad = _build(PADS, eff["pad"], NoContext())
    detector = _build(DETECTORS, d, DetectorContext(pad=pad, camera=camera, qos_policy=_qos_policy(s)))
    return camera, pad, detector


def _build(table: Mapping[str, BlockSpec[_C, _T]], block: Block, context: _C) -> _T:
    """The object of the chosen ``block``, from its parameters and its stage's build context (``table``:
    the stage's registry, which types what it builds)."""
    return table[block.name].build(block.params, context)


def build_preset(scenario: Any, airframe: Airframe, rng: np.random.Generator) -> Preset:
    """The pipeline of ``scenario``'s blocks (its preset's, with the scenario's overrides)."""
    del rng  # no block draws at construction; kept for the runner's call
    s = scenario
    eff = resolve_blocks(s, fresh_camera=True)  # this flight's own camera model
    uses_camera = bool(eff["detector"].spec.provides.get("image", True))
    camera, pad, detector = _vision(s, eff) if uses_camera else (None, None, None)
    mount = CameraMount.downward()
    view = MountedCamera(camera=camera, mount=mount)
    mission = Mission(_mission_config(s, eff, airframe.weight_N, visibility_commit_height_m(pad, camera)))
    area = s.search_area
    guidance = Guidance(
        mission.config,
        _build(PLANNERS, eff["planner"], airframe),
        GuidanceConfig(
            search_area=(area.x_min, area.x_max, area.y_min, area.y_max),
            camera_fov_rad=_coverage_fov_rad(s, eff, camera),
            wide_view_axis_B_rad=_wide_view_axis_B_rad(s, camera, mount),
            max_tilt_rad=airframe.max_tilt_rad,
            rotor_drag_per_s=airframe.rotor_drag[0],
            max_climb_accel_mps2=0.5 * (airframe.thrust_to_weight - 1.0) * GRAVITY_MPS2,
            **_mission_settings(s, eff, GuidanceConfig),
        ),
    )
    pipeline = Pipeline(
        ego_estimator=EgoEkf(_EGO_EKF_CONFIG),
        detector=detector,
        geolocator=_build(GEOLOCATORS, eff["geolocator"], view),
        platform_estimator=_build(PLATFORM_ESTIMATORS, eff["platform_estimator"], view),
        mission=mission,
        guidance=guidance,
        controller=_build(CONTROLLERS, eff["controller"], airframe),
        flow_origin_B=(
            airframe.feet_B
            if s.optical_flow is None
            else airframe.downward_sensor_B(s.optical_flow.position_B_m, "optical_flow.position_B_m")
        ),
    )
    return Preset(
        s.preset,
        pipeline,
        mount,
        RateControllerGains.for_airframe(airframe),
        uses_camera=uses_camera,
        camera=camera,
        pad=pad,
        color_camera=eff.color,
        energy_model=_energy_model(s, detector),
        planner_rate_hz=float(eff["planner"].params.rate_hz),
        blocks=eff,
    )


def effective_config(scenario: Any) -> dict[str, Any]:
    """What ``alight fly --print-config`` prints: the scenario with its effective blocks."""
    eff = resolve_blocks(scenario, load_camera=False)
    out: dict[str, Any] = scenario.model_dump(mode="json")
    out["blocks"] = eff.as_dict()
    out["preset_mission"] = dict(eff.mission)
    # the mission keys as they fly: the preset's defaults where the scenario leaves None
    for key, value in eff.mission.items():
        if key == "touchdown":
            td = out["mission"]["touchdown"]
            td.update({k: v for k, v in value.items() if td.get(k) is None})
        elif key in out["mission"] and out["mission"][key] is None:
            out["mission"][key] = value
    return out


__all__ = ["PRESETS", "Preset", "build_preset", "effective_config"]
