"""Benchmark of the candidate planner (paper 000 Sec. II-D): generation of minimum-jerk candidates plus
the input and floor feasibility tests, per candidate.

``bench_planner()`` returns a dict for ``alight bench``; ``test_bench_planner_batch1000`` is the same
measurement for pytest-benchmark (``pytest benchmarks/bench_planner.py``). Target: <= 2 us per candidate
for a batch of 1000 (the authors' C++ does ~1.1 us with both tests).
"""

from __future__ import annotations

import statistics
import time

import numpy as np

from alight.airframe import Airframe
from alight.planning.candidates import CandidatePlanner, PlannerConfig
from alight.planning.min_jerk import EndConstraint, _evaluate_kernel


def realistic_candidates(rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
    """One start near hover (p0 around (0, 0, 5), |v0| <= 3 m/s, small a0) and n end states at a target
    2-20 m away at 1-3 m height, moving horizontally at 0-4.2 m/s, with durations in [0.5, 6] s."""
    p0 = np.array([0.0, 0.0, 5.0]) + rng.uniform(-0.5, 0.5, 3)
    v0 = _random_directions(rng, 1)[0] * rng.uniform(0.0, 3.0)
    a0 = rng.uniform(-0.5, 0.5, 3)
    z_end = rng.uniform(1.0, 3.0, n)
    dist = rng.uniform(2.0, 20.0, n)
    horiz = np.sqrt(np.maximum(dist**2 - (z_end - p0[2]) ** 2, 0.0))
    heading = rng.uniform(-np.pi, np.pi, n)
    pf = np.column_stack([p0[0] + horiz * np.cos(heading), p0[1] + horiz * np.sin(heading), z_end])
    course = rng.uniform(-np.pi, np.pi, n)
    speed = rng.uniform(0.0, 4.2, n)
    vf = np.column_stack([speed * np.cos(course), speed * np.sin(course), np.zeros(n)])
    T = rng.uniform(0.5, 6.0, n)
    return {"p0": p0, "v0": v0, "a0": a0, "pf": pf, "vf": vf, "T": T}


def _random_directions(rng: np.random.Generator, n: int) -> np.ndarray:
    d = rng.normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def _kernel_args(case: dict[str, np.ndarray]) -> tuple:
    f_min, f_max = Airframe().collective_accel_limits
    n = case["T"].size
    return (
        case["p0"].reshape(1, 3), case["v0"].reshape(1, 3), case["a0"].reshape(1, 3), case["T"],
        case["pf"], case["vf"], np.zeros((1, 3)), int(EndConstraint.POS_VEL),
        np.array([f_min, f_max, 6.0, 0.02]), True, np.array([0.0, 0.0, 0.5]), np.array([0.0, 0.0, 1.0]),
        np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty(n), np.empty(n, np.int64),
        np.empty(n, np.bool_),
    )  # fmt: skip


def _median_seconds(fn, repeats: int, inner: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(inner):
            fn()
        times.append((time.perf_counter() - t0) / inner)
    return statistics.median(times)


def bench_planner(repeats: int = 30, seed: int = 0) -> dict[str, float]:
    """Median per-candidate times (us): the fused numba kernel on a batch of 1000 realistic candidates
    (generation + input test + floor test), and the full ``CandidatePlanner.plan`` call (Python overhead,
    result objects, hysteresis) for batches of 1 and 20, divided by the batch size."""
    rng = np.random.default_rng(seed)
    case = realistic_candidates(rng, 1000)
    args = _kernel_args(case)
    _evaluate_kernel(*args)  # warm-up (compile or load from the cache)
    codes = args[16]
    floor_ok = args[17]
    out: dict[str, float] = {}
    out["planner_us_per_candidate"] = (
        1e6 * _median_seconds(lambda: _evaluate_kernel(*args), repeats, 5) / 1000
    )
    out["planner_feasible_fraction_batch1000"] = float(np.mean((codes == 0) & floor_ok))
    for n in (1, 20):
        c = realistic_candidates(rng, n)
        planner = CandidatePlanner(PlannerConfig(n_candidates=n))
        te = c["T"]

        def call(planner=planner, c=c, te=te) -> None:
            planner.reset()  # every call does the full work, including building the adopted trajectory
            planner.plan(0.0, c["p0"], c["v0"], c["a0"], te, c["pf"], c["vf"])

        call()
        out[f"planner_us_per_candidate_batch{n}"] = 1e6 * _median_seconds(call, repeats, 50) / n
    return out


def test_bench_planner_batch1000(benchmark) -> None:  # type: ignore[no-untyped-def]
    args = _kernel_args(realistic_candidates(np.random.default_rng(0), 1000))
    _evaluate_kernel(*args)
    benchmark(_evaluate_kernel, *args)
    assert np.isfinite(args[15]).all()


if __name__ == "__main__":  # pragma: no cover
    import json

    print(json.dumps(bench_planner(), indent=2))
