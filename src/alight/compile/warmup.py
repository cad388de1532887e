"""Warm-up: compile every numba kernel a preset uses before any mission's clock starts.

alight's inner loops are numba kernels, compiled on their first call. Uncompiled, the first mission of a
process pays for the compile in its ``wall_time_s``, its block timers and its wall-clock ``timeout_s``
(the detector once showed 2,503 ms per simulated second instead of 43). So a campaign's sandbox calls
:func:`warm_up` before it reports ready: the mission clocks then start after every kernel is compiled.

The warm-up flies a whole mission of each preset rather than calling each kernel on tiny inputs: a
flight compiles exactly the signatures (dtypes, layouts, read-only flags) that missions use, and stays
right when a kernel or its caller changes. The platform starts out of the camera's view and drives
toward the take-off point, so the flight goes through take-off, exploration, detection, tracking, the
landing and the touchdown (a 12 s flight that stopped on the approach left the exploration's kernels to
compile in the middle of the first missions that searched, on their clocks). What one flight cannot be
relied on to meet is called directly: here the kernels of every platform path, which the scenario
chooses (:func:`alight.sim.world.call_every_platform_path`); a block's rare branch by the block
itself when it is built (the falanga tag detector's cross, taken only when the circle is not found). Its
results are thrown away; it changes no state that a later mission sees (every mission builds its own
world and pipeline from its scenario). ``tests/test_parallel_compile.py`` flies missions after the
warm-ups and fails on any kernel signature they call first.

Every ``@njit`` in alight has ``cache=True``, so the compile happens once per install: later processes
load the machine code from numba's cache (milliseconds per kernel). The cache directory is keyed by the
whole package's source (:mod:`alight.compile.cache`): numba by itself keeps a kernel's code after a change
to a kernel it calls from another file, so any change of alight's source starts a fresh cache.

On an empty cache, the kernels the flight calls from Python are first compiled in parallel processes
(:mod:`alight.compile.parallel`), since numba compiles one kernel at a time; the flight then loads them.
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from alight.compile.meter import compile_meter
from alight.compile.parallel import CompileAheadReport, compile_ahead
from alight.errors import AlightError

WARMUP_DURATION_S = 60.0
"""Most simulated seconds of a warm-up flight. It ends when the vehicle has landed: after 28-34 s, 49 s for
kim_kaist's slow descent (2026-11-29)."""

_WARMUP_BASE: dict[str, Any] = {
    "name": "warm-up",
    "seed": 0,
    "duration_s": WARMUP_DURATION_S,
    # Out of view when the climb ends, also of kim_kaist's omnidirectional camera (the vehicle explores),
    # driving toward the take-off point: the search finds it within 6-11 s.
    "platform": {"path": "straight", "speed_mps": 1.0, "start_xy": [35.0, 2.0], "heading_rad": 3.14},
}


@dataclass(frozen=True)
class WarmupReport:
    presets: tuple[str, ...]
    wall_s: float
    """Wall time of the whole warm-up (s)."""
    compile_s: float
    """CPU time numba spent compiling (s); near 0 when every kernel came from the cache."""
    n_signatures: int
    """Signatures compiled (0 with a warm cache)."""
    ahead: CompileAheadReport | None = None
    """What was compiled in parallel helper processes before the flight (:mod:`alight.compile.parallel`);
    their CPU time is not in ``compile_s``."""


def warmup_scenario(preset: str) -> dict[str, Any]:
    """The warm-up flight of ``preset``, as scenario data."""
    return {**_WARMUP_BASE, "preset": preset, "name": f"warm-up {preset}"}


def presets_to_warm_up(scenarios: Iterable[Mapping[str, Any]]) -> tuple[str, ...]:
    """The presets whose warm-up flights compile the kernels that ``scenarios`` (scenario data) fly, in
    the order first met.

    Each scenario's own preset; and for each block it flies in place of its preset's (a campaign's block
    set, a ``blocks:`` key), a preset that flies that block at the same stage, unless one chosen already
    does: a block's kernels are compiled by a flight of a preset that has it. Why not fly each composition
    itself: blocks.yaml's 62 compositions took 1,114 s to warm up that way (many never find their pad and
    fly the whole minute) for about 25 s of compile, and compositions that share blocks compile the same
    kernels. A block that no preset flies is left to its first mission (the apriltag and aruco detectors
    and the apriltag pad are OpenCV's and have no kernels; ``nfold`` is flown inside ``sdu``). A scenario
    that does not validate is left out: its missions report what is wrong."""
    from alight.mission.blocks import STAGES, resolve_blocks
    from alight.mission.presets import PRESETS
    from alight.scenario import Scenario

    blocks_of: dict[str, dict[str, str]] = {}  # preset -> stage -> block name, built when needed

    def preset_blocks(preset: str) -> dict[str, str]:
        if preset not in blocks_of:
            eff = resolve_blocks(Scenario.model_validate({"preset": preset}), load_camera=False)
            blocks_of[preset] = {stage: eff[stage].name for stage in STAGES}
        return blocks_of[preset]

    chosen: dict[str, None] = {}
    seen: set[str] = set()
    for data in scenarios:
        preset, blocks = data.get("preset", "groundtruth"), data.get("blocks") or {}
        key = json.dumps([preset, blocks], sort_keys=True, default=str)
        if key in seen:
            continue
        seen.add(key)
        try:
            scenario = Scenario.model_validate({"preset": preset, "blocks": blocks})
            eff = resolve_blocks(scenario, load_camera=False)
        except (ValueError, AlightError):  # pydantic's ValidationError is a ValueError
            continue
        chosen.setdefault(preset, None)
        for stage in STAGES:
            name = eff[stage].name
            if name == preset_blocks(preset)[stage] or any(preset_blocks(p)[stage] == name for p in chosen):
                continue
            owner = next((p for p in PRESETS if preset_blocks(p)[stage] == name), None)
            if owner is not None:
                chosen[owner] = None
    return tuple(chosen)


def warm_up(presets: Iterable[str], *, compile_first: bool = True) -> WarmupReport:
    """Fly the warm-up mission of each preset (in the order given, each once); see the module docstring.
    With ``compile_first``, the listed kernels that numba's cache lacks are first compiled in parallel
    processes (:func:`alight.compile.parallel.compile_ahead`). Raises what the mission raises (a preset
    that cannot fly here cannot fly a campaign's missions either)."""
    from alight.evaluation.runner import run_mission
    from alight.scenario import scenario_from_dict

    names = tuple(dict.fromkeys(presets))
    t0 = time.perf_counter()
    ahead = compile_ahead(names) if compile_first else None
    from alight.sim.world import call_every_platform_path

    with compile_meter() as meter:
        call_every_platform_path()
        for preset in names:
            run_mission(scenario_from_dict(warmup_scenario(preset), "warm-up"), record=True)
    return WarmupReport(names, time.perf_counter() - t0, meter.compile_s, meter.n_signatures, ahead)


def main(argv: list[str] | None = None) -> int:
    """``python -m alight.compile.warmup [PRESET ...]``: fill numba's cache for the presets (default: all)
    once, e.g. right after installing, so no later process pays the compile; prints what it took as JSON."""
    import json
    import sys

    from alight.mission.presets import PRESETS

    names = (sys.argv[1:] if argv is None else argv) or list(PRESETS)
    unknown = [n for n in names if n not in PRESETS]
    if unknown:
        print(
            f"alight.compile.warmup: unknown preset {unknown[0]!r}, expected one of {sorted(PRESETS)}",
            file=sys.stderr,
        )
        return 2
    report = warm_up(names)
    figures = {
        "presets": list(report.presets),
        "wall_s": round(report.wall_s, 2),
        "compile_s": round(report.compile_s, 2),
        "signatures": report.n_signatures,
    }
    if report.ahead is not None and report.ahead.helpers:
        figures["ahead"] = {
            "helpers": report.ahead.helpers,
            "signatures": report.ahead.kernels,
            "wall_s": round(report.ahead.wall_s, 2),
            "cpu_s": round(report.ahead.cpu_s, 2),
            "failed": report.ahead.failed,
        }
    print(json.dumps(figures))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
