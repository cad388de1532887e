"""The camera stage's registry: :data:`CAMERAS`, the camera models a scenario's ``blocks.camera`` names,
with their parameters and factories (:class:`alight.blockspec.BlockSpec`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache
from typing import TYPE_CHECKING

from alight.blockspec import BlockSpec, ResolveContext
from alight.cameras.omni import OmniCamera
from alight.cameras.pinhole import CameraMount, PinholeCamera
from alight.errors import AlightError

if TYPE_CHECKING:
    from alight.cameras import CameraModel


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
class CameraLoad:
    """The camera stage's build context."""

    fresh: bool = True
    """Build this flight's own model; False: a synthetic lens may be shared (a scenario's validation)."""


@dataclass(frozen=True, kw_only=True)
class MountedCamera:
    """The build context of the blocks that look through the camera (geolocators, platform estimators)."""

    camera: CameraModel | None
    """The camera model; None for the ground-truth sensor (no image)."""
    mount: CameraMount
    """The camera's pose on the body."""


@cache
def _synthetic_fisheye(width: int, height: int, fov_deg: float) -> OmniCamera:
    """A synthetic lens for validation (~70 ms to fit; the flight builds its own)."""
    return OmniCamera.synthetic(width, height, fov_deg=fov_deg)


def _calibrated(path: str, want: type, name: str, other: str) -> CameraModel:
    """The model in calibration file ``path``; a ``ValueError`` ``calibration: ...`` when it cannot be
    loaded or is not a ``want``."""
    from alight.cameras import load_camera  # the package's loader (this module is imported by it)

    try:
        cam = load_camera(path)
    except AlightError as err:
        raise ValueError(f"calibration: {err}") from None
    if not isinstance(cam, want):
        raise ValueError(
            f"calibration: {path} is a {type(cam).__name__} calibration, not a {name} one "
            f"(use camera: {other})"
        )
    return cam


def _pinhole(p: PinholeParams, ctx: CameraLoad) -> CameraModel:
    if p.calibration is None:
        return PinholeCamera.default_downward()
    return _calibrated(p.calibration, PinholeCamera, "pinhole", "fisheye")


def _fisheye(p: FisheyeParams, ctx: CameraLoad) -> CameraModel:
    if p.calibration is not None:
        return _calibrated(p.calibration, OmniCamera, "fisheye", "pinhole")
    if not ctx.fresh:
        return _synthetic_fisheye(p.width, p.height, p.fov_deg)
    return OmniCamera.synthetic(p.width, p.height, fov_deg=p.fov_deg)


def _calibration(ctx: ResolveContext) -> dict[str, str | None]:
    return {"calibration": ctx.calibration}


CameraSpec = BlockSpec[CameraLoad, "CameraModel"]
"""A camera block: parameters and a :class:`CameraLoad` -> a camera model."""

CAMERAS: dict[str, CameraSpec] = {
    "pinhole": BlockSpec(
        "camera",
        "pinhole",
        "pinhole camera with radial-tangential distortion (OpenCV); 752x480 by default",
        PinholeParams,
        build=_pinhole,
        context={"calibration": "camera.calibration"},
        context_values=_calibration,
        provides={"model": "pinhole"},
    ),
    "fisheye": BlockSpec(
        "camera",
        "fisheye",
        "omnidirectional camera, Scaramuzza's model (OCamCalib); a 186 deg 640x480 lens by default",
        FisheyeParams,
        build=_fisheye,
        context={"calibration": "camera.calibration"},
        context_values=_calibration,
        provides={"model": "omni"},
    ),
}
"""The camera stage's blocks by name."""

__all__ = ["CAMERAS", "CameraLoad", "CameraSpec", "FisheyeParams", "MountedCamera", "PinholeParams"]
