"""The quality-of-service detector (paper 004's energy-sensitive deployment): a detector run at a
:class:`alight.energy.qos.QosSetting` (frame rate, image scale, n-fold kernel cap), the setting following
the mission phase and the view's tilt through a :class:`alight.energy.qos.PhasePolicy`. It declares the
context it takes (:class:`alight.perception.ModeAware`, :class:`alight.perception.TiltAware`); the energy
model and the policies stay in :mod:`alight.energy.qos`, which depends on no pipeline stage."""

from __future__ import annotations

import copy
import math
import time
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from alight.cameras import CameraModel
from alight.energy.qos import PhasePolicy, QosEnergyModel, QosSetting
from alight.perception.image_input import as_gray_u8
from alight.perception.nfold import NFoldDetector
from alight.perception.sdu_marker import SduMarkerDetector
from alight.types import FloatArray, Image, Mode, Observation

# --------------------------------------------------------------------------------------------------
# The QoS-aware detector
# --------------------------------------------------------------------------------------------------


class ScaledCamera:
    """A camera model seen through an image resize: pixels of the resized image (``sx = W' / W``,
    ``sy = H' / H``, pixel centres mapped as ``u' = (u + 0.5) sx - 0.5``). For detectors that undo lens
    distortion with their camera model while reading a resized image."""

    def __init__(self, camera: CameraModel, width: int, height: int) -> None:
        self.camera = camera
        self._w, self._h = int(width), int(height)
        self.sx = self._w / float(camera.width)
        self.sy = self._h / float(camera.height)

    @property
    def width(self) -> int:
        return self._w

    @property
    def height(self) -> int:
        return self._h

    def project(self, points_C: FloatArray) -> FloatArray:
        px = np.asarray(self.camera.project(points_C), dtype=np.float64)
        out: FloatArray = (px + 0.5) * np.array([self.sx, self.sy]) - 0.5
        return out

    def fov_rad(self) -> tuple[float, float]:
        """The camera's: a resize keeps the field of view."""
        return self.camera.fov_rad()

    def unproject(self, pixels: FloatArray) -> FloatArray:
        full = (np.asarray(pixels, dtype=np.float64) + 0.5) / np.array([self.sx, self.sy]) - 0.5
        return np.asarray(self.camera.unproject(full), dtype=np.float64)


def capped_kernel_sizes(sizes: Sequence[int], max_kernel_px: int) -> tuple[int, ...]:
    """The kernel sizes of ``sizes`` at most ``max_kernel_px``; ValueError when none is."""
    out = tuple(int(k) for k in sizes if k <= max_kernel_px)
    if not out:
        raise ValueError(
            f"max_kernel_px {max_kernel_px} is below the detector's smallest kernel size {min(sizes)}"
        )
    return out


class QosDetector:
    """A detector run at a QoS setting (module docstring). ``detect(image, t)`` has the Detector signature.

    Parameters
    ----------
    inner:
        The detector: an :class:`alight.perception.sdu_marker.SduMarkerDetector` (anything with an
        ``nfold`` attribute holding an :class:`~alight.perception.nfold.NFoldDetector` and an optional
        ``camera``), a bare ``NFoldDetector``, or any other detector (then ``max_kernel_px`` has no
        effect: it has no n-fold kernels).
    setting:
        The initial :class:`QosSetting`, or a :class:`PhasePolicy` (then the setting follows
        :meth:`set_mode`, starting from the policy's ``IDLE`` setting).
    throttle:
        Skip frames to the setting's rate (default). A skipped frame returns ``[]`` and costs nothing.
        With False every frame is processed (the caller decimates, e.g. with :meth:`due`).

    Attributes
    ----------
    frames_by_setting:
        Frames processed at each setting (for :meth:`QosEnergyModel.mission_energy_J`).
    frames_skipped:
        Frames skipped by the rate.
    cpu_s_measured:
        Process CPU seconds spent in the processed calls (resize, detection, mapping back); machine- and
        load-dependent, for information only.
    """

    def __init__(self, inner: Any, setting: QosSetting | PhasePolicy, *, throttle: bool = True) -> None:
        self.inner = inner
        self.policy = setting if isinstance(setting, PhasePolicy) else None
        first = setting.setting_for(Mode.IDLE) if isinstance(setting, PhasePolicy) else setting
        if not isinstance(first, QosSetting):
            raise ValueError(f"setting must be a QosSetting or a PhasePolicy, got {setting!r}")
        self.throttle = bool(throttle)
        self._variants: dict[tuple[int, int, int], Any] = {}
        self._setting = first
        self._check(first)
        self.mode: Mode | None = None
        self.oblique = False
        self._tilt_lp: float | None = None
        self._t_tilt: float | None = None
        self.frames_by_setting: dict[QosSetting, int] = {}
        self.frames_skipped = 0
        self.cpu_s_measured = 0.0
        self.last_cpu_s = 0.0
        self._t_next: float | None = None
        self._t_last: float | None = None

    # -------------------------------------------------------------------------------- settings

    @property
    def setting(self) -> QosSetting:
        return self._setting

    def set_setting(self, setting: QosSetting) -> None:
        """Use ``setting`` from the next frame on (the rate schedule restarts from the last processed
        frame)."""
        if not isinstance(setting, QosSetting):
            raise ValueError(f"setting must be a QosSetting, got {setting!r}")
        if setting == self._setting:
            return
        self._check(setting)
        self._setting = setting
        if self._t_last is not None:
            self._t_next = self._t_last + 1.0 / setting.rate_hz

    def set_mode(self, mode: Mode | str) -> None:
        """Switch to the policy's setting for ``mode`` (a no-op without a policy)."""
        self.mode = Mode(mode)
        if self.policy is not None:
            self.set_setting(self.policy.setting_for(self.mode, self.oblique))

    def set_view_tilt(self, t: float, tilt_rad: float) -> None:
        """The camera's tilt from nadir at time ``t`` (rad), for the policy's oblique settings. It is
        low-passed (1 s: a pattern corner is not a wind) and switches with 5 deg of hysteresis."""
        if self.policy is None or not self.policy.oblique or not math.isfinite(tilt_rad):
            return
        if self._tilt_lp is None or self._t_tilt is None:
            self._tilt_lp = tilt_rad
        else:
            dt = min(max(t - self._t_tilt, 0.0), 1.0)
            self._tilt_lp += dt / (1.0 + dt) * (tilt_rad - self._tilt_lp)
        self._t_tilt = t
        threshold = self.policy.oblique_tilt_rad
        oblique = self._tilt_lp > (threshold - math.radians(5.0) if self.oblique else threshold)
        if oblique != self.oblique:
            self.oblique = oblique
            if self.mode is not None:
                self.set_setting(self.policy.setting_for(self.mode, oblique))

    def _check(self, setting: QosSetting) -> None:
        sizes = self._nfold_sizes()
        if sizes is not None:
            capped_kernel_sizes(sizes, setting.max_kernel_px)

    def _nfold(self) -> NFoldDetector | None:
        if isinstance(self.inner, NFoldDetector):
            return self.inner
        if isinstance(self.inner, SduMarkerDetector):  # the n-fold marker plus its ArUco landmarks
            return self.inner.nfold
        return None

    def _nfold_sizes(self) -> tuple[int, ...] | None:
        nf = self._nfold()
        return None if nf is None else nf.config.kernel_sizes

    def kernel_sizes(self, setting: QosSetting | None = None) -> tuple[int, ...] | None:
        """The n-fold kernel sizes the detector tries at ``setting`` (default: the current one)."""
        sizes = self._nfold_sizes()
        s = self._setting if setting is None else setting
        return None if sizes is None else capped_kernel_sizes(sizes, s.max_kernel_px)

    def _variant(self, width: int, height: int, max_k: int) -> Any:
        """The inner detector with its kernel sizes capped and its camera model seen through the resize
        (cached per resized size and cap)."""
        key = (width, height, max_k)
        det = self._variants.get(key)
        if det is not None:
            return det
        inner = self.inner
        if isinstance(inner, NFoldDetector):
            cfg = replace(inner.config, kernel_sizes=capped_kernel_sizes(inner.config.kernel_sizes, max_k))
            det = NFoldDetector(cfg, tip_P=inner.tip_P)
        else:
            det = copy.copy(inner)
            if isinstance(det, SduMarkerDetector):
                nf = det.nfold
                cfg = replace(nf.config, kernel_sizes=capped_kernel_sizes(nf.config.kernel_sizes, max_k))
                det.nfold = NFoldDetector(cfg, tip_P=nf.tip_P)
                cam = det.camera
                if cam is not None and (int(cam.width), int(cam.height)) != (width, height):
                    det.camera = ScaledCamera(cam, width, height)
        self._variants[key] = det
        return det

    # -------------------------------------------------------------------------------- frames

    def due(self, t: float) -> bool:
        """Whether a frame captured at ``t`` is processed under the current rate: frames are taken on a
        schedule of ``1 / rate_hz`` from the first one (the next due time advances by one period, or
        restarts from ``t`` after a gap longer than a period), so a camera faster than the rate is
        decimated to the rate on average and a slower one gives every frame."""
        return self._t_next is None or t >= self._t_next - 1e-6

    def will_process(self, t_capture: float) -> bool:
        """Whether :meth:`detect` on the frame captured at ``t_capture``, called next, processes it
        (:class:`~alight.perception.FrameGate`): not when the rate skips it. No state changes."""
        return not self.throttle or self.due(t_capture)

    def _advance(self, t: float) -> None:
        period = 1.0 / self._setting.rate_hz
        if self._t_next is None or t - self._t_next >= period - 1e-6:
            self._t_next = t + period
        else:
            self._t_next += period
        self._t_last = t

    def detect(self, image: Image, t: float) -> list[Observation]:
        """Observations in full-resolution pixels, or ``[]`` for a skipped frame (see ``throttle``)."""
        if self.throttle and not self.due(t):
            self.frames_skipped += 1
            return []
        c0 = time.process_time()
        s = self._setting
        obs = self._run(image, t, s)
        dt = time.process_time() - c0
        self.last_cpu_s = dt
        self.cpu_s_measured += dt
        self.frames_by_setting[s] = self.frames_by_setting.get(s, 0) + 1
        self._advance(t)
        return obs

    def _run(self, image: Image, t: float, s: QosSetting) -> list[Observation]:
        gray = as_gray_u8(image)
        if gray is None:
            return []
        H, W = gray.shape
        # NDArray[Any]: OpenCV's stubs type cv2.resize as returning Mat | ndarray of any numeric dtype.
        small: NDArray[Any]
        if s.image_scale == 1.0:
            small = gray
        else:
            w2, h2 = max(1, int(round(W * s.image_scale))), max(1, int(round(H * s.image_scale)))
            small = cv2.resize(gray, (w2, h2), interpolation=cv2.INTER_AREA)
        h2, w2 = small.shape
        det = self._variant(w2, h2, s.max_kernel_px)
        obs = det.detect(small, t)
        if (w2, h2) == (W, H):
            return list(obs)
        return [_rescale(o, W / w2, H / h2) for o in obs]

    def energy_J(self, model: QosEnergyModel, duration_s: float = 0.0) -> float:
        """Compute energy of the frames processed so far (J), from ``model`` (deterministic):
        ``model.mission_energy_J(self.frames_by_setting, duration_s)``."""
        return model.mission_energy_J(self.frames_by_setting, duration_s)

    @property
    def frames_processed(self) -> int:
        return sum(self.frames_by_setting.values())


def _rescale(o: Observation, fx: float, fy: float) -> Observation:
    """An observation from a resized image in full-resolution pixels (``u = (u' + 0.5) fx - 0.5``); the
    orientation angle is mapped through the same anisotropic scale (``fx`` and ``fy`` differ by rounding
    only)."""
    px = o.pixels
    if px.size:
        px = (px + 0.5) * np.array([fx, fy]) - 0.5
    yaw = o.yaw_CP
    if yaw is not None:
        yaw = math.atan2(math.sin(yaw) * fy, math.cos(yaw) * fx)
    return Observation(
        t=o.t,
        kind=o.kind,
        quality=o.quality,
        pixels=px,
        points_P=o.points_P,
        p_CP=o.p_CP,
        cov_p_CP=o.cov_p_CP,
        yaw_CP=yaw,
    )


__all__ = ["QosDetector", "ScaledCamera", "capped_kernel_sizes"]
