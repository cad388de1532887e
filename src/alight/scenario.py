"""Scenario files: what one mission is, validated with pydantic.

A scenario names a preset (which implementation each block uses), a seed, the platform's motion, the
wind, the sensors and the mission's parameters. Everything has a default, so the three-line file

    preset: groundtruth
    seed: 1
    platform: {path: circle, speed_mps: 2.0}

flies. Unknown keys are errors (a typo must not silently fall back to a default). ``load_scenario``
turns every problem into one ``ConfigError`` line that says what is wrong and where.
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


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, use_attribute_docstrings=True)


class PlatformSpec(_Strict):
    """The ground vehicle that carries the pad."""

    path: Literal["straight", "circle", "figure8", "tractor", "random"] = "straight"
    speed_mps: NonNegFloat = 1.2
    pad_size_m: PositiveFloat = 1.5
    pad_height_m: NonNegFloat = 0.5
    start_xy: tuple[FiniteFloat, FiniteFloat] | None = None
    """Start of the path in W (m); None draws it from the seed inside the search area."""
    heading_rad: FiniteFloat | None = None
    """Initial heading (rad); None draws it from the seed."""
    circle_radius_m: PositiveFloat = 10.0
    figure8_length_m: PositiveFloat = 60.0
    tractor_row_length_m: PositiveFloat = 30.0
    tractor_turn_radius_m: PositiveFloat = 4.0
    random_max_curvature: PositiveFloat = 0.15


class WindSpec(_Strict):
    """Wind: none, a steady air velocity, or the gust model of paper 004 Sec. IV-C."""

    model: Literal["none", "steady", "gust"] = "none"
    velocity_mps: tuple[FiniteFloat, FiniteFloat, FiniteFloat] = (0.0, 0.0, 0.0)
    """Steady wind: the air's velocity in W (m/s)."""
    gust_power_N: PositiveFloat = 7.0
    """Gust model: the initial force ``power_init`` (N); 3.45 and 7.76 N are the 8 and 12 m/s cases."""


class PerceptionSpec(_Strict):
    """The ground-truth perception sensor (preset ``groundtruth``) and the detection timing of all presets."""

    rate_hz: PositiveFloat = 20.0
    noise_m: NonNegFloat = 0.05
    """Standard deviation of the relative-position noise, per axis (m)."""
    latency_s: NonNegFloat = 0.1
    """Delay from image capture to the measurement reaching the estimator (s)."""
    dropout_prob: Probability = 0.0
    """Probability that a frame yields no detection."""
    fov_deg: tuple[PositiveFloat, PositiveFloat] = (90.0, 64.0)
    """Horizontal and vertical field of view of the downward camera (deg); the pad centre must be inside."""
    max_range_m: PositiveFloat = 25.0
    """Beyond this distance the pad is too small to detect (m)."""
    mitigation: Literal["none", "gate", "shape", "gate+shape"] = "none"
    """False-lock mitigation of the colour-filter detector (``kim_kaist``): none (paper 003's biggest red
    contour), gating with the estimator's predicted pixel, shape checks, or both; any of them also makes
    the estimator confirm a track (5 gated sightings in a row) before the vehicle follows it."""


class DistractorSpecModel(_Strict):
    """Red objects painted on the ground, per 20 m ground tile (``alight.sim.textures.DistractorSpec``)."""

    count: Annotated[int, Field(ge=0, le=500)] = 8
    size_m: PositiveFloat = 0.8
    """Diameter of a disc, long side of a rectangle (m)."""
    shape: Literal["disc", "rect", "mixed"] = "mixed"
    aspect: Annotated[float, Field(ge=1, allow_inf_nan=False)] = 2.0
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
    noise_dn: NonNegFloat = 2.0
    """Sensor noise, standard deviation in grey levels."""
    exposure_s: NonNegFloat = 0.0
    """Exposure time for motion blur from the body rates (s); 0 for none."""
    exposure_gain: PositiveFloat = 1.0
    """Brightness gain (exposure change)."""
    gamma: PositiveFloat = 1.0
    color: bool | None = None
    """Render BGR colour images; None: the preset decides (colour for presets whose detector needs it)."""
    illumination_gain_bgr: tuple[PositiveFloat, PositiveFloat, PositiveFloat] = (1.0, 1.0, 1.0)
    """Per-channel gain of the light (white balance / colour temperature), applied before the gamma."""
    brightness_drift: Annotated[float, Field(ge=0, lt=1, allow_inf_nan=False)] = 0.0
    """Relative amplitude of a slow sinusoidal brightness change (clouds passing the sun); 0: none."""
    brightness_drift_period_s: PositiveFloat = 60.0
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
    x_min: FiniteFloat = -20.0
    x_max: FiniteFloat = 20.0
    y_min: FiniteFloat = -20.0
    y_max: FiniteFloat = 20.0

    @model_validator(mode="after")
    def _ordered(self) -> SearchArea:
        if not (self.x_max > self.x_min and self.y_max > self.y_min):
            raise ValueError("search_area needs x_max > x_min and y_max > y_min")
        return self


class MissionSpec(_Strict):
    takeoff_altitude_m: PositiveFloat | None = None
    """Height of the take-off climb over the take-off point (m); None: the exploration altitude. Climbing
    straight up first gives the camera its widest footprint over the take-off point within seconds,
    before the pattern leaves it: a moving platform crossing the area is most often near it early (the
    zamanakos_sdu straight-line misses of a 4 m take-off were all platforms that passed there while the
    vehicle was still low and flying its first leg the other way)."""
    explore_altitude_m: PositiveFloat = 12.0
    track_height_m: PositiveFloat = 2.5
    land_speed_mps: PositiveFloat | None = None
    """Descent speed of the landing ramp (m/s); None: the preset's (0.4, and paper 003's 0.1 for
    ``kim_kaist``)."""
    motor_cutoff_range_m: PositiveFloat = 0.03
    land_commit_height_m: PositiveFloat = 0.6
    """Below this height above the pad a lost target no longer aborts the descent (m): the camera sees
    the tag's cross down to about 0.3 m, but a moving pad may leave the view in the last half metre."""
    lost_timeout_s: PositiveFloat = 3.0
    max_go_arounds: Annotated[int, Field(ge=0)] = 3
    time_budget_s: PositiveFloat | None = None
    search_pattern: Literal["spiral", "lawnmower"] = "spiral"
    """Coverage of the search area: an outward square spiral from the take-off point, or paper 000's
    generic waypoint coverage as a lawnmower from the nearest corner."""
    aim_camera: bool = True
    """In take-off and exploration, move the reference upwind so that the body-fixed downward camera, not
    the body, follows it: holding position in a side wind tilts the vehicle and its view moves
    ``h tan(tilt)`` downwind (mission/README.md has the measurements). False flies the body on the
    pattern, as papers 000 and 004 do."""


class PlannerSpec(_Strict):
    """Overrides of the planner block's parameters (``alight blocks`` lists them with their defaults);
    None: the block's default."""

    n_candidates: Annotated[int, Field(ge=1, le=10000)] | None = None
    """Candidates per planning cycle (block default 20)."""
    horizon_min_s: PositiveFloat | None = None
    """Shortest candidate duration (s; block default 1.0)."""
    horizon_max_s: PositiveFloat | None = None
    """Longest candidate duration (s; block default 3.0)."""
    rate_hz: PositiveFloat | None = None
    """Replanning rate, also the mission logic's (Hz; block default 50)."""
    adopt_threshold_m: NonNegFloat | None = None
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
    accel_noise: PositiveFloat | None = None
    """Tangential acceleration noise of the platform model (m/s^2/sqrt(Hz); ``unicycle_ekf`` default 0.1,
    ``kim_ukf`` 0.5)."""
    heading_noise: PositiveFloat | None = None
    """``unicycle_ekf``: heading-rate noise of the constant-heading model (rad/s/sqrt(Hz); default 0.1)."""
    turn_accel_noise: PositiveFloat | None = None
    """``unicycle_ekf``: turn-rate noise of the turn-rate model (rad/s^2/sqrt(Hz); default 0.1)."""


class ControllerSpec(_Strict):
    """Overrides of the controller block's parameters; None: the block's (or the preset's) value."""

    position_bandwidth_rad_s: PositiveFloat | None = None
    """Natural frequency of the position loop, critically damped (rad/s; block default 3.0)."""
    integral_gain: NonNegFloat | None = None
    """Integral gain on the position error per axis (1/s^3), as an autopilot's position loop has; None:
    the preset's (off for ``falanga2017``/``groundtruth``/``kim_kaist``, 2.0 for ``zamanakos_sdu``, which
    flies on PX4's integrating loops). Must be below kp * kv = 2 * bandwidth^3 of the position loop."""
    integral_limit_mps2: PositiveFloat | None = None
    """Largest acceleration the integral may command per axis (m/s^2; block default 6.0)."""
    l1_adaptive: bool | None = None
    """L1 adaptive augmentation of the outer loop (paper 003): true picks the controller ``faessler_l1``,
    false ``faessler``; None: the preset's (on for ``kim_kaist``, off otherwise)."""


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

    rate_hz: PositiveFloat = 30.0
    """Frames processed per second; the others are skipped (the camera's rate bounds it)."""
    image_scale: Annotated[float, Field(gt=0, le=1, allow_inf_nan=False)] = 1.0
    """Resize factor of the image before detection."""
    max_kernel_px: Annotated[int, Field(ge=5)] = 41
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
    gear_half_width_m: NonNegFloat = 0.2
    max_vertical_speed_mps: PositiveFloat = 1.0
    max_horizontal_speed_mps: PositiveFloat = 0.75
    max_tilt_deg: PositiveFloat = 25.0


class Scenario(_Strict):
    """One mission."""

    preset: str = "groundtruth"
    """A packaged preset (``mission/preset_data``): ``groundtruth``, ``falanga2017``, ``kim_kaist``,
    ``zamanakos_sdu``."""
    seed: Annotated[int, Field(ge=0)] = 0
    duration_s: PositiveFloat = 120.0
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
    blocks: BlocksSpec = Field(default_factory=BlocksSpec)
    """The blocks that fly, overriding the preset's (``docs/blocks.md``)."""
    name: str | None = None
    """Free text naming the scenario in reports."""

    @model_validator(mode="after")
    def _known_blocks(self) -> Scenario:
        # late import: the blocks import the algorithms. Refuses an unknown preset or block, a parameter a
        # block rejects and an incompatible pair, before anything flies (ValueError: one line, the key).
        from alight.mission.blocks import resolve_blocks

        resolve_blocks(self)
        return self

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
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"{p}: no such scenario file")
    try:
        data = yaml.safe_load(p.read_text(encoding="utf-8"))
    except (yaml.YAMLError, UnicodeDecodeError) as err:
        line = getattr(getattr(err, "problem_mark", None), "line", None)
        where = f" (line {line + 1})" if line is not None else ""
        raise ConfigError(f"{p}: not valid YAML{where}: {str(err).splitlines()[0]}") from None
    return scenario_from_dict(data, str(p))
