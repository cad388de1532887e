"""Scenario files: what one mission is, validated with pydantic.

A scenario names a preset (which implementation each block uses), a seed, the platform's motion, the
wind, the sensors and the mission's parameters. Everything has a default, so the three-line file

    preset: groundtruth
    seed: 1
    platform: {path: circle, speed_mps: 2.0}

flies. Unknown keys are errors (a typo must not silently fall back to a default). ``load_scenario``
turns every problem into one ``ConfigError`` line that says what is wrong and where.

Files: an empty file (or one with only comments) is refused, since it is more often a truncated or wrong
file than a request for every default (write ``{}`` for that); a key given twice in one mapping is refused
(YAML keeps the last silently; :class:`alight.yaml_io.UniqueKeyLoader`).

Physical bounds: every number has a generous physical limit, far beyond any vehicle, camera or weather we
simulate but small enough that an absurd value (a typo, an extra three zeros, 1e9) is refused by name
before flying instead of being flown, overflowing or reserving memory in proportion to it. The bound of
each field is in its annotation (``le=...``) and the message names the key and the bound; the main ones:
``duration_s`` <= 3600 s (:data:`MAX_DURATION_S`), speeds <= 50 m/s (platform) and wind <= 60 m/s per
axis, altitudes and heights <= 1000 m, latencies <= 10 s, rates <= 1000 Hz, distances and lengths
<= 10 km, the search area within 10 km of the take-off point.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_serializer,
    model_validator,
)

from alight.errors import ConfigError
from alight.mission.guidance import GuidanceConfig
from alight.mission.state_machine import MissionConfig
from alight.mission.touchdown_detector import TouchdownConfig
from alight.settings import (
    MAX_DURATION_S,
    FiniteFloat,
    NonNegFloat,
    PositiveFloat,
    Probability,
    RateHz,
    Section,
    dataclass_keys,
    refuse_bool_for_int,
    section_model,
)
from alight.sim.sea.config import SeaConfig
from alight.sim.sensors import OpticalFlowConfig, RangeFinderConfig
from alight.sim.telemetry import TelemetryConfig
from alight.sim.textures import DistractorSpec
from alight.yaml_io import read_yaml_file as read_yaml_file

MAX_DISTANCE_M = 1.0e4
"""Largest distance, length or coordinate (m): 10 km."""


Coordinate = Annotated[float, Field(ge=-MAX_DISTANCE_M, le=MAX_DISTANCE_M, allow_inf_nan=False)]
Length = Annotated[float, Field(gt=0, le=MAX_DISTANCE_M, allow_inf_nan=False)]
MountCoordinate = Annotated[float, Field(ge=-2.0, le=2.0, allow_inf_nan=False)]
"""A sensor's position on the vehicle along one body axis (m): within 2 m of the body origin."""
WindComponent = Annotated[float, Field(ge=-60.0, le=60.0, allow_inf_nan=False)]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, use_attribute_docstrings=True)

    @field_validator("*", mode="before")
    @classmethod
    def _no_bool_for_int(cls, value: Any, info: ValidationInfo) -> Any:
        return refuse_bool_for_int(cls, str(info.field_name), value)


MAX_PLATFORM_DECEL_MPS2 = 8.0
"""Hardest braking of a road vehicle: about 0.8 g on dry asphalt (tyre friction ~0.8)."""
MAX_PLATFORM_ACCEL_MPS2 = 4.0
"""Hardest acceleration of the ground vehicles that carry pads (cars, pick-ups, tractors): 0-100 km/h in 7 s
is 4 m/s^2."""

PlatformDecel = Annotated[float, Field(gt=0, le=MAX_PLATFORM_DECEL_MPS2, allow_inf_nan=False)]
PlatformAccel = Annotated[float, Field(gt=0, le=MAX_PLATFORM_ACCEL_MPS2, allow_inf_nan=False)]


class BrakeStopSpec(_Strict):
    """Brake hard to a stop at ``t_s``, stand for ``wait_s``, then drive on back to ``speed_mps``."""

    t_s: NonNegFloat
    """When braking starts (s)."""
    decel_mps2: PlatformDecel = 6.0
    """Braking deceleration (m/s^2), at most 8 (about 0.8 g, dry asphalt)."""
    wait_s: NonNegFloat = 3.0
    """Standstill before driving on (s)."""
    accel_mps2: PlatformAccel = 2.0
    """Acceleration back to the path speed (m/s^2), at most 4."""


class RampSpec(_Strict):
    """Accelerate or decelerate at ``t_s`` to a new speed, held from then on."""

    t_s: NonNegFloat
    """When the speed starts to change (s)."""
    speed_mps: NonNegFloat
    """The new speed along the path (m/s)."""
    accel_mps2: PlatformAccel = 1.0
    """Rate of the change, speeding up or slowing down (m/s^2), at most 4."""


class SpeedProfileSpec(_Strict):
    """One change of the platform's speed along its path: ``brake_stop`` or ``ramp``."""

    brake_stop: BrakeStopSpec | None = None
    ramp: RampSpec | None = None

    @model_validator(mode="after")
    def _one(self) -> SpeedProfileSpec:
        if (self.brake_stop is None) == (self.ramp is None):
            raise ValueError("speed_profile needs exactly one of brake_stop or ramp")
        return self


MIN_PAD_SIZE_M = 0.1
"""Smallest pad (m): the feet of the smallest camera-carrying multirotor (a 10 cm gear); 1e-9 m flew
today. A scenario also needs a pad wider than its own gear (checked against ``contact``)."""


class PlatformSpec(_Strict):
    """The ground vehicle that carries the pad."""

    path: Literal["straight", "circle", "figure8", "tractor", "random"] = "straight"
    speed_mps: Annotated[float, Field(ge=0, le=50.0, allow_inf_nan=False)] = 1.2
    """Speed along the path (m/s), at most 50 (180 km/h)."""
    pad_size_m: Annotated[float, Field(ge=MIN_PAD_SIZE_M, le=20.0, allow_inf_nan=False)] = 1.5
    """Side of the square pad (m), at least :data:`MIN_PAD_SIZE_M` and wider than the landing gear's
    footprint (``contact.gear_half_width_m``)."""
    pad_height_m: Annotated[float, Field(ge=0, le=20.0, allow_inf_nan=False)] = 0.5
    start_xy: tuple[Coordinate, Coordinate] | None = None
    """Start of the path in W (m); None draws it from the seed inside the search area."""
    heading_rad: Annotated[float, Field(ge=-100.0, le=100.0, allow_inf_nan=False)] | None = None
    """Initial heading (rad); None draws it from the seed."""
    circle_radius_m: Length = 10.0
    figure8_length_m: Length = 60.0
    tractor_row_length_m: Length = 30.0
    tractor_turn_radius_m: Length = 4.0
    random_max_curvature: Annotated[float, Field(gt=0, le=10.0, allow_inf_nan=False)] = 0.15
    speed_profile: SpeedProfileSpec | None = None
    """Changes of speed along the path (the path's geometry stays); None: ``speed_mps`` throughout."""
    telemetry: TelemetryConfig | None = None
    """The platform broadcasts its GNSS fix to the aircraft; None (default): no telemetry."""
    sea: SeaConfig | None = None
    """The platform is a vessel at sea: it follows the path and its speed profile, and the sea adds heave,
    roll, pitch, surge, sway and yaw (``docs/sea.md``); the pad's height is then the vessel's pad offset
    above the waterline (the world's z = 0, the sea's mean level), not ``pad_height_m``. None (default):
    a ground vehicle on level ground."""

    @field_validator("sea", mode="wrap")
    @classmethod
    def _sea_in_one_line(cls, value: Any, handler: Any) -> Any:
        # SeaConfig's cross-field rules raise ConfigError (one line that names the key): the scenario's
        # message names platform.sea once, from pydantic's location
        try:
            return handler(value)
        except ConfigError as err:
            raise ValueError(str(err).removeprefix("platform.sea: ").removeprefix("platform.sea.")) from None

    @model_validator(mode="after")
    def _no_pad_height_at_sea(self) -> PlatformSpec:
        # at sea the pad's height is the vessel's pad offset above the waterline: a pad_height_m set with
        # a sea would silently do nothing (the default passes: a dumped scenario writes it)
        default = PlatformSpec.model_fields["pad_height_m"].default
        if self.sea is not None and self.pad_height_m != default:
            raise ValueError(
                "pad_height_m has no effect with platform.sea: the pad's height is the vessel's "
                "(platform.sea.pad_offset_m, above the waterline)"
            )
        return self

    @model_serializer(mode="wrap")
    def _no_sea_key_on_land(self, handler: Any) -> Any:
        # a platform on land writes no ``sea`` key: the scenario (and result.json) of every mission
        # without a sea stays what it was before the key existed
        out = handler(self)
        if self.sea is None and isinstance(out, dict):
            out.pop("sea", None)
        return out


def _as_list(value: Any) -> Any:
    """Tuples and lists alike, for comparing a value with its default."""
    return [_as_list(v) for v in value] if isinstance(value, tuple | list) else value


class WindSpec(_Strict):
    """Wind: none, a steady air velocity (whose direction may turn), that wind with Dryden turbulence, or
    the gust model of paper 004 Sec. IV-C. Every key acts on the model it is set with or is refused."""

    model: Literal["none", "steady", "gust", "dryden"] = "none"
    velocity_mps: tuple[WindComponent, WindComponent, WindComponent] = (0.0, 0.0, 0.0)
    """Steady and dryden: the mean air velocity in W at t = 0 (m/s), each axis within +-60 (a
    hurricane's)."""
    gust_power_N: Annotated[float, Field(gt=0, le=100.0, allow_inf_nan=False)] = 7.0
    """Gust model: the initial force ``power_init`` (N); 3.45 and 7.76 N are the 8 and 12 m/s cases."""
    turbulence: Literal["none", "light", "moderate", "severe"] = "none"
    """Dryden: MIL-F-8785C low-altitude intensity (the wind at 20 ft: 15, 30, 45 kt); dryden needs one
    other than none, the other models take none."""
    turbulence_min_airspeed_mps: PositiveFloat = 1.0
    """Dryden: floor of the airspeed V through the frozen turbulence field (m/s); the filters' time
    constants are L / V."""
    direction_rate_rad_s: FiniteFloat = 0.0
    """Steady and dryden: the mean wind turns about +z at this rate (rad/s, counter-clockwise)."""
    direction_changes: list[tuple[NonNegFloat, FiniteFloat]] = Field(default_factory=list)
    """Steady and dryden: steps ``[t_s, delta_rad]``: at t_s the mean wind turns by delta_rad."""

    @model_validator(mode="after")
    def _keys_act(self) -> WindSpec:
        # A key that would silently do nothing with the chosen model is an error (a typo of the model
        # must not fly a different wind than the file describes). ``none`` is the exception: wind off,
        # with the other keys kept for a campaign that sweeps the model over a base setting them.
        if self.model == "none":
            return self
        mean_keys = {"velocity_mps", "direction_rate_rad_s", "direction_changes"}
        acts = {
            "steady": mean_keys,
            "dryden": mean_keys | {"turbulence", "turbulence_min_airspeed_mps"},
            "gust": {"gust_power_N"},
        }[self.model]
        # Only keys set away from their default count: a dumped and reloaded scenario (campaigns do
        # that) carries every key at its default value.
        defaults = {
            name: f.get_default(call_default_factory=True) for name, f in type(self).model_fields.items()
        }
        idle = sorted(
            k
            for k in (self.model_fields_set - {"model"}) - acts
            if _as_list(getattr(self, k)) != _as_list(defaults[k])
        )
        if idle:
            raise ValueError(f"wind model '{self.model}' does not use {', '.join(idle)}")
        if self.model == "dryden" and self.turbulence == "none":
            raise ValueError("wind model 'dryden' needs turbulence: light, moderate or severe")
        return self


class PerceptionSpec(_Strict):
    """The ground-truth perception sensor (preset ``groundtruth``) and the detection timing of all presets."""

    rate_hz: RateHz = 20.0
    noise_m: Annotated[float, Field(ge=0, le=100.0, allow_inf_nan=False)] = 0.05
    """Standard deviation of the relative-position noise, per axis (m)."""
    latency_s: Annotated[float, Field(ge=0, le=10.0, allow_inf_nan=False)] = 0.1
    """Delay from image capture to the measurement reaching the estimator (s), at most 10."""
    dropout_prob: Probability = 0.0
    """Probability that a frame yields no detection."""
    fov_deg: tuple[
        Annotated[float, Field(gt=0, le=360.0, allow_inf_nan=False)],
        Annotated[float, Field(gt=0, le=360.0, allow_inf_nan=False)],
    ] = (90.0, 64.0)
    """Horizontal and vertical field of view of the downward camera (deg); the pad centre must be inside."""
    max_range_m: Annotated[float, Field(gt=0, le=1000.0, allow_inf_nan=False)] = 25.0
    """Beyond this distance the pad is too small to detect (m)."""
    mitigation: Literal["none", "gate", "shape", "gate+shape"] = "none"
    """False-lock mitigation of the colour-filter detector (``kim_kaist``): none (paper 003's biggest red
    contour), gating with the estimator's predicted pixel, shape checks, or both; any of them also makes
    the estimator confirm a track (5 gated sightings in a row) before the vehicle follows it."""


class CameraSpec(_Strict):
    """The onboard camera of the vision presets and how its images are rendered."""

    calibration: str | None = None
    """OpenCV calibration YAML of a pinhole camera; None: the default downward 752x480 camera."""
    ground: Literal["grass", "asphalt", "concrete"] = "grass"
    """Procedural ground texture."""
    noise_dn: Annotated[float, Field(ge=0, le=255.0, allow_inf_nan=False)] = 2.0
    """Sensor noise, standard deviation in grey levels."""
    exposure_s: Annotated[float, Field(ge=0, le=1.0, allow_inf_nan=False)] = 0.0
    """Exposure time for motion blur from the body rates (s); 0 for none."""
    exposure_gain: Annotated[float, Field(gt=0, le=100.0, allow_inf_nan=False)] = 1.0
    """Brightness gain (exposure change)."""
    gamma: Annotated[float, Field(gt=0, le=10.0, allow_inf_nan=False)] = 1.0
    color: bool | None = None
    """Render BGR colour images; None: the preset decides (colour for presets whose detector needs it)."""
    illumination_gain_bgr: tuple[
        Annotated[float, Field(gt=0, le=100.0, allow_inf_nan=False)],
        Annotated[float, Field(gt=0, le=100.0, allow_inf_nan=False)],
        Annotated[float, Field(gt=0, le=100.0, allow_inf_nan=False)],
    ] = (1.0, 1.0, 1.0)
    """Per-channel gain of the light (white balance / colour temperature), applied before the gamma."""
    brightness_drift: Annotated[float, Field(ge=0, lt=1, allow_inf_nan=False)] = 0.0
    """Relative amplitude of a slow sinusoidal brightness change (clouds passing the sun); 0: none."""
    brightness_drift_period_s: Annotated[float, Field(gt=0, le=1.0e5, allow_inf_nan=False)] = 60.0
    distractors: DistractorSpec | None = None
    """Coloured objects on the ground that are not the target (the false targets of a colour filter)."""


Interval = tuple[FiniteFloat, FiniteFloat]


def _check_intervals(name: str, intervals: list[Interval]) -> None:
    for t0, t1 in intervals:
        if not t1 > t0:
            raise ValueError(f"{name} interval ({t0}, {t1}) must have t1 > t0")


class NoiseBurstSpec(_Strict):
    """Bursts of strong sensor noise (electrical interference, a failing cable)."""

    prob: Probability = 0.0
    """Probability that a burst starts at a frame."""
    frames: Annotated[int, Field(ge=1, le=1000)] = 3
    """Frames a burst lasts."""
    sigma_dn: PositiveFloat = 40.0
    """Standard deviation of the added noise (grey levels)."""


class OcclusionSpec(_Strict):
    """Part of the view hidden by something near the lens (an insect, a drop, a cable): a dark rectangle."""

    prob: Probability = 0.0
    """Probability per frame."""
    size_fraction: Annotated[float, Field(gt=0, le=1, allow_inf_nan=False)] = 0.4
    """Largest side of the rectangle as a fraction of the image's width and height; each side is drawn
    uniformly between half of it and all of it."""
    value_dn: Annotated[int, Field(ge=0, le=255)] = 20
    """Grey level of the occluder (out of focus and unlit: dark)."""


class ExposureSpikeSpec(_Strict):
    """A frame exposed far too long or too short (auto-exposure catching the sun, a glint)."""

    prob: Probability = 0.0
    """Probability per frame."""
    gain: Annotated[float, Field(gt=0, le=100, allow_inf_nan=False)] = 4.0
    """Brightness factor of the spiked frame (> 1 over-, < 1 under-exposed), saturating at 255."""


class FrozenFrameSpec(_Strict):
    """The camera driver hands over its previous buffer again, stamped with the new capture time."""

    prob: Probability = 0.0
    """Probability per frame."""


class StripesSpec(_Strict):
    """A band of rows or columns of garbage (lost packets of a USB/MIPI/analogue link)."""

    prob: Probability = 0.0
    """Probability per frame."""
    max_lines: Annotated[int, Field(ge=1)] = 60
    """Largest width of the band (px); each band is drawn uniformly from 1 to this, rows or columns with
    equal probability."""


class CorruptionSpec(_Strict):
    """Frame corruptions of the vision presets, each drawn independently per frame, applied in this order:
    frozen (replaces the frame), exposure, noise, occlusion, stripes."""

    noise: NoiseBurstSpec = Field(default_factory=NoiseBurstSpec)
    occlusion: OcclusionSpec = Field(default_factory=OcclusionSpec)
    exposure: ExposureSpikeSpec = Field(default_factory=ExposureSpikeSpec)
    frozen: FrozenFrameSpec = Field(default_factory=FrozenFrameSpec)
    stripes: StripesSpec = Field(default_factory=StripesSpec)

    def active(self) -> list[str]:
        """Names of the corruptions with a non-zero probability."""
        return [
            n for n in ("noise", "occlusion", "exposure", "frozen", "stripes") if getattr(self, n).prob > 0
        ]


class BiasStepSpec(_Strict):
    """A step of an IMU bias at ``t_s`` (a temperature jump, a knock), kept from then on."""

    t_s: NonNegFloat
    """When the bias steps (s)."""
    delta: tuple[FiniteFloat, FiniteFloat, FiniteFloat]
    """The step, in the IMU's (body) axes: m/s^2 for the accelerometer, rad/s for the gyroscope."""


class OdometryJumpSpec(_Strict):
    """The VIO re-localises at ``t_s``: its position jumps by ``offset_m`` and stays shifted."""

    t_s: NonNegFloat
    """When the odometry jumps (s)."""
    offset_m: tuple[FiniteFloat, FiniteFloat, FiniteFloat]
    """The jump of the reported position, in W (m)."""
    announced: bool = True
    """The VIO says so, as MAVLink ODOMETRY's ``reset_counter`` going up: the ego estimator restarts at
    the new pose and the pipeline keeps its frame. False: an unannounced jump, which the ego estimator
    refuses as an outlier until ``odometry_reset_after`` (10) messages in a row, then follows (its frame
    moves under the platform estimate and the plan)."""


class FaultSpec(_Strict):
    """Sensor and perception faults, each injected where it happens on a real vehicle (``docs/faults.md``).
    Every key acts on every preset, or the mission is refused with one line."""

    dropout_prob: Probability = 0.0
    """Extra probability that a frame is lost (added to ``perception.dropout_prob``): a camera frame is
    not delivered; the ground-truth sensor reports nothing."""
    blackouts: list[Interval] = Field(default_factory=list)
    """Intervals [t0, t1] (s) with a blacked-out camera: dark frames; the ground-truth sensor reports
    nothing."""
    latency_s: NonNegFloat = 0.0
    """Extra mean detection latency (s), added to ``perception.latency_s``."""
    latency_jitter_s: NonNegFloat = 0.0
    """Half-width of the uniform jitter of each frame's latency (s); frames are still delivered in
    capture order."""
    corruption: CorruptionSpec = Field(default_factory=CorruptionSpec)
    """Corrupted camera frames (vision presets; the ground-truth preset takes only ``frozen``)."""
    accel_bias_steps: list[BiasStepSpec] = Field(default_factory=list)
    """Accelerometer bias steps: ``{t_s, delta}`` with ``delta`` in m/s^2, body axes."""
    gyro_bias_steps: list[BiasStepSpec] = Field(default_factory=list)
    """Gyroscope bias steps: ``{t_s, delta}`` with ``delta`` in rad/s, body axes."""
    odometry_jumps: list[OdometryJumpSpec] = Field(default_factory=list)
    """VIO re-localisations: ``{t_s, offset_m}``."""
    odometry_dropouts: list[Interval] = Field(default_factory=list)
    """Intervals [t0, t1] (s) without odometry messages."""
    range_dropout_prob: Probability = 0.0
    """Probability that a range reading is invalid (no return)."""
    range_dropouts: list[Interval] = Field(default_factory=list)
    """Intervals [t0, t1] (s) of invalid range readings."""
    range_spurious_prob: Probability = 0.0
    """Probability that a range reading is a spurious return, uniform over the sensor's span."""
    flow_dropout_prob: Probability = 0.0
    """Probability that an optical-flow sample is lost (the module reports quality 0: too little texture
    or light under it); needs ``optical_flow:``."""
    flow_dropouts: list[Interval] = Field(default_factory=list)
    """Intervals [t0, t1] (s) without optical-flow samples (a dark or featureless deck, a dead module);
    needs ``optical_flow:``."""

    @model_validator(mode="after")
    def _ordered(self) -> FaultSpec:
        _check_intervals("blackout", self.blackouts)
        _check_intervals("odometry_dropouts", self.odometry_dropouts)
        _check_intervals("range_dropouts", self.range_dropouts)
        _check_intervals("flow_dropouts", self.flow_dropouts)
        return self

    def acts_on_flow(self) -> bool:
        """Whether a fault acts on the optical-flow module."""
        return self.flow_dropout_prob > 0 or bool(self.flow_dropouts)


class SearchArea(_Strict):
    """Where the platform starts and the vehicle searches (m, W), within 10 km of the take-off point."""

    x_min: Coordinate = -20.0
    x_max: Coordinate = 20.0
    y_min: Coordinate = -20.0
    y_max: Coordinate = 20.0

    @model_validator(mode="after")
    def _ordered(self) -> SearchArea:
        if not (self.x_max > self.x_min and self.y_max > self.y_min):
            raise ValueError("search_area needs x_max > x_min and y_max > y_min")
        return self


# -- sections derived from the runtime settings dataclasses (alight.settings): each key's type, bound,
# default and docstring are those of the dataclass field that uses it, declared once there --

_RUNTIME_ONLY_TOUCHDOWN = ("hover_thrust_N", "level_gain_per_s", "steady_tilt_time_constant_s")
"""The land detector's parameters a scenario does not set: the airframe's hover thrust, and two the
detector's tests hold."""

_RUNTIME_ONLY_MISSION = (
    "hover_tolerance_m",
    "hover_speed_tolerance_mps",
    "land_dwell_s",
    "land_tilt_wait_s",
    "land_tilt_time_constant_s",
    "abort_hover_s",
    "touchdown",
)
"""The mission logic's parameters a scenario does not set (``touchdown`` is its own section)."""

_SCENARIO_GUIDANCE = (
    "search_pattern",
    "aim_camera",
    "intercept",
    "adaptive_horizon",
    "no_feasible",
    "search_speed_uncertainty_mps",
    "max_platform_speed_mps",
    "track_view_sigmas",
    "scan_yaw_rate_rad_s",
    "weathervane_min_tilt_rad",
    "takeoff_climb_speed_mps",
)
"""The guidance's parameters a scenario sets (the rest come from the airframe, the camera and the search
area, or are the guidance's own)."""

_SCENARIO_ONLY_DEFAULTS = ("search_pattern", "aim_camera")
"""Mission keys a preset does not set: their scenario default is the guidance's."""


FlowPosition = tuple[MountCoordinate, MountCoordinate, MountCoordinate]
_FLOW_POSITION_DOC = """Where the module sits in the body frame B (m; x forward, y left, z up; what PX4's
``EKF2_OF_POS_X/Y/Z`` give in FRD); None: at the landing-gear feet under the body origin. The simulated
module measures from there and the pipeline takes the rotation's velocity at that point (w x r) out of
what it reads, on the simulator and on a real vehicle through the bridge alike. It may not sit below the
feet (checked against the airframe when the mission is built). A scenario key of its own: the runtime
config holds the resolved ``origin_B``."""


def _fields_except(cls: type, excluded: tuple[str, ...]) -> tuple[str, ...]:
    return tuple(k for k in dataclass_keys(cls) if k not in excluded)


if TYPE_CHECKING:  # mypy sees a section with any attribute; pydantic sees the derived model
    TouchdownSpec = Section
    RangeFinderSpec = Section
    OpticalFlowSpec = Section
    MissionSpec = Section
else:
    TouchdownSpec = section_model(
        "TouchdownSpec",
        "The onboard land detector (``alight.mission.touchdown_detector.TouchdownConfig``); None keeps the"
        " preset's or the block's value.",
        [(TouchdownConfig, _fields_except(TouchdownConfig, _RUNTIME_ONLY_TOUCHDOWN))],
        optional=True,
    )
    RangeFinderSpec = section_model(
        "RangeFinderSpec",
        "The downward range finder (TeraRanger One-like, ``alight.sim.sensors.RangeFinderConfig``),"
        " measured from the landing-gear feet.",
        [
            (
                RangeFinderConfig,
                {"min_range_m": "min_range_m", "max_range_m": "max_range_m", "noise_m": "noise_std_m"},
            )
        ],
        optional=False,
        check=RangeFinderConfig,
    )
    OpticalFlowSpec = section_model(
        "OpticalFlowSpec",
        "A downward optical-flow module with its own ranger (ARK Flow / Holybro H-Flow class,"
        " ``alight.sim.sensors.OpticalFlowConfig``): it measures the vehicle's velocity relative to the"
        " surface under it, the deck in a landing. The pipeline reads it in the committed descent, where the"
        " camera no longer sees the whole pad: a deck that brakes or speeds up under the last half metre"
        " sends the vehicle around (``mission.land_commit_deck_velocity_error_mps``).",
        [(OpticalFlowConfig, _fields_except(OpticalFlowConfig, ("origin_B",)))],
        optional=False,
        extra={"position_B_m": (FlowPosition | None, Field(default=None, description=_FLOW_POSITION_DOC))},
        check=OpticalFlowConfig,
    )
    MissionSpec = section_model(
        "MissionSpec",
        "Overrides of the mission logic's and the guidance's parameters"
        " (``alight.mission.state_machine.MissionConfig``, ``alight.mission.guidance.GuidanceConfig``,"
        " which hold every default); None: the preset's value where its ``mission:`` section sets one,"
        " else the block's default.",
        [
            (MissionConfig, _fields_except(MissionConfig, _RUNTIME_ONLY_MISSION)),
            (GuidanceConfig, _SCENARIO_GUIDANCE),
        ],
        optional=True,
        keep_defaults=_SCENARIO_ONLY_DEFAULTS,
        extra={
            "touchdown": (
                TouchdownSpec,
                Field(default_factory=TouchdownSpec, description="The onboard land detector."),
            )
        },
    )


PRESET_ONLY_MISSION_KEYS = ("coverage_fov_deg",)
"""Keys of a preset's ``mission:`` section that are not scenario keys: ``coverage_fov_deg``, the field of
view that spaces the exploration pattern (deg, or ``camera`` / ``perception``)."""


def _preset_mission_keys() -> tuple[str, ...]:
    """The scenario mission keys a preset may set defaults for: those whose scenario default is None (the
    scenario holds overrides only), and the land detector's (``touchdown``)."""
    return tuple(
        name
        for name, f in MissionSpec.model_fields.items()
        if name == "touchdown" or f.get_default(call_default_factory=True) is None
    )


@cache
def preset_mission_defaults(name: str) -> Mapping[str, Any]:
    """A preset's ``mission:`` defaults (``mission/preset_data/<name>.yaml``), checked as a scenario's
    mission section is: the values a mission flies where its scenario leaves a key None. ``ValueError``
    with one line naming the preset's key for a key a preset cannot set or a bad value."""
    from alight.mission.blocks import preset_data

    data = preset_data(name).get("mission") or {}
    where = f"preset {name}: mission"
    if not isinstance(data, Mapping):
        raise ValueError(f"{where}: expected a mapping, got {data!r}")
    allowed = _preset_mission_keys()
    for key in data:
        if key not in allowed and key not in PRESET_ONLY_MISSION_KEYS:
            raise ValueError(
                f"{where}.{key}: not a key a preset sets (it may set: {', '.join(allowed)}, "
                f"{', '.join(PRESET_ONLY_MISSION_KEYS)})"
            )
    fov = data.get("coverage_fov_deg", "camera")
    if fov not in ("camera", "perception") and not (
        isinstance(fov, int | float) and not isinstance(fov, bool) and 0 < fov <= 180
    ):
        raise ValueError(f"{where}.coverage_fov_deg: expected camera, perception or 0-180 deg, got {fov!r}")
    given = {k: v for k, v in data.items() if k not in PRESET_ONLY_MISSION_KEYS}
    try:
        spec = MissionSpec.model_validate(given)
    except ValidationError as err:
        first = err.errors()[0]
        key = ".".join(str(p) for p in first["loc"])
        raise ValueError(f"{where}.{key}: {first['msg']}") from None
    out: dict[str, Any] = {k: getattr(spec, k) for k in given if k != "touchdown"}
    if "touchdown" in given:
        out["touchdown"] = spec.touchdown.model_dump(exclude_none=True)
    return out


class PlannerSpec(_Strict):
    """Overrides of the planner block's parameters (``alight blocks`` lists them with their defaults);
    None: the block's default."""

    n_candidates: Annotated[int, Field(ge=1, le=10000)] | None = None
    """Candidates per planning cycle (block default 20)."""
    horizon_min_s: Annotated[float, Field(gt=0, le=60.0, allow_inf_nan=False)] | None = None
    """Shortest candidate duration (s; block default 1.0)."""
    horizon_max_s: Annotated[float, Field(gt=0, le=60.0, allow_inf_nan=False)] | None = None
    """Longest candidate duration (s; block default 3.0)."""
    rate_hz: RateHz | None = None
    """Replanning rate, also the mission logic's (Hz; block default 50)."""
    adopt_threshold_m: Annotated[float, Field(ge=0, le=100.0, allow_inf_nan=False)] | None = None
    """A new best whose end is closer than this to the current plan's is not adopted (m; default 0.2)."""
    end_acceleration: Literal["free", "platform"] | None = None
    """Final acceleration of each candidate: ``free`` as in paper 000, or ``platform`` (block default),
    the platform's predicted acceleration, which removes the lag of free-end plans on a curve."""


class EstimatorSpec(_Strict):
    """Overrides of the platform estimator's parameters; None: the block's default. A key the scenario's
    estimator does not have is refused (e.g. ``use_turn_rate`` for ``kim_ukf``)."""

    use_turn_rate: bool | None = None
    """``unicycle_ekf``: a turn-rate state (block default true; paper 000's model has none: false)."""
    gating: bool | None = None
    """Reject measurements outside the chi-square gate (``unicycle_ekf``, ``kim_ukf``; default true)."""
    accel_noise: Annotated[float, Field(gt=0, le=100.0, allow_inf_nan=False)] | None = None
    """Tangential acceleration noise of the platform model (m/s^2/sqrt(Hz); ``unicycle_ekf`` default 0.1,
    ``kim_ukf`` 0.5)."""
    heading_noise: Annotated[float, Field(gt=0, le=100.0, allow_inf_nan=False)] | None = None
    """``unicycle_ekf``: heading-rate noise of the constant-heading model (rad/s/sqrt(Hz); default 0.1)."""
    turn_accel_noise: Annotated[float, Field(gt=0, le=100.0, allow_inf_nan=False)] | None = None
    """``unicycle_ekf``: turn-rate noise of the turn-rate model (rad/s^2/sqrt(Hz); default 0.1)."""


class ControllerSpec(_Strict):
    """Overrides of the controller block's parameters; None: the block's (or the preset's) value."""

    position_bandwidth_rad_s: Annotated[float, Field(gt=0, le=100.0, allow_inf_nan=False)] | None = None
    """Natural frequency of the position loop, critically damped (rad/s; block default 3.0)."""
    integral_gain: Annotated[float, Field(ge=0, le=1000.0, allow_inf_nan=False)] | None = None
    """Integral gain on the position error per axis (1/s^3), as an autopilot's position loop has; None:
    the preset's (off for ``falanga2017``/``groundtruth``/``kim_kaist``, 2.0 for ``zamanakos_sdu``, which
    flies on PX4's integrating loops, and for ``alight``). Must be below kp * kv = 2 * bandwidth^3 of the
    position loop."""
    integral_limit_mps2: Annotated[float, Field(gt=0, le=100.0, allow_inf_nan=False)] | None = None
    """Largest acceleration the integral may command per axis (m/s^2; block default 6.0)."""
    l1_adaptive: bool | None = None
    """L1 adaptive augmentation of the outer loop (paper 003): true picks the controller ``faessler_l1``,
    false ``faessler``; None: the preset's (on for ``kim_kaist`` and ``alight``, off otherwise)."""


BlockEntry = str | dict[str, Any]
"""A block: its name, or ``{name: ..., <parameters>}``."""


class BlocksSpec(_Strict):
    """One implementation per stage, each a name or ``{name: ..., <parameters>}`` (``alight blocks``
    lists them); None: the preset's. A mapping without ``name`` sets parameters of the preset's block."""

    camera: BlockEntry | None = None
    """``pinhole`` or ``fisheye``, with ``calibration: FILE``."""
    pad: BlockEntry | None = None
    """``falanga_tag``, ``apriltag``, ``sdu_marker`` or ``red_target``."""
    detector: BlockEntry | None = None
    """``falanga``, ``apriltag``, ``aruco``, ``nfold``, ``sdu``, ``red`` or ``groundtruth``."""
    geolocator: BlockEntry | None = None
    """``pnp``, ``flat_earth``, ``homography`` or ``direct``."""
    platform_estimator: BlockEntry | None = None
    """``unicycle_ekf``, ``kim_ukf`` or ``sdu_kf``."""
    controller: BlockEntry | None = None
    """``faessler`` or ``faessler_l1``."""
    planner: BlockEntry | None = None
    """``min_jerk_candidates``."""


class QosSpec(_Strict):
    """One quality-of-service setting of the detector (``alight.energy.QosSetting``)."""

    rate_hz: RateHz = 30.0
    """Frames processed per second; the others are skipped (the camera's rate bounds it)."""
    image_scale: Annotated[float, Field(gt=0, le=1, allow_inf_nan=False)] = 1.0
    """Resize factor of the image before detection."""
    max_kernel_px: Annotated[int, Field(ge=5, le=1001)] = 41
    """Largest n-fold kernel size the adaptive search may try (px)."""


class EnergySpec(_Strict):
    """Compute energy of the onboard detector (``zamanakos_sdu``), on a device power profile."""

    device: Literal["jetson_nano", "odroid_xu4"] = "jetson_nano"
    """Companion computer (``alight/energy/devices``): paper 004 flies a Jetson Nano."""
    mode: str | None = None
    """Power mode of the device (e.g. ``10W``, ``5W``); None: its default."""
    include_idle: bool = False
    """Add the device's idle power over the whole flight (powprofiler's total-system energy)."""
    qos: Literal["phase", "fixed"] = "phase"
    """``phase``: the quality changes with the mission phase (explore, track, land); ``fixed``: the
    setting below throughout."""
    fixed: QosSpec = Field(default_factory=QosSpec)
    """The setting of ``qos: fixed`` (default: the highest quality of the shipped model)."""


MIN_CONTACT_SPEED_MPS = 0.05
"""Slowest contact-speed limit of the judge (m/s): it samples the speed at the 1 kHz physics step, in
which gravity alone adds 0.0098 m/s, so a limit below five times that judges the integrator, not the
landing (1e-9 m/s flew today and judged every touchdown a crash)."""


class ContactSpec(_Strict):
    """How the simulator judges a landing (ground truth) and its contact model of the feet."""

    gear_half_width_m: Annotated[float, Field(ge=0, le=10.0, allow_inf_nan=False)] = 0.2
    """Half the landing gear's footprint: the feet sit at (+-w, +-w) under the body, and the centre must
    stay this far inside the pad's edges (m)."""
    max_vertical_speed_mps: Annotated[
        float, Field(ge=MIN_CONTACT_SPEED_MPS, le=100.0, allow_inf_nan=False)
    ] = 1.0
    """Landed only below this vertical speed relative to the pad (m/s), at least 0.05
    (:data:`MIN_CONTACT_SPEED_MPS`)."""
    max_horizontal_speed_mps: Annotated[
        float, Field(ge=MIN_CONTACT_SPEED_MPS, le=100.0, allow_inf_nan=False)
    ] = 0.75
    """Landed only below this horizontal speed relative to the pad (m/s), at least 0.05
    (:data:`MIN_CONTACT_SPEED_MPS`)."""
    max_tilt_deg: Annotated[float, Field(gt=0, le=90.0, allow_inf_nan=False)] = 25.0
    settle_s: PositiveFloat = 2.0
    """After the motors stop, the vehicle must still be on the pad (or, after an abort's landing, where
    it landed) this long later to count as landed (s); sliding off, tipping over or a bounce onto the
    ground in that time is a crash."""
    stiffness_N_per_m: PositiveFloat = 2500.0
    """Normal stiffness of each foot (N/m)."""
    damping_Ns_per_m: NonNegFloat = 25.0
    """Normal damping of each foot (N s/m)."""
    friction: NonNegFloat = 0.6
    """Coulomb friction coefficient of the feet on the deck and the ground."""


MIN_DURATION_S = 1.0
"""Shortest mission (s): the motors' spin-up to hover thrust (~0.2 s) and a climb of a metre at 1 m/s,
the least a take-off takes; 1e-9 s flew today and was recorded as a result."""


class Scenario(_Strict):
    """One mission."""

    preset: str = "groundtruth"
    """A packaged preset (``mission/preset_data``): ``alight`` (this project's own composition),
    ``groundtruth``, ``falanga2017``, ``kim_kaist``, ``zamanakos_sdu``."""
    seed: Annotated[int, Field(ge=0, le=2**63 - 1)] = 0
    duration_s: Annotated[float, Field(ge=MIN_DURATION_S, le=MAX_DURATION_S, allow_inf_nan=False)] = 120.0
    """Simulated time limit of the mission (s), from :data:`MIN_DURATION_S` (1) to :data:`MAX_DURATION_S`
    (3600)."""
    platform: PlatformSpec = Field(default_factory=PlatformSpec)
    wind: WindSpec = Field(default_factory=WindSpec)
    perception: PerceptionSpec = Field(default_factory=PerceptionSpec)
    camera: CameraSpec = Field(default_factory=CameraSpec)
    faults: FaultSpec = Field(default_factory=FaultSpec)
    search_area: SearchArea = Field(default_factory=SearchArea)
    mission: MissionSpec = Field(default_factory=MissionSpec)
    planner: PlannerSpec = Field(default_factory=PlannerSpec)
    estimator: EstimatorSpec = Field(default_factory=EstimatorSpec)
    controller: ControllerSpec = Field(default_factory=ControllerSpec)
    contact: ContactSpec = Field(default_factory=ContactSpec)
    rangefinder: RangeFinderSpec = Field(default_factory=RangeFinderSpec)
    optical_flow: OpticalFlowSpec | None = None
    """A downward optical-flow module (``{}`` for the defaults); None: the vehicle has none."""
    energy: EnergySpec = Field(default_factory=EnergySpec)
    airframe: str = "f450"
    """The vehicle, for the simulator and the controller alike: a packaged airframe (``f450``, paper
    000's, or ``matrice100``) or an airframe YAML file (``alight.airframes``)."""
    blocks: BlocksSpec = Field(default_factory=BlocksSpec)
    """The blocks that fly, overriding the preset's (``docs/blocks.md``)."""
    name: str | None = None
    """Free text naming the scenario in reports."""

    @model_validator(mode="after")
    def _pad_holds_the_gear(self) -> Scenario:
        # the centre must stay gear_half_width_m inside each edge: on a narrower pad no landing counts
        gear = 2.0 * self.contact.gear_half_width_m
        if not self.platform.pad_size_m > gear:
            raise ValueError(
                f"platform.pad_size_m: {self.platform.pad_size_m:g} m is no wider than the landing gear "
                f"(2 x contact.gear_half_width_m = {gear:g} m)"
            )
        return self

    @model_validator(mode="after")
    def _flow_faults_need_the_module(self) -> Scenario:
        if self.optical_flow is None and self.faults.acts_on_flow():
            raise ValueError(
                "faults.flow_dropout_prob / flow_dropouts: the vehicle has no optical-flow module "
                "(add optical_flow: {})"
            )
        return self

    @model_validator(mode="after")
    def _known_blocks(self) -> Scenario:
        # late import: the blocks import the algorithms. Refuses an unknown preset or block, a parameter a
        # block rejects and an incompatible pair, before anything flies (ValueError: one line, the key).
        from alight.mission.blocks import resolve_blocks

        resolve_blocks(self)
        preset_mission_defaults(self.preset)
        return self

    @field_validator("airframe")
    @classmethod
    def _known_airframe(cls, value: str) -> str:
        from alight.airframes import load_airframe

        try:
            load_airframe(value)
        except ConfigError as err:
            raise ValueError(str(err)) from None
        return value

    def with_seed(self, seed: int) -> Scenario:
        return self.model_copy(update={"seed": int(seed)})


def _format_error(source: str, err: ValidationError) -> str:
    first = err.errors()[0]
    where = ".".join(str(p) for p in first["loc"])
    msg = first["msg"]
    if not where and first["type"] == "value_error":
        # a whole-scenario check (the blocks) names its key in its message
        return f"{source}: {msg.removeprefix('Value error, ')}"
    where = where or "(top level)"
    if first["type"] == "unexpected_keyword_argument":  # a settings dataclass's word for an unknown key
        msg = "Extra inputs are not permitted"
    extra = f" (and {err.error_count() - 1} more)" if err.error_count() > 1 else ""
    got = first.get("input")
    shown = "" if isinstance(got, dict | list) or got is None else f", got {got!r}"
    return f"{source}: {where}: {msg}{shown}{extra}"


def scenario_from_dict(data: Any, source: str = "scenario") -> Scenario:
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: expected a mapping of scenario keys, got {type(data).__name__}")
    try:
        return Scenario.model_validate(data)
    except ValidationError as err:
        raise ConfigError(_format_error(source, err)) from None


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario YAML file; any problem becomes one ``ConfigError`` line."""
    data, _ = read_yaml_file(path, "scenario")
    return scenario_from_dict(data, str(Path(path)))
