"""The perception stages' registries: :data:`DETECTORS` and :data:`GEOLOCATORS`, the blocks a scenario's
``blocks.detector`` and ``blocks.geolocator`` name, with their parameters and factories
(:class:`alight.blockspec.BlockSpec`). ``alight detect`` runs the detectors of this table too."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeVar

from alight.blockspec import BlockSpec, ResolveContext, param_kwargs, signature_params
from alight.cameras import CameraModel, MountedCamera, PinholeCamera
from alight.energy.qos import DEFAULT_PHASE_POLICY, PhasePolicy
from alight.errors import ConfigError
from alight.pads import AprilTagPad, FalangaTag, PadDesign, SduPad
from alight.perception.aruco import ArucoPadDetector
from alight.perception.color_filter import RedTargetDetector, RedTargetDetectorConfig
from alight.perception.falanga_tag import FalangaDetectorConfig, FalangaTagDetector
from alight.perception.flat_earth import FlatEarthGeolocator
from alight.perception.geolocation import DirectGeolocator, PnpGeolocator
from alight.perception.homography_geolocation import HomographyGeolocator
from alight.perception.nfold import NFoldConfig, NFoldDetector
from alight.perception.qos_detector import QosDetector
from alight.perception.sdu_marker import SduMarkerDetector

if TYPE_CHECKING:
    from alight.perception import Detector, Geolocator

PadT = TypeVar("PadT")


# -- parameters of the detectors that have no config class of their own --------------------------------


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
        for name, v in (
            ("nfold_sigma_px", self.nfold_sigma_px),
            ("aruco_corner_sigma_px", self.aruco_corner_sigma_px),
            ("gate_frac", self.gate_frac),
            ("gate_min_px", self.gate_min_px),
        ):
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be finite and > 0, got {v}")


@dataclass(frozen=True, kw_only=True)
class GroundTruthParams:
    """The ground-truth perception sensor (its rate, noise, latency and field of view are the scenario's
    ``perception:`` section)."""


PnpParams = signature_params(
    PnpGeolocator, ("camera", "mount"), "PnP on the observation's pad points, then the ego pose at capture."
)
FlatEarthParams = signature_params(
    FlatEarthGeolocator, ("camera", "mount"), "The pixel's ray intersected with the deck's plane (paper 003)."
)
HomographyParams = signature_params(
    HomographyGeolocator,
    ("camera", "mount", "landmark_offsets", "fov_rad"),
    "Pixel to ground through the homography of the camera's view at the altitude (paper 004).",
)
DirectParams = signature_params(
    DirectGeolocator, ("mount",), "Observations that carry the pad's position in C already (ground truth)."
)


# -- the detectors ---------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class DetectorContext:
    """The detector stage's build context."""

    pad: PadDesign | None
    """The pad drawn on the platform (the pad stage's block)."""
    camera: CameraModel | None = None
    """The camera model the images are rendered through."""
    qos_policy: PhasePolicy = DEFAULT_PHASE_POLICY
    """The quality-of-service policy of the scenario's ``energy:`` section (a detector with ``qos``)."""


def _pad_as(ctx: DetectorContext, cls: type[PadT]) -> PadT:
    """The context's pad as the design the detector reads (the registry's ``needs`` guarantee it)."""
    if not isinstance(ctx.pad, cls):
        raise ConfigError(f"the detector needs a {cls.__name__} pad, got {type(ctx.pad).__name__}")
    return ctx.pad


def _falanga(p: FalangaDetectorConfig, ctx: DetectorContext) -> Detector:
    return FalangaTagDetector(_pad_as(ctx, FalangaTag), p)


def _aruco(p: ArucoParams, ctx: DetectorContext) -> Detector:
    return ArucoPadDetector(_pad_as(ctx, AprilTagPad), **param_kwargs(p))


def _apriltag(p: ArucoParams, ctx: DetectorContext) -> Detector:
    return ArucoPadDetector(None, **param_kwargs(p))


def _nfold(p: NFoldConfig, ctx: DetectorContext) -> Detector:
    return NFoldDetector(p, tip_P=_pad_as(ctx, SduPad).nfold_center_P)


def _sdu(p: SduParams, ctx: DetectorContext) -> Detector:
    kw = param_kwargs(p)
    qos = kw.pop("qos")
    inner = SduMarkerDetector(_pad_as(ctx, SduPad), camera=ctx.camera, **kw)
    return QosDetector(inner, ctx.qos_policy) if qos else inner


def _red(p: RedTargetDetectorConfig, ctx: DetectorContext) -> Detector:
    return RedTargetDetector(p)


def _groundtruth(p: GroundTruthParams, ctx: DetectorContext) -> Detector | None:
    return None  # the simulator's perception sensor gives the observations; no image is read


def _nfold_of_pad(ctx: ResolveContext) -> dict[str, Any]:
    pad = SduPad.default(ctx.pad_size_m)
    return {"order": pad.nfold_order, "oriented": pad.nfold_oriented}


def _mitigation(ctx: ResolveContext) -> dict[str, Any]:
    return {"mitigation": ctx.mitigation}


DetectorSpec = BlockSpec[DetectorContext, "Detector | None"]
"""A detector block: parameters and a :class:`DetectorContext` -> a detector (None: no image)."""

_IMAGE_PAD_POINTS = {"observation": ("pad_points", "pixel"), "image": True}
_IMAGE_PIXEL = {"observation": ("pixel",), "image": True}

DETECTORS: dict[str, DetectorSpec] = {
    "falanga": BlockSpec(
        "detector",
        "falanga",
        "paper 000's tag detector (Alg. 1): the ring's ellipse and the cross's corners",
        FalangaDetectorConfig,
        build=_falanga,
        needs={"pad": ("falanga_tag",)},
        provides=_IMAGE_PAD_POINTS,
    ),
    "aruco": BlockSpec(
        "detector",
        "aruco",
        "the AprilTag pad's markers via OpenCV's ArUco module, merged into one observation",
        ArucoParams,
        build=_aruco,
        needs={"pad": ("apriltag",)},
        provides=_IMAGE_PAD_POINTS,
    ),
    "apriltag": BlockSpec(
        "detector",
        "apriltag",
        "every AprilTag 36h11 marker, no pad layout (each marker's own corners)",
        ArucoParams,
        build=_apriltag,
        defaults={"subpixel_corners": False},
        needs={"pad": ("apriltag",)},
        provides=_IMAGE_PIXEL,
    ),
    "nfold": BlockSpec(
        "detector",
        "nfold",
        "paper 004's n-fold marker alone (adaptive kernel size)",
        NFoldConfig,
        build=_nfold,
        context={"order": "pad sdu_marker", "oriented": "pad sdu_marker"},
        context_values=_nfold_of_pad,
        needs={"pad": ("sdu_marker",)},
        provides=_IMAGE_PIXEL,
    ),
    "sdu": BlockSpec(
        "detector",
        "sdu",
        "paper 004's landing marker: the n-fold marker and three ArUco landmarks",
        SduParams,
        build=_sdu,
        needs={"pad": ("sdu_marker",)},
        provides=_IMAGE_PIXEL,
    ),
    "red": BlockSpec(
        "detector",
        "red",
        "paper 003's colour filter (Alg. 1-2): the biggest red contour",
        RedTargetDetectorConfig,
        build=_red,
        context={"mitigation": "perception.mitigation"},
        context_values=_mitigation,
        needs={"pad": ("red_target",), "camera.color": (True,)},
        provides=_IMAGE_PIXEL,
    ),
    "groundtruth": BlockSpec(
        "detector",
        "groundtruth",
        "the simulator's ground-truth perception sensor (no image; the 'perfect perception' ablation)",
        GroundTruthParams,
        build=_groundtruth,
        provides={"observation": ("relative_position",), "image": False},
    ),
}
"""The detector stage's blocks by name."""


# -- the geolocators -------------------------------------------------------------------------------------


def _pnp(p: Any, ctx: MountedCamera) -> Geolocator:
    if not isinstance(ctx.camera, PinholeCamera):
        raise ValueError(f"pnp needs a pinhole camera model (K, lens), got {type(ctx.camera).__name__}")
    return PnpGeolocator(ctx.camera, ctx.mount, **param_kwargs(p))


def _flat_earth(p: Any, ctx: MountedCamera) -> Geolocator:
    if ctx.camera is None:
        raise ValueError("flat_earth needs a camera model (its rays)")
    return FlatEarthGeolocator(ctx.camera, ctx.mount, **param_kwargs(p))


def _homography(p: Any, ctx: MountedCamera) -> Geolocator:
    if ctx.camera is None:
        raise ValueError("homography needs a camera model (its size and field of view)")
    return HomographyGeolocator(ctx.camera, ctx.mount, **param_kwargs(p))


def _direct(p: Any, ctx: MountedCamera) -> Geolocator:
    return DirectGeolocator(ctx.mount, **param_kwargs(p))


def _deck_height(key: str) -> Any:
    def values(ctx: ResolveContext) -> dict[str, float]:
        return {key: ctx.pad_height_m}

    return values


GeolocatorSpec = BlockSpec[MountedCamera, "Geolocator"]
"""A geolocator block: parameters and the camera with its mount -> a geolocator."""

GEOLOCATORS: dict[str, GeolocatorSpec] = {
    "pnp": BlockSpec(
        "geolocator",
        "pnp",
        "PnP on the pad's points, with the ego pose at the capture time (paper 000)",
        PnpParams,
        build=_pnp,
        needs={"camera.model": ("pinhole",), "detector.observation": ("pad_points",)},
    ),
    "flat_earth": BlockSpec(
        "geolocator",
        "flat_earth",
        "the pixel's ray intersected with the deck's plane (paper 003, eq. 5-9)",
        FlatEarthParams,
        build=_flat_earth,
        defaults={"deck_height_m": None},
        context={"deck_height_m": "platform.pad_height_m"},
        context_values=_deck_height("deck_height_m"),
        needs={"detector.observation": ("pixel",), "platform.level": (True,)},
    ),
    "homography": BlockSpec(
        "geolocator",
        "homography",
        "pixel to ground by the homography of the camera's view at the altitude (paper 004, Sec. IV-A)",
        HomographyParams,
        build=_homography,
        defaults={"plane_z_W": None},
        context={"plane_z_W": "platform.pad_height_m"},
        context_values=_deck_height("plane_z_W"),
        needs={"camera.model": ("pinhole",), "detector.observation": ("pixel",), "platform.level": (True,)},
    ),
    "direct": BlockSpec(
        "geolocator",
        "direct",
        "observations that carry the pad's position in C (the ground-truth sensor)",
        DirectParams,
        build=_direct,
        needs={"detector.observation": ("relative_position",)},
    ),
}
"""The geolocator stage's blocks by name."""

__all__ = [
    "DETECTORS",
    "GEOLOCATORS",
    "ArucoParams",
    "DetectorContext",
    "DetectorSpec",
    "GeolocatorSpec",
    "GroundTruthParams",
    "SduParams",
]
