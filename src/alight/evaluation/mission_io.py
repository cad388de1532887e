"""Fly one mission and write everything a person or a campaign needs into its directory:
``result.json``, ``log.npz`` / ``log.csv`` / ``log_detections.csv``, the figures and ``report.html``."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from alight.errors import InputError
from alight.evaluation.log import save_arrays
from alight.evaluation.replay import REPLAY_GIF, FrameRecorder, write_replay
from alight.evaluation.report import write_mission_report
from alight.evaluation.result import SCENARIO_YAML, write_scenario_yaml
from alight.evaluation.runner import FrameSink, MissionRun, run_mission
from alight.scenario import Scenario

RESULT_JSON = "result.json"


def _json_safe(value: Any) -> Any:
    # NaN and inf are not JSON; a reader should see null, not a parse error.
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    return value


def write_result(out_dir: Path, result: dict[str, Any]) -> Path:
    path = out_dir / RESULT_JSON
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(_json_safe(result), indent=2, sort_keys=False), encoding="utf-8")
    tmp.replace(path)  # atomic: a reader never sees half a file
    return path


def _fan_out(sinks: Sequence[FrameSink]) -> FrameSink | None:
    if not sinks:
        return None
    if len(sinks) == 1:
        return sinks[0]

    def sink(t: float, image: Any, observations: Any) -> None:
        for s in sinks:
            s(t, image, observations)

    return sink


def fly_to_dir(
    scenario: Scenario,
    out_dir: str | Path,
    *,
    report: bool = True,
    replay: bool = False,
    frame_sinks: Sequence[FrameSink] = (),
) -> MissionRun:
    """Fly ``scenario`` and write its outputs into ``out_dir`` (created if needed); with ``replay`` also
    the animated replay ``replay.gif`` (camera view with detections beside a top view). ``frame_sinks``
    also see every camera frame (exports such as ``alight fly --mcap``)."""
    out = make_out_dir(out_dir)
    recorder = FrameRecorder() if replay else None
    sinks: list[FrameSink] = [*([recorder] if recorder is not None else []), *frame_sinks]
    # The recorder alone asks only for the frames it keeps; any other sink sees every frame.
    wanted = recorder.wants if recorder is not None and not frame_sinks else None
    run = run_mission(scenario, record=True, frame_sink=_fan_out(sinks), frame_wanted=wanted)
    write_mission_dir(out, scenario, run, report=report, recorder=recorder)
    return run


def make_out_dir(out_dir: str | Path) -> Path:
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise InputError(f"{out}: cannot create the output directory ({err.strerror})") from None
    return out


def write_mission_dir(
    out: Path,
    scenario: Scenario,
    run: MissionRun,
    *,
    report: bool = True,
    recorder: FrameRecorder | None = None,
) -> None:
    """Write a flown mission's files into ``out`` (an existing directory): the log, the scenario, the
    result, with ``report`` the figures and report.html, and with a ``recorder`` (the flight's
    :class:`FrameRecorder`) the animated replay."""
    if run.log is None:
        raise ValueError("the mission was flown without its log (run_mission(record=True) writes one)")
    save_arrays(run.log, out)
    if recorder is not None:
        r = run.result
        write_replay(
            run.log,
            out / REPLAY_GIF,
            frames=recorder.frames or None,
            pad_size_m=scenario.platform.pad_size_m,
            title=f"{r['preset']} · seed {r['seed']} · {r['outcome']}",
        )
    if report:
        write_mission_report(out, run.result, run.log, run.events)
    write_scenario_yaml(out / SCENARIO_YAML, scenario.model_dump(mode="json"))
    write_result(out, run.result)
