"""Real-time factor of whole missions: simulated seconds per wall-clock second, one core.

``sim_rtf_groundtruth``: a full ``groundtruth`` mission (take-off, exploration, tracking, landing on a
platform driving a circle at 2 m/s), timed after a warm-up mission so numba's compilation is excluded.
Target (issue 2): >= 50. Anchor: rotorpy runs its dynamics and controller alone at about 5.5.
"""

from __future__ import annotations

import statistics
import time

from alight.evaluation.runner import run_mission
from alight.scenario import scenario_from_dict

_SCENARIO = {
    "preset": "groundtruth",
    "seed": 7,
    "duration_s": 60.0,
    "platform": {"path": "circle", "speed_mps": 2.0},
}


def _rtf(scenario_dict: dict, seed: int, record: bool) -> tuple[float, str]:
    s = scenario_from_dict({**scenario_dict, "seed": seed})
    t0 = time.perf_counter()
    run = run_mission(s, record=record)
    wall = time.perf_counter() - t0
    return run.result["simulated_time_s"] / wall, run.result["outcome"]


def bench_sim(quick: bool = False) -> dict[str, float]:
    _rtf(_SCENARIO, 0, True)  # warm-up: numba compilation and caches
    seeds = range(1, 3 if quick else 6)
    logged = [_rtf(_SCENARIO, s, True)[0] for s in seeds]
    bare = [_rtf(_SCENARIO, s, False)[0] for s in seeds]
    return {
        "sim_rtf_groundtruth": round(statistics.median(logged), 1),
        "sim_rtf_groundtruth_nolog": round(statistics.median(bare), 1),
    }


def test_bench_sim_groundtruth(benchmark) -> None:  # type: ignore[no-untyped-def]
    s = scenario_from_dict(_SCENARIO)
    run_mission(s, record=False)
    benchmark.pedantic(run_mission, args=(s,), kwargs={"record": False}, rounds=3, iterations=1)
