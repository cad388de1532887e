"""Replay a recorded flight through a preset's Pipeline, offline: ``alight replay LOG --out DIR``.

The recording's odometry, IMU, range and camera frames drive the same ``on_odometry``, ``on_imu``,
``on_range`` and ``on_image`` the simulator's runner drives, in time order. Between messages the
Pipeline's ``command`` runs at the controller's 100 Hz on the recording's clock, so the ego history that
geolocation reads is filled as in flight; the mission is never stepped (it stays idle) and the commands
go nowhere: this is perception and estimation, judged on what was recorded.

Writes into ``DIR``: ``result.json`` (what was replayed: topics, duration, messages per stream, frames,
detections, estimate statistics), ``log.npz`` / ``log.csv`` / ``log_detections.csv`` (the mission log's
channels: ``p_WB`` is the log's ground truth when it has one, else the recorded odometry, the reference
the ego estimate is compared with), ``frames.csv`` (one row per camera frame: capture time, what the
detector found) and ``report.html``.
"""

from __future__ import annotations

import csv
import dataclasses
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

import alight
from alight.airframe import DEFAULT_AIRFRAME
from alight.errors import EstimationError, ReplayError
from alight.evaluation.recorded_flight import (
    FRAME_WIDTH_PX,
    FRAMES_SHOWN,
    CameraFrame,
    FrameSampler,
    PoseTrack,
    RecordedFlight,
    estimate_differences,
    frames_to_show,
)
from alight.interfaces.replay_readers import (
    FloatArray,
    ImageSample,
    ImuSample,
    OdometrySample,
    RangeSample,
    Recording,
    ReplayMapping,
    Sample,
    Stream,
    TruthSample,
    load_mapping,
    open_recording,
)
from alight.mission.pipeline import Pipeline
from alight.mission.presets import build_preset
from alight.scenario import Scenario, load_scenario, scenario_from_dict
from alight.types import Observation

CONTROL_DT = 0.01
"""Period of the Pipeline's ``command`` on the recording's clock (s), as in the runner."""
LOG_EVERY = 2
"""A log row every this many control ticks (50 Hz)."""
MAX_GAP_S = 1.0
"""A gap between two messages longer than this (s) is jumped over, not ticked through."""
DEFAULT_PRESET = "falanga2017"
FRAMES_CSV = "frames.csv"


@dataclass
class ReplayRun:
    """What a replay produced."""

    result: dict[str, Any]
    log: dict[str, np.ndarray]
    recorded: RecordedFlight
    """the log's own streams, messages and a few camera frames, for the recorded flight's report"""
    frames: list[tuple[float, list[Observation]]] = field(default_factory=list)
    """(capture time, observations) of every camera frame the detector saw, in order"""


def _scenario(scenario: str | Path | Scenario | None) -> Scenario:
    if isinstance(scenario, Scenario):
        return scenario
    if scenario is None:
        return scenario_from_dict({"preset": DEFAULT_PRESET}, source="replay default")
    return load_scenario(scenario)


def replay_recording(
    log_path: str | Path,
    *,
    mapping: ReplayMapping | str | Path | None = None,
    scenario: str | Path | Scenario | None = None,
) -> ReplayRun:
    """Replay the flight recorded in ``log_path`` through the Pipeline of ``scenario``'s preset
    (``falanga2017`` when no scenario is given) and return the result, the log and the frames.

    Raises:
        ReplayError: the log cannot be read, or has nothing to replay.
        ConfigError: the scenario is invalid.
    """
    wall0 = time.perf_counter()
    m = mapping if isinstance(mapping, ReplayMapping) else load_mapping(mapping)
    sc = _scenario(scenario)
    rec = open_recording(log_path, m)
    try:
        return _run(rec, sc, wall0)
    finally:
        rec.close()


def _run(rec: Recording, sc: Scenario, wall0: float) -> ReplayRun:
    seeds = np.random.SeedSequence(sc.seed).spawn(8)
    preset = build_preset(sc, DEFAULT_AIRFRAME, np.random.default_rng(seeds[7]))
    state = _ReplayState(preset.pipeline)
    _drive(rec, state)
    _check_replayed(rec, state)
    arrays = state.log.finalize()
    recorded = state.kept.recorded_flight(rec)
    result = _result(rec, sc, state, arrays, recorded, wall0)
    return ReplayRun(result=result, log=arrays, recorded=recorded, frames=state.frames)


class _StreamKeeper:
    """The recording's streams as the replay reads them, at their own rates, and a few camera frames
    (downscaled, with their observations) spread over the flight, for the report."""

    def __init__(self) -> None:
        self.odometry: list[OdometrySample] = []
        self.truth: list[TruthSample] = []
        self.imu: list[ImuSample] = []
        self.ranges: list[RangeSample] = []
        self.with_detections = FrameSampler(FRAMES_SHOWN)
        self.without = FrameSampler(FRAMES_SHOWN)

    def keep(self, s: Sample) -> None:
        if isinstance(s, OdometrySample):
            self.odometry.append(s)
        elif isinstance(s, ImuSample):
            self.imu.append(s)
        elif isinstance(s, RangeSample):
            self.ranges.append(s)
        elif isinstance(s, TruthSample) and s.stream is Stream.TRUTH_EGO:
            self.truth.append(s)

    def keep_frame(self, t: float, image: np.ndarray, observations: list[Observation]) -> None:
        sampler = self.with_detections if observations else self.without
        sampler.offer(lambda: _thumbnail(t, image, observations))

    def recorded_flight(self, rec: Recording) -> RecordedFlight:
        odo = rec.topics.get(Stream.ODOMETRY.value, "")
        estimate = f"PX4's estimate ({odo})" if rec.format == "ulog" else f"the log's odometry ({odo})"
        truth = _pose_track([(s.t, s.p_W, s.q_W, s.v_W) for s in self.truth]) if self.truth else None
        return RecordedFlight(
            estimate_label=estimate,
            odometry=_pose_track([(s.t, s.p_WB, s.q_WB, s.v_WB) for s in self.odometry]),
            truth=truth,
            truth_label=f"ground truth ({rec.topics.get(Stream.TRUTH_EGO.value, '')})",
            imu_t=np.array([s.t for s in self.imu], dtype=np.float64),
            f_B=np.array([s.f_B for s in self.imu], dtype=np.float64).reshape(-1, 3),
            w_B=np.array([s.w_B for s in self.imu], dtype=np.float64).reshape(-1, 3),
            range_t=np.array([s.t for s in self.ranges], dtype=np.float64),
            range_m=np.array([math.nan if s.range_m is None else s.range_m for s in self.ranges]),
            messages=list(rec.messages),
            warnings=list(rec.warnings),
            vehicle=rec.vehicle,
            frames=frames_to_show(self.with_detections, self.without),
        )


def _pose_track(rows: list[tuple[float, FloatArray, FloatArray | None, FloatArray | None]]) -> PoseTrack:
    """A :class:`PoseTrack` of (t, p, q, v) rows, NaN where q or v is missing."""
    if not rows:
        return PoseTrack.empty()
    nan3, nan4 = np.full(3, np.nan), np.full(4, np.nan)
    return PoseTrack(
        np.array([r[0] for r in rows], dtype=np.float64),
        np.array([r[1] for r in rows], dtype=np.float64),
        np.array([nan4 if r[2] is None else r[2] for r in rows], dtype=np.float64),
        np.array([nan3 if r[3] is None else r[3] for r in rows], dtype=np.float64),
    )


def _thumbnail(t: float, image: np.ndarray, observations: list[Observation]) -> CameraFrame:
    """The frame at most :data:`FRAME_WIDTH_PX` wide, its observations' pixels scaled with it."""
    width = image.shape[1]
    if width <= FRAME_WIDTH_PX:
        return CameraFrame(t, image.copy(), list(observations))
    s = FRAME_WIDTH_PX / width
    size = (FRAME_WIDTH_PX, max(round(image.shape[0] * s), 1))
    small = cv2.resize(image, size, interpolation=cv2.INTER_AREA)
    scaled = [dataclasses.replace(o, pixels=o.pixels * s) for o in observations]
    return CameraFrame(t, np.ascontiguousarray(small, dtype=np.uint8), scaled)


class _ReplayState:
    """The Pipeline fed by the recording, its clock on the recording's time, and what the replay keeps:
    the mission log, the frames and their observations, the latest odometry and truth, the estimate
    errors against the reference (the truth when the log has it, else its odometry)."""

    def __init__(self, pipeline: Pipeline) -> None:
        from alight.evaluation.log import MissionLog

        self.pipeline = pipeline
        self.log = MissionLog()
        self.frames: list[tuple[float, list[Observation]]] = []
        self.truth_ego: TruthSample | None = None
        self.truth_platform: TruthSample | None = None
        self.last_odo: OdometrySample | None = None
        self.platform_err: list[float] = []
        self.ego_err: list[float] = []
        self.skipped_frames = 0
        self.tick: int | None = None
        self.t_first: float | None = None
        self.t_last = -math.inf
        self.kept = _StreamKeeper()

    def run_ticks(self, until: float) -> None:
        """Run the Pipeline's ``command`` at the control rate up to ``until``, logging every
        :data:`LOG_EVERY` ticks."""
        if not self.pipeline.ego_initialized:
            return
        if self.tick is None or until - self.tick * CONTROL_DT > MAX_GAP_S:
            # start, or a gap in the recording: the Pipeline's clock jumps over it instead of ticking
            # through (a damaged stamp far ahead must not cost hours of ticks)
            self.tick = math.floor(until / CONTROL_DT + 1e-9)
        while (self.tick + 1) * CONTROL_DT <= until + 1e-9:
            self.tick += 1
            t = self.tick * CONTROL_DT
            self.pipeline.command(t)
            if self.tick % LOG_EVERY == 0:
                self.log_row(t)

    def _reference(self) -> tuple[FloatArray | None, FloatArray | None, FloatArray | None]:
        """(p, q, v) the ego estimate is compared with: the truth when the log has it, else the
        latest odometry; Nones before either."""
        if self.truth_ego is not None:
            return self.truth_ego.p_W, self.truth_ego.q_W, self.truth_ego.v_W
        if self.last_odo is not None:
            return self.last_odo.p_WB, self.last_odo.q_WB, self.last_odo.v_WB
        return None, None, None

    def log_row(self, t: float) -> None:
        pipeline = self.pipeline
        ego = pipeline.ego()
        target = pipeline.target(t)
        p_ref, q_ref, v_ref = self._reference()
        platform = self.truth_platform
        self.log.append(
            t,
            mode=pipeline.status.mode.value,
            p_WB=p_ref,
            v_WB=v_ref,
            q_WB=q_ref,
            p_WB_est=ego.p_WB,
            v_WB_est=ego.v_WB,
            q_WB_est=ego.q_WB,
            p_WP=None if platform is None else platform.p_W,
            v_WP=None if platform is None else platform.v_W,
            p_WP_est=None if target is None else target.p_WP,
            v_WP_est=None if target is None else target.v_WP,
            range_m=pipeline.range_m,
        )
        if p_ref is not None:
            self.ego_err.append(float(np.linalg.norm(ego.p_WB - p_ref)))
        if target is not None and platform is not None:
            self.platform_err.append(float(np.linalg.norm(target.p_WP - platform.p_W)))

    def feed(self, s: Sample) -> None:
        """Hand one sample to the Pipeline (a frame it cannot use yet is counted as skipped)."""
        pipeline = self.pipeline
        self.kept.keep(s)
        if isinstance(s, OdometrySample):
            self.last_odo = s
            pipeline.on_odometry(s.t, s.p_WB, s.q_WB, s.v_WB, s.reset_counter)
        elif isinstance(s, ImuSample):
            pipeline.on_imu(s.t, s.f_B, s.w_B)
        elif isinstance(s, RangeSample):
            if pipeline.ego_initialized:  # as the runner: ranges once the ego state is known
                pipeline.on_range(s.t, s.range_m)
        elif isinstance(s, ImageSample):
            self._feed_image(s)
        elif s.stream is Stream.TRUTH_EGO:
            self.truth_ego = s
        else:
            self.truth_platform = s

    def _feed_image(self, s: ImageSample) -> None:
        pipeline = self.pipeline
        if pipeline.detector is None or not pipeline.ego_initialized:
            self.skipped_frames += 1
            return
        observations, measurements = pipeline.on_image(s.t_capture, s.image)
        self.frames.append((s.t_capture, observations))
        self.kept.keep_frame(s.t_capture, s.image, observations)
        for meas in measurements:
            self.log.add_detection(meas.t, meas.p_WP)


def _drive(rec: Recording, state: _ReplayState) -> None:
    """Every sample of the recording, in time order, into the Pipeline, its clock ticking between them.

    Raises:
        ReplayError: a block refuses a (damaged) value.
    """
    t_now = -math.inf
    try:
        for s in rec.samples():
            t_now = s.t
            state.t_first = s.t if state.t_first is None else state.t_first
            state.t_last = max(state.t_last, s.t)
            state.run_ticks(s.t)
            state.feed(s)
        if state.t_first is not None:
            state.run_ticks(state.t_last)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError, EstimationError) as err:
        # the values of a damaged log can still reach a block that refuses them: one line, not a trace
        raise ReplayError(
            f"{rec.path}: the Pipeline cannot use the message at t={t_now:.3f} s ({err})"
        ) from None


def _check_replayed(rec: Recording, state: _ReplayState) -> None:
    """Refuse, in one line, a recording that gave nothing to replay or never started the ego state."""
    if state.t_first is None:
        raise ReplayError(f"{rec.path}: no messages on the mapped topics")
    if not state.pipeline.ego_initialized:
        raise ReplayError(
            f"{rec.path}: the ego state never started: no message on the odometry topic "
            f"({rec.topics.get(Stream.ODOMETRY.value, 'none mapped')})"
        )


def _result(
    rec: Recording,
    sc: Scenario,
    state: _ReplayState,
    arrays: dict[str, np.ndarray],
    recorded: RecordedFlight,
    wall0: float,
) -> dict[str, Any]:
    """``result.json``'s content: what was replayed and how the estimates did (``ego_vs_log_estimate``:
    alight's ego estimate against the log's own; ``ego_vs_truth`` against the log's ground truth)."""
    assert state.t_first is not None  # _check_replayed
    stats = state.pipeline.stats
    frames = state.frames
    differences = dict(estimate_differences(recorded, arrays))
    vs_truth = differences.get("ground truth")
    return {
        "source": str(rec.path),
        "format": rec.format,
        "preset": sc.preset,
        "seed": sc.seed,
        "outcome": "replayed",
        "topics": dict(rec.topics),
        "messages": dict(sorted(rec.counts.items())),
        "t_start_s": state.t_first,
        "t_end_s": state.t_last,
        "duration_s": state.t_last - state.t_first,
        "frames": len(frames),
        "frames_skipped": state.skipped_frames,
        "bad_frames": rec.bad_frames,
        "dropped_messages": rec.dropped,
        "warnings": list(rec.warnings),
        "frames_with_observations": sum(1 for _, o in frames if o),
        "observations": sum(len(o) for _, o in frames),
        "detections": stats.measurements,
        "rejected_measurements": stats.rejected_measurements,
        "time_first_detection_s": stats.t_first_detection,
        "ego_reference": "ground truth"
        if Stream.TRUTH_EGO.value in rec.topics
        else "odometry (the log has no ground truth)",
        "ego_estimate_rmse_m": _rmse(state.ego_err),
        "platform_estimate_rmse_m": _rmse(state.platform_err),
        "platform_ground_truth": Stream.TRUTH_PLATFORM.value in rec.topics,
        "ego_extent_m": _extent(arrays["p_WB"]),
        "ego_estimate_extent_m": _extent(arrays["p_WB_est"]),
        "ego_vs_log_estimate": differences["the log's estimate"].summary(),
        "ego_vs_truth": None if vs_truth is None else vs_truth.summary(),
        "vehicle": recorded.vehicle or None,
        "log_messages": len(recorded.messages),
        "block_time_s": {k: round(v, 6) for k, v in stats.block_time_s.items()},
        "wall_time_s": time.perf_counter() - wall0,
        "alight_version": alight.__version__,
    }


def _rmse(err: list[float]) -> float | None:
    a = np.asarray(err, dtype=np.float64)
    a = a[np.isfinite(a)]
    return float(np.sqrt(np.mean(a**2))) if a.size else None


def _extent(p: np.ndarray) -> dict[str, list[float]] | None:
    ok = np.isfinite(p).all(axis=1)
    if not ok.any():
        return None
    lo, hi = p[ok].min(axis=0), p[ok].max(axis=0)
    return {a: [float(lo[i]), float(hi[i])] for i, a in enumerate("xyz")}


def replay_to_dir(
    log_path: str | Path,
    out_dir: str | Path,
    *,
    mapping: ReplayMapping | str | Path | None = None,
    scenario: str | Path | Scenario | None = None,
    report: bool = True,
) -> ReplayRun:
    """:func:`replay_recording`, then write ``result.json``, the log, ``frames.csv`` and ``report.html``
    into ``out_dir`` (created if needed)."""
    from alight.evaluation.log import save_arrays
    from alight.evaluation.mission_io import write_result
    from alight.evaluation.recorded_report import write_recorded_report

    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ReplayError(f"{out}: cannot create the output directory ({err.strerror})") from None
    run = replay_recording(log_path, mapping=mapping, scenario=scenario)
    save_arrays(run.log, out)
    _write_frames(out / FRAMES_CSV, run.frames)
    if report:
        write_recorded_report(out, run.result, run.log, run.recorded)
    write_result(out, run.result)
    return run


def _write_frames(path: Path, frames: list[tuple[float, list[Observation]]]) -> None:
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["t_capture", "n_observations", "kind", "quality", "u_px", "v_px"])
        for t, obs in frames:
            if not obs:
                w.writerow([t, 0, "", "", "", ""])
                continue
            best = max(obs, key=lambda o: o.quality)
            u, v = (best.pixels.mean(axis=0).tolist()) if best.pixels.shape[0] else (math.nan, math.nan)
            w.writerow([t, len(obs), best.kind, best.quality, u, v])
