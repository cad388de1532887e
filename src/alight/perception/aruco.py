"""ArUco / AprilTag markers through OpenCV's ``cv2.aruco.ArucoDetector`` (the baseline that paper 000
says its framework generalises to, Sec. II-B, and the marker part of paper 004's pad).

Two modes:

- *pad layout* (``ArucoPadDetector(pad)``): every detected marker whose id is on the pad gives one
  :class:`~alight.types.Observation` of kind ``aruco:ID`` with its 4 corners (OpenCV's order: the marker's
  top-left, top-right, bottom-right, bottom-left) and the matching corners in the pad frame from
  ``pad.marker_corners_P(id)``, ready for PnP; markers with ids not on the pad are dropped (a marker of the
  same dictionary lying on the ground is not the pad). :func:`merge_observations` joins them into one
  observation for a single PnP over all markers.
- *generic* (``ArucoPadDetector(None)``): every marker of the dictionary, with ``points_P`` None; for
  counting markers in arbitrary photos.

The marker dictionary has no quality score; an observation's quality is 1 for markers whose shortest
side is at least ``full_quality_side_px`` and falls linearly to 0 at 0 px (small markers are both less
reliably decoded and less precise).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np

from alight.perception.image_input import as_gray_u8, check_time
from alight.types import FloatArray, Image, Observation

DICTIONARIES: dict[str, int] = {
    name: int(getattr(cv2.aruco, name)) for name in dir(cv2.aruco) if name.startswith("DICT_")
}
"""OpenCV's predefined marker dictionaries by name (``DICT_APRILTAG_36h11``, ``DICT_6X6_250``, ...)."""


def dictionary_id(dictionary: int | str) -> int:
    """The OpenCV id of a dictionary given by id or by name (``"DICT_APRILTAG_36h11"`` or
    ``"APRILTAG_36h11"``). Raises ``ValueError`` for an unknown name."""
    if isinstance(dictionary, str):
        key = dictionary if dictionary.startswith("DICT_") else "DICT_" + dictionary
        if key not in DICTIONARIES:
            raise ValueError(f"unknown marker dictionary {dictionary!r}; known: {sorted(DICTIONARIES)}")
        return DICTIONARIES[key]
    return int(dictionary)


class ArucoPadDetector:
    """Square fiducial markers via ``cv2.aruco.ArucoDetector``; ``detect(image, t)`` is a pure function
    of the image.

    Parameters
    ----------
    pad:
        A marker layout with ``marker_ids`` and ``marker_corners_P(id) -> (4, 3)`` (e.g.
        ``alight.pads.AprilTagPad``), or None for the generic mode (every marker, no ``points_P``).
    dictionary:
        OpenCV dictionary id or name; default ``DICT_APRILTAG_36h11`` (the dictionary of ``AprilTagPad``).
    parameters:
        ``cv2.aruco.DetectorParameters`` (OpenCV's defaults when None).
    full_quality_side_px:
        Shortest marker side (px) from which the quality is 1.
    subpixel_corners:
        Refine the corners to sub-pixel (``CORNER_REFINE_SUBPIX``) when ``parameters`` is None; OpenCV's
        default leaves them on the integer grid, which costs PnP accuracy.
    """

    def __init__(
        self,
        pad: Any | None = None,
        dictionary: int | str = cv2.aruco.DICT_APRILTAG_36h11,
        parameters: Any | None = None,
        full_quality_side_px: float = 20.0,
        subpixel_corners: bool = False,
    ) -> None:
        if not full_quality_side_px > 0:
            raise ValueError(f"full_quality_side_px must be positive, got {full_quality_side_px}")
        self.pad = pad
        self.dictionary = dictionary_id(dictionary)
        if parameters is None:
            params = cv2.aruco.DetectorParameters()
            if subpixel_corners:
                params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
        else:
            params = parameters
        self._detector = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(self.dictionary), params)
        self.full_quality_side_px = float(full_quality_side_px)
        self._corners_P: dict[int, FloatArray] = {}
        if pad is not None:
            for mid in pad.marker_ids:
                c = np.asarray(pad.marker_corners_P(int(mid)), dtype=np.float64)
                if c.shape != (4, 3):
                    raise ValueError(f"pad.marker_corners_P({mid}) must have shape (4, 3), got {c.shape}")
                self._corners_P[int(mid)] = c

    def detect_markers(self, image: Image) -> tuple[list[FloatArray], list[int]]:
        """Raw detections: corner arrays (4, 2) and ids, in OpenCV's order; empty for an unusable image."""
        gray = as_gray_u8(image)
        if gray is None or min(gray.shape) < 8:
            return [], []
        corners, ids, _ = self._detector.detectMarkers(gray)
        if ids is None or len(corners) == 0:
            return [], []
        return [np.asarray(c, dtype=np.float64).reshape(4, 2) for c in corners], [int(i) for i in ids.ravel()]

    def detect(self, image: Image, t: float) -> list[Observation]:
        """One observation per marker (kind ``aruco:ID``), sorted by id; ``[]`` when there is none or the
        image is unusable (:mod:`alight.perception.image_input`)."""
        t = check_time(t)
        corners, ids = self.detect_markers(image)
        out: list[Observation] = []
        for c, mid in sorted(zip(corners, ids, strict=True), key=lambda a: a[1]):
            if self.pad is not None and mid not in self._corners_P:
                continue
            e = c[[1, 2, 3, 0]] - c
            side = float(np.hypot(e[:, 0], e[:, 1]).min())
            quality = min(1.0, max(0.0, side / self.full_quality_side_px))
            pts = self._corners_P.get(mid) if self.pad is not None else None
            out.append(Observation(t=t, kind=f"aruco:{mid}", quality=quality, pixels=c, points_P=pts))
        return out


def merge_observations(observations: Sequence[Observation], kind: str = "aruco:pad") -> Observation | None:
    """One observation holding the points of every observation that has ``points_P`` (for one PnP over
    all markers of a pad), with the mean quality; None when there is none. The capture time is the first
    one's (all should come from the same image)."""
    obs = [o for o in observations if o.points_P is not None and o.pixels.shape[0] > 0]
    if not obs:
        return None
    px = np.concatenate([o.pixels for o in obs])
    pts = np.concatenate([o.points_P for o in obs if o.points_P is not None])
    q = float(np.mean([o.quality for o in obs]))
    return Observation(t=obs[0].t, kind=kind, quality=q, pixels=px, points_P=pts)


__all__ = ["DICTIONARIES", "ArucoPadDetector", "dictionary_id", "merge_observations"]
