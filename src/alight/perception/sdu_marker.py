"""Detector of paper 004's landing marker (Zamanakos et al., Sec. IV-A): the n-fold marker and the three
ArUco markers of :class:`alight.pads.SduPad`, fused into one landing-marker pixel.

Paper 004: the n-fold marker "is primarily used to detect the moving platform from a high altitude, while
the ArUco markers are used as extra landmarks in case the marker is partially visible"; "to detect the
ArUco markers the standard OpenCV library is used"; for ArUco markers "an offset vector ... is added
depending on the ArUco marker's id" (step 8); and "the mean measurements from the detected n-fold and/or
ArUco markers are used to determine the position and orientation of the landing marker".

What this detector does, per image:

1. the n-fold marker with :class:`alight.perception.nfold.NFoldDetector` (adaptive kernel size, the pad's
   order); its tip is the pad centre;
2. the pad's ArUco markers with OpenCV (``cv2.aruco.ArucoDetector``, the pad's dictionary, sub-pixel
   corners); markers with other ids are ignored;
3. a landing-marker pixel from each ArUco marker: the paper's "marker centre plus its known offset,
   turned by the marker's orientation", done with the marker's own homography (P plane -> image, from its
   4 corners), i.e. ``H_i (x_c, y_c, 1)`` for the pad centre ``(x_c, y_c)``. A homography is that rule
   with the marker's rotation, scale and perspective foreshortening all taken from the marker itself.
   Given the camera model (optional), the homography is fitted on undistorted coordinates and the result
   projected back through the model: lens distortion otherwise bends a 2.6-side extrapolation by tens of
   pixels near the image border;
4. a gate against outliers (ours; the paper takes the plain mean): the reference is the median of the
   ArUco estimates (their ids are decoded, so they are the harder ones to fake) or, without ArUco, the
   n-fold tip; an estimate farther than ``max(gate_min_px, gate_frac x the pad's side in pixels)`` from
   it, and farther than 3 sigma of its difference to the reference, is not used (a lone small marker
   does not gate out a good tip);
5. the fused pixel: the mean of the used estimates weighted by their inverse variances (the paper's
   mean when the variances are equal). Variances: ``nfold_sigma_px^2`` for the tip; for an ArUco
   estimate, the first-order propagation of ``aruco_corner_sigma_px`` on each corner coordinate through
   the homography (per axis, half the trace of ``sigma^2 J J^T``, ``J`` the 2 x 8 Jacobian by central
   differences). Extrapolating from a 0.3 m marker to a point 0.78 m away multiplies the corner noise by
   ~3-6 (measured on rendered frames: ArUco estimates 1.5-2.5 px median error, the n-fold tip ~0.03 px),
   so the tip dominates the mean whenever it is seen;
6. the orientation: the image angle of the pad's +x axis at the pad centre (``yaw_CP``, from +u toward
   +v, the convention of :class:`alight.types.Observation` for a camera looking down), from each ArUco
   homography; the n-fold gives it modulo ``2 pi / n`` (unique for an oriented marker), and is folded to
   the candidate nearest the ArUco mean. The circular mean of the used estimates; None when only a plain
   n-fold marker is seen.

Output (``detect``): at most one :class:`~alight.types.Observation`, kind ``sdu``:

- ``pixels[0]`` is the fused landing-marker pixel and ``points_P[0]`` the pad centre ``(0, 0, 0)``: what a
  geolocator that maps one pixel to the ground (paper 004's homography, steps 1-7) needs;
- the next rows are the measured points the fusion used: the n-fold tip (``points_P`` the pad centre),
  then each used ArUco marker's 4 corners in OpenCV's order, by id (``points_P`` their corners in P), so a
  PnP geolocator can use them (row 0 is their mean, a duplicate it may drop);
- ``quality`` is the largest quality of the used sources (n-fold quality score; ArUco side / 20 px,
  capped at 1); ``yaw_CP`` the fused orientation or None.

:meth:`SduMarkerDetector.detect_detailed` returns everything per source (:class:`SduDetection`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from alight.cameras import CameraModel
from alight.pads.sdu_pad import SduPad
from alight.perception.aruco import ArucoPadDetector
from alight.perception.image_input import as_gray_u8, check_time
from alight.perception.nfold import NFoldConfig, NFoldDetector, NFoldResult
from alight.types import FloatArray, Image, Observation


@dataclass(frozen=True, slots=True)
class SduSource:
    """One source's estimate of the landing-marker pixel."""

    kind: str
    """``nfold`` or ``aruco:ID``."""
    pixel: FloatArray
    """Its landing-marker (pad centre) pixel (u, v), shape (2,)."""
    sigma_px: float
    """Standard deviation of ``pixel`` per axis (px), from the module's variance model."""
    yaw_CP: float | None
    """Image angle of the pad's +x axis (rad, from +u toward +v); for a plain n-fold marker the angle of a
    black wedge, valid modulo 2 pi / n."""
    quality: float
    """The source's quality in [0, 1]."""
    points: FloatArray
    """The measured image points, (N, 2): the tip (1, 2) or the marker's corners (4, 2)."""
    points_P: FloatArray
    """Their positions in P (m), (N, 3)."""
    used: bool
    """False when the outlier gate dropped it."""


@dataclass(frozen=True, slots=True)
class SduDetection:
    """Everything :class:`SduMarkerDetector` found in one image."""

    t: float
    """Capture time (s)."""
    pixel: FloatArray
    """Fused landing-marker pixel (u, v), shape (2,)."""
    sigma_px: float
    """Its standard deviation per axis (px) under the variance model."""
    quality: float
    """Largest quality of the used sources."""
    yaw_CP: float | None
    """Fused image angle of the pad's +x axis (rad), None when unknown."""
    sources: tuple[SduSource, ...]
    """Every source, n-fold first, then the ArUco markers by id."""
    nfold: NFoldResult | None
    """The n-fold detection as the n-fold detector returned it."""


class SduMarkerDetector:
    """Paper 004's landing-marker detector (module docstring). ``detect(image, t)`` is a pure function of
    the image.

    Parameters
    ----------
    pad:
        The landing marker (:class:`alight.pads.SduPad`, default ``SduPad.default()``).
    nfold:
        n-fold detector settings; default ``NFoldConfig(order=pad.nfold_order,
        oriented=pad.nfold_oriented)``. Its order and variant must match the pad's.
    aruco_parameters:
        ``cv2.aruco.DetectorParameters``; default OpenCV's with sub-pixel corner refinement.
    nfold_sigma_px, aruco_corner_sigma_px:
        Pixel noise of the n-fold tip and of an ArUco corner (px), for the weights.
    gate_frac, gate_min_px:
        Outlier gate: an estimate farther than ``max(gate_min_px, gate_frac x pad side in px)`` from the
        reference (step 4) is dropped.
    full_quality_side_px:
        ArUco side (px) from which an ArUco source's quality is 1.
    camera:
        The camera model the images come from (:class:`alight.cameras.CameraModel`), optional. With it
        the ArUco homographies are fitted on undistorted (normalised) coordinates and the pad centre is
        projected back through the model, so lens distortion does not bend the extrapolation (on the
        default downward camera at 0.6-1 m over a corner: 16-39 px error without, 0.3-0.9 px with). The
        n-fold tip is a measured pixel either way.
    """

    def __init__(
        self,
        pad: SduPad | None = None,
        nfold: NFoldConfig | None = None,
        aruco_parameters: Any | None = None,
        *,
        nfold_sigma_px: float = 0.3,
        aruco_corner_sigma_px: float = 0.25,
        gate_frac: float = 0.1,
        gate_min_px: float = 3.0,
        full_quality_side_px: float = 20.0,
        camera: CameraModel | None = None,
    ) -> None:
        self.pad = SduPad.default() if pad is None else pad
        p = self.pad
        cfg = NFoldConfig(order=p.nfold_order, oriented=p.nfold_oriented) if nfold is None else nfold
        if cfg.order != p.nfold_order or cfg.oriented != p.nfold_oriented:
            raise ValueError(
                f"the n-fold config (order {cfg.order}, oriented {cfg.oriented}) does not match the pad's "
                f"marker (order {p.nfold_order}, oriented {p.nfold_oriented})"
            )
        for name, v in (
            ("nfold_sigma_px", nfold_sigma_px),
            ("aruco_corner_sigma_px", aruco_corner_sigma_px),
            ("full_quality_side_px", full_quality_side_px),
        ):
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be finite and positive, got {v}")
        if not (
            math.isfinite(gate_frac) and gate_frac > 0 and math.isfinite(gate_min_px) and gate_min_px > 0
        ):
            raise ValueError(f"gate_frac and gate_min_px must be positive, got {gate_frac}, {gate_min_px}")
        self.nfold = NFoldDetector(cfg, tip_P=p.nfold_center_P)
        self.aruco = ArucoPadDetector(
            p,
            dictionary=p.aruco_dictionary_id,
            parameters=aruco_parameters,
            full_quality_side_px=full_quality_side_px,
            subpixel_corners=True,
        )
        self.camera = camera
        self.nfold_sigma_px = float(nfold_sigma_px)
        self.aruco_corner_sigma_px = float(aruco_corner_sigma_px)
        self.gate_frac = float(gate_frac)
        self.gate_min_px = float(gate_min_px)
        c = p.nfold_center_P
        # the pad centre and a point along +x (a tenth of the pad), homogeneous, for the ArUco homographies
        self._probe_P = np.array([[c[0], c[1], 1.0], [c[0] + 0.1 * p.size_m, c[1], 1.0]])

    # ------------------------------------------------------------------------------------ public API

    def detect(self, image: Image, t: float) -> list[Observation]:
        """``[Observation(kind="sdu")]`` with the fused landing-marker pixel first (module docstring), or
        ``[]`` when neither the n-fold marker nor any of the pad's ArUco markers is found."""
        det = self.detect_detailed(image, t)
        if det is None:
            return []
        used = [s for s in det.sources if s.used]
        pixels = np.concatenate([det.pixel[None, :]] + [s.points for s in used])
        points_P = np.concatenate([self.pad.nfold_center_P[None, :]] + [s.points_P for s in used])
        return [
            Observation(
                t=t, kind="sdu", quality=det.quality, pixels=pixels, points_P=points_P, yaw_CP=det.yaw_CP
            )
        ]

    def detect_detailed(self, image: Image, t: float) -> SduDetection | None:
        """Every source and the fusion (:class:`SduDetection`); None when nothing is found (or the image
        is unusable: :mod:`alight.perception.image_input`)."""
        t = check_time(t)
        gray = as_gray_u8(image)
        if gray is None or min(gray.shape) < 8:
            return None
        sources: list[SduSource] = []
        nf = self.nfold.detect_result(gray)
        if nf is not None:
            tip = np.array([nf.x, nf.y])
            sources.append(
                SduSource(
                    kind="nfold",
                    pixel=tip,
                    sigma_px=self.nfold_sigma_px,
                    yaw_CP=nf.theta,
                    quality=nf.quality,
                    points=tip[None, :],
                    points_P=self.pad.nfold_center_P[None, :],
                    used=True,
                )
            )
        for obs in self.aruco.detect(gray, t):
            src = self._aruco_source(obs)
            if src is not None:
                sources.append(src)
        if not sources:
            return None
        sources = self._gate(sources)
        return self._fuse(t, sources, nf)

    # ------------------------------------------------------------------------------------ internals

    def _aruco_source(self, obs: Observation) -> SduSource | None:
        """The landing-marker pixel and pad yaw from one ArUco marker's homography (step 3), with the
        first-order variance of the pixel from the corners' noise (step 5)."""
        if obs.points_P is None:  # ArucoPadDetector with a pad always fills it
            return None
        src = np.ascontiguousarray(obs.points_P[:, :2], dtype=np.float64)
        # the nominal corners and 16 perturbed copies (+-h on each of the 8 coordinates), mapped together
        h = 1e-3
        d = np.zeros((17, 8))
        d[1:9] = h * np.eye(8)
        d[9:] = -h * np.eye(8)
        sets = obs.pixels[None, :, :] + d.reshape(17, 4, 2)
        plane = self._to_plane(sets.reshape(-1, 2)).reshape(17, 4, 2)
        if not np.isfinite(plane).all():
            return None
        mapped = np.empty((18, 2))
        for i in range(17):
            H = cv2.getPerspectiveTransform(src.astype(np.float32), plane[i].astype(np.float32))
            q = (self._probe_P if i == 0 else self._probe_P[:1]) @ H.T
            if not (np.isfinite(q).all() and np.all(np.abs(q[:, 2]) > 1e-12)):
                return None
            p = q[:, :2] / q[:, 2:]
            if i == 0:
                mapped[0], mapped[17] = p[0], p[1]
            else:
                mapped[i] = p[0]
        px = self._from_plane(mapped)
        if not np.isfinite(px).all():
            return None
        c = px[0]
        J = ((px[1:9] - px[9:17]) / (2 * h)).T  # d(centre pixel) / d(corner coordinates), (2, 8)
        # per-axis variance: half the trace of sigma^2 J J^T
        sigma = self.aruco_corner_sigma_px * math.sqrt(0.5 * float(np.sum(J * J)))
        ax = px[17] - c
        return SduSource(
            kind=obs.kind,
            pixel=c,
            sigma_px=sigma,
            yaw_CP=math.atan2(float(ax[1]), float(ax[0])),
            quality=obs.quality,
            points=obs.pixels,
            points_P=obs.points_P,
            used=True,
        )

    def _to_plane(self, pixels: FloatArray) -> FloatArray:
        """Pixels (N, 2) -> the plane the homographies live in: the normalised image plane (x/z, y/z) of
        the camera model when one is given (so that lens distortion is undone), else the pixels."""
        if self.camera is None:
            return pixels
        rays = np.asarray(self.camera.unproject(pixels), dtype=np.float64)
        with np.errstate(divide="ignore", invalid="ignore"):
            out = rays[:, :2] / rays[:, 2:]
        return np.where(rays[:, 2:] > 1e-9, out, np.nan)

    def _from_plane(self, pts: FloatArray) -> FloatArray:
        """The inverse of :meth:`_to_plane`, (N, 2) -> pixels (NaN where the camera has no pixel)."""
        if self.camera is None:
            return pts
        return np.asarray(self.camera.project(np.c_[pts, np.ones(len(pts))]), dtype=np.float64)

    def _gate(self, sources: list[SduSource]) -> list[SduSource]:
        """Step 4: drop estimates far from the reference (ArUco median, else the n-fold tip)."""
        aru = [s for s in sources if s.kind != "nfold"]
        if len(sources) < 2 or not aru:
            return sources
        ref = np.median(np.array([s.pixel for s in aru]), axis=0)
        # The reference is only as good as the markers it comes from: a lone marker of a few pixels
        # extrapolates the pad centre with a sigma of several pixels, and must not gate out an n-fold
        # tip that agrees with it within that uncertainty (3 sigma of the difference).
        ref_sigma = float(np.median([s.sigma_px for s in aru])) / math.sqrt(len(aru))
        side_px = []
        for s in aru:
            e = s.points[[1, 2, 3, 0]] - s.points
            side_px.append(float(np.mean(np.hypot(e[:, 0], e[:, 1]))))
        pad_px = float(np.median(side_px)) / self.pad.aruco_size_m * self.pad.size_m
        gate = max(self.gate_min_px, self.gate_frac * pad_px)
        out = []
        for s in sources:
            radius = max(gate, 3.0 * math.hypot(s.sigma_px, ref_sigma))
            ok = bool(np.hypot(*(s.pixel - ref)) <= radius)
            out.append(s if ok else _replace_used(s, False))
        return out

    def _fuse(self, t: float, sources: list[SduSource], nf: NFoldResult | None) -> SduDetection | None:
        """Steps 5-6: inverse-variance mean of the used pixels, circular mean of the yaws."""
        used = [s for s in sources if s.used]
        if not used:
            return None
        w = np.array([1.0 / s.sigma_px**2 for s in used])
        px = (w[:, None] * np.array([s.pixel for s in used])).sum(axis=0) / w.sum()
        sigma = float(1.0 / math.sqrt(w.sum()))
        yaws = [s.yaw_CP for s in used if s.kind != "nfold" and s.yaw_CP is not None]
        n = self.pad.nfold_order
        for s in used:
            if s.kind == "nfold" and s.yaw_CP is not None:
                if yaws:
                    ref = math.atan2(sum(math.sin(a) for a in yaws), sum(math.cos(a) for a in yaws))
                    yaws.append(ref + math.remainder(s.yaw_CP - ref, 2.0 * math.pi / n))
                elif self.pad.nfold_oriented:
                    yaws.append(s.yaw_CP)
        yaw = math.atan2(sum(math.sin(a) for a in yaws), sum(math.cos(a) for a in yaws)) if yaws else None
        quality = max(s.quality for s in used)
        return SduDetection(
            t=t,
            pixel=px,
            sigma_px=sigma,
            quality=float(quality),
            yaw_CP=yaw,
            sources=tuple(sources),
            nfold=nf,
        )


def _replace_used(s: SduSource, used: bool) -> SduSource:
    return SduSource(s.kind, s.pixel, s.sigma_px, s.yaw_CP, s.quality, s.points, s.points_P, used)


__all__ = ["SduDetection", "SduMarkerDetector", "SduSource"]
