"""Issue 6's delay-compensation table: the zamanakos_sdu Kalman filter (paper 004 Sec. IV-B) with and
without the detection delay compensated, at 100 to 250 ms of latency, the platform a tractor at 1.5 m/s
(a row, a U-turn, the next row), the UAV hovering or tracking it.

    python benchmarks/sdu_latency_table.py [--seeds 6]

The runs are those of ``tests/estimation/test_sdu_kf.py::test_latency_compensation_at_1_5_mps`` (the test
asserts the claim; this prints the numbers): worst horizontal error of ``state(t)`` over every seed, and
the mean of the per-run RMS, in metres.
"""

from __future__ import annotations

import argparse
import importlib.util
from pathlib import Path

_TEST = Path(__file__).resolve().parent.parent / "tests" / "estimation" / "test_sdu_kf.py"


def _load_test_module():  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location("sdu_kf_latency_runs", _TEST)
    if spec is None or spec.loader is None:
        raise SystemExit(f"cannot load {_TEST}")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=6, help="seeded runs per cell (default 6)")
    args = ap.parse_args()
    runs = _load_test_module()
    runs.LATENCY_SEEDS = range(args.seeds)
    cols = ("compensated, hover", "compensated, tracking", "uncompensated, hover", "uncompensated, tracking")
    print("| latency (worst / RMS, m) | " + " | ".join(cols) + " |")
    print("|---|---|---|---|---|")
    for latency in (0.10, 0.15, 0.20, 0.25):
        n = runs.latency_table(latency)
        cells = [
            f"{n[f'{c}_{u}_max']:.3f} / {n[f'{c}_{u}_rms']:.3f}"
            for c in ("comp", "uncomp")
            for u in ("hover", "track")
        ]
        print(f"| {latency * 1e3:.0f} ms | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
