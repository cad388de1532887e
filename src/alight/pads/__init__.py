"""Landing-pad designs: marker geometry in the pad frame ``P`` and textures (grayscale or BGR colour).

Pad frame ``P``: origin at the pad centre, z up, x along the platform heading, y to the left. A pad is a
square of side ``size_m`` on the plane z = 0 of P.

Texture convention (every design): the pad seen from above, +x (front) at the image top, +y (left) at the
image left, not mirrored. An ``n x n`` texture (``n = round(size_m * px_per_m)``) maps the P point
``(x, y)`` to the pixel ``u = s (size_m/2 - y) - 0.5``, ``v = s (size_m/2 - x) - 0.5`` with
``s = n / size_m``; ``texture_homography_P_to_px(px_per_m)`` is that map as a 3x3 homography. A texture is
grayscale, shape (n, n), or BGR colour (OpenCV's channel order), shape (n, n, 3); the renderer converts
either to what it draws (a grey pad in a colour image is replicated, a colour pad in a grey image is
converted with ``cv2.COLOR_BGR2GRAY``).

:data:`PADS` is the pad stage's registry (``pads/registry.py``).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from alight.pads._texture import texture_homography, texture_side_px
from alight.pads.apriltag_pad import APRILTAG_DICTIONARY, AprilTagPad
from alight.pads.falanga_tag import FalangaTag
from alight.pads.red_target import RedTarget
from alight.pads.registry import PADS, PadParams, PadSpec
from alight.pads.sdu_pad import SduPad
from alight.types import FloatArray


@runtime_checkable
class PadDesign(Protocol):
    """What the renderer and the detectors need of a pad."""

    @property
    def size_m(self) -> float:
        """Side of the pad's square (m)."""
        ...

    def texture(self, px_per_m: float) -> NDArray[np.uint8]:
        """Texture, uint8, grayscale of shape (n, n) or BGR of shape (n, n, 3), ``n = round(size_m *
        px_per_m)``."""
        ...

    def texture_homography_P_to_px(self, px_per_m: float) -> FloatArray:
        """3x3 homography from P-plane points (x, y, 1) in m to texture pixels (u, v, 1)."""
        ...


@runtime_checkable
class WholeMarkerPad(Protocol):
    """A pad whose detectors need a part of it whole in view (a marker): it cannot be detected from
    closer than where that part fills the image. Pads seen in part down to the ground do not declare
    it."""

    @property
    def min_view_side_m(self) -> float:
        """Side of the smallest square around the pad centre a camera must see whole (m)."""
        ...


__all__ = [
    "APRILTAG_DICTIONARY",
    "PADS",
    "AprilTagPad",
    "FalangaTag",
    "PadDesign",
    "PadParams",
    "PadSpec",
    "RedTarget",
    "SduPad",
    "WholeMarkerPad",
    "texture_homography",
    "texture_side_px",
]
