"""Perception: detectors that find a landing pad in a camera image, and geolocators that turn a detection
into a platform measurement in the world frame.

- :class:`Detector`: ``detect(image, t) -> list[Observation]``, a function of the image alone unless one
  of the hooks below was called: ``falanga`` (paper 000's cross-and-ring tag, Alg. 1), ``aruco`` (the
  AprilTag pad's markers via OpenCV), ``apriltag`` (every AprilTag 36h11 marker, no pad layout).
- :class:`Geolocator`: ``locate(observation, p_WB, R_WB) -> PlatformMeasurement | None`` with the ego pose
  at the capture time: ``pnp`` (PnP on the observation's points) and ``direct`` (observations that carry
  ``p_CP`` already, like the ground-truth sensor).

Context: besides the image and its capture time, a detector may declare that it takes the flight's
context, by satisfying one of the Protocols below; the :class:`alight.mission.pipeline.Pipeline` checks
them once, when it is built, and then calls them before each image (or at each mode change):
:class:`PixelGated` (where the platform estimator expects the target, and the gate radius),
:class:`RangeAware` (the range finder's reading: the Falanga detector's close-range stage),
:class:`ModeAware` (the mission phase) and :class:`TiltAware` (the camera's tilt from nadir; the
quality-of-service wrapper). A detector that declares none depends on the image and its capture time only.

:data:`DETECTORS` and :data:`GEOLOCATORS` (``perception/registry.py``) are the two stages' registries:
name -> :class:`alight.blockspec.BlockSpec` (parameters, needs/provides, factory). A new detector: write
``perception/<name>.py`` with a class that satisfies :class:`Detector` and add one entry to
:data:`DETECTORS` (or :func:`alight.mission.blocks.register_block` from outside the package); the flight,
``alight blocks``, ``alight detect`` and the contract tests in ``tests/perception`` then use it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol, runtime_checkable

from alight.perception.aruco import ArucoPadDetector, merge_observations
from alight.perception.color_filter import RedTargetDetector, RedTargetDetectorConfig
from alight.perception.falanga_tag import FalangaDetectorConfig, FalangaTagDetector
from alight.perception.flat_earth import FlatEarthGeolocator
from alight.perception.geolocation import DirectGeolocator, PnpGeolocator
from alight.perception.homography_geolocation import HomographyGeolocator
from alight.perception.nfold import NFoldConfig, NFoldDetector
from alight.perception.pnp import PnpResult, solve_pnp
from alight.perception.registry import DETECTORS, GEOLOCATORS, DetectorContext, DetectorSpec, GeolocatorSpec
from alight.perception.sdu_marker import SduMarkerDetector
from alight.types import FloatArray, Image, Mode, Observation, PlatformMeasurement

if TYPE_CHECKING:  # for annotations only
    from alight.energy import QosEnergyModel


@runtime_checkable
class Detector(Protocol):
    """Finds the pad (or its markers) in one image."""

    def detect(self, image: Image, t: float) -> list[Observation]:
        """Observations in ``image`` (:data:`alight.types.Image`: grey or colour, any numeric dtype, read
        by :mod:`alight.perception.image_input`) captured at ``t`` (s); ``[]`` when nothing is found or
        ``image`` is not an image. Must not raise on an empty, tiny or uniform image."""
        ...


@runtime_checkable
class PixelGated(Protocol):
    """A detector that gates its candidates with the estimator's predicted pixel."""

    def set_prediction(self, px: FloatArray | None, radius_px: float | None = None) -> None:
        """The predicted pixel ``(u, v)`` of the target in the next image and the gate radius (px); None
        when there is no prediction."""
        ...


@runtime_checkable
class RangeAware(Protocol):
    """A detector that uses the range finder's reading (m, to the surface below; None when invalid)."""

    def set_range(self, range_m: float | None) -> None: ...


@runtime_checkable
class ModeAware(Protocol):
    """A detector whose processing follows the mission phase (quality of service)."""

    def set_mode(self, mode: Mode) -> None:
        """The mission's new :class:`alight.types.Mode` (called at each mode change)."""
        ...


@runtime_checkable
class TiltAware(Protocol):
    """A detector whose processing follows the obliquity of the view."""

    def set_view_tilt(self, t: float, tilt_rad: float) -> None:
        """The camera's tilt from nadir at time ``t`` (rad), at the planner's rate."""
        ...


@runtime_checkable
class FrameGate(Protocol):
    """A detector that knows, before an image is made, whether it will look at the image captured at a
    given time (a detector run at a reduced rate skips frames). A simulator asks it first and renders
    only the frames it will process; a skipped frame is still handed to ``detect`` (with a stand-in
    image it never reads), so the detector counts and skips it exactly as before."""

    def will_process(self, t_capture: float) -> bool:
        """Whether ``detect(image, t_capture)``, called next, reads the image. Must not change the
        detector's state."""
        ...


@runtime_checkable
class ComputeMetered(Protocol):
    """A detector that meters its own compute: the frames it processed and their energy under a
    quality-of-service energy model (``perception/qos_detector.py``)."""

    @property
    def frames_processed(self) -> int: ...

    def energy_J(self, model: QosEnergyModel, duration_s: float = 0.0) -> float: ...


@runtime_checkable
class Geolocator(Protocol):
    """Turns an observation and the ego pose at its capture time into a measurement in W."""

    def locate(self, obs: Observation, p_WB: FloatArray, R_WB: FloatArray) -> PlatformMeasurement | None:
        """Pad centre (m, W) with covariance (and yaw when measured), or None when the observation does
        not give one. ``p_WB`` (3,) body position in W (m), ``R_WB`` (3, 3) body attitude."""
        ...


__all__ = [
    "DETECTORS",
    "ComputeMetered",
    "FrameGate",
    "GEOLOCATORS",
    "ArucoPadDetector",
    "Detector",
    "DetectorContext",
    "DetectorSpec",
    "GeolocatorSpec",
    "DirectGeolocator",
    "FalangaDetectorConfig",
    "FlatEarthGeolocator",
    "FalangaTagDetector",
    "Geolocator",
    "HomographyGeolocator",
    "NFoldConfig",
    "NFoldDetector",
    "PnpGeolocator",
    "PnpResult",
    "RedTargetDetector",
    "RedTargetDetectorConfig",
    "SduMarkerDetector",
    "ModeAware",
    "PixelGated",
    "RangeAware",
    "TiltAware",
    "merge_observations",
    "solve_pnp",
]
