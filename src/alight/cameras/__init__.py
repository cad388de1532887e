"""Camera models and the camera mount.

Camera frame ``C`` is OpenCV's (x right, y down, z along the optical axis); pixels ``(u, v)`` have integer
values at pixel centres. Every model satisfies :class:`CameraModel`; :func:`load_camera` reads a
calibration file and picks the model from the file type: OpenCV ``FileStorage`` YAML/XML/JSON for
:class:`PinholeCamera`, OCamCalib ``calib_results.txt`` for :class:`OmniCamera`.
:data:`CAMERAS` is the camera stage's registry (``cameras/registry.py``).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Protocol, runtime_checkable

from alight.cameras.omni import OmniCamera, solve_rho
from alight.cameras.pinhole import CameraMount, PinholeCamera, camera_pose_W
from alight.cameras.registry import CAMERAS, CameraLoad, CameraSpec, MountedCamera
from alight.errors import InputError
from alight.types import FloatArray


@runtime_checkable
class CameraModel(Protocol):
    """What the renderer, the detectors and the geolocators need of a camera."""

    @property
    def width(self) -> int:
        """Image width (px)."""
        ...

    @property
    def height(self) -> int:
        """Image height (px)."""
        ...

    def project(self, points_C: FloatArray) -> FloatArray:
        """Pixels of points in C (m), shape (N, 3) -> (N, 2); NaN rows for points with no image."""
        ...

    def unproject(self, pixels: FloatArray) -> FloatArray:
        """Unit rays in C through pixels, shape (N, 2) -> (N, 3); NaN rows where there is none."""
        ...

    def fov_rad(self) -> tuple[float, float]:
        """(horizontal, vertical) full field of view (rad)."""
        ...


LOADERS: dict[str, Callable[[str], CameraModel]] = {
    ".yml": PinholeCamera.from_opencv_yaml,
    ".yaml": PinholeCamera.from_opencv_yaml,
    ".xml": PinholeCamera.from_opencv_yaml,
    ".json": PinholeCamera.from_opencv_yaml,
    ".txt": OmniCamera.from_ocamcalib,
}
"""Calibration-file loaders by lower-case file suffix (``.txt``: OCamCalib's ``calib_results.txt``)."""


def load_camera(path: str | os.PathLike[str]) -> CameraModel:
    """Load a camera model from a calibration file, choosing the loader from the file's suffix
    (:data:`LOADERS`). Raises ``alight.errors.InputError`` for a missing file or an unknown type."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{p}: camera calibration file not found")
    loader = LOADERS.get(p.suffix.lower())
    if loader is None:
        raise InputError(f"{p}: unknown camera calibration type {p.suffix!r} (known: {sorted(LOADERS)})")
    return loader(str(p))


__all__ = [
    "CAMERAS",
    "LOADERS",
    "CameraLoad",
    "CameraSpec",
    "MountedCamera",
    "CameraModel",
    "CameraMount",
    "OmniCamera",
    "PinholeCamera",
    "camera_pose_W",
    "load_camera",
    "solve_rho",
]
