"""Fault injection: sensor and perception faults, each applied where it happens on a real vehicle.

The runner builds one :class:`Faults` from the scenario's ``faults`` section and calls it on the sensor
data on their way into the pipeline. Nothing here knows the pipeline's internals: a fault only changes
(or withholds) what a sensor hands over, exactly as a real failure would. Where each fault acts:

- camera frames (vision presets), before the detector: lost frames are not delivered
  (``dropout_prob``: a frame the driver never hands over), a blacked-out camera delivers dark frames
  (``blackouts``: a covered lens or a dead sensor still produces frames, all black), and corrupted frames
  are delivered corrupted (``corruption``: noise bursts, occlusion, exposure spikes, frozen frames,
  stripes). For the ground-truth sensor (no image) dropouts and blackouts stay in
  :class:`~alight.sim.truth_perception.TruthPerception`, as before, and a frozen frame re-delivers the
  previous report with the new capture time; the image corruptions have no meaning without an image and
  are refused (:meth:`Faults.check_preset`). The runner draws a camera frame's fate (:meth:`Faults.fate`)
  when it is captured, before rendering, and renders only a frame that is delivered and not dark
  (:meth:`Faults.deliver` then corrupts it): a lost or dark frame costs no rendering.
- detection latency (every preset): each frame reaches the pipeline ``perception.latency_s +
  faults.latency_s`` after capture, plus a uniform jitter of +-``latency_jitter_s``, never before the
  frame captured before it (a detector processes frames one after the other, so results come out in
  capture order: a late frame delays the next ones rather than being overtaken).
- IMU bias steps: added to the simulated IMU's bias state (``Imu.step_bias``) at their time, so the
  compiled IMU kernel carries them from that sample on, with its random walk on top.
- odometry: a jump shifts every later position message by its offset (the VIO re-localised into a
  shifted frame; velocity and attitude are unaffected); a dropout withholds messages (the odometry
  still runs underneath: its drift goes on).
- range finder: a dropout makes the reading invalid (``+inf``, what the TeraRanger driver reports when
  nothing returns); a spurious return replaces it with a reading uniform over the sensor's span.
- optical flow (a vehicle with ``optical_flow:``): a dropout withholds the sample, as PX4 drops a sample
  of quality 0 (a dark or featureless surface, a dead module). The pipeline then has no measurement of
  the deck under the feet, and its gate on it stays silent.

Randomness: every fault draws from its own generator, a child of the ``SeedSequence`` the runner gives
(a child of the scenario's seed that no other component uses), and draws the same numbers per frame or
reading whether or not it fires. So faults never change another component's random numbers (a mission
without faults is bit-identical to one flown before faults existed), and one fault's setting does not
change which frames another fault hits.
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from alight.errors import ConfigError
from alight.types import EgoState, FloatArray, Observation

if TYPE_CHECKING:
    from alight.scenario import FaultSpec, SpeedProfileSpec
    from alight.sim.platform import SpeedProfile
    from alight.sim.sensors import Imu

Frame = NDArray[np.uint8]

# Child generators of the fault SeedSequence, one per fault (the order fixes the streams).
# A new fault's stream goes last: SeedSequence children are numbered, so the others keep their numbers.
_STREAMS = ("drop", "latency", "noise", "occlusion", "exposure", "frozen", "stripes", "range", "flow")


@dataclasses.dataclass(frozen=True)
class FrameFate:
    """What happens to one camera frame (:meth:`Faults.fate`), drawn before the frame is rendered."""

    dropped: bool = False
    """Lost: never delivered (no need to render it)."""
    dark: bool = False
    """In a blackout: delivered all black (no need to render it)."""
    frozen: bool = False
    """The previous delivered frame is delivered again."""
    exposure: bool = False
    """An exposure spike."""
    noise_seed: int | None = None
    """The seed of a noise burst's noise on this frame, or None."""
    occlusion: tuple[float, float, float, float] | None = None
    """An occluder's (width, height, x, y) draws, or None."""
    stripes: tuple[float, float, float, int] | None = None
    """Stripes' (orientation, width, position draws, garbage seed), or None."""

    @property
    def needs_image(self) -> bool:
        """Whether the delivered frame shows the rendered image (not lost, not dark)."""
        return not (self.dropped or self.dark)


_AS_CAPTURED = FrameFate()
"""The fate of every frame of a mission without frame faults: delivered as captured."""


def _in_any(t: float, intervals: list[tuple[float, float]]) -> bool:
    return any(t0 <= t <= t1 for t0, t1 in intervals)


def speed_profile(spec: SpeedProfileSpec | None, speed_mps: float) -> SpeedProfile | None:
    """The platform's :class:`~alight.sim.platform.SpeedProfile` from the scenario's ``speed_profile``."""
    from alight.sim.platform import SpeedProfile

    if spec is None:
        return None
    if spec.brake_stop is not None:
        b = spec.brake_stop
        return SpeedProfile.brake_stop(speed_mps, b.t_s, b.decel_mps2, b.wait_s, b.accel_mps2)
    if spec.ramp is None:  # the scenario's validator makes one of them present
        raise ConfigError("platform.speed_profile needs one of brake_stop or ramp")
    r = spec.ramp
    return SpeedProfile.ramp(speed_mps, r.t_s, r.speed_mps, r.accel_mps2)


class Faults:
    """The faults of one mission, applied to sensor data on their way into the pipeline."""

    def __init__(
        self,
        spec: FaultSpec,
        seeds: np.random.SeedSequence,
        *,
        camera: bool,
        latency_s: float,
        extra_dropout_prob: float = 0.0,
        range_span_m: tuple[float, float] = (0.0, 14.0),
        tick_dt: float = 0.005,
    ) -> None:
        """``camera``: the preset delivers images (else observations of the ground-truth sensor);
        ``latency_s``: the scenario's ``perception.latency_s`` (s); ``extra_dropout_prob``: the
        scenario's ``perception.dropout_prob`` (it acts on camera frames here; the ground-truth sensor
        applies it itself); ``range_span_m``: the range finder's (min, max) reading (m), for spurious
        returns; ``tick_dt``: the IMU sample period (s), for placing bias steps on samples."""
        self.spec = spec
        self.camera = camera
        self._rng = dict(
            zip(_STREAMS, (np.random.default_rng(c) for c in seeds.spawn(len(_STREAMS))), strict=True)
        )
        self._latency_s = latency_s
        self._extra_latency_s = spec.latency_s
        self._jitter_s = spec.latency_jitter_s
        self._last_delivery = -math.inf
        self._drop_prob = min(1.0, spec.dropout_prob + extra_dropout_prob)
        self._blackouts = [(float(a), float(b)) for a, b in spec.blackouts]
        c = spec.corruption
        self._corrupt = c.active()
        self._noise_left = 0  # frames left in the current noise burst
        self._last_frame: Frame | list[Observation] | None = None
        self._range_span = range_span_m
        self._range_dropouts = [(float(a), float(b)) for a, b in spec.range_dropouts]
        self._flow_dropouts = [(float(a), float(b)) for a, b in spec.flow_dropouts]
        self._flow_active = spec.acts_on_flow()
        self._odo_dropouts = [(float(a), float(b)) for a, b in spec.odometry_dropouts]
        self._jumps = sorted((j.t_s, np.array(j.offset_m, dtype=np.float64)) for j in spec.odometry_jumps)
        self._announced = sorted(j.t_s for j in spec.odometry_jumps if j.announced)
        self.odometry_reset_counter = 0
        """The odometry's reset counter (MAVLink ODOMETRY ``reset_counter``) as of the last message:
        the announced jumps so far."""
        # IMU bias steps on the sample index k (time k * tick_dt) of the first sample that carries them.
        steps: dict[int, FloatArray] = {}
        for offset, bias_steps in ((0, spec.accel_bias_steps), (3, spec.gyro_bias_steps)):
            for b in bias_steps:
                k = max(1, math.ceil(b.t_s / tick_dt - 1e-9))
                d = steps.setdefault(k, np.zeros(6))
                d[offset : offset + 3] += b.delta
        self._bias_ticks = sorted(steps)
        self._bias_steps = steps
        self._frames_active = bool(self._corrupt or (camera and (self._drop_prob > 0 or self._blackouts)))

    # -- refusals -------------------------------------------------------------------------------------
    def check_preset(self, preset: str, uses_camera: bool) -> None:
        """Refuse faults that cannot act on this preset (one ``ConfigError`` line)."""
        if not uses_camera:
            image_only = [n for n in self._corrupt if n != "frozen"]
            if image_only:
                raise ConfigError(
                    f"faults.corruption needs a camera preset: preset '{preset}' has no image for "
                    f"{', '.join(image_only)} to corrupt (only 'frozen' applies to it)"
                )

    # -- IMU -----------------------------------------------------------------------------------------
    def before_imu_batch(self, k: int, m: int, imu: Imu) -> int:
        """Called before the runner samples IMU ticks k .. k + m - 1 in one compiled batch: steps the
        IMU's bias for the steps due at tick k, and returns the batch length cut so that it ends before
        the next step (the kernel holds the bias input for a whole batch)."""
        while self._bias_ticks and self._bias_ticks[0] <= k:
            imu.step_bias(self._bias_steps.pop(self._bias_ticks.pop(0)))
        if self._bias_ticks:
            m = min(m, self._bias_ticks[0] - k)
        return m

    # -- odometry ------------------------------------------------------------------------------------
    def odometry(self, odo: EgoState) -> EgoState | None:
        """The odometry message as delivered: shifted by the jumps so far, or None during a dropout."""
        t = odo.t
        if self._odo_dropouts and _in_any(t, self._odo_dropouts):
            return None
        if not self._jumps or t < self._jumps[0][0]:
            return odo
        self.odometry_reset_counter = sum(t >= t_j for t_j in self._announced)
        offset = sum((d for t_j, d in self._jumps if t >= t_j), np.zeros(3))
        return EgoState.trusted(t, odo.p_WB + offset, odo.v_WB, odo.q_WB, odo.w_WB_B)

    # -- range finder ----------------------------------------------------------------------------------
    def range(self, t: float, r: float) -> float:
        """The range reading (m) as delivered: ``+inf`` (invalid) during a dropout, else possibly a
        spurious return."""
        s = self.spec
        if not (s.range_dropout_prob > 0 or s.range_spurious_prob > 0 or self._range_dropouts):
            return r
        u_drop, u_spur, u_value = self._rng["range"].random(3)
        if u_drop < s.range_dropout_prob or _in_any(t, self._range_dropouts):
            return math.inf
        if u_spur < s.range_spurious_prob:
            lo, hi = self._range_span
            return lo + float(u_value) * (hi - lo)
        return r

    # -- optical flow ----------------------------------------------------------------------------------
    def flow_delivered(self, t: float) -> bool:
        """Whether the optical-flow sample taken at ``t`` is delivered (False: dropped). One draw per
        sample whenever a flow fault is set, whether it fires or not."""
        if not self._flow_active:
            return True
        u_drop = float(self._rng["flow"].random())
        return not (u_drop < self.spec.flow_dropout_prob or _in_any(t, self._flow_dropouts))

    # -- camera frames / detections ------------------------------------------------------------------
    def delivery_time(self, t_capture: float) -> float:
        """When the frame captured at ``t_capture`` reaches the pipeline (s): after the latency with its
        jitter, and not before the previous frame."""
        t = t_capture + self._latency_s
        if self._extra_latency_s == 0.0 and self._jitter_s == 0.0:
            return t  # unchanged from a mission without latency faults
        u = float(self._rng["latency"].random())
        t = max(t + self._extra_latency_s + self._jitter_s * (2.0 * u - 1.0), t_capture)
        t = max(t, self._last_delivery)
        self._last_delivery = t
        return t

    def frame(self, t: float, frame: object) -> object | None:
        """The frame captured at ``t`` as the camera delivers it: None when it is lost, a dark frame in a
        blackout, corrupted, or the frame itself. ``frame`` is an image (uint8 array) for a camera
        preset, the ground-truth sensor's observations otherwise. It is never modified in place.

        The same as ``deliver(fate(t), frame)``: the runner calls those two instead, so that it renders
        only the frames that are delivered (and used)."""
        if not self._frames_active:
            return frame
        if not self.camera:
            return self._observations(t, frame)  # type: ignore[arg-type]
        return self.deliver(self.fate(t), frame)  # type: ignore[arg-type]

    @property
    def remembers_frames(self) -> bool:
        """Whether a delivered frame can come back later (a frozen frame repeats the last delivered
        one): then every delivered frame has to be rendered and passed to :meth:`deliver`, even one the
        detector will skip."""
        return self.camera and self.spec.corruption.frozen.prob > 0

    def fate(self, t: float) -> FrameFate:
        """Draw what happens to the camera frame captured at ``t``, before it is rendered: the random
        numbers of :meth:`frame`, drawn in the same order (one draw per frame and fault, fired or not),
        so a mission is the same whether the frame is then rendered or not. Camera presets only."""
        if not self._frames_active:
            return _AS_CAPTURED
        dropped = bool(self._rng["drop"].random() < self._drop_prob)
        c = self.spec.corruption
        rng = self._rng
        frozen = bool(rng["frozen"].random() < c.frozen.prob)
        exposure = bool(rng["exposure"].random() < c.exposure.prob)
        u = rng["noise"].random()
        if self._noise_left == 0 and u < c.noise.prob:
            self._noise_left = c.noise.frames
        noise_seed = int(rng["noise"].integers(2**63))
        noise = None
        if self._noise_left > 0:
            self._noise_left -= 1
            noise = noise_seed
        u, fw, fh, cx, cy = rng["occlusion"].random(5)
        occlusion = (float(fw), float(fh), float(cx), float(cy)) if u < c.occlusion.prob else None
        u, rows, width, pos = rng["stripes"].random(4)
        stripe_seed = int(rng["stripes"].integers(2**63))
        stripes = (float(rows), float(width), float(pos), stripe_seed) if u < c.stripes.prob else None
        return FrameFate(dropped, _in_any(t, self._blackouts), frozen, exposure, noise, occlusion, stripes)

    def deliver(self, fate: FrameFate, img: Frame | None) -> Frame | None:
        """The frame as the camera delivers it, given its :meth:`fate`: None when it is lost, a dark frame
        in a blackout, else ``img`` corrupted. ``img`` may be None when the fate is ``dropped``, and
        any image of the frame's shape when it is ``dark`` (neither needs rendering). Frames must
        be delivered in the order their fates were drawn (a frozen frame repeats the last delivered)."""
        if fate is _AS_CAPTURED:
            return img
        if fate.dropped:
            return None
        if img is None:
            raise ValueError("a delivered frame needs an image (any image of the frame's shape when dark)")
        out: Frame = np.zeros_like(img) if fate.dark else self._corrupted(fate, img)
        self._last_frame = out
        return out

    def _corrupted(self, f: FrameFate, img: Frame) -> Frame:
        c = self.spec.corruption
        out = img
        # frozen: the driver hands over its previous buffer again (with the new time stamp)
        if f.frozen and isinstance(self._last_frame, np.ndarray):
            out = self._last_frame.copy()
        if f.exposure:
            out = np.clip(out.astype(np.float32) * c.exposure.gain, 0, 255).astype(np.uint8)
        if f.noise_seed is not None:
            n = np.random.default_rng(f.noise_seed).standard_normal(out.shape, dtype=np.float32)
            out = np.clip(out.astype(np.float32) + c.noise.sigma_dn * n, 0, 255).astype(np.uint8)
        if f.occlusion is not None:
            fw, fh, cx, cy = f.occlusion
            H, W = out.shape[0], out.shape[1]
            w = max(1, int(round(W * c.occlusion.size_fraction * (0.5 + 0.5 * fw))))
            h = max(1, int(round(H * c.occlusion.size_fraction * (0.5 + 0.5 * fh))))
            x0, y0 = int(cx * (W - w)), int(cy * (H - h))
            out = out.copy() if out is img else out
            out[y0 : y0 + h, x0 : x0 + w] = c.occlusion.value_dn
        if f.stripes is not None:
            rows, width, pos, stripe_seed = f.stripes
            out = out.copy() if out is img else out
            axis = 0 if rows < 0.5 else 1
            n = out.shape[axis]
            lines = min(n, 1 + int(width * c.stripes.max_lines))
            a = int(pos * (n - lines + 1))
            band = (slice(a, a + lines),) if axis == 0 else (slice(None), slice(a, a + lines))
            garbage = np.random.default_rng(stripe_seed).integers(0, 256, out[band].shape, dtype=np.uint8)
            out[band] = garbage
        return out

    def _observations(self, t: float, obs: list[Observation]) -> list[Observation]:
        frozen = self._rng["frozen"].random() < self.spec.corruption.frozen.prob
        if frozen and isinstance(self._last_frame, list):
            out = [dataclasses.replace(o, t=t) for o in self._last_frame]
        else:
            out = obs
        self._last_frame = out
        return out
