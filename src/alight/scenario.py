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
(YAML keeps the last silently; :class:`UniqueKeyLoader`).

Physical bounds: every number has a generous physical limit, far beyond any vehicle, camera or weather we
simulate but small enough that an absurd value (a typo, an extra three zeros, 1e9) is refused by name
before flying instead of being flown, overflowing or reserving memory in proportion to it. The bound of
each field is in its annotation (``le=...``) and the message names the key and the bound; the main ones:
``duration_s`` <= 3600 s (:data:`MAX_DURATION_S`), speeds <= 50 m/s (platform) and wind <= 60 m/s per
axis, altitudes and heights <= 1000 m, latencies <= 10 s, rates <= 1000 Hz, distances and lengths
<= 10 km, the search area within 10 km of the take-off point.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from alight.errors import ConfigError

FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegFloat = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Probability = Annotated[float, Field(ge=0, le=1, allow_inf_nan=False)]

MAX_DURATION_S = 3600.0
"""Longest mission (s): an hour, ten times a multirotor's endurance."""
MAX_DISTANCE_M = 1.0e4
"""Largest distance, length or coordinate (m): 10 km."""


Coordinate = Annotated[float, Field(ge=-MAX_DISTANCE_M, le=MAX_DISTANCE_M, allow_inf_nan=False)]
Length = Annotated[float, Field(gt=0, le=MAX_DISTANCE_M, allow_inf_nan=False)]
Altitude = Annotated[float, Field(gt=0, le=1000.0, allow_inf_nan=False)]
RateHz = Annotated[float, Field(gt=0, le=1000.0, allow_inf_nan=False)]
WindComponent = Annotated[float, Field(ge=-60.0, le=60.0, allow_inf_nan=False)]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class PlatformSpec(_Strict):
    """The ground vehicle that carries the pad."""

    path: Literal["straight", "circle", "figure8", "tractor", "random"] = "straight"
    speed_mps: Annotated[float, Field(ge=0, le=50.0, allow_inf_nan=False)] = 1.2
    """Speed along the path (m/s), at most 50 (180 km/h)."""
    pad_size_m: Annotated[float, Field(gt=0, le=20.0, allow_inf_nan=False)] = 1.5
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


class WindSpec(_Strict):
    """Wind: none, a steady air velocity, or the gust model of paper 004 Sec. IV-C."""

    model: Literal["none", "steady", "gust"] = "none"
    velocity_mps: tuple[WindComponent, WindComponent, WindComponent] = (0.0, 0.0, 0.0)
    """Steady wind: the air's velocity in W (m/s), each axis within +-60 (a hurricane's)."""
    gust_power_N: Annotated[float, Field(gt=0, le=100.0, allow_inf_nan=False)] = 7.0
    """Gust model: the initial force ``power_init`` (N); 3.45 and 7.76 N are the 8 and 12 m/s cases."""


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


class DistractorSpecModel(_Strict):
    """Red objects painted on the ground, per 20 m ground tile (``alight.sim.textures.DistractorSpec``)."""

    count: Annotated[int, Field(ge=0, le=500)] = 8
    size_m: Annotated[float, Field(gt=0, le=100.0, allow_inf_nan=False)] = 0.8
    """Diameter of a disc, long side of a rectangle (m)."""
    shape: Literal["disc", "rect", "mixed"] = "mixed"
    aspect: Annotated[float, Field(ge=1, le=100, allow_inf_nan=False)] = 2.0
    color_bgr: tuple[
        Annotated[int, Field(ge=0, le=255)],
        Annotated[int, Field(ge=0, le=255)],
        Annotated[int, Field(ge=0, le=255)],
    ] = (40, 40, 200)
    color_jitter_dn: Annotated[float, Field(ge=0, le=255, allow_inf_nan=False)] = 25.0


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
    distractors: DistractorSpecModel | None = None
    """Coloured objects on the ground that are not the target (the false targets of a colour filter)."""


class FaultSpec(_Strict):
    dropout_prob: Probability = 0.0
    """Extra probability that a detection is lost."""
    blackouts: list[tuple[FiniteFloat, FiniteFloat]] = Field(default_factory=list)
    """Intervals [t0, t1] (s) with no detections at all."""

    @model_validator(mode="after")
    def _ordered(self) -> FaultSpec:
        for t0, t1 in self.blackouts:
            if not t1 > t0:
                raise ValueError(f"blackout interval ({t0}, {t1}) must have t1 > t0")
        return self


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


class MissionSpec(_Strict):
    takeoff_altitude_m: Altitude | None = None
    """Height of the take-off climb over the take-off point (m); None: the exploration altitude. Climbing
    straight up first gives the camera its widest footprint over the take-off point within seconds,
    before the pattern leaves it: a moving platform crossing the area is most often near it early (the
    zamanakos_sdu straight-line misses of a 4 m take-off were all platforms that passed there while the
    vehicle was still low and flying its first leg the other way)."""
    explore_altitude_m: Altitude = 12.0
    """Height of the search (m), at most 1000 (as every altitude and height)."""
    track_height_m: Altitude = 2.5
    land_speed_mps: Annotated[float, Field(gt=0, le=10.0, allow_inf_nan=False)] | None = None
    """Descent speed of the landing ramp (m/s); None: the preset's (0.4, and paper 003's 0.1 for
    ``kim_kaist``)."""
    motor_cutoff_range_m: Annotated[float, Field(gt=0, le=10.0, allow_inf_nan=False)] = 0.03
    land_commit_height_m: Altitude = 0.6
    """Below this height above the pad a lost target no longer aborts the descent (m): the camera sees
    the tag's cross down to about 0.3 m, but a moving pad may leave the view in the last half metre."""
    lost_timeout_s: Annotated[float, Field(gt=0, le=MAX_DURATION_S, allow_inf_nan=False)] = 3.0
    max_go_arounds: Annotated[int, Field(ge=0, le=1000)] = 3
    time_budget_s: Annotated[float, Field(gt=0, le=MAX_DURATION_S, allow_inf_nan=False)] | None = None
    search_pattern: Literal["spiral", "lawnmower"] = "spiral"
    """Coverage of the search area: an outward square spiral from the take-off point, or paper 000's
    generic waypoint coverage as a lawnmower from the nearest corner."""
    aim_camera: bool = True
    """In take-off and exploration, move the reference upwind so that the body-fixed downward camera, not
    the body, follows it: holding position in a side wind tilts the vehicle and its view moves
    ``h tan(tilt)`` downwind (mission/README.md has the measurements). False flies the body on the
    pattern, as papers 000 and 004 do."""


class PlannerSpec(_Strict):
    n_candidates: Annotated[int, Field(ge=1, le=10000)] = 20
    horizon_min_s: Annotated[float, Field(gt=0, le=60.0, allow_inf_nan=False)] = 1.0
    horizon_max_s: Annotated[float, Field(gt=0, le=60.0, allow_inf_nan=False)] = 3.0
    rate_hz: RateHz = 50.0
    adopt_threshold_m: Annotated[float, Field(ge=0, le=100.0, allow_inf_nan=False)] = 0.2
    end_acceleration: Literal["free", "platform"] = "platform"
    """Final acceleration of each candidate: ``free`` as in paper 000, or the platform's predicted
    acceleration (a turning platform's centripetal acceleration), which removes the lag of free-end
    plans behind a platform on a curve."""

    @model_validator(mode="after")
    def _ordered(self) -> PlannerSpec:
        if self.horizon_max_s < self.horizon_min_s:
            raise ValueError("planner.horizon_max_s must be >= horizon_min_s")
        return self


class EstimatorSpec(_Strict):
    use_turn_rate: bool = True
    """Unicycle EKF with a turn-rate state (paper 000's model has none: set False for the paper's)."""
    gating: bool = True
    accel_noise: Annotated[float, Field(gt=0, le=100.0, allow_inf_nan=False)] = 0.1
    """Tangential acceleration noise of the platform model (m/s^2/sqrt(Hz))."""
    heading_noise: Annotated[float, Field(gt=0, le=100.0, allow_inf_nan=False)] = 0.1
    """Heading-rate noise of the constant-heading model (rad/s/sqrt(Hz))."""
    turn_accel_noise: Annotated[float, Field(gt=0, le=100.0, allow_inf_nan=False)] = 0.1
    """Turn-rate noise of the turn-rate model (rad/s^2/sqrt(Hz))."""


class ControllerSpec(_Strict):
    position_bandwidth_rad_s: Annotated[float, Field(gt=0, le=100.0, allow_inf_nan=False)] = 3.0
    """Natural frequency of the position loop, critically damped (rad/s)."""
    integral_gain: Annotated[float, Field(ge=0, le=1000.0, allow_inf_nan=False)] | None = None
    """Integral gain on the position error per axis (1/s^3), as an autopilot's position loop has; None:
    the preset's (off for ``falanga2017``/``groundtruth``/``kim_kaist``, on for ``zamanakos_sdu``, which
    flies on PX4's integrating loops). Must be below kp * kv of the position loop."""
    integral_limit_mps2: Annotated[float, Field(gt=0, le=100.0, allow_inf_nan=False)] = 6.0
    """Largest acceleration the integral may command per axis (m/s^2)."""
    l1_adaptive: bool | None = None
    """L1 adaptive augmentation of the outer loop (paper 003); None: the preset decides (on for
    ``kim_kaist``, off otherwise)."""


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


class ContactSpec(_Strict):
    gear_half_width_m: Annotated[float, Field(ge=0, le=10.0, allow_inf_nan=False)] = 0.2
    max_vertical_speed_mps: Annotated[float, Field(gt=0, le=100.0, allow_inf_nan=False)] = 1.0
    max_horizontal_speed_mps: Annotated[float, Field(gt=0, le=100.0, allow_inf_nan=False)] = 0.75
    max_tilt_deg: Annotated[float, Field(gt=0, le=90.0, allow_inf_nan=False)] = 25.0


class Scenario(_Strict):
    """One mission."""

    preset: str = "groundtruth"
    seed: Annotated[int, Field(ge=0, le=2**63 - 1)] = 0
    duration_s: Annotated[float, Field(gt=0, le=MAX_DURATION_S, allow_inf_nan=False)] = 120.0
    """Simulated time limit of the mission (s), at most :data:`MAX_DURATION_S` (3600)."""
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
    energy: EnergySpec = Field(default_factory=EnergySpec)
    name: str | None = None
    """Free text naming the scenario in reports."""

    @model_validator(mode="after")
    def _known_preset(self) -> Scenario:
        from alight.mission.presets import PRESETS  # late import: presets import the blocks

        if self.preset not in PRESETS:
            raise ValueError(f"unknown preset '{self.preset}', expected one of {sorted(PRESETS)}")
        return self

    def with_seed(self, seed: int) -> Scenario:
        return self.model_copy(update={"seed": int(seed)})


def _format_error(source: str, err: ValidationError) -> str:
    first = err.errors()[0]
    where = ".".join(str(p) for p in first["loc"]) or "(top level)"
    msg = first["msg"]
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


class UniqueKeyLoader(yaml.SafeLoader):  # type: ignore[misc,unused-ignore]  # PyYAML has no stubs here
    """PyYAML's safe loader, refusing a key given twice in one mapping (the plain loader keeps the last
    one silently, so ``speed_mps: 2`` ... ``speed_mps: 20`` would fly the second)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen: set[Any] = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            try:
                duplicate = key in seen
            except TypeError:  # an unhashable key: the base class reports it
                break
            if duplicate:
                raise yaml.constructor.ConstructorError(
                    None, None, f"key {key!r} given twice", key_node.start_mark
                )
            seen.add(key)
        mapping: dict[Any, Any] = super().construct_mapping(node, deep=deep)
        return mapping


def load_yaml_text(text: str, source: str, what: str = "scenario") -> Any:
    """Parse YAML with :class:`UniqueKeyLoader`; an empty document, bad YAML or a duplicate key becomes
    one ``ConfigError`` line naming ``source`` (and the line where YAML says it)."""
    try:
        data = yaml.load(text, Loader=UniqueKeyLoader)  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        line = getattr(mark, "line", None)
        where = f" (line {line + 1})" if line is not None else ""
        problem = getattr(err, "problem", None) or str(err).splitlines()[0]
        raise ConfigError(f"{source}: not valid YAML{where}: {problem}") from None
    except RecursionError:
        raise ConfigError(f"{source}: not valid YAML: nested too deeply") from None
    if data is None:
        raise ConfigError(f"{source}: the file is empty (write {{}} for a {what} with every default)")
    return data


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario YAML file; any problem becomes one ``ConfigError`` line."""
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"{p}: no such scenario file")
    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError as err:
        raise ConfigError(f"{p}: not valid YAML: not UTF-8 text ({err.reason})") from None
    except OSError as err:
        raise ConfigError(f"{p}: cannot read the scenario file: {err.strerror or err}") from None
    return scenario_from_dict(load_yaml_text(text, str(p)), str(p))
