"""Blocks by name: the registry a scenario's ``blocks:`` section and the presets choose from.

Seven stages, each a name from its table in :data:`BLOCKS`:

    camera, pad, detector, geolocator, platform_estimator, controller, planner

Each :class:`BlockSpec` carries, as data:

- ``params``: a frozen dataclass whose fields are the block's parameters with their defaults (the
  algorithm's own config class where it has one, e.g. ``PlatformEkfConfig``), plus ``defaults``: the
  values missions fly where they differ from the algorithm class's library defaults (one place, here;
  the scenario holds only overrides, ``None`` meaning "the block's default");
- ``context``: parameters filled from the scenario when not given (the pad's size, the deck height, ...);
- ``needs`` / ``provides``: what the block requires of the other stages' choices and what it offers them.
  ``needs`` maps ``"<stage>"`` to the block names it works with, or ``"<stage>.<feature>"`` to the
  values of that feature (in the chosen block's ``provides``) it accepts. One function,
  :func:`check_compatibility`, reads them; nothing else decides what goes with what.

A preset (``mission/preset_data/<name>.yaml``) is a named set of choices with parameters; a scenario's
``blocks:`` entries override its preset's. :func:`resolve_blocks` gives the effective choices (preset +
the scenario's per-block sections + ``blocks:``) and refuses, with a ``ValueError`` whose message names
the scenario key, an unknown name, an unknown or rejected parameter, or an incompatible pair.
This module builds configs only; the objects that fly are made in :mod:`alight.mission.presets`.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cache
from importlib import resources
from typing import Any

import yaml

from alight.estimation.kim_ukf import KimUkfConfig
from alight.estimation.platform_ekf import PlatformEkfConfig
from alight.estimation.sdu_kf import SduKfConfig
from alight.perception.color_filter import RedTargetDetectorConfig
from alight.perception.falanga_tag import FalangaDetectorConfig
from alight.perception.flat_earth import FlatEarthGeolocator
from alight.perception.geolocation import DirectGeolocator, PnpGeolocator
from alight.perception.homography_geolocation import HomographyGeolocator
from alight.perception.nfold import NFoldConfig

STAGES = ("camera", "pad", "detector", "geolocator", "platform_estimator", "controller", "planner")
"""The stages a ``blocks:`` section names, in data-flow order."""


# -- parameters of the blocks that have no config class of their own -------------------------------------


@dataclass(frozen=True, kw_only=True)
class PinholeParams:
    """The downward pinhole camera."""

    calibration: str | None = None
    """OpenCV calibration YAML/XML/JSON or ROS ``camera_info`` YAML (``plumb_bob`` or
    ``rational_polynomial``); None: paper 000's mvBlueFOX 752x480 with a 2.4 mm lens."""


@dataclass(frozen=True, kw_only=True)
class FisheyeParams:
    """The downward omnidirectional camera (Scaramuzza model)."""

    calibration: str | None = None
    """OCamCalib ``calib_results.txt``; None: a synthetic lens with the values below."""
    width: int = 640
    """Image width of the synthetic lens (px)."""
    height: int = 480
    """Image height of the synthetic lens (px); the field of view's circle is inscribed."""
    fov_deg: float = 186.0
    """Field of view of the synthetic lens (deg); paper 003 flies a 186 deg fisheye."""

    def __post_init__(self) -> None:
        if self.width < 16 or self.height < 16:
            raise ValueError(f"width and height must be >= 16 px, got {self.width} x {self.height}")
        if not (math.isfinite(self.fov_deg) and 60.0 <= self.fov_deg <= 240.0):
            raise ValueError(f"fov_deg must be in [60, 240], got {self.fov_deg}")


@dataclass(frozen=True, kw_only=True)
class PadParams:
    """A landing-pad design drawn on the platform."""

    size_m: float | None = None
    """Side of the pad (m); None: the scenario's ``platform.pad_size_m``."""

    def __post_init__(self) -> None:
        if self.size_m is not None and not (math.isfinite(self.size_m) and self.size_m > 0):
            raise ValueError(f"size_m must be finite and > 0, got {self.size_m}")


@dataclass(frozen=True, kw_only=True)
class ArucoParams:
    """OpenCV's ArUco detector on AprilTag 36h11 markers."""

    full_quality_side_px: float = 20.0
    """Marker side (px) from which an observation gets quality 1."""
    subpixel_corners: bool = True
    """Refine the corners to sub-pixel: halves the PnP error on rendered frames."""

    def __post_init__(self) -> None:
        if not self.full_quality_side_px > 0:
            raise ValueError(f"full_quality_side_px must be > 0, got {self.full_quality_side_px}")


@dataclass(frozen=True, kw_only=True)
class SduParams:
    """Paper 004's landing marker: the n-fold marker and three ArUco landmarks."""

    nfold_sigma_px: float = 0.3
    """Standard deviation of the n-fold centre (px)."""
    aruco_corner_sigma_px: float = 0.25
    """Standard deviation of an ArUco corner (px)."""
    gate_frac: float = 0.1
    gate_min_px: float = 3.0
    full_quality_side_px: float = 20.0
    qos: bool = False
    """Run the detector at the quality-of-service settings of the scenario's ``energy:`` section and count
    its compute energy (paper 004's Jetson Nano)."""

    def __post_init__(self) -> None:
        for name in ("nfold_sigma_px", "aruco_corner_sigma_px", "gate_frac", "gate_min_px"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be finite and > 0, got {v}")


@dataclass(frozen=True, kw_only=True)
class GroundTruthParams:
    """The ground-truth perception sensor (its rate, noise, latency and field of view are the scenario's
    ``perception:`` section)."""


@dataclass(frozen=True, kw_only=True)
class ControllerParams:
    """Paper 000's high-level controller (Faessler et al.), critically damped position loop."""

    position_bandwidth_rad_s: float = 3.0
    """Natural frequency of the position loop, critically damped (rad/s)."""
    integral_gain: float = 0.0
    """Integral gain on the position error per axis (1/s^3), as an autopilot's position loop has. Must be
    below kp * kv = 2 * bandwidth^3."""
    integral_limit_mps2: float = 6.0
    """Largest acceleration the integral may command per axis (m/s^2)."""

    def __post_init__(self) -> None:
        bw, ki = self.position_bandwidth_rad_s, self.integral_gain
        if not (math.isfinite(bw) and bw > 0):
            raise ValueError(f"position_bandwidth_rad_s must be finite and > 0, got {bw}")
        if not (math.isfinite(self.integral_limit_mps2) and self.integral_limit_mps2 > 0):
            raise ValueError(f"integral_limit_mps2 must be finite and > 0, got {self.integral_limit_mps2}")
        # Routh-Hurwitz of s^3 + kv s^2 + kp s + ki with kp = bw^2, kv = 2 bw (the controller's own check)
        if not (math.isfinite(ki) and 0.0 <= ki < 2.0 * bw**3):
            raise ValueError(
                f"integral_gain must satisfy 0 <= integral_gain < 2 * position_bandwidth_rad_s^3 = "
                f"{2.0 * bw**3:.3g} (a stable loop), got {ki}"
            )


@dataclass(frozen=True, kw_only=True)
class PlannerParams:
    """Paper 000's planner: minimum-jerk candidates to predicted platform states, the cheapest feasible."""

    n_candidates: int = 20
    horizon_min_s: float = 1.0
    horizon_max_s: float = 3.0
    rate_hz: float = 50.0
    """Replanning rate (Hz); the mission logic runs at the same rate."""
    adopt_threshold_m: float = 0.2
    end_acceleration: str = "platform"
    """Final acceleration of each candidate: ``free`` as in paper 000, or ``platform``, the platform's
    predicted acceleration (removes the lag of free-end plans behind a platform on a curve)."""

    def __post_init__(self) -> None:
        if not 1 <= self.n_candidates <= 10000:
            raise ValueError(f"n_candidates must be in [1, 10000], got {self.n_candidates}")
        for name in ("horizon_min_s", "horizon_max_s", "rate_hz"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be finite and > 0, got {v}")
        if self.horizon_max_s < self.horizon_min_s:
            raise ValueError("horizon_max_s must be >= horizon_min_s")
        if not (math.isfinite(self.adopt_threshold_m) and self.adopt_threshold_m >= 0):
            raise ValueError(f"adopt_threshold_m must be finite and >= 0, got {self.adopt_threshold_m}")
        if self.end_acceleration not in ("free", "platform"):
            raise ValueError(f"end_acceleration must be 'free' or 'platform', got {self.end_acceleration!r}")


def _signature_params(cls: type, skip: tuple[str, ...], doc: str) -> type:
    """A frozen dataclass of a constructor's keyword parameters (after ``skip``), with its defaults: the
    block's parameters are its constructor's, listed once."""
    fields_: list[tuple[str, Any, Any]] = []
    for p in inspect.signature(cls).parameters.values():
        if p.name in skip or p.name == "self" or p.default is inspect.Parameter.empty:
            continue
        fields_.append((p.name, Any, field(default=p.default)))
    made = dataclasses.make_dataclass(f"{cls.__name__}Params", fields_, frozen=True, kw_only=True)
    made.__doc__ = doc
    return made


PnpParams = _signature_params(
    PnpGeolocator, ("camera", "mount"), "PnP on the observation's pad points, then the ego pose at capture."
)
FlatEarthParams = _signature_params(
    FlatEarthGeolocator, ("camera", "mount"), "The pixel's ray intersected with the deck's plane (paper 003)."
)
HomographyParams = _signature_params(
    HomographyGeolocator,
    ("camera", "mount", "landmark_offsets", "fov_rad"),
    "Pixel to ground through the homography of the camera's view at the altitude (paper 004).",
)
DirectParams = _signature_params(
    DirectGeolocator, ("mount",), "Observations that carry the pad's position in C already (ground truth)."
)


# -- the registry ----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BlockSpec:
    """One block as the registry declares it (module docstring)."""

    stage: str
    name: str
    summary: str
    params: type
    """Frozen dataclass of the parameters; its field defaults are the library defaults."""
    defaults: Mapping[str, Any] = field(default_factory=dict)
    """Defaults that missions fly where they differ from ``params``' own (the block's defaults)."""
    context: Mapping[str, str] = field(default_factory=dict)
    """Parameter -> where its value comes from when not given (a scenario key or another block)."""
    needs: Mapping[str, tuple[Any, ...]] = field(default_factory=dict)
    provides: Mapping[str, Any] = field(default_factory=dict)
    hidden: tuple[str, ...] = ()
    """Fields of ``params`` that are not block parameters (objects the builder passes)."""

    def parameters(self) -> list[tuple[str, Any, str]]:
        """(name, default, docstring) of every parameter, the block's defaults applied."""
        docs = _field_docs(self.params)
        out = []
        for f in dataclasses.fields(self.params):
            if f.name in self.hidden or not f.init:
                continue
            if f.name in self.defaults:
                default: Any = self.defaults[f.name]
            elif f.default is not dataclasses.MISSING:
                default = f.default
            elif f.default_factory is not dataclasses.MISSING:
                default = f.default_factory()
            else:
                default = None
            out.append((f.name, default, docs.get(f.name, "")))
        return out


@cache  # reading and parsing the source costs ~50 ms a class; the scenario validation asks often
def _field_docs(cls: type) -> dict[str, str]:
    """The docstrings under a dataclass's fields (the attribute-docstring convention of this codebase)."""
    import ast
    import textwrap

    try:
        src = textwrap.dedent(inspect.getsource(cls))
    except (OSError, TypeError):
        return {}
    tree = ast.parse(src)
    out: dict[str, str] = {}
    body = tree.body[0].body if tree.body and isinstance(tree.body[0], ast.ClassDef) else []
    for a, b in zip(body, body[1:], strict=False):
        if (
            isinstance(a, ast.AnnAssign)
            and isinstance(a.target, ast.Name)
            and isinstance(b, ast.Expr)
            and isinstance(b.value, ast.Constant)
            and isinstance(b.value.value, str)
        ):
            out[a.target.id] = " ".join(b.value.value.split())
    return out


_PAD_SIZE = {"size_m": "platform.pad_size_m"}
MANEUVER_ACCEL_NOISE = 2.0
"""The unicycle EKF's process noise while the platform brakes or accelerates (m/s^2/sqrt(Hz)): a road
vehicle brakes at up to 8 m/s^2 and accelerates at up to 4 (``platform.speed_profile``'s limits); with the
fixed 0.1 the speed estimate lagged a 6 m/s^2 stop by a second and the vehicle landed beside the pad."""

BLOCKS: dict[str, dict[str, BlockSpec]] = {
    "camera": {
        "pinhole": BlockSpec(
            "camera",
            "pinhole",
            "pinhole camera with radial-tangential distortion (OpenCV); 752x480 by default",
            PinholeParams,
            context={"calibration": "camera.calibration"},
            provides={"model": "pinhole"},
        ),
        "fisheye": BlockSpec(
            "camera",
            "fisheye",
            "omnidirectional camera, Scaramuzza's model (OCamCalib); a 186 deg 640x480 lens by default",
            FisheyeParams,
            context={"calibration": "camera.calibration"},
            provides={"model": "omni"},
        ),
    },
    "pad": {
        "falanga_tag": BlockSpec(
            "pad",
            "falanga_tag",
            "paper 000's cross in a ring",
            PadParams,
            context=_PAD_SIZE,
            provides={"yaw_fold": 4},
        ),
        "apriltag": BlockSpec(
            "pad", "apriltag", "AprilTag 36h11 markers in a known layout", PadParams, context=_PAD_SIZE
        ),
        "sdu_marker": BlockSpec(
            "pad",
            "sdu_marker",
            "paper 004's n-fold marker and three ArUco landmarks",
            PadParams,
            context=_PAD_SIZE,
        ),
        "red_target": BlockSpec(
            "pad", "red_target", "paper 003's red disc (a colour target)", PadParams, context=_PAD_SIZE
        ),
    },
    "detector": {
        "falanga": BlockSpec(
            "detector",
            "falanga",
            "paper 000's tag detector (Alg. 1): the ring's ellipse and the cross's corners",
            FalangaDetectorConfig,
            needs={"pad": ("falanga_tag",)},
            provides={"observation": ("pad_points", "pixel"), "image": True},
        ),
        "aruco": BlockSpec(
            "detector",
            "aruco",
            "the AprilTag pad's markers via OpenCV's ArUco module, merged into one observation",
            ArucoParams,
            needs={"pad": ("apriltag",)},
            provides={"observation": ("pad_points", "pixel"), "image": True},
        ),
        "apriltag": BlockSpec(
            "detector",
            "apriltag",
            "every AprilTag 36h11 marker, no pad layout (each marker's own corners)",
            ArucoParams,
            defaults={"subpixel_corners": False},
            needs={"pad": ("apriltag",)},
            provides={"observation": ("pixel",), "image": True},
        ),
        "nfold": BlockSpec(
            "detector",
            "nfold",
            "paper 004's n-fold marker alone (adaptive kernel size)",
            NFoldConfig,
            context={"order": "pad sdu_marker", "oriented": "pad sdu_marker"},
            needs={"pad": ("sdu_marker",)},
            provides={"observation": ("pixel",), "image": True},
        ),
        "sdu": BlockSpec(
            "detector",
            "sdu",
            "paper 004's landing marker: the n-fold marker and three ArUco landmarks",
            SduParams,
            needs={"pad": ("sdu_marker",)},
            provides={"observation": ("pixel",), "image": True},
        ),
        "red": BlockSpec(
            "detector",
            "red",
            "paper 003's colour filter (Alg. 1-2): the biggest red contour",
            RedTargetDetectorConfig,
            context={"mitigation": "perception.mitigation"},
            needs={"pad": ("red_target",), "camera.color": (True,)},
            provides={"observation": ("pixel",), "image": True},
        ),
        "groundtruth": BlockSpec(
            "detector",
            "groundtruth",
            "the simulator's ground-truth perception sensor (no image; the 'perfect perception' ablation)",
            GroundTruthParams,
            provides={"observation": ("relative_position",), "image": False},
        ),
    },
    "geolocator": {
        "pnp": BlockSpec(
            "geolocator",
            "pnp",
            "PnP on the pad's points, with the ego pose at the capture time (paper 000)",
            PnpParams,
            needs={"camera.model": ("pinhole",), "detector.observation": ("pad_points",)},
        ),
        "flat_earth": BlockSpec(
            "geolocator",
            "flat_earth",
            "the pixel's ray intersected with the deck's plane (paper 003, eq. 5-9)",
            FlatEarthParams,
            defaults={"deck_height_m": None},
            context={"deck_height_m": "platform.pad_height_m"},
            needs={"detector.observation": ("pixel",)},
        ),
        "homography": BlockSpec(
            "geolocator",
            "homography",
            "pixel to ground by the homography of the camera's view at the altitude (paper 004, Sec. IV-A)",
            HomographyParams,
            defaults={"plane_z_W": None},
            context={"plane_z_W": "platform.pad_height_m"},
            needs={"camera.model": ("pinhole",), "detector.observation": ("pixel",)},
        ),
        "direct": BlockSpec(
            "geolocator",
            "direct",
            "observations that carry the pad's position in C (the ground-truth sensor)",
            DirectParams,
            needs={"detector.observation": ("relative_position",)},
        ),
    },
    "platform_estimator": {
        "unicycle_ekf": BlockSpec(
            "platform_estimator",
            "unicycle_ekf",
            "paper 000's unicycle EKF, with a turn-rate state (ours) unless use_turn_rate is false",
            PlatformEkfConfig,
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
        "kim_ukf": BlockSpec(
            "platform_estimator",
            "kim_ukf",
            "paper 003's UKF on the target's pixel through the camera model (eq. 10-27)",
            KimUkfConfig,
            context={
                "deck_height": "platform.pad_height_m",
                "confirm_updates": "perception.mitigation (0 for none, else 5)",
                "measurement_model": "camera (quartic for fisheye, the model's project otherwise)",
            },
            defaults={"deck_height": None, "confirm_updates": None, "measurement_model": None},
            needs={"detector.image": (True,)},
        ),
        "sdu_kf": BlockSpec(
            "platform_estimator",
            "sdu_kf",
            "paper 004's Kalman filter on the relative position, delay compensated, with the velocity "
            "estimator",
            SduKfConfig,
            context={"velocity": "pad (n-fold order as the yaw fold, measured yaw increments)"},
            defaults={"velocity": None},
        ),
    },
    "controller": {
        "faessler": BlockSpec(
            "controller", "faessler", "paper 000's high-level controller (Faessler et al.)", ControllerParams
        ),
        "faessler_l1": BlockSpec(
            "controller",
            "faessler_l1",
            "the Faessler controller with paper 003's L1 adaptive augmentation of the outer loop",
            ControllerParams,
        ),
    },
    "planner": {
        "min_jerk_candidates": BlockSpec(
            "planner",
            "min_jerk_candidates",
            "paper 000's minimum-jerk candidates to predicted platform states (Sec. II-D)",
            PlannerParams,
        ),
    },
}
"""Every block by stage and name."""

# Scenario sections whose keys are parameters of one stage's block (the sections predate ``blocks:``;
# they stay as its shorthand). ``controller.l1_adaptive`` picks the controller instead (below).
SECTION_STAGE = {"planner": "planner", "estimator": "platform_estimator", "controller": "controller"}


# -- presets as data -------------------------------------------------------------------------------------


@cache
def preset_names() -> tuple[str, ...]:
    files = resources.files("alight.mission").joinpath("preset_data")
    return tuple(sorted(p.name[:-5] for p in files.iterdir() if p.name.endswith(".yaml")))


@cache
def preset_data(name: str) -> Mapping[str, Any]:
    """The preset's YAML (``mission/preset_data/<name>.yaml``): ``description``, ``blocks`` and the
    preset's ``mission`` defaults."""
    if name not in preset_names():
        raise ValueError(f"preset: unknown preset '{name}', expected one of {list(preset_names())}")
    text = resources.files("alight.mission").joinpath("preset_data", f"{name}.yaml").read_text("utf-8")
    data = yaml.safe_load(text)
    return data  # type: ignore[no-any-return]


# -- resolution ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Block:
    """One effective choice: the block and its parameters (all of them, defaults applied)."""

    stage: str
    name: str
    params: Any
    """An instance of the block's ``params`` dataclass."""
    given: Mapping[str, Any]
    """The parameters set by the preset or the scenario (the rest are defaults or context)."""

    @property
    def spec(self) -> BlockSpec:
        return BLOCKS[self.stage][self.name]

    def as_dict(self) -> dict[str, Any]:
        hidden = set(self.spec.hidden)
        return {
            "name": self.name,
            **{
                f.name: _plain(getattr(self.params, f.name))
                for f in dataclasses.fields(self.params)
                if f.init and f.name not in hidden
            },
        }


def _plain(v: Any) -> Any:
    if dataclasses.is_dataclass(v) and not isinstance(v, type):
        return {f.name: _plain(getattr(v, f.name)) for f in dataclasses.fields(v)}
    if isinstance(v, tuple | list):
        return [_plain(x) for x in v]
    if hasattr(v, "value") and isinstance(getattr(v, "value", None), str | int):  # enums
        return v.value
    return v


def parse_entry(entry: Any, where: str) -> tuple[str | None, dict[str, Any]]:
    """A ``blocks:`` entry: a name, or ``{name: ..., <parameters>}`` (``name`` may be left out to set
    the preset's block's parameters)."""
    if isinstance(entry, str):
        return entry, {}
    if isinstance(entry, Mapping):
        params = dict(entry)
        name = params.pop("name", None)
        if name is not None and not isinstance(name, str):
            raise ValueError(f"{where}.name: a block name must be a string, got {name!r}")
        return name, params
    raise ValueError(f"{where}: expected a block name or {{name: ..., <parameters>}}, got {entry!r}")


def _check_type(value: Any, default: Any, where: str) -> None:
    """Reject a value of the wrong kind for a scalar parameter (a YAML typo: a string for a number)."""
    if default is None or value is None:
        return
    if isinstance(default, bool):
        ok = isinstance(value, bool)
        kind = "true or false"
    elif isinstance(default, int | float) and not isinstance(default, bool):
        ok = isinstance(value, int | float) and not isinstance(value, bool)
        if ok and isinstance(default, int) and not isinstance(value, int) and float(value).is_integer():
            ok = True
        kind = "a number"
        if ok and not math.isfinite(float(value)):
            raise ValueError(f"{where}: must be finite, got {value!r}")
    elif isinstance(default, str):
        ok, kind = isinstance(value, str), "a string"
    else:
        return
    if not ok:
        raise ValueError(f"{where}: expected {kind}, got {value!r}")


def make_params(spec: BlockSpec, given: Mapping[str, Any], context: Mapping[str, Any], where: str) -> Any:
    """The block's parameter dataclass from its defaults, the scenario's context and ``given``."""
    known = {f.name: f for f in dataclasses.fields(spec.params) if f.init and f.name not in spec.hidden}
    for key in given:
        if key not in known:
            raise ValueError(
                f"{where}.{key}: unknown parameter of {spec.stage} '{spec.name}' (known: {', '.join(known)})"
            )
    defaults = {name: d for name, d, _ in spec.parameters()}
    kw: dict[str, Any] = {k: v for k, v in spec.defaults.items() if k in known}
    for k, v in context.items():
        if k in known and kw.get(k) is None:
            kw[k] = v
    for key, value in given.items():
        f = known[key]
        sub = f.type if isinstance(f.type, type) else None
        default = defaults.get(key)
        if dataclasses.is_dataclass(default) and isinstance(value, Mapping):
            try:
                value = dataclasses.replace(default, **value)  # type: ignore[type-var]
            except TypeError as err:
                raise ValueError(f"{where}.{key}: {err}") from None
            except ValueError as err:
                raise ValueError(f"{where}.{key}: {err}") from None
        elif sub is not None and dataclasses.is_dataclass(sub) and isinstance(value, Mapping):
            value = sub(**value)
        else:
            _check_type(value, default, f"{where}.{key}")
        kw[key] = value
    kw = {k: v for k, v in kw.items() if not (v is None and k in spec.defaults and k not in given)}
    try:
        return spec.params(**kw)
    except (ValueError, TypeError) as err:
        raise ValueError(f"{where}: {spec.stage} '{spec.name}' rejects its parameters: {err}") from None


@dataclass(frozen=True)
class EffectiveBlocks:
    """The blocks a scenario flies, after its preset and its overrides."""

    preset: str
    blocks: Mapping[str, Block]
    mission: Mapping[str, Any]
    """The preset's mission defaults (``land_speed_mps``, ``coverage_fov_deg``)."""
    camera_model: Any = None
    """The loaded camera model (vision blocks), or None."""
    color: bool = False
    """Render colour images (a detector that needs colour, or the scenario's ``camera.color``)."""

    def __getitem__(self, stage: str) -> Block:
        return self.blocks[stage]

    def as_dict(self) -> dict[str, Any]:
        return {stage: self.blocks[stage].as_dict() for stage in STAGES}


@cache
def _synthetic_fisheye(width: int, height: int, fov_deg: float) -> Any:
    """A synthetic lens for validation (~70 ms to fit; the flight builds its own)."""
    from alight.cameras.omni import OmniCamera

    return OmniCamera.synthetic(width, height, fov_deg=fov_deg)


def _load_camera_model(name: str, params: Any, where: str, *, fresh: bool = True) -> Any:
    from alight.cameras import load_camera
    from alight.cameras.omni import OmniCamera
    from alight.cameras.pinhole import PinholeCamera
    from alight.errors import AlightError

    if params.calibration is None:
        if name == "pinhole":
            return PinholeCamera.default_downward()
        if not fresh:
            return _synthetic_fisheye(params.width, params.height, params.fov_deg)
        return OmniCamera.synthetic(params.width, params.height, fov_deg=params.fov_deg)
    try:
        cam = load_camera(params.calibration)
    except AlightError as err:
        raise ValueError(f"{where}.calibration: {err}") from None
    want = PinholeCamera if name == "pinhole" else OmniCamera
    if not isinstance(cam, want):
        other = "fisheye" if name == "pinhole" else "pinhole"
        raise ValueError(
            f"{where}.calibration: {params.calibration} is a {type(cam).__name__} calibration, not a "
            f"{name} one (use camera: {other})"
        )
    return cam


def _context(stage: str, name: str, scenario: Any, chosen: Mapping[str, Block]) -> dict[str, Any]:
    """Parameters a block takes from the scenario (or an upstream block) when not given."""
    if stage == "camera":
        return {"calibration": scenario.camera.calibration}
    if stage == "pad":
        return {"size_m": scenario.platform.pad_size_m}
    if stage == "detector" and name == "red":
        return {"mitigation": scenario.perception.mitigation}
    if stage == "detector" and name == "nfold":
        from alight.pads.sdu_pad import SduPad

        pad = SduPad.default(scenario.platform.pad_size_m)
        return {"order": pad.nfold_order, "oriented": pad.nfold_oriented}
    if stage == "geolocator" and name == "flat_earth":
        return {"deck_height_m": scenario.platform.pad_height_m}
    if stage == "geolocator" and name == "homography":
        return {"plane_z_W": scenario.platform.pad_height_m}
    if stage == "platform_estimator" and name == "kim_ukf":
        cam = chosen.get("camera")
        return {
            "deck_height": scenario.platform.pad_height_m,
            "confirm_updates": 0 if scenario.perception.mitigation == "none" else 5,
            "measurement_model": "quartic" if cam is not None and cam.name == "fisheye" else "camera",
        }
    if stage == "platform_estimator" and name == "sdu_kf":
        from alight.estimation.platform_velocity import PlatformVelocityConfig

        pad_block = chosen.get("pad")
        fold = 1
        if pad_block is not None and pad_block.name == "sdu_marker":
            from alight.pads.sdu_pad import SduPad

            fold = SduPad.default(scenario.platform.pad_size_m).nfold_order
        elif pad_block is not None:
            fold = int(pad_block.spec.provides.get("yaw_fold", 1))
        return {"velocity": PlatformVelocityConfig(measured_yaw_increments=True, yaw_fold=fold)}
    return {}


def resolve_blocks(scenario: Any, *, load_camera: bool = True, fresh_camera: bool = False) -> EffectiveBlocks:
    """The effective blocks of ``scenario`` (preset, then the per-block sections, then ``blocks:``).

    Raises ``ValueError`` with one line naming the scenario key for an unknown name, an unknown or
    rejected parameter, or an incompatible pair of blocks."""
    preset = preset_data(scenario.preset)
    pblocks = preset.get("blocks", {})
    names: dict[str, str] = {}
    preset_given: dict[str, dict[str, Any]] = {}
    for stage in STAGES:
        name, params = parse_entry(pblocks[stage], f"preset {scenario.preset}: blocks.{stage}")
        if name is None:
            raise ValueError(f"preset {scenario.preset}: blocks.{stage}: no block name")
        names[stage], preset_given[stage] = name, params
    preset_names_ = dict(names)
    source = {stage: f"blocks.{stage} (preset {scenario.preset})" for stage in STAGES}
    # the per-block sections: parameters of the stage's block, whichever block that is
    section_params: dict[str, dict[str, Any]] = {}
    for section, stage in SECTION_STAGE.items():
        spec_obj = getattr(scenario, section, None)
        if spec_obj is None:
            continue
        values = {k: v for k, v in spec_obj.model_dump().items() if v is not None}
        if section == "controller" and "l1_adaptive" in values:
            names["controller"] = "faessler_l1" if values.pop("l1_adaptive") else "faessler"
        section_params[stage] = {f"{section}.{k}": v for k, v in values.items()}
    blocks_given: dict[str, dict[str, Any]] = {stage: {} for stage in STAGES}
    bl = getattr(scenario, "blocks", None)
    for stage in STAGES:
        entry = None if bl is None else getattr(bl, stage, None)
        if entry is None:
            continue
        name, params = parse_entry(entry, f"blocks.{stage}")
        if name is not None:
            names[stage] = name
        blocks_given[stage] = params
        source[stage] = f"blocks.{stage}"

    chosen: dict[str, Block] = {}
    camera_model = None
    for stage in STAGES:
        name = names[stage]
        table = BLOCKS[stage]
        if name not in table:
            raise ValueError(f"{source[stage]}: unknown {stage} '{name}', expected one of {list(table)}")
        spec = table[name]
        # the preset's parameters belong to the preset's block: another block starts from its defaults
        params = dict(preset_given[stage]) if name == preset_names_[stage] else {}
        known = {p for p, _, _ in spec.parameters()}
        for dotted, value in section_params.get(stage, {}).items():
            key = dotted.split(".", 1)[1]
            if key not in known:
                raise ValueError(
                    f"{dotted}: not a parameter of {stage} '{name}' ({source[stage]}); "
                    f"its parameters: {', '.join(sorted(known))}"
                )
            params[key] = value
        params.update(blocks_given[stage])
        where = source[stage].split(" (preset")[0]
        if section_params.get(stage) and not blocks_given[stage] and source[stage] != f"blocks.{stage}":
            where = next(iter(section_params[stage])).split(".")[0]  # the section the user wrote
        ctx = _context(stage, name, scenario, chosen)
        block = Block(stage, name, make_params(spec, params, ctx, where), params)
        chosen[stage] = block
        if stage == "camera" and load_camera:
            camera_model = _load_camera_model(name, block.params, where, fresh=fresh_camera)
    color_needed = any(b.spec.needs.get("camera.color") == (True,) for b in chosen.values())
    color = color_needed if scenario.camera.color is None else bool(scenario.camera.color)
    check_compatibility(chosen, source, color=color)
    if load_camera:
        # a geolocator validates its parameters in its constructor (cheap): run it now, not in flight
        from alight.cameras.pinhole import CameraMount

        g = chosen["geolocator"]
        where = source["geolocator"].split(" (preset")[0]
        try:
            build_geolocator(g, camera_model, CameraMount.downward())
        except (ValueError, TypeError) as err:
            raise ValueError(f"{where}: geolocator '{g.name}' rejects its parameters: {err}") from None
    return EffectiveBlocks(scenario.preset, chosen, dict(preset.get("mission", {})), camera_model, color)


def build_geolocator(block: Block, camera: Any, mount: Any) -> Any:
    """The geolocator of ``block`` (stage ``geolocator``) for a camera model and mount."""
    kw = {f.name: getattr(block.params, f.name) for f in dataclasses.fields(block.params)}
    if block.name == "pnp":
        return PnpGeolocator(camera, mount, **kw)
    if block.name == "flat_earth":
        return FlatEarthGeolocator(camera, mount, **kw)
    if block.name == "homography":
        return HomographyGeolocator(camera, mount, **kw)
    return DirectGeolocator(mount, **kw)


def check_compatibility(chosen: Mapping[str, Block], source: Mapping[str, str], *, color: bool) -> None:
    """Every block's ``needs`` against the other choices' names and ``provides``; the first mismatch
    raises ``ValueError`` naming the key of the block whose need is not met."""
    uses_image = bool(chosen["detector"].spec.provides.get("image", True))
    for stage in STAGES:
        block = chosen[stage]
        for need, allowed in block.spec.needs.items():
            other_stage, _, feature = need.partition(".")
            other = chosen[other_stage]
            if not feature:
                ok = other.name in allowed
                what = f"{other_stage} '{other.name}'"
                want = f"{other_stage} {' or '.join(map(str, allowed))}"
            elif other_stage == "camera" and feature == "color":
                if not uses_image:
                    continue
                ok = color
                what = "a grey camera (camera.color: false)"
                want = "a colour camera"
            else:
                offered = other.spec.provides.get(feature)
                offered_t = offered if isinstance(offered, tuple) else (offered,)
                ok = any(v in allowed for v in offered_t)
                what = f"{other_stage} '{other.name}' (gives {feature} {'/'.join(map(str, offered_t))})"
                want = f"{other_stage} {feature} {' or '.join(map(str, allowed))}"
            if not ok:
                where = source[stage].split(" (preset")[0]
                raise ValueError(
                    f"{where}: {stage} '{block.name}' needs {want}, not {what} ({source[other_stage]})"
                )


def describe_blocks() -> str:
    """The text of ``alight blocks``: every block with its parameters and what it works with."""
    lines: list[str] = []
    for stage in STAGES:
        lines.append(f"{stage}:")
        for name, spec in BLOCKS[stage].items():
            lines.append(f"  {name}: {spec.summary}")
            if spec.needs:
                needs = "; ".join(f"{k} in {list(v)}" for k, v in spec.needs.items())
                lines.append(f"    works with: {needs}")
            if spec.provides:
                lines.append(f"    provides: {', '.join(f'{k}={v}' for k, v in spec.provides.items())}")
            for pname, default, doc in spec.parameters():
                ctx = spec.context.get(pname)
                shown = f"from {ctx}" if ctx is not None and default is None else repr(_plain(default))
                lines.append(f"    {pname} = {shown}" + (f"  # {doc}" if doc else ""))
    lines.append("presets: " + ", ".join(preset_names()))
    return "\n".join(lines)


def compatible_pairs() -> list[tuple[str, str, str, str]]:
    """Every pair of blocks whose ``needs`` name a stage: (stage, name, other stage, other name)."""
    out = []
    for stage in STAGES:
        for spec in BLOCKS[stage].values():
            for need, allowed in spec.needs.items():
                other_stage, _, feature = need.partition(".")
                if other_stage not in BLOCKS:
                    continue
                for other in BLOCKS[other_stage].values():
                    if feature:
                        v = other.provides.get(feature)
                        vt = v if isinstance(v, tuple) else (v,)
                        if not any(x in allowed for x in vt):
                            continue
                    elif other.name not in allowed:
                        continue
                    out.append((stage, spec.name, other_stage, other.name))
    return out
