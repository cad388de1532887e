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
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import alight
from alight.airframe import DEFAULT_AIRFRAME
from alight.errors import EstimationError, ReplayError
from alight.interfaces.replay_readers import (
    ImageSample,
    ImuSample,
    OdometrySample,
    RangeSample,
    Recording,
    ReplayMapping,
    Stream,
    TruthSample,
    load_mapping,
    open_recording,
)
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
    from alight.evaluation.log import MissionLog

    seeds = np.random.SeedSequence(sc.seed).spawn(8)
    preset = build_preset(sc, DEFAULT_AIRFRAME, np.random.default_rng(seeds[7]))
    pipeline = preset.pipeline
    log = MissionLog()
    frames: list[tuple[float, list[Observation]]] = []
    truth_ego: TruthSample | None = None
    truth_platform: TruthSample | None = None
    last_odo: OdometrySample | None = None
    platform_err: list[float] = []
    ego_err: list[float] = []
    skipped_frames = 0
    tick: int | None = None
    t_first: float | None = None
    t_last = -math.inf

    def run_ticks(until: float) -> None:
        nonlocal tick
        if not pipeline.ego_initialized:
            return
        if tick is None or until - tick * CONTROL_DT > MAX_GAP_S:
            # start, or a gap in the recording: the Pipeline's clock jumps over it instead of ticking
            # through (a damaged stamp far ahead must not cost hours of ticks)
            tick = math.floor(until / CONTROL_DT + 1e-9)
        while (tick + 1) * CONTROL_DT <= until + 1e-9:
            tick += 1
            t = tick * CONTROL_DT
            pipeline.command(t)
            if tick % LOG_EVERY == 0:
                _log_row(t)

    def _log_row(t: float) -> None:
        ego = pipeline.ego()
        target = pipeline.target(t)
        ref = truth_ego if truth_ego is not None else last_odo
        p_ref = None if ref is None else (ref.p_W if isinstance(ref, TruthSample) else ref.p_WB)
        q_ref = None if ref is None else (ref.q_W if isinstance(ref, TruthSample) else ref.q_WB)
        v_ref = None if ref is None else (ref.v_W if isinstance(ref, TruthSample) else ref.v_WB)
        log.append(
            t,
            mode=pipeline.status.mode.value,
            p_WB=p_ref,
            v_WB=v_ref,
            q_WB=q_ref,
            p_WB_est=ego.p_WB,
            v_WB_est=ego.v_WB,
            q_WB_est=ego.q_WB,
            p_WP=None if truth_platform is None else truth_platform.p_W,
            v_WP=None if truth_platform is None else truth_platform.v_W,
            p_WP_est=None if target is None else target.p_WP,
            v_WP_est=None if target is None else target.v_WP,
            range_m=pipeline.range_m,
        )
        if p_ref is not None:
            ego_err.append(float(np.linalg.norm(ego.p_WB - p_ref)))
        if target is not None and truth_platform is not None:
            platform_err.append(float(np.linalg.norm(target.p_WP - truth_platform.p_W)))

    def _feed(s: object) -> int:
        """Hand one sample to the Pipeline; 1 when it is a frame that could not be used, else 0."""
        nonlocal last_odo, truth_ego, truth_platform
        if isinstance(s, OdometrySample):
            last_odo = s
            pipeline.on_odometry(s.t, s.p_WB, s.q_WB, s.v_WB, s.reset_counter)
        elif isinstance(s, ImuSample):
            pipeline.on_imu(s.t, s.f_B, s.w_B)
        elif isinstance(s, RangeSample):
            if pipeline.ego_initialized:  # as the runner: ranges once the ego state is known
                pipeline.on_range(s.t, s.range_m)
        elif isinstance(s, ImageSample):
            if pipeline.detector is None or not pipeline.ego_initialized:
                return 1
            observations, measurements = pipeline.on_image(s.t_capture, s.image)
            frames.append((s.t_capture, observations))
            for meas in measurements:
                log.add_detection(meas.t, meas.p_WP)
        elif isinstance(s, TruthSample):
            if s.stream is Stream.TRUTH_EGO:
                truth_ego = s
            else:
                truth_platform = s
        return 0

    t_now = -math.inf
    try:
        for s in rec.samples():
            t_now = s.t
            t_first = s.t if t_first is None else t_first
            t_last = max(t_last, s.t)
            run_ticks(s.t)
            skipped_frames += _feed(s)
        if t_first is not None:
            run_ticks(t_last)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError, EstimationError) as err:
        # the values of a damaged log can still reach a block that refuses them: one line, not a trace
        raise ReplayError(
            f"{rec.path}: the Pipeline cannot use the message at t={t_now:.3f} s ({err})"
        ) from None

    if t_first is None:
        raise ReplayError(f"{rec.path}: no messages on the mapped topics")
    if not pipeline.ego_initialized:
        raise ReplayError(
            f"{rec.path}: the ego state never started: no message on the odometry topic "
            f"({rec.topics.get(Stream.ODOMETRY.value, 'none mapped')})"
        )
    arrays = log.finalize()
    stats = pipeline.stats
    n_obs = sum(len(o) for _, o in frames)
    result: dict[str, Any] = {
        "source": str(rec.path),
        "format": rec.format,
        "preset": sc.preset,
        "seed": sc.seed,
        "outcome": "replayed",
        "topics": dict(rec.topics),
        "messages": dict(sorted(rec.counts.items())),
        "t_start_s": t_first,
        "t_end_s": t_last,
        "duration_s": t_last - t_first,
        "frames": len(frames),
        "frames_skipped": skipped_frames,
        "bad_frames": rec.bad_frames,
        "dropped_messages": rec.dropped,
        "warnings": list(rec.warnings),
        "frames_with_observations": sum(1 for _, o in frames if o),
        "observations": n_obs,
        "detections": stats.measurements,
        "rejected_measurements": stats.rejected_measurements,
        "time_first_detection_s": stats.t_first_detection,
        "ego_reference": "ground truth"
        if Stream.TRUTH_EGO.value in rec.topics
        else "odometry (the log has no ground truth)",
        "ego_estimate_rmse_m": _rmse(ego_err),
        "platform_estimate_rmse_m": _rmse(platform_err),
        "platform_ground_truth": Stream.TRUTH_PLATFORM.value in rec.topics,
        "ego_extent_m": _extent(arrays["p_WB"]),
        "ego_estimate_extent_m": _extent(arrays["p_WB_est"]),
        "block_time_s": {k: round(v, 6) for k, v in stats.block_time_s.items()},
        "wall_time_s": time.perf_counter() - wall0,
        "alight_version": alight.__version__,
    }
    return ReplayRun(result=result, log=arrays, frames=frames)


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
    from alight.evaluation.report import write_mission_report

    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ReplayError(f"{out}: cannot create the output directory ({err.strerror})") from None
    run = replay_recording(log_path, mapping=mapping, scenario=scenario)
    save_arrays(run.log, out)
    _write_frames(out / FRAMES_CSV, run.frames)
    if report:
        events = {"t_first_detection": run.result["time_first_detection_s"]}
        write_mission_report(out, run.result, run.log, events)
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
